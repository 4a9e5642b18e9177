// The trace-cost capacity policy (plan/policy.h): its ray sample against the Embree oracle,
// its work estimates against the reference trace's own counters, its determinism, and what it
// buys over the no-saturation policy on a "teapot in a stadium" (measured work and accuracy).
#include <catch2/catch.hpp>

#include <cstring>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/reference/compare.h"
#include "gridrt/plan/policy.h"
#include "test_grid_util.h"

using namespace gridrt;
using namespace gridtest;
namespace sh = gridrt::shared;
using reference::GridCandidate;
using reference::GridChoice;
using reference::GridOptions;
using reference::ReferenceGridTracer;
using reference::Traversal;
using reference::WorkEstimate;

namespace {

// `n` copies of one right triangle of unit legs, one static instance.
Scene copies_of_one_triangle(uint32_t n) {
  Scene s;
  s.name = "copies";
  Mesh m;
  m.name = "copies";
  m.positions = {{0.0f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}};
  for (uint32_t i = 0; i < n; ++i) m.triangles.push_back({0u, 1u, 2u});
  m.materials.assign(m.triangles.size(), 0u);
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "", .mesh = 0});
  s.finalize();
  return s;
}

// The chosen candidate of the trace-cost policy, and the choice.
GridChoice choose(const Scene& scene, const GridOptions& o) {
  GridChoice choice;
  reference::choose_grid(scene, 0.0f, o, &choice);
  REQUIRE(!choice.candidates.empty());
  return choice;
}

// A grid built at exactly one candidate's cells, capacity and padding.
GridOptions at_candidate(GridOptions o, const GridCandidate& c) {
  o.cell_size = c.cell_size;
  if (!plan::compact_enabled(o)) o.capacity = c.capacity;  // the compact layout has no capacity
  o.aabb_padding = c.aabb_padding;
  return o;
}

// The built-in teapot (3552 triangles) inside a closed box 16 times its size: the density target
// makes cells that fit the box, which a no-saturation grid must make coarse around the teapot.
Scene teapot_in_a_stadium() {
  Scene s = make_builtin("teapot");
  const Bounds b = s.bounds(0.0f);
  const glm::vec3 c = 0.5f * (b.lo + b.hi);
  const float r = 8.0f * glm::length(b.extent());
  Mesh box;
  box.name = "stadium";
  for (int i = 0; i < 8; ++i)
    box.positions.push_back(c + r * glm::vec3(i & 1 ? 1.0f : -1.0f, i & 2 ? 1.0f : -1.0f, i & 4 ? 1.0f : -1.0f));
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    box.triangles.push_back({q[0], q[1], q[2]});
    box.triangles.push_back({q[0], q[2], q[3]});
  }
  box.materials.assign(box.triangles.size(), 0u);
  s.meshes.push_back(std::move(box));
  s.instances.push_back(Instance{.name = "stadium", .mesh = uint32_t(s.meshes.size() - 1)});
  s.finalize();
  return s;
}

}  // namespace

TEST_CASE("trace-cost policy: the sample's ray ends are the oracle's first hits", "[grid][policy][oracle]") {
  for (const char* name : {"teapot", "atrium"}) {
    INFO(name);
    const Scene scene = make_builtin(name);
    GridOptions o;
    o.threads = 2;
    const GridChoice choice = choose(scene, o);
    const reference::WorkSample& s = choice.sample;
    REQUIRE(s.rays.size() > 500);
    CHECK(s.bounce == scene.has_glossy());
    EmbreeTracer embree(2);
    embree.build(scene, 0.0f);
    std::vector<Hit> want(s.rays.size());
    embree.trace(s.rays, want);
    size_t same = 0, hits = 0;
    for (size_t i = 0; i < s.rays.size(); ++i) {
      hits += !is_miss(want[i]);
      const bool miss = !std::isfinite(s.t_end[i]);
      if (miss == is_miss(want[i]) && (miss || reference::ulp_distance(s.t_end[i], want[i].t) <= 64)) ++same;
      else if (same + 4 > i) UNSCOPED_INFO("ray " << i << ": sample t " << s.t_end[i] << ", Embree " << hx(want[i]));
    }
    WARN(name << ": " << same << " of " << s.rays.size() << " sample rays end where Embree's do (" << hits << " hits)");
    CHECK(hits > s.rays.size() / 5);
    CHECK(double(same) >= 0.999 * double(s.rays.size()));
  }
}

TEST_CASE("trace-cost policy: estimated cells and tests per ray are the reference trace's counters",
          "[grid][policy]") {
  // The chosen grid rebuilt, the sample traced through it: where no cell saturates, exact
  // traversal visits exactly the cells the estimate walks (with empty-space skipping, the same
  // steps over empty cells: the skip field the estimate computes from the trial counts is the
  // build's) and tests exactly its references. Paper traversal, or saturated cells: within 5 % (the
  // estimate takes the hit as found in its own segment's visit or the next, and a saturated cell as
  // keeping the launch triangle).
  struct Mode {
    Traversal traversal;
    bool skip;
  };
  for (const char* name : {"teapot", "atrium"}) {
    for (const Mode mode : {Mode{Traversal::exact, true}, Mode{Traversal::exact, false}, Mode{Traversal::paper, false}}) {
      const Traversal t = mode.traversal;
      INFO(name << (t == Traversal::exact ? " exact" : " paper") << (mode.skip ? ", skipping" : ""));
      const Scene scene = make_builtin(name);
      GridOptions o;
      o.threads = 2;
      o.traversal = t;
      o.skip_empty = mode.skip;
      o.mailbox = false;     // the estimate tests every reference of every visit (the mailbox only drops re-tests,
      o.skip_covered = false;  // covered cells whole runs of them)
      const GridChoice choice = choose(scene, o);
      const GridCandidate& c = choice.candidates[choice.chosen];
      ReferenceGridTracer grid(at_candidate(o, c));
      grid.build(scene, 0.0f);
      CHECK(grid.params().cells == c.cells);
      std::vector<Hit> hits(choice.sample.rays.size());
      grid.trace(choice.sample.rays, hits);
      const WorkEstimate m = reference::measured_work(choice.sample.rays, hits);
      WARN(name << ": estimated " << c.work.cells << " cells, " << c.work.tests << " tests per ray; measured "
                << m.cells << ", " << m.tests << "; saturated cells " << c.saturated_cells);
      if (t == Traversal::exact && c.saturated_cells == 0) {
        CHECK(m.cells == Approx(c.work.cells).epsilon(1e-12));
        CHECK(m.tests == Approx(c.work.tests).epsilon(1e-12));
      } else {
        CHECK(m.cells == Approx(c.work.cells).epsilon(0.05));
        CHECK(m.tests == Approx(c.work.tests).epsilon(0.05));
      }
      if (t == Traversal::exact) {
        // With the mailbox (the default): the same cells, at most the estimated tests
        o.mailbox = true;
        ReferenceGridTracer mailbox(at_candidate(o, c));
        mailbox.build(scene, 0.0f);
        std::vector<Hit> fewer(hits.size());
        mailbox.trace(choice.sample.rays, fewer);
        const WorkEstimate f = reference::measured_work(choice.sample.rays, fewer);
        WARN(name << ": measured with the mailbox " << f.cells << " cells, " << f.tests << " tests per ray");
        CHECK(f.cells == m.cells);
        CHECK(f.tests <= m.tests);
        // With covered cells skipped (the default, where the skip field is on): the same cells, at
        // most the estimated tests
        o.mailbox = false;
        o.skip_covered = true;
        ReferenceGridTracer covered(at_candidate(o, c));
        covered.build(scene, 0.0f);
        std::vector<Hit> skipped(hits.size());
        covered.trace(choice.sample.rays, skipped);
        const WorkEstimate v = reference::measured_work(choice.sample.rays, skipped);
        WARN(name << ": measured with covered cells skipped " << v.cells << " cells, " << v.tests << " tests per ray");
        CHECK(v.cells == m.cells);
        CHECK(v.tests <= m.tests);
      }
    }
  }
}

TEST_CASE("trace-cost policy: the same grid on any thread count", "[grid][policy]") {
  const Scene scene = make_builtin("atrium");
  GridOptions one;
  one.threads = 1;
  GridOptions three;
  three.threads = 3;
  const sh::GridParams a = reference::choose_grid(scene, 0.0f, one);
  const sh::GridParams b = reference::choose_grid(scene, 0.0f, three);
  CHECK(std::memcmp(&a, &b, sizeof a) == 0);
}

TEST_CASE("trace-cost policy: a teapot in a stadium gets a cheaper grid than no-saturation, as accurate",
          "[grid][policy][oracle]") {
  // The no-saturation policy takes the resolution nearest the density target whose fullest cell
  // fits; around a dense object in a huge box that is a coarse grid with long cell lists. The
  // trace-cost policy must do measurably less work per ray (the reference's own counters) with no
  // loss of exact-mode accuracy against Embree.
  const Scene scene = teapot_in_a_stadium();
  const Camera cam = scene.frame_camera();
  std::vector<Ray> rays;
  for (uint32_t y = 0; y < 48; ++y)
    for (uint32_t x = 0; x < 64; ++x) rays.push_back(camera_ray(cam, 64, 48, x, y));
  EmbreeTracer embree(2);
  embree.build(scene, 0.0f);
  std::vector<Hit> want(rays.size());
  embree.trace(rays, want);
  struct Run {
    double work = 0.0;
    size_t same = 0;
    sh::GridParams params{};
  };
  const auto run = [&](GridOptions::CapacityPolicy p) {
    GridOptions o;
    o.threads = 2;
    o.traversal = Traversal::exact;
    o.capacity_policy = p;
    o.max_image_dimension = 16384;
    ReferenceGridTracer grid(o);
    grid.build(scene, 0.0f);
    std::vector<Hit> got(rays.size());
    grid.trace(rays, got);
    const WorkEstimate m = reference::measured_work(rays, got);
    Run r;
    r.work = m.tests + double(plan::cell_visit_cost(o)) * m.cells;
    r.params = grid.params();
    for (size_t i = 0; i < rays.size(); ++i)
      r.same += is_miss(got[i]) == is_miss(want[i]) &&
                (is_miss(got[i]) || (got[i].instance == want[i].instance && got[i].triangle == want[i].triangle));
    return r;
  };
  const Run cost = run(GridOptions::CapacityPolicy::trace_cost);
  const Run nosat = run(GridOptions::CapacityPolicy::no_saturation);
  WARN("trace-cost: " << cost.params.cells.x << "x" << cost.params.cells.y << "x" << cost.params.cells.z << " cap "
                      << cost.params.capacity << ", work " << cost.work << " per ray, " << cost.same << " agree; "
                      << "no-saturation: " << nosat.params.cells.x << "x" << nosat.params.cells.y << "x"
                      << nosat.params.cells.z << " cap " << nosat.params.capacity << ", work " << nosat.work << ", "
                      << nosat.same << " agree, of " << rays.size());
  CHECK(cost.work < 0.8 * nosat.work);
  CHECK(cost.same >= nosat.same);
}

// A flat model far from the origin: the grid box is padded by at least the narrowest cell the
// domain allows there (1e-3 of the model's size would round away at z = 75,000), so the grid
// builds and a ray down onto the triangle finds it, on both traversals.
TEST_CASE("grid: a flat triangle far from the origin gets a grid and is hit", "[grid][policy][hardcase]") {
  Scene s;
  s.name = "flat far";
  Mesh m;
  m.name = "tri";
  m.positions = {{0, 0, 75000}, {1, 0, 75000}, {0, 1, 75000}};
  m.triangles = {{0, 1, 2}};
  m.materials = {0};
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "", .mesh = 0});
  s.finalize();
  for (Traversal t : {Traversal::exact, Traversal::paper}) {
    INFO((t == Traversal::exact ? "exact" : "paper"));
    ReferenceGridTracer grid(GridOptions{{.traversal = t}, {}, {.threads = 1}});
    REQUIRE_NOTHROW(grid.build(s, 0.0f));
    CHECK(grid.params().cell_size > 0.0f);
    Ray r{};
    r.org = glm::vec3(0.25f, 0.25f, 75010.0f);
    r.dir = glm::vec3(0.0f, 0.0f, -1.0f);
    r.tmin = 0.0f;
    r.tmax = std::numeric_limits<float>::infinity();
    r.launch_ref = sh::kNoRef;
    Hit h{};
    grid.trace(std::span<const Ray>(&r, 1), std::span<Hit>(&h, 1));
    CHECK_FALSE(is_miss(h));
    CHECK(h.t == 10.0f);
  }
}

TEST_CASE("grid: triangles that overlap one another keep the automatic grid within the work bound",
          "[grid][policy][hardcase]") {
  // 6000 triangles of random vertices in a thin slab: each spans a good part of the scene, so the
  // density target's cells (cells per triangle) put every triangle in a large share of them
  Scene s;
  s.name = "overlapping";
  Mesh m;
  m.name = "soup";
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (uint32_t i = 0; i < 6000; ++i) {
    for (int k = 0; k < 3; ++k) m.positions.push_back({u(rng), u(rng), 0.01f * u(rng)});
    m.triangles.push_back({3 * i, 3 * i + 1, 3 * i + 2});
  }
  m.materials.assign(m.triangles.size(), 0u);
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "", .mesh = 0});
  s.finalize();
  const uint64_t bound = plan::range_cells_budget(s.triangle_count());
  // The density target's cells would exceed it many times over
  {
    GridOptions o;
    const uint32_t n = uint32_t(std::sqrt(double(o.density) * double(s.triangle_count())));
    o.resolution = glm::uvec3(n, n, 1u);
    o.layout = GridOptions::Layout::image;
    o.capacity = 16u;
    const sh::GridParams g = reference::choose_grid(s, 0.0f, o);
    CHECK(plan::range_cells(s, 0.0f, g) > 2 * bound);
  }
  using Policy = GridOptions::CapacityPolicy;
  for (auto [t, policy] : {std::pair{Traversal::exact, Policy::trace_cost}, std::pair{Traversal::paper, Policy::trace_cost},
                           std::pair{Traversal::exact, Policy::no_saturation}, std::pair{Traversal::paper, Policy::percentile}}) {
    INFO((t == Traversal::exact ? "exact" : "paper") << ", policy " << int(policy));
    GridOptions o;
    o.traversal = t;
    o.capacity_policy = policy;
    o.threads = 2;
    GridChoice choice;
    const sh::GridParams g = reference::choose_grid(s, 0.0f, o, &choice);
    CHECK(plan::range_cells(s, 0.0f, g) <= bound);
    for (const GridCandidate& c : choice.candidates) CHECK(c.range_cells <= bound);
    if (policy != Policy::percentile) CHECK(choice.over_bound > 0u);  // the density target's among them
    // The trial's references are a subset of the ranges' cells
    uint64_t refs = 0;
    for (size_t i = 0; i < s.instances.size(); ++i)
      plan::for_each_triangle_cell(s, i, 0.0f, g, [&](uint32_t, size_t) { ++refs; });
    CHECK(refs > 0u);
    CHECK(refs <= plan::range_cells(s, 0.0f, g));
  }
}

// Grid options an outside sweep found to give a blank picture with exit 0, or a wrong reason: each
// refused with one that names the real problem (the paper traversal keeps its knob).
TEST_CASE("grid: cells wider than the domain, an exact traversal below the cell's sphere, a cell size over the budget",
          "[grid][policy][badinput]") {
  const Scene scene = make_builtin("cornell");
  reference::GridOptions go;
  go.threads = 2;
  go.traversal = reference::Traversal::exact;
  go.cell_size = 2e19f;  // its enlarged sphere's squared radius overflowed: nothing was inserted
  CHECK_THROWS_WITH(reference::choose_grid(scene, 0.0f, go), Catch::Contains("wider than the domain allows"));
  go.cell_size = plan::kMaxCellSize;  // the widest: one cell, every triangle in it, hit
  {
    reference::ReferenceGridTracer t(go);
    t.build(scene, 0.0f);
    CHECK(t.params().cells == glm::uvec3(1u));
    const Camera cam = scene.frame_camera();
    const std::vector<Ray> rays{make_ray(cam.eye, cam.target - cam.eye)};
    std::vector<Hit> hits(1);
    t.trace(rays, hits);
    CHECK(!is_miss(hits[0]));
  }
  go.cell_size.reset();
  go.sphere_enlargement = 0.5f;  // drops triangles at cells' corners: refused by the exact traversal
  CHECK_THROWS_WITH(reference::choose_grid(scene, 0.0f, go), Catch::Contains("needs at") && Catch::Contains("least 1"));
  CHECK(plan::gather_options(go).sphere_enlargement == 1.0f);  // the paper's gather stays exact
  // and keeps every reference, with no self-hit offset (an outside sweep's finds: `--spill off`
  // in a full cell, or `--self-hit-offset 20`, made the CPU's gather miss what the GPU's hit)
  {
    reference::GridOptions t = go;
    t.spill = reference::GridOptions::Spill::off;
    t.spill_capacity = 5u;
    t.self_hit_offset = 20.0f;
    const reference::GridOptions gt = plan::gather_options(t);
    CHECK(gt.spill == reference::GridOptions::Spill::on);
    CHECK_FALSE(gt.spill_capacity.has_value());
    CHECK(gt.self_hit_offset == 0.0f);
  }
  // and takes the gather's rule, the watertight test, whatever the trace's and its traversal
  for (auto test : {reference::GridOptions::TriangleTest::automatic, reference::GridOptions::TriangleTest::moller,
                    reference::GridOptions::TriangleTest::watertight})
    for (auto traversal : {reference::Traversal::paper, reference::Traversal::exact}) {
      reference::GridOptions t = go;
      t.triangle_test = test;
      t.traversal = traversal;
      CHECK(plan::gather_options(t).triangle_test == reference::GridOptions::TriangleTest::watertight);
    }
  go.traversal = reference::Traversal::paper;  // the paper's knob
  CHECK_NOTHROW(reference::choose_grid(scene, 0.0f, go));
  // An AABB padding of 0 leaves a triangle on a cell face out of the cell across it: refused by
  // the exact traversal, the paper's knob, and the paper's gather takes the default
  go.sphere_enlargement = 1.25f;
  go.aabb_padding = 0.0f;
  CHECK_NOTHROW(reference::choose_grid(scene, 0.0f, go));
  CHECK_FALSE(plan::gather_options(go).aabb_padding.has_value());
  go.traversal = reference::Traversal::exact;
  CHECK_THROWS_WITH(reference::choose_grid(scene, 0.0f, go), Catch::Contains("AABB padding of 0") && Catch::Contains("above 0"));
  go.aabb_padding.reset();
  // A cell-size override over the compact layout's budget names the budget, not the image's limits
  go.traversal = reference::Traversal::exact;
  go.sphere_enlargement = 1.25f;
  go.cell_size = 0.02f;
  go.memory_budget = uint64_t(1) << 20;
  CHECK_THROWS_WITH(reference::choose_grid(scene, 0.0f, go),
                    Catch::Contains("over its memory budget") && Catch::Contains("--memory-budget"));
}

TEST_CASE("trace-cost policy: copies of one triangle are sampled within the work bound, the same on any thread count",
          "[grid][policy][hardcase]") {
  // 12,000 copies of one triangle: every sample ray through it tests them all (an outside sweep's
  // 300,000 copies went minutes without a word before the grid was chosen). The sample stops
  // casting after the chunk whose tests pass plan::kSampleTestBudget: fewer rays, spread over the
  // image, the same ones on any thread count, and each still ends where Embree's does.
  constexpr uint32_t kCopies = 12000;
  const Scene s = copies_of_one_triangle(kCopies);
  GridOptions one;
  one.traversal = Traversal::exact;
  one.threads = 1;
  GridOptions two = one;
  two.threads = 2;
  const GridChoice a = choose(s, one), b = choose(s, two);
  const reference::WorkSample& sa = a.sample;
  const uint32_t full = one.work_sample_width * one.work_sample_height;  // the camera rays (no glossy material)
  REQUIRE_FALSE(sa.bounce);
  INFO(sa.rays.size() << " of " << full << " camera rays sampled");
  CHECK(sa.rays.size() > 0u);
  CHECK(sa.rays.size() < full);
  // A kept ray that hits the triangle tested every copy (they share its cells): those tests alone
  // stay within the bound and one chunk past it
  uint64_t hits = 0;
  for (const float t : sa.t_end) hits += std::isfinite(t);
  CHECK(hits > 0u);
  CHECK(hits * kCopies <= plan::kSampleTestBudget + uint64_t(kCopies) * (plan::kSampleChunk + 1));
  // The rays spread over the image: some in its first and some in its last row
  const std::vector<Ray> all = camera_rays(s.frame_camera(), one.work_sample_width, one.work_sample_height);
  size_t first_row = 0, last_row = 0;
  for (const Ray& r : sa.rays)
    for (uint32_t x = 0; x < one.work_sample_width; ++x) {
      first_row += std::memcmp(&r, &all[x], sizeof r) == 0;
      last_row += std::memcmp(&r, &all[all.size() - 1 - x], sizeof r) == 0;
    }
  CHECK(first_row > 0u);
  CHECK(last_row > 0u);
  // The same sample on any thread count
  REQUIRE(b.sample.rays.size() == sa.rays.size());
  CHECK(std::memcmp(b.sample.rays.data(), sa.rays.data(), sa.rays.size() * sizeof(Ray)) == 0);
  CHECK(std::memcmp(b.sample.t_end.data(), sa.t_end.data(), sa.t_end.size() * sizeof(float)) == 0);
  // And each kept ray ends where Embree's does
  EmbreeTracer embree(2);
  embree.build(s, 0.0f);
  std::vector<Hit> want(sa.rays.size());
  embree.trace(sa.rays, want);
  size_t same = 0;
  for (size_t i = 0; i < sa.rays.size(); ++i) {
    const bool miss = !std::isfinite(sa.t_end[i]);
    same += miss == is_miss(want[i]) && (miss || reference::ulp_distance(sa.t_end[i], want[i].t) <= 64);
  }
  CHECK(same == sa.rays.size());
}

TEST_CASE("grid: a compact candidate's trial stops once its references pass the memory budget, its memory a lower bound",
          "[grid][policy][badinput]") {
  // The count stops where the references alone put the grid over the budget (copies of one
  // triangle spent tens of seconds counting candidates the budget then refused: an outside sweep);
  // the refusal names what was counted, "at least", between the budget and the whole grid's memory
  // 20,000 copies of one triangle over about 100 cells each: the references are nearly all of the
  // grid's memory, so a budget of a fifth of it is above the cells' own and the trial stops
  const Scene scene = copies_of_one_triangle(20000);
  GridOptions go;
  go.threads = 2;
  go.traversal = Traversal::exact;
  go.cell_size = 0.07f;
  go.memory_budget = uint64_t(1) << 40;
  GridChoice whole;
  reference::choose_grid(scene, 0.0f, go, &whole);
  REQUIRE(whole.candidates.size() == 1);
  const GridCandidate& c = whole.candidates[0];
  CHECK_FALSE(c.memory_at_least);
  INFO(c.cells.x << "x" << c.cells.y << "x" << c.cells.z << " cells, " << c.memory << " bytes");
  const uint64_t budget = c.memory / 5;  // above the cells' own memory, below the references'

  go.memory_budget = budget;
  std::string message;
  try {
    reference::choose_grid(scene, 0.0f, go);
  } catch (const Error& e) {
    message = e.what();
  }
  INFO(message);
  const size_t at = message.find("take at least ");
  REQUIRE(at != std::string::npos);
  const double mib = std::stod(message.substr(at + std::strlen("take at least ")));
  const double budget_mib = double(budget) / double(1u << 20), whole_mib = double(c.memory) / double(1u << 20);
  CHECK(mib >= budget_mib - 0.05);  // over the budget (one decimal printed)
  CHECK(mib <= whole_mib + 0.05);   // and no more than the whole count's
  CHECK(mib < whole_mib - 0.05);    // stopped early: the whole count's is well above it
  // Within the budget, the choice is the whole count's
  go.memory_budget = c.memory;
  GridChoice fits;
  const sh::GridParams g = reference::choose_grid(scene, 0.0f, go, &fits);
  REQUIRE(fits.candidates.size() == 1);
  CHECK(g.cells == c.cells);
  CHECK(fits.candidates[0].memory == c.memory);
}
