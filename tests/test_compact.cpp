// test_compact.cpp: the compact layout (docs/SPEC.md "Compact layout") on the CPU reference: the
// same hits as the image layout, every ray in bits, on random scenes and through update frames;
// its arrays' invariants (offsets monotone, each cell's run ascending, every (triangle, cell) pair
// the cell test accepts present exactly once, the dynamic references in their cells' spill lists);
// the memory function equal to what the build allocates; bad combinations refused clearly.
#include <catch2/catch.hpp>

#include <algorithm>
#include <bit>
#include <cstring>
#include <random>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/reference/compare.h"
#include "tests/run_tool.h"
#include "tests/test_grid_util.h"

using namespace gridrt;
using reference::GridOptions;
using reference::ReferenceGridTracer;
using reference::Traversal;
namespace sh = gridrt::shared;

namespace {

GridOptions compact_options(GridOptions::Layout layout) {
  GridOptions o;
  o.traversal = Traversal::exact;
  o.layout = layout;
  o.threads = 2;
  o.skip_covered = false;  // the layouts alone, test for test (covered cells: test_grid_covered.cpp)
  return o;
}

size_t differing(std::span<const Hit> a, std::span<const Hit> b) {
  size_t n = 0;
  for (size_t i = 0; i < a.size(); ++i) n += std::memcmp(&a[i], &b[i], sizeof(Hit)) != 0;
  return n;
}

// The compact arrays against the candidates recomputed from the geometry buffer.
void check_compact_invariants(const reference::GridData& grid) {
  const sh::GridParams& g = grid.params;
  REQUIRE((g.flags & sh::kGridCompact) != 0u);
  const size_t cells = sh::grid_cell_count(g);
  if ((g.flags & sh::kGridSparseOffsets) == 0u) {
    // Dense offsets: one per cell, ascending from 0, then the total
    REQUIRE(grid.offsets.size() == cells + 1);
    CHECK(grid.offsets.front() == 0u);
    for (size_t c = 0; c < cells; ++c) REQUIRE(grid.offsets[c] <= grid.offsets[c + 1]);
  } else {
    // The index of occupied cells: per word of 32 cells its base (the occupied cells before it) and
    // mask, then one start per occupied cell (ascending from 0, each run non-empty), then the total
    const uint32_t runs = sh::compact_runs_base(uint32_t(cells));
    REQUIRE(grid.offsets.size() > runs);
    const size_t occupied = grid.offsets.size() - runs - 1;
    uint32_t before = 0;
    for (uint32_t w = 0; w < sh::compact_word_count(uint32_t(cells)); ++w) {
      CHECK(grid.offsets[2 * w] == before);
      const uint32_t mask = grid.offsets[2 * w + 1];
      if (32 * size_t(w + 1) > cells) CHECK((uint64_t(mask) >> (cells - 32 * w)) == 0u);  // no bit past the last cell
      before += uint32_t(std::popcount(mask));
    }
    CHECK(before == occupied);
    CHECK(grid.offsets[runs] == 0u);
    for (size_t k = 0; k < occupied; ++k) CHECK(grid.offsets[runs + k] < grid.offsets[runs + k + 1]);
    CHECK(reference::compact_occupied_cells(grid) == occupied);
  }
  CHECK(grid.offsets.back() <= grid.refs.size());  // refs: the plan's count (at least one word)
  const std::vector<std::vector<uint32_t>> cand = reference::cell_candidates(grid);
  size_t bad_order = 0, bad_set = 0, bad_dynamic = 0;
  const reference::SpillDump spill = reference::spill_dump(grid);
  std::string problem;
  const std::vector<reference::SpillList> lists = reference::walk_spill_lists(spill, &problem);
  CHECK(problem.empty());
  std::vector<std::vector<uint32_t>> dynamic(cells);
  for (const reference::SpillList& l : lists) {
    REQUIRE(l.head % 4 == 1);  // only dynamic lists
    dynamic[l.head / 4] = l.refs;
  }
  for (size_t c = 0; c < cells; ++c) {
    uint32_t begin = 0, end = 0;
    const bool has_run = reference::compact_run(grid, uint32_t(c), begin, end);
    REQUIRE(begin <= end);
    REQUIRE(end <= grid.refs.size());
    const std::vector<uint32_t> run(grid.refs.begin() + begin, grid.refs.begin() + end);
    if (has_run != !run.empty()) ++bad_set;
    if (!std::is_sorted(run.begin(), run.end()) || std::adjacent_find(run.begin(), run.end()) != run.end()) ++bad_order;
    std::vector<uint32_t> want_static, want_dynamic;
    for (uint32_t r : cand[c]) (r < g.comparison_offset ? want_static : want_dynamic).push_back(r);
    std::sort(want_static.begin(), want_static.end());
    std::sort(want_dynamic.begin(), want_dynamic.end());
    if (run != want_static) ++bad_set;
    if (dynamic[c] != want_dynamic) ++bad_dynamic;
  }
  CHECK(bad_order == 0);
  CHECK(bad_set == 0);
  CHECK(bad_dynamic == 0);
}

}  // namespace

TEST_CASE("Compact layout: the arrays hold every (triangle, cell) pair the cell test accepts once, each run "
          "ascending - the dynamic references in their cells' spill lists, through updates",
          "[grid][compact]") {
  const Scene scene = gridtest::random_scene(600, 0.6f, 8.0f, 11, 120);
  for (int variant = 0; variant < 3; ++variant) {
    const bool skip = variant != 1;
    INFO((skip ? "skip field on, " : "skip field off, ") << (variant == 2 ? "sparse offsets" : "dense offsets"));
    GridOptions o = compact_options(GridOptions::Layout::automatic);  // auto: compact for the exact traversal
    o.skip_empty = skip;
    o.offsets = variant == 2 ? GridOptions::Offsets::sparse : GridOptions::Offsets::dense;
    o.shuffle_seed = 5;
    ReferenceGridTracer t(o);
    t.build(scene, 0.0f);
    REQUIRE(((t.params().flags & sh::kGridSparseOffsets) != 0u) == (variant == 2));
    check_compact_invariants(t.data());
    CHECK(t.data().spill_header.static_count == 0u);
    CHECK(t.data().spill_header.count > 0u);
    for (float time : {0.7f, 1.9f}) {
      INFO("t = " << time);
      t.update(time);
      check_compact_invariants(t.data());
    }
  }
}

TEST_CASE("Compact layout: the same hit as the image layout for every ray, in bits, on random scenes through "
          "update frames",
          "[grid][compact]") {
  for (uint32_t seed : {3u, 8u}) {
    INFO("seed " << seed << (seed == 8u ? ", sparse offsets" : ", dense offsets"));
    const Scene scene = gridtest::random_scene(500, 0.7f, 8.0f, seed, 90);
    GridOptions oc = compact_options(GridOptions::Layout::compact), oi = compact_options(GridOptions::Layout::image);
    oc.offsets = seed == 8u ? GridOptions::Offsets::sparse : GridOptions::Offsets::dense;
    // The same cells for both (the image layout's capacity small: saturated cells spill)
    oc.resolution = oi.resolution = glm::uvec3(14, 12, 13);
    oi.capacity = 6;
    ReferenceGridTracer c(oc), i(oi);
    c.build(scene, 0.0f);
    i.build(scene, 0.0f);
    REQUIRE((c.params().flags & sh::kGridCompact) != 0u);
    REQUIRE((i.params().flags & sh::kGridCompact) == 0u);
    REQUIRE(i.data().spill_header.static_count > 0u);
    for (float time : {0.0f, 1.1f, 2.6f}) {
      INFO("t = " << time);
      if (time > 0.0f) c.update(time), i.update(time);
      const std::vector<Ray> rays = gridtest::box_rays(c.data(), 3000, 8.0f, seed * 7 + uint32_t(time * 10));
      std::vector<Hit> hc(rays.size()), hi(rays.size());
      c.trace(rays, hc);
      i.trace(rays, hi);
      CHECK(differing(hc, hi) == 0);
      size_t hits = 0;
      for (const Hit& h : hc) hits += !is_miss(h);
      CHECK(hits > rays.size() / 2);
    }
    // The explained ray: the same report
    const Ray ray = gridtest::box_rays(c.data(), 1, 8.0f, 99)[0];
    const reference::ExplainRecord ec = c.explain_ray(ray), ei = i.explain_ray(ray);
    CHECK(std::memcmp(&ec.hit, &ei.hit, sizeof(Hit)) == 0);
  }
  // Each layout's own default grid: the same hits (instance, triangle, t, u, v)
  const Scene scene = gridtest::random_scene(400, 0.5f, 6.0f, 21, 60);
  ReferenceGridTracer c(compact_options(GridOptions::Layout::compact)), i(compact_options(GridOptions::Layout::image));
  c.build(scene, 0.5f);
  i.build(scene, 0.5f);
  const std::vector<Ray> rays = gridtest::box_rays(c.data(), 2000, 6.0f, 4);
  std::vector<Hit> hc(rays.size()), hi(rays.size());
  c.trace(rays, hc);
  i.trace(rays, hi);
  size_t other = 0;
  for (size_t k = 0; k < rays.size(); ++k)
    other += hc[k].instance != hi[k].instance || hc[k].triangle != hi[k].triangle || std::memcmp(&hc[k].t, &hi[k].t, 4) != 0 ||
             std::memcmp(&hc[k].u, &hi[k].u, 4) != 0 || std::memcmp(&hc[k].v, &hi[k].v, 4) != 0;
  CHECK(other == 0);
}

TEST_CASE("Compact layout: the memory function equals what the build allocates, and the policy keeps within "
          "the budget",
          "[grid][compact][unit]") {
  const Scene scene = gridtest::random_scene(700, 0.5f, 8.0f, 2, 80);
  for (int variant = 0; variant < 3; ++variant) {
    const GridOptions::Layout layout = variant == 2 ? GridOptions::Layout::image : GridOptions::Layout::compact;
    GridOptions o = compact_options(layout);
    if (layout == GridOptions::Layout::compact)
      o.offsets = variant == 1 ? GridOptions::Offsets::sparse : GridOptions::Offsets::dense;
    INFO("variant " << variant);
    ReferenceGridTracer t(o);
    t.build(scene, 0.0f);
    const plan::GridPlan p = plan::plan_grid(scene, 0.0f, o);
    const plan::GridMemory want =
        plan::grid_memory(t.params(), p.static_references, p.static_cells, p.spill_capacity, p.region.cells());
    const plan::GridMemory got = reference::grid_allocated(t.data());
    CHECK(want.image == got.image);
    CHECK(want.offsets == got.offsets);
    CHECK(want.refs == got.refs);
    CHECK(want.spill == got.spill);
    CHECK(want.heads == got.heads);
    CHECK(want.skip == got.skip);
    CHECK(want.dirty == got.dirty);
    CHECK(t.stats().memory.total() == want.total());
    if (layout == GridOptions::Layout::compact) {
      CHECK(want.total() <= plan::compact_budget(compact_options(layout), 780));
      CHECK(t.data().refs.size() == p.static_references);
    }
  }
  // A tight budget: coarser cells, still within it
  GridOptions tight = compact_options(GridOptions::Layout::compact);
  tight.memory_budget = 96 * 1024;
  ReferenceGridTracer t(tight);
  t.build(scene, 0.0f);
  CHECK(t.stats().memory.total() <= 96u * 1024u);
  // A resolution asked for that the budget cannot hold: refused, naming the budget (not the image,
  // which the compact layout does not have)
  tight.resolution = glm::uvec3(64u);
  ReferenceGridTracer over(tight);
  CHECK_THROWS_WITH(over.build(scene, 0.0f), Catch::Contains("over its memory budget") && Catch::Contains("--memory-budget"));
  tight.memory_budget = uint64_t(64) << 20;
  ReferenceGridTracer within(tight);
  within.build(scene, 0.0f);
  CHECK(within.params().cells == glm::uvec3(64u));
}

// The automatic offsets: dense where they fit the budget; a grid that fits only with sparse
// offsets is chosen only if its estimate beats the best dense grid's by kSparseOffsetsMargin.
// Checked on the candidates the policy weighed, over budgets from generous to tight.
TEST_CASE("Compact layout: automatic offsets - dense where they fit, sparse only for a grid whose estimate is "
          "kSparseOffsetsMargin cheaper",
          "[grid][compact][unit]") {
  // The built-in atrium (a room of open floors, columns and a moving sphere: most cells of a fine
  // grid empty) weighed under budgets from coarse to generous
  const Scene scene = make_builtin("atrium");
  uint32_t sparse_chosen = 0, dense_chosen = 0;
  for (uint64_t kib : {256u, 1024u, 1280u, 1536u, 1792u, 65536u}) {
    INFO("budget " << kib << " KiB");
    GridOptions o = compact_options(GridOptions::Layout::compact);
    o.memory_budget = kib * 1024;
    plan::GridPlan p;
    try {
      p = plan::plan_grid(scene, 0.0f, o);
    } catch (const Error&) {
      continue;  // nothing fits the tightest budgets
    }
    const plan::GridChoice& ch = p.choice;
    REQUIRE(!ch.candidates.empty());
    const plan::GridCandidate& c = ch.candidates[ch.chosen];
    CHECK(((p.params.flags & sh::kGridSparseOffsets) != 0u) == c.sparse_offsets);
    CHECK(c.memory <= kib * 1024);
    double best_dense = 1e300, best_any = 1e300;
    for (const plan::GridCandidate& k : ch.candidates) {
      CHECK(k.memory <= kib * 1024);
      best_any = std::min(best_any, k.cost);
      if (!k.sparse_offsets) best_dense = std::min(best_dense, k.cost);
    }
    if (c.sparse_offsets) {
      ++sparse_chosen;
      CHECK(c.cost == best_any);
      CHECK(c.cost <= plan::kSparseOffsetsMargin * best_dense);
    } else {
      ++dense_chosen;
      CHECK(c.cost == best_dense);
      CHECK(best_any >= plan::kSparseOffsetsMargin * best_dense);
    }
    // The plan sizes what the build allocates, either way
    ReferenceGridTracer t(o);
    t.build(scene, 0.0f);
    CHECK(t.params().flags == p.params.flags);
    CHECK(reference::grid_allocated(t.data()).total() <= kib * 1024);
    check_compact_invariants(t.data());
  }
  CHECK(dense_chosen > 0u);
  CHECK(sparse_chosen > 0u);  // (1.5 MiB: 48x28x71 with sparse offsets, docs/SPEC.md)
}

TEST_CASE("Compact layout: the paper traversal or spill off is refused with a clear message", "[grid][compact][cli]") {
  GridOptions o;
  o.layout = GridOptions::Layout::compact;
  const Scene scene = gridtest::random_scene(50, 0.5f, 4.0f, 1);
  ReferenceGridTracer paper(o);
  CHECK_THROWS_WITH(paper.build(scene, 0.0f), Catch::Contains("exact traversal"));
  o.traversal = Traversal::exact;
  o.spill = GridOptions::Spill::off;
  ReferenceGridTracer nospill(o);
  CHECK_THROWS_WITH(nospill.build(scene, 0.0f), Catch::Contains("--spill on"));
  // Options that contradict one another: the command line's error, exit 2 (an outside sweep found 1)
  const auto r = gridrt::test::run_tool("stats builtin:teapot --layout compact --traversal paper");
  CHECK(r.exit_code == 2);
  CHECK_THAT(r.output, Catch::Contains("compact layout is for the exact traversal"));
  // The offsets' form asked for: refused where the grid is an image, named on the compact layout
  const auto image = gridrt::test::run_tool("stats builtin:teapot --offsets sparse --traversal paper");
  CHECK(image.exit_code == 2);
  const auto no_spill = gridrt::test::run_tool("stats builtin:teapot --layout compact --traversal exact --spill off");
  CHECK(no_spill.exit_code == 2);
  CHECK_THAT(no_spill.output, Catch::Contains("needs --spill on"));
  CHECK_THAT(image.output, Catch::Contains("--offsets is the compact layout's"));
  const auto sparse = gridrt::test::run_tool("stats builtin:teapot --offsets sparse --traversal exact");
  CHECK(sparse.exit_code == 0);
  CHECK_THAT(sparse.output, Catch::Contains("sparse offsets (occupied cells only)"));
  const auto bad = gridrt::test::run_tool("stats builtin:teapot --offsets some");
  CHECK(bad.exit_code == 2);
}
