// test_vulkan_compact.cpp: the compact layout on the Vulkan port against the CPU reference
// (lavapipe, validation layer on, the raster-free compute build and the raster build): the
// offsets and references word for word, the spill lists equal, every hit record and an explained
// ray's events bit for bit, through update frames; the device's allocation equal to the plan's
// memory function.
#include <catch2/catch.hpp>

#include <cstring>
#include <random>

#include "gridrt/reference/compare.h"
#include "tests/test_grid_util.h"
#include "tests/vulkan_test_util.h"
#include "gridrt/vulkan/grid.h"

using namespace gridrt;
using namespace gridrt::test;
using gridrt::vulkan::BuildMode;
using gridrt::vulkan::VulkanGridTracer;
using reference::GridOptions;
using reference::ReferenceGridTracer;
using reference::Traversal;
namespace sh = gridrt::shared;

TEST_CASE("Vulkan compact layout: arrays, spill lists, hits and explain events bit for bit with the reference "
          "through updates - compute and raster build",
          "[vulkan][diff][grid][compact]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = gridtest::random_scene(500, 0.6f, 8.0f, 17, 100);
  for (BuildMode mode : {BuildMode::compute, BuildMode::raster}) {
    if (mode == BuildMode::raster && (!ctx.info().geometry_shader || !ctx.info().vertex_pipeline_stores_and_atomics))
      continue;
    INFO((mode == BuildMode::compute ? "compute build" : "raster build"));
    GridOptions o;
    o.traversal = Traversal::exact;
    o.layout = GridOptions::Layout::compact;
    o.threads = 2;
    o.shuffle_seed = 3;
    o.mailbox = true;  // the re-tests it skips are checked below
    ReferenceGridTracer ref(o);
    VulkanGridTracer vk(ctx, o, {.build = mode});
    ref.build(scene, 0.0f);
    vk.build(scene, 0.0f);
    REQUIRE((vk.params().flags & sh::kGridCompact) != 0u);
    // The allocation is the plan's memory function
    const plan::GridMemory want = reference::grid_allocated(ref.data()), got = vk.memory();
    CHECK(want.total() == got.total());
    CHECK(want.offsets == got.offsets);
    CHECK(want.refs == got.refs);
    CHECK(want.heads == got.heads);
    for (float time : {0.0f, 0.9f, 2.2f}) {
      INFO("t = " << time);
      if (time > 0.0f) ref.update(time), vk.update(time);
      const AccelDump a = ref.dump(), b = vk.dump();
      CHECK(a.kind == "grid-compact");
      CHECK(reference::compare_texels(a, b).differing.empty());
      const reference::SpillDiff sd = reference::compare_spill(ref.spill(), vk.spill());
      CHECK(sd.same_header);
      CHECK(sd.same_lists);
      CHECK(sd.only_want.empty());
      CHECK(sd.only_got.empty());
      CHECK(vk.download_skip() == ref.data().skip);
      const std::vector<Ray> rays = gridtest::box_rays(ref.data(), 2000, 8.0f, uint32_t(time * 10) + 1);
      std::vector<Hit> w(rays.size()), g(rays.size());
      ref.trace(rays, w);
      vk.trace(rays, g);
      size_t differ = 0;
      for (size_t i = 0; i < rays.size(); ++i) differ += std::memcmp(&w[i], &g[i], sizeof(Hit)) != 0;
      CHECK(differ == 0);
      // An explained ray that visits a cell of the dynamic region: the same events
      const plan::ExplainRecord re = ref.explain_ray(rays[5]);
      const plan::ExplainRecord ge = vk.explain_ray(rays, 5);
      REQUIRE(re.events.size() == ge.events.size());
      CHECK(std::memcmp(re.events.data(), ge.events.data(), re.events.size() * sizeof(sh::ExplainEvent)) == 0);
      // A ray whose mailbox (kGridMailbox, on here) skips a re-test: the same events
      REQUIRE((vk.params().flags & sh::kGridMailbox) != 0u);
      size_t m = rays.size();
      for (size_t i = 0; i < rays.size() && m == rays.size(); ++i)
        if (w[i].tests > 4)
          for (const sh::ExplainEvent& e : ref.explain_ray(rays[i]).events)
            if (e.kind == sh::kEvTest && e.code == sh::kTestMailboxed) m = i;
      REQUIRE(m < rays.size());
      const plan::ExplainRecord rm = ref.explain_ray(rays[m]);
      const plan::ExplainRecord gm = vk.explain_ray(rays, uint32_t(m));
      REQUIRE(rm.events.size() == gm.events.size());
      CHECK(std::memcmp(rm.events.data(), gm.events.data(), rm.events.size() * sizeof(sh::ExplainEvent)) == 0);
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan compact layout on a grid of over a million cells: the offsets' scan over several chunks of "
          "groups, long runs ordered, the skip field - bit for bit with the reference",
          "[vulkan][diff][grid][compact][skip]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  // Large triangles over a fine grid: 160 x 96 x 80 = 1,228,800 cells (1,200 groups of 1,024 cells:
  // two chunks of the groups' scan), many references per cell
  const Scene scene = gridtest::random_scene(300, 3.0f, 8.0f, 29, 20);
  GridOptions o;
  o.traversal = Traversal::exact;
  o.layout = GridOptions::Layout::compact;
  o.resolution = glm::uvec3(160, 96, 80);
  o.memory_budget = uint64_t(64) << 20;
  o.threads = 2;
  ReferenceGridTracer ref(o);
  VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
  ref.build(scene, 0.0f);
  vk.build(scene, 0.0f);
  REQUIRE((vk.params().flags & sh::kGridCompact) != 0u);
  REQUIRE((vk.params().flags & sh::kGridSkipEmpty) != 0u);
  REQUIRE(sh::grid_cell_count(vk.params()) > 1024u * 1024u);
  const AccelDump a = ref.dump(), b = vk.dump();
  REQUIRE(a.texels.size() == b.texels.size());
  CHECK(reference::compare_texels(a, b).differing.empty());
  CHECK(vk.download_skip() == ref.data().skip);
  const reference::SpillDiff sd = reference::compare_spill(ref.spill(), vk.spill());
  CHECK(sd.same_header);
  CHECK(sd.same_lists);
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

// The compact passes at their boundaries: a grid of 81 x 80 x 41 cells (1038 blocks of
// kCompactBlock cells, so the blocks' scan gives each of its kCompactScanLanes lanes two blocks; a
// partial last block, empty: the room fills the lower half of the x and y rows only), the room's
// walls in cells on block boundaries, 24 references stacked in one cell (their counts and
// scatter cursors contend in one SIMD batch), and a dynamic instance of 6 triangles in one cell of
// a non-cubic dynamic region whose list holds exactly the spill list's capacity. (The blocks are
// the reference's scan's; the shaders' scan has since worked in groups of 1024 cells, which this
// grid's 265,680 cells end mid-group: docs/SPEC.md "Compact layout".)
TEST_CASE("Vulkan compact layout: two blocks a scan lane, block boundaries, a crowded cell, a full dynamic list - "
          "bit for bit with the reference",
          "[vulkan][diff][grid][compact]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  Scene s = gridtest::random_scene(200, 0.3f, 7.2f, 23);  // moved inside the room: [0.1, 7.9]^3
  for (glm::vec3& p : s.meshes[0].positions) p += glm::vec3(0.4f);
  s.meshes.push_back(gridtest::box_mesh(glm::vec3(0.0f), glm::vec3(8.0f)));
  s.instances.push_back(Instance{.name = "room", .mesh = 1});
  // The crowded cell (20, 20, 20): [3.902, 4.098)^3
  Mesh stack;
  stack.name = "stack";
  for (uint32_t i = 0; i < 24; ++i) {
    const float z = 3.93f + 0.006f * float(i);
    stack.positions.insert(stack.positions.end(), {{3.95f, 3.95f, z}, {4.05f, 3.95f, z}, {3.95f, 4.05f, z}});
    stack.triangles.push_back({3 * i, 3 * i + 1, 3 * i + 2});
  }
  stack.materials.assign(stack.triangles.size(), 0u);
  s.meshes.push_back(stack);
  s.instances.push_back(Instance{.name = "stack", .mesh = 2});
  // The dynamic cell (10, 25, 30): [1.947, 2.143) x [4.880, 5.075) x [5.857, 6.053); it does not move
  Mesh dyn;
  dyn.name = "dynamic";
  for (uint32_t i = 0; i < 6; ++i) {
    const float z = 5.88f + 0.025f * float(i);
    dyn.positions.insert(dyn.positions.end(), {{1.98f, 4.92f, z}, {2.10f, 4.92f, z}, {1.98f, 5.04f, z}});
    dyn.triangles.push_back({3 * i, 3 * i + 1, 3 * i + 2});
  }
  dyn.materials.assign(dyn.triangles.size(), 0u);
  s.meshes.push_back(dyn);
  s.instances.push_back(Instance{.name = "dynamic", .mesh = 3, .dynamic = true});
  s.finalize();
  const uint32_t dynamic_instance = uint32_t(s.instances.size() - 1);

  GridOptions o;
  o.traversal = Traversal::exact;
  o.layout = GridOptions::Layout::compact;
  o.resolution = glm::uvec3(81, 80, 41);
  o.memory_budget = uint64_t(1) << 28;
  o.spill_capacity = 6;
  o.threads = 2;
  o.shuffle_seed = 5;
  ReferenceGridTracer ref(o);
  ref.build(s, 0.0f);
  // The boundaries are reached (on the reference's arrays)
  const reference::GridData& d = ref.data();
  const uint32_t cells = sh::grid_cell_count(d.params);
  const uint32_t blocks = (cells + sh::kCompactBlock - 1) / sh::kCompactBlock;
  REQUIRE(d.params.cells == glm::uvec3(81, 80, 41));
  REQUIRE((d.params.flags & sh::kGridCompact) != 0u);
  CHECK((blocks + sh::kCompactScanLanes - 1) / sh::kCompactScanLanes == 2u);
  CHECK(cells % sh::kCompactBlock != 0u);
  const auto run_length = [&](uint32_t c) {
    uint32_t begin = 0, end = 0;
    reference::compact_run(d, c, begin, end);
    return end - begin;
  };
  uint32_t last_block = 0;  // references in the last block: none
  for (uint32_t c = (blocks - 1) * sh::kCompactBlock; c < cells; ++c) last_block += run_length(c);
  CHECK(last_block == 0u);
  CHECK(cells % 32u != 0u);  // the index's last word is partial
  CHECK(d.offsets.back() == d.refs.size());
  uint32_t boundary_cells = 0;  // blocks whose last cell holds references
  for (uint32_t b = 0; b + 1 < blocks; ++b) boundary_cells += run_length((b + 1) * sh::kCompactBlock - 1) > 0u;
  CHECK(boundary_cells > 10u);
  const uint32_t crowded = sh::cell_linear_index(d.params, glm::uvec3(20, 20, 20));
  CHECK(run_length(crowded) == 24u);
  const glm::uvec3 rlo(d.spill_heads[0], d.spill_heads[1], d.spill_heads[2]);
  const glm::uvec3 rhi(d.spill_heads[4], d.spill_heads[5], d.spill_heads[6]);
  CHECK(rhi.y != rhi.z);
  CHECK(ref.spill().header.capacity == 6u);
  CHECK(ref.spill().header.count == 6u);
  for (const sh::SpillEntry& e : ref.spill().entries)
    CHECK(e.cell == sh::cell_linear_index(d.params, glm::uvec3(10, 25, 30)));

  // Dense offsets with both builds; sparse offsets (the index of occupied cells, its last word
  // partial: 265,680 cells) with the compute build
  for (int variant = 0; variant < 3; ++variant) {
    const BuildMode mode = variant == 1 ? BuildMode::raster : BuildMode::compute;
    if (mode == BuildMode::raster && (!ctx.info().geometry_shader || !ctx.info().vertex_pipeline_stores_and_atomics))
      continue;
    INFO((mode == BuildMode::compute ? "compute build" : "raster build") << (variant == 2 ? ", sparse offsets" : ", dense offsets"));
    GridOptions ov = o;
    ov.offsets = variant == 2 ? GridOptions::Offsets::sparse : GridOptions::Offsets::dense;
    ReferenceGridTracer cpu(ov);
    VulkanGridTracer vk(ctx, ov, {.build = mode});
    cpu.build(s, 0.0f);
    vk.build(s, 0.0f);
    REQUIRE(((vk.params().flags & sh::kGridSparseOffsets) != 0u) == (variant == 2));
    for (float time : {0.0f, 1.0f}) {
      INFO("t = " << time);
      if (time > 0.0f) cpu.update(time), vk.update(time);
      CHECK(reference::compare_texels(cpu.dump(), vk.dump()).differing.empty());
      const reference::SpillDiff sd = reference::compare_spill(cpu.spill(), vk.spill());
      CHECK(sd.same());
      CHECK(vk.download_skip() == cpu.data().skip);
      const std::vector<Ray> rays = gridtest::box_rays(cpu.data(), 2000, 8.0f, 7 + uint32_t(time));
      std::vector<Hit> w(rays.size()), g(rays.size());
      cpu.trace(rays, w);
      vk.trace(rays, g);
      size_t differ = 0, dynamic_hits = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        differ += std::memcmp(&w[i], &g[i], sizeof(Hit)) != 0;
        dynamic_hits += w[i].instance == dynamic_instance;
      }
      CHECK(differ == 0);
      CHECK(dynamic_hits > 0u);
      // A ray that hits the dynamic cell: the same events (its list walked in ascending order)
      for (size_t i = 0; i < rays.size(); ++i) {
        if (w[i].instance != dynamic_instance) continue;
        const plan::ExplainRecord re = cpu.explain_ray(rays[i]);
        const plan::ExplainRecord ge = vk.explain_ray(rays, uint32_t(i));
        REQUIRE(re.events.size() == ge.events.size());
        CHECK(std::memcmp(re.events.data(), ge.events.data(), re.events.size() * sizeof(sh::ExplainEvent)) == 0);
        break;
      }
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan compact layout: a scene whose every triangle has zero area holds no reference and every ray "
          "misses, as on the reference",
          "[vulkan][diff][grid][compact]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  // Collinear vertices, a repeated vertex, a point: the build inserts none of them (triangle_normal is 0)
  Mesh m;
  m.name = "degenerate";
  m.positions = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 0, 1}, {3, 0, 1}, {4, 2, 0}, {1, 3, 2}, {1, 3, 2}, {1, 3, 2}};
  m.triangles = {{0, 1, 2}, {3, 4, 5}, {6, 7, 8}, {2, 1, 0}};
  m.materials.assign(m.triangles.size(), 0u);
  Scene s;
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "static", .mesh = 0});
  s.instances.push_back(Instance{.name = "dynamic", .mesh = 0, .dynamic = true});
  s.finalize();
  GridOptions o;
  o.traversal = Traversal::exact;
  o.layout = GridOptions::Layout::compact;
  o.threads = 2;
  ReferenceGridTracer cpu(o);
  cpu.build(s, 0.0f);
  REQUIRE((cpu.data().params.flags & sh::kGridCompact) != 0u);
  CHECK(cpu.data().offsets.back() == 0u);
  VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
  vk.build(s, 0.0f);  // threw "the compact build counted 0 static references, the plan 1" before
  CHECK(reference::compare_texels(cpu.dump(), vk.dump()).differing.empty());
  CHECK(reference::compare_spill(cpu.spill(), vk.spill()).same());
  const std::vector<Ray> rays = gridtest::box_rays(cpu.data(), 500, 4.0f, 3);
  std::vector<Hit> w(rays.size()), g(rays.size());
  cpu.trace(rays, w);
  vk.trace(rays, g);
  size_t misses = 0, differ = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    misses += is_miss(w[i]);
    differ += std::memcmp(&w[i], &g[i], sizeof(Hit)) != 0;
  }
  CHECK(misses == rays.size());
  CHECK(differ == 0u);
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan exact trace: rays through thousands of copies of one triangle agree with the reference, or are "
          "refused on llvmpipe past its loop limit",
          "[vulkan][diff][grid][compact][hardcase]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const bool llvmpipe = ctx.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE;
  for (uint32_t copies : {1000u, 5000u}) {
    INFO(copies << " copies");
    Mesh m;
    m.name = "stack";
    m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (uint32_t i = 0; i < copies; ++i) m.triangles.push_back({0, 1, 2});
    m.materials.assign(m.triangles.size(), 0u);
    Scene s;
    s.meshes.push_back(m);
    s.instances.push_back(Instance{.name = "stack", .mesh = 0});
    s.finalize();
    GridOptions o;
    o.traversal = Traversal::exact;
    o.layout = GridOptions::Layout::compact;
    o.resolution = glm::uvec3(4, 4, 1);
    o.threads = 2;
    ReferenceGridTracer cpu(o);
    VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
    cpu.build(s, 0.0f);
    vk.build(s, 0.0f);
    // Down through the triangle (a hit: the smallest reference of the ties) and beside it (a miss)
    std::vector<Ray> rays;
    for (float x : {0.1f, 0.3f, 0.9f})
      for (float y : {0.05f, 0.4f, 0.8f}) {
        Ray r{};
        r.org = glm::vec3(x, y, 1.0f);
        r.dir = glm::vec3(0.0f, 0.0f, -1.0f);
        r.tmax = std::numeric_limits<float>::infinity();
        r.launch_ref = sh::kNoRef;
        rays.push_back(r);
      }
    std::vector<Hit> w(rays.size()), g(rays.size());
    cpu.trace(rays, w);
    uint32_t most = 0;
    uint64_t iterations = 0;
    for (const Hit& h : w) {
      most = std::max(most, h.tests);
      iterations = std::max(iterations, vulkan::llvmpipe_loop_estimate(vk.params(), h.tests, h.cells));
    }
    CHECK(most >= copies);
    if (llvmpipe && iterations >= vulkan::kLlvmpipeLoopBudget) {
      CHECK_THROWS_WITH(vk.trace(rays, g), Catch::Contains("llvmpipe"));
      continue;
    }
    vk.trace(rays, g);
    for (size_t i = 0; i < rays.size(); ++i) CHECK(std::memcmp(&w[i], &g[i], sizeof(Hit)) == 0);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

// An outside sweep's find: the guard counted only the exact trace's tests, and a ray walking
// thousands of cells with one test (down a tube of empty cells) was cut by llvmpipe's loop limit
// near 5,000 cells: a wrong record, a surface drawn in shadow with exit 0. The guard estimates
// the walk's iterations too (vulkan::llvmpipe_loop_estimate).
TEST_CASE("Vulkan exact trace: rays through thousands of empty cells agree with the reference, or are refused on "
          "llvmpipe past its loop limit",
          "[vulkan][diff][grid][compact][hardcase]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const bool llvmpipe = ctx.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE;
  Mesh m;  // a small triangle at x = 0 and one across the tube (0.03 wide) at x = 1200
  m.name = "tube";
  m.positions = {{0, 0, 0},         {0, 0.01f, 0},        {0, 0, 0.01f},
                 {1200, -0.01f, -0.01f}, {1200, 0.02f, -0.01f}, {1200, -0.01f, 0.02f}};
  m.triangles = {{0, 1, 2}, {3, 4, 5}};
  m.materials = {0, 0};
  Scene s;
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "tube", .mesh = 0});
  s.finalize();
  for (const uint32_t cells : {1000u, 8000u}) {
    INFO(cells << " cells along x");
    GridOptions o;
    o.traversal = Traversal::exact;
    o.layout = GridOptions::Layout::compact;
    o.skip_empty = false;
    o.resolution = glm::uvec3(cells, 16, 16);  // cubic cells: the grid box's padding keeps them at least 0.15
    o.threads = 2;
    ReferenceGridTracer cpu(o);
    VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
    cpu.build(s, 0.0f);
    vk.build(s, 0.0f);
    std::vector<Ray> rays;
    for (const glm::vec2 yz : {glm::vec2(-0.005f, 0.005f), glm::vec2(0.009f, -0.005f)}) {  // beside the small one
      Ray r{};
      r.org = glm::vec3(-1.0f, yz.x, yz.y);
      r.dir = glm::vec3(1.0f, 0.0f, 0.0f);
      r.tmax = std::numeric_limits<float>::infinity();
      r.launch_ref = sh::kNoRef;
      rays.push_back(r);
    }
    std::vector<Hit> w(rays.size()), g(rays.size());
    cpu.trace(rays, w);
    uint64_t iterations = 0;
    for (const Hit& h : w) {
      REQUIRE(!is_miss(h));
      CHECK(h.triangle == 1u);
      CHECK(h.cells >= cells * 9 / 10);
      iterations = std::max(iterations, vulkan::llvmpipe_loop_estimate(vk.params(), h.tests, h.cells));
    }
    if (llvmpipe && iterations >= vulkan::kLlvmpipeLoopBudget) {
      CHECK(cells == 8000u);
      CHECK_THROWS_WITH(vk.trace(rays, g), Catch::Contains("llvmpipe"));
      continue;
    }
    vk.trace(rays, g);
    for (size_t i = 0; i < rays.size(); ++i) CHECK(std::memcmp(&w[i], &g[i], sizeof(Hit)) == 0);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}
