// test_vulkan_grid.cpp: the Vulkan grid against the CPU reference, on lavapipe with the
// validation layer on (docs/VULKAN.md):
//  - sorted images identical texel for texel, geometry buffers identical in bits;
//  - first-empty images identical per cell as multisets where unsaturated, a flagged choice of
//    the candidates where saturated;
//  - the raster build (geometry shader) and the compute build give the same images;
//  - every hit record identical in bits (t, ids, barycentrics, flags, cells, tests), in paper and
//    exact modes, with alpha keying and gap-fill, after several animated frames;
//  - the explained ray leaves the same events as the reference's explain.
// Every mismatch prints the index, the ray and both records as hex bits.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <random>
#include <sstream>

#include "gridrt/reference/compare.h"
#include "tests/test_grid_util.h"
#include "tests/run_tool.h"
#include "tests/vulkan_test_util.h"
#include "gridrt/vulkan/grid.h"
#include "gridrt/vulkan/frame.h"

using namespace gridrt;
using namespace gridrt::test;
using gridrt::vulkan::BuildMode;
using gridrt::vulkan::VulkanGridTracer;
using reference::GridOptions;
using reference::ReferenceGridTracer;
namespace sh = gridrt::shared;

namespace {

// Random triangles, a dynamic instance that moves, and alpha-keyed quads with a checkerboard mask
// (alpha 0 and 255 in 4x4 blocks of an 16x16 texture), static and dynamic.
Scene test_scene(uint32_t seed, bool alpha = true) {
  Scene s = gridtest::random_scene(300, 0.7f, 10.0f, seed, 60);
  if (!alpha) return s;
  Texture tex;
  tex.width = tex.height = 16;
  tex.rgba.resize(16 * 16 * 4);
  for (uint32_t y = 0; y < 16; ++y)
    for (uint32_t x = 0; x < 16; ++x) {
      uint8_t* p = &tex.rgba[(y * 16 + x) * 4];
      p[0] = p[1] = p[2] = 200;
      p[3] = ((x / 4 + y / 4) % 2) ? 255 : 0;
    }
  tex.has_alpha = true;
  s.textures.push_back(tex);
  if (s.materials.empty()) s.materials.push_back(Material{.name = "default"});
  s.materials.push_back(Material{.name = "leaves", .alpha_texture = 0});
  Mesh quads;
  quads.name = "leaves";
  std::mt19937 rng(seed + 99);
  std::uniform_real_distribution<float> pos(1.0f, 9.0f), uvr(-2.0f, 2.0f);
  for (uint32_t q = 0; q < 12; ++q) {
    const glm::vec3 c(pos(rng), pos(rng), pos(rng));
    const uint32_t b = uint32_t(quads.positions.size());
    const glm::vec3 a = glm::normalize(glm::vec3(uvr(rng), uvr(rng), uvr(rng))) * 1.5f;
    const glm::vec3 bb = glm::normalize(glm::cross(a, glm::vec3(0.3f, 1.0f, 0.1f))) * 1.5f;
    quads.positions.insert(quads.positions.end(), {c - a - bb, c + a - bb, c + a + bb, c - a + bb});
    const glm::vec2 o(uvr(rng), uvr(rng));
    quads.uvs.insert(quads.uvs.end(), {o, o + glm::vec2(3.0f, 0.0f), o + glm::vec2(3.0f, 3.0f), o + glm::vec2(0.0f, 3.0f)});
    quads.triangles.push_back({b, b + 1, b + 2});
    quads.triangles.push_back({b, b + 2, b + 3});
  }
  quads.materials.assign(quads.triangles.size(), 1u);
  s.meshes.push_back(quads);
  s.instances.push_back(Instance{.name = "leaves", .mesh = uint32_t(s.meshes.size() - 1)});
  Instance moving{.name = "leaves-moving", .mesh = uint32_t(s.meshes.size() - 1), .dynamic = true};
  moving.motion.axis = {0.0f, 1.0f, 0.0f};
  moving.motion.pivot = glm::vec3(5.0f);
  moving.motion.angular_speed = 0.9f;
  s.instances.push_back(moving);
  s.finalize();
  return s;
}

// Camera rays (a 96x64 image from outside the box), random rays through the box, and secondary
// rays leaving the primary hits (launch normal and reference set: self-hit and gap-fill logic).
std::vector<Ray> test_rays(const ReferenceGridTracer& ref, uint32_t seed) {
  std::vector<Ray> rays;
  const glm::vec3 eye(-6.0f, 13.0f, -7.0f), target(5.0f, 4.5f, 5.0f);
  const glm::vec3 f = glm::normalize(target - eye), r = glm::normalize(glm::cross(f, glm::vec3(0, 1, 0))),
                  u = glm::cross(r, f);
  for (uint32_t y = 0; y < 64; ++y)
    for (uint32_t x = 0; x < 96; ++x) {
      const float px = (float(x) + 0.5f) / 96.0f * 2.0f - 1.0f, py = 1.0f - (float(y) + 0.5f) / 64.0f * 2.0f;
      rays.push_back(gridtest::make_ray(eye, f + 0.75f * px * r + 0.5f * py * u));
    }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> p(-1.0f, 11.0f), d(-1.0f, 1.0f);
  for (uint32_t i = 0; i < 1500; ++i) {
    glm::vec3 dir(d(rng), d(rng), d(rng));
    if (glm::dot(dir, dir) < 1e-4f) dir = {0.0f, 0.0f, 1.0f};
    rays.push_back(gridtest::make_ray({p(rng), p(rng), p(rng)}, dir, 0.0f, (i % 3) ? INFINITY : 4.0f));
  }
  // Far rays: origins about 1e7 away (an ulp of t is about 1, so a segment's midpoint rounds onto
  // its ends: where gap-fill's "inside the ray" test is decided by its strict comparisons)
  for (uint32_t i = 0; i < 500; ++i) {
    glm::vec3 away(d(rng), d(rng), d(rng));
    if (glm::dot(away, away) < 1e-4f) away = {1.0f, 0.0f, 0.0f};
    const glm::vec3 at(p(rng), p(rng), p(rng));
    const glm::vec3 org = at + glm::normalize(away) * 1.0e7f;
    rays.push_back(gridtest::make_ray(org, glm::normalize(at - org)));
  }
  // Secondary rays from the reference's primary hits
  std::vector<Hit> hits(rays.size());
  const size_t primary = rays.size();
  std::vector<Ray> first(rays.begin(), rays.begin() + 96 * 64);
  hits.resize(first.size());
  const_cast<ReferenceGridTracer&>(ref).trace(first, hits);
  const reference::GridData& g = ref.data();
  for (size_t i = 0; i < first.size() && rays.size() < primary + 1500; i += 3) {
    const Hit& h = hits[i];
    if (is_miss(h) || (h.flags & sh::kHitGapFill)) continue;
    const sh::GridTriangle& t = g.triangles[g.instances[h.instance].tri_offset + h.triangle];
    glm::vec3 n = sh::triangle_normal(t.v0, t.v1, t.v2);
    if (glm::dot(n, first[i].dir) > 0.0f) n = -n;
    Ray s = gridtest::make_ray(first[i].org + first[i].dir * h.t, glm::reflect(first[i].dir, glm::normalize(n)));
    s.launch_normal = n;
    s.launch_ref = sh::ref_pack(h.instance, h.triangle);
    rays.push_back(s);
  }
  return rays;
}

std::string hex_hit(const Hit& h) {
  std::ostringstream os;
  os << "t " << hex(h.t) << " inst " << h.instance << " tri " << h.triangle << " u " << hex(h.u) << " v "
     << hex(h.v) << " flags " << h.flags << " cells " << h.cells << " tests " << h.tests;
  return os.str();
}
std::string hex_ray(const Ray& r) {
  std::ostringstream os;
  os << "org (" << hex(r.org.x) << ", " << hex(r.org.y) << ", " << hex(r.org.z) << ") dir (" << hex(r.dir.x) << ", "
     << hex(r.dir.y) << ", " << hex(r.dir.z) << ") tmin " << hex(r.tmin) << " tmax " << hex(r.tmax) << " launch ref "
     << hex(r.launch_ref);
  return os.str();
}

// How two tracers' hit records agree.
struct HitAgreement {
  size_t rays = 0;
  size_t bit_different = 0;   // any bit of the record
  size_t hit_different = 0;   // instance, triangle or flags
  size_t stats_different = 0; // cells or tests, same hit
  double max_t_rel = 0.0;     // same hit: |dt| / max(1, |t|)
  double max_uv_abs = 0.0;    // same hit: |du|, |dv|
};

HitAgreement compare_hits(std::span<const Ray> rays, std::span<const Hit> want, std::span<const Hit> got,
                          bool report_bits) {
  HitAgreement a;
  a.rays = rays.size();
  for (size_t i = 0; i < rays.size(); ++i) {
    const Hit& w = want[i];
    const Hit& g = got[i];
    if (std::memcmp(&w, &g, sizeof(Hit)) == 0) continue;
    ++a.bit_different;
    const bool same_hit = w.instance == g.instance && w.triangle == g.triangle && w.flags == g.flags;
    if (same_hit) {
      a.stats_different += w.cells != g.cells || w.tests != g.tests;
      a.max_t_rel = std::max(a.max_t_rel, std::abs(double(w.t) - double(g.t)) / std::max(1.0, std::abs(double(w.t))));
      a.max_uv_abs = std::max({a.max_uv_abs, std::abs(double(w.u) - double(g.u)), std::abs(double(w.v) - double(g.v))});
    } else {
      ++a.hit_different;
    }
    if ((report_bits ? a.bit_different : a.hit_different) <= 5 && (report_bits || !same_hit))
      UNSCOPED_INFO("ray " << i << ": " << hex_ray(rays[i]) << "\n  reference " << hex_hit(w) << "\n  vulkan    "
                           << hex_hit(g));
  }
  return a;
}

// lavapipe and NVIDIA (bit_exact_hits_device): every hit record identical in bits. Other devices
// (docs/VULKAN.md): at most 1 % of the rays find another hit, and the same hits agree within a
// relative 1e-5 in t and 1e-3 in u, v.
void check_hits(const vulkan::Context& ctx, std::span<const Ray> rays, std::span<const Hit> want,
                std::span<const Hit> got) {
  const bool exact = bit_exact_hits_device(ctx);
  const HitAgreement a = compare_hits(rays, want, got, exact);
  if (exact) {
    CHECK(a.bit_different == 0);
    return;
  }
  WARN(ctx.info().name << ": " << a.bit_different << " of " << a.rays << " hit records differ in bits; "
                       << a.hit_different << " find another hit, " << a.stats_different
                       << " the same hit with other cells/tests; largest relative t difference " << a.max_t_rel
                       << ", largest u/v difference " << a.max_uv_abs);
  CHECK(a.hit_different * 100 <= a.rays);
  CHECK(a.max_t_rel <= 1e-5);
  CHECK(a.max_uv_abs <= 1e-3);
}

size_t compare_texels(const AccelDump& want, const AccelDump& got) {
  REQUIRE(want.extent == got.extent);
  REQUIRE(want.texels.size() == got.texels.size());
  size_t bad = 0;
  for (size_t i = 0; i < want.texels.size(); ++i)
    if (want.texels[i] != got.texels[i] && ++bad <= 5)
      UNSCOPED_INFO("texel " << i << " (x " << i % want.extent.x << ", y " << (i / want.extent.x) % want.extent.y
                             << ", z " << i / (size_t(want.extent.x) * want.extent.y) << "): reference "
                             << hex(want.texels[i]) << " vulkan " << hex(got.texels[i]));
  return bad;
}

size_t compare_triangles(const std::vector<sh::GridTriangle>& want, const std::vector<sh::GridTriangle>& got) {
  REQUIRE(want.size() == got.size());
  size_t bad = 0;
  for (size_t i = 0; i < want.size(); ++i) {
    const glm::vec3 a[3] = {want[i].v0, want[i].v1, want[i].v2}, b[3] = {got[i].v0, got[i].v1, got[i].v2};
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c)
        if (bits(a[k][c]) != bits(b[k][c]) && ++bad <= 5)
          UNSCOPED_INFO("triangle " << i << " vertex " << k << " axis " << c << ": reference " << hex(a[k][c])
                                    << " vulkan " << hex(b[k][c]));
    if (want[i].material != got[i].material && ++bad <= 5) UNSCOPED_INFO("triangle " << i << ": material differs");
  }
  return bad;
}

// The plane buffer, bit for bit. Returns the number of differing planes.
size_t compare_planes(const std::vector<sh::GridPlane>& want, const std::vector<sh::GridPlane>& got) {
  REQUIRE(want.size() == got.size());
  size_t bad = 0;
  for (size_t i = 0; i < want.size(); ++i) {
    const float a[4] = {want[i].n.x, want[i].n.y, want[i].n.z, want[i].scale};
    const float b[4] = {got[i].n.x, got[i].n.y, got[i].n.z, got[i].scale};
    for (int c = 0; c < 4; ++c)
      if (bits(a[c]) != bits(b[c]) && ++bad <= 5)
        UNSCOPED_INFO("plane " << i << " component " << c << ": reference " << hex(a[c]) << " vulkan " << hex(b[c]));
  }
  return bad;
}

// First-empty: unsaturated cells hold exactly their candidates; saturated ones `capacity` of them,
// flagged (reference::check_cells_as_multisets). Returns the number of bad cells; counts saturated
// cells.
size_t check_first_empty(const reference::GridData& grid, const AccelDump& got, size_t* saturated) {
  const reference::CellCheck c = reference::check_cells_as_multisets(grid, got);
  *saturated = c.saturated;
  const sh::GridParams& g = grid.params;
  for (size_t k = 0; k < c.bad.size() && k < 5; ++k)
    UNSCOPED_INFO("cell (" << c.bad[k] % g.cells.x << ", " << (c.bad[k] / g.cells.x) % g.cells.y << ", "
                           << c.bad[k] / (size_t(g.cells.x) * g.cells.y) << ") breaks the multiset rule");
  return c.bad.size();
}

std::vector<uint32_t> sorted(std::vector<uint32_t> v) {
  std::sort(v.begin(), v.end());
  return v;
}

GridOptions options(reference::Insertion insertion, reference::Traversal traversal, uint32_t capacity) {
  GridOptions o;
  o.insertion = insertion;
  o.traversal = traversal;
  o.threads = 2;
  o.capacity = capacity;  // small: some cells saturate (gap-fill, first-empty choices)
  return o;
}

}  // namespace

// Caps (three vertices nearly on a line: the third at the rounded midpoint of the other two, moved
// by a few ulps) make the plane's normal again from the exact edges (plane_normal_scaled): the
// plane buffer the build writes must hold the reference's bits there too, static and dynamic, after
// updates, and the trace that reads it the reference's hits.
TEST_CASE("Vulkan grid: the plane buffer identical bit for bit, caps' refined normals included, through updates",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  Scene scene = gridtest::random_scene(240, 0.7f, 10.0f, 17, 60);
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> nudge(-4, 4);
  for (Mesh& m : scene.meshes)
    for (size_t i = 0; 3 * i + 2 < m.positions.size(); i += 2) {
      const glm::vec3 mid = (m.positions[3 * i] + m.positions[3 * i + 1]) * 0.5f;
      glm::vec3 v = mid;
      for (int c = 0; c < 3; ++c)
        for (int k = nudge(rng); k != 0; k += k > 0 ? -1 : 1) v[c] = std::nextafter(v[c], k > 0 ? INFINITY : -INFINITY);
      m.positions[3 * i + 2] = v;
    }
  scene.finalize();
  const GridOptions o = options(reference::Insertion::sorted, reference::Traversal::exact, 8);  // the watertight test
  ReferenceGridTracer ref(o);
  ref.build(scene, 0.0f);
  // Caps are there: planes whose scale shrank below the unrefined cross product's rounding scale
  size_t refined = 0;
  for (size_t k = 0; k < ref.data().triangles.size(); ++k) {
    const sh::GridTriangle& t = ref.data().triangles[k];
    const sh::GridPlane& p = ref.data().planes[k];
    const sh::GridPlane q = sh::triangle_plane(t.v0, t.v1, t.v2);
    CHECK((bits(p.n.x) == bits(q.n.x) && bits(p.n.y) == bits(q.n.y) && bits(p.n.z) == bits(q.n.z) &&
           bits(p.scale) == bits(q.scale)));
    const float s = std::min({sh::plane_normal_scale(t.v1 - t.v0, t.v2 - t.v1), sh::plane_normal_scale(t.v2 - t.v1, t.v0 - t.v2),
                              sh::plane_normal_scale(t.v0 - t.v2, t.v1 - t.v0)});
    if (p.scale < 0.5f * s) ++refined;
  }
  CHECK(refined > 100);
  const std::vector<Ray> rays = gridtest::box_rays(ref.data(), 3000, 10.0f, 23);
  for (BuildMode mode : {BuildMode::raster, BuildMode::compute}) {
    INFO((mode == BuildMode::raster ? "raster build" : "compute build"));
    VulkanGridTracer vk(ctx, o, {.build = mode});
    vk.build(scene, 0.0f);
    CHECK(compare_planes(ref.data().planes, vk.download_planes()) == 0);
    for (float time : {0.7f, 2.2f}) {
      INFO("after update to " << time);
      ReferenceGridTracer ref_t(o);
      ref_t.build(scene, 0.0f);
      ref_t.update(time);
      vk.update(time);
      CHECK(compare_planes(ref_t.data().planes, vk.download_planes()) == 0);
      CHECK(compare_triangles(ref_t.data().triangles, vk.download_triangles()) == 0);
      std::vector<Hit> want(rays.size()), got(rays.size());
      ref_t.trace(rays, want);
      vk.trace(rays, got);
      check_hits(ctx, rays, want, got);
      CHECK(std::count_if(want.begin(), want.end(), [](const Hit& h) { return !is_miss(h); }) > 100);
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan grid, sorted: images identical texel for texel, raster and compute builds, through updates",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = test_scene(3);
  const GridOptions o = options(reference::Insertion::sorted, reference::Traversal::paper, 5);
  ReferenceGridTracer ref(o);
  ref.build(scene, 0.0f);
  for (BuildMode mode : {BuildMode::raster, BuildMode::compute}) {
    INFO((mode == BuildMode::raster ? "raster build" : "compute build"));
    VulkanGridTracer vk(ctx, o, {.build = mode});
    vk.build(scene, 0.0f);
    CHECK(std::memcmp(&vk.params(), &ref.params(), sizeof(sh::GridParams)) == 0);
    const AccelDump want = ref.dump();
    CHECK(compare_texels(want, vk.dump()) == 0);
    CHECK(compare_triangles(ref.data().triangles, vk.download_triangles()) == 0);
    CHECK(sorted(vk.download_dirty_cells()) == sorted(reference::dirty_cells(ref.data())));
    // Saturated cells exist, static and dynamic
    const reference::GridStats stats = ref.stats();
    CHECK(stats.saturated_static > 0);
    CHECK(stats.saturated_dynamic > 0);
    for (float time : {0.4f, 1.3f, 2.9f}) {
      INFO("after update to " << time);
      ReferenceGridTracer ref_t(o);
      ref_t.build(scene, 0.0f);
      ref_t.update(time);
      vk.update(time);
      CHECK(compare_texels(ref_t.dump(), vk.dump()) == 0);
      CHECK(compare_triangles(ref_t.data().triangles, vk.download_triangles()) == 0);
      // The dirty-cell list: the same cells, each once (the order is the device's)
      const std::vector<uint32_t> listed = sorted(vk.download_dirty_cells());
      CHECK(!listed.empty());
      CHECK(std::adjacent_find(listed.begin(), listed.end()) == listed.end());
      CHECK(listed == sorted(reference::dirty_cells(ref_t.data())));
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

// The build's run list at its capacity (VulkanGridOptions::build_list_capacity): the room's 12
// walls over a 16^3 grid hand out R runs of 8 cells; a list of exactly R runs takes them all, one of
// R - 5 overflows within a triangle's runs (those that fit are listed, the rest walked by the
// triangle's invocation), one of R + 1 has a run to spare. Every item the list dispatches must be
// written: the images equal the reference's in every case, both builds.
TEST_CASE("Vulkan grid: a build run list filled exactly, overflowed within a triangle, or with room to spare",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  Scene scene;
  scene.name = "room";
  scene.meshes.push_back(gridtest::box_mesh(glm::vec3(0.0f), glm::vec3(8.0f)));
  scene.instances.push_back(Instance{.name = "room", .mesh = 0});
  scene.finalize();
  GridOptions o = options(reference::Insertion::sorted, reference::Traversal::paper, 4);
  o.resolution = glm::uvec3(16, 16, 16);
  ReferenceGridTracer ref(o);
  ref.build(scene, 0.0f);
  uint32_t runs = 0;
  for (const sh::GridTriangle& t : ref.data().triangles) {
    glm::uvec3 lo, hi;
    sh::triangle_cell_range(ref.params(), t.v0, t.v1, t.v2, lo, hi);
    const glm::uvec3 size = hi - lo + 1u;
    const uint32_t count = size.x * size.y * size.z;
    if (count > 8u) runs += (count + 7u) / 8u;
  }
  REQUIRE(runs > 100u);
  for (BuildMode mode : {BuildMode::raster, BuildMode::compute}) {
    if (mode == BuildMode::raster && (!ctx.info().geometry_shader || !ctx.info().vertex_pipeline_stores_and_atomics))
      continue;
    for (uint32_t capacity : {runs, runs - 5u, runs + 1u}) {
      INFO((mode == BuildMode::raster ? "raster build" : "compute build") << ", a list of " << capacity << " runs for "
                                                                           << runs);
      VulkanGridTracer vk(ctx, o, {.build = mode, .build_list_capacity = capacity});
      vk.build(scene, 0.0f);
      CHECK(vk.download_build_runs() == std::min(runs, capacity));
      CHECK(compare_texels(ref.dump(), vk.dump()) == 0);
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan grid on a model 1e-6 across: the raster build's images identical to the reference's",
          "[vulkan][diff][grid]") {
  // In world units the paper's cell test squared products into denormals here, which lavapipe's
  // geometry shaders flush: a texel differed (scene cell (14, 14, 2)). The test now takes its
  // products in units of about a cell (cell_test_scale).
  const gridrt::test::Run r = gridrt::test::run_tool(std::string("diff ") + GRIDRT_DATA_DIR +
                                                     "/fixtures/tiny_1e-6.obj --traversal paper --vk-build raster "
                                                     "--width 48 --height 32 --frames 1 --threads 2");
  INFO(r.output);
  CHECK(r.exit_code == 0);
  CHECK_THAT(r.output, Catch::Contains("AGREE") && Catch::Contains("0 of"));
}

TEST_CASE("Vulkan grid, separating-axis cell test: images identical texel for texel, raster and compute builds",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = test_scene(3);
  GridOptions o = options(reference::Insertion::sorted, reference::Traversal::paper, 5);
  o.cell_test = GridOptions::CellTest::box;
  ReferenceGridTracer ref(o);
  ref.build(scene, 0.0f);
  REQUIRE((ref.params().flags & sh::kGridCellBox) != 0u);
  for (BuildMode mode : {BuildMode::raster, BuildMode::compute}) {
    INFO((mode == BuildMode::raster ? "raster build" : "compute build"));
    VulkanGridTracer vk(ctx, o, {.build = mode});
    vk.build(scene, 0.0f);
    CHECK(std::memcmp(&vk.params(), &ref.params(), sizeof(sh::GridParams)) == 0);
    CHECK(compare_texels(ref.dump(), vk.dump()) == 0);
    ReferenceGridTracer ref_t(o);
    ref_t.build(scene, 0.0f);
    ref_t.update(1.3f);
    vk.update(1.3f);
    CHECK(compare_texels(ref_t.dump(), vk.dump()) == 0);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan grid, first-empty: unsaturated cells hold their references, saturated ones a flagged choice",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = test_scene(4);
  const GridOptions o = options(reference::Insertion::first_empty, reference::Traversal::paper, 5);
  ReferenceGridTracer ref(o);
  ref.build(scene, 0.0f);
  for (BuildMode mode : {BuildMode::raster, BuildMode::compute}) {
    INFO((mode == BuildMode::raster ? "raster build" : "compute build"));
    VulkanGridTracer vk(ctx, o, {.build = mode});
    vk.build(scene, 0.0f);
    size_t saturated = 0;
    CHECK(check_first_empty(ref.data(), vk.dump(), &saturated) == 0);
    CHECK(saturated > 0);
    CHECK(compare_triangles(ref.data().triangles, vk.download_triangles()) == 0);
    CHECK(sorted(vk.download_dirty_cells()) == sorted(reference::dirty_cells(ref.data())));
    vk.update(1.1f);
    ReferenceGridTracer ref_t(o);
    ref_t.build(scene, 0.0f);
    ref_t.update(1.1f);
    CHECK(check_first_empty(ref_t.data(), vk.dump(), &saturated) == 0);
    CHECK(sorted(vk.download_dirty_cells()) == sorted(reference::dirty_cells(ref_t.data())));
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan grid: every hit record identical in bits to the reference's, paper and exact, animated",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = test_scene(5);
  for (auto traversal : {reference::Traversal::paper, reference::Traversal::exact}) {
    const bool paper = traversal == reference::Traversal::paper;
    INFO((paper ? "paper traversal" : "exact traversal"));
    const GridOptions o = options(reference::Insertion::sorted, traversal, paper ? 4 : 8);
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    VulkanGridTracer vk(ctx, o, {.build = paper ? BuildMode::raster : BuildMode::compute});
    vk.build(scene, 0.0f);
    for (float time : {0.0f, 0.7f, 2.2f}) {
      INFO("time " << time);
      if (time > 0.0f) {
        ref.update(time);
        vk.update(time);
      }
      const std::vector<Ray> rays = test_rays(ref, 17 + uint32_t(time * 10));
      std::vector<Hit> want(rays.size()), got(rays.size());
      ref.trace(rays, want);
      vk.trace(rays, got);
      check_hits(ctx, rays, want, got);
      // The rays exercise what they should
      size_t hits = 0, gap = 0, back = 0, alpha_cut = 0;
      for (const Hit& h : want) {
        hits += !is_miss(h);
        gap += (h.flags & sh::kHitGapFill) != 0;
        back += (h.flags & sh::kHitBackFace) != 0;
      }
      (void)alpha_cut;
      INFO("hits " << hits << " gap-fill " << gap << " back faces " << back << " of " << rays.size());
      CHECK(hits > rays.size() / 10);
      if (paper) CHECK(gap > 0);
      CHECK(back > 0);
      // The gap-fill rays again, each ending exactly at its voxel's midpoint (tmax = the reported
      // t): a hit needs t < tmax, so no such voxel is reported, on either backend
      std::vector<Ray> ended;
      for (size_t i = 0; i < rays.size() && ended.size() < 200; ++i)
        if (want[i].flags & sh::kHitGapFill) {
          ended.push_back(rays[i]);
          ended.back().tmax = want[i].t;
        }
      std::vector<Hit> want_ended(ended.size()), got_ended(ended.size());
      ref.trace(ended, want_ended);
      vk.trace(ended, got_ended);
      check_hits(ctx, ended, want_ended, got_ended);
      for (size_t i = 0; i < ended.size(); ++i) CHECK((is_miss(want_ended[i]) || want_ended[i].t < ended[i].tmax));
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan grid: alpha keying, features off and the paper's repeat modes agree with the reference",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = test_scene(6);
  // Rays straight at the alpha-keyed quads: some cut, some kept
  GridOptions o = options(reference::Insertion::sorted, reference::Traversal::exact, 8);
  for (int variant = 0; variant < 6; ++variant) {
    o.mailbox = variant != 5;  // 5: exact without the mailbox
    o.alpha_keying = variant != 1;
    o.gap_fill = variant != 2;
    o.traversal = variant >= 2 && variant <= 4 ? reference::Traversal::paper : reference::Traversal::exact;
    o.repeats = variant == 3   ? GridOptions::Repeats::skip
                : variant == 4 ? GridOptions::Repeats::retest
                               : GridOptions::Repeats::merge;
    INFO("alpha keying " << o.alpha_keying << ", gap-fill " << o.gap_fill << ", traversal "
                         << (o.traversal == reference::Traversal::paper ? "paper" : "exact") << ", repeats "
                         << int(o.repeats) << ", mailbox " << o.mailbox);
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    VulkanGridTracer vk(ctx, o);
    vk.build(scene, 0.0f);
    const std::vector<Ray> rays = test_rays(ref, 40 + variant);
    std::vector<Hit> want(rays.size()), got(rays.size());
    ref.trace(rays, want);
    vk.trace(rays, got);
    check_hits(ctx, rays, want, got);
    size_t leaves = 0;
    for (const Hit& h : want) leaves += !is_miss(h) && scene.instances[h.instance].name.rfind("leaves", 0) == 0;
    CHECK(leaves > 0);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan grid: the explained ray leaves the reference's events, bit for bit", "[vulkan][diff][grid][explain]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = test_scene(7);
  for (auto traversal : {reference::Traversal::paper, reference::Traversal::exact}) {
    GridOptions o = options(reference::Insertion::sorted, traversal, 4);
    o.mailbox = true;  // the exact traversal's skipped re-tests explained too (the paper traversal ignores it)
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    VulkanGridTracer vk(ctx, o);
    vk.build(scene, 0.0f);
    const std::vector<Ray> rays = test_rays(ref, 77);
    // A hit, a gap-fill, a miss, an alpha cut where there is one, a secondary ray
    std::vector<Hit> hits(rays.size());
    ref.trace(rays, hits);
    std::vector<uint32_t> chosen = {0u, uint32_t(96 * 32 + 48), uint32_t(rays.size() - 1)};
    for (uint32_t i = 0; i < rays.size(); ++i)
      if (hits[i].flags & sh::kHitGapFill) {
        chosen.push_back(i);
        break;
      }
    for (uint32_t i = 0; i < rays.size(); ++i)
      if (!is_miss(hits[i]) && hits[i].tests > 6) {
        chosen.push_back(i);
        break;
      }
    // Exact: a ray whose mailbox skips a re-test (kTestMailboxed)
    if (traversal == reference::Traversal::exact) {
      bool found = false;
      for (uint32_t i = 0; i < rays.size() && !found; i += 7) {
        const reference::ExplainRecord rec = ref.explain_ray(rays[i]);
        for (const sh::ExplainEvent& e : rec.events)
          if (e.kind == sh::kEvTest && e.code == sh::kTestMailboxed) found = true;
        if (found) chosen.push_back(i);
      }
      CHECK(found);
    }
    for (uint32_t index : chosen) {
      INFO((traversal == reference::Traversal::paper ? "paper" : "exact") << " ray " << index << ": "
                                                                          << hex_ray(rays[index]));
      const reference::ExplainRecord want = ref.explain_ray(rays[index]);
      const reference::ExplainRecord got = vk.explain_ray(rays, index);
      if (!bit_exact_hits_device(ctx)) {
        // Elsewhere the values may differ by ulps (docs/VULKAN.md): the record must still be the
        // device's own trace of the ray, from the ray event to the report or miss
        std::vector<Hit> traced(rays.size());
        vk.trace(rays, traced);
        CHECK(std::memcmp(&traced[index], &got.hit, sizeof(Hit)) == 0);
        REQUIRE(got.events.size() >= 2);
        CHECK(got.events.front().kind == sh::kEvRay);
        CHECK((got.events.back().kind == sh::kEvReport || got.events.back().kind == sh::kEvMiss));
        continue;
      }
      CHECK(std::memcmp(&want.hit, &got.hit, sizeof(Hit)) == 0);
      REQUIRE(want.events.size() == got.events.size());
      size_t bad = 0;
      for (size_t e = 0; e < want.events.size(); ++e)
        if (std::memcmp(&want.events[e], &got.events[e], sizeof(sh::ExplainEvent)) != 0 && ++bad <= 3)
          UNSCOPED_INFO("event " << e << " differs (kind " << want.events[e].kind << " vs " << got.events[e].kind << ")");
      CHECK(bad == 0);
      CHECK(reference::to_text(want) == reference::to_text(got));
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"

TEST_CASE("Vulkan grid on the built-in scenes: images and every hit identical, primary and bounce rays, animated",
          "[vulkan][diff][grid][scenes]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  for (const std::string& name : builtin_names()) {
    const Scene scene = make_builtin(name);
    for (auto traversal : {reference::Traversal::paper, reference::Traversal::exact}) {
      GridOptions o;
      o.traversal = traversal;
      o.threads = 2;
      INFO(name << ", " << (traversal == reference::Traversal::paper ? "paper" : "exact") << " traversal, "
                << scene.triangle_count() << " triangles");
      ReferenceGridTracer ref(o);
      ref.build(scene, 0.0f);
      VulkanGridTracer vk(ctx, o, {.build = traversal == reference::Traversal::paper ? BuildMode::raster
                                                                                      : BuildMode::compute});
      vk.build(scene, 0.0f);
      CHECK(compare_texels(ref.dump(), vk.dump()) == 0);
      // The compute build hands long AABB ranges out in runs (the atrium's floor and walls)
      if (traversal == reference::Traversal::exact && name == "atrium") CHECK(vk.download_build_runs() > 0);
      const Camera cam = scene.frame_camera();
      for (float time : {0.0f, 0.8f, 2.5f}) {
        INFO("time " << time);
        if (time > 0.0f) {
          if (!scene.has_dynamic()) break;
          ref.update(time);
          vk.update(time);
          CHECK(compare_texels(ref.dump(), vk.dump()) == 0);
        }
        // Primary rays (96x64) and the glossy bounce off the reference's gather buffer
        const GatherBuffer gather = make_gather(scene, ref, cam, 96, 64, time);
        std::vector<Ray> rays;
        for (uint32_t y = 0; y < 64; ++y)
          for (uint32_t x = 0; x < 96; ++x) rays.push_back(camera_ray(cam, 96, 64, x, y));
        const std::vector<Ray> bounce = bounce_rays(scene, gather, 1);
        rays.insert(rays.end(), bounce.begin(), bounce.end());
        std::vector<Hit> want(rays.size()), got(rays.size());
        ref.trace(rays, want);
        vk.trace(rays, got);
        check_hits(ctx, rays, want, got);
        size_t hits = 0;
        for (const Hit& h : want) hits += !is_miss(h);
        CHECK(hits > 96 * 64 / 4);
      }
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

// Timings of the Vulkan grid. Hidden: run with
//   build/dev/tests/gridrt_tests "[.vkbench]"   (GRIDRT_BENCH_SIZE=WxH, default 480x270;
//   GRIDRT_BENCH_ONLY=paper-raster|paper-compute|exact-raster|exact-compute for one configuration)
// Medians after warm-ups, validation off; device time (timestamps) and host time
// (submit to fence) of each pass. On lavapipe read the host times (docs/VULKAN.md).
TEST_CASE("Vulkan grid timings on the atrium", "[.vkbench]") {
  uint32_t w = 480, h = 270;
  if (const char* s = std::getenv("GRIDRT_BENCH_SIZE")) std::sscanf(s, "%ux%u", &w, &h);
  vulkan::ContextOptions co = vulkan::ContextOptions::from_env();
  co.validation = false;
  vulkan::Context ctx(co);
  const Scene scene = make_builtin("atrium");
  const Camera cam = scene.frame_camera();
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::vector<Ray> rays;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) rays.push_back(camera_ray(cam, w, h, x, y));
  std::ostringstream out;
  out << ctx.info().name << ", atrium (" << scene.triangle_count() << " triangles), " << w << "x" << h
      << ": device ms / host ms, medians (builds of 5, updates of 3, traces of 15)\n";
  const char* only = std::getenv("GRIDRT_BENCH_ONLY");  // e.g. "paper-compute"
  const int repeat = std::getenv("GRIDRT_BENCH_REPEAT") ? std::atoi(std::getenv("GRIDRT_BENCH_REPEAT")) : 1;
  for (int rep = 0; rep < repeat; ++rep)
  for (auto traversal : {reference::Traversal::paper, reference::Traversal::exact})
    for (BuildMode mode : {BuildMode::raster, BuildMode::compute}) {
      const std::string config = std::string(traversal == reference::Traversal::paper ? "paper" : "exact") +
                                 (mode == BuildMode::raster ? "-raster" : "-compute");
      if (only && config != only) continue;
      GridOptions o;
      o.traversal = traversal;
      VulkanGridTracer vk(ctx, o, {.build = mode});
      std::vector<double> t[8];
      std::vector<Hit> hits(rays.size());
      for (int run = 0; run < 6; ++run) {  // builds: one warm-up, five timed
        vk.build(scene, 0.0f);
        if (run) t[0].push_back(vk.timings().build_ms), t[1].push_back(vk.timings().build_host_ms);
      }
      // Frames: update, then each trace five times back to back, after a second of back-to-back
      // traces: GPUs lower their clocks under bursty work such as this (the host makes the gather
      // buffer between traces), and the first configuration would otherwise run at other clocks
      // than the rest. One warm-up frame, three timed.
      for (int run = 0; run < 4; ++run) {
        const float time = 0.1f * float(run + 1);
        const GatherBuffer gather = make_gather(scene, vk, cam, w, h, time);
        const std::vector<Ray> bounce = bounce_rays(scene, gather, 1);
        std::vector<Hit> bh(bounce.size());
        for (const auto t0 = std::chrono::steady_clock::now();
             std::chrono::steady_clock::now() - t0 < std::chrono::seconds(1);)
          vk.trace(rays, hits);
        vk.update(time);
        if (run) t[2].push_back(vk.timings().update_ms), t[3].push_back(vk.timings().update_host_ms);
        for (int k = 0; k < 5; ++k) {
          vk.trace(rays, hits);
          if (run) t[4].push_back(vk.timings().trace_ms), t[5].push_back(vk.timings().trace_host_ms);
        }
        for (int k = 0; k < 5; ++k) {
          vk.trace(bounce, bh);
          if (run) t[6].push_back(vk.timings().trace_ms), t[7].push_back(vk.timings().trace_host_ms);
        }
      }
      char line[400];
      std::snprintf(line, sizeof line,
                    "  %s, %s build: build %.2f / %.2f, update %.2f / %.2f, primary trace %.2f / %.2f, bounce "
                    "trace %.2f / %.2f\n",
                    traversal == reference::Traversal::paper ? "paper" : "exact",
                    mode == BuildMode::raster ? "raster " : "compute", median(t[0]), median(t[1]), median(t[2]),
                    median(t[3]), median(t[4]), median(t[5]), median(t[6]), median(t[7]));
      out << line;
    }
  out << "  grid from reference::choose_grid; the reference's own times: [.bench] tests of the reference\n";
  WARN(out.str());
}

// The accuracy knobs in the shaders: the watertight triangle test (a specialization constant) and
// every slot axis (the image's x carries the slots of scene axis x, y or z) give images identical
// texel for texel and hit records identical in bits, paper and exact, after an update.
TEST_CASE("Vulkan grid: watertight test and slot axes identical in bits to the reference", "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = test_scene(7);
  using SA = GridOptions::SlotAxis;
  using TT = GridOptions::TriangleTest;
  for (const auto& [axis, test, traversal] :
       {std::tuple{SA::x, TT::watertight, reference::Traversal::exact}, std::tuple{SA::y, TT::watertight, reference::Traversal::paper},
        std::tuple{SA::z, TT::moller, reference::Traversal::exact}, std::tuple{SA::automatic, TT::watertight, reference::Traversal::exact}}) {
    GridOptions o = options(reference::Insertion::sorted, traversal, 8);
    o.slot_axis = axis;
    o.triangle_test = test;
    INFO("slot axis " << int(axis) << ", watertight " << (test == TT::watertight) << ", exact "
                      << (traversal == reference::Traversal::exact));
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    VulkanGridTracer vk(ctx, o, {.build = axis == SA::y ? BuildMode::raster : BuildMode::compute});
    vk.build(scene, 0.0f);
    ref.update(0.9f);
    vk.update(0.9f);
    CHECK(compare_texels(ref.dump(), vk.dump()) == 0);
    if (axis != SA::automatic)
      CHECK(sh::grid_slot_axis(ref.params()) == uint32_t(axis) - 1u);
    const std::vector<Ray> rays = test_rays(ref, 70 + uint32_t(axis));
    std::vector<Hit> want(rays.size()), got(rays.size());
    ref.trace(rays, want);
    vk.trace(rays, got);
    check_hits(ctx, rays, want, got);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

// The surface rule (shared::origin_on_plane) in the trace shader: rays launched from the shared
// edges of a fan of slivers, most leaving nearly in the neighbour's plane. The triangle test alone
// accepts that neighbour (through the origin) at a t just past the origin epsilon on some of them;
// both backends refuse it, bit for bit, and report the same hits.
TEST_CASE("Vulkan grid: the surface rule on rays launched from a fan of slivers, bit for bit", "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  constexpr int kSlivers = 1000;
  Scene scene;
  Mesh mesh;
  mesh.name = "cone";
  mesh.positions.push_back(glm::vec3(0, 0, 1));
  for (int k = 0; k < kSlivers; ++k) {
    const double a = 2.0 * 3.14159265358979323846 * k / kSlivers;
    mesh.positions.push_back(glm::vec3(float(std::cos(a)), float(std::sin(a)), 0.0f));
  }
  for (int k = 0; k < kSlivers; ++k) {
    mesh.triangles.emplace_back(0u, uint32_t(k + 1), uint32_t((k + 1) % kSlivers + 1));
    mesh.materials.push_back(0u);
  }
  scene.materials.push_back(Material{.name = "grey"});
  scene.meshes.push_back(mesh);
  scene.instances.push_back(Instance{.name = "cone", .mesh = 0});
  scene.finalize();
  GridOptions o;
  o.traversal = reference::Traversal::exact;
  o.threads = 2;
  ReferenceGridTracer ref(o);
  ref.build(scene, 0.0f);
  VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
  vk.build(scene, 0.0f);
  // From the midpoint of sliver k's edge shared with sliver k + 1, into the half-space in front of
  // sliver k: along the neighbour's plane tilted out by 1e-3 to 1e-6 of a radian, and at random
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Ray> rays;
  size_t neighbour_accepted = 0;
  for (int k = 0; k < kSlivers; k += 7) {
    const glm::vec3 apex = mesh.positions[0], b1 = mesh.positions[size_t(k + 1)],
                    b2 = mesh.positions[size_t((k + 1) % kSlivers + 1)], b3 = mesh.positions[size_t((k + 2) % kSlivers + 1)];
    const glm::vec3 org = 0.5f * (apex + b2);
    const glm::vec3 n_launch = glm::normalize(glm::cross(b2 - apex, b1 - apex));  // outward
    const glm::vec3 along = glm::normalize(b3 - org);                            // in the neighbour
    for (float tilt : {1e-3f, 1e-4f, 1e-5f, 1e-6f}) {
      Ray r{};
      r.org = org;
      r.dir = glm::normalize(along + tilt * n_launch);
      r.tmin = 0.0f;
      r.tmax = std::numeric_limits<float>::infinity();
      r.launch_normal = n_launch;
      r.launch_ref = sh::ref_pack(0, uint32_t(k));
      rays.push_back(r);
      // The triangle test alone on the neighbour (k + 1), at the trace's interval
      sh::TriangleTest t{};
      if (sh::triangle_test(sh::kTriangleWatertight, r.org, r.dir, apex, b2, b3, sh::origin_tmin(r.org, r.dir, 0.0f),
                            r.tmax, std::numeric_limits<float>::infinity(), -1.0f, t) == sh::kTestAccepted)
        neighbour_accepted += 1;
    }
    for (int j = 0; j < 4; ++j) {
      Ray r = rays.back();
      r.dir = glm::vec3(u(rng), u(rng), u(rng));
      if (glm::dot(r.dir, n_launch) < 0.0f) r.dir = -r.dir;
      rays.push_back(r);
    }
  }
  std::vector<Hit> want(rays.size()), got(rays.size());
  ref.trace(rays, want);
  vk.trace(rays, got);
  check_hits(ctx, rays, want, got);
  INFO(neighbour_accepted << " rays whose triangle test alone accepts the neighbour through the origin");
  CHECK(neighbour_accepted > 0);
  // No ray reports the sliver through its origin
  for (size_t i = 0; i < rays.size(); ++i) {
    const uint32_t neighbour = (sh::ref_triangle(rays[i].launch_ref) + 1u) % kSlivers;
    if (!is_miss(want[i])) CHECK_FALSE((want[i].triangle == neighbour && want[i].t < 1e-4f));
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

#include "tests/tracer_contract.h"

TEST_CASE("Library: the Vulkan grid keeps the Tracer contract - failed builds, times, unfinalized scenes", "[vulkan]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  reference::GridOptions o;
  o.traversal = reference::Traversal::exact;
  o.threads = 2;
  gridtest::check_contract([&ctx, o] { return std::make_unique<vulkan::VulkanGridTracer>(ctx, o); });
  // A frame renders only on the build it was made on: a new build makes new buffers (the frame
  // rendered from the freed ones: a crash in the driver), a failed one leaves none
  const Scene good = gridtest::random_scene(300, 0.6f, 10.0f, 5);
  VulkanGridTracer grid(ctx, o);
  vulkan::FrameOptions fo;
  fo.width = 16, fo.height = 12;
  REQUIRE_THROWS_WITH(vulkan::VulkanFrame(grid, good, fo), Catch::Contains("not built"));
  grid.build(good, 0.0f);
  {
    vulkan::VulkanFrame frame(grid, good, fo);
    frame.render(0);
    grid.build(good, 0.0f);
    REQUIRE_THROWS_WITH(frame.render(0), Catch::Contains("built again"));
  }
  {
    vulkan::VulkanFrame frame(grid, good, fo);
    frame.render(0);
    REQUIRE_THROWS_AS(grid.build(gridtest::refused_scene(), 0.0f), Error);
    REQUIRE_THROWS_WITH(frame.render(0), Catch::Contains("not built"));
  }
  fo.width = 4294967295u, fo.height = 1u;
  grid.build(good, 0.0f);
  REQUIRE_THROWS_WITH(vulkan::VulkanFrame(grid, good, fo), Catch::Contains("more than 65536"));
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}
