// build.cpp: choosing the grid, scene build (paper 2.1) and scene update (paper 2.2).
#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <thread>

#include "gridrt/common/invocations.h"
#include "gridrt/common/progress.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/shared/transform.h"
#include "gridrt/reference/grid.h"
#include "gridrt/plan/policy.h"

namespace gridrt::reference {

using shared::GridParams;
using shared::kBlank;


// ---- The skip field (kGridSkipEmpty; docs/SPEC.md "Empty-space skipping") ----

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
        const bool occupied = cell_occupied(grid, c);
        sum += occupied ? 1u : 0u;
        table[i] = sum;
      } else {
        sum += table[i];
        table[i] = sum;
      }
    }
  }, 64);
}
// Whether the sorted run refs[b0, b1) lies in the sorted run refs[a0, a1) (one merge walk).
bool run_within(const std::vector<uint32_t>& refs, uint32_t b0, uint32_t b1, uint32_t a0, uint32_t a1) {
  if (b1 - b0 > a1 - a0) return false;
  uint32_t j = a0;
  for (uint32_t k = b0; k < b1; ++k) {
    while (j < a1 && refs[j] < refs[k]) ++j;
    if (j == a1 || refs[j] != refs[k]) return false;
    ++j;
  }
  return true;
}

// A cell's cover bits (kGridSkipCovered; shared/grid.h "Covered cells"): bit f set iff its static
// run is not empty and lies in the run of its neighbour across face f.
uint32_t skip_cover_bits(const GridData& grid, glm::uvec3 c) {
  const GridParams& g = grid.params;
  uint32_t b0 = 0u, b1 = 0u;
  if (!compact_run(grid, shared::cell_linear_index(g, c), b0, b1) || b1 == b0) return 0u;
  uint32_t bits = 0u;
  for (uint32_t f = 0u; f < 6u; ++f) {
    glm::uvec3 n;
    uint32_t a0 = 0u, a1 = 0u;
    if (shared::skip_face_neighbour(g, c, f, n) && compact_run(grid, shared::cell_linear_index(g, n), a0, a1) &&
        run_within(grid.refs, b0, b1, a0, a1))
      bits |= 1u << f;
  }
  return bits;
}
}  // namespace

void skip_field_build(GridData& grid, const GridOptions& o) {
  const GridParams& g = grid.params;
  std::vector<uint32_t> table(shared::skip_table_words(g), 0u);
  for (uint32_t pass = 0; pass < 3; ++pass) skip_table_pass(grid, table, pass, o);
  // The bricks' distances, one invocation per brick: the smallest R whose grown box holds an
  // occupied cell, by binary search over [0, kSkipMaxBrickDistance]
  std::vector<uint32_t> bricks(shared::skip_brick_count(g));
  run_invocations(uint32_t(bricks.size()), thread_count(o), std::nullopt, [&](uint32_t b) {
    bricks[b] = plan::skip_brick_distance(g, table, shared::skip_brick_of_index(g, b));
  }, 256);
  // The cells' bytes, one invocation per word (4 cells): the distance, the smallest r whose cube
  // holds an occupied cell, by binary search over the window its brick's distance leaves
  // (skip_cell_window); an occupied cell's cover bits in its byte (kGridSkipCovered)
  const uint32_t cells = shared::grid_cell_count(g);
  const bool covered = (g.flags & shared::kGridSkipCovered) != 0u;
  run_invocations((cells + 3u) / 4u, thread_count(o), std::nullopt, [&](uint32_t word) {
    uint32_t packed = 0u;
    for (uint32_t q = 0; q < 4u && 4u * word + q < cells; ++q) {
      const uint32_t i = 4u * word + q;
      const glm::uvec3 c = shared::cell_of_linear_index(g, i);
      uint32_t lo = 0u, hi = 0u;
      shared::skip_cell_window(bricks[shared::skip_brick_index(g, c)], lo, hi);
      const uint32_t d = plan::skip_static_distance(g, table, c, lo, hi);
      const uint32_t cover = covered && d == 0u ? skip_cover_bits(grid, c) : 0u;
      packed |= shared::skip_byte(d, cover) << shared::skip_distance_shift(i);
    }
    grid.skip[shared::kSkipHeaderWords + word] = packed;
  }, 256);
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
  uint32_t arrival = shared::spill_arrival_index(c, ref >= g.comparison_offset);
  if ((g.flags & shared::kGridCompact) != 0u) {
    // Compact: the heads of the dynamic region's cells (no reference reaches a cell outside it:
    // the region bounds the dynamic instances' swept bounds with a cell of margin)
    const glm::uvec3 lo(grid.spill_heads[0], grid.spill_heads[1], grid.spill_heads[2]);
    const glm::uvec3 hi(grid.spill_heads[4], grid.spill_heads[5], grid.spill_heads[6]);
    if (!shared::region_contains(cell, lo, hi)) return;
    arrival = shared::compact_arrival_index(shared::region_index(cell, lo, hi));
  }
  grid.spill[i].arrival = atomicExchange(grid.spill_heads[arrival], i);
}

// ---- The compact layout (kGridCompact; docs/SPEC.md "Compact layout") ----

// The count pass (the static pass's insertion): the cell's count, and the (cell, ref) pair at the
// next index of the pair list (its capacity is the plan's count of the static references).
void compact_count(GridData& grid, glm::uvec3 cell, uint32_t ref) {
  const uint32_t c = shared::cell_linear_index(grid.params, cell);
  atomicAdd(grid.compact_counts[c], 1u);
  const uint32_t k = atomicAdd(grid.compact_pair_count, 1u);
  if (2 * size_t(k) + 1 < grid.compact_pairs.size()) {
    grid.compact_pairs[2 * size_t(k)] = c;
    grid.compact_pairs[2 * size_t(k) + 1] = ref;
  }
}

// The offsets pass: the exclusive scan of the counts (the scatter's cursors), which are the dense
// offsets (cells + 1 words: offsets[i], offsets[cells] the total); with kGridSparseOffsets, the
// index of the occupied cells' runs instead (shared/grid.h: per word of 32 cells its base and
// occupancy mask, then per occupied cell its run's start, then the total). Both scans in three steps, on pairs (references,
// occupied cells): per block of kCompactBlock cells its sums; the blocks' exclusive scan
// (kCompactScanLanes shares of the blocks, each share's sums, the shares' sums scanned, then each
// share's blocks'); per block its cells (a block is whole words: kCompactBlock is a multiple of
// 32). Integer sums: the same bits in any order (compact.comp groups the work otherwise:
// docs/SPEC.md "Compact layout").
void compact_offsets(GridData& grid, const GridOptions& o) {
  const uint32_t cells = shared::grid_cell_count(grid.params);
  const uint32_t blocks = (cells + shared::kCompactBlock - 1u) / shared::kCompactBlock;
  static_assert(shared::kCompactBlock % 32u == 0u, "a block of the offsets pass is whole words");
  std::vector<glm::uvec2> block(blocks, glm::uvec2(0u));  // (references, occupied cells)
  run_invocations(blocks, thread_count(o), std::nullopt, [&](uint32_t b) {
    glm::uvec2 sum(0u);
    for (uint32_t i = b * shared::kCompactBlock; i < std::min(cells, (b + 1u) * shared::kCompactBlock); ++i)
      sum += glm::uvec2(grid.compact_counts[i], grid.compact_counts[i] != 0u ? 1u : 0u);
    block[b] = sum;
  }, 64);
  const uint32_t per_lane = (blocks + shared::kCompactScanLanes - 1u) / shared::kCompactScanLanes;
  std::vector<glm::uvec2> lane_sum(shared::kCompactScanLanes, glm::uvec2(0u));
  for (uint32_t l = 0; l < shared::kCompactScanLanes; ++l)
    for (uint32_t b = l * per_lane; b < std::min(blocks, (l + 1u) * per_lane); ++b) lane_sum[l] += block[b];
  glm::uvec2 running(0u);
  for (uint32_t l = 0; l < shared::kCompactScanLanes; ++l) {
    const glm::uvec2 s = lane_sum[l];
    lane_sum[l] = running;
    running += s;
  }
  for (uint32_t l = 0; l < shared::kCompactScanLanes; ++l) {
    glm::uvec2 r = lane_sum[l];
    for (uint32_t b = l * per_lane; b < std::min(blocks, (l + 1u) * per_lane); ++b) {
      const glm::uvec2 s = block[b];
      block[b] = r;
      r += s;
    }
  }
  const bool sparse = (grid.params.flags & shared::kGridSparseOffsets) != 0u;
  const uint32_t runs = shared::compact_runs_base(cells);
  const size_t words = grid.offsets.size();
  run_invocations(blocks, thread_count(o), std::nullopt, [&](uint32_t b) {
    glm::uvec2 r = block[b];
    const uint32_t block_end = std::min(cells, (b + 1u) * shared::kCompactBlock);
    if (!sparse) {
      for (uint32_t i = b * shared::kCompactBlock; i < block_end; ++i) {
        const uint32_t n = grid.compact_counts[i];
        grid.offsets[i] = r.x;
        grid.compact_counts[i] = r.x;  // the scatter's cursor
        r.x += n;
      }
      if (block_end == cells) grid.offsets[cells] = r.x;
      return;
    }
    for (uint32_t i = b * shared::kCompactBlock; i < block_end; ++i) {
      const uint32_t n = grid.compact_counts[i];
      if (i % 32u == 0u) {
        grid.offsets[shared::compact_base_index(i)] = r.y;
        grid.offsets[shared::compact_mask_index(i)] = 0u;
      }
      grid.compact_counts[i] = r.x;  // the scatter's cursor
      if (n != 0u) {
        grid.offsets[shared::compact_mask_index(i)] |= 1u << (i % 32u);
        if (runs + size_t(r.y) < words) grid.offsets[runs + r.y] = r.x;
      }
      r += glm::uvec2(n, n != 0u ? 1u : 0u);
    }
    // The last cell's block writes the total after the last occupied cell's start
    if (block_end == cells && runs + size_t(r.y) < words) grid.offsets[runs + r.y] = r.x;
  }, 64);
}

bool compact_run(const GridData& grid, uint32_t i, uint32_t& begin, uint32_t& end) {
  const uint32_t cells = shared::grid_cell_count(grid.params);
  if ((grid.params.flags & shared::kGridSparseOffsets) == 0u) {
    begin = grid.offsets[i];
    end = grid.offsets[i + 1];
    return end > begin;
  }
  const uint32_t mask = grid.offsets[shared::compact_mask_index(i)];
  begin = end = 0u;
  if (!shared::compact_occupied(mask, i)) return false;
  const uint32_t k = shared::compact_run_index(cells, grid.offsets[shared::compact_base_index(i)], mask, i);
  if (size_t(k) + 1 >= grid.offsets.size()) return false;  // past the index (as compact.comp: a wrong count fails the build)
  begin = grid.offsets[k];
  end = grid.offsets[k + 1];
  return true;
}

uint32_t compact_occupied_cells(const GridData& grid) {
  const uint32_t cells = shared::grid_cell_count(grid.params);
  if ((grid.params.flags & shared::kGridSparseOffsets) == 0u) {
    uint32_t n = 0;
    for (uint32_t i = 0; i < cells; ++i) n += grid.offsets[i + 1] > grid.offsets[i];
    return n;
  }
  return uint32_t(grid.offsets.size()) - shared::compact_runs_base(shared::grid_cell_count(grid.params)) - 1u;
}

// The scatter pass, one invocation per pair: the reference into its cell's run at the cell's
// cursor (an atomic add: the order within a run is the device's timing).
void compact_scatter(GridData& grid, const GridOptions& o) {
  const uint32_t pairs = std::min<uint32_t>(grid.compact_pair_count, uint32_t(grid.compact_pairs.size() / 2));
  run_invocations(pairs, thread_count(o), std::nullopt, [&](uint32_t k) {
    const uint32_t c = grid.compact_pairs[2 * size_t(k)], ref = grid.compact_pairs[2 * size_t(k) + 1];
    const uint32_t at = atomicAdd(grid.compact_counts[c], 1u);
    grid.compact_scattered[at] = ref;
  }, 64);
}

// The order pass: each pair's rank in its cell's scattered run (the references of a cell are
// distinct: a triangle visits a cell once) is its place in the ordered run; so the runs are in
// ascending order whatever the scatter's order. The shader (compact.comp) gives each pair an
// invocation that counts its run's smaller references (k steps for a run of k, k^2 a run); here
// each run is sorted once, the same places in k log k (3,000 copies of one triangle in a cell
// took seconds of a build: an outside sweep).
void compact_order(GridData& grid, const GridOptions& o) {
  const uint32_t pairs = std::min<uint32_t>(grid.compact_pair_count, uint32_t(grid.compact_pairs.size() / 2));
  std::vector<uint32_t> cells(pairs);
  for (uint32_t k = 0; k < pairs; ++k) cells[k] = grid.compact_pairs[2 * size_t(k)];
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  run_invocations(uint32_t(cells.size()), thread_count(o), std::nullopt, [&](uint32_t k) {
    uint32_t begin, end;
    compact_run(grid, cells[k], begin, end);
    end = std::min<uint32_t>(end, uint32_t(grid.compact_scattered.size()));  // as compact.comp: never past the arrays
    if (end <= begin) return;
    std::vector<uint32_t> run(grid.compact_scattered.begin() + begin, grid.compact_scattered.begin() + end);
    std::sort(run.begin(), run.end());
    for (size_t j = 0; j < run.size() && size_t(begin) + j < grid.refs.size(); ++j) grid.refs[begin + j] = run[j];
  });
}

// The update's clear step of the compact layout: the spill counter back to the static count (no
// static reference is spilled there: 0) and every dynamic head of the region empty (Vulkan: a copy
// and a fill of the heads after the header).
void clear_dynamic_spill(GridData& grid) {
  grid.spill_header.count = grid.spill_header.static_count;
  std::fill(grid.spill_heads.begin() + shared::kCompactHeadsHeader, grid.spill_heads.end(), shared::kSpillEnd);
}

bool cell_occupied(const GridData& grid, glm::uvec3 cell) {
  const GridParams& g = grid.params;
  if ((g.flags & shared::kGridCompact) != 0u) {
    uint32_t begin, end;
    return compact_run(grid, shared::cell_linear_index(g, cell), begin, end) && end > begin;
  }
  return imageLoad(grid.image, glm::ivec3(shared::cell_slot_texel(g, cell, 0u))) != kBlank;
}

std::vector<uint32_t> cell_references(const GridData& grid, glm::uvec3 cell) {
  const GridParams& g = grid.params;
  std::vector<uint32_t> out;
  if ((g.flags & shared::kGridCompact) != 0u) {
    uint32_t begin, end;
    if (compact_run(grid, shared::cell_linear_index(g, cell), begin, end))
      out.assign(grid.refs.begin() + begin, grid.refs.begin() + end);
    return out;
  }
  for (uint32_t s = 0; s < g.capacity; ++s) {
    const uint32_t ref = imageLoad(grid.image, glm::ivec3(shared::cell_slot_texel(g, cell, s)));
    if (ref == kBlank) break;
    out.push_back(ref);
  }
  return out;
}

std::vector<uint32_t> cell_traced_references(const GridData& grid, glm::uvec3 cell) {
  const GridParams& g = grid.params;
  std::vector<uint32_t> out = cell_references(grid, cell);
  if ((g.flags & shared::kGridSpill) == 0u || grid.spill_heads.empty()) return out;
  // The walks of the trace's test_spilled and test_compact_cell (reference/trace.cpp): one bound of
  // the list's capacity over both of a cell's lists
  uint32_t k = 0;
  const auto walk = [&](uint32_t e) {
    for (; e != shared::kSpillEnd && k < grid.spill_header.capacity; ++k, e = grid.spill[e].next)
      out.push_back(grid.spill[e].ref);
  };
  if ((g.flags & shared::kGridCompact) != 0u) {
    const glm::uvec3 lo(grid.spill_heads[0], grid.spill_heads[1], grid.spill_heads[2]);
    const glm::uvec3 hi(grid.spill_heads[4], grid.spill_heads[5], grid.spill_heads[6]);
    if (shared::region_contains(cell, lo, hi))
      walk(grid.spill_heads[shared::compact_head_index(shared::region_index(cell, lo, hi))]);
    return out;
  }
  if (cell_status(grid, cell) == 0u) return out;
  for (bool dynamic : {false, true})
    walk(grid.spill_heads[shared::spill_head_index(shared::cell_linear_index(g, cell), dynamic)]);
  return out;
}

uint32_t cell_status(const GridData& grid, glm::uvec3 cell) {
  // The compact layout drops nothing: no cell is saturated
  if ((grid.params.flags & shared::kGridCompact) != 0u) return 0u;
  return imageLoad(grid.image, glm::ivec3(shared::cell_status_texel(grid.params, cell)));
}

plan::GridMemory grid_allocated(const GridData& grid) {
  plan::GridMemory m;
  m.image = uint64_t(grid.image.size()) * 4;
  m.offsets = grid.offsets.size() * 4;
  m.refs = grid.refs.size() * 4;
  m.spill = sizeof(shared::SpillHeader) + std::max<size_t>(grid.spill.size(), 1) * sizeof(shared::SpillEntry);
  m.heads = grid.spill_heads.size() * 4;
  m.skip = grid.skip.size() * 4;
  m.dirty = uint64_t(grid.dirty.size) * 4;
  return m;
}

// The order pass: every entry of [first, stored) links to the smallest larger reference of its
// arrival list (its successor in ascending order); the entry with no smaller reference becomes
// the list's head. References in a list are distinct (a triangle visits a cell once), so every
// entry finds its own place whatever the arrival order: the lists the trace walks are the same on
// every backend. After the build's static pass with first = 0, after every dynamic pass with
// first = static_count.
// The shader (spill_order.comp) gives each entry an invocation that walks its list for that
// successor: k^2 steps for a list of k entries, in parallel. Here each list is sorted once, the
// same links in k log k (the walk took minutes on a cell of 2,000 copies of one triangle under a
// fixed capacity: an outside sweep); entries before `first` keep their links, and the head moves
// only to an entry of this pass, as there.
void spill_order(GridData& grid, const GridOptions& o, uint32_t first) {
  const GridParams& g = grid.params;
  const uint32_t stored = std::min(grid.spill_header.count, grid.spill_header.capacity);
  if ((g.flags & shared::kGridSpill) == 0u || first >= stored) return;
  // The lists this pass's entries arrived in: (arrival index, head index), each once
  std::vector<std::pair<uint32_t, uint32_t>> lists;
  {
    std::vector<std::pair<uint32_t, uint32_t>> all;
    all.reserve(stored - first);
    for (uint32_t i = first; i < stored; ++i) {
      const shared::SpillEntry e = grid.spill[i];
      const bool dynamic = e.ref >= g.comparison_offset;
      uint32_t head = shared::spill_head_index(e.cell, dynamic), arrival = shared::spill_arrival_index(e.cell, dynamic);
      if ((g.flags & shared::kGridCompact) != 0u) {
        const glm::uvec3 lo(grid.spill_heads[0], grid.spill_heads[1], grid.spill_heads[2]);
        const glm::uvec3 hi(grid.spill_heads[4], grid.spill_heads[5], grid.spill_heads[6]);
        const glm::uvec3 cell = shared::cell_of_linear_index(g, e.cell);
        if (!shared::region_contains(cell, lo, hi)) continue;
        head = shared::compact_head_index(shared::region_index(cell, lo, hi));
        arrival = shared::compact_arrival_index(shared::region_index(cell, lo, hi));
      }
      all.emplace_back(arrival, head);
    }
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    lists = std::move(all);
  }
  run_invocations(uint32_t(lists.size()), thread_count(o), std::nullopt, [&](uint32_t l) {
    const auto [arrival, head] = lists[l];
    std::vector<std::pair<uint32_t, uint32_t>> entries;  // (reference, entry)
    for (uint32_t j = grid.spill_heads[arrival]; j != shared::kSpillEnd; j = grid.spill[j].arrival)
      entries.emplace_back(grid.spill[j].ref, j);
    std::sort(entries.begin(), entries.end());
    for (size_t k = 0; k < entries.size(); ++k)
      if (entries[k].second >= first && entries[k].second < stored)
        grid.spill[entries[k].second].next = k + 1 < entries.size() ? entries[k + 1].second : shared::kSpillEnd;
    if (!entries.empty() && entries.front().second >= first && entries.front().second < stored)
      grid.spill_heads[head] = entries.front().second;
  });
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
  // The copy of the entries and the heads (four words a cell): checked before it is made
  require_host_memory(16 * uint64_t(shared::grid_cell_count(grid.params)) +
                          uint64_t(std::min(grid.spill_header.count, grid.spill_header.capacity)) * sizeof(shared::SpillEntry),
                      "a copy of the spill list", "use a coarser grid");
  SpillDump d;
  d.on = (grid.params.flags & shared::kGridSpill) != 0u;
  d.header = grid.spill_header;
  d.entries.assign(grid.spill.begin(), grid.spill.begin() + ptrdiff_t(d.stored()));
  // (one copy of the heads: a conditional of a prvalue and a const lvalue would make a second)
  if ((grid.params.flags & shared::kGridCompact) != 0u) d.heads = plan::expand_compact_heads(grid.spill_heads, grid.params.cells);
  else d.heads = grid.spill_heads;
  return d;
}

SpillDump spill_counts(const GridData& grid) {
  SpillDump d;
  d.on = (grid.params.flags & shared::kGridSpill) != 0u;
  d.header = grid.spill_header;
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
// buffer and its plane to the plane buffer, insert its reference into every cell of its AABB range that the cell test keeps (its
// plane passes through the cell's enlarged bounding sphere; with kGridCellBox, no separating axis).
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
  const uint32_t k = grid.instances[instance].tri_offset + triangle;
  shared::GridTriangle& out = grid.triangles[k];
  out.v0 = v0;
  out.v1 = v1;
  out.v2 = v2;
  // Its plane, for the watertight test (the plane buffer; zero-area triangles too: one rule)
  grid.planes[k] = shared::triangle_plane(v0, v1, v2);
  // Skip zero-area triangles: no ray can hit them
  if (shared::triangle_zero_area(v0, v1, v2)) return;
  const glm::vec3 n = shared::triangle_normal(v0, v1, v2);
  // Cells of the AABB range that the cell test keeps
  glm::uvec3 lo, hi;
  shared::triangle_cell_range(g, v0, v1, v2, lo, hi);
  const uint32_t ref = shared::ref_pack(instance, triangle);
  for (uint32_t z = lo.z; z <= hi.z; ++z)
    for (uint32_t y = lo.y; y <= hi.y; ++y)
      for (uint32_t x = lo.x; x <= hi.x; ++x) {
        const glm::uvec3 cell(x, y, z);
        if (!shared::triangle_overlaps_cell(g, v0, v1, v2, n, cell)) continue;
        if ((g.flags & shared::kGridCompact) != 0u) {
          // Compact: a static reference is counted (and its pair kept) for the offsets; a dynamic
          // one goes to its cell's dynamic spill list
          if (ref < g.comparison_offset) compact_count(grid, cell, ref);
          else spill_reference(grid, cell, ref);
          continue;
        }
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
  Progress progress("grid build: triangles inserted", t1 - t0);  // a line where it takes over a second
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
        progress.advance();
      },
      16);
  progress.finish();
}

}  // namespace

// ---- Scene build (paper 2.1) ----

void scene_build(GridData& grid, const Scene& scene, float time, const GridOptions& o) {
  grid = GridData{};
  plan::GridPlan plan = plan::plan_grid(scene, time, o);
  grid.params = plan.params;
  grid.requested_flags = grid.params.flags;
  const GridParams& g = grid.params;
  // Everything below at once, before any of it is allocated
  require_host_memory(plan::host_build_memory(g, plan.static_references, plan.static_cells, plan.spill_capacity,
                                              plan.region.cells()),
                      "reference build: " + std::to_string(g.cells.x) + "x" + std::to_string(g.cells.y) + "x" +
                          std::to_string(g.cells.z) + " cells",
                      "lower --resolution or --memory-budget");
  // The spill list: empty, room for the references the trial would drop
  grid.spill_header = shared::SpillHeader{0u, plan.spill_capacity, 0u, 0u};
  grid.spill.assign(grid.spill_header.capacity, shared::SpillEntry{0u, kBlank, shared::kSpillEnd, shared::kSpillEnd});
  // (the image layout's heads, four per cell; the compact layout's, only its region's, below)
  const bool compact = (g.flags & shared::kGridCompact) != 0u;
  if ((g.flags & shared::kGridSpill) != 0u && !compact)
    grid.spill_heads.assign(4 * size_t(g.cells.x) * g.cells.y * g.cells.z, shared::kSpillEnd);
  // Tables: instances, materials and their alpha masks, the geometry buffer
  grid.static_instances = plan.tables.static_instances;
  grid.static_triangles = plan.tables.static_triangles;
  grid.instances = std::move(plan.tables.instances);
  grid.triangles = std::move(plan.tables.triangles);
  grid.planes.assign(grid.triangles.size(), shared::GridPlane{});
  grid.uvs = std::move(plan.tables.uvs);
  grid.materials = std::move(plan.tables.materials);
  grid.texels = std::move(plan.tables.texels);
  // The image, every texel blank; status texels 0; the dirty-cell list empty
  if (compact) {
    // Compact: a one-texel image and an empty dirty list's header as stand-ins; the region's heads, empty;
    // the counts zero, room for the plan's count of static references
    grid.image = Image3D(glm::uvec3(1u), kBlank);
    grid.dirty = WordBuffer(shared::kWorkListHeaderWords, 0u);
    grid.spill_heads = plan::compact_heads(plan.region);
    const size_t refs = std::max<uint64_t>(plan.static_references, 1);
    grid.offsets.assign((g.flags & shared::kGridSparseOffsets) != 0u
                            ? shared::compact_offsets_words(shared::grid_cell_count(g), uint32_t(plan.static_cells))
                            : size_t(shared::grid_cell_count(g)) + 1,
                        0u);
    grid.refs.assign(refs, kBlank);
    grid.compact_counts.assign(shared::grid_cell_count(g), 0u);
    grid.compact_pairs.assign(2 * refs, 0u);
    grid.compact_scattered.assign(refs, kBlank);
    grid.compact_pair_count = 0u;
  } else {
    grid.image = Image3D(shared::grid_image_extent(g), kBlank);
    grid.dirty = WordBuffer(shared::dirty_list_words(g), 0u);
    run_invocations(g.cells.x * g.cells.y * g.cells.z, thread_count(o), std::nullopt, [&](uint32_t c) {
      const glm::uvec3 cell(c % g.cells.x, (c / g.cells.x) % g.cells.y, c / (g.cells.x * g.cells.y));
      imageStore(grid.image, glm::ivec3(shared::cell_status_texel(g, cell)), 0u);
    }, 4096);
  }
  // Static instances first (their references fill the first slots and are spilled first), then
  // the dynamic ones
  insert_instances(grid, scene, time, o, 0, grid.static_instances);
  grid.spill_header.static_count = grid.spill_header.count;
  spill_order(grid, o, 0);
  if (compact) {
    // The compact layout's offsets, scatter and order passes; then the temporaries go
    if (grid.compact_pair_count != plan.static_references)
      throw Error("compact build: " + std::to_string(grid.compact_pair_count) + " static references, the plan counted " +
                  std::to_string(plan.static_references));
    compact_offsets(grid, o);
    if ((g.flags & shared::kGridSparseOffsets) != 0u) {
      // The last word's base and mask: the occupied cells the index holds, the plan's count
      const uint32_t runs = shared::compact_runs_base(shared::grid_cell_count(g));
      const uint32_t occupied = grid.offsets[runs - 2u] + uint32_t(std::popcount(grid.offsets[runs - 1u]));
      if (occupied != plan.static_cells)
        throw Error("compact build: " + std::to_string(occupied) + " occupied cells, the plan counted " +
                    std::to_string(plan.static_cells));
    }
    compact_scatter(grid, o);
    compact_order(grid, o);
    // Freed, not just emptied (`= {}` keeps a vector's capacity): 4 bytes a cell and 12 a reference
    std::vector<uint32_t>().swap(grid.compact_counts);
    std::vector<uint32_t>().swap(grid.compact_pairs);
    std::vector<uint32_t>().swap(grid.compact_scattered);
  }
  // The skip field from the static references; the dynamic boxes at `time`
  if ((g.flags & shared::kGridSkipEmpty) != 0u) {
    grid.skip.assign(shared::skip_words(g), 0u);
    skip_field_build(grid, o);
    const std::vector<uint32_t> boxes = plan::skip_box_words(scene, time, g);
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
  if ((grid.params.flags & shared::kGridCompact) != 0u) {
    // Compact: no list; the cells the dynamic references reached are their spill entries' cells
    std::vector<uint32_t> out;
    std::vector<uint8_t> seen(shared::grid_cell_count(grid.params), 0u);
    const uint32_t stored = std::min(grid.spill_header.count, grid.spill_header.capacity);
    for (uint32_t i = grid.spill_header.static_count; i < stored; ++i)
      if (!seen[grid.spill[i].cell]++) out.push_back(grid.spill[i].cell);
    return out;
  }
  if (grid.dirty.size == 0) return {};
  const uint32_t n = grid.dirty.load(shared::kWorkListAppendedWord);
  std::vector<uint32_t> out(n);
  for (uint32_t k = 0; k < n; ++k) out[k] = grid.dirty.load(shared::kWorkListHeaderWords + k);
  return out;
}

void spill_grow(GridData& grid, uint32_t capacity) {
  if (capacity <= grid.spill_header.capacity) throw Error("reference build: the spill list grows, never shrinks");
  require_host_memory(uint64_t(capacity - grid.spill_header.capacity) * sizeof(shared::SpillEntry),
                      "reference update: a spill list of " + std::to_string(capacity) + " entries",
                      "set --spill-capacity");
  grid.spill.resize(capacity, shared::SpillEntry{0u, kBlank, shared::kSpillEnd, shared::kSpillEnd});
  grid.spill_header.capacity = capacity;
}

void scene_update(GridData& grid, const Scene& scene, float time, const GridOptions& o) {
  if (grid.static_instances == scene.instances.size()) return;
  if ((grid.params.flags & shared::kGridCompact) != 0u) clear_dynamic_spill(grid);
  else clear_dynamic_references(grid, o);
  if ((grid.params.flags & shared::kGridSkipEmpty) != 0u) {
    const std::vector<uint32_t> boxes = plan::skip_box_words(scene, time, grid.params);
    std::copy(boxes.begin(), boxes.end(), grid.skip.begin());
  }
  insert_instances(grid, scene, time, o, grid.static_instances, uint32_t(scene.instances.size()));
  spill_order(grid, o, grid.spill_header.static_count);
  // Gap-fill only while some cell is saturated
  grid.params.flags = trace_flags(grid.requested_flags, o, grid.spill_header.count);
}

}  // namespace gridrt::reference
