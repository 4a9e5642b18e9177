// test_grid_any_hit.cpp: the grid's any-hit trace (docs/SPEC.md "Any hit"; shadow rays), against
// the closest-hit trace of the same grid on every ray of each batch:
//  - it hits exactly where the closest hit does (occlusion is the closest hit's), gap-fill included;
//  - its hit is the closest-hit trace's first accepted candidate (the first kEvCandidate of the
//    closest trace's events), and its events are the closest trace's up to that candidate, then
//    the report: the same walk, cut short;
//  - without a candidate it is the closest trace's record in bits;
//  - it never reads more cells or tests more references.
// Both traversals, both layouts, skipping on and off, saturated cells (spill list, gap-fill), alpha
// keying, launch triangles (rays leaving surfaces, as shadow rays do), through updates.
#include <catch2/catch.hpp>

#include <random>

#include "gridrt/common/builtin/builtin.h"
#include "tests/test_grid_util.h"

using namespace gridrt;
using reference::GridOptions;
using reference::ReferenceGridTracer;
namespace sh = gridrt::shared;

namespace {

struct Totals {
  uint64_t rays = 0, hits = 0, with_candidate = 0, tests_closest = 0, tests_any = 0, gap_fill = 0;
};

// Every property of the file's header on every ray; `t` counts.
void check_any_hit(ReferenceGridTracer& grid, const std::vector<Ray>& rays, Totals& t) {
  std::vector<Hit> closest(rays.size()), any(rays.size());
  grid.trace(rays, closest);
  grid.trace_any(rays, any);
  for (size_t i = 0; i < rays.size(); ++i) {
    const Hit& c = closest[i];
    const Hit& a = any[i];
    INFO("ray " << i << " " << gridtest::hx(rays[i]) << "\nclosest " << gridtest::hx(c) << "\nany     "
                << gridtest::hx(a));
    REQUIRE(is_miss(a) == is_miss(c));
    REQUIRE(a.tests <= c.tests);
    REQUIRE(a.cells <= c.cells);
    t.rays += 1;
    t.hits += !is_miss(c);
    t.tests_closest += c.tests;
    t.tests_any += a.tests;
    t.gap_fill += (a.flags & sh::kHitGapFill) != 0u;
    // The closest trace's events and its first candidate
    const reference::ExplainRecord ce = grid.explain_ray(rays[i]);
    const reference::ExplainRecord ae = grid.explain_ray(rays[i], sh::kTraceAnyHit);
    REQUIRE(ae.mode == sh::kTraceAnyHit);
    REQUIRE(std::memcmp(&ae.hit, &a, sizeof(Hit)) == 0);  // the explain traces as trace_any does
    size_t first = ce.events.size();
    for (size_t k = 0; k < ce.events.size(); ++k)
      if (ce.events[k].kind == sh::kEvCandidate) {
        first = k;
        break;
      }
    if (first == ce.events.size()) {
      // No candidate: the same walk to the end, the same record
      REQUIRE(std::memcmp(&a, &c, sizeof(Hit)) == 0);
      REQUIRE(ae.events.size() == ce.events.size());
      continue;
    }
    t.with_candidate += 1;
    // The same events up to the candidate, then the report of that candidate
    REQUIRE(ae.events.size() == first + 2);
    for (size_t k = 0; k <= first; ++k) {
      INFO("event " << k);
      REQUIRE(std::memcmp(&ae.events[k], &ce.events[k], sizeof(sh::ExplainEvent)) == 0);
    }
    const sh::ExplainEvent& cand = ce.events[first];
    REQUIRE(ae.events[first + 1].kind == sh::kEvReport);
    REQUIRE(a.instance == sh::ref_instance(cand.ref));
    REQUIRE(a.triangle == sh::ref_triangle(cand.ref));
    REQUIRE(a.t == cand.f0.x);
    REQUIRE(a.u == cand.f0.y);
    REQUIRE(a.v == cand.f0.z);
    REQUIRE((a.flags & sh::kHitGapFill) == 0u);
  }
}

GridOptions options(reference::Traversal traversal, bool compact, bool skip) {
  GridOptions o;
  o.threads = 2;
  o.traversal = traversal;
  o.layout = compact ? GridOptions::Layout::compact : GridOptions::Layout::image;
  o.skip_empty = skip;
  return o;
}

}  // namespace

TEST_CASE("Any hit: occluded exactly where the closest hit is, at its first candidate, in no more tests",
          "[grid][any-hit]") {
  using reference::Traversal;
  struct Case {
    const char* scene;
    Traversal traversal;
    bool compact, skip;
    std::optional<uint32_t> capacity;  // small: saturated cells (spill list, gap-fill)
  };
  const Case cases[] = {
      {"atrium", Traversal::exact, true, true, {}},  // the exact traversal's defaults; alpha keying
      {"atrium", Traversal::exact, false, false, {}},
      {"atrium", Traversal::paper, false, false, {}},  // the paper's defaults
      {"atrium", Traversal::paper, false, false, 4u},  // saturated: gap-fill, spill list
      {"fan", Traversal::exact, false, true, 4u},      // slivers over a few cells: long spill lists
      {"fan", Traversal::paper, false, false, 4u},
      {"random", Traversal::exact, true, false, {}},   // dynamic instances in the compact layout
  };
  for (const Case& k : cases) {
    INFO(k.scene << (k.traversal == Traversal::exact ? " exact" : " paper") << (k.compact ? " compact" : " image")
                 << (k.skip ? " skip" : "") << (k.capacity ? " capacity " + std::to_string(*k.capacity) : ""));
    const std::string name = k.scene;
    const Scene scene = name == "fan"      ? gridtest::fan_scene(120, 1)
                        : name == "random" ? gridtest::random_scene(150, 0.8f, 10.0f, 5, 30)
                                           : make_builtin(name);
    GridOptions o = options(k.traversal, k.compact, k.skip);
    o.capacity = k.capacity;
    ReferenceGridTracer grid(o);
    grid.build(scene, 0.0f);
    Totals t;
    for (float time : {0.0f, 1.3f}) {
      if (time > 0.0f) grid.update(time);
      std::vector<Ray> rays = gridtest::leaving_rays(grid.data(), 1200, 17 + uint32_t(time * 10));
      if (name == "fan") {
        const std::vector<Ray> more = gridtest::fan_rays(grid.data(), 400, 23);
        rays.insert(rays.end(), more.begin(), more.end());
      }
      check_any_hit(grid, rays, t);
    }
    WARN(k.scene << ": " << t.rays << " rays, " << t.hits << " hit, " << t.with_candidate << " with a candidate, "
                 << t.gap_fill << " gap-fill; tests per ray closest " << double(t.tests_closest) / t.rays << ", any "
                 << double(t.tests_any) / t.rays);
    // The batches exercise what they are for: hits, rays that stop early, misses
    CHECK(t.hits > t.rays / 10);
    CHECK(t.hits < t.rays);
    CHECK(t.tests_any < t.tests_closest);
    if (k.capacity && k.traversal == Traversal::paper && name == "atrium") CHECK(t.gap_fill > 0);
  }
}
