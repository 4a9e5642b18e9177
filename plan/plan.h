// plan.h: the grid's placement, resolution and capacity chosen from the scene (choose_grid and its
// capacity policy), the spill list's capacity, and which effects the trace runs.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "gridrt/common/scene.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/tracer.h"
#include "gridrt/plan/options.h"

namespace gridrt::plan {

// Whether `o` turns the spill list on (Spill::automatic: for the exact traversal).
bool spill_enabled(const AlgorithmOptions& o);
// The narrowest cell the domain allows (docs/SPEC.md, "Domain"): kMinCellUlps ulps of the
// largest coordinate magnitude `reach` of the grid box.
inline constexpr float kMinCellUlps = 64.0f;
inline float min_cell_size(float reach) { return reach * (kMinCellUlps * 0x1p-23f); }
// The widest cell (docs/SPEC.md, "Domain"): 2^26, four times the domain's reach, so one cell holds
// any scene the domain admits. Wider ones say nothing more, and their derived constants (the
// enlarged sphere's squared radius, (16 * 2^26 * sqrt(3) / 2)^2 ~ 8.6e17 at most) stay finite.
inline constexpr float kMaxCellSize = 0x1p26f;


// Whether `o` takes the compact layout (kGridCompact: compact, or automatic with the exact
// traversal). The compact layout needs the exact traversal and the spill list: compact_check
// throws a clear message where the options ask for it otherwise.
bool compact_enabled(const AlgorithmOptions& o);
void compact_check(const AlgorithmOptions& o);

// The compact layout's default memory budget (PlanOptions::memory_budget unset): per scene
// triangle, and the least.
inline constexpr uint64_t kCompactBytesPerTriangle = 320;
inline constexpr uint64_t kCompactMinBudget = uint64_t(4) << 20;
// PlanOptions::Offsets::automatic takes a grid that fits the budget only with sparse offsets when
// its estimated cost is at most this share of the best dense grid's: on the H200 the index's load
// cost 1.8-2.8 % of the trace on the same cells and the finer grids' static build 0.45-0.66 ms more
// (docs/BENCHMARKS.md "Offsets of the occupied cells only").
inline constexpr double kSparseOffsetsMargin = 0.95;
// The automatic resolution's work bound: a candidate grid is weighed only when the cells of its
// triangles' AABB ranges, summed (what its trial count and its build test), stay within
// kRangeCellsPerTriangle per scene triangle, at least kRangeCellsFloor. Triangles that overlap
// one another, or that are large beside the density target's cells, would otherwise make the
// finer candidates' trials and builds quadratic (docs/SPEC.md "The work bound").
inline constexpr uint64_t kRangeCellsPerTriangle = 256;
inline constexpr uint64_t kRangeCellsFloor = uint64_t(1) << 22;
// The trace-cost policy's ray sample (work_sample) casts its rays in strided chunks of about
// kSampleChunk rays until one trace's triangle tests pass kSampleTestBudget (plan/policy.cpp,
// SampleCaster::trace_within): a scene whose rays each test thousands of triangles is sampled by
// fewer rays, spread over the whole image, rather than for minutes. The grids chosen for this
// project's scenes are the same with it (docs/SPEC.md "The ray sample").
inline constexpr size_t kSampleChunk = 256;
inline constexpr uint64_t kSampleTestBudget = uint64_t(1) << 23;
uint64_t range_cells_budget(uint64_t scene_triangles);
// The cells of every triangle's AABB range on grid `g` (triangle_cell_range), summed over the
// scene's instances at `time`; zero-area triangles (never inserted) count none. O(triangles).
uint64_t range_cells(const Scene& scene, float time, const shared::GridParams& g);
uint64_t compact_budget(const PlanOptions& o, uint64_t scene_triangles);

// Everything the grid keeps on the device (both backends allocate exactly this; bytes): the image
// layout's 3D image, or the compact layout's offsets and references; the spill list (header and
// entries) and its heads (image: four per cell; compact: the header and two per dynamic-region
// cell); the skip field; the dirty-cell list (image layout only).
struct GridMemory {
  uint64_t image = 0, offsets = 0, refs = 0, spill = 0, heads = 0, skip = 0, dirty = 0;
  uint64_t total() const { return image + offsets + refs + spill + heads + skip + dirty; }
};
// `static_refs`: the compact layout's references, `static_cells` the cells holding one;
// `region_cells`: its dynamic region's cells.
GridMemory grid_memory(const shared::GridParams& g, uint64_t static_refs, uint64_t static_cells, uint32_t spill_capacity,
                       uint64_t region_cells);

// The host memory a plan of `g` and the reference's build of it take at their peak: what the grid
// keeps (grid_memory) and the temporaries beside it: the trial's counts (a word a cell), the
// compact passes' counts (a word a cell), pairs and scattered references (three words a
// reference), the skip field's corner table and bricks. The image layout's image at `g.capacity`.
uint64_t host_build_memory(const shared::GridParams& g, uint64_t static_refs, uint64_t static_cells,
                           uint32_t spill_capacity, uint64_t region_cells);

// The compact layout's dynamic region: the box of cells every dynamic instance's references can
// reach over the whole animation (its swept bounds, as animation_bounds, one cell of margin, the
// AABB padding), clamped to the grid; empty (lo > hi) without dynamic instances.
struct CellBox {
  glm::uvec3 lo{1u}, hi{0u};
  bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  uint64_t cells() const { return empty() ? 0 : uint64_t(hi.x - lo.x + 1) * (hi.y - lo.y + 1) * (hi.z - lo.z + 1); }
};
CellBox dynamic_region(const Scene& scene, float time, const shared::GridParams& g);
// The compact layout's spill heads buffer: the header (the region's box) and every head empty.
std::vector<uint32_t> compact_heads(const CellBox& region);

// Whether `o` turns empty-space skipping on (kGridSkipEmpty: the exact traversal with skip_empty).
bool skip_enabled(const AlgorithmOptions& o);
// Whether `o` turns the mailbox on (kGridMailbox: the exact traversal with mailbox and sorted insertion).
bool mailbox_enabled(const AlgorithmOptions& o);
// Whether `o` turns covered cells on (kGridSkipCovered: the skip field and the compact layout, with skip_covered).
bool covered_enabled(const AlgorithmOptions& o);
// Whether `o` takes the separating-axis cell test (kGridCellBox: box, or automatic with the exact traversal).
bool cell_box_enabled(const AlgorithmOptions& o);

// The skip field's header words (shared::kSkipHeaderWords): the boxes of cells that cover the
// dynamic instances' references at `time` (shared::skip_box_of_bounds; instance i of the dynamic
// ones joins box i % kSkipMaxBoxes). Both backends upload these at every build and update.
std::vector<uint32_t> skip_box_words(const Scene& scene, float time, const shared::GridParams& g);

// A cell's static skip distance from the summed-volume table of the occupancy (shared/grid.h "The
// skip field": skip_table_index's layout): the smallest r in [lo, hi) whose cube of radius r around
// c holds an occupied cell, else hi, by binary search (each probe 8 table reads); the caller
// guarantees the distance capped at kSkipMaxDistance lies in [lo, hi]. Without a window: [0,
// kSkipMaxDistance] (8 probes), as the trace-cost estimate (plan/policy.h, SkipDistances) asks per
// cell; the build (the reference's skip_field_build, skip_field.comp) searches the window of the
// cell's brick (skip_cell_window: 3 probes).
uint32_t skip_static_distance(const shared::GridParams& g, std::span<const uint32_t> table, glm::uvec3 c,
                              uint32_t lo, uint32_t hi);
uint32_t skip_static_distance(const shared::GridParams& g, std::span<const uint32_t> table, glm::uvec3 c);
// Brick b's distance B(b) (shared/grid.h, kSkipBrick): binary search over [0, kSkipMaxBrickDistance].
uint32_t skip_brick_distance(const shared::GridParams& g, std::span<const uint32_t> table, glm::uvec3 b);

// Grid placement and size chosen from the scene (docs/SPEC.md, "Resolution and capacity").
shared::GridParams choose_grid(const Scene& scene, float time, const GridOptions& options);

// The work a trace does per ray on one grid: estimated by the trace-cost policy on its ray sample
// (estimate_work, plan/policy.h), or measured from hit records (measured_work).
struct WorkEstimate {
  size_t rays = 0;
  double cells = 0.0;    // cells visited per ray
  double tests = 0.0;    // references tested per ray
  double at_risk = 0.0;  // share of rays that visit a saturated cell before they end
  double lost = 0.0;     // share of rays whose answer the grid changes: expected (the hit
                         // triangle in no visited cell, dropped, a gap-fill voxel), or measured
                         // (gap-fill hits)
  double skipped = 0.0;  // expected share of rays whose hit triangle no visited cell was offered
  double spilled = 0.0;  // per ray: dropped references of the saturated cells it visits
};

// The policy's ray sample: the glossy bounce rays of a small gather buffer of the scene's frame
// camera (the rays the paper's frame traces through the grid), of up to work_sample_frames frames
// (each frame perturbs the glossy directions anew) until work_sample_rays are sampled, or its
// camera rays where the scene has no glossy material; and where each ray ends (its first hit's t, +inf for a miss), found
// exactly by a compact grid without a capacity (a CSR cell list, exact DDA, alpha keying).
struct WorkSample {
  std::vector<Ray> rays;
  std::vector<float> t_end;
  std::vector<std::array<glm::vec3, 3>> hit;     // the triangle each ray ends on (world space; zeros: a miss)
  std::vector<std::array<glm::vec3, 3>> launch;  // the ray's launch triangle (zeros: none)
  bool bounce = true;  // false: camera rays (no glossy material)
};

// One resolution choose_grid weighed: its cells, the largest per-cell count over the animation
// samples, the capacity the limits allow it, and the references it would drop.
struct GridCandidate {
  float cell_size = 0.0f;
  float aabb_padding = kAabbPadding;
  glm::uvec3 cells{0};
  uint32_t slot_axis = 0;        // 0 x, 1 y, 2 z
  uint32_t max_count = 0;        // largest per-cell count (static + dynamic over the samples)
  uint32_t capacity = 0;         // min(max_count, what the limits allow), >= min_capacity
  uint64_t dropped = 0;          // sum over cells of max(0, count - capacity)
  uint64_t saturated_cells = 0;  // cells with count > capacity
  uint64_t texels = 0;
  uint64_t memory = 0;           // compact layout: grid_memory's total (the budget's measure)
  bool memory_at_least = false;  // compact layout: the trial stopped once over the budget; `memory` a lower bound
  bool sparse_offsets = false;   // compact layout: the offsets of the occupied cells only (kGridSparseOffsets)
  uint64_t range_cells = 0;      // the triangles' AABB range cells, summed (range_cells)
  bool over_bound = false;       // range_cells over the work bound: not counted, not a candidate
  uint64_t over_host = 0;        // the host memory its trial and build would take, over what is left: not a candidate
  bool fits = false;             // within max_image_dimension and max_texels (compact: the memory budget)
  WorkEstimate work;             // trace_cost policy: the estimated work on its ray sample
  double cost = 0.0;             // trace_cost policy: work_cost(work)
};
// The candidates choose_grid weighed (in the order it weighed them) and the index it took; empty
// when capacity or resolution is overridden.
struct GridChoice {
  std::vector<GridCandidate> candidates;
  size_t chosen = 0;
  WorkSample sample;        // trace_cost: the rays the estimates were made on
  uint32_t over_bound = 0;  // candidates left out by the work bound (range_cells_budget)
};
shared::GridParams choose_grid(const Scene& scene, float time, const GridOptions& options, GridChoice* choice);
// The spill list's capacity for grid `g` (chosen by choose_grid with `choice`): 0 with spill off;
// else the option, or the references the trial would drop (the chosen candidate's `dropped`, or a
// count on `g` where choose_grid weighed no candidate) plus a quarter and 64 (the trial samples
// moving instances at 16 times: a bound it is not).
// The capacity for `dropped` spilled references: a quarter and 64 more, at most 2^28 entries.
uint32_t spill_capacity_for(uint64_t dropped);
// The capacity an update grows the list to when the forecast fell short (spill_header.count >
// capacity after inserting the dynamic instances at a time the trial did not sample): the count
// with spill_capacity_for's margin; 0 where it holds (`header.count <= capacity`), where the
// capacity was asked for (GridOptions::spill_capacity: kept, the overflow reported), or where the
// list cannot grow (2^28 entries). Both backends then insert the update again, so they agree.
uint32_t spill_growth(const shared::SpillHeader& header, const GridOptions& options, uint32_t flags);
uint32_t choose_spill_capacity(const Scene& scene, float time, const GridOptions& options, const shared::GridParams& g,
                               const GridChoice& choice);
// The flags the trace runs with: `requested` (GridParams::flags as chosen) without gap-fill while no
// reference is dropped (`spill_count` == 0: no cell is saturated), unless gap_fill_if_saturated is off.
uint32_t trace_flags(uint32_t requested, const AlgorithmOptions& options, uint32_t spill_count);
// World bounds of the scene over its whole animation: static instances at `time`, dynamic ones
// swept over their motion; not padded.
Bounds animation_bounds(const Scene& scene, float time);


// The grid's tables as the build's geometry buffer and the trace read them: per instance its
// triangle offset, count and flags; per triangle its material (positions are the build's to
// write) and texture coordinates; per material its alpha mask in `texels` (RGBA8 packed, a << 24).
struct GridTables {
  std::vector<shared::GridInstance> instances;
  std::vector<shared::GridTriangle> triangles;
  std::vector<shared::GridTriangleUv> uvs;
  std::vector<shared::GridMaterial> materials;
  std::vector<uint32_t> texels;
  uint32_t static_instances = 0;
  uint32_t static_triangles = 0;  // triangles of the static instances (first)
};
GridTables pack_tables(const Scene& scene);
// Appends the texels of `tex` to `texels`, RGBA8 packed (r | g << 8 | b << 16 | a << 24).
void append_rgba8(const Texture& tex, std::vector<uint32_t>& texels);

// Everything a backend needs to build the grid: the params (flags as requested; the trace runs
// trace_flags of them), the spill list's capacity, the choice behind them and the tables.
struct GridPlan {
  shared::GridParams params{};
  uint32_t spill_capacity = 0;
  // The compact layout: the static references the build will store (counted as the build's count
  // pass does), the cells that hold one (the index of occupied cells' runs) and the dynamic region
  uint64_t static_references = 0;
  uint64_t static_cells = 0;
  CellBox region;
  GridChoice choice;
  GridTables tables;
};
// The plan of `scene` at `time` under `options` (overrides settled here).
GridPlan plan_grid(const Scene& scene, float time, const GridOptions& options);

}  // namespace gridrt::plan
