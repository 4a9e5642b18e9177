// policy.h: what the trace-cost capacity policy of choose_grid weighs (docs/SPEC.md, "Grid
// placement, resolution and capacity"): a small sample of the frame's own rays with the distance
// at which each really ends, and per candidate grid the work a trace of that sample would do
// (cells visited, references tested) and how many of its rays would meet a saturated cell.
#pragma once

#include <array>
#include <functional>
#include <span>
#include <vector>

#include "gridrt/plan/plan.h"

namespace gridrt::plan {

// A triangle of an instance as the build sees it at some time: its world vertices, its
// unnormalized normal (triangle_normal) and its AABB cell range (triangle_cell_range).
struct PlacedTriangle {
  uint32_t index = 0;  // within its mesh
  glm::vec3 v0{}, v1{}, v2{}, n{};
  glm::uvec3 lo{}, hi{};
};
// Calls f for every triangle of instance `instance` at `time` with a non-zero area (the build
// inserts no other).
void for_each_placed_triangle(const Scene& scene, size_t instance, float time, const shared::GridParams& g,
                              const std::function<void(const PlacedTriangle&)>& f);

// Calls f(triangle, cell index) for every cell the build would insert that triangle of instance
// `instance` into at `time` (its AABB cell range, the plane vs enlarged-sphere test; no capacity).
// Cell index: (z * cells.y + y) * cells.x + x. `before`, where given, is called with each
// triangle before its cells (a progress count).
void for_each_triangle_cell(const Scene& scene, size_t instance, float time, const shared::GridParams& g,
                            const std::function<void(uint32_t, size_t)>& f,
                            const std::function<void(const PlacedTriangle&)>& before = {});

// The cells a traversal visits along a ray, in order, as trace_paper and trace_exact step (the
// functions of shared/grid.h), without testing anything: f(cell, k, last, t_report, tested) per
// step, where the paper's visit covers segments k..last (merged repeats) and t_report is the
// visit's segment end (a hit is reported once best_t < t_report); the DDA's k-th cell has
// last = k and t_report = its exit (reported once best_t <= t_report). `tested` is false for a
// step the paper's `skip` rule skips. f returns false to stop the walk; it also stops where the
// traversal would (past t_end, the grid, the step limit). False if the ray misses the grid.
// `skip` (exact traversal, empty-space skipping): the skip field's distance of a cell; a cell at
// distance d > 0 is a step over the box of radius d - 1 around it, as trace_exact takes it, with
// `tested` false and t_report the box's exit.
bool for_each_visit(const shared::GridParams& g, const Ray& ray,
                    const std::function<bool(glm::uvec3 cell, uint32_t k, uint32_t last, float t_report, bool tested)>& f,
                    const std::function<uint32_t(glm::uvec3 cell)>& skip = {});

// The trial counts of one candidate grid: per cell the references a build would insert (no
// capacity). `fixed`: the instances that do not move, at the build's time, every cell; the moving
// ones only in the box of cells they reach over the animation samples: their count at the build's
// time (`moving_now`) and the largest over the samples (`moving_max`, what the capacity needs).
struct TrialCounts {
  glm::uvec3 cells{0};
  std::vector<uint32_t> fixed;              // (z * cells.y + y) * cells.x + x
  glm::uvec3 box_lo{0}, box_size{0};        // the moving instances' box of cells
  std::vector<uint32_t> moving_now, moving_max;  // per box cell, x fastest
  bool over_limit = false;  // the static references passed the trial's limit: the counts are incomplete

  // The count at the build's time, and the largest over the animation, of one cell.
  uint32_t now(glm::uvec3 c) const { return at(c, moving_now); }
  uint32_t largest(glm::uvec3 c) const { return at(c, moving_max); }
  // f(largest count) for every cell.
  template <class F>
  void for_each_largest(F&& f) const {
    for (uint32_t z = 0; z < cells.z; ++z)
      for (uint32_t y = 0; y < cells.y; ++y)
        for (uint32_t x = 0; x < cells.x; ++x) f(largest({x, y, z}));
  }

 private:
  uint32_t at(glm::uvec3 c, const std::vector<uint32_t>& moving) const {
    uint32_t n = fixed[(size_t(c.z) * cells.y + c.y) * cells.x + c.x];
    const glm::uvec3 b = c - box_lo;  // wraps below box_lo: outside
    if (!moving.empty() && b.x < box_size.x && b.y < box_size.y && b.z < box_size.z)
      n += moving[(size_t(b.z) * box_size.y + b.y) * box_size.x + b.x];
    return n;
  }
};

// The skip field's distances of a candidate grid (shared/grid.h "The skip field"), as its build
// would make them: a summed-volume table of the cells the trial counts of the instances that do
// not move occupy, and the dynamic boxes (`box_words`, skip_box_words' header of the candidate); a
// cell's distance, skip_static_distance on that table (the build's search) lowered to its distance
// to every box, computed where a walk asks. (The
// counts' non-moving dynamic instances lie in their boxes, so counting them as occupied changes no
// distance.)
class SkipDistances {
 public:
  SkipDistances(const shared::GridParams& g, const TrialCounts& counts, std::span<const uint32_t> box_words);
  // The dynamic boxes the walk of `ray` (its setup `rs`) can reach, bit b for box b
  // (shared::skip_box_reached; the trace's skip_box_mask).
  uint32_t box_mask(const Ray& ray, const shared::RaySetup& rs) const;
  // A cell's distance: its static distance lowered to its distance to every box of `mask`.
  uint32_t operator()(glm::uvec3 cell, uint32_t mask) const;

 private:
  shared::GridParams g_;
  std::vector<uint32_t> table_, boxes_;
};

// The policy's ray sample (WorkSample, reference/grid.h) of `scene` at `time`.
// `base`: the grid placement (origin, cell size, cells) the compact grid uses.
WorkSample work_sample(const Scene& scene, float time, const shared::GridParams& base, const GridOptions& o);

// The work a trace of the sample would do on one candidate grid: `g` its params (traversal,
// capacity, cells, padding, ...), `counts` its trial counts (the references each cell is offered
// at the sample's time). Per ray, following the traversal's own stepping
// (for_each_visit) up to the visit that reports the ray's end: cells visited and references
// tested (min(count, capacity) per visit, less the launch triangle where the visited cell holds it:
// the trace skips it uncounted); the share of rays that visit a saturated cell
// (at_risk); and the expected share whose answer the grid changes (lost), a ray counting as kept
// when some visit up to its end was offered its hit triangle (the build's range and plane test)
// with a window covering the hit (paper: the elongated segment; exact: the whole ray) and kept it
// (certainly in an unsaturated cell, with probability capacity / count in a saturated one), and,
// in paper mode with gap-fill, when no saturated cell passed beyond the launch surface
// (gap_fill_left_surface) ended it first with a voxel; `skipped` is the share lost because no
// visit was offered the triangle (the paper's samples stepped past its cells). `spilled`: the
// dropped references of the saturated cells visited (what a spill list would add).
// With empty-space skipping (exact traversal, kGridSkipEmpty in g.flags) the walk takes the skip
// field's steps (`skip_boxes`: skip_box_words of the candidate; SkipDistances): a step over empty
// cells counts as one cell visited, as the trace counts it, and tests nothing.
WorkEstimate estimate_work(const shared::GridParams& g, const TrialCounts& counts, const WorkSample& sample,
                           std::span<const uint32_t> skip_boxes = {});

// A cell visit's cost in reference tests: the option, else the traversal's. Exact traversal: a
// visit (a tested cell or a step of the skip field over empty ones) fitted to the NVIDIA H200's
// trace times of 22 grids of four frames (docs/SPEC.md); paper traversal: 1, as first set.
inline constexpr float kExactCellVisitCost = 1.6f;
inline constexpr float kPaperCellVisitCost = 1.0f;
float cell_visit_cost(const GridOptions& o);

// The candidate's cost in reference tests per ray: tests + cell_visit_cost * cells
// + saturation_cost * lost (docs/SPEC.md).
double work_cost(const WorkEstimate& w, const GridOptions& o);

// Measured work of traced hits (their `cells` and `tests` counters) per ray over the used rays;
// lost = the share of gap-fill hits.
WorkEstimate measured_work(std::span<const Ray> rays, std::span<const Hit> hits);

}  // namespace gridrt::plan
