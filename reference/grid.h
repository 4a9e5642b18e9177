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

#include "gridrt/common/scene.h"
#include "gridrt/common/shared/explain.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/triangle.h"
#include "gridrt/common/tracer.h"
#include "gridrt/plan/plan.h"
#include "gridrt/plan/policy.h"
#include "gridrt/plan/records.h"
#include "gridrt/reference/image3d.h"

namespace gridrt::reference {

// The plan (plan/): the options, choose_grid and the records, shared with the Vulkan port.
using plan::AlgorithmOptions;
using plan::animation_bounds;
using plan::choose_grid;
using plan::choose_spill_capacity;
using plan::EmulationOptions;
using plan::ExplainRecord;
using plan::for_each_visit;
using plan::GridCandidate;
using plan::GridChoice;
using plan::GridOptions;
using plan::GridPlan;
using plan::hex;
using plan::Insertion;
using plan::kAabbPadding;
using plan::measured_work;
using plan::PlanOptions;
using plan::spill_enabled;
using plan::SpillDump;
using plan::thread_count;
using plan::to_text;
using plan::trace_flags;
using plan::Traversal;
using plan::warn_spill_overflow;
using plan::WorkEstimate;
using plan::WorkSample;


// Everything the GPU holds, as the shaders see it.
struct GridData {
  shared::GridParams params{};
  Image3D image;                                 // the 3D image of references
  WordBuffer dirty;                              // the dirty-cell list (shared::dirty_list_words)
  std::vector<shared::GridInstance> instances;   // per instance: triangle offset, count, flags
  std::vector<shared::GridTriangle> triangles;   // world-space triangles (geometry buffer)
  std::vector<shared::GridPlane> planes;         // per triangle its plane (the plane buffer: triangle_plane)
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
  // The compact layout (kGridCompact; docs/SPEC.md "Compact layout"): `offsets` indexes the
  // occupied cells' runs (shared/grid.h: per word of 32 cells its base and occupancy mask, then per
  // occupied cell its run's start, then the total; compact_run), each run's static references in
  // `refs` in ascending order; `spill_heads` is then the region's
  // header and two heads per region cell (shared::compact_head_index); the image a one-texel
  // stand-in. The build's temporaries (the count pass's per-cell counts, later the scatter's
  // cursors, and its (cell, ref) pairs) are emptied after the build.
  std::vector<uint32_t> offsets, refs;
  std::vector<uint32_t> compact_counts, compact_pairs, compact_scattered;
  uint32_t compact_pair_count = 0;
  uint32_t requested_flags = 0;                  // GridParams::flags as chosen; params.flags is what
                                                 // the trace runs (trace_flags)
};

// The skip field's static distances from the static references in `grid.image` (slot 0 of a cell
// not blank): shared::kSkipMaxDistance-capped Chebyshev distances by a summed-volume table and a
// binary search per cell, as the skip_field compute passes do.
void skip_field_build(GridData& grid, const GridOptions& o);

// Phases (paper names)
void scene_build(GridData& grid, const Scene& scene, float time, const GridOptions& options);
void scene_update(GridData& grid, const Scene& scene, float time, const GridOptions& options);
// The spill list grown to `capacity` entries (more than it holds), its stored entries kept: an
// update inserts again after it (ReferenceGridTracer::update, plan::spill_growth).
void spill_grow(GridData& grid, uint32_t capacity);
void clear_dynamic_references(GridData& grid, const GridOptions& options);
void insert_first_empty(GridData& grid, glm::uvec3 cell, uint32_t ref);
void insert_sorted(GridData& grid, glm::uvec3 cell, uint32_t ref);
void spill_reference(GridData& grid, glm::uvec3 cell, uint32_t ref);
void spill_order(GridData& grid, const GridOptions& options, uint32_t first);
// The compact layout's passes (docs/SPEC.md "Compact layout"): count (in the static pass: per cell
// an atomic count, and the (cell, ref) pair appended), offsets (the exclusive scan of the counts:
// block sums, the blocks' scan, each block's offsets, which also set the cursors), scatter (each
// pair to its cell's run at an atomic cursor), order (each reference to its rank in its run), and
// the update's clear_dynamic_spill (the counter back to the static count, every dynamic head empty).
void compact_count(GridData& grid, glm::uvec3 cell, uint32_t ref);
void compact_offsets(GridData& grid, const GridOptions& options);
void compact_scatter(GridData& grid, const GridOptions& options);
void compact_order(GridData& grid, const GridOptions& options);
// Cell i's run of static references, refs[begin .. end), through the index of occupied cells
// (false, and an empty run, for a cell that holds none); and how many cells hold one.
bool compact_run(const GridData& grid, uint32_t i, uint32_t& begin, uint32_t& end);
uint32_t compact_occupied_cells(const GridData& grid);
void clear_dynamic_spill(GridData& grid);
// Whether a cell holds a static reference (slot 0 not blank, or a non-empty run).
bool cell_occupied(const GridData& grid, glm::uvec3 cell);
// A cell's references in order (the slots up to the first blank, or its compact run: static only)
// and its status texel (compact: 0, no cell saturates).
std::vector<uint32_t> cell_references(const GridData& grid, glm::uvec3 cell);
// Every reference the trace tests in `cell`: cell_references, then the spilled ones it walks there
// (a saturated cell's lists with the spill list on; the compact layout's dynamic region list)
std::vector<uint32_t> cell_traced_references(const GridData& grid, glm::uvec3 cell);
uint32_t cell_status(const GridData& grid, glm::uvec3 cell);
// Everything the grid keeps, as allocated (plan::grid_memory's parts).
plan::GridMemory grid_allocated(const GridData& grid);

uint32_t first_slot_at_least(const Image3D& image, const shared::GridParams& g, glm::uvec3 cell, uint32_t bound);
void append_dirty_cell(WordBuffer& dirty, const shared::GridParams& g, glm::uvec3 cell);
// The dirty-cell list's cells (linear indices, shared::cell_linear_index) in list order: the
// cells appended since the last clear pass (compact layout, which keeps no list: the cells of the
// dynamic spill entries, in entry order).
std::vector<uint32_t> dirty_cells(const GridData& grid);

SpillDump spill_dump(const GridData& grid);
// The spill list's header alone (no entries, no heads: a dump's 32 bytes a cell are not made), for
// the overflow warning and the statistics.
SpillDump spill_counts(const GridData& grid);


// scene_trace for one ray; `explain` (may be null) receives the events; `mode`: which hit
// (shared::kTraceClosestHit, or kTraceAnyHit: the first accepted, docs/SPEC.md "Any hit").
Hit scene_trace(const GridData& grid, const Ray& ray, ExplainRecord* explain,
                uint32_t mode = shared::kTraceClosestHit);

struct GridStats {
  glm::vec3 origin{0.0f};
  float cell_size = 0.0f;
  glm::uvec3 cells{0};
  uint32_t capacity = 0;
  glm::uvec3 image_extent{0};
  uint64_t image_bytes = 0, geometry_bytes = 0;   // the image; triangles + planes + uvs + tables + masks
  bool compact = false;                           // the compact layout (image_extent: its stand-in)
  bool sparse_offsets = false;                   // its offsets of the occupied cells only (kGridSparseOffsets)
  uint64_t region_cells = 0;                      // compact: the dynamic region's cells
  plan::GridMemory memory;                        // everything the grid keeps
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
  void build_scene(const Scene& scene, float time) override;
  void update_to(float time) override;
  void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) override;
  void trace_occlusion(std::span<const Ray> rays, std::span<Hit> hits) override;
  AccelDump dump() const override;

  ExplainRecord explain_ray(const Ray& ray, uint32_t mode = shared::kTraceClosestHit) const;
  GridStats stats() const;
  SpillDump spill() const { return spill_dump(grid_); }
  const GridOptions& options() const { return options_; }
  const GridData& data() const { return grid_; }
  const shared::GridParams& params() const { return grid_.params; }

 private:
  // trace() and trace_any(): every ray by scene_trace in `mode`, on the options' threads
  void run_trace(std::span<const Ray> rays, std::span<Hit> hits, uint32_t mode) const;
  GridOptions options_;
  const Scene* scene_ = nullptr;
  GridData grid_;
  double build_ms_ = 0.0, update_ms_ = 0.0;
  bool overflow_warned_ = false;
};


}  // namespace gridrt::reference
