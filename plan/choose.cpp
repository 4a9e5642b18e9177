// choose.cpp: choosing the grid (choose_grid and its capacity policies), the spill list's capacity
// and the trace's flags.
#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <mutex>
#include <set>

#include "gridrt/common/invocations.h"
#include "gridrt/common/parallel.h"
#include "gridrt/common/progress.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/shared/transform.h"
#include "gridrt/plan/plan.h"
#include "gridrt/plan/policy.h"

namespace gridrt::plan {

using shared::GridParams;

namespace {
// A number for a message: %g (1e-30 is not "0.000000")
std::string gnum(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}
}  // namespace

unsigned thread_count(const EmulationOptions& options) { return thread_count_or_hardware(options.threads); }

// ---- Grid bounds over the animation ----

namespace {
// One instance's bounds over the whole animation: at `time` where it does not move, else swept.
Bounds instance_animation_bounds(const Scene& scene, const Instance& inst, float time) {
  Bounds b;
  const Mesh& mesh = scene.meshes[inst.mesh];
  // An empty mesh bounds nothing, moving or not (its empty box swept along a path read as NaN and
  // was named "not finite", and a rotating one added its pivot: an outside sweep)
  if (mesh.positions.empty()) return b;
  if (!inst.dynamic || !inst.motion.moves()) {
    const glm::mat4 m = inst.transform_at(time);
    for (const glm::vec3& p : mesh.positions) b.grow(glm::vec3(m * glm::vec4(p, 1.0f)));
    return b;
  }
  // Swept bounds: world p = path(t) + pivot + R(t) (base p - pivot). A rotating instance stays
  // in the sphere around its pivot through its farthest base vertex; the path offsets stay in
  // the hull of the path points (piecewise linear).
  const Motion& mo = inst.motion;
  Bounds local;
  if (mo.angular_speed != 0.0f) {
    float r = 0.0f;
    for (const glm::vec3& p : mesh.positions)
      r = std::max(r, glm::length(glm::vec3(inst.transform * glm::vec4(p, 1.0f)) - mo.pivot));
    // Relative margins: 1e-4 of the radius, and 8 ulps of the coordinates the rotated vertices
    // round at (an absolute 1e-6 made a scene 2e-9 across a grid 1000 times its size, and the
    // policy's warning blamed the pivot: an outside sweep)
    const glm::vec3 ap = glm::abs(mo.pivot);
    r = r * 1.0001f + (std::max({ap.x, ap.y, ap.z}) + r) * 9.5367431640625e-07f;
    local.grow(mo.pivot - glm::vec3(r));
    local.grow(mo.pivot + glm::vec3(r));
  } else {
    for (const glm::vec3& p : mesh.positions) local.grow(glm::vec3(inst.transform * glm::vec4(p, 1.0f)));
  }
  if (mo.path_points.empty()) {
    b.grow(local);
  } else {
    for (const glm::vec3& off : mo.path_points) {
      b.grow(local.lo + off);
      b.grow(local.hi + off);
    }
  }
  return b;
}
}  // namespace

Bounds animation_bounds(const Scene& scene, float time) {
  Bounds b, still;
  const Instance* widest = nullptr;
  float widest_side = 0.0f, widest_own = 0.0f;  // the widest sweep against its instance's own size
  const auto side = [](const Bounds& x) {
    const glm::vec3 e = x.empty() ? glm::vec3(0.0f) : x.extent();
    return std::max({e.x, e.y, e.z});
  };
  for (const Instance& inst : scene.instances) {
    const Bounds ib = instance_animation_bounds(scene, inst, time);
    if (!inst.motion.moves()) {
      still.grow(ib);
    } else if (side(ib) > widest_side) {
      Bounds own;
      const glm::mat4 m = inst.transform_at(time);
      for (const glm::vec3& p : scene.meshes[inst.mesh].positions) own.grow(glm::vec3(m * glm::vec4(p, 1.0f)));
      widest = &inst, widest_side = side(ib), widest_own = side(own);
    }
    // A sweep past float range (a pivot 3e38 away: the rotation's sphere overflowed, and the grid
    // blamed its cell size): named here, with the instance
    const auto finite = [](const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); };
    const bool nan = glm::any(glm::isnan(ib.lo)) || glm::any(glm::isnan(ib.hi));
    if (nan || (!ib.empty() && !(finite(ib.lo) && finite(ib.hi))))
      throw Error("instance '" + inst.name + "': its bounds over the animation (pivot, rotation, path) are not finite");
    b.grow(ib);
  }
  // One moving instance sweeping a box far larger than itself and the still geometry (a small
  // object turning about a pivot far away): the grid's cells are sized for the whole box, and the
  // still geometry falls into a few of them (an outside tester's 35,000 triangles in one cell: 30 s
  // for a 64 x 36 picture instead of 1.6). Valid, so said once per scene, not refused
  static std::mutex warned_lock;
  static std::set<std::string> warned;
  const float still_side = side(still);
  const float reference = std::max(still_side, widest_own);
  if (widest && still_side > 0.0f && widest_side > 1000.0f * reference) {
    const std::lock_guard<std::mutex> hold(warned_lock);
    if (warned.insert(scene.name).second)
      std::fprintf(stderr,
                   "gridrt: warning: instance '%s' sweeps a box of %g over its motion, %.0f times its own size and the "
                   "still geometry's (%g): the grid's cells are sized for the whole box, and the still geometry falls "
                   "into few cells (slow traces); a pivot or path nearer the scene keeps them fine\n",
                   widest->name.c_str(), double(widest_side), double(widest_side / reference), double(reference));
  }
  return b;
}

CellBox dynamic_region(const Scene& scene, float time, const GridParams& g) {
  Bounds b;
  for (size_t i = scene.static_instance_count(); i < scene.instances.size(); ++i)
    b.grow(instance_animation_bounds(scene, scene.instances[i], time));
  CellBox r;
  if (b.empty()) return r;
  // One cell of margin beyond the AABB padding: the swept bounds are computed with other float
  // operations than the build's transform_point
  const glm::vec3 margin(1.0f + g.aabb_padding);
  r.lo = shared::cell_of_local(g, shared::grid_local(g, b.lo) - margin);
  r.hi = shared::cell_of_local(g, shared::grid_local(g, b.hi) + margin);
  return r;
}

std::vector<uint32_t> compact_heads(const CellBox& region) {
  std::vector<uint32_t> w(shared::kCompactHeadsHeader + 2 * region.cells(), shared::kSpillEnd);
  w[0] = region.lo.x, w[1] = region.lo.y, w[2] = region.lo.z, w[3] = 0u;
  w[4] = region.hi.x, w[5] = region.hi.y, w[6] = region.hi.z, w[7] = 0u;
  return w;
}

bool compact_enabled(const AlgorithmOptions& o) {
  switch (o.layout) {
    case AlgorithmOptions::Layout::compact: return true;
    case AlgorithmOptions::Layout::image: return false;
    case AlgorithmOptions::Layout::automatic: break;
  }
  return o.traversal == Traversal::exact && spill_enabled(o);
}

void compact_check(const AlgorithmOptions& o) {
  if (o.layout != AlgorithmOptions::Layout::compact) return;
  if (o.traversal != Traversal::exact)
    throw OptionsError("grid: the compact layout is for the exact traversal (the paper traversal keeps the image: --layout image)");
  if (!spill_enabled(o))
    throw OptionsError("grid: the compact layout keeps the dynamic references in the spill list: it needs --spill on");
}

uint64_t compact_budget(const PlanOptions& o, uint64_t scene_triangles) {
  if (o.memory_budget) return *o.memory_budget;
  return std::max(kCompactMinBudget, kCompactBytesPerTriangle * scene_triangles);
}

uint64_t range_cells_budget(uint64_t scene_triangles) {
  return std::max(kRangeCellsFloor, kRangeCellsPerTriangle * scene_triangles);
}

uint64_t range_cells(const Scene& scene, float time, const GridParams& g) {
  uint64_t sum = 0;
  for (size_t i = 0; i < scene.instances.size(); ++i)
    for_each_placed_triangle(scene, i, time, g, [&](const PlacedTriangle& p) {
      const glm::uvec3 k = p.hi - p.lo + 1u;
      sum += uint64_t(k.x) * k.y * k.z;
    });
  return sum;
}

GridMemory grid_memory(const GridParams& g, uint64_t static_refs, uint64_t static_cells, uint32_t spill_capacity,
                       uint64_t region_cells) {
  GridMemory m;
  const uint64_t cells = uint64_t(g.cells.x) * g.cells.y * g.cells.z;
  const bool spill = (g.flags & shared::kGridSpill) != 0u;
  m.spill = sizeof(shared::SpillHeader) + uint64_t(std::max(spill_capacity, 1u)) * sizeof(shared::SpillEntry);
  m.skip = (g.flags & shared::kGridSkipEmpty) != 0u ? uint64_t(shared::skip_words(g)) * 4 : 0;
  if ((g.flags & shared::kGridCompact) != 0u) {
    m.image = 4;  // a one-texel stand-in keeps the image binding valid
    m.offsets = (g.flags & shared::kGridSparseOffsets) != 0u
                    ? (2 * ((cells + 31) / 32) + static_cells + 1) * 4  // shared::compact_offsets_words
                    : (cells + 1) * 4;
    m.refs = std::max<uint64_t>(static_refs, 1) * 4;
    m.heads = (shared::kCompactHeadsHeader + 2 * region_cells) * 4;
    m.dirty = shared::kWorkListHeaderWords * 4;  // a stand-in (an empty list's header): no dirty-cell list
  } else {
    const glm::uvec3 e = shared::grid_image_extent(g);
    m.image = uint64_t(e.x) * e.y * e.z * 4;
    m.heads = spill ? 16 * cells : 0;
    m.dirty = uint64_t(shared::dirty_list_words(g)) * 4;
  }
  return m;
}

uint64_t host_build_memory(const GridParams& g, uint64_t static_refs, uint64_t static_cells, uint32_t spill_capacity,
                           uint64_t region_cells) {
  const uint64_t cells = uint64_t(g.cells.x) * g.cells.y * g.cells.z;
  const bool compact = (g.flags & shared::kGridCompact) != 0u;
  // What the grid keeps, and the largest of the temporaries, which live one after the other: the
  // plan's trial counts (a word a cell, before the grid is made), the compact passes' counts, pairs
  // and scattered references (freed once the runs are ordered), the skip field's summed-volume
  // table and bricks' distances (freed after its passes); an eighth more for the allocator's slack
  // (checked against peak resident sets, exact and paper, both layouts: docs/ROBUSTNESS.md)
  const uint64_t grid = grid_memory(g, static_refs, static_cells, spill_capacity, region_cells).total();
  uint64_t temporary = 4 * cells;
  if (compact) temporary = std::max(temporary, 4 * cells + 12 * std::max<uint64_t>(static_refs, 1));
  if ((g.flags & shared::kGridSkipEmpty) != 0u) {
    const uint64_t table = uint64_t(g.cells.x + 1) * (g.cells.y + 1) * (g.cells.z + 1);
    const uint64_t bricks = uint64_t((g.cells.x + 3) / 4) * ((g.cells.y + 3) / 4) * ((g.cells.z + 3) / 4);
    temporary = std::max(temporary, 4 * (table + bricks));
  }
  const uint64_t bytes = grid + temporary;
  return bytes + bytes / 8;
}

namespace {

// The trial that chooses the capacity: per cell the references a build would insert (no
// capacity). Instances that do not move count at `time` (`fixed`, every cell); moving ones, in the
// box of cells they can reach, at `samples` times spread over the longest period of their motions
// (at most 60 s): their count at `time` (the first sample) and, per cell, the largest.
// `fixed_limit`: once the static references counted pass it, the count stops (tc.over_limit): a
// compact candidate whose references alone are over the memory budget is not counted to its end
// (300,000 copies of one triangle spent 36 s counting coarser candidates the budget then refused:
// an outside sweep). The decision is the one the whole count would give.
struct TrialOverLimit {};
TrialCounts trial_counts(const Scene& scene, float time, const GridParams& g, uint32_t samples,
                         uint64_t fixed_limit = ~uint64_t(0)) {
  TrialCounts tc;
  tc.cells = g.cells;
  tc.fixed.assign(size_t(g.cells.x) * g.cells.y * g.cells.z, 0u);
  std::vector<size_t> moving;
  double horizon = 0.0;
  uint64_t fixed_total = 0;
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    if (!inst.dynamic || !inst.motion.moves()) {
      try {
        for_each_triangle_cell(scene, i, time, g, [&](uint32_t, size_t c) {
          ++tc.fixed[c];
          if (++fixed_total > fixed_limit) throw TrialOverLimit{};
        });
      } catch (const TrialOverLimit&) {
        tc.over_limit = true;
        return tc;
      }
      continue;
    }
    moving.push_back(i);
    const Motion& mo = inst.motion;
    if (mo.path_points.size() > 1) horizon = std::max(horizon, double(mo.path_period));
    if (mo.angular_speed != 0.0f) horizon = std::max(horizon, 2.0 * 3.14159265358979 / std::abs(double(mo.angular_speed)));
  }
  if (moving.empty()) return tc;
  horizon = std::min(horizon, 60.0);
  const uint32_t n = std::max(1u, samples);
  std::vector<float> times(n);
  for (uint32_t k = 0; k < n; ++k) times[k] = float(double(time) + horizon * double(k) / double(n));
  // The box of cells the moving instances reach (their triangles' cell ranges at every sample),
  // so that a sample costs its references, not the grid's cells
  glm::uvec3 lo(~0u), hi(0u);
  for (float t : times)
    for (size_t i : moving) {
      const Instance& inst = scene.instances[i];
      const Mesh& mesh = scene.meshes[inst.mesh];
      const shared::Affine m = shared::to_affine(inst.transform_at(t));
      for (const glm::uvec3& tri : mesh.triangles) {
        glm::uvec3 a, b;
        shared::triangle_cell_range(g, shared::transform_point(m, mesh.positions[tri.x]),
                                    shared::transform_point(m, mesh.positions[tri.y]),
                                    shared::transform_point(m, mesh.positions[tri.z]), a, b);
        lo = glm::min(lo, a);
        hi = glm::max(hi, b);
      }
    }
  if (lo.x > hi.x || lo.y > hi.y || lo.z > hi.z) return tc;
  tc.box_lo = lo;
  tc.box_size = hi - lo + 1u;
  const size_t nbox = size_t(tc.box_size.x) * tc.box_size.y * tc.box_size.z;
  tc.moving_now.assign(nbox, 0u);
  tc.moving_max.assign(nbox, 0u);
  std::vector<uint32_t> dyn(nbox, 0u);
  const auto box_index = [&](size_t c) {
    const size_t x = c % g.cells.x, y = (c / g.cells.x) % g.cells.y, z = c / (size_t(g.cells.x) * g.cells.y);
    return ((z - lo.z) * tc.box_size.y + (y - lo.y)) * tc.box_size.x + (x - lo.x);
  };
  for (uint32_t k = 0; k < n; ++k) {
    std::fill(dyn.begin(), dyn.end(), 0u);
    for (size_t i : moving) for_each_triangle_cell(scene, i, times[k], g, [&](uint32_t, size_t c) { ++dyn[box_index(c)]; });
    if (k == 0) tc.moving_now = dyn;
    for (size_t b = 0; b < nbox; ++b) tc.moving_max[b] = std::max(tc.moving_max[b], dyn[b]);
  }
  return tc;
}

void set_cell_size(GridParams& g, float cell_size, const GridOptions& o) {
  g.cell_size = cell_size;
  g.inv_cell_size = 1.0f / cell_size;
  const double half_diagonal = double(cell_size) * std::sqrt(3.0) / 2.0;
  g.sphere_r2 = float(std::pow(double(o.sphere_enlargement) * half_diagonal, 2.0));
  g.gap_fill_r2 = float(std::pow(double(o.gap_fill_distance) * double(cell_size), 2.0));
}

// The slot axis for `cells`: the option, or the axis with the fewest cells (ties: x, y, z).
uint32_t slot_axis_for(glm::uvec3 cells, const GridOptions& o) {
  switch (o.slot_axis) {
    case GridOptions::SlotAxis::x: return 0;
    case GridOptions::SlotAxis::y: return 1;
    case GridOptions::SlotAxis::z: return 2;
    case GridOptions::SlotAxis::automatic: break;
  }
  if (cells.x <= cells.y && cells.x <= cells.z) return 0;
  return cells.y <= cells.z ? 1 : 2;
}

glm::uvec3 cells_for(glm::vec3 extent, float cs) {
  const glm::vec3 n = glm::ceil(extent / cs);
  return glm::uvec3(glm::clamp(n, glm::vec3(1.0f), glm::vec3(1.0e6f)));
}

// The largest capacity the limits allow `cells` with slots along `axis` (0 when none does).
uint32_t capacity_allowed(glm::uvec3 cells, uint32_t axis, const GridOptions& o) {
  const uint64_t along = cells[axis];
  for (uint32_t a = 0; a < 3; ++a)
    if (a != axis && cells[a] > o.max_image_dimension) return 0;
  const uint64_t total = uint64_t(cells.x) * cells.y * cells.z;
  const uint64_t by_dim = o.max_image_dimension / along;
  const uint64_t by_mem = o.max_texels / total;
  const uint64_t cap = std::min({by_dim, by_mem, uint64_t(o.max_capacity) + 1});
  return cap == 0 ? 0 : uint32_t(cap - 1);
}

// Weigh one resolution: count, then the capacity that drops nothing if the limits allow it.
// `counts_out` (may be null) receives the trial's counts.
// `range_bounded`: an automatic resolution, held to the work bound (range_cells_budget).
// The shared code counts and indexes a grid's cells in 32 bits (grid_cell_count, cell_linear_index,
// the compact offsets): a grid of 2^31 cells or more is never made (an outside sweep: 4096x4096x256
// cells wrapped to 0 and the plan wrote past its occupancy map after taking 17 GB).
constexpr uint64_t kMaxGridCells = uint64_t(1) << 31;
bool too_many_cells(glm::uvec3 cells) { return uint64_t(cells.x) * cells.y * cells.z >= kMaxGridCells; }

GridCandidate weigh(const Scene& scene, float time, GridParams& g, float cs, glm::uvec3 cells,
                    std::optional<uint32_t> cap_over, const GridOptions& o, bool range_bounded,
                    TrialCounts* counts_out = nullptr) {
  GridCandidate c;
  c.cell_size = cs;
  c.aabb_padding = g.aabb_padding;
  c.cells = cells;
  if (too_many_cells(cells)) return c;  // c.fits false: not a candidate
  c.slot_axis = slot_axis_for(cells, o);
  const bool compact = (g.flags & shared::kGridCompact) != 0u;
  const uint32_t allowed = capacity_allowed(cells, c.slot_axis, o);
  const uint32_t lowest = cap_over ? *cap_over : o.min_capacity;
  c.fits = compact || allowed >= lowest;
  if (!c.fits) return c;
  set_cell_size(g, cs, o);
  g.cells = cells;
  // The compact layout's budget: a grid whose cells alone (the offsets' index, skip field) exceed
  // it is not counted either (a 1000^3 resolution: 5 GB before the budget said no)
  // (sparse offsets where allowed: the least any layout of these cells takes)
  const bool sparse_allowed = o.offsets != GridOptions::Offsets::dense;
  const bool dense_allowed = o.offsets != GridOptions::Offsets::sparse;
  const auto with_offsets = [&](bool sparse) {
    GridParams t = g;
    t.flags = sparse ? (t.flags | shared::kGridSparseOffsets) : (t.flags & ~shared::kGridSparseOffsets);
    return t;
  };
  if (compact) {
    c.memory = grid_memory(with_offsets(sparse_allowed), 0, 0, 0, 0).total();
    if (c.memory > compact_budget(o, scene.triangle_count())) {
      c.fits = false;
      return c;
    }
  }
  // The host memory the trial and the build take for these cells alone (the least layout, the
  // least capacity): a request beyond the machine fails here, before the trial counts a cell.
  // An automatic candidate is not counted (a coarser one is); an explicit resolution is an error.
  {
    GridParams least = compact ? with_offsets(sparse_allowed) : g;
    least.capacity = lowest;
    least.flags = (least.flags & ~shared::kGridSlotAxisMask) | (c.slot_axis << shared::kGridSlotAxisShift);
    const uint64_t bytes = host_build_memory(least, 0, 0, 0, 0);
    if (bytes > host_memory_available()) {
      if (range_bounded) {
        c.fits = false;
        c.over_host = bytes;
        return c;
      }
      require_host_memory(bytes,
                          "grid: " + std::to_string(cells.x) + "x" + std::to_string(cells.y) + "x" +
                              std::to_string(cells.z) + " cells",
                          "lower --resolution or raise --cell-size");
    }
  }
  // The work bound: a grid whose AABB ranges alone exceed it is not counted (nor built)
  c.range_cells = range_cells(scene, time, g);
  if (range_bounded && c.range_cells > range_cells_budget(scene.triangle_count())) {
    c.fits = false;
    c.over_bound = true;
    return c;
  }
  // The compact layout: the references past which the grid is over the budget whatever else it
  // holds (each 4 bytes beyond the cells' own memory, c.memory above, which counts one)
  uint64_t fixed_limit = ~uint64_t(0);
  if (compact) {
    const uint64_t budget = compact_budget(o, scene.triangle_count());
    fixed_limit = (budget - c.memory) / 4 + 1;
  }
  TrialCounts counts = trial_counts(scene, time, g, o.capacity_time_samples, fixed_limit);
  if (counts.over_limit) {
    c.fits = false;
    c.memory += 4 * (fixed_limit + 1) - 4;
    c.memory_at_least = true;
    return c;
  }
  counts.for_each_largest([&](uint32_t n) { c.max_count = std::max(c.max_count, n); });
  if (compact) {
    // No slots: nothing is dropped (capacity = the largest count, so that the estimate tests every
    // reference); fits within the memory budget, counted by grid_memory
    c.capacity = std::max(c.max_count, 1u);
    uint64_t fixed = 0, moving = 0, occupied = 0;
    for (uint32_t n : counts.fixed) fixed += n, occupied += n != 0u;
    for (uint32_t n : counts.moving_max) moving += n;
    const uint64_t spill = moving + moving / 4 + 64;
    const uint32_t spill_entries = uint32_t(std::min<uint64_t>(spill, 1u << 28));
    const uint64_t region = dynamic_region(scene, time, g).cells();
    const uint64_t budget = compact_budget(o, scene.triangle_count());
    // Dense offsets where they fit (no index to read), else sparse
    c.sparse_offsets = !dense_allowed;
    c.memory = grid_memory(with_offsets(c.sparse_offsets), fixed, occupied, spill_entries, region).total();
    if (c.memory > budget && !c.sparse_offsets && sparse_allowed) {
      c.sparse_offsets = true;
      c.memory = grid_memory(with_offsets(true), fixed, occupied, spill_entries, region).total();
    }
    c.fits = c.memory <= budget;
    if (counts_out) *counts_out = std::move(counts);
    return c;
  }
  c.capacity = cap_over ? *cap_over : std::clamp(c.max_count, o.min_capacity, allowed);
  if (c.max_count > c.capacity)
    counts.for_each_largest([&](uint32_t n) {
      if (n > c.capacity) c.dropped += n - c.capacity, c.saturated_cells += 1;
    });
  c.texels = uint64_t(cells.x) * cells.y * cells.z * (c.capacity + 1);
  if (counts_out) *counts_out = std::move(counts);
  return c;
}

}  // namespace

GridParams choose_grid(const Scene& scene, float time, const GridOptions& o) {
  return choose_grid(scene, time, o, nullptr);
}

void check_options(const GridOptions& o) {
  // `what` (the field, and the option that sets it) within [lo, hi]; NaN lies outside every range
  const auto within = [](double v, double lo, double hi, const char* what) {
    if (!(v >= lo && v <= hi))
      throw OptionsError("grid options: " + std::string(what) + " is " + gnum(v) + ", outside [" + gnum(lo) + ", " +
                         gnum(hi) + "]");
  };
  // (a capacity above max_capacity is refused by choose_grid, naming both; the automatic capacity of
  // an image layout may reach 65,535 with --max-capacity, and `grid --measure` builds it back)
  if (o.capacity) within(*o.capacity, 1, 65535, "capacity (--capacity, at most --max-capacity)");
  if (o.resolution)
    for (int a = 0; a < 3; ++a) within((*o.resolution)[a], 1, 16384, "a resolution's cells per axis (--resolution)");
  if (o.cell_size) within(*o.cell_size, std::numeric_limits<float>::min(), std::numeric_limits<float>::max(), "cell_size (--cell-size)");
  within(o.density, 1e-3, 1e3, "density (--density)");
  within(o.max_capacity, 4, 65535, "max_capacity (--max-capacity)");
  within(o.min_capacity, 1, o.max_capacity, "min_capacity (1 to max_capacity)");
  within(o.max_image_dimension, 2, 65536, "max_image_dimension (--max-image-dimension)");
  within(double(o.max_texels), 1, double(uint64_t(1) << 48), "max_texels (--memory-budget)");
  if (o.memory_budget) within(double(*o.memory_budget), 1, double(uint64_t(1) << 50), "memory_budget (--memory-budget)");
  within(o.sphere_enlargement, 0, 16, "sphere_enlargement (--enlargement)");
  if (o.aabb_padding) within(*o.aabb_padding, 0, 16, "aabb_padding (--aabb-padding)");
  within(o.paper_padding, 0, 16, "paper_padding");
  within(o.elongation, 0, 16, "elongation (--elongation)");
  within(o.gap_fill_distance, 0, 1e6, "gap_fill_distance (--gap-fill-distance)");
  within(o.self_hit_offset, 0, 1e6, "self_hit_offset (--self-hit-offset)");
  if (o.spill_capacity) within(*o.spill_capacity, 0, 1u << 28, "spill_capacity (--spill-capacity)");
  if (o.cell_visit_cost) within(*o.cell_visit_cost, 0, 1e6, "cell_visit_cost (--cell-visit-cost)");
  within(o.saturation_cost, 0, 1e12, "saturation_cost (--saturation-cost)");
  within(o.capacity_percentile, 1e-6, 1, "capacity_percentile (above 0, at most 1)");
  within(o.work_sample_width, 1, 4096, "work_sample_width (--work-sample)");
  within(o.work_sample_height, 1, 4096, "work_sample_height (--work-sample)");
  within(double(o.work_sample_width) * o.work_sample_height, 1, double(kMaxWorkSamplePixels),
         "work_sample_width x work_sample_height (--work-sample)");
  within(o.work_sample_frames, 1, 64, "work_sample_frames");
  within(o.work_sample_rays, 1, 1 << 20, "work_sample_rays");
  within(o.capacity_time_samples, 1, 1024, "capacity_time_samples");
  within(o.threads, 0, kMaxThreads, "threads (--threads)");
}

GridOptions settle_overrides(GridOptions o, const Scene& scene) {
  // The command line over the scene file, the grid's size as one choice: a resolution or a cell
  // size given there replaces the file's (either); both given at one level are refused, where
  // the cell size silently won (an outside sweep's find)
  if (o.resolution && o.cell_size)
    throw OptionsError("--resolution and --cell-size both size the grid: give one of them");
  if (!o.resolution && !o.cell_size) {
    o.resolution = scene.grid.resolution;
    o.cell_size = scene.grid.cell_size;
  }
  // A capacity rule named on the command line (--capacity trace-cost, ...) replaces the file's
  // number too, as a number named there does
  if (!o.capacity && !o.capacity_policy_given) o.capacity = scene.grid.capacity;
  // Knobs of a choice the file has made (outside sweeps: accepted, the grid the same)
  if (o.density_given && (o.resolution || o.cell_size))
    throw OptionsError("--density picks the automatic resolution; the scene file fixes the grid's size (its grid's "
                       "resolution or cell_size): it does nothing (leave it out, or give --resolution or --cell-size)");
  if (o.max_capacity_given && !o.capacity && compact_enabled(o))
    throw OptionsError("--max-capacity bounds the image layout's automatic slots per cell; the grid here takes the "
                       "compact layout (the exact traversal's default), which has none: it does nothing (leave it "
                       "out, or give --layout image)");
  return o;
}

namespace {

// The grid's box: the animation's bounds, padded by 1e-3 of the largest extent on every side.
Bounds grid_box(const Scene& scene, float time) {
  Bounds b = animation_bounds(scene, time);
  if (b.empty()) throw Error("grid: the scene has no vertices");
  const glm::vec3 ext = b.extent();
  // 1e-3 of the largest extent, whatever the scene's size: a floor of 1e-3 padded a scene 1e-9
  // across by 1e-6 on every side, and the whole model fell into one cell of a grid a thousand
  // times its size (the paper traversal dropping references, an outside sweep)
  const float big = std::max({ext.x, ext.y, ext.z});
  // At least the narrowest cell the domain allows at the box's reach (min_cell_size): a flat or
  // tiny model far from the origin keeps a box of non-zero extent on every axis, where 1e-3 of its
  // size would round away in its coordinates.
  const float reach = std::max({std::abs(b.lo.x), std::abs(b.lo.y), std::abs(b.lo.z), std::abs(b.hi.x),
                                std::abs(b.hi.y), std::abs(b.hi.z)});
  const float pad = std::max(1e-3f * big, min_cell_size(reach));
  b.lo -= glm::vec3(pad);
  b.hi += glm::vec3(pad);
  return b;
}

// The cell size to start from: the override, the resolution's, or density cells per triangle
// (cubic cells) over a box of extent `e`.
float target_cell_size(const Scene& scene, const GridOptions& o, const Bounds& b) {
  const glm::vec3 e = b.extent();
  float cs;
  if (o.cell_size) {
    cs = *o.cell_size;
  } else if (o.resolution) {
    const glm::uvec3 res = *o.resolution;
    cs = std::max({e.x / float(res.x), e.y / float(res.y), e.z / float(res.z)});
  } else {
    const double target = std::max(1.0, double(o.density) * double(scene.triangle_count()));
    cs = float(std::cbrt(double(e.x) * double(e.y) * double(e.z) / target));
  }
  if (!(cs > 0.0f) || !std::isfinite(cs)) throw Error("grid: cell size must be positive and finite");
  // The domain (docs/SPEC.md, "Domain"): coordinates within 2^24, and cells no narrower than
  // kMinCellUlps ulps of the largest coordinate (else the DDA's cell boundaries, rounded to the
  // coordinates' ulps, could step past the cell of a hit): an automatic size is coarsened (its
  // finest trace-cost candidate, a quarter of it, included), an override refused.
  const float reach = std::max({std::abs(b.lo.x), std::abs(b.lo.y), std::abs(b.lo.z), std::abs(b.hi.x),
                                std::abs(b.hi.y), std::abs(b.hi.z)});
  if (!(reach <= shared::kDomainMaxCoordinate))
    throw Error("grid: the scene's grid box (its bounds padded by 1e-3 of their largest side) reaches " + gnum(reach) +
                " from the origin; the domain ends at 2^24 = " + gnum(shared::kDomainMaxCoordinate) +
                " (move it nearer the origin or scale it down)");
  if (cs > kMaxCellSize)
    throw Error("grid: cells of " + gnum(cs) + " are wider than the domain allows (at most 2^26 = " +
                gnum(kMaxCellSize) + ", four times its reach: one such cell holds any scene)");
  const float min_cs = min_cell_size(reach);
  if (cs < min_cs && (o.cell_size || o.resolution))
    throw Error("grid: cells of " + gnum(cs) + " are narrower than " + gnum(kMinCellUlps) +
                " ulps of the scene's coordinates (" + gnum(min_cs) + " at " + gnum(reach) +
                " from the origin); choose coarser cells or move the scene nearer the origin");
  if (!o.cell_size && !o.resolution) cs = std::max(cs, 4.0f * min_cs);
  return cs;
}

// The GridParams fields the algorithm's knobs decide (traversal, insertion, flags, ...).
GridParams algorithm_params(const AlgorithmOptions& o, const Scene& scene) {
  GridParams g{};
  g.aabb_padding = o.aabb_padding.value_or(kAabbPadding);
  g.elongation = o.elongation;
  g.self_hit_offset = o.self_hit_offset;
  g.comparison_offset = scene.static_instance_count() << 16;
  g.insertion = o.insertion == Insertion::sorted ? shared::kInsertSorted : shared::kInsertFirstEmpty;
  g.traversal = o.traversal == Traversal::exact ? shared::kTraversalExact : shared::kTraversalPaper;
  g.triangle_test = resolved_triangle_test(o) == GridOptions::TriangleTest::watertight ? shared::kTriangleWatertight
                                                                                       : shared::kTriangleMoller;
  g.flags = (o.exclude_launch_ref ? shared::kGridExcludeLaunchRef : 0u) |
            (o.alpha_keying ? shared::kGridAlphaKeying : 0u) |
            (spill_enabled(o) ? shared::kGridSpill : (o.gap_fill ? shared::kGridGapFill : 0u)) |
            (skip_enabled(o) ? shared::kGridSkipEmpty : 0u) | (cell_box_enabled(o) ? shared::kGridCellBox : 0u) |
            (compact_enabled(o) ? shared::kGridCompact : 0u) | (mailbox_enabled(o) ? shared::kGridMailbox : 0u) |
            (covered_enabled(o) ? shared::kGridSkipCovered : 0u);
  g.repeats = o.repeats == GridOptions::Repeats::skip     ? shared::kRepeatSkip
              : o.repeats == GridOptions::Repeats::retest ? shared::kRepeatRetest
                                                          : shared::kRepeatMerge;
  return g;
}

Error too_big(glm::uvec3 cells, uint32_t cap, const GridOptions& o) {
  return Error("grid: " + std::to_string(cells.x) + "x" + std::to_string(cells.y) + "x" + std::to_string(cells.z) +
               " cells of capacity " + std::to_string(cap) + " exceed the image limits (max dimension " +
               std::to_string(o.max_image_dimension) + " (--max-image-dimension, or the device's), max texels " +
               std::to_string(o.max_texels) + " (--memory-budget, 4 bytes a texel)): give coarser cells (--resolution, "
               "--cell-size), a smaller --capacity, or a larger --memory-budget");
}

// `p` with the candidate's offsets (kGridSparseOffsets: the compact layout's index of occupied cells).
GridParams with_sparse_offsets(GridParams p, const GridCandidate& c) {
  if (c.sparse_offsets) p.flags |= shared::kGridSparseOffsets;
  return p;
}

// `base` with `cells` of edge `cell_size`, capacity `cap`, slots along `axis`, AABB padding `padding`.
GridParams sized_params(const GridParams& base, glm::uvec3 cells, float cell_size, uint32_t cap, uint32_t axis,
                        float padding, const GridOptions& o) {
  GridParams p = base;
  p.aabb_padding = padding;
  set_cell_size(p, cell_size, o);
  p.cells = cells;
  p.capacity = cap;
  p.flags |= axis << shared::kGridSlotAxisShift;
  p.upper = p.origin + glm::vec3(p.cells) * p.cell_size;
  p.max_segments = p.cells.x + p.cells.y + p.cells.z + 3u;
  return p;
}

// The percentile policy: capacity = a percentile of the trial's non-empty cells, clamped; larger
// cells until the image fits.
GridParams choose_by_percentile(const Scene& scene, float time, const GridOptions& o, GridParams g, glm::vec3 e,
                                float cs) {
  const std::optional<glm::uvec3> res = o.resolution;
  const std::optional<float> cs_over = o.cell_size;
  for (int attempt = 0;; ++attempt) {
    set_cell_size(g, cs, o);
    g.cells = (res && !cs_over) ? *res : cells_for(e, cs);
    // The work bound (an automatic resolution): coarser cells until the AABB ranges fit it
    if (!res && !cs_over && attempt <= 60 &&
        range_cells(scene, time, g) > range_cells_budget(scene.triangle_count())) {
      cs = float(double(cs) * 1.25);
      continue;
    }
    std::vector<uint32_t> nonempty;
    trial_counts(scene, time, g, o.capacity_time_samples).for_each_largest([&](uint32_t c) {
      if (c) nonempty.push_back(c);
    });
    uint32_t cap = o.min_capacity;
    if (!nonempty.empty()) {
      const size_t k = std::min(nonempty.size() - 1,
                                size_t(std::ceil(double(o.capacity_percentile) * double(nonempty.size()))) - 1);
      std::nth_element(nonempty.begin(), nonempty.begin() + ptrdiff_t(k), nonempty.end());
      cap = nonempty[k];
    }
    cap = std::clamp(cap, o.min_capacity, o.max_capacity);
    const uint32_t axis = slot_axis_for(g.cells, o);
    const uint32_t allowed = capacity_allowed(g.cells, axis, o);
    if (cap <= allowed && allowed > 0) return sized_params(g, g.cells, cs, cap, axis, g.aabb_padding, o);
    if ((res && !cs_over) || attempt > 60) throw too_big(g.cells, cap, o);
    const double along = double(g.cells[axis]) * (cap + 1);
    const double texels = along * double(g.cells.x) * g.cells.y * g.cells.z / g.cells[axis];
    const double ratio = std::max({along / o.max_image_dimension, double(g.cells.x) / o.max_image_dimension,
                                   double(g.cells.y) / o.max_image_dimension,
                                   double(g.cells.z) / o.max_image_dimension,
                                   std::cbrt(texels / double(o.max_texels)), 1.1});
    cs = float(double(cs) * std::min(ratio, 2.0));
  }
}

// A compact-layout candidate over the memory budget, as an error naming the budget's option.
Error over_budget(const GridCandidate& c, const GridOptions& o, const Scene& scene) {
  const auto mib = [](uint64_t bytes) {
    char b[32];
    std::snprintf(b, sizeof b, "%.1f", double(bytes) / double(1u << 20));
    return std::string(b);
  };
  // Two sizes that round alike ("0.1 MiB over a budget of 0.1 MiB") are given in bytes too
  const uint64_t budget = compact_budget(o, scene.triangle_count());
  const bool alike = mib(c.memory) == mib(budget);
  const auto size = [&](uint64_t bytes) {
    return mib(bytes) + " MiB" + (alike ? " (" + std::to_string(bytes) + " bytes)" : std::string());
  };
  return Error("grid: " + std::to_string(c.cells.x) + "x" + std::to_string(c.cells.y) + "x" + std::to_string(c.cells.z) +
               " cells take " + (c.range_cells == 0 || c.memory_at_least ? "at least " : "") + size(c.memory) +
               " in the compact layout, over its memory budget of " + size(budget) + " (--memory-budget)");
}

// A grid whose densest cell holds thousands of references: a part of the scene far smaller than
// its extent (a teapot in a stadium) that no uniform grid within the limits separates. Every ray
// through that cell tests all of them (an outside test: a teapot of 89,000 triangles beside two
// triangles 1e6 away, one cell of 9 x 9 x 9 holding the teapot, 70 s for a 160 x 90 frame).
// Valid, so said once per scene and kind of grid, with what the trace will pay and what helps. A
// grid without the spill list (`spill` false: the paper traversal's) keeps `capacity` of them and
// drops the rest: said so (the warning said every ray tests them all, where a paper grid had
// dropped 4,098 of 5,122 and a shadow went missing: an outside sweep).
void warn_crowded_cell(const Scene& scene, const GridCandidate& c, bool spill, float reach) {
  if (c.max_count < kCrowdedCellReferences) return;
  // Cells at the narrowest the domain allows at the scene's distance from the origin: finer ones are
  // refused there, so the advice is to move the model, not to ask for cells (a dense model 1e5 from
  // the origin alone was told of far geometry and --resolution: an outside sweep)
  if (c.cell_size <= 2.0f * min_cell_size(reach)) {
    static std::mutex domain_lock;
    static std::set<std::string> domain_warned;
    const std::lock_guard<std::mutex> hold(domain_lock);
    if (!domain_warned.insert(scene.name).second) return;
    std::fprintf(stderr,
                 "gridrt: warning: grid %ux%ux%u: its densest cell holds %u references of the scene's %llu triangles; "
                 "every ray through it tests them all. The cells (%g) are already near the narrowest the domain allows "
                 "%g from the origin (%g: %g ulps of the coordinates there, docs/SPEC.md \"Domain\"), so finer cells "
                 "are refused: expect slow traces, or move the model nearer the origin\n",
                 c.cells.x, c.cells.y, c.cells.z, c.max_count, (unsigned long long)scene.triangle_count(),
                 double(c.cell_size), double(reach), double(min_cell_size(reach)), double(kMinCellUlps));
    return;
  }
  static std::mutex warned_lock;
  static std::set<std::string> warned;
  const std::lock_guard<std::mutex> hold(warned_lock);
  if (!warned.insert(scene.name + (spill ? "#spill" : "#slots")).second) return;
  if (!spill && c.max_count > c.capacity) {
    std::fprintf(stderr,
                 "gridrt: warning: grid %ux%ux%u: its densest cell holds %u references of the scene's %llu triangles, "
                 "more than its %u slots: without the spill list (the paper traversal's default) the build keeps %u "
                 "and drops the rest (%llu references in all), so rays through such cells may miss what they should "
                 "hit (gap-fill answers some). A part of the scene far smaller than its extent (a dense model beside "
                 "far geometry) is more than a uniform grid within the limits can separate; the exact traversal keeps "
                 "every reference (--traversal exact), or keep the far geometry out\n",
                 c.cells.x, c.cells.y, c.cells.z, c.max_count, (unsigned long long)scene.triangle_count(), c.capacity,
                 c.capacity, (unsigned long long)c.dropped);
    return;
  }
  std::fprintf(stderr,
               "gridrt: warning: grid %ux%ux%u: its densest cell holds %u references of the scene's %llu triangles; "
               "every ray through it tests them all. A part of the scene far smaller than its extent (a dense "
               "model beside far geometry) is more than a uniform grid within the limits can separate: expect slow "
               "traces; keep the far geometry out, or give finer cells (--resolution, --memory-budget)\n",
               c.cells.x, c.cells.y, c.cells.z, c.max_count, (unsigned long long)scene.triangle_count());
}

// The candidate search of the no_saturation and trace_cost policies (and the one candidate of a
// resolution, cell-size or capacity override).
GridParams choose_by_candidates(const Scene& scene, float time, const GridOptions& o, GridParams g, glm::vec3 e,
                                float cs, GridChoice* choice) {
  const std::optional<glm::uvec3> res = o.resolution;
  const std::optional<float> cs_over = o.cell_size;
  const std::optional<uint32_t> cap_over = o.capacity;
  // Fixed cells (a resolution or cell-size override, or a capacity override): one candidate, an
  // error if it does not fit
  GridChoice local;
  GridChoice& ch = choice ? *choice : local;
  ch = GridChoice{};
  if (res && !cs_over) {
    const GridCandidate c = weigh(scene, time, g, cs, *res, cap_over, o, false);
    if (!c.fits && (g.flags & shared::kGridCompact) != 0u) throw over_budget(c, o, scene);
    if (!c.fits) throw too_big(*res, cap_over.value_or(o.min_capacity), o);
    ch.candidates.push_back(c);
    return with_sparse_offsets(sized_params(g, c.cells, cs, c.capacity, c.slot_axis, c.aabb_padding, o), c);
  }
  // Candidate cell sizes cs * 2^(j/4) around the density target. With a cell-size override only
  // j = 0; with a capacity override the density target unless it does not fit.
  // no_saturation: weighed in the order j = 0, -1, 1, -2, 2, ... (finer cells first at each
  // distance): the first that drops no reference wins; else the one dropping fewest.
  // trace_cost: every j counted (candidates in parallel), each one's work estimated on the frame's
  // ray sample (plan/policy.h), for the paper traversal without a padding option at two AABB
  // paddings (kAabbPadding and paper_padding); the cheapest wins.
  const bool search = !cs_over && !cap_over;
  const bool by_cost = search && o.capacity_policy == GridOptions::CapacityPolicy::trace_cost;
  const int finest = search ? -8 : 0, coarsest = search ? 12 : 0;
  std::vector<float> paddings{g.aabb_padding};
  if (by_cost && !o.aabb_padding && o.traversal == Traversal::paper && o.paper_padding != g.aabb_padding)
    paddings.push_back(o.paper_padding);
  WorkSample& sample = ch.sample;
  if (by_cost) {
    // The sample's hits do not depend on the grid (the exact traversal, no capacity): the density
    // target's cells, coarser while their AABB ranges exceed the work bound
    const uint64_t bound = range_cells_budget(scene.triangle_count());
    float sample_cs = cs;
    GridParams gs = sized_params(g, cells_for(e, sample_cs), sample_cs, 0u, 0u, g.aabb_padding, o);
    for (int k = 0; k < 80 && range_cells(scene, time, gs) > bound; ++k) {
      sample_cs = float(double(sample_cs) * std::exp2(0.25));
      gs = sized_params(g, cells_for(e, sample_cs), sample_cs, 0u, 0u, g.aabb_padding, o);
    }
    sample = work_sample(scene, time, gs, o);
  }
  const auto weigh_j = [&](int j, float padding, GridParams& gj) {
    const float c_cs = float(double(cs) * std::exp2(double(j) / 4.0));
    TrialCounts counts;
    gj.aabb_padding = padding;
    GridCandidate c = weigh(scene, time, gj, c_cs, cells_for(e, c_cs), cap_over, o, !cs_over, by_cost ? &counts : nullptr);
    if (c.fits && by_cost) {
      const GridParams gc = sized_params(g, c.cells, c_cs, c.capacity, c.slot_axis, padding, o);
      const std::vector<uint32_t> boxes =
          (gc.flags & shared::kGridSkipEmpty) != 0u ? skip_box_words(scene, time, gc) : std::vector<uint32_t>{};
      c.work = estimate_work(gc, counts, sample, boxes);
      c.cost = work_cost(c.work, o);
    }
    return c;
  };
  bool done = false;
  std::optional<GridCandidate> unfit;  // the first candidate weighed that did not fit
  if (by_cost) {
    const size_t per_pad = size_t(coarsest - finest + 1);
    std::vector<GridCandidate> all(per_pad * paddings.size());
    // A line on stderr where the weighing takes over a second (a scene of many large or
    // overlapping triangles: each candidate's trial count tests up to kRangeCellsPerTriangle cells
    // a triangle)
    Progress progress("grid: weighing " + std::to_string(all.size()) + " candidate grids", all.size());
    run_invocations(uint32_t(all.size()), thread_count(o), std::nullopt, [&](uint32_t k) {
      GridParams gk = g;
      all[k] = weigh_j(finest + int(k % per_pad), paddings[k / per_pad], gk);
      progress.advance();
    }, 1);
    progress.finish();
    for (const GridCandidate& c : all) {
      if (c.fits) ch.candidates.push_back(c);
      ch.over_bound += c.over_bound ? 1u : 0u;
    }
  } else {
    std::vector<int> order{0};
    for (int d = 1; d <= std::max(-finest, coarsest); ++d) {
      if (-d >= finest) order.push_back(-d);
      if (d <= coarsest) order.push_back(d);
    }
    for (int j : order) {
      const GridCandidate c = weigh_j(j, g.aabb_padding, g);
      ch.over_bound += c.over_bound ? 1u : 0u;
      if (!c.fits && !unfit) unfit = c;
      if (!c.fits) continue;
      ch.candidates.push_back(c);
      if (c.dropped == 0) {
        done = true;
        break;
      }
    }
  }
  // Nothing fits yet (tiny image limits): coarser cells until something does
  std::optional<GridCandidate> coarsest_unfit;  // the last of those that did not fit either
  {
    Progress progress("grid: coarser candidates weighed (none fits yet)", 0);
    for (int j = coarsest + 1; !done && ch.candidates.empty() && j < coarsest + 80; ++j) {
      if (cs_over) break;
      const GridCandidate c = weigh_j(j, paddings[0], g);
      if (c.fits) ch.candidates.push_back(c);
      else coarsest_unfit = c;
      progress.advance();
    }
  }
  // Where the last grid tried was left out for the host's memory, that is what to name
  if (ch.candidates.empty()) {
    const std::optional<GridCandidate>& c = coarsest_unfit ? coarsest_unfit : unfit;
    if (c && c->over_host)
      require_host_memory(c->over_host,
                          "grid: " + std::to_string(c->cells.x) + "x" + std::to_string(c->cells.y) + "x" +
                              std::to_string(c->cells.z) + " cells (the coarsest grid tried)",
                          "raise --max-host-mib, or free memory");
  }
  // A cell-size override that does not fit: the compact layout's budget, or the image's limits
  if (ch.candidates.empty() && cs_over && unfit && !unfit->over_bound && (g.flags & shared::kGridCompact) != 0u)
    throw over_budget(*unfit, o, scene);
  // The compact layout has no image: where even the coarsest grid tried is over the memory budget,
  // the budget is what to name (not the image's limits)
  if (ch.candidates.empty() && (g.flags & shared::kGridCompact) != 0u) {
    const std::optional<GridCandidate>& c = coarsest_unfit ? coarsest_unfit : unfit;
    if (c && !c->over_bound) throw over_budget(*c, o, scene);
  }
  if (ch.candidates.empty()) throw too_big(cells_for(e, cs), cap_over.value_or(o.min_capacity), o);
  size_t best = 0;
  for (size_t i = 1; i < ch.candidates.size(); ++i)
    if (by_cost ? ch.candidates[i].cost < ch.candidates[best].cost
                : ch.candidates[i].dropped < ch.candidates[best].dropped)
      best = i;
  // Sparse offsets cost a dependent load per occupied cell visited and build more cells, which the
  // estimate does not see: a grid that fits only with them is taken only if its estimate beats the
  // best grid with dense offsets by kSparseOffsetsMargin (docs/SPEC.md "Compact layout")
  if (by_cost && ch.candidates[best].sparse_offsets && o.offsets == GridOptions::Offsets::automatic) {
    std::optional<size_t> dense;
    for (size_t i = 0; i < ch.candidates.size(); ++i)
      if (!ch.candidates[i].sparse_offsets && (!dense || ch.candidates[i].cost < ch.candidates[*dense].cost)) dense = i;
    if (dense && ch.candidates[best].cost > kSparseOffsetsMargin * ch.candidates[*dense].cost) best = *dense;
  }
  ch.chosen = best;
  const GridCandidate& c = ch.candidates[best];
  return with_sparse_offsets(sized_params(g, c.cells, c.cell_size, c.capacity, c.slot_axis, c.aabb_padding, o), c);
}

}  // namespace

GridParams choose_grid(const Scene& scene, float time, const GridOptions& options, GridChoice* choice) {
  check_options(options);
  const GridOptions o = settle_overrides(options, scene);
  // A capacity asked for above the largest allowed: named (the image's limits are not the cause)
  if (o.capacity && *o.capacity > o.max_capacity) {
    const std::string what = "grid: a capacity of " + std::to_string(*o.capacity) + " slots is above --max-capacity " +
                             std::to_string(o.max_capacity);
    // Two options that contradict each other are a bad command line (exit 2); the scene file's
    // capacity against the option, bad input
    if (options.capacity) throw OptionsError(what);
    throw Error(what + " (the capacity is the scene file's)");
  }
  // The exact traversal's promise (every triangle in every cell it overlaps) needs the plane test's
  // sphere to hold the whole cell: an enlargement below 1 drops triangles that cross a corner
  if (o.traversal == Traversal::exact && !(o.sphere_enlargement >= 1.0f))
    throw OptionsError("grid: an enlargement of " + gnum(o.sphere_enlargement) +
                " lets the plane test drop triangles that cross a cell's corners; the exact traversal needs at "
                "least 1 (the cell's own bounding sphere); below 1 is the paper traversal's knob");
  // And AABB padding above 0: without it a triangle whose edge lies on a cell face is left out of
  // the cell across it, where a ray crossing that edge is walked (an outside tester's miss)
  if (o.traversal == Traversal::exact && o.aabb_padding && !(*o.aabb_padding > 0.0f))
    throw OptionsError("grid: an AABB padding of " + gnum(*o.aabb_padding) +
                " leaves a triangle whose edge lies on a cell face out of the cell across it; the exact traversal "
                "needs a padding above 0 (default " + gnum(kAabbPadding) + "); 0 is the paper traversal's knob");
  scene.require_extent(time, "grid");
  const Bounds b = grid_box(scene, time);
  const glm::vec3 e = b.extent();
  // Resolution: density cells per triangle, cubic cells, or the overrides
  const float cs = target_cell_size(scene, o, b);
  GridParams g = algorithm_params(o, scene);
  // A capacity asked for (option or scene) has a meaning in the image alone: auto takes the image
  if (o.capacity && o.layout == AlgorithmOptions::Layout::automatic)
    g.flags &= ~(shared::kGridCompact | shared::kGridSkipCovered);
  g.origin = b.lo;
  // Covered cells' bits live in the skip field's bytes of occupied cells (shared/grid.h, skip_byte):
  // they cost no memory, and come with the compact layout wherever it is chosen
  // Fixed cells past the grid's index range, named as such, whatever the policy (a cell size that
  // gave them was reported as "at least 0.0 MiB, over the memory budget": an outside test; the
  // percentile policy counted them). Counted in double: cells_for clamps each axis.
  if (o.cell_size || o.resolution) {
    const glm::dvec3 n = o.cell_size ? glm::ceil(glm::dvec3(e) / double(cs)) : glm::dvec3(*o.resolution);
    if (n.x * n.y * n.z >= double(kMaxGridCells)) {
      char count[96];
      std::snprintf(count, sizeof count, "%.0fx%.0fx%.0f cells are %.4g", n.x, n.y, n.z, n.x * n.y * n.z);
      throw Error("grid: " + std::string(count) +
                  ", more than a grid may have (under 2^31 = 2147483648): give coarser cells (--resolution, --cell-size)");
    }
  }
  GridChoice local;
  GridChoice& ch = choice ? *choice : local;
  GridParams p = o.capacity_policy == GridOptions::CapacityPolicy::percentile && !o.capacity
                     ? choose_by_percentile(scene, time, o, g, e, cs)
                     : choose_by_candidates(scene, time, o, g, e, cs, &ch);
  if ((p.flags & shared::kGridCompact) == 0u) p.flags &= ~shared::kGridSkipCovered;
  if (!ch.candidates.empty()) {
    const float reach = std::max({std::abs(b.lo.x), std::abs(b.lo.y), std::abs(b.lo.z), std::abs(b.hi.x),
                                  std::abs(b.hi.y), std::abs(b.hi.z)});
    warn_crowded_cell(scene, ch.candidates[ch.chosen], (p.flags & shared::kGridSpill) != 0u, reach);
  }
  return p;
}

// ---- The spill list's capacity, and which effects the trace runs ----

bool spill_enabled(const AlgorithmOptions& o) {
  switch (o.spill) {
    case GridOptions::Spill::on: return true;
    case GridOptions::Spill::off: return false;
    case GridOptions::Spill::automatic: break;
  }
  return o.traversal == Traversal::exact;
}

// ---- Empty-space skipping: which traversal takes it, the dynamic boxes ----

bool skip_enabled(const AlgorithmOptions& o) { return o.skip_empty && o.traversal == Traversal::exact; }

// The mailbox's test count depends on the order of a cell's references: with first-empty insertion
// (the paper's compare-and-swap) that order is the build's timing, so the count would differ
// between runs and backends: the mailbox is for the sorted insertion only.
bool mailbox_enabled(const AlgorithmOptions& o) {
  return o.mailbox && o.traversal == Traversal::exact && o.insertion == Insertion::sorted;
}

// The cover bits live after the skip field's distances and describe the compact layout's runs.
bool covered_enabled(const AlgorithmOptions& o) { return o.skip_covered && skip_enabled(o) && compact_enabled(o); }

bool cell_box_enabled(const AlgorithmOptions& o) {
  return o.cell_test == AlgorithmOptions::CellTest::box ||
         (o.cell_test == AlgorithmOptions::CellTest::automatic && o.traversal == Traversal::exact);
}

namespace {
// Occupied cells in the box whose corner j skip_corner(j) names: inclusion-exclusion over its 8
// corners in the summed-volume table (exact in uint arithmetic).
template <class Corner>
uint32_t skip_box_count(const GridParams& g, std::span<const uint32_t> table, Corner corner) {
  uint32_t count = 0u;
  for (uint32_t j = 0; j < 8u; ++j) {
    const uint32_t v = table[shared::skip_table_index(g, corner(j))];
    count = shared::skip_corner_positive(j) ? count + v : count - v;
  }
  return count;
}
}  // namespace

uint32_t skip_static_distance(const GridParams& g, std::span<const uint32_t> table, glm::uvec3 c, uint32_t lo,
                              uint32_t hi) {
  while (lo < hi) {
    const uint32_t mid = (lo + hi) / 2u;
    if (skip_box_count(g, table, [&](uint32_t j) { return shared::skip_cube_corner(g, c, mid, j); }) > 0u) hi = mid;
    else lo = mid + 1u;
  }
  return lo;
}

uint32_t skip_static_distance(const GridParams& g, std::span<const uint32_t> table, glm::uvec3 c) {
  return skip_static_distance(g, table, c, 0u, shared::kSkipMaxDistance);
}

uint32_t skip_brick_distance(const GridParams& g, std::span<const uint32_t> table, glm::uvec3 b) {
  uint32_t lo = 0u, hi = shared::kSkipMaxBrickDistance;
  while (lo < hi) {
    const uint32_t mid = (lo + hi) / 2u;
    if (skip_box_count(g, table, [&](uint32_t j) { return shared::skip_brick_corner(g, b, mid, j); }) > 0u) hi = mid;
    else lo = mid + 1u;
  }
  return lo;
}

std::vector<uint32_t> skip_box_words(const Scene& scene, float time, const GridParams& g) {
  std::vector<uint32_t> w(shared::kSkipHeaderWords, 0u);
  std::vector<glm::uvec3> lo(shared::kSkipMaxBoxes, glm::uvec3(~0u)), hi(shared::kSkipMaxBoxes, glm::uvec3(0u));
  uint32_t boxes = 0;
  uint32_t k = 0;  // dynamic instances with vertices so far
  for (uint32_t i = scene.static_instance_count(); i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    const Mesh& mesh = scene.meshes[inst.mesh];
    if (mesh.positions.empty()) continue;
    // The padded local bounds of its world-space vertices (the build's transform_point)
    const shared::Affine m = shared::to_affine(inst.transform_at(time));
    glm::vec3 fmin(shared::sh_infinity()), fmax(-shared::sh_infinity());
    for (const glm::vec3& p : mesh.positions) {
      const glm::vec3 f = shared::grid_local(g, shared::transform_point(m, p));
      fmin = glm::min(fmin, f);
      fmax = glm::max(fmax, f);
    }
    glm::uvec3 a, b;
    shared::skip_box_of_bounds(g, fmin, fmax, a, b);
    const uint32_t box = k++ % shared::kSkipMaxBoxes;
    lo[box] = glm::min(lo[box], a);
    hi[box] = glm::max(hi[box], b);
    boxes = std::max(boxes, box + 1);
  }
  w[0] = boxes;
  for (uint32_t b = 0; b < boxes; ++b) {
    const uint32_t at = shared::skip_box_word(b);
    const glm::uvec3 l = lo[b], h = hi[b];  // every box below `boxes` has an instance
    w[at] = l.x, w[at + 1] = l.y, w[at + 2] = l.z;
    w[at + 4] = h.x, w[at + 5] = h.y, w[at + 6] = h.z;
  }
  return w;
}

uint32_t choose_spill_capacity(const Scene& scene, float time, const GridOptions& o, const GridParams& g,
                               const GridChoice& choice) {
  if ((g.flags & shared::kGridSpill) == 0u) return 0;
  if (o.spill_capacity) return *o.spill_capacity;
  uint64_t dropped = 0;
  if ((g.flags & shared::kGridCompact) != 0u) {
    // Compact: every dynamic reference is spilled; the moving instances' largest counts over the
    // trial's samples, and the dynamic instances that do not move at `time`
    const TrialCounts tc = trial_counts(scene, time, g, o.capacity_time_samples);
    for (uint32_t n : tc.moving_max) dropped += n;
    for (size_t i = scene.static_instance_count(); i < scene.instances.size(); ++i)
      if (!scene.instances[i].motion.moves()) for_each_triangle_cell(scene, i, time, g, [&](uint32_t, size_t) { ++dropped; });
  } else if (!choice.candidates.empty()) {
    dropped = choice.candidates[choice.chosen].dropped;
  } else {
    // The percentile policy weighs no candidate: count on the chosen grid
    trial_counts(scene, time, g, o.capacity_time_samples).for_each_largest([&](uint32_t n) {
      if (n > g.capacity) dropped += n - g.capacity;
    });
  }
  return spill_capacity_for(dropped);
}

uint32_t spill_capacity_for(uint64_t dropped) {
  return uint32_t(std::min<uint64_t>(dropped + dropped / 4 + 64, uint64_t(1) << 28));
}

uint32_t spill_growth(const shared::SpillHeader& header, const GridOptions& options, uint32_t flags) {
  if ((flags & shared::kGridSpill) == 0u || options.spill_capacity || header.count <= header.capacity) return 0u;
  const uint32_t grown = spill_capacity_for(header.count);
  return grown > header.capacity ? grown : 0u;
}

uint32_t trace_flags(uint32_t requested, const AlgorithmOptions& o, uint32_t spill_count) {
  // Simulate only what the scene calls for: gap-fill while some cell is saturated
  if (o.gap_fill_if_saturated && spill_count == 0u) return requested & ~shared::kGridGapFill;
  return requested;
}

GridPlan plan_grid(const Scene& scene, float time, const GridOptions& options) {
  GridPlan plan;
  compact_check(options);
  plan.params = choose_grid(scene, time, options, &plan.choice);
  if (options.offsets != GridOptions::Offsets::automatic && (plan.params.flags & shared::kGridCompact) == 0u)
    throw OptionsError("grid: --offsets is the compact layout's (the image layout has no offsets): the compact layout "
                "needs the exact traversal and the spill list, and no --capacity");
  plan.spill_capacity = choose_spill_capacity(scene, time, options, plan.params, plan.choice);
  // The compact layout's budget holds the whole grid: a spill list asked for alone over it is refused
  if ((plan.params.flags & shared::kGridCompact) != 0u && options.spill_capacity) {
    const uint64_t bytes = sizeof(shared::SpillHeader) + uint64_t(std::max(plan.spill_capacity, 1u)) * sizeof(shared::SpillEntry);
    const uint64_t budget = compact_budget(options, scene.triangle_count());
    if (bytes > budget) {
      char text[200];
      std::snprintf(text, sizeof text,
                    "takes %.1f MiB (%llu bytes), over the compact layout's memory budget of %.1f MiB (%llu bytes)",
                    double(bytes) / double(1u << 20), (unsigned long long)bytes, double(budget) / double(1u << 20),
                    (unsigned long long)budget);
      throw Error("grid: --spill-capacity " + std::to_string(plan.spill_capacity) + " " + text +
                  " for the whole grid (--memory-budget)");
    }
  }
  if ((plan.params.flags & shared::kGridCompact) != 0u) {
    std::vector<bool> occupied(size_t(shared::grid_cell_count(plan.params)), false);
    // (counted once: the count walks the instances, and in the loop's test it made 65,535
    // instances take 18 s here, an outside sweep)
    const size_t statics = scene.static_instance_count();
    for (size_t i = 0; i < statics; ++i)
      for_each_triangle_cell(scene, i, time, plan.params, [&](uint32_t, size_t c) {
        ++plan.static_references;
        if (!occupied[c]) occupied[c] = true, ++plan.static_cells;
      });
    plan.region = dynamic_region(scene, time, plan.params);
  }
  plan.tables = pack_tables(scene);
  return plan;
}

}  // namespace gridrt::plan
