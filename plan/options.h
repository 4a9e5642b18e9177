// options.h: every knob of the grid, with its default (docs/SPEC.md, "Parameters"), grouped by
// purpose: the algorithm's knobs (what becomes shared::GridParams and the trace's flags), the
// plan's (how choose_grid picks the resolution and capacity, the limits, the overrides) and the
// CPU emulation's (threads, shuffled invocation order). GridOptions holds all three; a function
// takes the group it reads.
#pragma once

#include <algorithm>
#include <cstdint>
#include <optional>

#include <glm/glm.hpp>

#include "gridrt/common/scene.h"

namespace gridrt::plan {

enum class Traversal { paper, exact };
enum class Insertion { first_empty, sorted };

inline constexpr float kAabbPadding = 1.0e-3f;  // the AABB padding where none is chosen
// A chosen grid whose densest cell holds this many references is warned of (plan/choose.cpp,
// warn_crowded_cell): the real scenes' densest cells hold at most a few hundred
inline constexpr uint32_t kCrowdedCellReferences = 4096;

// The algorithm: what GridParams and the trace's flags are made of (make_params, trace_flags).
struct AlgorithmOptions {
  // Traversal and insertion
  Traversal traversal = Traversal::paper;
  Insertion insertion = Insertion::sorted;  // sorted: images independent of thread timing
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
  // The mailbox (docs/SPEC.md "Mailbox"): the exact traversal does not test again a reference it
  // tested among the last kMailboxSize on the ray (the hit cannot change; only the test count
  // drops). Exact traversal with sorted insertion only; the paper traversal tests per segment and
  // stays the paper's; first-empty insertion orders a cell's slots by the build's timing, which the
  // test count would then depend on. Off by default: on an NVIDIA H100 it took 12-22 % of the
  // tests off the three frames' bounce rays but made their trace 11-16 % slower (the shift
  // register's compares and moves cost more than the re-tests, whose triangles are still cached;
  // docs/BENCHMARKS.md "The mailbox").
  bool mailbox = false;
  // Covered cells (docs/SPEC.md "Covered cells"): the exact traversal does not read the static run
  // of a cell entered through a face whose cover bit says every reference of the run lies in the
  // neighbour's run across it (tested there: the hit cannot change; only the test count drops).
  // Needs the compact layout and the skip field (the cover bits follow its distances).
  bool skip_covered = true;
  // The build's cell test (docs/SPEC.md "Scene build", *Separating axes*): sphere, the paper's (the triangle's plane
  // through the cell's enlarged bounding sphere, within its AABB's cell range); box, that and the
  // separating-axis test against the padded cell box (kGridCellBox: fewer references); automatic:
  // box for the exact traversal, sphere for the paper's.
  enum class CellTest { automatic, sphere, box } cell_test = CellTest::automatic;
  // The spill list (docs/SPEC.md, "Spill list"): references no slot took are kept as (cell, ref) and
  // the trace tests a saturated cell's spilled references too. automatic: on for the exact
  // traversal, off for the paper's (which answers saturation with gap-fill; spill on turns
  // gap-fill off). Its capacity is a plan knob (PlanOptions::spill_capacity).
  enum class Spill { automatic, on, off } spill = Spill::automatic;
  // The grid's layout (docs/SPEC.md "Compact layout"): image, the paper's fixed-capacity 3D image
  // (slots per cell, status texels); compact, the static references in one array ordered per cell
  // (indexed by an occupancy mask per 32 cells and a start per occupied cell) and the dynamic ones
  // only in the spill list (exact traversal with the spill list only); automatic: compact for the
  // exact traversal (with the spill list, and no capacity asked for), image for the paper's.
  enum class Layout { automatic, compact, image } layout = Layout::automatic;
  // paper: consecutive samples in one cell: merge (one visit, the union of their segments),
  // skip (the literal reading of visited-cell tracking), retest (a second visit)
  enum class Repeats { merge, skip, retest } repeats = Repeats::merge;
  // Triangle test: Moller-Trumbore (fast, not watertight) or Woop-Benthin-Wald (watertight);
  // automatic: watertight for the exact traversal (no ray through a shared edge or vertex passes
  // between its triangles), Moller-Trumbore for the paper's (docs/SPEC.md, "Triangle test")
  enum class TriangleTest { automatic, moller, watertight } triangle_test = TriangleTest::automatic;
};

// The plan: how choose_grid picks resolution and capacity (docs/SPEC.md, "Grid placement,
// resolution and capacity"), the limits it keeps within, and the overrides.
struct PlanOptions {
  float density = 2.0f;                   // target cells per triangle
  bool density_given = false;             // --density named: a scene file's size does not silently win
  // trace_cost (default): candidate resolutions around the density target are counted, each with
  // capacity = min(its largest cell count, what the limits allow), and the one whose estimated
  // trace cost on a sample of the frame's rays is lowest is taken (work_cost, plan/policy.h).
  // no_saturation: the candidate closest to the density target whose largest cell count fits the
  // limits, capacity = that count (no cell drops a reference); if none fits, the candidate
  // dropping the fewest references.
  // percentile: the original rule, capacity = capacity_percentile of the non-empty cells' counts.
  enum class CapacityPolicy { trace_cost, no_saturation, percentile } capacity_policy = CapacityPolicy::trace_cost;
  // The rule was named by the user (--capacity RULE): a scene file's capacity does not replace it
  bool capacity_policy_given = false;
  // trace_cost: the cost of a candidate in reference tests per ray: tests + cell_visit_cost *
  // cells visited + saturation_cost * (expected share of rays whose answer saturation changes).
  // Unset: the traversal's own (plan::cell_visit_cost: the exact trace's fitted on the H200, the
  // paper's as it was first set; docs/SPEC.md "Grid placement, resolution and capacity").
  std::optional<float> cell_visit_cost;
  float saturation_cost = 1.0e5f;
  uint32_t work_sample_width = 96, work_sample_height = 54;  // the sample's gather buffer (16:9)
  uint32_t work_sample_frames = 4;     // glossy bounce rays of up to this many frames off that gather
  uint32_t work_sample_rays = 4000;    // buffer, fewer once this many rays are sampled
  float capacity_percentile = 0.99f;      // percentile policy: capacity = this percentile of counts
  uint32_t min_capacity = 4, max_capacity = 1024;
  bool max_capacity_given = false;        // --max-capacity named: refused where no slots are chosen
  // The scene axis laid along the image's x (the slots' axis): automatic = the axis with the fewest
  // cells, which leaves the most room for slots under max_image_dimension.
  enum class SlotAxis { automatic, x, y, z } slot_axis = SlotAxis::automatic;
  uint32_t max_image_dimension = 4096;    // 4096 on lavapipe, 16384 on NVIDIA
  uint64_t max_texels = uint64_t(1) << 28;  // the memory budget: 2^28 texels = 1 GiB of image
  // The compact layout's memory budget in bytes (grid_memory: everything the grid keeps); none:
  // kCompactBytesPerTriangle per scene triangle, at least kCompactMinBudget. --memory-budget sets it
  // (and max_texels for the image layout).
  std::optional<uint64_t> memory_budget;
  // The compact layout's offsets (docs/SPEC.md "Compact layout"): dense, one per cell; sparse, the
  // occupied cells' only (an occupancy mask per 32 cells: a quarter of the bytes, one dependent
  // load more per occupied cell); automatic: dense where it fits the memory budget, sparse for a
  // grid that fits only so, chosen only if its estimate beats the best dense grid's by
  // kSparseOffsetsMargin.
  enum class Offsets { automatic, dense, sparse } offsets = Offsets::automatic;
  uint32_t capacity_time_samples = 16;    // dynamic instances counted at this many times of their motion
  // The spill list's entries; default: the references choose_grid's trial would drop, with margin
  // (choose_spill_capacity).
  std::optional<uint32_t> spill_capacity;
  // Overrides of the automatic resolution and capacity. Where one is unset the scene's own
  // (Scene::grid) applies: settle_overrides, the one place that decides.
  std::optional<glm::uvec3> resolution;   // cells per axis
  std::optional<uint32_t> capacity;       // slots per cell
  std::optional<float> cell_size;         // world units
};

// The CPU emulation: invocations on threads (0 = std::thread::hardware_concurrency()); a seed
// runs the build/update invocations in a seeded shuffled order (on any thread count). The plan's
// own parallel work (the policy's candidates and sample) uses the same threads.
struct EmulationOptions {
  unsigned threads = 0;
  std::optional<uint64_t> shuffle_seed;
};

struct GridOptions : AlgorithmOptions, PlanOptions, EmulationOptions {};

inline constexpr unsigned kMaxThreads = 1024;
inline constexpr uint64_t kMaxWorkSamplePixels = 256 * 144;  // the trace-cost sample, traced once per candidate

// Every number of `o` within the range the command line allows for it (apps/backends.cpp), else
// OptionsError naming the field: choose_grid checks it first, so a program that sets GridOptions
// itself gets the command line's rules (a capacity of 0 built a grid in which every ray missed;
// a negative elongation, a paper trace that found nothing).
void check_options(const GridOptions& o);

// The options with every override settled: the resolution, capacity and cell size of `o` where
// set, else the scene's (Scene::grid). (The command line's --resolution and image limit are
// written into GridOptions by the tool before this.)
GridOptions settle_overrides(GridOptions o, const Scene& scene);

unsigned thread_count(const EmulationOptions& options);

// The triangle test `o` traces with: automatic is the watertight test for the exact traversal and
// Moller-Trumbore for the paper's (plan/choose.cpp makes GridParams::triangle_test from it).
inline AlgorithmOptions::TriangleTest resolved_triangle_test(const AlgorithmOptions& o) {
  if (o.triangle_test != AlgorithmOptions::TriangleTest::automatic) return o.triangle_test;
  return o.traversal == Traversal::exact ? AlgorithmOptions::TriangleTest::watertight
                                         : AlgorithmOptions::TriangleTest::moller;
}

// The options of the grid that makes a frame's gather buffer on the CPU: the exact traversal
// with the watertight test, whatever the trace's. The paper rasterizes its gather buffer, so
// primary visibility is exact, and watertight: a rasterizer's rules give every pixel of a closed
// mesh to one of its triangles. The watertight test computes a shared edge's function once for
// both faces, so no camera ray passes between them; Moller-Trumbore let 11 of 1,024 pixels of a
// closed mesh see the background (an outside sweep). The GPU frame's gather takes the same test
// (gather_ray_test): the CPU and GPU gathers agree in bits (docs/SPEC.md, "The gather as a
// rasterizer").
inline GridOptions gather_options(GridOptions o) {
  o.traversal = Traversal::exact;
  o.triangle_test = AlgorithmOptions::TriangleTest::watertight;
  // Exact primary visibility: the plane test's sphere holds the whole cell (an enlargement below 1
  // is the paper traversal's knob, for its segments, not for the gather)
  o.sphere_enlargement = std::max(o.sphere_enlargement, 1.0f);
  // and AABB padding above 0 (0 is the paper traversal's knob too): the default where it is not
  if (o.aabb_padding && !(*o.aabb_padding > 0.0f)) o.aabb_padding.reset();
  // and every reference kept: the spill list on at its forecast capacity (a full cell of
  // `--spill off` or a fixed `--spill-capacity` dropped triangles the GPU's gathers see), and no
  // self-hit offset (the bounce rays' knob: it made camera rays miss what the GPU's gathers hit)
  o.spill = AlgorithmOptions::Spill::on;
  o.spill_capacity.reset();
  o.self_hit_offset = AlgorithmOptions{}.self_hit_offset;
  // The trace's --max-capacity is the trace's: the gather's grid may take the compact layout
  o.max_capacity_given = false;
  return o;
}

}  // namespace gridrt::plan
