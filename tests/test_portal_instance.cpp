// test_portal_instance.cpp: instanced subspaces of the portal tracer ("A Novel Raytracing Algorithm
// for GPU", docs/PORTAL.md, "Instanced subspaces") against the independent truth: the same world
// flattened (every instance written out as plain voxels), traced by the exact voxel DDA and by the
// plain portal tracer. The instanced traversal decides every plane crossing with the same
// predicate on the same fine-space planes (the top level's tile planes are the fine planes times
// 2^-k, exact), so the hit records agree in t, material, voxel, face, u and v bit for bit, and the
// rendered images in every pixel.
#include <catch2/catch.hpp>
#include <cstring>
#include <random>

#include "gridrt/common/camera.h"
#include "gridrt/reference/portal/build.h"
#include "gridrt/reference/portal/instance.h"
#include "gridrt/reference/portal/trace.h"
#include "gridrt/reference/portal/world.h"

using namespace gridrt;
using namespace gridrt::portal;

namespace {

Ray ray_of(glm::vec3 o, glm::vec3 d, float tmax = std::numeric_limits<float>::infinity()) {
  Ray r{};
  r.org = o, r.dir = d, r.tmin = 0.0f, r.tmax = tmax;
  r.launch_normal = glm::vec3(0.0f);
  r.launch_ref = shared::kNoRef;
  return r;
}

uint32_t bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

// What must agree: everything but the step counts (cells, tests: each structure's own).
void require_same_hit(const Hit& a, const Hit& b, const Ray& r) {
  INFO("ray org (" << r.org.x << ", " << r.org.y << ", " << r.org.z << ") dir (" << r.dir.x << ", " << r.dir.y << ", "
                   << r.dir.z << ") tmax " << r.tmax);
  REQUIRE(a.instance == b.instance);
  REQUIRE(a.triangle == b.triangle);
  REQUIRE(bits(a.t) == bits(b.t));
  REQUIRE(bits(a.u) == bits(b.u));
  REQUIRE(bits(a.v) == bits(b.v));
}

// Camera rays, random rays from random points inside the world box (tile units), rays from outside
// with bounded and unbounded tmax, and rays through fine-voxel corners and along edges.
std::vector<Ray> test_rays(const InstancedWorld& iw, uint32_t seed) {
  std::vector<Ray> rays = camera_rays(iw.top.camera, 48, 24);
  std::mt19937 rng(seed);
  const glm::vec3 ext(iw.top.dims);
  std::uniform_real_distribution<float> U(0.0f, 1.0f), N(-1.0f, 1.0f);
  for (int i = 0; i < 1500; ++i) {
    const glm::vec3 o(U(rng) * ext.x, U(rng) * ext.y, U(rng) * ext.z);
    rays.push_back(ray_of(o, glm::vec3(N(rng), N(rng), N(rng))));
  }
  for (int i = 0; i < 500; ++i) {
    const glm::vec3 target(U(rng) * ext.x, U(rng) * ext.y, U(rng) * ext.z);
    const glm::vec3 o = ext * 0.5f + glm::vec3(N(rng), N(rng), N(rng)) * glm::length(ext);
    const float tmax = i % 3 == 0 ? std::numeric_limits<float>::infinity() : U(rng) * 1.5f;
    rays.push_back(ray_of(o, target - o, tmax));
  }
  // Fine-voxel corners (multiples of 1/scale) and tile corners, diagonal and axis directions.
  const float f = 1.0f / float(iw.scale);
  for (int i = 0; i < 300; ++i) {
    const glm::vec3 o(float(rng() % (iw.top.dims.x * iw.scale)) * f, float(rng() % (iw.top.dims.y * iw.scale)) * f,
                      float(rng() % (iw.top.dims.z * iw.scale)) * f);
    for (glm::vec3 d : {glm::vec3(1, 1, 1), glm::vec3(-1, 0, 1), glm::vec3(1, 0, 0), glm::vec3(0, -1, 0), glm::vec3(-2, 1, 1),
                        glm::vec3(1, 0, -1), glm::vec3(0, 0, -1)})
      rays.push_back(ray_of(o, d, i % 4 == 0 ? 0.7f : std::numeric_limits<float>::infinity()));
  }
  rays.push_back(ray_of(ext * 0.5f, glm::vec3(0.0f)));  // no direction
  return rays;
}

// A random block map: scale 4, blocks of random fine voxels, tiles random walls, instances or air.
InstancedWorld random_block_world(uint32_t seed) {
  std::mt19937 rng(seed);
  std::string text = "scale 4\nsize 9 7 2\n";
  for (int b = 0; b < 3; ++b) {
    text += "block b" + std::to_string(b) + "\n";
    for (int k = 0; k < 5; ++k) {
      const int x0 = rng() % 4, y0 = rng() % 4, z0 = rng() % 4;
      text += "box " + std::to_string(x0) + " " + std::to_string(y0) + " " + std::to_string(z0) + " " +
              std::to_string(x0 + 1 + rng() % (4 - x0)) + " " + std::to_string(y0 + 1 + rng() % (4 - y0)) + " " +
              std::to_string(z0 + 1 + rng() % (4 - z0)) + " " + std::to_string(rng() % 10) + "\n";
    }
    text += "end\ntile " + std::string(1, char('A' + b)) + " b" + std::to_string(b) + "\n";
  }
  text += "map\n";
  for (int z = 0; z < 7; ++z) {
    for (int x = 0; x < 9; ++x) {
      const uint32_t r = rng() % 10;
      text += (z == 3 && x == 4) ? 'E' : r < 4 ? '.' : r < 8 ? char('A' + r % 3) : '3';
    }
    text += "\n";
  }
  return parse_block_map(text, "random blocks");
}

void compare_with_flattened(const InstancedWorld& iw, uint32_t seed, bool with_portal) {
  const World flat = flatten(iw);
  const PortalBuild ib = build_instanced(iw, PortalOptions{1024, 1024, 0, false});
  std::optional<PortalBuild> fb;
  if (with_portal) fb = build_portal(flat, PortalOptions{1024, 1024, 0, false});
  size_t hits = 0, into_blocks = 0;
  for (const Ray& r : test_rays(iw, seed)) {
    const Hit a = trace_portal(ib.packed, r);
    require_same_hit(a, trace_dda(flat, r), r);
    if (fb) require_same_hit(a, trace_portal(fb->packed, r), r);
    hits += !is_miss(a);
    into_blocks += !is_miss(a) && a.instance < iw.instance_base && a.instance != 11 && a.instance != 12;
  }
  CHECK(hits > 1000);
  CHECK(into_blocks > 100);
}

}  // namespace

TEST_CASE("Portal instancing: hits equal the flattened world's (DDA and portal) in bits - random blocks", "[portal][instance]") {
  for (uint32_t seed : {1u, 2u, 3u}) {
    INFO("seed " << seed);
    compare_with_flattened(random_block_world(seed), seed, true);
  }
}

TEST_CASE("Portal instancing: hits equal the flattened world's - generated and built-in block levels", "[portal][instance]") {
  compare_with_flattened(generated_blocks_spec("gen-blocks:14x11x2:5"), 11, true);
  compare_with_flattened(builtin_blocks(), 12, false);  // the DDA on the flattened world as the truth
}

TEST_CASE("Portal instancing: the render equals the flattened world's in every pixel", "[portal][instance]") {
  const InstancedWorld iw = generated_blocks_spec("gen-blocks:14x11x2:5");
  const PortalBuild ib = build_instanced(iw, PortalOptions{1024, 1024, 0, false});
  const PortalBuild fb = build_portal(flatten(iw), PortalOptions{1024, 1024, 0, false});
  for (bool fsm : {true, false}) {
    RenderOptions ro;
    ro.width = 96, ro.height = 48, ro.state_machine = fsm;
    RenderStats si, sf;
    const std::vector<glm::vec3> a = render(ib, iw.top.camera, ro, &si), b = render(fb, iw.top.camera, ro, &sf);
    REQUIRE(a.size() == b.size());
    REQUIRE(std::memcmp(a.data(), b.data(), a.size() * sizeof(glm::vec3)) == 0);
    CHECK(si.shadow_rays == sf.shadow_rays);
    CHECK(si.shadow_rays > 1000);
  }
}

TEST_CASE("Portal instancing: explain names the enter and leave events", "[portal][instance]") {
  const InstancedWorld iw = builtin_blocks();
  const PortalBuild ib = build_instanced(iw, PortalOptions{1024, 1024, 0, false});
  // Along a brick wall's face, grazing: the ray enters bricks and leaves them through joints.
  std::string all;
  for (const Ray& r : test_rays(iw, 3)) {
    std::string log;
    trace_portal(ib.packed, r, &log);
    all += log;
    if (all.find("enter instance") != std::string::npos && all.find("leave instance") != std::string::npos) break;
  }
  CHECK(all.find("enter instance: block") != std::string::npos);
  CHECK(all.find("leave instance: tile") != std::string::npos);
  CHECK(ib.packed.top_divs + ib.block_divs == ib.packed.div_count);
}

TEST_CASE("Portal instancing: bad block maps are clear errors", "[portal][instance][badinput]") {
  const std::string head = "scale 4\nsize 5 5 1\nblock a\nbox 0 0 0 4 4 4 1\nend\ntile A a\n";
  const std::string rows = "map\nAAAAA\nA...A\nA.E.A\nA...A\nAAAAA\n";
  auto err = [](const std::string& text) -> std::string {
    try {
      parse_block_map(text, "t");
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  CHECK(err(head + rows) == "no error");
  CHECK_THAT(err("scale 4\nsize 5 5 1\nblock a\nend\ntile A nosuch\n" + rows), Catch::Contains("unknown block 'nosuch'"));
  CHECK_THAT(err("scale 4\nsize 5 5 1\nblock a\nbox 0 0 0 4 4 4 A\nend\ntile A a\n" + rows),
             Catch::Contains("blocks inside blocks are not supported"));
  CHECK_THAT(err("scale 3\n" + head.substr(8) + rows), Catch::Contains("scale must be 2, 4, 8 or 16"));
  CHECK_THAT(err("scale 4\nsize 5 5 1\nblock a\nbox 0 0 0 5 4 4 1\nend\ntile A a\n" + rows), Catch::Contains("outside the block"));
  CHECK_THAT(err("scale 4\nsize 5 5 1\nblock a\nbox 0 0 0 4 4 4 G\nend\ntile A a\n" + rows), Catch::Contains("glass"));
  CHECK_THAT(err("scale 4\nsize 5 5 1\nblock a\nbox 0 0 0 4 4 4 q\nend\ntile A a\n" + rows), Catch::Contains("unknown material"));
  CHECK_THAT(err("scale 4\nsize 5 5 1\nblock a\nbox 0 0 0 4 4 4 1\n" + rows), Catch::Contains("unknown keyword"));
  CHECK_THAT(err(head + "map\nAAAAA\nA.Z.A\nA.E.A\nA...A\nAAAAA\n"), Catch::Contains("unknown character 'Z'"));
  CHECK_THAT(err(head + "map\nAAAAA\nA...A\n"), Catch::Contains("expected 5 map rows"));
  CHECK_THAT(err("scale 4\nsize 5 5 1\nmaterial m x 2 0 0\nblock a\nbox 0 0 0 4 4 4 1\nend\ntile A a\n" + rows),
             Catch::Contains("material colour must be within [0, 1]"));
  CHECK_THAT(err("scale 16\nsize 255 255 20\nblock a\nend\ntile A a\nmap\n"), Catch::Contains("2^29"));
  CHECK_THAT(err("scale 4\nsize 256 5 1\n"), Catch::Contains("255 tiles"));
  CHECK_THAT(err("scale 4\nsize 5 5 1\n" + rows), Catch::Contains("no blocks"));
  CHECK_THAT(err("scale 4\nsize 5 5 1\nblock a\nend\nblock a\nend\n" + rows), Catch::Contains("defined twice"));
  // Block names become file names in `portal export`: no path separators, quotes or dots.
  CHECK_THAT(err("scale 4\nsize 5 5 1\nblock ../x\nend\n" + rows), Catch::Contains("block name '../x'"));
  CHECK_THAT(err("scale 4\nsize 5 5 1\nblock a\"b\nend\n" + rows), Catch::Contains("letters, digits"));
  // A world whose flattened form breaks the plain world's 255 voxels per axis still builds instanced.
  const InstancedWorld big = generated_blocks_spec("gen-blocks:40x40x1");
  CHECK_THROWS_WITH(flatten(big), Catch::Contains("only the instanced world fits"));
  CHECK_THROWS_WITH(generated_blocks_spec("gen-blocks:4x40x1"), Catch::Contains("5 .. 255"));
  CHECK_THROWS_WITH(generated_blocks_spec("gen-blocks:40x40"), Catch::Contains("expected gen-blocks:"));
  CHECK_THROWS_WITH(generated_blocks_spec("gen-blocks:40x40x1:abc"), Catch::Contains("expected gen-blocks:"));
  CHECK_THROWS_WITH(generated_blocks_spec("gen-blocks:40x40x1:-1"), Catch::Contains("expected gen-blocks:"));
  PortalOptions mip{1024, 1024, 0, false};
  mip.mip_levels = 2, mip.mip_distance = 4.0f;
  CHECK_THROWS_WITH(build_instanced(builtin_blocks(), mip), Catch::Contains("mip levels are not supported"));
}

#include <filesystem>
#include <fstream>

#include "tests/run_tool.h"

TEST_CASE("Portal instancing: data/maps/blocks.map is builtin:blocks", "[portal][instance]") {
  std::ifstream f(std::string(GRIDRT_DATA_DIR) + "/maps/blocks.map", std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(f)), {});
  CHECK(text == builtin_blocks_text());
  CHECK(is_block_map(text));
  CHECK_FALSE(is_block_map(builtin_level_text()));
}

TEST_CASE("CLI: portal verbs on instanced worlds - --flatten, --flat-compare, explain, bad block maps",
          "[cli][portal][instance]") {
  using gridrt::test::run_tool;
  const std::string map = std::string(GRIDRT_DATA_DIR) + "/maps/blocks.map";
  const std::string out = (std::filesystem::temp_directory_path() / "gridrt_instance.ppm").string();
  const auto r = run_tool("portal render " + map + " --width 48 --height 24 --flat-compare -o " + out);
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  CHECK_THAT(r.output, Catch::Contains("0 of 1152 pixels differ"));
  CHECK_THAT(r.output, Catch::Contains("top level +"));
  const auto e = run_tool("portal explain builtin:blocks --width 48 --height 24 --pixel 24,12");
  INFO(e.output);
  REQUIRE(e.exit_code == 0);
  CHECK_THAT(e.output, Catch::Contains("instanced world 'builtin:blocks'"));
  const auto fl = run_tool("portal explain builtin:blocks --flatten --width 48 --height 24 --pixel 24,12");
  INFO(fl.output);
  REQUIRE(fl.exit_code == 0);
  CHECK_THAT(fl.output, Catch::Contains("(agrees)"));
  // Hostile input: clear messages, exit 1 (bad input) or 2 (command line).
  const auto big = run_tool("portal render gen-blocks:255x255x4 --flatten --width 8 --height 4 -o " + out);
  CHECK(big.exit_code == 1);
  CHECK_THAT(big.output, Catch::Contains("only the instanced world fits"));
  const std::string bad = (std::filesystem::temp_directory_path() / "gridrt_bad_blocks.map").string();
  std::ofstream(bad) << "scale 4\nsize 5 5 1\nblock a\nbox 0 0 0 4 4 4 A\nend\ntile A a\nmap\nAAAAA\nA...A\nA.E.A\nA...A\nAAAAA\n";
  const auto rec = run_tool("portal render " + bad + " --width 8 --height 4 -o " + out);
  CHECK(rec.exit_code == 1);
  CHECK_THAT(rec.output, Catch::Contains("blocks inside blocks are not supported"));
  const auto nf = run_tool("portal render builtin:level --flat-compare --width 8 --height 4 -o " + out);
  CHECK(nf.exit_code == 2);  // a contradiction on the command line
  CHECK_THAT(nf.output, Catch::Contains("--flat-compare needs an instanced world"));
  const auto gen = run_tool("portal bench gen-blocks:9x9 --repeat 1");
  CHECK(gen.exit_code == 1);
  CHECK_THAT(gen.output, Catch::Contains("expected gen-blocks:"));
  // A second 'scale' line: a box valid at the first scale wrote past the block at the second (heap
  // corruption, an abort); now refused where it stands (an outside sweep's find)
  std::ofstream(bad) << "scale 16\nblock big\nbox 0 0 0 16 16 16 1\nend\ntile B big\nscale 2\nsize 3 3 1\nmap\nBBB\nBEB\nBBB\n";
  const auto twice = run_tool("portal render " + bad + " --width 8 --height 4 -o " + out);
  CHECK(twice.exit_code == 1);
  CHECK_THAT(twice.output, Catch::Contains(":6: 'scale' given twice"));
  // The per-pixel work views ignored the mip, flatten and compare options: refused, as a command line
  const auto view = run_tool("portal render builtin:blocks --view divs --flat-compare --width 8 --height 4 -o " + out);
  CHECK(view.exit_code == 2);
  CHECK_THAT(view.output, Catch::Contains("leave out --mip-levels"));
  const auto mip = run_tool("portal render builtin:level --mip-compare --width 8 --height 4 -o " + out);
  CHECK(mip.exit_code == 2);
  CHECK_THAT(mip.output, Catch::Contains("needs --mip-levels 2 or more"));
}

#include "gridrt/common/scene_io.h"

TEST_CASE("Portal instancing: export as a triangle scene - the grid's instances and the flattened mesh", "[portal][instance]") {
  const auto dir = std::filesystem::temp_directory_path() / "gridrt_instance_export";
  std::filesystem::create_directories(dir);
  const InstancedWorld iw = generated_blocks_spec("gen-blocks:9x8x1:3");
  const size_t inst = export_scene(iw, (dir / "level.json").string(), false);
  const size_t flat = export_scene(iw, (dir / "flat.json").string(), true);
  const Scene a = load_scene_file((dir / "level.json").string());
  const Scene b = load_scene_file((dir / "flat.json").string());
  CHECK(a.triangle_count() == inst);
  CHECK(b.triangle_count() == flat);
  // The instanced scene also holds the faces where an instance touches another or a wall (hidden
  // there), the flattened one only faces towards empty voxels: never fewer instanced.
  CHECK(inst >= flat);
  CHECK(flat > 1000);
  CHECK(a.instances.size() > 10);
  CHECK(glm::length(a.camera->eye - iw.top.camera.eye) == 0.0f);
  CHECK_THROWS_WITH(export_scene(iw, (dir / "level.obj").string(), false), Catch::Contains(".json"));
}

TEST_CASE("Portal instancing: the DDA over instanced voxels - the flattened DDA's records, and the truth beyond flatten",
          "[portal][instance]") {
  {
    const InstancedWorld iw = builtin_blocks();
    const World flat = flatten(iw);
    for (const Ray& r : test_rays(iw, 41)) {
      const Hit a = trace_dda_instanced(iw, r), b = trace_dda(flat, r);
      require_same_hit(a, b, r);
      REQUIRE(a.cells == b.cells);
      REQUIRE(a.tests == b.tests);
    }
  }
  // 640 x 32 x 560 fine voxels: only the instanced world exists; the DDA over its voxels is the truth.
  const InstancedWorld big = generated_blocks_spec("gen-blocks:80x70x2:9");
  CHECK_THROWS(flatten(big));
  const PortalBuild b = build_instanced(big, PortalOptions{1024, 1024, 0, false});
  size_t hits = 0;
  for (const Ray& r : test_rays(big, 42)) {
    const Hit a = trace_portal(b.packed, r);
    require_same_hit(a, trace_dda_instanced(big, r), r);
    hits += !is_miss(a);
  }
  CHECK(hits > 1000);
}
