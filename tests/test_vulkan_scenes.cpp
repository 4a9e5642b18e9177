// test_vulkan_scenes.cpp: the Vulkan port against the CPU reference the way `gridrt diff` holds
// them, on the real scenes (when present; CI requires them) and on built-in scenes, sized for CI:
// a small gather buffer, both builds, both traversals, a build and an update, both insertions
// where the result is defined (sorted: texel for texel; first-empty: every cell's slots as a
// multiset of its candidates, docs/VULKAN.md). Validation layer on; any message fails.
#include <algorithm>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/reference/compare.h"
#include "tests/vulkan_test_util.h"
#include "gridrt/vulkan/grid.h"

using namespace gridrt;
using namespace gridrt::test;
using gridrt::vulkan::BuildMode;
using gridrt::vulkan::VulkanGridTracer;
using reference::GridOptions;
using reference::Insertion;
using reference::ReferenceGridTracer;
using reference::Traversal;
namespace sh = gridrt::shared;
namespace fs = std::filesystem;

namespace {

struct Config {
  BuildMode build;
  Traversal traversal;
  Insertion insertion;
  uint32_t frames;  // the first a build, the rest updates
};

std::string text(const Config& c) {
  return std::string(c.build == BuildMode::raster ? "raster" : "compute") + " build, " +
         (c.traversal == Traversal::paper ? "paper" : "exact") + " traversal, " +
         (c.insertion == Insertion::sorted ? "sorted" : "first-empty") + " insertion";
}

// The cell of texel `i` (x fastest) as "cell (x, y, z) slot s" in scene axes.
std::string texel_text(const sh::GridParams& g, const AccelDump& d, size_t i) {
  const uint32_t tx = uint32_t(i % d.extent.x), ty = uint32_t((i / d.extent.x) % d.extent.y),
                 tz = uint32_t(i / (size_t(d.extent.x) * d.extent.y));
  return "texel (" + std::to_string(tx) + ", " + std::to_string(ty) + ", " + std::to_string(tz) + ") slot " +
         std::to_string(tx % (g.capacity + 1)) + " of image cell (" + std::to_string(tx / (g.capacity + 1)) + ", " +
         std::to_string(ty) + ", " + std::to_string(tz) + ")";
}

// One configuration: the reference and the port built and updated side by side; after each
// frame the image (sorted: texel for texel; first-empty: the multiset rule, with the spill list),
// the spill header, the dirty cells, and every hit record of the camera rays and of the glossy
// bounce off the reference's gather buffer (w x h), in bits where the device is held to the bit.
// First-empty hit records are compared where the trace tests every candidate of a cell (the exact
// traversal with the spill list: slots and spilled entries are the candidates whatever the order).
void diff_scene(vulkan::Context& ctx, const Scene& scene, const GridOptions& o, const Config& c, uint32_t w,
                uint32_t h) {
  INFO(scene.name << ": " << text(c));
  ReferenceGridTracer ref(o);
  VulkanGridTracer vk(ctx, o, {.build = c.build});
  const Camera cam = scene.frame_camera();
  for (uint32_t frame = 0; frame < c.frames; ++frame) {
    const float time = float(frame) * 0.7f;
    INFO("frame " << frame << " (" << (frame ? "update" : "build") << ")");
    if (frame == 0) {
      ref.build(scene, time);
      vk.build(scene, time);
      REQUIRE(std::memcmp(&vk.params(), &ref.params(), sizeof(sh::GridParams)) == 0);
    } else {
      ref.update(time);
      vk.update(time);
    }
    const sh::GridParams& g = ref.params();
    const reference::SpillDump want_spill = ref.spill(), got_spill = vk.spill();
    CHECK(want_spill.header.count == got_spill.header.count);
    CHECK(want_spill.header.static_count == got_spill.header.static_count);
    const bool spill_on = (g.flags & sh::kGridSpill) != 0u;
    const AccelDump got = vk.dump();
    if (c.insertion == Insertion::sorted) {
      const AccelDump want = ref.dump();
      const reference::TexelDiff d = reference::compare_texels(want, got);
      if (!d.differing.empty())
        UNSCOPED_INFO("first differing " << texel_text(g, want, d.differing.front()) << ": reference "
                                         << hex(want.texels[d.differing.front()]) << ", vulkan "
                                         << hex(got.texels[d.differing.front()]));
      CHECK(d.differing.size() == 0);
      if (spill_on) {
        const reference::SpillDiff s = reference::compare_spill(want_spill, got_spill);
        INFO(s.problem_want << s.problem_got);
        CHECK(s.same());
      }
    } else {
      const reference::CellCheck cc = reference::check_cells_as_multisets(ref.data(), got, spill_on ? &got_spill : nullptr);
      if (!cc.bad.empty())
        UNSCOPED_INFO("first cell that breaks the multiset rule: " << cc.bad.front());
      CHECK(cc.bad.size() == 0);
    }
    std::vector<uint32_t> a = vk.download_dirty_cells(), b = reference::dirty_cells(ref.data());
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    CHECK(a == b);
    if (c.insertion == Insertion::first_empty && !(c.traversal == Traversal::exact && spill_on)) continue;
    // Camera rays and the glossy bounce off the reference's own gather buffer
    GridOptions exact = o;
    exact.traversal = Traversal::exact;
    ReferenceGridTracer gather_tracer(exact);
    gather_tracer.build(scene, time);
    const GatherBuffer gather = make_gather(scene, gather_tracer, cam, w, h, time);
    std::vector<Ray> rays = bounce_rays(scene, gather, frame);
    size_t bounces = 0;
    for (const Ray& r : rays) bounces += !is_unused(r);
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) rays.push_back(camera_ray(cam, w, h, x, y));
    std::vector<Hit> want_hits(rays.size()), got_hits(rays.size());
    ref.trace(rays, want_hits);
    vk.trace(rays, got_hits);
    const reference::HitDiff d = reference::compare_hits(want_hits, got_hits);
    if (!d.differing.empty()) {
      const size_t i = d.differing.front();
      UNSCOPED_INFO("first differing ray " << i << (i < size_t(w) * h ? " (bounce)" : " (primary)") << ": "
                                           << reference::hex_ray(rays[i]) << "\n  reference "
                                           << reference::hex_hit(want_hits[i]) << "\n  vulkan    "
                                           << reference::hex_hit(got_hits[i]));
    }
    size_t hits = 0;
    for (const Hit& hit : want_hits) hits += !is_miss(hit);
    CHECK(hits > size_t(w) * h / 4);  // the camera sees the scene: the comparison is not of misses
    if (bit_exact_hits_device(ctx)) {
      CHECK(d.identical == d.rays);
    } else {
      CHECK(d.discrete.size() * 100 <= d.rays);
    }
  }
}

// The configurations every scene runs: each build with each traversal, sorted through an update;
// first-empty with each build once.
const Config kConfigs[] = {
    {BuildMode::raster, Traversal::paper, Insertion::sorted, 2},
    {BuildMode::compute, Traversal::paper, Insertion::sorted, 1},
    {BuildMode::raster, Traversal::exact, Insertion::sorted, 1},
    {BuildMode::compute, Traversal::exact, Insertion::sorted, 2},
    {BuildMode::raster, Traversal::exact, Insertion::first_empty, 2},
    {BuildMode::compute, Traversal::paper, Insertion::first_empty, 1},
};

// The grid the policy chooses for the scene (once: the trace-cost policy samples rays), as fixed
// options the configurations share.
GridOptions fixed_grid(const Scene& scene, uint32_t max_image_dimension) {
  GridOptions o;
  o.threads = 2;
  o.max_image_dimension = max_image_dimension;
  ReferenceGridTracer probe(o);
  probe.build(scene, 0.0f);
  o.resolution = probe.params().cells;
  o.capacity = probe.params().capacity;
  return o;
}

void diff_all(const Scene& scene, uint32_t max_image_dimension, uint32_t w, uint32_t h) {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const GridOptions base = fixed_grid(scene, max_image_dimension);
  for (const Config& c : kConfigs) {
    GridOptions o = base;
    o.traversal = c.traversal;
    o.insertion = c.insertion;
    diff_scene(ctx, scene, o, c, w, h);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

std::string real_scenes() {
  const std::string dir = real_scenes_dir();
  if (fs::is_directory(dir)) return dir;
  if (std::getenv("CI")) FAIL("the real scenes folder '" << dir << "' is missing, and CI must test with it");
  WARN("skipped: the real scenes folder '" << dir << "' is missing (set GRIDRT_SCENES)");
  return "";
}

// A floor of two triangles over 257 x 257 cells (66,049 cells in each one's AABB range) and a
// small moving triangle: one invocation walking the floor's range alone runs past lavapipe's
// 65,535 loop iterations.
Scene floor_scene() {
  Scene s;
  s.name = "floor";
  Mesh floor;
  floor.name = "floor";
  floor.positions = {{0.0f, 0.5f, 0.0f}, {64.0f, 0.5f, 0.0f}, {64.0f, 0.5f, 64.0f}, {0.0f, 0.5f, 64.0f}};
  floor.triangles = {{0, 1, 2}, {0, 2, 3}};
  floor.materials.assign(floor.triangles.size(), 0u);
  Mesh small;
  small.name = "small";
  small.positions = {{10.0f, 0.2f, 10.0f}, {11.0f, 0.9f, 10.0f}, {10.0f, 0.2f, 11.0f}};
  small.triangles = {{0, 1, 2}};
  small.materials = {0u};
  s.meshes = {floor, small};
  s.materials.push_back(Material{.name = "default"});
  s.instances.push_back(Instance{.name = "floor", .mesh = 0});
  Instance moving{.name = "small-moving", .mesh = 1, .dynamic = true};
  moving.motion.axis = {0.0f, 1.0f, 0.0f};
  moving.motion.pivot = glm::vec3(32.0f, 0.5f, 32.0f);
  moving.motion.angular_speed = 0.3f;
  s.instances.push_back(moving);
  s.camera = Camera{.eye = {-8.0f, 20.0f, -8.0f}, .target = {32.0f, 0.5f, 32.0f}};
  s.finalize();
  return s;
}

}  // namespace

// The raster build's geometry shader once walked a triangle's whole AABB range itself; lavapipe
// ends every loop of an invocation after 65,535 iterations in total, so the cells past that were
// silently left without the reference (53,798 texels on Sibenik). Both builds now hand ranges of
// more than 8 cells out in runs (build.glsl): every cell of the floor holds its two triangles.
TEST_CASE("Vulkan grid: a triangle over 66049 cells is in every one of them, raster and compute builds",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = floor_scene();
  for (const auto& [mode, insertion] : {std::pair{BuildMode::raster, Insertion::sorted},
                                       std::pair{BuildMode::compute, Insertion::sorted},
                                       std::pair{BuildMode::raster, Insertion::first_empty}}) {
    GridOptions o;
    o.threads = 2;
    o.cell_size = 0.25f;  // 257 x 4 x 257 cells
    o.capacity = 4;
    o.insertion = insertion;
    diff_scene(ctx, scene, o, Config{mode, Traversal::paper, insertion, mode == BuildMode::raster ? 2u : 1u}, 48, 27);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

// An outside sweep's find: a triangle's invocation lists its range's runs one by one, 110,592 of
// them for one triangle over 96^3 cells; llvmpipe cut that loop, leaving cells without the
// triangle and the list's tail stale (junk references), with exit 0 or a count mismatch. Such a
// triangle is now refused on llvmpipe, at the build and at an update, naming its range.
TEST_CASE("Vulkan grid on llvmpipe: a triangle whose range the build's run list cannot hold is refused",
          "[vulkan][grid][badinput]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  // One triangle across the unit cube's diagonal: its range is every cell
  Scene scene;
  scene.name = "diagonal";
  Mesh tri;
  tri.name = "tri";
  tri.positions = {{0.0f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 1.0f}};
  tri.triangles = {{0, 1, 2}};
  tri.materials = {0u};
  scene.meshes = {tri};
  scene.materials.push_back(Material{.name = "default"});
  scene.instances.push_back(Instance{.name = "tri", .mesh = 0});
  scene.camera = Camera{.eye = {0.5f, 0.5f, -3.0f}, .target = {0.5f, 0.5f, 0.5f}};
  scene.finalize();
  for (const BuildMode mode : {BuildMode::raster, BuildMode::compute}) {
    GridOptions o;
    o.threads = 2;
    o.resolution = glm::uvec3(72u);  // 373,248 cells in the triangle's range: more than kLlvmpipeRangeCellLimit
    o.capacity = 1;
    o.traversal = Traversal::paper;
    VulkanGridTracer gpu(ctx, o, vulkan::VulkanGridOptions{.build = mode});
    if (ctx.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE) {
      CHECK_THROWS_WITH(gpu.build(scene, 0.0f), Catch::Contains("AABB range holds") && Catch::Contains("llvmpipe"));
    } else {
      REQUIRE_NOTHROW(gpu.build(scene, 0.0f));  // a GPU lists every run
    }
  }
  // A review's find: 33 triangles each at the limit (64^3 cells) list more runs than the list
  // holds (2^20), and the 33rd walked its range itself, cut: refused too; 32 of them agree
  for (const uint32_t copies : {32u, 33u}) {
    Scene many = scene;
    many.instances.assign(copies, Instance{.name = "tri", .mesh = 0});
    many.finalize();
    GridOptions o;
    o.threads = 2;
    o.resolution = glm::uvec3(64u);
    o.capacity = 33;  // every copy's reference in its cells (the image's side: 64 x 34 texels)
    o.traversal = Traversal::paper;
    INFO(copies << " copies");
    VulkanGridTracer gpu(ctx, o, vulkan::VulkanGridOptions{.build = BuildMode::compute});
    if (ctx.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE && copies == 33u) {
      CHECK_THROWS_WITH(gpu.build(many, 0.0f), Catch::Contains("more than the build's run list holds"));
    } else {
      REQUIRE_NOTHROW(gpu.build(many, 0.0f));
      ReferenceGridTracer ref(o);
      ref.build(many, 0.0f);
      CHECK(reference::compare_texels(ref.dump(), gpu.dump()).differing.empty());
    }
  }
  // An outside sweep's find: past the list, a walk of 8,192 cells (the old limit) whose cells each
  // take an insertion at 256 slots passed 65,535 iterations and lost 21,008 references, exit 0:
  // 1,100 triangles of 128 x 64 x 1 cells each (1,126,400 runs) on a grid of 128 x 64 x 8
  CHECK(vulkan::llvmpipe_walk_cell_limit(1) <= vulkan::kLlvmpipeWalkCellLimit);
  CHECK(vulkan::llvmpipe_walk_cell_limit(1) >= 4096u);  // a kept cell costs about 12 iterations at 1 slot
  CHECK(vulkan::llvmpipe_walk_cell_limit(256) < 256u);
  if (ctx.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE) {
    Scene walk;
    Mesh sheets;
    sheets.name = "sheets";
    for (uint32_t i = 0; i < 1100; ++i) {
      const float z = 0.5f + float(i % 4) * 2.0f, s = 1.0e-3f * float(i % 97);
      const uint32_t k = uint32_t(sheets.positions.size());
      sheets.positions.insert(sheets.positions.end(), {{0.2f + s, 0.2f, z}, {127.8f, 0.2f + s, z}, {0.2f, 63.8f - s, z}});
      sheets.triangles.push_back({k, k + 1, k + 2});
    }
    const uint32_t k = uint32_t(sheets.positions.size());  // anchors: the box 128 x 64 x 8
    sheets.positions.insert(sheets.positions.end(), {{0, 0, 0}, {0.01f, 0, 0}, {0, 0.01f, 0}, {128, 64, 8},
                                                     {127.99f, 64, 8}, {128, 63.99f, 8}});
    sheets.triangles.push_back({k, k + 1, k + 2});
    sheets.triangles.push_back({k + 3, k + 4, k + 5});
    sheets.materials.assign(sheets.triangles.size(), 0u);
    walk.meshes = {sheets};
    walk.materials.push_back(Material{.name = "default"});
    walk.instances.push_back(Instance{.name = "sheets", .mesh = 0});
    walk.camera = Camera{.eye = {64.0f, 32.0f, -40.0f}, .target = {64.0f, 32.0f, 4.0f}};
    walk.finalize();
    GridOptions o;
    o.threads = 2;
    o.resolution = glm::uvec3(128u, 64u, 8u);
    o.capacity = 256;
    o.traversal = Traversal::paper;
    VulkanGridTracer gpu(ctx, o, vulkan::VulkanGridOptions{.build = BuildMode::compute});
    CHECK_THROWS_WITH(gpu.build(walk, 0.0f), Catch::Contains("more than the build's run list holds") &&
                                                 Catch::Contains("at 256 slots a cell"));
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan diff on a built-in scene: both builds, traversals and insertions, through an update",
          "[vulkan][diff][grid]") {
  diff_all(make_builtin("atrium"), 1024, 48, 27);
}

TEST_CASE("Vulkan diff on the real scenes: both builds, traversals and insertions, through an update",
          "[vulkan][diff][grid][scenes]") {
  const std::string dir = real_scenes();
  if (dir.empty()) return;
  for (const char* name : {"sibenik-teapots", "sponza-teapots"}) {
    const Scene scene = load_scene(std::string(GRIDRT_DATA_DIR) + "/scenes/" + name + ".json");
    diff_all(scene, 1024, 32, 18);
  }
}
