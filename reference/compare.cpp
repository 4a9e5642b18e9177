#include "gridrt/reference/compare.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <iterator>
#include <sstream>

#include "gridrt/plan/policy.h"

namespace gridrt::reference {

namespace sh = gridrt::shared;

std::string hex_hit(const Hit& h) {
  std::ostringstream os;
  os << "t " << hex(h.t) << " (" << h.t << ") inst " << h.instance << " tri " << h.triangle << " u " << hex(h.u)
     << " v " << hex(h.v) << " flags " << h.flags << " cells " << h.cells << " tests " << h.tests;
  return os.str();
}

std::string hex_ray(const Ray& r) {
  std::ostringstream os;
  os << "org (" << hex(r.org.x) << ", " << hex(r.org.y) << ", " << hex(r.org.z) << ") dir (" << hex(r.dir.x)
     << ", " << hex(r.dir.y) << ", " << hex(r.dir.z) << ") tmin " << hex(r.tmin) << " tmax " << hex(r.tmax)
     << " launch ref 0x" << std::hex << r.launch_ref;
  return os.str();
}

HitDiff compare_hits(std::span<const Hit> want, std::span<const Hit> got) {
  HitDiff d;
  d.rays = std::min(want.size(), got.size());
  for (size_t i = 0; i < d.rays; ++i) {
    const Hit& a = want[i];
    const Hit& b = got[i];
    if (std::memcmp(&a, &b, sizeof(Hit)) == 0) {
      ++d.identical;
      ++d.same_discrete;
      continue;
    }
    d.differing.push_back(i);
    if (a.instance == b.instance && a.triangle == b.triangle && a.flags == b.flags && a.cells == b.cells &&
        a.tests == b.tests) {
      ++d.same_discrete;
      d.max_ulps_t = std::max(d.max_ulps_t, ulp_distance(a.t, b.t));
      d.max_ulps_uv = std::max({d.max_ulps_uv, ulp_distance(a.u, b.u), ulp_distance(a.v, b.v)});
    } else {
      d.discrete.push_back(i);
    }
  }
  return d;
}

TexelDiff compare_texels(const AccelDump& want, const AccelDump& got) {
  TexelDiff d;
  if (want.extent != got.extent || want.texels.size() != got.texels.size())
    throw Error("grid images of different extents cannot be compared texel for texel");
  d.texels = want.texels.size();
  for (size_t i = 0; i < d.texels; ++i)
    if (want.texels[i] != got.texels[i]) d.differing.push_back(i);
  return d;
}

std::vector<std::vector<uint32_t>> cell_candidates(const GridData& grid) {
  const sh::GridParams& g = grid.params;
  std::vector<std::vector<uint32_t>> out(size_t(g.cells.x) * g.cells.y * g.cells.z);
  for (uint32_t i = 0; i < grid.instances.size(); ++i)
    for (uint32_t k = 0; k < grid.instances[i].tri_count; ++k) {
      const sh::GridTriangle& t = grid.triangles[grid.instances[i].tri_offset + k];
      if (sh::triangle_zero_area(t.v0, t.v1, t.v2)) continue;
      const glm::vec3 n = sh::triangle_normal(t.v0, t.v1, t.v2);
      glm::uvec3 lo, hi;
      sh::triangle_cell_range(g, t.v0, t.v1, t.v2, lo, hi);
      for (uint32_t z = lo.z; z <= hi.z; ++z)
        for (uint32_t y = lo.y; y <= hi.y; ++y)
          for (uint32_t x = lo.x; x <= hi.x; ++x)
            if (sh::triangle_overlaps_cell(g, t.v0, t.v1, t.v2, n, {x, y, z}))
              out[(size_t(z) * g.cells.y + y) * g.cells.x + x].push_back(sh::ref_pack(i, k));
    }
  return out;
}

std::vector<SpillList> walk_spill_lists(const SpillDump& spill, std::string* problem) {
  std::vector<SpillList> out;
  std::string local;
  std::string& p = problem ? *problem : local;
  p.clear();
  const auto fail = [&](const std::string& what) {
    if (p.empty()) p = what;
  };
  std::vector<uint8_t> seen(spill.entries.size(), 0);
  for (uint32_t h = 0; h < spill.heads.size(); ++h) {
    if (h % 4 >= 2) continue;  // the arrival heads: their order is the order of the appends
    uint32_t i = spill.heads[h];
    if (i == sh::kSpillEnd) continue;
    SpillList list{h, {}};
    while (i != sh::kSpillEnd) {
      if (i >= spill.entries.size()) {
        fail("head " + std::to_string(h) + ": a link to entry " + std::to_string(i) + " past the stored entries");
        break;
      }
      if (seen[i]++) {
        fail("entry " + std::to_string(i) + " is reached twice");
        break;
      }
      const sh::SpillEntry& e = spill.entries[i];
      if (e.cell != h / 4) fail("entry " + std::to_string(i) + " of cell " + std::to_string(e.cell) + " in cell " + std::to_string(h / 4) + "'s list");
      if (!list.refs.empty() && e.ref <= list.refs.back()) fail("head " + std::to_string(h) + ": not in ascending order");
      list.refs.push_back(e.ref);
      i = e.next;
    }
    out.push_back(std::move(list));
  }
  if (spill.on && spill.overflow() == 0)
    for (size_t i = 0; i < seen.size(); ++i)
      if (!seen[i]) fail("entry " + std::to_string(i) + " is in no list");
  return out;
}

SpillDiff compare_spill(const SpillDump& want, const SpillDump& got) {
  SpillDiff d;
  if (want.on || got.on) {
    const std::vector<SpillList> a = walk_spill_lists(want, &d.problem_want), b = walk_spill_lists(got, &d.problem_got);
    if (want.overflow() == 0 && got.overflow() == 0) {
      d.same_lists = a.size() == b.size();
      for (size_t i = 0; d.same_lists && i < a.size(); ++i) d.same_lists = a[i].head == b[i].head && a[i].refs == b[i].refs;
    }
  }
  d.same_header = std::memcmp(&want.header, &got.header, sizeof(sh::SpillHeader)) == 0;
  d.entries = want.entries.size();
  const auto key = [](const sh::SpillEntry& e) { return uint64_t(e.cell) << 32 | e.ref; };
  const auto less = [&](const sh::SpillEntry& a, const sh::SpillEntry& b) { return key(a) < key(b); };
  std::vector<sh::SpillEntry> a = want.entries, b = got.entries;
  std::sort(a.begin(), a.end(), less);
  std::sort(b.begin(), b.end(), less);
  std::set_difference(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(d.only_want), less);
  std::set_difference(b.begin(), b.end(), a.begin(), a.end(), std::back_inserter(d.only_got), less);
  return d;
}

CellCheck check_cells_as_multisets(const GridData& grid, const AccelDump& image, const SpillDump* spill) {
  const sh::GridParams& g = grid.params;
  const std::vector<std::vector<uint32_t>> cand = cell_candidates(grid);
  std::vector<std::vector<uint32_t>> spilled;
  if (spill) {
    spilled.resize(cand.size());
    for (const sh::SpillEntry& e : spill->entries)
      if (e.cell < spilled.size()) spilled[e.cell].push_back(e.ref);
      else return CellCheck{cand.size(), 0, {size_t(e.cell)}};
  }
  CellCheck c;
  c.cells = cand.size();
  for (uint32_t z = 0; z < g.cells.z; ++z)
    for (uint32_t y = 0; y < g.cells.y; ++y)
      for (uint32_t x = 0; x < g.cells.x; ++x) {
        const size_t index = (size_t(z) * g.cells.y + y) * g.cells.x + x;
        const glm::uvec3 cell(x, y, z);
        std::vector<uint32_t> want = cand[index];
        std::vector<uint32_t> have;
        for (uint32_t s = 0; s < g.capacity; ++s) {
          const uint32_t v = image.texels[sh::texel_index(sh::cell_slot_texel(g, cell, s), image.extent)];
          if (v != sh::kBlank) have.push_back(v);
        }
        const uint32_t status = image.texels[sh::texel_index(sh::cell_status_texel(g, cell), image.extent)];
        std::sort(want.begin(), want.end());
        std::sort(have.begin(), have.end());
        bool ok;
        if (want.size() <= g.capacity) {
          ok = have == want && status == 0u;
        } else {
          ++c.saturated;
          ok = have.size() == g.capacity && std::adjacent_find(have.begin(), have.end()) == have.end() &&
               std::includes(want.begin(), want.end(), have.begin(), have.end()) && status != 0u;
          if (spill && spill->overflow() == 0) {
            // The slots and the spilled entries together: every candidate once
            std::vector<uint32_t> all = have;
            all.insert(all.end(), spilled[index].begin(), spilled[index].end());
            std::sort(all.begin(), all.end());
            ok = ok && all == want;
          }
        }
        if (spill && want.size() <= g.capacity && !spilled[index].empty()) ok = false;
        if (!ok) c.bad.push_back(index);
      }
  return c;
}

const char* to_string(Difference d) {
  switch (d) {
    case Difference::none: return "none";
    case Difference::tie: return "tie";
    case Difference::gap_fill: return "gap-fill";
    case Difference::grid_nearer: return "grid nearer";
    case Difference::tested: return "tested";
    case Difference::reported_early: return "reported early";
    case Difference::dropped: return "dropped";
    case Difference::window: return "window";
    case Difference::skipped_cell: return "skipped cell";
  }
  return "?";
}

Difference classify_difference(const GridData& grid, const Ray& ray, const Hit& got, const Hit& want) {
  const sh::GridParams& g = grid.params;
  const bool gh = !is_miss(got), wh = !is_miss(want);
  if (gh == wh && (!gh || (got.instance == want.instance && got.triangle == want.triangle))) return Difference::none;
  if (gh && (got.flags & sh::kHitGapFill)) return Difference::gap_fill;
  if (gh && wh && ulp_distance(got.t, want.t) <= kTieUlps) return Difference::tie;
  if (gh && (!wh || got.t < want.t)) return Difference::grid_nearer;
  // The oracle's triangle W: which cells the build offered it, which kept it
  const uint32_t w_ref = sh::ref_pack(want.instance, want.triangle);
  const sh::GridTriangle& tri = grid.triangles[grid.instances[want.instance].tri_offset + want.triangle];
  const glm::vec3 n = sh::triangle_normal(tri.v0, tri.v1, tri.v2);
  const bool area = !sh::triangle_zero_area(tri.v0, tri.v1, tri.v2);
  glm::uvec3 lo, hi;
  sh::triangle_cell_range(g, tri.v0, tri.v1, tri.v2, lo, hi);
  const auto offered = [&](glm::uvec3 c) {
    return area && glm::all(glm::greaterThanEqual(c, lo)) && glm::all(glm::lessThanEqual(c, hi)) &&
           sh::triangle_overlaps_cell(g, tri.v0, tri.v1, tri.v2, n, c);
  };
  const auto stored = [&](glm::uvec3 c) {
    for (uint32_t v : cell_traced_references(grid, c))
      if (v == w_ref) return true;
    return false;
  };
  sh::RaySetup rs;
  sh::ray_setup(g, ray.org, ray.dir, ray.tmin, ray.tmax, rs);
  const bool exact = g.traversal == sh::kTraversalExact;
  uint32_t visit = 0, reachable = UINT32_MAX;
  bool dropped = false, in_cell = false;
  for_each_visit(g, ray, [&](glm::uvec3 c, uint32_t k, uint32_t last, float, bool tested) {
    if (!tested) return true;
    const float t_lo = exact ? rs.t_lo : std::max(rs.t_lo, sh::segment_elongated_begin(g, rs, k));
    const float t_hi = exact ? ray.tmax : std::min(ray.tmax, sh::segment_elongated_end(g, rs, last));
    const bool covers = t_lo < want.t && want.t < t_hi;
    if (offered(c)) {
      const bool kept = stored(c);
      in_cell = in_cell || kept;
      if (covers && kept && reachable == UINT32_MAX) reachable = visit;
      if (covers && !kept) dropped = true;
    }
    ++visit;
    return true;
  });
  if (reachable != UINT32_MAX) return reachable < got.cells ? Difference::tested : Difference::reported_early;
  if (dropped) return Difference::dropped;
  return in_cell ? Difference::window : Difference::skipped_cell;
}

}  // namespace gridrt::reference
