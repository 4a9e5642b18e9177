// test_spill.cpp: the spill list (docs/SPEC.md, "Spill list") on the CPU reference: a saturated
// cell that no capacity the limits allow would hold (fans of triangles about vertices of high
// valence, capacity forced small) loses no reference and no hit with the spill list on, against
// the Embree oracle; the nearest hit does not depend on the order of the list; dynamic references
// spill and move, and the clear pass resets the counter; an overflow is counted and reported; and
// gap-fill runs only while a cell is saturated, leaving the output unchanged where it is left out.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cstring>
#include <random>

#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/reference/compare.h"
#include "tests/test_grid_util.h"

using namespace gridrt;
using namespace gridtest;
namespace sh = gridrt::shared;
using reference::GridData;
using reference::GridOptions;
using reference::ReferenceGridTracer;
using reference::Traversal;
using TT = GridOptions::TriangleTest;
using Spill = GridOptions::Spill;

namespace {

// The fan scene's grid: 8x8x8 cells of about one unit, capacity forced to 4 (the fan's cell holds
// 2n references, the room's corners 6).
GridOptions small_capacity(Traversal traversal, TT test, Spill spill) {
  GridOptions o;
  o.traversal = traversal;
  o.triangle_test = test;
  o.spill = spill;
  o.resolution = glm::uvec3(8);
  o.capacity = 4;
  o.threads = 2;
  return o;
}

// Against the oracle: same (instance, triangle), or both miss, or a tie (another triangle at a t
// within a relative 1e-5: a shared edge or vertex). Holes: the grid misses where Embree hits.
struct Oracle {
  size_t rays = 0, same = 0, ties = 0, holes = 0, false_hits = 0, other = 0;
  std::string first;
};
Oracle against_embree(std::span<const Ray> rays, std::span<const Hit> got, std::span<const Hit> want) {
  Oracle a;
  for (size_t i = 0; i < rays.size(); ++i) {
    ++a.rays;
    const Hit &g = got[i], &w = want[i];
    const bool gm = is_miss(g), wm = is_miss(w);
    bool ok = false;
    if (gm && wm) ok = true;
    else if (gm) ++a.holes;
    else if (wm || (g.flags & sh::kHitGapFill)) ++a.false_hits;
    else if (g.instance == w.instance && g.triangle == w.triangle) ok = true;
    else if (std::abs(double(g.t) - double(w.t)) <= 1e-5 * std::max(1.0, double(w.t))) ok = true, ++a.ties;
    else ++a.other;
    if (ok) ++a.same;
    else if (a.first.empty()) a.first = hx(rays[i]) + "\n  grid   " + hx(g) + "\n  embree " + hx(w);
  }
  return a;
}

std::string text(const Oracle& a) {
  return std::to_string(a.same) + "/" + std::to_string(a.rays) + " agree (" + std::to_string(a.ties) +
         " ties), holes " + std::to_string(a.holes) + ", false hits " + std::to_string(a.false_hits) +
         ", other triangle " + std::to_string(a.other) + (a.first.empty() ? "" : "\nfirst: " + a.first);
}

std::vector<Hit> trace_all(const GridData& grid, std::span<const Ray> rays) {
  std::vector<Hit> hits(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) hits[i] = reference::scene_trace(grid, rays[i], nullptr);
  return hits;
}

size_t differing(std::span<const Hit> a, std::span<const Hit> b) {
  size_t n = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const bool same = std::memcmp(&a[i], &b[i], sizeof(Hit)) == 0;
    if (!same && n < 3) UNSCOPED_INFO("ray " << i << ": " << hx(a[i]) << " vs " << hx(b[i]));
    n += !same;
  }
  return n;
}

}  // namespace

TEST_CASE("Spill: a fan of 128 triangles about two vertices in one cell of capacity 4 - exact mode with the spill "
          "list agrees with Embree on every ray, no holes",
          "[hardcase][oracle][grid]") {
  const Scene scene = fan_scene(64);
  EmbreeTracer embree(2);
  embree.build(scene, 0.0f);
  for (TT test : {TT::watertight, TT::moller}) {
    INFO((test == TT::watertight ? "watertight" : "moller"));
    ReferenceGridTracer grid(small_capacity(Traversal::exact, test, Spill::automatic));
    grid.build(scene, 0.0f);
    const reference::GridStats s = grid.stats();
    INFO(reference::to_text(s));
    REQUIRE(s.spill_on);  // automatic: on for the exact traversal
    CHECK(s.saturated_static > 0);
    CHECK(s.spill_appended >= 124);  // the fan's cell alone drops 128 - 4
    CHECK(s.spill_stored == s.spill_appended);
    CHECK(s.spill_overflow == 0);
    const std::vector<Ray> rays = fan_rays(grid.data(), 3000, 11);
    std::vector<Hit> want(rays.size()), got(rays.size());
    embree.trace(rays, want);
    grid.trace(rays, got);
    const Oracle a = against_embree(rays, got, want);
    INFO(text(a));
    CHECK(a.same == a.rays);
    CHECK(a.holes == 0);
    CHECK(a.false_hits == 0);
    // The case is hard: without the spill list the same grid loses hits
    ReferenceGridTracer dropped(small_capacity(Traversal::exact, test, Spill::off));
    dropped.build(scene, 0.0f);
    dropped.trace(rays, got);
    const Oracle b = against_embree(rays, got, want);
    INFO("spill off: " << text(b));
    CHECK(b.same < b.rays - 100);
  }
}

TEST_CASE("Spill: each cell's spilled references are walked in ascending order whatever the order of the appends",
          "[grid]") {
  const Scene scene = fan_scene(48, 8);
  for (Traversal traversal : {Traversal::exact, Traversal::paper}) {
    INFO((traversal == Traversal::exact ? "exact" : "paper"));
    GridOptions o = small_capacity(traversal, TT::moller, Spill::on);
    GridData grid;
    reference::scene_build(grid, scene, 0.0f, o);
    REQUIRE(grid.spill_header.count > 100);
    std::string problem;
    const std::vector<reference::SpillList> lists = reference::walk_spill_lists(reference::spill_dump(grid), &problem);
    INFO(problem);
    CHECK(problem.empty());
    size_t walked = 0;
    for (const reference::SpillList& l : lists) {
      walked += l.refs.size();
      CHECK(std::is_sorted(l.refs.begin(), l.refs.end()));
      // A static list holds static references, a dynamic one dynamic ones
      for (uint32_t ref : l.refs) CHECK((ref >= grid.params.comparison_offset) == (l.head % 2 == 1));
    }
    CHECK(walked == grid.spill_header.count);
    const std::vector<Ray> rays = fan_rays(grid, 2000, 5);
    const std::vector<Hit> first = trace_all(grid, rays);
    // Builds on other thread counts in shuffled orders append in other orders: the same lists,
    // the same hits, the same explained events
    for (uint64_t seed : {77u, 78u, 79u}) {
      o.threads = unsigned(seed % 4 + 1);
      o.shuffle_seed = seed;
      GridData other;
      reference::scene_build(other, scene, 0.0f, o);
      const reference::SpillDiff d = reference::compare_spill(reference::spill_dump(grid), reference::spill_dump(other));
      CHECK(d.same());
      CHECK(differing(first, trace_all(other, rays)) == 0);
      size_t explained = 0;
      for (size_t i = 0; i < rays.size() && explained < 10; ++i) {
        reference::ExplainRecord a, b;
        reference::scene_trace(grid, rays[i], &a);
        reference::scene_trace(other, rays[i], &b);
        REQUIRE(a.events.size() == b.events.size());
        CHECK(std::memcmp(a.events.data(), b.events.data(), a.events.size() * sizeof(sh::ExplainEvent)) == 0);
        CHECK(std::memcmp(&a.hit, &first[i], sizeof(Hit)) == 0);
        bool spilled = false;
        for (const sh::ExplainEvent& e : a.events) spilled = spilled || e.kind == sh::kEvSpilled;
        if (!spilled) continue;
        ++explained;
        const std::string t = reference::to_text(a);
        CHECK(t.find("spill list: the cell dropped references") != std::string::npos);
        CHECK(t.find("spilled 0: 0x") != std::string::npos);
      }
      CHECK(explained == 10);
    }
  }
}

TEST_CASE("Spill: dynamic references spill, move away and back - the clear pass resets the counter and the update "
          "equals a fresh build",
          "[hardcase][oracle][grid]") {
  const Scene scene = fan_scene(32, 16);
  for (auto insertion : {reference::Insertion::sorted, reference::Insertion::first_empty}) {
    const bool sorted = insertion == reference::Insertion::sorted;
    INFO((sorted ? "sorted" : "first-empty"));
    GridOptions o = small_capacity(Traversal::exact, TT::watertight, Spill::on);
    o.insertion = insertion;
    o.spill_capacity = 4096;
    ReferenceGridTracer grid(o);
    grid.build(scene, 0.0f);
    EmbreeTracer embree(2);
    embree.build(scene, 0.0f);
    const uint32_t statics = grid.data().spill_header.static_count;
    CHECK(statics >= 64 - 4);
    uint32_t least = ~0u, most = 0;
    for (float time : {0.5f, 1.0f, 2.0f, 3.0f, 4.0f, 2.0f, 0.0f}) {
      INFO("update to t = " << time);
      grid.update(time);
      embree.update(time);
      ReferenceGridTracer fresh(o);
      fresh.build(scene, time);
      // The counter is the fresh build's (not the sum of the frames'), the static part kept
      const reference::SpillDump a = grid.spill(), b = fresh.spill();
      CHECK(a.header.count == b.header.count);
      CHECK(a.header.static_count == statics);
      CHECK(b.header.static_count == statics);
      CHECK(a.overflow() == 0);
      least = std::min(least, a.header.count - statics);
      most = std::max(most, a.header.count - statics);
      if (sorted) {
        CHECK(reference::compare_spill(b, a).same());
        const reference::TexelDiff d = reference::compare_texels(fresh.dump(), grid.dump());
        CHECK(d.differing.empty());
      } else {
        // The slots and the spill together hold every candidate of a saturated cell once
        const reference::CellCheck c = reference::check_cells_as_multisets(grid.data(), grid.dump(), &a);
        CHECK(c.bad.empty());
        CHECK(c.saturated > 0);
      }
      // Every ray agrees with the oracle at that time
      const std::vector<Ray> rays = fan_rays(grid.data(), 1500, uint32_t(7 + time * 10));
      std::vector<Hit> want(rays.size()), got(rays.size()), again(rays.size());
      embree.trace(rays, want);
      grid.trace(rays, got);
      const Oracle r = against_embree(rays, got, want);
      INFO(text(r));
      CHECK(r.same == r.rays);
      if (sorted) {
        fresh.trace(rays, again);
        CHECK(differing(got, again) == 0);
      }
    }
    // The moving fan spilled more where it met the static one (t = 2) than away from it
    CHECK(most > least);
  }
}

TEST_CASE("Spill: an update past the forecast grows the list and inserts again - nothing lost, a fresh build's hits",
          "[hardcase][oracle][grid]") {
  for (GridOptions::Layout layout : {GridOptions::Layout::compact, GridOptions::Layout::image}) {
    INFO((layout == GridOptions::Layout::compact ? "compact" : "image") << " layout");
    const gridtest::SpillGrowthCase growth = gridtest::spill_growth_case(layout);
    const Scene& scene = growth.scene;
    const GridOptions& o = growth.options;
    const float peak = growth.peak;
    ReferenceGridTracer grid(o);
    grid.build(scene, 0.0f);
    const uint32_t forecast = grid.data().spill_header.capacity;
    REQUIRE(forecast > 0u);
    // The same forecast held fixed (as --spill-capacity): the update at the peak overflows it, so
    // the scene does reach past the forecast
    GridOptions fixed = o;
    fixed.spill_capacity = forecast;
    ReferenceGridTracer short_list(fixed);
    short_list.build(scene, 0.0f);
    short_list.update(peak);
    REQUIRE(short_list.spill().overflow() > 0u);
    EmbreeTracer embree(2);
    embree.build(scene, 0.0f);
    for (float time : {peak, 0.25f, 1.5f, peak}) {
      INFO("update to t = " << time);
      grid.update(time);
      embree.update(time);
      const reference::SpillDump a = grid.spill();
      CHECK(a.overflow() == 0u);
      CHECK(a.header.capacity > forecast);
      // Every ray agrees with the oracle and with a fresh build at that time, in every bit
      ReferenceGridTracer fresh(o);
      fresh.build(scene, time);
      const std::vector<Ray> rays = walk_rays(grid.data().params, uint32_t(11 + time * 8));
      std::vector<Hit> want(rays.size()), got(rays.size()), again(rays.size());
      embree.trace(rays, want);
      grid.trace(rays, got);
      fresh.trace(rays, again);
      // (against Embree the random rays alone: the lattice rays hit the slab's outer edges exactly,
      // where the watertight test and Embree's may part; against the fresh build, all of them)
      const size_t random = 3000;
      const Oracle r = against_embree(std::span(rays).first(random), std::span(got).first(random),
                                      std::span(want).first(random));
      INFO(text(r));
      CHECK(r.same == r.rays);
      CHECK(differing(got, again) == 0);
      size_t hits = 0;
      for (const Hit& h : got) hits += h.instance != sh::kNoInstance;
      CHECK(hits > rays.size() / 20);
    }
  }
}

TEST_CASE("Spill: an overflowing list is counted and reported, never silent", "[grid]") {
  const Scene scene = fan_scene(64);
  GridOptions o = small_capacity(Traversal::exact, TT::moller, Spill::on);
  o.spill_capacity = 10;
  o.layout = GridOptions::Layout::image;  // the image's saturated cells spill (the compact layout drops nothing)
  ReferenceGridTracer grid(o);
  grid.build(scene, 0.0f);  // prints the warning on stderr (the CLI test reads it)
  const reference::GridStats s = grid.stats();
  CHECK(s.spill_capacity == 10);
  CHECK(s.spill_stored == 10);
  CHECK(s.spill_appended >= 124);
  CHECK(s.spill_overflow == s.spill_appended - 10);
  const std::string t = reference::to_text(s);
  INFO(t);
  CHECK(t.find("lost to overflow (WARNING") != std::string::npos);
  // The trace still runs (and loses hits: the count says so)
  const std::vector<Ray> rays = fan_rays(grid.data(), 200, 1);
  std::vector<Hit> hits(rays.size());
  grid.trace(rays, hits);
  // The explain tells of it
  bool told = false;
  for (const Ray& r : rays) {
    const std::string e = reference::to_text(grid.explain_ray(r));
    if (e.find("the list overflowed") != std::string::npos) told = true;
    if (told) break;
  }
  CHECK(told);
  // The default capacity comes from the capacity trial: no overflow, with the capacity forced
  // (one candidate), the automatic policy's, and the percentile policy (which weighs no candidate:
  // the trial counts on the chosen grid)
  o.spill_capacity.reset();
  GridOptions automatic_policy = o, percentile = o;
  automatic_policy.capacity.reset();
  automatic_policy.max_image_dimension = 64;  // too small for the fan's cell: some cells saturate
  percentile.capacity.reset();
  percentile.capacity_policy = GridOptions::CapacityPolicy::percentile;
  for (const GridOptions& option : {o, automatic_policy, percentile}) {
    ReferenceGridTracer automatic(option);
    automatic.build(scene, 0.0f);
    const reference::GridStats st = automatic.stats();
    INFO(reference::to_text(st));
    CHECK(st.spill_appended > 0);
    CHECK(st.spill_overflow == 0);
    CHECK(st.spill_capacity >= st.spill_appended);
    CHECK(st.spill_capacity <= st.spill_appended + st.spill_appended / 4 + 64);  // the trial's forecast was exact
  }
}

TEST_CASE("Gap-fill runs only while some cell is saturated, and leaving it out changes no hit", "[grid][hardcase]") {
  // Capacity 8: the room's corners hold 6 references, a static fan of 5 triangles and a moving one of
  // 5 hold 5 each, and 10 where they meet (t near 2): saturation comes and goes with the motion.
  Scene scene;
  scene.name = "meeting fans";
  scene.meshes.push_back(box_mesh(glm::vec3(0.0f), glm::vec3(8.0f)));
  Mesh fan = fan_mesh({4.5f, 4.5f, 4.6f}, 0.2f, 0.2f, 5);
  std::erase_if(fan.triangles, [](const glm::uvec3& t) { return t.x != 0u; });  // the apex's five only
  fan.materials.resize(fan.triangles.size());
  scene.meshes.push_back(fan);
  Mesh moving = fan;
  for (glm::vec3& p : moving.positions) p += glm::vec3(-2.0f, 0.05f, -0.1f);
  scene.meshes.push_back(moving);
  scene.instances.push_back(Instance{.name = "room", .mesh = 0});
  scene.instances.push_back(Instance{.name = "fan", .mesh = 1});
  Instance d{.name = "moving", .mesh = 2, .dynamic = true};
  d.motion.path_points = {glm::vec3(0.0f), glm::vec3(2.0f, 0.0f, 0.0f)};
  d.motion.path_period = 4.0f;
  scene.instances.push_back(d);
  scene.finalize();

  GridOptions o;
  o.traversal = Traversal::paper;
  o.resolution = glm::uvec3(8);
  o.capacity = 8;
  o.threads = 2;
  GridOptions always = o;
  always.gap_fill_if_saturated = false;
  ReferenceGridTracer pruned(o), full(always);
  pruned.build(scene, 0.0f);
  full.build(scene, 0.0f);
  bool seen_off = false, seen_on = false;
  size_t gap_hits = 0;
  for (float time : {0.0f, 1.0f, 2.0f, 3.0f, 4.0f}) {
    INFO("t = " << time);
    if (time > 0.0f) {
      pruned.update(time);
      full.update(time);
    }
    const bool saturated = pruned.data().spill_header.count > 0;
    CHECK(saturated == (time == 2.0f));
    CHECK(((pruned.params().flags & sh::kGridGapFill) != 0u) == saturated);
    CHECK(pruned.stats().gap_fill_active == saturated);
    CHECK((full.params().flags & sh::kGridGapFill) != 0u);
    (saturated ? seen_on : seen_off) = true;
    // Rays at the fans from every side, and random ones
    const std::vector<Ray> rays = fan_rays(pruned.data(), 1500, uint32_t(time * 10 + 1));
    std::vector<Hit> a(rays.size()), b(rays.size());
    pruned.trace(rays, a);
    full.trace(rays, b);
    CHECK(differing(a, b) == 0);
    for (const Hit& h : b) gap_hits += (h.flags & sh::kHitGapFill) != 0;
  }
  CHECK(seen_on);
  CHECK(seen_off);
  CHECK(gap_hits > 0);  // where a cell is saturated gap-fill does run
}

TEST_CASE("Spill: the paper traversal with the spill list tests the spilled references and gap-fills nothing",
          "[grid]") {
  const Scene scene = fan_scene(64);
  EmbreeTracer embree(2);
  embree.build(scene, 0.0f);
  GridOptions gap = small_capacity(Traversal::paper, TT::moller, Spill::automatic);
  GridOptions spill = small_capacity(Traversal::paper, TT::moller, Spill::on);
  ReferenceGridTracer a(gap), b(spill);
  a.build(scene, 0.0f);
  b.build(scene, 0.0f);
  CHECK((a.params().flags & sh::kGridSpill) == 0u);  // automatic: off for the paper traversal
  CHECK((a.params().flags & sh::kGridGapFill) != 0u);
  CHECK((b.params().flags & sh::kGridGapFill) == 0u);  // the spilled references replace gap-fill
  const std::vector<Ray> rays = fan_rays(b.data(), 2000, 9);
  std::vector<Hit> want(rays.size()), ha(rays.size()), hb(rays.size());
  embree.trace(rays, want);
  a.trace(rays, ha);
  b.trace(rays, hb);
  const Oracle oa = against_embree(rays, ha, want), ob = against_embree(rays, hb, want);
  INFO("gap-fill: " << text(oa) << "\nspill: " << text(ob));
  for (const Hit& h : hb) CHECK((h.flags & sh::kHitGapFill) == 0u);
  CHECK(ob.false_hits == 0);
  CHECK(ob.same > oa.same);
}
