// grid.h: the CPU reference of the fixed-capacity grid (the spec the Vulkan port is held to).
// The paper's three phases as functions of the same names as the shaders':
//   scene_build  (2.1)  one emulated geometry-shader invocation per triangle, on threads
//   scene_update (2.2)  clear_dynamic_references, then the dynamic instances' invocations
//   scene_trace  (2.3)  one ray: paper segments or the exact DDA
// and ReferenceGridTracer, the gridrt::Tracer over them. docs/SPEC.md states every rule.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/scene.h"
#include "common/shared/explain.h"
#include "common/shared/grid.h"
#include "common/shared/triangle.h"
#include "common/tracer.h"
#include "reference/image3d.h"

namespace gridrt::reference {

enum class Traversal { paper, exact };
enum class Insertion { first_empty, sorted };

inline constexpr float kAabbPadding = 1.0e-3f;  // the AABB padding where none is chosen

// Every knob of the grid, with its default (docs/SPEC.md, "Parameters").
struct GridOptions {
  // Traversal and insertion
  Traversal traversal = Traversal::paper;
  Insertion insertion = Insertion::sorted;  // sorted: images independent of thread timing
  // Emulated invocations: 0 threads = std::thread::hardware_concurrency(); a seed runs the
  // build/update invocations in a seeded shuffled order (on any thread count)
  unsigned threads = 0;
  std::optional<uint64_t> shuffle_seed;
  // Build (2.1)
  float sphere_enlargement = 1.25f;  // cell bounding-sphere radius multiplier (>= 1: conservative)
  // Cell units added on each side of a triangle's AABB. None: kAabbPadding, except that the
  // trace-cost policy also weighs paper_padding for the paper traversal (its samples then find
  // triangles whose cells they step past; docs/SPEC.md "Grid placement, resolution and capacity")
  std::optional<float> aabb_padding;
  float paper_padding = 0.25f;
  // Trace (2.3)
  float elongation = 0.5f;           // paper: segment elongation on each side, in segment lengths
  float gap_fill_distance = 2.0f;    // paper: cells the segment must be away from the launch surface
  float self_hit_offset = 0.0f;      // hits need t * |dir| > self_hit_offset * cell_size
  bool exclude_launch_ref = true;    // never accept the launch triangle (RayRecord::launch_ref)
  bool alpha_keying = true;          // alpha-keyed materials cut holes (Features::alpha_keying)
  bool gap_fill = true;              // paper: gap-fill in saturated cells (Features::gap_fill)
  // Gap-fill runs (is compiled into the trace shader) only while some cell is saturated, that is
  // while the spill counter says a reference was dropped; false keeps it always (--all-effects).
  bool gap_fill_if_saturated = true;
  // Empty-space skipping (docs/SPEC.md "Empty-space skipping"): the exact traversal's DDA passes
  // boxes of empty cells at once, by the skip field built after the static references. Exact
  // traversal only; the paper traversal stays the paper's.
  bool skip_empty = true;
  // The spill list (docs/SPEC.md, "Spill list"): references no slot took are kept as (cell, ref) and
  // the trace tests a saturated cell's spilled references too. automatic: on for the exact
  // traversal, off for the paper's (which answers saturation with gap-fill; spill on turns
  // gap-fill off). spill_capacity: entries the list holds; default: the references choose_grid's
  // trial would drop, with margin (choose_spill_capacity).
  enum class Spill { automatic, on, off } spill = Spill::automatic;
  std::optional<uint32_t> spill_capacity;
  // paper: consecutive samples in one cell: merge (one visit, the union of their segments),
  // skip (the literal reading of visited-cell tracking), retest (a second visit)
  enum class Repeats { merge, skip, retest } repeats = Repeats::merge;
  // Triangle test: Moller-Trumbore (fast, not watertight) or Woop-Benthin-Wald (watertight)
  enum class TriangleTest { moller, watertight } triangle_test = TriangleTest::moller;
  // Automatic resolution and capacity (overridden by the fields below, then by Scene::grid);
  // docs/SPEC.md, "Grid placement, resolution and capacity"
  float density = 2.0f;                   // target cells per triangle
  // trace_cost (default): candidate resolutions around the density target are counted, each with
  // capacity = min(its largest cell count, what the limits allow), and the one whose estimated
  // trace cost on a sample of the frame's rays is lowest is taken (work_cost, reference/policy.h).
  // no_saturation: the candidate closest to the density target whose largest cell count fits the
  // limits, capacity = that count (no cell drops a reference); if none fits, the candidate
  // dropping the fewest references.
  // percentile: the original rule, capacity = capacity_percentile of the non-empty cells' counts.
  enum class CapacityPolicy { trace_cost, no_saturation, percentile } capacity_policy = CapacityPolicy::trace_cost;
  // trace_cost: the cost of a candidate in reference tests per ray: tests + cell_visit_cost *
  // cells visited + saturation_cost * (expected share of rays whose answer saturation changes)
  float cell_visit_cost = 1.0f;
  float saturation_cost = 1.0e5f;
  uint32_t work_sample_width = 96, work_sample_height = 54;  // the sample's gather buffer (16:9)
  uint32_t work_sample_frames = 4;     // glossy bounce rays of up to this many frames off that gather
  uint32_t work_sample_rays = 4000;    // buffer, fewer once this many rays are sampled
  float capacity_percentile = 0.99f;      // percentile policy: capacity = this percentile of counts
  uint32_t min_capacity = 4, max_capacity = 1024;
  // The scene axis laid along the image's x (the slots' axis): automatic = the axis with the fewest
  // cells, which leaves the most room for slots under max_image_dimension.
  enum class SlotAxis { automatic, x, y, z } slot_axis = SlotAxis::automatic;
  uint32_t max_image_dimension = 4096;    // 4096 on lavapipe, 16384 on NVIDIA
  uint64_t max_texels = uint64_t(1) << 28;  // the memory budget: 2^28 texels = 1 GiB of image
  uint32_t capacity_time_samples = 16;    // dynamic instances counted at this many times of their motion
  std::optional<glm::uvec3> resolution;   // cells per axis
  std::optional<uint32_t> capacity;       // slots per cell
  std::optional<float> cell_size;         // world units
};

// Everything the GPU holds, as the shaders see it.
struct GridData {
  shared::GridParams params{};
  Image3D image;                                 // the 3D image of references
  WordBuffer dirty;                              // the dirty-cell list (shared::dirty_list_words)
  std::vector<shared::GridInstance> instances;   // per instance: triangle offset, count, flags
  std::vector<shared::GridTriangle> triangles;   // world-space triangles (geometry buffer)
  std::vector<shared::GridTriangleUv> uvs;       // per triangle texture coordinates
  std::vector<shared::GridMaterial> materials;   // per material: its alpha mask in `texels`
  std::vector<uint32_t> texels;                  // alpha masks, RGBA8 packed (a << 24)
  uint32_t static_instances = 0;
  uint32_t static_triangles = 0;                 // triangles of the static instances (first)
  // The spill list: the header (its count is updated with atomics), `capacity` entries, and per
  // cell the heads of its static and dynamic lists, ordered and arrival (spill_head_index,
  // spill_arrival_index; empty with spill off)
  shared::SpillHeader spill_header{};
  std::vector<shared::SpillEntry> spill;
  std::vector<uint32_t> spill_heads;
  // The skip field (kGridSkipEmpty; shared::skip_words words): the dynamic boxes, then the static
  // distances (shared/grid.h, "The skip field"); empty without kGridSkipEmpty
  std::vector<uint32_t> skip;
  uint32_t requested_flags = 0;                  // GridParams::flags as chosen; params.flags is what
                                                 // the trace runs (trace_flags)
};

// Whether `o` turns the spill list on (Spill::automatic: for the exact traversal).
bool spill_enabled(const GridOptions& o);

// Whether `o` turns empty-space skipping on (kGridSkipEmpty: the exact traversal with skip_empty).
bool skip_enabled(const GridOptions& o);

// The skip field's header words (shared::kSkipHeaderWords): the boxes of cells that cover the
// dynamic instances' references at `time` (shared::skip_box_of_bounds; instance i of the dynamic
// ones joins box i % kSkipMaxBoxes). Both backends upload these at every build and update.
std::vector<uint32_t> skip_box_words(const Scene& scene, float time, const shared::GridParams& g);

// The skip field's static distances from the static references in `grid.image` (slot 0 of a cell
// not blank): shared::kSkipMaxDistance-capped Chebyshev distances by a summed-volume table and a
// binary search per cell, as the skip_field compute passes do.
void skip_field_build(GridData& grid, const GridOptions& o);

// Grid placement and size chosen from the scene (docs/SPEC.md, "Resolution and capacity").
shared::GridParams choose_grid(const Scene& scene, float time, const GridOptions& options);

// The work a trace does per ray on one grid: estimated by the trace-cost policy on its ray sample
// (estimate_work, reference/policy.h), or measured from hit records (measured_work).
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
  bool fits = false;             // within max_image_dimension and max_texels
  WorkEstimate work;             // trace_cost policy: the estimated work on its ray sample
  double cost = 0.0;             // trace_cost policy: work_cost(work)
};
// The candidates choose_grid weighed (in the order it weighed them) and the index it took; empty
// when capacity or resolution is overridden.
struct GridChoice {
  std::vector<GridCandidate> candidates;
  size_t chosen = 0;
  WorkSample sample;  // trace_cost: the rays the estimates were made on
};
shared::GridParams choose_grid(const Scene& scene, float time, const GridOptions& options, GridChoice* choice);
// The spill list's capacity for grid `g` (chosen by choose_grid with `choice`): 0 with spill off;
// else the option, or the references the trial would drop (the chosen candidate's `dropped`, or a
// count on `g` where choose_grid weighed no candidate) plus a quarter and 64 (the trial samples
// moving instances at 16 times: a bound it is not).
uint32_t choose_spill_capacity(const Scene& scene, float time, const GridOptions& options, const shared::GridParams& g,
                               const GridChoice& choice);
// The flags the trace runs with: `requested` (GridParams::flags as chosen) without gap-fill while no
// reference is dropped (`spill_count` == 0: no cell is saturated), unless gap_fill_if_saturated is off.
uint32_t trace_flags(uint32_t requested, const GridOptions& options, uint32_t spill_count);
// World bounds of the scene over its whole animation: static instances at `time`, dynamic ones
// swept over their motion; not padded.
Bounds animation_bounds(const Scene& scene, float time);

// Phases (paper names)
void scene_build(GridData& grid, const Scene& scene, float time, const GridOptions& options);
void scene_update(GridData& grid, const Scene& scene, float time, const GridOptions& options);
void clear_dynamic_references(GridData& grid, const GridOptions& options);
void insert_first_empty(GridData& grid, glm::uvec3 cell, uint32_t ref);
void insert_sorted(GridData& grid, glm::uvec3 cell, uint32_t ref);
void spill_reference(GridData& grid, glm::uvec3 cell, uint32_t ref);
void spill_order(GridData& grid, const GridOptions& options, uint32_t first);

uint32_t first_slot_at_least(const Image3D& image, const shared::GridParams& g, glm::uvec3 cell, uint32_t bound);
void append_dirty_cell(WordBuffer& dirty, const shared::GridParams& g, glm::uvec3 cell);
// The dirty-cell list's cells (linear indices, shared::cell_linear_index) in list order: the
// cells appended since the last clear pass.
std::vector<uint32_t> dirty_cells(const GridData& grid);

// The spill list as plain data: the header, the stored entries [0, min(count, capacity)) in the
// order they were appended (which differs between runs and backends: compare them as multisets,
// and the lists walked from the heads, which are in ascending reference order), and the heads.
struct SpillDump {
  bool on = false;  // kGridSpill: with spill off the count only counts, and nothing overflows
  shared::SpillHeader header{};
  std::vector<shared::SpillEntry> entries;
  std::vector<uint32_t> heads;
  uint32_t stored() const { return header.count < header.capacity ? header.count : header.capacity; }
  uint32_t overflow() const { return on && header.count > header.capacity ? header.count - header.capacity : 0u; }
};
SpillDump spill_dump(const GridData& grid);

// The explanation of one ray: the events in order, and the hit.
struct ExplainRecord {
  Ray ray{};
  shared::GridParams params{};
  std::vector<shared::ExplainEvent> events;
  Hit hit{};
};
std::string to_text(const ExplainRecord& record);

// scene_trace for one ray; `explain` (may be null) receives the events.
Hit scene_trace(const GridData& grid, const Ray& ray, ExplainRecord* explain);

struct GridStats {
  glm::vec3 origin{0.0f};
  float cell_size = 0.0f;
  glm::uvec3 cells{0};
  uint32_t capacity = 0;
  glm::uvec3 image_extent{0};
  uint64_t image_bytes = 0, geometry_bytes = 0;   // the image; triangles + uvs + tables + masks
  uint64_t cell_count = 0, empty_cells = 0;
  uint64_t saturated_static = 0, saturated_dynamic = 0;  // cells with that status bit
  // The spill list: references that found no slot (appended, with spill off only counted), of
  // them static, the list's capacity, entries stored, lost to overflow; whether it is on
  bool spill_on = false;
  uint64_t spill_appended = 0, spill_static = 0, spill_capacity = 0, spill_stored = 0, spill_overflow = 0;
  bool gap_fill_active = false;                   // the trace runs gap-fill (trace_flags)
  std::vector<uint64_t> occupancy;                // occupancy[k]: cells holding k references
  uint64_t references = 0;                        // non-blank slots
  uint64_t triangles = 0, degenerate_triangles = 0;
  double references_per_triangle_mean = 0.0;      // over non-degenerate triangles
  uint32_t references_per_triangle_max = 0;
  // The build's work (docs/BENCHMARKS.md, "Static build"): cells of each triangle's AABB range
  // (each gets the plane test); the sorted insertion's slot accesses had every insertion walked
  // from slot 0 to the first blank (a cell of n references costs n(n+1)/2, in any order), in
  // total and along the longest chain of one build invocation (the sum over its cells of their
  // final n); the galloping search's loads along that invocation (2 ceil(log2(n + 1)) per cell)
  double range_cells_per_triangle_mean = 0.0;
  uint64_t range_cells_per_triangle_max = 0;
  uint64_t walk_accesses = 0;
  uint64_t walk_chain_max = 0, search_chain_max = 0;
  double build_ms = 0.0, update_ms = 0.0;         // last build / update, wall clock
};
GridStats grid_stats(const GridData& grid);
std::string to_text(const GridStats& stats);

// The Tracer: build/update/trace/dump over the functions above.
class ReferenceGridTracer : public Tracer {
 public:
  explicit ReferenceGridTracer(GridOptions options = {});
  std::string name() const override { return "reference-grid"; }
  void build(const Scene& scene, float time) override;
  void update(float time) override;
  void trace(std::span<const Ray> rays, std::span<Hit> hits) override;
  AccelDump dump() const override;

  ExplainRecord explain_ray(const Ray& ray) const;
  GridStats stats() const;
  SpillDump spill() const { return spill_dump(grid_); }
  const GridOptions& options() const { return options_; }
  const GridData& data() const { return grid_; }
  const shared::GridParams& params() const { return grid_.params; }

 private:
  GridOptions options_;
  const Scene* scene_ = nullptr;
  GridData grid_;
  double build_ms_ = 0.0, update_ms_ = 0.0;
  bool overflow_warned_ = false;
};

// A one-time warning on stderr when the spill list overflowed (references lost: holes possible);
// `warned` keeps it to once per tracer.
void warn_spill_overflow(const SpillDump& spill, const std::string& who, bool& warned);

// Helpers shared by the reference's passes and tests
unsigned thread_count(const GridOptions& options);
// Hex bits of a float, e.g. "0x3f800000".
std::string hex(float f);

}  // namespace gridrt::reference
