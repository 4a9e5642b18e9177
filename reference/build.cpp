// build.cpp: choosing the grid, scene build (paper 2.1) and scene update (paper 2.2).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include "common/shared/transform.h"
#include "reference/grid.h"
#include "reference/invocations.h"
#include "reference/policy.h"

namespace gridrt::reference {

using shared::GridParams;
using shared::kBlank;

unsigned thread_count(const GridOptions& options) {
  if (options.threads) return options.threads;
  return std::max(1u, std::thread::hardware_concurrency());
}

// ---- Grid bounds over the animation ----

Bounds animation_bounds(const Scene& scene, float time) {
  Bounds b;
  for (const Instance& inst : scene.instances) {
    const Mesh& mesh = scene.meshes[inst.mesh];
    if (!inst.dynamic || !inst.motion.moves()) {
      const glm::mat4 m = inst.transform_at(time);
      for (const glm::vec3& p : mesh.positions) b.grow(glm::vec3(m * glm::vec4(p, 1.0f)));
      continue;
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
      r = r * 1.0001f + 1e-6f;
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
  }
  return b;
}

namespace {

// The trial that chooses the capacity: per cell the references a build would insert (no
// capacity). Instances that do not move count at `time` (`fixed`, every cell); moving ones, in the
// box of cells they can reach, at `samples` times spread over the longest period of their motions
// (at most 60 s): their count at `time` (the first sample) and, per cell, the largest.
TrialCounts trial_counts(const Scene& scene, float time, const GridParams& g, uint32_t samples) {
  TrialCounts tc;
  tc.cells = g.cells;
  tc.fixed.assign(size_t(g.cells.x) * g.cells.y * g.cells.z, 0u);
  std::vector<size_t> moving;
  double horizon = 0.0;
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    if (!inst.dynamic || !inst.motion.moves()) {
      for_each_triangle_cell(scene, i, time, g, [&](uint32_t, size_t c) { ++tc.fixed[c]; });
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
GridCandidate weigh(const Scene& scene, float time, GridParams& g, float cs, glm::uvec3 cells,
                    std::optional<uint32_t> cap_over, const GridOptions& o, TrialCounts* counts_out = nullptr) {
  GridCandidate c;
  c.cell_size = cs;
  c.aabb_padding = g.aabb_padding;
  c.cells = cells;
  c.slot_axis = slot_axis_for(cells, o);
  const uint32_t allowed = capacity_allowed(cells, c.slot_axis, o);
  const uint32_t lowest = cap_over ? *cap_over : o.min_capacity;
  c.fits = allowed >= lowest;
  if (!c.fits) return c;
  set_cell_size(g, cs, o);
  g.cells = cells;
  TrialCounts counts = trial_counts(scene, time, g, o.capacity_time_samples);
  counts.for_each_largest([&](uint32_t n) { c.max_count = std::max(c.max_count, n); });
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

GridParams choose_grid(const Scene& scene, float time, const GridOptions& o, GridChoice* choice) {
  GridParams g{};
  // Grid bounds: the animation's bounds, padded by 1e-3 of the largest extent on every side
  Bounds b = animation_bounds(scene, time);
  if (b.empty()) throw Error("grid: the scene has no vertices");
  const glm::vec3 ext = b.extent();
  const float big = std::max({ext.x, ext.y, ext.z, 1e-3f});
  const float pad = 1e-3f * big;
  b.lo -= glm::vec3(pad);
  b.hi += glm::vec3(pad);
  const glm::vec3 e = b.extent();
  g.origin = b.lo;

  // Resolution: density cells per triangle, cubic cells, or the overrides
  const std::optional<glm::uvec3> res = o.resolution ? o.resolution : scene.grid.resolution;
  const std::optional<float> cs_over = o.cell_size ? o.cell_size : scene.grid.cell_size;
  const std::optional<uint32_t> cap_over = o.capacity ? o.capacity : scene.grid.capacity;
  float cs;
  if (cs_over) {
    cs = *cs_over;
  } else if (res) {
    cs = std::max({e.x / float(res->x), e.y / float(res->y), e.z / float(res->z)});
  } else {
    const double target = std::max(1.0, double(o.density) * double(scene.triangle_count()));
    cs = float(std::cbrt(double(e.x) * double(e.y) * double(e.z) / target));
  }
  if (!(cs > 0.0f) || !std::isfinite(cs)) throw Error("grid: cell size must be positive and finite");

  g.aabb_padding = o.aabb_padding.value_or(kAabbPadding);
  g.elongation = o.elongation;
  g.self_hit_offset = o.self_hit_offset;
  g.comparison_offset = scene.static_instance_count() << 16;
  g.insertion = o.insertion == Insertion::sorted ? shared::kInsertSorted : shared::kInsertFirstEmpty;
  g.traversal = o.traversal == Traversal::exact ? shared::kTraversalExact : shared::kTraversalPaper;
  g.triangle_test = o.triangle_test == GridOptions::TriangleTest::watertight ? shared::kTriangleWatertight
                                                                              : shared::kTriangleMoller;
  g.flags = (o.exclude_launch_ref ? shared::kGridExcludeLaunchRef : 0u) |
            (o.alpha_keying ? shared::kGridAlphaKeying : 0u) |
            (spill_enabled(o) ? shared::kGridSpill : (o.gap_fill ? shared::kGridGapFill : 0u)) |
            (skip_enabled(o) ? shared::kGridSkipEmpty : 0u);
  g.repeats = o.repeats == GridOptions::Repeats::skip     ? shared::kRepeatSkip
              : o.repeats == GridOptions::Repeats::retest ? shared::kRepeatRetest
                                                          : shared::kRepeatMerge;
  const auto too_big = [&](glm::uvec3 cells, uint32_t cap) {
    return Error("grid: " + std::to_string(cells.x) + "x" + std::to_string(cells.y) + "x" + std::to_string(cells.z) +
                 " cells of capacity " + std::to_string(cap) + " exceed the image limits (max dimension " +
                 std::to_string(o.max_image_dimension) + ", max texels " + std::to_string(o.max_texels) + ")");
  };
  // The params of `cells` of edge `cell_size`, capacity `cap`, slots along `axis`, AABB padding `padding`
  const auto params_for = [&](glm::uvec3 cells, float cell_size, uint32_t cap, uint32_t axis, float padding) {
    GridParams p = g;
    p.aabb_padding = padding;
    set_cell_size(p, cell_size, o);
    p.cells = cells;
    p.capacity = cap;
    p.flags |= axis << shared::kGridSlotAxisShift;
    p.upper = p.origin + glm::vec3(p.cells) * p.cell_size;
    p.max_segments = p.cells.x + p.cells.y + p.cells.z + 3u;
    return p;
  };
  const auto finish = [&](glm::uvec3 cells, float cell_size, uint32_t cap, uint32_t axis, float padding) {
    g = params_for(cells, cell_size, cap, axis, padding);
    return g;
  };

  if (o.capacity_policy == GridOptions::CapacityPolicy::percentile && !cap_over) {
    // The original rule: a percentile of the trial's non-empty cells, clamped; larger cells until
    // the image fits
    for (int attempt = 0;; ++attempt) {
      set_cell_size(g, cs, o);
      g.cells = (res && !cs_over) ? *res : cells_for(e, cs);
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
      if (cap <= allowed && allowed > 0) return finish(g.cells, cs, cap, axis, g.aabb_padding);
      if ((res && !cs_over) || attempt > 60) throw too_big(g.cells, cap);
      const double along = double(g.cells[axis]) * (cap + 1);
      const double texels = along * double(g.cells.x) * g.cells.y * g.cells.z / g.cells[axis];
      const double ratio = std::max({along / o.max_image_dimension, double(g.cells.x) / o.max_image_dimension,
                                     double(g.cells.y) / o.max_image_dimension,
                                     double(g.cells.z) / o.max_image_dimension,
                                     std::cbrt(texels / double(o.max_texels)), 1.1});
      cs = float(double(cs) * std::min(ratio, 2.0));
    }
  }

  // Fixed cells (a resolution or cell-size override, or a capacity override): one candidate, an
  // error if it does not fit
  GridChoice local;
  GridChoice& ch = choice ? *choice : local;
  ch = GridChoice{};
  if (res && !cs_over) {
    const GridCandidate c = weigh(scene, time, g, cs, *res, cap_over, o);
    if (!c.fits) throw too_big(*res, cap_over.value_or(o.min_capacity));
    ch.candidates.push_back(c);
    return finish(c.cells, cs, c.capacity, c.slot_axis, c.aabb_padding);
  }
  // Candidate cell sizes cs * 2^(j/4) around the density target. With a cell-size override only
  // j = 0; with a capacity override the density target unless it does not fit.
  // no_saturation: weighed in the order j = 0, -1, 1, -2, 2, ... (finer cells first at each
  // distance): the first that drops no reference wins; else the one dropping fewest.
  // trace_cost: every j counted (candidates in parallel), each one's work estimated on the frame's
  // ray sample (reference/policy.h), for the paper traversal without a padding option at two AABB
  // paddings (kAabbPadding and paper_padding); the cheapest wins.
  const bool search = !cs_over && !cap_over;
  const bool by_cost = search && o.capacity_policy == GridOptions::CapacityPolicy::trace_cost;
  const int finest = search ? -8 : 0, coarsest = search ? 12 : 0;
  std::vector<float> paddings{g.aabb_padding};
  if (by_cost && !o.aabb_padding && o.traversal == Traversal::paper && o.paper_padding != g.aabb_padding)
    paddings.push_back(o.paper_padding);
  WorkSample& sample = ch.sample;
  if (by_cost) sample = work_sample(scene, time, params_for(cells_for(e, cs), cs, 0u, 0u, g.aabb_padding), o);
  const auto weigh_j = [&](int j, float padding, GridParams& gj) {
    const float c_cs = float(double(cs) * std::exp2(double(j) / 4.0));
    TrialCounts counts;
    gj.aabb_padding = padding;
    GridCandidate c = weigh(scene, time, gj, c_cs, cells_for(e, c_cs), cap_over, o, by_cost ? &counts : nullptr);
    if (c.fits && by_cost) {
      c.work = estimate_work(params_for(c.cells, c_cs, c.capacity, c.slot_axis, padding), counts, sample);
      c.cost = work_cost(c.work, o);
    }
    return c;
  };
  bool done = false;
  if (by_cost) {
    const size_t per_pad = size_t(coarsest - finest + 1);
    std::vector<GridCandidate> all(per_pad * paddings.size());
    run_invocations(uint32_t(all.size()), thread_count(o), std::nullopt, [&](uint32_t k) {
      GridParams gk = g;
      all[k] = weigh_j(finest + int(k % per_pad), paddings[k / per_pad], gk);
    }, 1);
    for (const GridCandidate& c : all)
      if (c.fits) ch.candidates.push_back(c);
  } else {
    std::vector<int> order{0};
    for (int d = 1; d <= std::max(-finest, coarsest); ++d) {
      if (-d >= finest) order.push_back(-d);
      if (d <= coarsest) order.push_back(d);
    }
    for (int j : order) {
      const GridCandidate c = weigh_j(j, g.aabb_padding, g);
      if (!c.fits) continue;
      ch.candidates.push_back(c);
      if (c.dropped == 0) {
        done = true;
        break;
      }
    }
  }
  // Nothing fits yet (tiny image limits): coarser cells until something does
  for (int j = coarsest + 1; !done && ch.candidates.empty() && j < coarsest + 80; ++j) {
    if (cs_over) break;
    const GridCandidate c = weigh_j(j, paddings[0], g);
    if (c.fits) ch.candidates.push_back(c);
  }
  if (ch.candidates.empty()) throw too_big(cells_for(e, cs), cap_over.value_or(o.min_capacity));
  size_t best = 0;
  for (size_t i = 1; i < ch.candidates.size(); ++i)
    if (by_cost ? ch.candidates[i].cost < ch.candidates[best].cost
                : ch.candidates[i].dropped < ch.candidates[best].dropped)
      best = i;
  ch.chosen = best;
  const GridCandidate& c = ch.candidates[best];
  return finish(c.cells, c.cell_size, c.capacity, c.slot_axis, c.aabb_padding);
}

// ---- The spill list's capacity, and which effects the trace runs ----

bool spill_enabled(const GridOptions& o) {
  switch (o.spill) {
    case GridOptions::Spill::on: return true;
    case GridOptions::Spill::off: return false;
    case GridOptions::Spill::automatic: break;
  }
  return o.traversal == Traversal::exact;
}

bool skip_enabled(const GridOptions& o) { return o.skip_empty && o.traversal == Traversal::exact; }

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

namespace {
// The summed-volume table's passes (skip_field.comp): pass 0 writes each x line's running count of
// occupied cells (slot 0 not blank), passes 1 and 2 add along y and z; one invocation per line.
void skip_table_pass(const GridData& grid, std::vector<uint32_t>& table, uint32_t pass, const GridOptions& o) {
  const GridParams& g = grid.params;
  const glm::uvec3 n = g.cells;
  const glm::uvec3 lines = pass == 0 ? glm::uvec3(n.y, n.z, n.x) : pass == 1 ? glm::uvec3(n.x, n.z, n.y)
                                                                          : glm::uvec3(n.x, n.y, n.z);
  run_invocations(lines.x * lines.y, thread_count(o), std::nullopt, [&](uint32_t line) {
    const uint32_t a = line % lines.x, b = line / lines.x;
    uint32_t sum = 0u;
    for (uint32_t k = 0; k < lines.z; ++k) {
      const glm::uvec3 c = pass == 0 ? glm::uvec3(k, a, b) : pass == 1 ? glm::uvec3(a, k, b) : glm::uvec3(a, b, k);
      const uint32_t i = shared::skip_table_index(g, c + 1u);
      if (pass == 0) {
        const bool occupied = imageLoad(grid.image, glm::ivec3(shared::cell_slot_texel(g, c, 0u))) != kBlank;
        sum += occupied ? 1u : 0u;
        table[i] = sum;
      } else {
        sum += table[i];
        table[i] = sum;
      }
    }
  }, 64);
}

// Occupied cells in the cube of radius r around c, from the table.
uint32_t skip_cube_count(const GridParams& g, const std::vector<uint32_t>& table, glm::uvec3 c, uint32_t r) {
  uint32_t count = 0u;
  for (uint32_t j = 0; j < 8u; ++j) {
    const uint32_t v = table[shared::skip_table_index(g, shared::skip_cube_corner(g, c, r, j))];
    count = shared::skip_corner_positive(j) ? count + v : count - v;
  }
  return count;
}
}  // namespace

void skip_field_build(GridData& grid, const GridOptions& o) {
  const GridParams& g = grid.params;
  std::vector<uint32_t> table(shared::skip_table_words(g), 0u);
  for (uint32_t pass = 0; pass < 3; ++pass) skip_table_pass(grid, table, pass, o);
  // The distances, one invocation per word (4 cells): the smallest r whose cube holds an occupied
  // cell, by binary search over [0, kSkipMaxDistance]
  const uint32_t cells = shared::grid_cell_count(g);
  run_invocations((cells + 3u) / 4u, thread_count(o), std::nullopt, [&](uint32_t word) {
    uint32_t packed = 0u;
    for (uint32_t q = 0; q < 4u && 4u * word + q < cells; ++q) {
      const uint32_t i = 4u * word + q;
      const glm::uvec3 c = shared::cell_of_linear_index(g, i);
      uint32_t lo = 0u, hi = shared::kSkipMaxDistance;
      while (lo < hi) {
        const uint32_t mid = (lo + hi) / 2u;
        if (skip_cube_count(g, table, c, mid) > 0u) hi = mid;
        else lo = mid + 1u;
      }
      packed |= lo << shared::skip_distance_shift(i);
    }
    grid.skip[shared::kSkipHeaderWords + word] = packed;
  }, 256);
}

uint32_t choose_spill_capacity(const Scene& scene, float time, const GridOptions& o, const GridParams& g,
                               const GridChoice& choice) {
  if ((g.flags & shared::kGridSpill) == 0u) return 0;
  if (o.spill_capacity) return *o.spill_capacity;
  uint64_t dropped = 0;
  if (!choice.candidates.empty()) {
    dropped = choice.candidates[choice.chosen].dropped;
  } else {
    // The percentile policy weighs no candidate: count on the chosen grid
    trial_counts(scene, time, g, o.capacity_time_samples).for_each_largest([&](uint32_t n) {
      if (n > g.capacity) dropped += n - g.capacity;
    });
  }
  const uint64_t cap = dropped + dropped / 4 + 64;
  return uint32_t(std::min<uint64_t>(cap, uint64_t(1) << 28));
}

uint32_t trace_flags(uint32_t requested, const GridOptions& o, uint32_t spill_count) {
  // Simulate only what the scene calls for: gap-fill while some cell is saturated
  if (o.gap_fill_if_saturated && spill_count == 0u) return requested & ~shared::kGridGapFill;
  return requested;
}

// ---- Insertion (paper 2.1) ----

namespace {
// GLSL's atomics on a storage buffer's uint (the spill list's counter and arrival heads), relaxed
// as on the GPU; the passes that read what they wrote come after a join (a barrier).
uint32_t atomicAdd(uint32_t& mem, uint32_t data) {
  return std::atomic_ref<uint32_t>(mem).fetch_add(data, std::memory_order_relaxed);
}
uint32_t atomicExchange(uint32_t& mem, uint32_t data) {
  return std::atomic_ref<uint32_t>(mem).exchange(data, std::memory_order_relaxed);
}
}  // namespace

// A reference no slot of `cell` took: counted, and with kGridSpill stored as (cell, ref) in the
// entry the counter gave it and pushed onto the arrival list of the cell's static or dynamic
// references (one exchange of the head: no loop, no order), while the list has room (past its
// capacity it is lost: the count says how many). The order pass links it in ascending order.
void spill_reference(GridData& grid, glm::uvec3 cell, uint32_t ref) {
  const GridParams& g = grid.params;
  const uint32_t i = atomicAdd(grid.spill_header.count, 1u);
  if ((g.flags & shared::kGridSpill) == 0u || i >= grid.spill_header.capacity) return;
  const uint32_t c = shared::cell_linear_index(g, cell);
  grid.spill[i].cell = c;
  grid.spill[i].ref = ref;
  grid.spill[i].arrival = atomicExchange(grid.spill_heads[shared::spill_arrival_index(c, ref >= g.comparison_offset)], i);
}

// The order pass, one invocation per entry of [first, stored): walk the entry's arrival list for
// the smallest larger reference (its successor in ascending order) and link to it; the entry
// with no smaller reference becomes the list's head. References in a list are distinct (a
// triangle visits a cell once), so every entry finds its own place whatever the arrival order:
// the lists the trace walks are the same on every backend. After the build's static pass with
// first = 0, after every dynamic pass with first = static_count.
void spill_order(GridData& grid, const GridOptions& o, uint32_t first) {
  const GridParams& g = grid.params;
  const uint32_t stored = std::min(grid.spill_header.count, grid.spill_header.capacity);
  if ((g.flags & shared::kGridSpill) == 0u || first >= stored) return;
  run_invocations(stored - first, thread_count(o), std::nullopt, [&](uint32_t invocation) {
    const uint32_t i = first + invocation;
    const shared::SpillEntry e = grid.spill[i];
    const bool dynamic = e.ref >= g.comparison_offset;
    uint32_t next = shared::kSpillEnd, next_ref = kBlank;
    bool smallest = true;
    for (uint32_t j = grid.spill_heads[shared::spill_arrival_index(e.cell, dynamic)]; j != shared::kSpillEnd;
         j = grid.spill[j].arrival) {
      const uint32_t r = grid.spill[j].ref;
      if (r < e.ref) smallest = false;
      if (r > e.ref && r < next_ref) next = j, next_ref = r;
    }
    grid.spill[i].next = next;
    if (smallest) grid.spill_heads[shared::spill_head_index(e.cell, dynamic)] = i;
  }, 64);
}

// The first slot of `cell` holding a value >= `bound`, where the slots holding smaller values are
// a prefix that stays one through the pass (docs/SPEC.md, "Insert"): during a pass a slot's value
// only decreases (atomic min) or leaves blank once (compare-and-swap), the cells stay sorted
// (sorted insertion) or filled from slot 0 without gaps (first-empty), and static references
// precede dynamic ones; so a slot seen below `bound` stays below it, with every slot before it,
// whatever other invocations do meanwhile. Plain loads, galloping (slots 0, 2, 6, 14, ...) then
// halving: about 2 log2(n) loads for n references, where a walk from slot 0 costs n.
uint32_t first_slot_at_least(const Image3D& image, const GridParams& g, glm::uvec3 cell, uint32_t bound) {
  const auto below = [&](uint32_t s) {
    return imageLoad(image, glm::ivec3(shared::cell_slot_texel(g, cell, s))) < bound;
  };
  // Gallop until a slot that is not below the bound
  uint32_t lo = 0, hi = g.capacity;
  for (uint32_t span = 1; lo < hi; span *= 2) {
    const uint32_t probe = std::min(lo + span - 1, hi - 1);
    if (!below(probe)) {
      hi = probe;
      break;
    }
    lo = probe + 1;
  }
  // Halve [lo, hi): the slots before lo are below the bound, slot hi (if any) is not
  while (lo < hi) {
    const uint32_t mid = (lo + hi) / 2;
    if (below(mid)) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}

// Paper: compare-and-swap blank -> ref into the first slot that takes it; when none does, flag
// the cell saturated (static or dynamic bit by the reference's kind) and spill the reference.
void insert_first_empty(GridData& grid, glm::uvec3 cell, uint32_t ref) {
  const GridParams& g = grid.params;
  // The filled slots would refuse the reference: start at the first blank
  for (uint32_t s = first_slot_at_least(grid.image, g, cell, kBlank); s < g.capacity; ++s) {
    const uint32_t old = imageAtomicCompSwap(grid.image, glm::ivec3(shared::cell_slot_texel(g, cell, s)), kBlank, ref);
    if (old == kBlank) return;
  }
  // Saturated: no slot took the reference
  const uint32_t bit = ref < g.comparison_offset ? shared::kStatusStatic : shared::kStatusDynamic;
  imageAtomicOr(grid.image, glm::ivec3(shared::cell_status_texel(g, cell)), bit);
  spill_reference(grid, cell, ref);
}

// Ours: an atomic-min cascade. The carried value v takes the smaller of itself and each slot in
// turn (old = atomicMin(slot, v); v = max(old, v)) until it is blank; the cell ends holding its
// `capacity` smallest references in ascending order whatever the timing. A value pushed out of
// the last slot is dropped: it flags the cell (static bit if it is static, else dynamic) and is
// spilled.
void insert_sorted(GridData& grid, glm::uvec3 cell, uint32_t ref) {
  const GridParams& g = grid.params;
  uint32_t v = ref;
  // The slots holding smaller references would pass v on unchanged: start after them
  for (uint32_t s = first_slot_at_least(grid.image, g, cell, ref); s < g.capacity; ++s) {
    const uint32_t old = imageAtomicMin(grid.image, glm::ivec3(shared::cell_slot_texel(g, cell, s)), v);
    v = std::max(old, v);
    if (v == kBlank) return;
  }
  // Saturated: the dropped value names the bit
  const uint32_t bit = v < g.comparison_offset ? shared::kStatusStatic : shared::kStatusDynamic;
  imageAtomicOr(grid.image, glm::ivec3(shared::cell_status_texel(g, cell)), bit);
  spill_reference(grid, cell, v);
}

SpillDump spill_dump(const GridData& grid) {
  SpillDump d;
  d.on = (grid.params.flags & shared::kGridSpill) != 0u;
  d.header = grid.spill_header;
  d.entries.assign(grid.spill.begin(), grid.spill.begin() + ptrdiff_t(d.stored()));
  d.heads = grid.spill_heads;
  return d;
}

// The dirty-cell list (scene update): the first dynamic reference to reach a cell in a pass sets
// the cell's listed bit and appends the cell, so the list holds every cell a dynamic reference
// reached (stored or dropped), once.
void append_dirty_cell(WordBuffer& dirty, const GridParams& g, glm::uvec3 cell) {
  const uint32_t i = shared::cell_linear_index(g, cell);
  const uint32_t old = atomicOr(dirty, shared::kWorkListHeaderWords + shared::dirty_bit_item(g, i), shared::dirty_bit(i));
  if ((old & shared::dirty_bit(i)) != 0u) return;
  const uint32_t k = atomicAdd(dirty, shared::kWorkListAppendedWord, 1u);
  dirty.store(shared::kWorkListHeaderWords + k, i);
}

namespace {

// One emulated geometry-shader invocation: transform the triangle, write it to the geometry
// buffer, insert its reference into every cell of its AABB range whose enlarged bounding sphere
// the triangle's plane passes through.
void build_invocation(GridData& grid, const Scene& scene, float time, uint32_t instance,
                      uint32_t triangle, const shared::Affine& m) {
  const GridParams& g = grid.params;
  const Instance& inst = scene.instances[instance];
  const Mesh& mesh = scene.meshes[inst.mesh];
  (void)time;
  // Transform the vertices and write the world-space triangle
  const glm::uvec3 idx = mesh.triangles[triangle];
  const glm::vec3 v0 = shared::transform_point(m, mesh.positions[idx.x]);
  const glm::vec3 v1 = shared::transform_point(m, mesh.positions[idx.y]);
  const glm::vec3 v2 = shared::transform_point(m, mesh.positions[idx.z]);
  shared::GridTriangle& out = grid.triangles[grid.instances[instance].tri_offset + triangle];
  out.v0 = v0;
  out.v1 = v1;
  out.v2 = v2;
  // Skip zero-area triangles: no ray can hit them
  const glm::vec3 n = shared::triangle_normal(v0, v1, v2);
  const float nn = shared::sh_dot(n, n);
  if (nn == 0.0f) return;
  // Cells of the AABB range whose enlarged bounding sphere meets the plane
  glm::uvec3 lo, hi;
  shared::triangle_cell_range(g, v0, v1, v2, lo, hi);
  const uint32_t ref = shared::ref_pack(instance, triangle);
  for (uint32_t z = lo.z; z <= hi.z; ++z)
    for (uint32_t y = lo.y; y <= hi.y; ++y)
      for (uint32_t x = lo.x; x <= hi.x; ++x) {
        const glm::uvec3 cell(x, y, z);
        if (!shared::plane_intersects_enlarged_sphere(v0, n, nn, shared::cell_center(g, cell), g.sphere_r2))
          continue;
        if (ref >= g.comparison_offset) append_dirty_cell(grid.dirty, g, cell);
        if (g.insertion == shared::kInsertSorted) insert_sorted(grid, cell, ref);
        else insert_first_empty(grid, cell, ref);
      }
}

// Invocations over the triangles of instances [first, last): one per triangle.
void insert_instances(GridData& grid, const Scene& scene, float time, const GridOptions& o,
                      uint32_t first, uint32_t last) {
  if (first >= last) return;
  std::vector<shared::Affine> affine(last - first);
  for (uint32_t i = first; i < last; ++i) affine[i - first] = shared::to_affine(scene.instances[i].transform_at(time));
  const uint32_t t0 = grid.instances[first].tri_offset;
  const uint32_t t1 = grid.instances[last - 1].tri_offset + grid.instances[last - 1].tri_count;
  run_invocations(
      t1 - t0, thread_count(o), o.shuffle_seed,
      [&](uint32_t invocation) {
        const uint32_t global = t0 + invocation;
        // The instance holding this triangle: the last whose offset is <= global
        auto it = std::upper_bound(grid.instances.begin() + first, grid.instances.begin() + last, global,
                                   [](uint32_t v, const shared::GridInstance& gi) { return v < gi.tri_offset; });
        const uint32_t instance = uint32_t(it - grid.instances.begin()) - 1;
        build_invocation(grid, scene, time, instance, global - grid.instances[instance].tri_offset,
                         affine[instance - first]);
      },
      16);
}

}  // namespace

// ---- Scene build (paper 2.1) ----

void scene_build(GridData& grid, const Scene& scene, float time, const GridOptions& o) {
  grid = GridData{};
  GridChoice choice;
  grid.params = choose_grid(scene, time, o, &choice);
  grid.requested_flags = grid.params.flags;
  const GridParams& g = grid.params;
  // The spill list: empty, room for the references the trial would drop
  grid.spill_header = shared::SpillHeader{0u, choose_spill_capacity(scene, time, o, g, choice), 0u, 0u};
  grid.spill.assign(grid.spill_header.capacity, shared::SpillEntry{0u, kBlank, shared::kSpillEnd, shared::kSpillEnd});
  if (g.flags & shared::kGridSpill) grid.spill_heads.assign(4 * size_t(g.cells.x) * g.cells.y * g.cells.z, shared::kSpillEnd);
  // Tables: instances, materials and their alpha masks, the geometry buffer
  grid.static_instances = scene.static_instance_count();
  uint32_t offset = 0;
  for (uint32_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    const Mesh& mesh = scene.meshes[inst.mesh];
    shared::GridInstance gi{offset, mesh.triangle_count(), inst.dynamic ? shared::kInstanceDynamic : 0u, 0u};
    for (uint32_t m : mesh.materials)
      if (scene.materials[m].alpha_keyed()) gi.flags |= shared::kInstanceAlphaKeyed;
    grid.instances.push_back(gi);
    if (i < grid.static_instances) grid.static_triangles = offset + mesh.triangle_count();
    offset += mesh.triangle_count();
  }
  grid.triangles.assign(offset, shared::GridTriangle{});
  grid.uvs.assign(offset, shared::GridTriangleUv{});
  for (uint32_t i = 0; i < scene.instances.size(); ++i) {
    const Mesh& mesh = scene.meshes[scene.instances[i].mesh];
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      const uint32_t k = grid.instances[i].tri_offset + t;
      grid.triangles[k].material = mesh.materials.empty() ? 0u : mesh.materials[t];
      if (!mesh.uvs.empty()) {
        const glm::uvec3 idx = mesh.triangles[t];
        grid.uvs[k] = {mesh.uvs[idx.x], mesh.uvs[idx.y], mesh.uvs[idx.z]};
      }
    }
  }
  for (const Material& mat : scene.materials) {
    shared::GridMaterial gm{};
    if (mat.alpha_keyed()) {
      const Texture& tex = scene.textures[size_t(mat.alpha_texture)];
      gm.alpha_offset = uint32_t(grid.texels.size());
      gm.alpha_width = tex.width;
      gm.alpha_height = tex.height;
      for (size_t p = 0; p < size_t(tex.width) * tex.height; ++p)
        grid.texels.push_back(uint32_t(tex.rgba[4 * p]) | uint32_t(tex.rgba[4 * p + 1]) << 8 |
                              uint32_t(tex.rgba[4 * p + 2]) << 16 | uint32_t(tex.rgba[4 * p + 3]) << 24);
    }
    grid.materials.push_back(gm);
  }
  // The image, every texel blank; status texels 0; the dirty-cell list empty
  grid.image = Image3D(shared::grid_image_extent(g), kBlank);
  grid.dirty = WordBuffer(shared::dirty_list_words(g), 0u);
  run_invocations(g.cells.x * g.cells.y * g.cells.z, thread_count(o), std::nullopt, [&](uint32_t c) {
    const glm::uvec3 cell(c % g.cells.x, (c / g.cells.x) % g.cells.y, c / (g.cells.x * g.cells.y));
    imageStore(grid.image, glm::ivec3(shared::cell_status_texel(g, cell)), 0u);
  }, 4096);
  // Static instances first (their references fill the first slots and are spilled first), then
  // the dynamic ones
  insert_instances(grid, scene, time, o, 0, grid.static_instances);
  grid.spill_header.static_count = grid.spill_header.count;
  spill_order(grid, o, 0);
  // The skip field from the static references; the dynamic boxes at `time`
  if ((g.flags & shared::kGridSkipEmpty) != 0u) {
    grid.skip.assign(shared::skip_words(g), 0u);
    skip_field_build(grid, o);
    const std::vector<uint32_t> boxes = skip_box_words(scene, time, g);
    std::copy(boxes.begin(), boxes.end(), grid.skip.begin());
  }
  insert_instances(grid, scene, time, o, grid.static_instances, uint32_t(scene.instances.size()));
  spill_order(grid, o, grid.spill_header.static_count);
  // Gap-fill only if some cell saturated
  grid.params.flags = trace_flags(grid.requested_flags, o, grid.spill_header.count);
}

// ---- Scene update (paper 2.2) ----

// The clear pass over the dirty-cell list, one workgroup of 64 invocations per listed cell: the
// dispatch step takes the cells appended since the last pass (and starts the list again); per
// listed cell, blank every reference >= the comparison offset from the first such slot up to the
// first blank, the invocations taking every 64th slot; reset the dynamic saturation bit, empty the
// cell's dynamic spill list and take the cell off the list. Before it, the spill counter goes back
// to the static references' count (Vulkan: a copy of static_count onto count): the dynamic entries
// were appended after them.
void clear_dynamic_references(GridData& grid, const GridOptions& o) {
  const GridParams& g = grid.params;
  // Drop the dynamic references' spill entries
  grid.spill_header.count = grid.spill_header.static_count;
  // The dispatch step (work_list_dispatch.comp)
  const uint32_t size = grid.dirty.load(shared::kWorkListAppendedWord);
  grid.dirty.store(shared::kWorkListSizeWord, size);
  grid.dirty.store(shared::kWorkListAppendedWord, 0u);
  run_invocations(size, thread_count(o), std::nullopt, [&](uint32_t k) {
    const uint32_t i = grid.dirty.load(shared::kWorkListHeaderWords + k);
    const glm::uvec3 cell = shared::cell_of_linear_index(g, i);
    // The first dynamic slot (the static references precede the dynamic ones)
    const uint32_t first_dynamic = first_slot_at_least(grid.image, g, cell, g.comparison_offset);
    // Blank the dynamic references up to the first blank, every 64th slot per invocation (a slot
    // found blank ends the invocation's walk: the blanks form the cell's tail)
    for (uint32_t lane = 0; lane < 64; ++lane)
      for (uint32_t s = first_dynamic + lane; s < g.capacity; s += 64)
        if (imageAtomicExchange(grid.image, glm::ivec3(shared::cell_slot_texel(g, cell, s)), kBlank) == kBlank) break;
    // Reset the dynamic saturation bit; the static one persists
    imageAtomicAnd(grid.image, glm::ivec3(shared::cell_status_texel(g, cell)), ~shared::kStatusDynamic);
    // Empty the dynamic spill list; the static one persists (every cell a dynamic reference was
    // spilled in is listed: the reference reached it)
    if ((g.flags & shared::kGridSpill) != 0u) {
      grid.spill_heads[shared::spill_head_index(i, true)] = shared::kSpillEnd;
      grid.spill_heads[shared::spill_arrival_index(i, true)] = shared::kSpillEnd;
    }
    // Off the list
    atomicAnd(grid.dirty, shared::kWorkListHeaderWords + shared::dirty_bit_item(g, i), ~shared::dirty_bit(i));
  }, 1);
}

std::vector<uint32_t> dirty_cells(const GridData& grid) {
  if (grid.dirty.size == 0) return {};
  const uint32_t n = grid.dirty.load(shared::kWorkListAppendedWord);
  std::vector<uint32_t> out(n);
  for (uint32_t k = 0; k < n; ++k) out[k] = grid.dirty.load(shared::kWorkListHeaderWords + k);
  return out;
}

void scene_update(GridData& grid, const Scene& scene, float time, const GridOptions& o) {
  if (grid.static_instances == scene.instances.size()) return;
  clear_dynamic_references(grid, o);
  if ((grid.params.flags & shared::kGridSkipEmpty) != 0u) {
    const std::vector<uint32_t> boxes = skip_box_words(scene, time, grid.params);
    std::copy(boxes.begin(), boxes.end(), grid.skip.begin());
  }
  insert_instances(grid, scene, time, o, grid.static_instances, uint32_t(scene.instances.size()));
  spill_order(grid, o, grid.spill_header.static_count);
  // Gap-fill only while some cell is saturated
  grid.params.flags = trace_flags(grid.requested_flags, o, grid.spill_header.count);
}

}  // namespace gridrt::reference
