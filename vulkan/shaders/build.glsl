// build.glsl: scene build (paper 2.1), the body of one build invocation, shared by the geometry
// shader of the raster pass (build.geom) and the compute build (build.comp). Same names and
// heading comments as reference/build.cpp.
#ifndef GRIDRT_BUILD_GLSL
#define GRIDRT_BUILD_GLSL

#include "grid_common.glsl"

layout(binding = kGridBindImage, r32ui) uniform coherent uimage3D grid_image;
// The spill list (kGridSpill; the counter always) and its per-cell heads
layout(std430, binding = kGridBindSpill) buffer Spill {
  SpillHeader spill_header;
  SpillEntry spill_entries[];
};
layout(std430, binding = kGridBindSpillHeads) buffer SpillHeads { uint spill_heads[]; };

// A reference no slot of `cell` took: counted, and with kGridSpill stored as (cell, ref) in the
// entry the counter gave it and pushed onto the arrival list of the cell's static or dynamic
// references (one exchange of the head: no loop, no order), while the list has room (past its
// capacity it is lost: the count says how many). The order pass links it in ascending order.
void spill_reference(GridParams g, uvec3 cell, uint ref) {
  const uint i = atomicAdd(spill_header.count, 1u);
  if ((g.flags & kGridSpill) == 0u || i >= spill_header.capacity) return;
  const uint c = cell_linear_index(g, cell);
  spill_entries[i].cell = c;
  spill_entries[i].ref = ref;
  uint arrival = spill_arrival_index(c, ref >= g.comparison_offset);
  if ((g.flags & kGridCompact) != 0u) {
    // Compact: the heads of the dynamic region's cells (no reference reaches a cell outside it:
    // the region bounds the dynamic instances' swept bounds with a cell of margin)
    const uvec3 lo = uvec3(spill_heads[0], spill_heads[1], spill_heads[2]);
    const uvec3 hi = uvec3(spill_heads[4], spill_heads[5], spill_heads[6]);
    if (!region_contains(cell, lo, hi)) return;
    arrival = compact_arrival_index(region_index(cell, lo, hi));
  }
  spill_entries[i].arrival = atomicExchange(spill_heads[arrival], i);
}

// ---- The compact layout (kGridCompact; docs/SPEC.md "Compact layout") ----
layout(std430, binding = kGridBindCompactCounts) buffer CompactCounts { uint compact_counts[]; };
layout(std430, binding = kGridBindCompactPairs) buffer CompactPairs {
  uint compact_pair_count;
  uint compact_pairs_pad0;
  uint compact_pairs_pad1;
  uint compact_pairs_pad2;
  uint compact_pairs[];
};

// The count pass (the static pass's insertion): the cell's count, and the (cell, ref) pair at the
// next index of the pair list (its capacity is the plan's count of the static references). The
// compute build (GRIDRT_BUILD_SUBGROUP) takes the indices of the lanes counting together with one
// atomic add of the subgroup on the shared counter (its lowest lane's), each lane its rank among
// them: the same set of indices as one add per pair, without millions of adds on one address.
void compact_count(GridParams g, uvec3 cell, uint ref) {
  const uint c = cell_linear_index(g, cell);
  atomicAdd(compact_counts[c], 1u);
#ifdef GRIDRT_BUILD_SUBGROUP
  const uvec4 lanes = subgroupBallot(true);
  uint first = 0u;
  if (subgroupElect()) first = atomicAdd(compact_pair_count, subgroupBallotBitCount(lanes));
  const uint k = subgroupBroadcastFirst(first) + subgroupBallotExclusiveBitCount(lanes);
#else
  const uint k = atomicAdd(compact_pair_count, 1u);
#endif
  if (2u * k + 1u < uint(compact_pairs.length())) {
    compact_pairs[2u * k] = c;
    compact_pairs[2u * k + 1u] = ref;
  }
}

// The dirty-cell list (common/shared/worklist.h, grid.h): header, items, listed bits.
layout(std430, binding = kGridBindDirty) buffer Dirty {
  WorkListHeader dirty_header;
  uint dirty_items[];
};

// The first slot of `cell` holding a value >= `bound`, where the slots holding smaller values are
// a prefix that stays one through the pass (docs/SPEC.md, "Insert"): during a pass a slot's value
// only decreases (atomic min) or leaves blank once (compare-and-swap), the cells stay sorted
// (sorted insertion) or filled from slot 0 without gaps (first-empty), and static references
// precede dynamic ones; so a slot seen below `bound` stays below it, with every slot before it,
// whatever other invocations do meanwhile. Plain loads, galloping (slots 0, 2, 6, 14, ...) then
// halving: about 2 log2(n) loads for n references, where a walk from slot 0 costs n. A stale load
// (one that misses another invocation's atomic in this pass) sees a value at least the slot's
// current one, so it can only stop the search early, and the atomics from there pass the smaller
// slots unchanged: the image is the same, `coherent` (the image's) only saves those atomics.
bool slot_below(GridParams g, uvec3 cell, uint s, uint bound) {
  return imageLoad(grid_image, ivec3(cell_slot_texel(g, cell, s))).x < bound;
}

uint first_slot_at_least(GridParams g, uvec3 cell, uint bound) {
  // Gallop until a slot that is not below the bound
  uint lo = 0u;
  uint hi = g.capacity;
  for (uint span = 1u; lo < hi; span *= 2u) {
    const uint probe = min(lo + span - 1u, hi - 1u);
    if (!slot_below(g, cell, probe, bound)) {
      hi = probe;
      break;
    }
    lo = probe + 1u;
  }
  // Halve [lo, hi): the slots before lo are below the bound, slot hi (if any) is not
  while (lo < hi) {
    const uint mid = (lo + hi) / 2u;
    if (slot_below(g, cell, mid, bound)) lo = mid + 1u;
    else hi = mid;
  }
  return lo;
}

// Paper: compare-and-swap blank -> ref into the first slot that takes it; when none does, flag
// the cell saturated (static or dynamic bit by the reference's kind) and spill the reference.
void insert_first_empty(GridParams g, uvec3 cell, uint ref) {
  // The filled slots would refuse the reference: start at the first blank
  for (uint s = first_slot_at_least(g, cell, kBlank); s < g.capacity; ++s) {
    const uint old = imageAtomicCompSwap(grid_image, ivec3(cell_slot_texel(g, cell, s)), kBlank, ref);
    if (old == kBlank) return;
  }
  // Saturated: no slot took the reference
  const uint bit = ref < g.comparison_offset ? kStatusStatic : kStatusDynamic;
  imageAtomicOr(grid_image, ivec3(cell_status_texel(g, cell)), bit);
  spill_reference(g, cell, ref);
}

// Ours: an atomic-min cascade. The carried value v takes the smaller of itself and each slot in
// turn (old = atomicMin(slot, v); v = max(old, v)) until it is blank; the cell ends holding its
// `capacity` smallest references in ascending order whatever the timing. A value pushed out of
// the last slot is dropped: it flags the cell (static bit if it is static, else dynamic) and is
// spilled.
void insert_sorted(GridParams g, uvec3 cell, uint ref) {
  uint v = ref;
  // The slots holding smaller references would pass v on unchanged: start after them
  for (uint s = first_slot_at_least(g, cell, ref); s < g.capacity; ++s) {
    const uint old = imageAtomicMin(grid_image, ivec3(cell_slot_texel(g, cell, s)), v);
    v = max(old, v);
    if (v == kBlank) return;
  }
  // Saturated: the dropped value names the bit
  const uint bit = v < g.comparison_offset ? kStatusStatic : kStatusDynamic;
  imageAtomicOr(grid_image, ivec3(cell_status_texel(g, cell)), bit);
  spill_reference(g, cell, v);
}

// The dirty-cell list (scene update): the first dynamic reference to reach a cell in a pass sets
// the cell's listed bit and appends the cell, so the list holds every cell a dynamic reference
// reached (stored or dropped), once.
void append_dirty_cell(GridParams g, uvec3 cell) {
  const uint i = cell_linear_index(g, cell);
  const uint old = atomicOr(dirty_items[dirty_bit_item(g, i)], dirty_bit(i));
  if ((old & dirty_bit(i)) != 0u) return;
  const uint k = atomicAdd(dirty_header.appended, 1u);
  dirty_items[k] = i;
}

// The compute build's runs (build.comp, build_cells.comp): a triangle whose AABB range holds more
// than kBuildRun cells leaves them to other invocations, kBuildRun cells each, through this work
// list of (reference, run) pairs, so that no invocation walks thousands of cells alone (the
// build's longest chain of dependent atomics, docs/BENCHMARKS.md). Same cells, same insertions.
const uint kBuildRun = 8u;
layout(std430, binding = kGridBindBuildList) buffer BuildList {
  WorkListHeader build_header;
  uint build_items[];
};

// Insert the reference into the cells [first, last) of the range lo..hi (x fastest) that the cell
// test keeps (triangle_overlaps_cell).
void insert_range_cells(GridParams g, uint ref, vec3 v0, vec3 v1, vec3 v2, vec3 n, uvec3 lo, uvec3 hi,
                        uint first, uint last) {
  const uvec3 size = hi - lo + 1u;
  for (uint i = first; i < last; ++i) {
    const uvec3 cell = lo + uvec3(i % size.x, (i / size.x) % size.y, i / (size.x * size.y));
    if (!triangle_overlaps_cell(g, v0, v1, v2, n, cell)) continue;
    if ((g.flags & kGridCompact) != 0u) {
      // Compact: a static reference is counted (and its pair kept) for the offsets; a dynamic one
      // goes to its cell's dynamic spill list
      if (ref < g.comparison_offset) compact_count(g, cell, ref);
      else spill_reference(g, cell, ref);
      continue;
    }
    if (ref >= g.comparison_offset) append_dirty_cell(g, cell);
    if (g.insertion == kInsertSorted) insert_sorted(g, cell, ref);
    else insert_first_empty(g, cell, ref);
  }
}

// One build invocation: write the world-space triangle to the geometry buffer and its plane to
// the plane buffer, insert its
// reference into every cell of its AABB range that the cell test keeps (`split`: the compute build hands ranges of more than kBuildRun cells out in runs).
void build_invocation(uint instance, uint triangle, vec3 v0, vec3 v1, vec3 v2, bool split) {
  const GridParams g = grid_params();
  // Write the world-space triangle (the material was written by the host)
  const uint k = instances[instance].tri_offset + triangle;
  triangles[k].v0 = v0;
  triangles[k].v1 = v1;
  triangles[k].v2 = v2;
  // Its plane, for the watertight test (the plane buffer; zero-area triangles too: one rule)
  planes[k] = triangle_plane(v0, v1, v2);
  // Skip zero-area triangles: no ray can hit them
  if (triangle_zero_area(v0, v1, v2)) return;
  const vec3 n = triangle_normal(v0, v1, v2);
  // Cells of the AABB range that the cell test keeps
  uvec3 lo;
  uvec3 hi;
  triangle_cell_range(g, v0, v1, v2, lo, hi);
  const uint ref = ref_pack(instance, triangle);
  const uvec3 size = hi - lo + 1u;
  const uint count = size.x * size.y * size.z;
  uint walked = 0u;
  if (split && count > kBuildRun) {
    // Long range: runs of kBuildRun cells for build_cells.comp, as many as the list has room for;
    // the runs past a full list are walked here. Every item below the list's size (the appended
    // count, at most the capacity) is so written: build_cells.comp reads no stale item.
    const uint runs = (count + kBuildRun - 1u) / kBuildRun;
    const uint capacity = uint(build_items.length()) / 2u;
#ifdef GRIDRT_BUILD_SUBGROUP
    // The subgroup's lanes here take their runs with one atomic add of their sum (the lowest
    // lane's), each lane after the lanes below it: the same as one add each in that order
    uint base = 0u;
    const uint total = subgroupAdd(runs);
    if (subgroupElect()) base = atomicAdd(build_header.appended, total);
    const uint first = subgroupBroadcastFirst(base) + subgroupExclusiveAdd(runs);
#else
    const uint first = atomicAdd(build_header.appended, runs);
#endif
    const uint listed = first < capacity ? min(runs, capacity - first) : 0u;
    for (uint r = 0u; r < listed; ++r) {
      build_items[2u * (first + r)] = ref;
      build_items[2u * (first + r) + 1u] = r;
    }
    if (listed == runs) return;
    walked = listed * kBuildRun;
  }
  insert_range_cells(g, ref, v0, v1, v2, n, lo, hi, walked, count);
}

#endif
