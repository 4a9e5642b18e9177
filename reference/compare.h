// compare.h: how two tracers are held to each other: hit records by bits (and by ulps where a
// driver may differ), grid images texel for texel (sorted) or per cell as multisets (first-empty).
// Used by `gridrt diff` and by the differential tests.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "gridrt/common/tracer.h"
#include "gridrt/common/util.h"
#include "gridrt/reference/grid.h"

namespace gridrt::reference {

using gridrt::ulp_distance;  // common/util.h

// Hit records, both as bits ("t 0x3f800000 inst 1 tri 2 ...") for messages.
std::string hex_hit(const Hit& h);
std::string hex_ray(const Ray& r);

struct HitDiff {
  size_t rays = 0;
  size_t identical = 0;          // memcmp-equal records
  size_t same_discrete = 0;      // same instance, triangle, flags, cells and tests (floats may differ)
  uint32_t max_ulps_t = 0, max_ulps_uv = 0;  // over same_discrete records
  std::vector<size_t> differing; // indices of the records that are not identical, in order
  std::vector<size_t> discrete;  // indices whose discrete fields differ (another hit, cells, ...)
};
HitDiff compare_hits(std::span<const Hit> want, std::span<const Hit> got);

struct TexelDiff {
  size_t texels = 0;
  std::vector<size_t> differing;  // texel indices (x fastest)
};
TexelDiff compare_texels(const AccelDump& want, const AccelDump& got);

// Every reference a build would insert into each cell if capacity were unlimited (cell index
// (z * cells.y + y) * cells.x + x), from the grid's geometry buffer.
std::vector<std::vector<uint32_t>> cell_candidates(const GridData& grid);

// First-empty images: an unsaturated cell holds exactly its candidates (any slot order) and a
// clear status; a saturated one `capacity` distinct candidates and a set status, and with `spill`
// (a list that did not overflow) its slots and its spilled entries together are exactly its
// candidates.
struct CellCheck {
  size_t cells = 0, saturated = 0;
  std::vector<size_t> bad;  // cell indices that break the rule
};
CellCheck check_cells_as_multisets(const GridData& grid, const AccelDump& image, const SpillDump* spill = nullptr);

// The spill lists walked from their heads: per non-empty head (spill_head_index order) the
// references in list order. `problem` (may be null) receives the first broken rule: a list not in
// ascending order, an entry of another cell, an entry reached twice or never, a link out of range.
struct SpillList {
  uint32_t head = 0;            // spill_head_index: 4 * cell + (dynamic ? 1 : 0)
  std::vector<uint32_t> refs;   // in list order
};
std::vector<SpillList> walk_spill_lists(const SpillDump& spill, std::string* problem);

// Two spill lists: the headers (count, capacity, static count), the stored entries as multisets
// of (cell, ref) (the order of appends differs by design), and the lists walked from the heads
// (ascending, so equal whatever the order of appends) where neither overflowed.
struct SpillDiff {
  bool same_header = false;
  size_t entries = 0;                // entries of `want`
  std::vector<shared::SpillEntry> only_want, only_got;  // the multisets' differences
  std::string problem_want, problem_got;  // walk_spill_lists' findings
  bool same_lists = true;
  bool same() const {
    return same_header && only_want.empty() && only_got.empty() && problem_want.empty() && problem_got.empty() &&
           same_lists;
  }
};
SpillDiff compare_spill(const SpillDump& want, const SpillDump& got);

// Why a ray's grid hit differs from the oracle's (docs/ACCURACY.md, "Why paper mode differs"),
// judged by walking the ray's visits again without stopping (for_each_visit) with W the oracle's
// triangle and t_W its distance:
//   tie           both hit, at distances within kTieUlps (a shared edge or coplanar overlap), the
//                 one definition of a tie (sweep's ties column counts the same; docs/ACCURACY.md):
//                 Embree's t is within 2 ulps of the exact one, the watertight test's within a few
//                 (docs/ACCURACY.md, "Exact referee"); Moller-Trumbore's t on slivers can be
//                 hundreds of ulps off, and such a case is no tie (`gridrt verify` judges it exactly)
//   gap_fill      the grid reported a gap-fill voxel (a saturated cell, the paper's design)
//   grid_nearer   the grid reports a real triangle nearer than the oracle's hit, or one where the
//                 oracle finds nothing
//   tested        a visit the trace made stored W and its window covered t_W, yet the test did
//                 not accept it (float test, alpha) or the tie rule chose another
//   reported_early W lies in a later visit's cell and window, but a farther hit was reported
//                 before the trace got there (the "t < segment end" rule)
//   dropped       a visit whose window covers t_W was offered W, but its saturated cell dropped it
//                 (a reference the spill list keeps for the cell is not dropped: cell_traced_references)
//   window        W is stored in a visited cell, but no window (elongated segment) covers t_W
//   skipped_cell  no visited cell holds W: the samples stepped past every cell W was inserted in
inline constexpr uint32_t kTieUlps = 64;
enum class Difference { none, tie, gap_fill, grid_nearer, tested, reported_early, dropped, window, skipped_cell };
const char* to_string(Difference d);
Difference classify_difference(const GridData& grid, const Ray& ray, const Hit& got, const Hit& want);

}  // namespace gridrt::reference
