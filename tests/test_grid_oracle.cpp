// The reference grid against the Embree oracle on built-in and real scenes: camera rays and
// mirror bounce rays off the gather buffer (the paper's use), paper and exact traversal.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/scene_io.h"
#include "test_grid_util.h"

using namespace gridrt;
using namespace gridtest;
namespace sh = gridrt::shared;
namespace fs = std::filesystem;
using reference::GridOptions;
using reference::ReferenceGridTracer;
using reference::Traversal;

namespace {

// Camera rays (w x h) and, for every pixel whose camera ray hits, the mirror bounce ray off the
// gather buffer: origin the gather position, launch normal and launch reference set.
std::vector<Ray> oracle_rays(const Scene& scene, EmbreeTracer& embree, uint32_t w, uint32_t h, float time) {
  const Camera cam = scene.frame_camera();
  const GatherBuffer gb = make_gather(scene, embree, cam, w, h, time);
  std::vector<Ray> rays;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) rays.push_back(camera_ray(cam, w, h, x, y));
  for (size_t i = 0; i < gb.size(); ++i) {
    if (!gb.valid[i]) continue;
    const glm::vec3 n = gb.normal[i], d = gb.incident[i];
    Ray r = make_ray(gb.position[i], d - 2.0f * glm::dot(d, n) * n);
    r.launch_normal = n;
    r.launch_ref = gb.launch_ref[i];
    rays.push_back(r);
  }
  return rays;
}

struct Agreement {
  uint64_t rays = 0, same = 0, holes = 0, false_hits = 0, gap_fills = 0, wrong = 0;
  uint64_t gap_fills_in_place = 0;  // gap-fill voxels within 1.5 cells of the oracle's hit
  double max_dt = 0.0;  // relative, over agreeing hits
  std::string first;
  double share() const { return rays ? double(same) / double(rays) : 1.0; }
  std::string text() const {
    std::ostringstream os;
    os << same << "/" << rays << " agree (" << 100.0 * share() << "%), holes " << holes << ", false hits "
       << false_hits << " (gap-fill " << gap_fills << ", of which " << gap_fills_in_place
       << " within 1.5 cells of the oracle's hit), other triangle " << wrong << ", max |dt|/t " << max_dt;
    if (!first.empty()) os << "\nfirst difference: " << first;
    return os.str();
  }
};

// Same: both miss, or the same (instance, triangle), or a different triangle at the same t (within
// 1e-5 relative: a shared edge or vertex, where either answer is right).
Agreement compare(std::span<const Ray> rays, std::span<const Hit> got, std::span<const Hit> want, float cell_size) {
  Agreement a;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (is_unused(rays[i])) continue;
    ++a.rays;
    const Hit &g = got[i], &w = want[i];
    const bool gh = !is_miss(g), wh = !is_miss(w);
    if (g.flags & sh::kHitGapFill) {
      ++a.gap_fills;
      if (wh && std::abs(g.t - w.t) * glm::length(rays[i].dir) <= 1.5f * cell_size) ++a.gap_fills_in_place;
    }
    bool same = gh == wh;
    if (same && gh && !(g.flags & sh::kHitGapFill)) {
      const double dt = std::abs(double(g.t) - double(w.t)) / std::max(1e-6, double(w.t));
      same = (g.instance == w.instance && g.triangle == w.triangle) || dt <= 1e-5;
      if (same) a.max_dt = std::max(a.max_dt, dt);
    } else if (g.flags & sh::kHitGapFill) {
      same = false;
    }
    if (same) {
      ++a.same;
      continue;
    }
    if (wh && !gh) ++a.holes;
    else if (gh && (!wh || (g.flags & sh::kHitGapFill))) ++a.false_hits;
    else ++a.wrong;
    if (a.first.empty()) a.first = hx(rays[i]) + "\n  grid   " + hx(g) + "\n  embree " + hx(w);
  }
  return a;
}

struct Run {
  Agreement paper, exact;
};

Run run_scene(const Scene& scene, uint32_t w, uint32_t h, GridOptions o = {}) {
  EmbreeTracer embree(2);
  embree.build(scene, 0.0f);
  const std::vector<Ray> rays = oracle_rays(scene, embree, w, h, 0.0f);
  std::vector<Hit> want(rays.size()), got(rays.size());
  embree.trace(rays, want);
  Run r;
  o.threads = 2;
  for (Traversal t : {Traversal::paper, Traversal::exact}) {
    o.traversal = t;
    ReferenceGridTracer grid(o);
    grid.build(scene, 0.0f);
    grid.trace(rays, got);
    (t == Traversal::paper ? r.paper : r.exact) = compare(rays, got, want, grid.params().cell_size);
  }
  return r;
}

std::string real_scenes() {
  const std::string dir = real_scenes_dir();
  if (fs::is_directory(dir)) return dir;
  if (std::getenv("CI")) FAIL("the real scenes folder '" << dir << "' is missing, and CI must test with it");
  WARN("skipped: the real scenes folder '" << dir << "' is missing (set GRIDRT_SCENES)");
  return "";
}

}  // namespace

// Thresholds: measured at the defaults (the trace-cost capacity policy; docs/ACCURACY.md) minus a
// margin that still catches a regression. Exact mode: every ray but a handful of shared-edge slips.
// Measured (48x36 camera rays + mirror bounces): cornell and teapot 100 % in both modes; atrium
// paper 99.44 % (4 holes, 2 gap-fill voxels: its moving teapots saturate a few cells at the
// 4096-texel limit), exact 100 %.
TEST_CASE("Grid vs Embree on the built-in scenes (paper and exact)", "[oracle][grid]") {
  struct Case {
    const char* name;
    double paper_min, exact_min;
  };
  for (const Case c : {Case{"cornell", 0.999, 0.999}, Case{"teapot", 0.998, 0.999}, Case{"atrium", 0.99, 0.998}}) {
    const Scene scene = make_builtin(c.name);
    const Run r = run_scene(scene, 48, 36);
    INFO(c.name << "\n paper: " << r.paper.text() << "\n exact: " << r.exact.text());
    WARN(c.name << " paper: " << r.paper.text() << "\n" << c.name << " exact: " << r.exact.text());
    CHECK(r.paper.share() >= c.paper_min);
    CHECK(r.exact.share() >= c.exact_min);
    CHECK(r.exact.gap_fills == 0);
    CHECK(r.exact.holes + r.exact.false_hits == 0);
    CHECK(r.exact.max_dt < 1e-4);
  }
}

// Real scenes at the defaults (lavapipe's 4096-texel image limit): no grid of the real scenes fits
// every cell's references under 4096 texels, so the trace-cost policy accepts some saturated
// cells where few rays go; they cost paper mode a few gap-fill voxels and dropped references.
// Exact mode has the spill list (its default) and must agree on every ray (next test case).
// Measured (32x24 camera rays + mirror bounces): Sponza paper 98.6 %, Sibenik paper 94.4 % (before
// the policy: 80-85 % and 42-46 %). Thresholds: the measured shares minus a margin.
TEST_CASE("Grid vs Embree on the real scenes (paper and exact)", "[oracle][grid][scenes]") {
  const std::string dir = real_scenes();
  if (dir.empty()) return;
  for (const char* name : {"sponza-teapots", "sibenik-teapots"}) {
    const Scene scene = load_scene(std::string(GRIDRT_DATA_DIR) + "/scenes/" + name + ".json");
    const Run r = run_scene(scene, 32, 24);
    INFO(name << "\n paper: " << r.paper.text() << "\n exact: " << r.exact.text());
    WARN(name << " paper: " << r.paper.text() << "\n" << name << " exact: " << r.exact.text());
    CHECK(r.paper.share() >= (name[1] == 'p' ? 0.97 : 0.93));
    CHECK(r.exact.share() == 1.0);
    CHECK(r.exact.holes + r.exact.false_hits == 0);
  }
}

// Exact mode agrees with Embree on every ray of the real scenes, up to ties, with no holes,
// at lavapipe's 4096 limit where cells saturate: the spill list keeps what the slots drop. Camera
// rays and mirror bounces (64x48), the Moller-Trumbore and the watertight test.
TEST_CASE("Exact mode with the spill list agrees with Embree on every ray of the real scenes at 4096",
          "[oracle][grid][scenes][hardcase]") {
  const std::string dir = real_scenes();
  if (dir.empty()) return;
  for (const char* name : {"sibenik-teapots", "sponza-teapots"}) {
    const Scene scene = load_scene(std::string(GRIDRT_DATA_DIR) + "/scenes/" + name + ".json");
    EmbreeTracer embree(2);
    embree.build(scene, 0.0f);
    const std::vector<Ray> rays = oracle_rays(scene, embree, 64, 48, 0.0f);
    std::vector<Hit> want(rays.size()), got(rays.size());
    embree.trace(rays, want);
    // The image layout (where cells saturate: the case the spill list is for) with both triangle
    // tests, and the compact layout (the exact traversal's default) with its default test.
    using L = GridOptions::Layout;
    using T = GridOptions::TriangleTest;
    for (auto [layout, test] : {std::pair{L::image, T::moller}, std::pair{L::image, T::watertight},
                                std::pair{L::compact, T::watertight}}) {
      GridOptions o;
      o.traversal = Traversal::exact;
      o.layout = layout;
      o.triangle_test = test;
      o.max_image_dimension = 4096;
      o.threads = 2;
      ReferenceGridTracer grid(o);
      grid.build(scene, 0.0f);
      const reference::GridStats s = grid.stats();
      grid.trace(rays, got);
      const Agreement a = compare(rays, got, want, grid.params().cell_size);
      INFO(name << (layout == L::image ? " image" : " compact") << (test == T::moller ? " moller" : " watertight")
                << ": " << a.text() << "\n" << reference::to_text(s));
      if (layout == L::image) CHECK(s.saturated_static + s.saturated_dynamic > 0);
      CHECK(s.spill_on);
      CHECK(s.spill_stored > 0);
      CHECK(s.spill_overflow == 0);
      CHECK(a.same == a.rays);
      CHECK(a.holes == 0);
      CHECK(a.false_hits == 0);
    }
  }
}

// A tool, not a test: grid vs Embree on one scene (SCENE=cornell or SCENE=sibenik-teapots.json),
// knobs from the environment (EXACT, REPEATS, DENSITY, ENLARGE, ELONG, NOGAP, MAXDIM, MAXCAP, PCT);
// SHOW=1 prints the explanation of the first disagreeing ray (SKIP=n: from ray n on).
TEST_CASE("Explore: grid vs Embree on one scene", "[.explore]") {
  const char* name = std::getenv("SCENE") ? std::getenv("SCENE") : "cornell";
  const std::string sname = name;
  const Scene scene = sname.find(".json") != std::string::npos ? load_scene(std::string(GRIDRT_DATA_DIR) + "/scenes/" + sname) : make_builtin(name);
  EmbreeTracer embree(2);
  embree.build(scene, 0.0f);
  const std::vector<Ray> rays = oracle_rays(scene, embree, 48, 36, 0.0f);
  std::vector<Hit> want(rays.size()), got(rays.size());
  embree.trace(rays, want);
  GridOptions o;
  if (std::getenv("EXACT")) o.traversal = Traversal::exact;
  if (std::getenv("REPEATS")) o.repeats = GridOptions::Repeats(std::atoi(std::getenv("REPEATS")));
  if (std::getenv("DENSITY")) o.density = float(std::atof(std::getenv("DENSITY")));
  if (std::getenv("ENLARGE")) o.sphere_enlargement = float(std::atof(std::getenv("ENLARGE")));
  if (std::getenv("ELONG")) o.elongation = float(std::atof(std::getenv("ELONG")));
  if (std::getenv("NOGAP")) o.gap_fill = false;
  if (std::getenv("MAXDIM")) o.max_image_dimension = uint32_t(std::atoi(std::getenv("MAXDIM")));
  if (std::getenv("MAXCAP")) o.max_capacity = uint32_t(std::atoi(std::getenv("MAXCAP")));
  if (std::getenv("PCT")) o.capacity_percentile = float(std::atof(std::getenv("PCT")));
  ReferenceGridTracer grid(o);
  grid.build(scene, 0.0f);
  grid.trace(rays, got);
  std::cout << reference::to_text(grid.stats());
  int shown = 0;
  const Agreement a = compare(rays, got, want, grid.params().cell_size);
  std::cout << a.text() << "\n";
  for (size_t i = 0; i < rays.size() && shown < (std::getenv("SHOW") ? 1 : 0); ++i) {
    if (is_miss(want[i]) == is_miss(got[i]) && (is_miss(got[i]) || (got[i].instance == want[i].instance && got[i].triangle == want[i].triangle))) continue;
    if (std::getenv("SKIP") && i < size_t(std::atoi(std::getenv("SKIP")))) continue;
    std::cout << "ray " << i << "\n  embree " << hx(want[i]) << "\n" << reference::to_text(grid.explain_ray(rays[i]));
    ++shown;
  }
}
