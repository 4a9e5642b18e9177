// merge_estimate: would merging cells pay? An estimate, on the trace-cost policy's own ray sample,
// of the cells a ray visits and the references it tests in an irregular grid (Perard-Gayot,
// Kalojanov, Slusallek, "GPU Ray Tracing using Irregular Grids"), beside the uniform grid the
// policy chose for the exact traversal. Nothing here is built for the GPU and no triangle is
// tested: like the policy's estimate_work (plan/policy.h), a walk counts its visits up to the
// point where the ray's true hit (found by the sample's own exact trace) would be reported.
//   gridrt_merge_estimate [--factors 1,2] [--visit-cost C] [--expand subset|empty|off]
//                         [--merge on|off|subdivide] [--threshold T] [--threads N] SCENE...
// Per scene and factor f, the virtual grid is the chosen grid's box in f times its cells per
// axis; each cell holds the triangles the build's cell test gives it. Then:
//   merge   along x, y, z in turn, a cell and its neighbour across its upper face (the same
//           extent on the other two axes) become one cell where the SAH-like cost falls:
//           area(m) (C + N(m)) <= area(a) (C + N(a)) + area(b) (C + N(b)), C the visit cost in
//           tests (the policy's 1.6 for the exact traversal), N a cell's references; until no
//           pair merges
//   (--merge subdivide instead: a two-level grid, each chosen-grid cell one cell unless the union
//   of its f^3 virtual cells' references holds more than T; then those f^3 cells stay)
//   expand  each cell's exit box grows over a neighbouring slab of virtual cells while every cell
//           of the slab holds only references the cell holds (an empty one: none), one face at a
//           time (+x, -x, +y, -y, +z, -z) until no face grows: a ray leaving the box has tested
//           every reference it passed
//   walk    from the ray's grid entry, the cell holding the point, its references counted, the
//           exit of its expanded box; the walk stops where the hit lies at or before that exit,
//           or the ray leaves the grid
// Printed per scene: the policy's estimate on its chosen grid (the uniform grid's walk with the
// skip field, equal to the reference trace's counters), this program's walk of the same grid
// unmerged (a cross-check: the plain DDA's cells), and per factor the irregular grid's cells
// (count, and their references per triangle) and per ray cells and tests, with
// tests + C cells, the policy's cost, beside the chosen grid's; and the bytes a GPU layout would
// keep, with a dense map of the virtual cells or a two-level one (per chosen-grid cell one entry,
// or f^3 where its virtual cells belong to more than one merged cell).
#include <algorithm>
#include <chrono>
#include <array>
#include <cmath>
#include <map>
#include <cstdio>
#include <numeric>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "gridrt/common/scene_io.h"
#include "gridrt/common/util.h"
#include "gridrt/plan/plan.h"
#include "gridrt/plan/policy.h"
#include "gridrt/reference/grid.h"

using namespace gridrt;
using glm::uvec3;
using glm::vec3;

namespace {

struct Cell {
  uvec3 lo{0}, hi{0};   // virtual cells, inclusive
  uvec3 elo{0}, ehi{0};  // the expanded exit box
  uint32_t first = 0, count = 0;  // references pool[first .. first + count), ascending
};

class IrregularGrid {
 public:
  IrregularGrid(const shared::GridParams& g, std::vector<uint32_t> first, std::vector<uint32_t> refs, float visit_cost)
      : g_(g), c_(visit_cost) {
    const size_t n = size_t(g.cells.x) * g.cells.y * g.cells.z;
    map_.resize(n);
    cells_.reserve(n);
    pool_ = std::move(refs);
    for (size_t i = 0; i < n; ++i) {
      const uvec3 v = coords(i);
      cells_.push_back(Cell{v, v, v, v, first[i], first[i + 1] - first[i]});
      map_[i] = uint32_t(i);
    }
  }

  uvec3 coords(size_t i) const {
    return uvec3(uint32_t(i % g_.cells.x), uint32_t((i / g_.cells.x) % g_.cells.y), uint32_t(i / (size_t(g_.cells.x) * g_.cells.y)));
  }
  size_t index(uvec3 v) const { return (size_t(v.z) * g_.cells.y + v.y) * g_.cells.x + v.x; }

  // Surface area in cell units
  static double area(uvec3 lo, uvec3 hi) {
    const glm::dvec3 e = glm::dvec3(hi - lo) + 1.0;
    return 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
  }
  double cost(const Cell& c, uint32_t n) const { return area(c.lo, c.hi) * (c_ + double(n)); }

  void merge() {
    std::vector<uint32_t> u;
    std::vector<uint32_t> live(cells_.size());
    std::iota(live.begin(), live.end(), 0u);
    std::vector<uint8_t> used(cells_.size(), 0);
    for (bool merged = true; merged;) {
      merged = false;
      for (int axis = 0; axis < 3; ++axis) {
        for (uint32_t a : live) used[a] = 0;
        for (uint32_t a : live) {
          Cell& ca = cells_[a];
          if (ca.count == ~0u || used[a] || ca.hi[axis] + 1 >= g_.cells[axis]) continue;
          uvec3 nv = ca.lo;
          nv[axis] = ca.hi[axis] + 1;
          const uint32_t b = map_[index(nv)];
          Cell& cb = cells_[b];
          if (used[b]) continue;
          bool same = true;
          for (int k = 0; k < 3; ++k)
            if (k != axis && (cb.lo[k] != ca.lo[k] || cb.hi[k] != ca.hi[k])) same = false;
          if (!same || cb.lo[axis] != nv[axis]) continue;
          u.clear();
          std::set_union(pool_.begin() + ca.first, pool_.begin() + ca.first + ca.count, pool_.begin() + cb.first,
                         pool_.begin() + cb.first + cb.count, std::back_inserter(u));
          Cell m = ca;
          m.hi[axis] = cb.hi[axis];
          if (cost(m, uint32_t(u.size())) > cost(ca, ca.count) + cost(cb, cb.count)) continue;
          // a takes b's cells; the union appended to the pool where it grew
          if (u.size() != ca.count) {
            m.first = uint32_t(pool_.size());
            pool_.insert(pool_.end(), u.begin(), u.end());
          }
          m.count = uint32_t(u.size());
          for (uint32_t z = cb.lo.z; z <= cb.hi.z; ++z)
            for (uint32_t y = cb.lo.y; y <= cb.hi.y; ++y)
              for (uint32_t x = cb.lo.x; x <= cb.hi.x; ++x) map_[index({x, y, z})] = a;
          m.elo = m.lo;
          m.ehi = m.hi;
          ca = m;
          cb.count = ~0u;  // gone
          used[a] = used[b] = 1;
          merged = true;
        }
        std::erase_if(live, [&](uint32_t a) { return cells_[a].count == ~0u; });
      }
    }
    drop_gone();
  }

  // The live cells (count not ~0u), renumbered in the map
  void drop_gone() {
    std::vector<uint32_t> renum(cells_.size(), ~0u);
    std::vector<Cell> kept;
    for (uint32_t i = 0; i < cells_.size(); ++i)
      if (cells_[i].count != ~0u) {
        renum[i] = uint32_t(kept.size());
        kept.push_back(cells_[i]);
      }
    for (uint32_t& m : map_) m = renum[m];
    cells_ = std::move(kept);
  }

  // Two levels (Kalojanov et al.'s, "Two-Level Grids for Ray Tracing on GPUs", with the resolution
  // per top cell 1 or f): each block of f^3 virtual cells (a chosen-grid cell) becomes one cell
  // holding the union of their references, unless that union holds more than `threshold`
  // references: then its f^3 cells stay.
  void subdivide(uint32_t f, uint32_t threshold) {
    const uvec3 top = g_.cells / f;
    std::vector<uint32_t> u, w;
    for (uint32_t z = 0; z < top.z; ++z)
      for (uint32_t y = 0; y < top.y; ++y)
        for (uint32_t x = 0; x < top.x; ++x) {
          const uvec3 lo = uvec3(x, y, z) * f;
          u.clear();
          for (uint32_t k = 0; k < f * f * f; ++k) {
            const Cell& c = cells_[map_[index(lo + uvec3(k % f, (k / f) % f, k / (f * f)))]];
            w.clear();
            std::set_union(u.begin(), u.end(), pool_.begin() + c.first, pool_.begin() + c.first + c.count,
                           std::back_inserter(w));
            u.swap(w);
          }
          if (u.size() > threshold) continue;
          const uint32_t a = map_[index(lo)];
          Cell& ca = cells_[a];
          ca.lo = ca.elo = lo;
          ca.hi = ca.ehi = lo + uvec3(f - 1);
          ca.first = uint32_t(pool_.size());
          ca.count = uint32_t(u.size());
          pool_.insert(pool_.end(), u.begin(), u.end());
          for (uint32_t k = 0; k < f * f * f; ++k) {
            const size_t i = index(lo + uvec3(k % f, (k / f) % f, k / (f * f)));
            if (map_[i] != a) cells_[map_[i]].count = ~0u;
            map_[i] = a;
          }
        }
    drop_gone();
  }

  // A cell's references hold those of every cell of the slab beyond face (axis, side)
  // `chain`: a slab cell counts as held only where its references lie in its neighbour's towards
  // the box (a cover bit's relation; the box's cells lie in the cell's by induction).
  bool slab_covered(const Cell& c, int axis, bool upper, bool empty_only, bool chain, uint32_t max_extent) const {
    uvec3 lo = c.elo, hi = c.ehi;
    if (upper) {
      if (c.ehi[axis] + 1 >= g_.cells[axis] || c.ehi[axis] - c.hi[axis] >= max_extent) return false;
      lo[axis] = hi[axis] = c.ehi[axis] + 1;
    } else {
      if (c.elo[axis] == 0 || c.lo[axis] - c.elo[axis] >= max_extent) return false;
      lo[axis] = hi[axis] = c.elo[axis] - 1;
    }
    const auto begin = pool_.begin() + c.first, end = begin + c.count;
    uint32_t last = ~0u;
    for (uint32_t z = lo.z; z <= hi.z; ++z)
      for (uint32_t y = lo.y; y <= hi.y; ++y)
        for (uint32_t x = lo.x; x <= hi.x; ++x) {
          const uint32_t o = map_[index({x, y, z})];
          if (o == last) continue;
          last = o;
          const Cell& n = cells_[o];
          if (n.count > c.count || (empty_only && n.count > 0)) return false;
          if (chain && n.count > 0) {
            uvec3 in{x, y, z};
            in[axis] = upper ? in[axis] - 1 : in[axis] + 1;
            const Cell& m = cells_[map_[index(in)]];
            if (!std::includes(pool_.begin() + m.first, pool_.begin() + m.first + m.count, pool_.begin() + n.first,
                               pool_.begin() + n.first + n.count))
              return false;
            continue;
          }
          if (!std::includes(begin, end, pool_.begin() + n.first, pool_.begin() + n.first + n.count)) return false;
        }
    return true;
  }

  // `empty_only`: grow only over empty cells (the skip field's kind of step), not over cells whose
  // references the cell holds.
  void expand(bool empty_only, bool chain, uint32_t max_extent) {
    for (Cell& c : cells_)
      for (bool grew = true; grew;) {
        grew = false;
        for (int axis = 0; axis < 3; ++axis) {
          if (slab_covered(c, axis, true, empty_only, chain, max_extent)) c.ehi[axis] += 1, grew = true;
          if (slab_covered(c, axis, false, empty_only, chain, max_extent)) c.elo[axis] -= 1, grew = true;
        }
      }
  }

  // Cells visited and references tested by a ray up to where its hit at t_hit is reported;
  // `launch`: the launch triangle's id (its test is skipped uncounted), else ~0u.
  // `hit`: the hit triangle's id (~0u: a miss); `offered` set where a visited cell holds it.
  void walk(const Ray& ray, float t_hit, uint32_t launch, uint32_t hit, uint64_t& cells, uint64_t& tests,
            bool& offered) const {
    shared::RaySetup rs;
    const vec3 dir = shared::traced_direction(ray.dir);
    if (!shared::ray_valid(ray.org, dir, ray.tmin, ray.tmax) || !shared::ray_setup(g_, ray.org, dir, ray.tmin, ray.tmax, rs))
      return;
    const glm::dvec3 org(ray.org), d(dir), origin(g_.origin);
    const double cs = double(g_.cell_size);
    double t = rs.t_start;
    // The first cell: the one holding the entry point
    uvec3 v;
    for (int k = 0; k < 3; ++k) {
      const double x = std::floor((org[k] + d[k] * t - origin[k]) / cs);
      v[k] = uint32_t(std::clamp(x, 0.0, double(g_.cells[k] - 1)));
    }
    for (int steps = 0; steps < 1 << 20; ++steps) {
      const Cell& c = cells_[map_[index(v)]];
      cells += 1;
      tests += c.count;
      if (launch != ~0u && std::binary_search(pool_.begin() + c.first, pool_.begin() + c.first + c.count, launch))
        tests -= 1;
      if (hit != ~0u && std::binary_search(pool_.begin() + c.first, pool_.begin() + c.first + c.count, hit))
        offered = true;
      // The expanded box's exit
      double t_exit = 1e300;
      int axis = -1;
      for (int k = 0; k < 3; ++k) {
        if (d[k] == 0.0) continue;
        const double face = origin[k] + cs * double(d[k] > 0.0 ? c.ehi[k] + 1 : c.elo[k]);
        const double tk = (face - org[k]) / d[k];
        if (tk < t_exit) t_exit = tk, axis = k;
      }
      if (axis < 0 || double(t_hit) <= t_exit || t_exit >= double(rs.t_end)) return;
      // The neighbour across the exit face; the other axes where the ray is there
      uvec3 n;
      for (int k = 0; k < 3; ++k) {
        if (k == axis) continue;
        const double x = std::floor((org[k] + d[k] * t_exit - origin[k]) / cs);
        n[k] = uint32_t(std::clamp(x, double(c.elo[k]), double(c.ehi[k])));
      }
      if (d[axis] > 0.0) {
        if (c.ehi[axis] + 1 >= g_.cells[axis]) return;
        n[axis] = c.ehi[axis] + 1;
      } else {
        if (c.elo[axis] == 0) return;
        n[axis] = c.elo[axis] - 1;
      }
      v = n;
      t = t_exit;
    }
  }

  size_t cell_count() const { return cells_.size(); }
  // A GPU layout's bytes: a dense map of 4 bytes per virtual cell, per cell its box and exit box
  // (12 16-bit words) and its run's start (4 bytes), 4 bytes per reference
  double mib() const {
    return (4.0 * double(map_.size()) + 28.0 * double(cells_.size()) + 4.0 * double(refs_stored())) / 1048576.0;
  }
  // The same with a two-level map (Perard-Gayot et al.'s): per top cell of f^3 virtual cells (the
  // chosen grid's), 4 bytes, the one cell they all belong to or the start of f^3 entries of 4 bytes
  double two_level_mib(uint32_t f) const {
    const uvec3 top = g_.cells / f;
    uint64_t mixed = 0;
    for (uint32_t z = 0; z < top.z; ++z)
      for (uint32_t y = 0; y < top.y; ++y)
        for (uint32_t x = 0; x < top.x; ++x) {
          const uint32_t first = map_[index(uvec3(x, y, z) * f)];
          bool same = true;
          for (uint32_t k = 0; k < f * f * f && same; ++k)
            same = map_[index(uvec3(x, y, z) * f + uvec3(k % f, (k / f) % f, k / (f * f)))] == first;
          mixed += same ? 0u : 1u;
        }
    const double top_cells = double(top.x) * top.y * top.z;
    return (4.0 * top_cells + 4.0 * double(f * f * f) * double(mixed) + 28.0 * double(cells_.size()) +
            4.0 * double(refs_stored())) / 1048576.0;
  }
  uint64_t refs_stored() const {
    uint64_t r = 0;
    for (const Cell& c : cells_) r += c.count;
    return r;
  }

 private:
  shared::GridParams g_;
  float c_;
  std::vector<uint32_t> map_;  // virtual cell -> cell
  std::vector<Cell> cells_;
  std::vector<uint32_t> pool_;
};

}  // namespace

int main(int argc, char** argv) {
  reference::GridOptions o;
  o.traversal = reference::Traversal::exact;
  std::vector<uint32_t> factors{1, 2};
  float visit_cost = plan::kExactCellVisitCost;
  std::string expand = "subset";
  std::string merge = "on";
  std::vector<std::string> scenes;
  CLI::App app("gridrt_merge_estimate: cells and tests per ray of an irregular grid (merged cells) against the chosen uniform grid");
  app.add_option("scenes", scenes, "Scenes: builtin:NAME, a scene file or a mesh")->required();
  app.add_option("--factors", factors, "Virtual grids: the chosen grid's cells times each factor per axis")
      ->delimiter(',')
      ->check(CLI::Range(1u, 4u));
  app.add_option("--visit-cost", visit_cost, "A cell visit's cost in tests (merge rule and cost column)")
      ->check(CLI::Range(0.0f, 100.0f));
  app.add_option("--expand", expand, "Exit boxes grown over cells whose references the cell holds, over empty cells only, or not")
      ->check(CLI::IsMember({"subset", "chain", "empty", "off"}));
  uint32_t max_extent = 1u << 30;
  app.add_option("--max-extent", max_extent, "An exit box's most cells beyond its cell on each side");
  app.add_option("--merge", merge, "Cells merged by the cost rule, or kept as the virtual grid's (off: exit boxes on a uniform grid)")
      ->check(CLI::IsMember({"on", "off", "subdivide"}));
  uint32_t threshold = 8;
  app.add_option("--threshold", threshold, "--merge subdivide: a chosen-grid cell holding more references is kept as f^3 cells");
  app.add_option("--threads", o.threads, "CPU threads for the grid choice (0: all)");
  CLI11_PARSE(app, argc, argv);
  try {
  for (const std::string& spec : scenes) {
    const Scene scene = load_scene(spec);
    const float time = 0.0f;
    reference::GridChoice choice;
    const shared::GridParams g0 = reference::choose_grid(scene, time, o, &choice);
    const plan::WorkSample& sample = choice.sample;
    if (sample.rays.empty() || choice.candidates.empty()) {
      std::printf("%s: the trace-cost policy weighed no grid (a grid the scene file fixes?): nothing to compare\n",
                  spec.c_str());
      continue;
    }
    const plan::GridCandidate& chosen = choice.candidates[choice.chosen];
    std::printf("== %s: chosen %ux%ux%u, %zu sample rays (%s)\n", spec.c_str(), g0.cells.x, g0.cells.y, g0.cells.z,
                sample.rays.size(), sample.bounce ? "bounce" : "camera");
    const double rays = double(sample.rays.size());
    const double uni_cost = chosen.work.tests + visit_cost * chosen.work.cells;
    std::printf("| grid | cells | refs stored | refs per triangle | cells per ray | tests per ray | tests + %.1f cells | vs chosen | hit triangle offered %% | MiB (dense map / two-level map) |\n",
                visit_cost);
    std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
    std::printf("| uniform %ux%ux%u, skip field (the policy's estimate) | %llu | - | - | %.2f | %.2f | %.2f | 1.000 | - | %.1f (the budget's measure: no plane buffer) |\n",
                g0.cells.x, g0.cells.y, g0.cells.z, (unsigned long long)(uint64_t(g0.cells.x) * g0.cells.y * g0.cells.z),
                chosen.work.cells, chosen.work.tests, uni_cost, double(chosen.memory) / 1048576.0);
    // Triangle ids: per instance its first id
    std::vector<uint32_t> inst_first(scene.instances.size() + 1, 0);
    for (size_t i = 0; i < scene.instances.size(); ++i)
      inst_first[i + 1] = inst_first[i] + scene.meshes[scene.instances[i].mesh].triangle_count();
    const uint64_t triangles = inst_first.back();
    // The sample's hit triangles by their world vertices (the sample keeps vertices, not ids)
    std::map<std::array<float, 9>, uint32_t> by_vertices;
    for (size_t i = 0; i < scene.instances.size(); ++i)
      plan::for_each_placed_triangle(scene, i, time, g0, [&](const plan::PlacedTriangle& p) {
        by_vertices.emplace(std::array<float, 9>{p.v0.x, p.v0.y, p.v0.z, p.v1.x, p.v1.y, p.v1.z, p.v2.x, p.v2.y, p.v2.z},
                            inst_first[i] + p.index);
      });
    std::vector<uint32_t> hit_id(sample.rays.size(), ~0u);
    size_t hits = 0;
    for (size_t r = 0; r < sample.rays.size(); ++r) {
      if (!std::isfinite(sample.t_end[r])) continue;
      const auto& h = sample.hit[r];
      const auto it = by_vertices.find({h[0].x, h[0].y, h[0].z, h[1].x, h[1].y, h[1].z, h[2].x, h[2].y, h[2].z});
      if (it != by_vertices.end()) hit_id[r] = it->second, hits += 1;
    }
    for (uint32_t f : factors) {
      const auto t0 = std::chrono::steady_clock::now();
      shared::GridParams g = g0;
      // The chosen grid's box in f times its cells (set_cell_size's fields, sized_params's bounds)
      g.cells = g0.cells * f;
      g.cell_size = g0.cell_size / float(f);
      g.inv_cell_size = 1.0f / g.cell_size;
      g.sphere_r2 = g0.sphere_r2 / float(f * f);
      g.gap_fill_r2 = g0.gap_fill_r2 / float(f * f);
      g.upper = g.origin + vec3(g.cells) * g.cell_size;
      g.max_segments = g.cells.x + g.cells.y + g.cells.z + 3u;
      const size_t n = size_t(g.cells.x) * g.cells.y * g.cells.z;
      // About 70 bytes of host memory per virtual cell (its cell record, the map, the merge's lists)
      if (n > (size_t(1) << 27)) {
        std::printf("| over %ux%ux%u (factor %u) | skipped: %zu virtual cells, over the 2^27 this program takes (about 9 GB) |\n",
                    g.cells.x, g.cells.y, g.cells.z, f, n);
        continue;
      }
      // The cells' references, CSR (each list ascending: ids by instance, then triangle)
      std::vector<uint32_t> first(n + 1, 0);
      for (size_t i = 0; i < scene.instances.size(); ++i)
        plan::for_each_triangle_cell(scene, i, time, g, [&](uint32_t, size_t c) { first[c + 1] += 1; });
      std::partial_sum(first.begin(), first.end(), first.begin());
      std::vector<uint32_t> refs(first[n]);
      std::vector<uint32_t> fill(first.begin(), first.end() - 1);
      for (size_t i = 0; i < scene.instances.size(); ++i)
        plan::for_each_triangle_cell(scene, i, time, g, [&](uint32_t t, size_t c) { refs[fill[c]++] = inst_first[i] + t; });
      for (size_t c = 0; c < n; ++c) std::sort(refs.begin() + first[c], refs.begin() + first[c + 1]);
      IrregularGrid grid(g, std::move(first), std::move(refs), visit_cost);
      const auto walk_all = [&](uint64_t& cells, uint64_t& tests, size_t& offered) {
        cells = tests = 0;
        offered = 0;
        for (size_t r = 0; r < sample.rays.size(); ++r) {
          const uint32_t ref = sample.rays[r].launch_ref;
          const uint32_t launch = ref != shared::kNoRef && (g.flags & shared::kGridExcludeLaunchRef) != 0u &&
                                          shared::ref_instance(ref) < scene.instances.size()
                                      ? inst_first[shared::ref_instance(ref)] + shared::ref_triangle(ref)
                                      : ~0u;
          bool found = false;
          grid.walk(sample.rays[r], sample.t_end[r], launch, hit_id[r], cells, tests, found);
          offered += found ? 1u : 0u;
        }
      };
      uint64_t cells = 0, tests = 0;
      size_t offered = 0;
      if (f == 1) {
        const uint64_t stored = grid.refs_stored();
        walk_all(cells, tests, offered);
        const double cost = (tests + visit_cost * cells) / rays;
        std::printf("| uniform %ux%ux%u, every cell walked | %zu | %llu | %.2f | %.2f | %.2f | %.2f | %.3f | %.2f | %.1f |\n", g.cells.x,
                    g.cells.y, g.cells.z, grid.cell_count(), (unsigned long long)stored, double(stored) / double(triangles),
                    cells / rays, tests / rays, cost, cost / uni_cost, 100.0 * double(offered) / double(std::max<size_t>(hits, 1)), grid.mib());
      }
      if (merge == "on") grid.merge();
      if (merge == "subdivide" && f > 1) grid.subdivide(f, threshold);
      if (expand != "off") grid.expand(expand == "empty", expand == "chain", max_extent);
      walk_all(cells, tests, offered);
      const uint64_t stored = grid.refs_stored();
      const double cost = (tests + visit_cost * cells) / rays;
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::printf("| irregular over %ux%ux%u (merge %s, expand %s; %.1f s) | %zu | %llu | %.2f | %.2f | %.2f | %.2f | %.3f | %.2f | %.1f / %.1f |\n",
                  g.cells.x, g.cells.y, g.cells.z, merge.c_str(), expand.c_str(), s, grid.cell_count(), (unsigned long long)stored,
                  double(stored) / double(triangles), cells / rays, tests / rays, cost, cost / uni_cost,
                  100.0 * double(offered) / double(std::max<size_t>(hits, 1)), grid.mib(), grid.two_level_mib(f));
      std::fflush(stdout);
    }
  }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gridrt_merge_estimate: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
