// test_vulkan_portal.cpp: the Vulkan portal tracer (vulkan/portal.h) against the CPU reference
// (reference/portal), on lavapipe with the validation layer on (docs/PORTAL.md, docs/VULKAN.md):
//  - every hit record identical in bits to PortalTracer's (t, material, voxel<<3|face, u, v,
//    flags, divs visited, texels read): the built-in level (camera rays, random rays inside and
//    outside, rays through voxel corners and along edges, short tmax) and a voxelized teapot;
//  - the atlas read back from the device equals the packed atlas;
//  - the GPU render equals the CPU render: every pixel in bits except those that saw glass, whose
//    colour goes through pow (std::pow vs the driver's pow), and every statistic exactly;
//  - on the GPU, the single-loop state machine and the three separate loops agree bit for bit;
//  - explain: the shader's own record of a ray reads as the reference's, line for line.
// Off lavapipe (docs/VULKAN.md) division may round differently: t, u, v are held to ulps instead.
#include <cmath>
#include <cstring>
#include <random>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/reference/portal/build.h"
#include "gridrt/reference/portal/instance.h"
#include "gridrt/reference/portal/trace.h"
#include "tests/run_tool.h"
#include "tests/vulkan_test_util.h"
#include "gridrt/vulkan/portal.h"

using namespace gridrt;
using namespace gridrt::test;
using gridrt::vulkan::PortalVulkanTracer;
using gridrt::test::Run;
using gridrt::test::run_tool;
namespace pt = gridrt::portal;

namespace {

Ray make_ray(glm::vec3 o, glm::vec3 d, float tmin = 0.0f, float tmax = INFINITY) {
  Ray r{};
  r.org = o, r.dir = d, r.tmin = tmin, r.tmax = tmax;
  r.launch_normal = glm::vec3(0.0f);
  r.launch_ref = shared::kNoRef;
  return r;
}

std::string ray_text(const Ray& r) {
  return "org (" + hex(r.org.x) + ", " + hex(r.org.y) + ", " + hex(r.org.z) + ") dir (" + hex(r.dir.x) + ", " +
         hex(r.dir.y) + ", " + hex(r.dir.z) + ") t in (" + hex(r.tmin) + ", " + hex(r.tmax) + ")";
}

std::string hit_text(const Hit& h) {
  return "t " + hex(h.t) + " instance " + std::to_string(h.instance) + " triangle " + hex(h.triangle) + " u " +
         hex(h.u) + " v " + hex(h.v) + " flags " + std::to_string(h.flags) + " cells " + std::to_string(h.cells) +
         " tests " + std::to_string(h.tests);
}

const pt::PortalBuild& builtin_build() {
  static const pt::PortalBuild b = pt::build_portal(pt::builtin_level(), pt::PortalOptions{1024, 1024, 0, false});
  return b;
}

const pt::PortalBuild& teapot_build() {
  static const pt::PortalBuild b = [] {
    return pt::build_portal(pt::voxelize(make_builtin("teapot"), 24), pt::PortalOptions{1024, 1024, 0, false});
  }();
  return b;
}

// A random ray starting in an empty voxel (or outside the world, `outside`), random direction.
Ray random_ray(const pt::World& w, std::mt19937& rng, bool outside) {
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  glm::vec3 d;
  do d = glm::vec3(U(rng), U(rng), U(rng)) * 2.0f - 1.0f;
  while (glm::length(d) < 0.1f);
  if (outside) {
    const glm::vec3 c = w.to_world(glm::vec3(w.dims) * 0.5f);
    const float r = glm::length(glm::vec3(w.dims)) * w.voxel_size;
    const glm::vec3 target = w.to_world(glm::vec3(U(rng), U(rng), U(rng)) * glm::vec3(w.dims));
    const glm::vec3 o = c + glm::normalize(d) * r;
    return make_ray(o, target - o);
  }
  for (;;) {
    const glm::ivec3 v(rng() % w.dims.x, rng() % w.dims.y, rng() % w.dims.z);
    if (w.solid(v)) continue;
    const glm::vec3 o = w.to_world(glm::vec3(v) + glm::vec3(U(rng), U(rng), U(rng)));
    return make_ray(o, d);
  }
}

// The rays of a world: camera rays, random rays inside and outside, and (voxel-space corners)
// rays through voxel corners and along edges, some with a short tmax.
std::vector<Ray> test_rays(const pt::World& w, uint32_t seed, size_t random_each) {
  std::vector<Ray> rays;
  for (uint32_t y = 0; y < 24; ++y)
    for (uint32_t x = 0; x < 48; ++x) rays.push_back(camera_ray(w.camera, 48, 24, x, y));
  std::mt19937 rng(seed);
  for (size_t i = 0; i < random_each; ++i) rays.push_back(random_ray(w, rng, false));
  for (size_t i = 0; i < random_each; ++i) rays.push_back(random_ray(w, rng, true));
  for (uint32_t x = 1; x + 1 < w.dims.x; x += 3)
    for (uint32_t z = 1; z + 1 < w.dims.z; z += 2)
      for (glm::vec3 d : {glm::vec3(1, 1, 1), glm::vec3(-1, 0, 1), glm::vec3(1, 0, 0), glm::vec3(0, -1, 0),
                          glm::vec3(-2, 1, 1), glm::vec3(1, 0, -1)}) {
        const glm::vec3 o = w.to_world(glm::vec3(float(x), float(w.dims.y / 2), float(z)));
        rays.push_back(make_ray(o, d));
        rays.push_back(make_ray(o, d, 0.0f, 2.5f * w.voxel_size));
      }
  // Rays starting in glass (an outside sweep: the portal traced out of it, the DDA said inside),
  // and intervals that hold nothing or start behind the origin
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (uint32_t i = 0, n = 0; i < 100000 && n < 64; ++i) {
    const glm::ivec3 v(rng() % w.dims.x, rng() % w.dims.y, rng() % w.dims.z);
    if (w.medium(v) == pt::kEmpty || w.medium(v) == pt::World::kOpaque) continue;
    rays.push_back(make_ray(w.to_world(glm::vec3(v) + glm::vec3(U(rng), U(rng), U(rng))),
                            glm::vec3(U(rng), U(rng), U(rng)) * 2.0f - 1.0f));
    ++n;
  }
  const glm::vec3 mid = w.to_world(glm::vec3(w.dims) * 0.5f);
  for (const auto& [tmin, tmax] : {std::pair{0.0f, 0.0f}, {2.0f, 1.0f}, {-1.0f, 1e30f}, {NAN, 1e30f}})
    rays.push_back(make_ray(mid, glm::vec3(1, 0.3f, 0.1f), tmin, tmax));
  // Degenerate rays: zero direction, NaN origin.
  rays.push_back(make_ray(w.to_world(glm::vec3(w.dims) * 0.5f), glm::vec3(0.0f)));
  rays.push_back(make_ray(glm::vec3(NAN), glm::vec3(1, 0, 0)));
  return rays;
}

// Every record in bits on lavapipe; elsewhere discrete fields equal and t, u, v within ulps.
void require_same_hits(const std::vector<Ray>& rays, const std::vector<Hit>& cpu, const std::vector<Hit>& gpu,
                       bool bit_exact) {
  REQUIRE(cpu.size() == gpu.size());
  size_t hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const Hit& c = cpu[i];
    const Hit& g = gpu[i];
    INFO("ray " << i << ": " << ray_text(rays[i]));
    INFO("cpu " << hit_text(c));
    INFO("gpu " << hit_text(g));
    hits += !is_miss(c);
    REQUIRE(c.instance == g.instance);
    REQUIRE(c.triangle == g.triangle);
    REQUIRE(c.flags == g.flags);
    REQUIRE(c.cells == g.cells);
    REQUIRE(c.tests == g.tests);
    if (bit_exact) {
      REQUIRE(same_float(bits(c.t), bits(g.t)));
      REQUIRE(same_float(bits(c.u), bits(g.u)));
      REQUIRE(same_float(bits(c.v), bits(g.v)));
    } else {
      REQUIRE((bits(c.t) == bits(g.t) || ulp_distance(bits(c.t), bits(g.t)) <= kDivisionUlps));
      REQUIRE(std::abs(c.u - g.u) <= 1e-4f);
      REQUIRE(std::abs(c.v - g.v) <= 1e-4f);
    }
  }
  CHECK(hits > rays.size() / 4);
}

void check_trace(const pt::PortalBuild& build, uint32_t seed, size_t random_each) {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  PortalVulkanTracer gpu(ctx, build);
  pt::PortalTracer cpu(build, pt::PortalOptions{1024, 1024, 0, false});
  const std::vector<Ray> rays = test_rays(build.world, seed, random_each);
  std::vector<Hit> a(rays.size()), b(rays.size());
  cpu.trace(rays, a);
  gpu.trace(rays, b);
  require_same_hits(rays, a, b, bit_exact_device(ctx));
  // The atlas as the device holds it.
  const AccelDump d = gpu.dump();
  REQUIRE(d.kind == "portal");
  REQUIRE(d.extent == glm::uvec3(build.packed.atlas_width, build.packed.atlas_height, 1));
  REQUIRE(d.texels == std::vector<uint32_t>(build.packed.atlas.begin(), build.packed.atlas.end()));
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

// A room with two glass materials touching (the default 'G' and an amber 'H' of another index):
// a ray crossing from one into the other meets a surface of the glass it enters.
pt::World two_glasses() {
  return pt::parse_tile_map(
      "size 9 5 3\nmaterial H amber 1.0 0.6 0.2 glass 1.9\nmap\n111111111\n1.......1\n1E..GH..1\n1....HG.1\n111111111\n",
      "two glasses");
}

}  // namespace

TEST_CASE("Portal Vulkan: hit records identical to portal-cpu where two glasses touch", "[vulkan][portal][diff]") {
  check_trace(pt::build_portal(two_glasses(), pt::PortalOptions{64, 64, 1, false}), 14, 1000);
}

TEST_CASE("Portal Vulkan: a far camera's cycling pixels end as background on both, counted", "[vulkan][portal][diff]") {
  // An outside sweep: from 1e7 voxels away three divs handed a ray round at one t; the CPU render
  // hung and lavapipe left the pixels black with exit 0. Both now end such a pixel as background and
  // count it (llvmpipe's own loop limit, 65,535 iterations, may end it before the renderer's limit:
  // the pictures agree, the iteration counts need not)
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  pt::World w;
  w.name = "far";
  w.dims = glm::uvec3(32);
  w.materials = {{"a", glm::vec3(1, 0, 0)}, {"b", glm::vec3(0, 1, 0)}, {"c", glm::vec3(0, 0, 1)}};
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  w.voxels.resize(w.voxel_count());
  for (auto& v : w.voxels) v = U(rng) < 0.08f ? uint16_t(rng() % 3) : pt::kEmpty;
  const pt::PortalBuild b = pt::build_portal(w, pt::PortalOptions{1024, 1024, 0, false});
  PortalVulkanTracer gpu(ctx, b);
  Camera cam;
  cam.target = w.to_world(glm::vec3(16.0f));
  cam.eye = cam.target + glm::normalize(glm::vec3(0.55f, 0.38f, 0.74f)) * (1.0e7f * w.voxel_size);
  cam.vfov_degrees = 2.0e-4f;
  pt::RenderOptions o;
  o.width = 64, o.height = 64;
  pt::RenderStats cs, gs;
  const std::vector<glm::vec3> cpu = pt::render(b, cam, o, &cs);
  const std::vector<glm::vec3> img = gpu.render(cam, o, &gs);
  CHECK(cs.cut_pixels > 0);
  CHECK(gs.cut_pixels == cs.cut_pixels);
  if (bit_exact_device(ctx)) CHECK(std::memcmp(cpu.data(), img.data(), cpu.size() * sizeof(glm::vec3)) == 0);
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Portal Vulkan: a camera inside glass renders as portal-cpu's, through the glass's surface",
          "[vulkan][portal][diff]") {
  // An outside sweep: a camera in glass traced the glass as air (no refraction out, no filter)
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const pt::World w = two_glasses();
  const pt::PortalBuild b = pt::build_portal(w, pt::PortalOptions{64, 64, 1, false});
  PortalVulkanTracer gpu(ctx, b);
  glm::ivec3 g(-1);  // the first glass voxel
  for (int z = 0; z < int(w.dims.z) && g.x < 0; ++z)
    for (int y = 0; y < int(w.dims.y) && g.x < 0; ++y)
      for (int x = 0; x < int(w.dims.x) && g.x < 0; ++x)
        if (w.medium({x, y, z}) != pt::kEmpty && w.medium({x, y, z}) != pt::World::kOpaque) g = {x, y, z};
  REQUIRE(g.x >= 0);
  Camera cam = w.camera;
  cam.eye = w.to_world(glm::vec3(g) + 0.5f);
  cam.target = cam.eye + w.camera.target - w.camera.eye;
  pt::RenderOptions o;
  o.width = 32, o.height = 16;
  pt::RenderStats cs, gs;
  const std::vector<glm::vec3> cpu = pt::render(b, cam, o, &cs);
  const std::vector<glm::vec3> img = gpu.render(cam, o, &gs);
  CHECK(cs.refractions + cs.reflections >= uint64_t(o.width) * o.height);  // every ray leaves the glass
  CHECK(gs.refractions == cs.refractions);
  CHECK(gs.reflections == cs.reflections);
  size_t differ = 0;
  for (size_t i = 0; i < cpu.size(); ++i)
    for (int c = 0; c < 3; ++c) differ += std::abs(cpu[i][c] - img[i][c]) > 1e-5f * std::max(1.0f, std::abs(cpu[i][c]));
  CHECK(differ == 0);
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Portal Vulkan: hit records identical to portal-cpu on the built-in level", "[vulkan][portal][diff]") {
  check_trace(builtin_build(), 11, 3000);
}

TEST_CASE("Portal Vulkan: hit records identical to portal-cpu on a voxelized teapot", "[vulkan][portal][diff]") {
  check_trace(teapot_build(), 12, 3000);
}

namespace {

void check_render(const pt::PortalBuild& b, bool has_glass, uint32_t max_interfaces = 32) {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  PortalVulkanTracer gpu(ctx, b);
  REQUIRE(gpu.name() == "portal-vulkan");
  pt::RenderOptions o;
  o.width = 160, o.height = 80;
  o.max_interfaces = max_interfaces;
  for (bool refraction : {true, false}) {
    o.refraction = refraction;
    INFO("refraction " << refraction);
    o.state_machine = true;
    pt::RenderStats cs, gs, ls;
    const std::vector<glm::vec3> cpu = pt::render(b, b.world.camera, o, &cs);
    const std::vector<glm::vec3> fsm = gpu.render(b.world.camera, o, &gs);
    const std::vector<shared::PortalPixel> pixels = gpu.last_pixels();
    o.state_machine = false;
    const std::vector<glm::vec3> loops = gpu.render(b.world.camera, o, &ls);
    // FSM == separate loops on the GPU: the same transitions, so the same bits (any device).
    REQUIRE(std::memcmp(fsm.data(), loops.data(), fsm.size() * sizeof(glm::vec3)) == 0);
    CHECK(gs.loop_iterations == ls.loop_iterations);
    CHECK(gs.primary_steps == ls.primary_steps);
    CHECK(gs.shadow_steps == ls.shadow_steps);
    // GPU == CPU: every statistic, and every pixel that saw no glass, in bits (lavapipe).
    size_t glass = 0, differ = 0, differ_glass = 0;
    float max_rel = 0.0f;
    for (size_t i = 0; i < cpu.size(); ++i) {
      const bool saw_glass = pixels[i].refractions + pixels[i].reflections > 0;
      // a ray is given up at its (max_interfaces + 1)-th glass interface
      if (pixels[i].refractions + pixels[i].reflections > max_interfaces) FAIL("pixel " << i << " past the interface limit");
      glass += saw_glass;
      const bool same = std::memcmp(&cpu[i], &fsm[i], sizeof(glm::vec3)) == 0;
      if (same) continue;
      for (int c = 0; c < 3; ++c)
        max_rel = std::max(max_rel, std::abs(cpu[i][c] - fsm[i][c]) / std::max(std::abs(cpu[i][c]), 1e-6f));
      if (saw_glass) ++differ_glass;
      else ++differ;
      if (bit_exact_device(ctx) && !saw_glass) {
        INFO("pixel (" << i % o.width << ", " << i / o.width << "): cpu " << hex(cpu[i].x) << " " << hex(cpu[i].y)
                       << " " << hex(cpu[i].z) << " gpu " << hex(fsm[i].x) << " " << hex(fsm[i].y) << " "
                       << hex(fsm[i].z));
        REQUIRE(same);
      }
    }
    WARN("render " << o.width << "x" << o.height << " refraction " << refraction << ": " << glass
                   << " pixels saw glass, " << differ_glass << " of them differ from the CPU (pow), " << differ
                   << " other pixels differ; largest relative difference " << max_rel);
    if (bit_exact_device(ctx)) {
      CHECK(cs.primary_steps == gs.primary_steps);
      CHECK(cs.shadow_steps == gs.shadow_steps);
      CHECK(cs.shadow_rays == gs.shadow_rays);
      CHECK(cs.loop_iterations == gs.loop_iterations);
      CHECK(cs.refractions == gs.refractions);
      CHECK(cs.reflections == gs.reflections);
      CHECK(max_rel <= 1e-5f);
    } else {
      CHECK(differ <= cpu.size() / 100);
    }
    if (refraction && has_glass) {
      CHECK(glass > 0);
      CHECK(gs.refractions > 0);
      CHECK(gs.reflections > 0);  // total internal reflection
    }
    if (!refraction) CHECK(glass == 0);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

}  // namespace

TEST_CASE("Portal Vulkan: the render equals the CPU render - state machine == separate loops", "[vulkan][portal][diff]") {
  SECTION("the built-in level") { check_render(builtin_build(), false); }
  SECTION("a glass block in a room (refraction, total internal reflection)") {
    const pt::World w =
        pt::parse_tile_map("size 9 5 3\nmap\n111111111\n1.......1\n1E..GG..1\n1.......1\n111111111\n", "glass");
    check_render(pt::build_portal(w, pt::PortalOptions{64, 64, 1, false}), true);
  }
  SECTION("two glasses touching (the medium entered decides the refraction and the filter)") {
    check_render(pt::build_portal(two_glasses(), pt::PortalOptions{64, 64, 1, false}), true);
  }
  SECTION("the glass block with at most two interfaces a ray (the limit reached: given up black)") {
    const pt::World w =
        pt::parse_tile_map("size 9 5 3\nmap\n111111111\n1.......1\n1E..GG..1\n1.......1\n111111111\n", "glass");
    check_render(pt::build_portal(w, pt::PortalOptions{64, 64, 1, false}), true, 2);
  }
}

TEST_CASE("Portal Vulkan: explain shows the shader's own record, as the reference's", "[vulkan][portal][diff]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const pt::PortalBuild& b = builtin_build();
  PortalVulkanTracer gpu(ctx, b);
  for (uint32_t x : {10u, 70u, 150u}) {
    const Ray r = camera_ray(b.world.camera, 160, 80, x, 40);
    const vulkan::PortalExplainRecord rec = gpu.explain_ray(r);
    const Hit cpu = pt::trace_portal(b.packed, r);
    REQUIRE(rec.events.size() == size_t(cpu.cells) + 1);  // the start, then one per div
    const std::string text = gpu.explain(r);
    INFO(text);
    CHECK(text.find("they part") == std::string::npos);
    CHECK(text.find("exits by") != std::string::npos);
    if (bit_exact_device(ctx)) CHECK(text.find("identical in bits") != std::string::npos);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Portal Vulkan: hit records identical to portal-cpu on a generated level, both div choices",
          "[vulkan][portal][diff]") {
  const pt::World w = pt::generated_level_spec("gen:48x40x5:7");
  for (const pt::DivChoice choice : {pt::DivChoice::bounded, pt::DivChoice::exact}) {
    pt::PortalOptions o{1024, 1024, 0, false};
    o.choice = choice;
    INFO(pt::div_choice_name(choice));
    check_trace(pt::build_portal(w, o), 13, 1000);
  }
}

TEST_CASE("Portal Vulkan: gridrt portal diff - exit 0 when the two agree, 1 bad input, 2 bad command line",
          "[vulkan][portal][diff][cli]") {
  const Run ok = run_tool("portal diff gen:24x16x3 --width 32 --height 16");
  INFO(ok.output);
  CHECK(ok.exit_code == 0);
  CHECK_THAT(ok.output, Catch::Contains("512 of 512 identical in bits"));
  CHECK_THAT(ok.output, Catch::Contains("agree"));
  const Run bad = run_tool("portal diff gen:24x16 --width 32 --height 16");
  INFO(bad.output);
  CHECK(bad.exit_code == 1);
  CHECK_THAT(bad.output, Catch::Contains("gen:WIDTHxDEPTHxHEIGHT"));
  const Run cmd = run_tool("portal diff --width 0");
  CHECK(cmd.exit_code == 2);
}

namespace {

// Mip-mapped space (docs/PORTAL.md): the built-in level with three levels and a short level
// distance, so that camera rays go coarse and meet translucent coarse voxels (and none reaches
// the glass at full resolution).
const pt::PortalBuild& builtin_mip_build() {
  static const pt::PortalBuild b = [] {
    pt::PortalOptions o{1024, 1024, 0, false};
    o.mip_levels = 3;
    o.mip_distance = 1.0f;
    return pt::build_portal(pt::builtin_level(), o);
  }();
  return b;
}

}  // namespace

TEST_CASE("Portal Vulkan: mip-mapped space - records, render and explain as portal-cpu's", "[vulkan][portal][diff][mip]") {
  const pt::PortalBuild& b = builtin_mip_build();
  // Both kinds of coarse surface are met by these rays (translucent and opaque, resolved).
  size_t translucent = 0;
  for (const Ray& r : test_rays(b.world, 23, 300)) {
    const Hit h = pt::trace_portal(b.packed, r);
    translucent += !is_miss(h) && h.instance < b.world.materials.size() && b.world.materials[h.instance].coverage < 1.0f;
  }
  CHECK(translucent > 20);
  check_trace(b, 23, 300);
  check_render(b, false);
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  PortalVulkanTracer gpu(ctx, b);
  for (uint32_t x : {20u, 80u, 140u}) {
    const std::string text = gpu.explain(camera_ray(b.world.camera, 160, 80, x, 40));
    INFO(text);
    CHECK(text.find("they part") == std::string::npos);
    if (bit_exact_device(ctx)) CHECK(text.find("identical in bits") != std::string::npos);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Portal Vulkan: instanced subspaces - records, render and explain as portal-cpu's", "[vulkan][portal][diff][instance]") {
  // The built-in block level: rays enter instances through tile faces, cross block divs and leave
  // back to the top level; rays also start inside instances (random origins anywhere in the box).
  const pt::PortalBuild b = pt::build_instanced(pt::builtin_blocks(), pt::PortalOptions{1024, 1024, 0, false});
  check_trace(b, 31, 800);
  std::mt19937 rng(32);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  std::vector<Ray> rays;
  const glm::vec3 ext(b.world.dims);
  for (int i = 0; i < 2000; ++i)
    rays.push_back(make_ray(glm::vec3(U(rng), U(rng), U(rng)) * ext, glm::vec3(U(rng), U(rng), U(rng)) * 2.0f - 1.0f,
                            0.0f, i % 3 ? INFINITY : U(rng) * 2.0f));
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  PortalVulkanTracer gpu(ctx, b);
  std::vector<Hit> c(rays.size()), g(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) c[i] = pt::trace_portal(b.packed, rays[i]);
  gpu.trace(rays, g);
  require_same_hits(rays, c, g, bit_exact_device(ctx));
  check_render(b, false);
  bool entered = false, left = false;
  for (uint32_t x = 0; x < 160 && !(entered && left); x += 7) {
    const std::string text = gpu.explain(camera_ray(b.world.camera, 160, 80, x, 30));
    INFO(text);
    CHECK(text.find("they part") == std::string::npos);
    if (bit_exact_device(ctx)) CHECK(text.find("identical in bits") != std::string::npos);
    entered |= text.find("enter instance") != std::string::npos;
    left |= text.find("leave instance") != std::string::npos;
  }
  CHECK(entered);
  CHECK(left);
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
  // The tool: portal diff on an instanced world agrees, and --flat-compare finds no pixel differing.
  const Run ok = run_tool("portal diff builtin:blocks --width 32 --height 16");
  INFO(ok.output);
  CHECK(ok.exit_code == 0);
  CHECK_THAT(ok.output, Catch::Contains("512 of 512 identical in bits"));
}
