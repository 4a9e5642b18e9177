// test_portal_mip.cpp: mip-mapped space of the portal tracer ("A Novel Raytracing Algorithm for GPU",
// docs/PORTAL.md, "Mip-mapped space") against independent truths: the full-resolution tracer where
// the level rule never leaves level 0 and where every coarse voxel is empty or opaque (then the
// return to full resolution must give the very same hits and image), and coverage counted voxel
// by voxel for a translucent coarse voxel.
#include <catch2/catch.hpp>
#include <cstring>
#include <random>

#include "gridrt/common/camera.h"
#include "gridrt/reference/portal/build.h"
#include "gridrt/reference/portal/trace.h"
#include "gridrt/reference/portal/world.h"

using namespace gridrt;
using namespace gridrt::portal;

namespace {

Ray ray_of(glm::vec3 o, glm::vec3 d) {
  Ray r{};
  r.org = o, r.dir = d, r.tmin = 0.0f, r.tmax = std::numeric_limits<float>::infinity();
  r.launch_normal = glm::vec3(0.0f);
  r.launch_ref = shared::kNoRef;
  return r;
}

// Every voxel of `w` as a 2 x 2 x 2 block (voxel size halved: the same world in world space).
World doubled(const World& w) {
  World d = w;
  d.dims = w.dims * 2u;
  d.voxel_size = w.voxel_size * 0.5f;
  d.voxels.assign(d.voxel_count(), kEmpty);
  for (uint32_t z = 0; z < d.dims.z; ++z)
    for (uint32_t y = 0; y < d.dims.y; ++y)
      for (uint32_t x = 0; x < d.dims.x; ++x) d.voxels[d.index(x, y, z)] = w.voxels[w.index(x / 2, y / 2, z / 2)];
  return d;
}

// Random occupancy with probability `fill`, two materials.
World random_world(glm::uvec3 dims, float fill, uint32_t seed) {
  World w;
  w.name = "random";
  w.dims = dims;
  w.materials = {{"a", glm::vec3(1, 0.5f, 0)}, {"b", glm::vec3(0, 0.5f, 1)}};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  w.voxels.resize(w.voxel_count());
  for (auto& v : w.voxels) v = U(rng) < fill ? uint16_t(rng() % 2) : kEmpty;
  return w;
}

PortalOptions mip_options(uint32_t levels, float distance) {
  PortalOptions o{1024, 1024, 0, false};
  o.mip_levels = levels;
  o.mip_distance = distance;
  return o;
}

// Camera rays and random rays from empty voxels.
std::vector<Ray> rays_of(const World& w, uint32_t width, uint32_t height, size_t random) {
  std::vector<Ray> rays;
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x) rays.push_back(camera_ray(w.camera, width, height, x, y));
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  while (rays.size() < size_t(width) * height + random) {
    const glm::ivec3 v(rng() % w.dims.x, rng() % w.dims.y, rng() % w.dims.z);
    if (w.solid(v)) continue;
    const glm::vec3 d = glm::vec3(U(rng), U(rng), U(rng)) * 2.0f - 1.0f;
    if (glm::length(d) < 0.1f) continue;
    rays.push_back(ray_of(w.to_world(glm::vec3(v) + glm::vec3(U(rng), U(rng), U(rng))), d));
  }
  return rays;
}

}  // namespace

TEST_CASE("Portal mip: beyond the level distance nothing changes - records and render as full resolution, in bits",
          "[portal][mip]") {
  // The built-in level (with glass) and three levels, but a distance no ray reaches: level 0 only.
  const PortalBuild full = build_portal(builtin_level(), PortalOptions{1024, 1024, 0, false});
  const PortalBuild mip = build_portal(builtin_level(), mip_options(3, 1e6f));
  REQUIRE(mip.packed.levels == 3);
  REQUIRE(mip.packed.div_count > full.packed.div_count);  // the coarse levels' divs are there
  for (const Ray& r : rays_of(full.world, 48, 24, 500)) {
    const Hit a = trace_portal(full.packed, r), b = trace_portal(mip.packed, r);
    REQUIRE(std::memcmp(&a, &b, sizeof(Hit)) == 0);
  }
  RenderOptions o;
  o.width = 96, o.height = 48, o.threads = 2;
  RenderStats sa, sb;
  const auto ia = render(full, full.world.camera, o, &sa), ib = render(mip, mip.world.camera, o, &sb);
  REQUIRE(std::memcmp(ia.data(), ib.data(), ia.size() * sizeof(glm::vec3)) == 0);
  CHECK(sa.primary_steps == sb.primary_steps);
  CHECK(sa.shadow_steps == sb.shadow_steps);
}

TEST_CASE("Portal mip: where every coarse voxel is empty or opaque, the return to full resolution gives the same hits",
          "[portal][mip]") {
  // A sparse random world (many small divs: rays cross many) with every voxel doubled: level 1's
  // voxels are the original voxels, each empty or entirely wall. The mip tracer must hit exactly
  // what full resolution hits (t, material, voxel, face, u, v in bits) and render the same image.
  // (Not in fewer steps: level 1's divs are the same boxes as level 0's here.)
  World w = doubled(random_world(glm::uvec3(20, 12, 20), 0.04f, 3));
  w.camera.eye = w.to_world(glm::vec3(1.0f, 12.0f, 1.0f));
  w.camera.target = w.to_world(glm::vec3(40.0f, 10.0f, 40.0f));
  w.lights = {w.to_world(glm::vec3(20.5f, 22.5f, 3.5f)), w.to_world(glm::vec3(3.5f, 20.5f, 30.5f))};
  const PortalBuild full = build_portal(w, PortalOptions{1024, 1024, 0, false});
  const PortalBuild mip = build_portal(w, mip_options(2, 2.0f));
  for (const WallMaterial& m : mip.world.materials) CHECK(m.coverage == 1.0f);
  uint64_t steps_full = 0, steps_mip = 0;
  size_t hits = 0;
  for (const Ray& r : rays_of(w, 48, 24, 1000)) {
    const Hit a = trace_portal(full.packed, r), b = trace_portal(mip.packed, r);
    INFO("org " << r.org.x << " " << r.org.y << " " << r.org.z << " dir " << r.dir.x << " " << r.dir.y << " " << r.dir.z);
    REQUIRE(a.instance == b.instance);
    REQUIRE(a.triangle == b.triangle);
    REQUIRE(std::memcmp(&a.t, &b.t, 4) == 0);
    REQUIRE(std::memcmp(&a.u, &b.u, 4) == 0);
    REQUIRE(std::memcmp(&a.v, &b.v, 4) == 0);
    steps_full += a.cells, steps_mip += b.cells, hits += !is_miss(a);
  }
  CHECK(hits > 500);
  CHECK(steps_mip != steps_full);  // the rays did go coarse
  RenderOptions o;
  o.width = 96, o.height = 48, o.threads = 2;
  RenderStats sa, sb;
  const auto ia = render(full, w.camera, o, &sa), ib = render(mip, w.camera, o, &sb);
  REQUIRE(std::memcmp(ia.data(), ib.data(), ia.size() * sizeof(glm::vec3)) == 0);
  CHECK(sb.primary_steps != sa.primary_steps);
}

TEST_CASE("Portal mip: a partly occupied coarse voxel is the first surface, with its coverage counted voxel by voxel",
          "[portal][mip]") {
  // 8 x 8 x 8 voxels, a wall at x = 2 with a 2 x 2 window at y, z in {3, 4}. A ray along +x through
  // the window from x = 0.5 crosses x = 2 at distance 1.5; with distance 0.5, level 1 starts at 1
  // voxel, and x = 2 is a plane of level 1: the coarse voxel (1, 2, 2) holds fine x in {2, 3},
  // y, z in {4, 5}, of which (2,4,5), (2,5,4), (2,5,5) are wall: coverage 3/8, translucent.
  World w;
  w.name = "window";
  w.dims = glm::uvec3(8);
  w.materials = {{"wall", glm::vec3(0.5f, 0.25f, 1.0f)}};
  w.voxels.assign(w.voxel_count(), kEmpty);
  for (uint32_t z = 0; z < 8; ++z)
    for (uint32_t y = 0; y < 8; ++y)
      if (!(y >= 3 && y <= 4 && z >= 3 && z <= 4)) w.voxels[w.index(2, y, z)] = 0;
  const PortalBuild mip = build_portal(w, mip_options(2, 0.5f));
  const Ray r = ray_of(glm::vec3(0.5f, 4.25f, 4.25f), glm::vec3(1, 0, 0));
  const Hit h = trace_portal(mip.packed, r);
  REQUIRE_FALSE(is_miss(h));
  CHECK(h.t == 1.5f);
  REQUIRE(h.instance >= 1);  // a coarse material
  const WallMaterial& m = mip.world.materials[h.instance];
  CHECK(m.coverage == 3.0f / 8.0f);
  CHECK_FALSE(m.resolve);
  CHECK(m.color == w.materials[0].color);
  CHECK(hit_voxel(mip.world, h) == glm::ivec3(2, 4, 4));  // the fine voxel beyond the plane: the window
  // Full resolution: through the window, nothing behind: a miss.
  const PortalBuild full = build_portal(w, PortalOptions{1024, 1024, 0, false});
  CHECK(is_miss(trace_portal(full.packed, r)));
  // The explanation names the move and the coarse surface.
  const std::string text = explain_portal(mip.packed, mip.world, r);
  CHECK_THAT(text, Catch::Contains("mip: level 1 from here"));
  CHECK_THAT(text, Catch::Contains("translucent"));
}

TEST_CASE("Portal mip: bad options are a clear Error", "[portal][mip][badinput]") {
  auto msg = [](PortalOptions o) {
    try {
      build_portal(builtin_level(), o);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CHECK_THAT(msg(mip_options(5, 10.0f)), Catch::Contains("levels"));
  CHECK_THAT(msg(mip_options(2, 0.0f)), Catch::Contains("distance"));
  CHECK_THAT(msg(mip_options(2, std::numeric_limits<float>::quiet_NaN())), Catch::Contains("distance"));
}
