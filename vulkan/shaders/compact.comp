#version 460
// compact.comp: the compact layout's passes after the static count pass (reference/build.cpp,
// same names; docs/SPEC.md "Compact layout"), one pass per dispatch (push constant `pass`). The
// arrays they leave (offsets, refs) are the reference's in every bit; the work is organized for a
// GPU (coalesced loads, no invocation walking a block alone), not as the reference's loops. The
// scans are of pairs (references, occupied cells):
//   0 group sums    one workgroup per group of kCompactScanLanes cells, a lane per cell
//                   (coalesced): the group's sums (a workgroup scan in shared memory)
//   1 group scan    one workgroup: the groups' sums scanned kCompactScanLanes at a time
//                   (coalesced; a workgroup scan per chunk, the running totals carried)
//   2 offsets       one workgroup per group, a lane per cell: its cursor (the exclusive sum of
//                   the references before it), also its dense offset (the last cell's lane writes
//                   offsets[cells], the total); with kGridSparseOffsets instead an occupied cell's lane writes it as its run's
//                   start at its place among the occupied cells; the first lane of each word of 32
//                   cells writes the word's base and mask (the mask's bits gathered in shared
//                   memory); the last cell's lane writes the total after the last start
//   3 scatter       one invocation per (cell, ref) pair: the reference into its cell's run at the
//                   cell's cursor (atomic add), and the cell beside it (second half of the buffer)
//   4 order         one invocation per scattered position: its rank in its cell's run is its place
//                   in the ordered run (the references of a cell are distinct). Adjacent lanes take
//                   adjacent positions, mostly of one cell: the run's loads are shared (broadcast)
//                   and the lanes' trip counts agree, where a lane per pair (in the count pass's
//                   order) would walk a different cell's run than its neighbours.
// Integer sums: the bits are the reference's whatever the order of the additions.
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 1024) in;  // kCompactScanLanes
layout(push_constant) uniform Push { CompactPush pc; };
layout(std430, binding = kGridBindOffsets) buffer Offsets { uint compact_offsets[]; };
layout(std430, binding = kGridBindRefs) buffer Refs { uint compact_refs[]; };
layout(std430, binding = kGridBindCompactCounts) buffer CompactCounts { uint compact_counts[]; };
layout(std430, binding = kGridBindCompactPairs) buffer CompactPairs {
  uint compact_pair_count;
  uint compact_pairs_pad0;
  uint compact_pairs_pad1;
  uint compact_pairs_pad2;
  uint compact_pairs[];
};
// The scattered references [0, capacity), then each one's cell [capacity, 2 capacity)
layout(std430, binding = kGridBindCompactScattered) buffer CompactScattered { uint compact_scattered[]; };
layout(std430, binding = kGridBindCompactBlocks) buffer CompactBlocks { uint compact_blocks[]; };

shared uvec2 scan_lanes[kCompactScanLanes];
shared uint word_masks[kCompactScanLanes / 32u];

// The workgroup's inclusive scan of `v` (lane order), Hillis-Steele in shared memory; `total` is
// the sum over the workgroup. Every lane calls it (barriers).
uvec2 workgroup_inclusive_scan(uvec2 v, out uvec2 total) {
  const uint l = gl_LocalInvocationID.x;
  scan_lanes[l] = v;
  barrier();
  for (uint d = 1u; d < kCompactScanLanes; d *= 2u) {
    const uvec2 t = l >= d ? scan_lanes[l - d] : uvec2(0u);
    barrier();
    v += t;
    scan_lanes[l] = v;
    barrier();
  }
  total = scan_lanes[kCompactScanLanes - 1u];
  barrier();  // every lane has read the total before the array is written again
  return v;
}

// A cell's run in the ordered references, through the index of occupied cells (the reference's
// compact_run): [begin, end), empty for a cell that holds none
uvec2 compact_run(GridParams g, uint cells, uint i) {
  if ((g.flags & kGridSparseOffsets) == 0u) return uvec2(compact_offsets[i], compact_offsets[i + 1u]);
  const uint mask = compact_offsets[compact_mask_index(i)];
  if (!compact_occupied(mask, i)) return uvec2(0u);
  const uint k = compact_run_index(cells, compact_offsets[compact_base_index(i)], mask, i);
  if (k + 1u >= uint(compact_offsets.length())) return uvec2(0u);  // more occupied cells than the plan's (the host fails the build)
  return uvec2(compact_offsets[k], compact_offsets[k + 1u]);
}

void main() {
  const GridParams g = grid_params();
  const uint cells = grid_cell_count(g);
  const uint groups = (cells + kCompactScanLanes - 1u) / kCompactScanLanes;
  const uint pairs = min(compact_pair_count, uint(compact_pairs.length()) / 2u);
  const uint capacity = uint(compact_scattered.length()) / 2u;
  const uint words = uint(compact_offsets.length());
  const uint l = gl_LocalInvocationID.x;
  const uint id = gl_GlobalInvocationID.x;
  if (pc.pass == 0u) {
    const uint n = id < cells ? compact_counts[id] : 0u;
    uvec2 total;
    workgroup_inclusive_scan(uvec2(n, n != 0u ? 1u : 0u), total);
    if (l == 0u) {
      compact_blocks[2u * gl_WorkGroupID.x] = total.x;
      compact_blocks[2u * gl_WorkGroupID.x + 1u] = total.y;
    }
  } else if (pc.pass == 1u) {
    uvec2 carry = uvec2(0u);
    for (uint base = 0u; base < groups; base += kCompactScanLanes) {
      const uvec2 s = base + l < groups ? uvec2(compact_blocks[2u * (base + l)], compact_blocks[2u * (base + l) + 1u])
                                        : uvec2(0u);
      uvec2 total;
      const uvec2 incl = workgroup_inclusive_scan(s, total);
      if (base + l < groups) {
        const uvec2 e = carry + incl - s;
        compact_blocks[2u * (base + l)] = e.x;
        compact_blocks[2u * (base + l) + 1u] = e.y;
      }
      carry += total;
    }
  } else if (pc.pass == 2u) {
    const uint n = id < cells ? compact_counts[id] : 0u;
    const uvec2 v = uvec2(n, n != 0u ? 1u : 0u);
    uvec2 total;
    const uvec2 incl = workgroup_inclusive_scan(v, total);
    if (l < kCompactScanLanes / 32u) word_masks[l] = 0u;
    barrier();
    if (n != 0u) atomicOr(word_masks[l / 32u], 1u << (l % 32u));
    barrier();
    if (id >= cells) return;
    const uvec2 r = uvec2(compact_blocks[2u * gl_WorkGroupID.x], compact_blocks[2u * gl_WorkGroupID.x + 1u]) + incl - v;
    if ((g.flags & kGridSparseOffsets) == 0u) {  // dense: the cursor is the cell's offset
      compact_offsets[id] = r.x;
      compact_counts[id] = r.x;
      if (id + 1u == cells) compact_offsets[cells] = r.x + n;
      return;
    }
    const uint runs = compact_runs_base(cells);
    compact_counts[id] = r.x;  // the scatter's cursor
    if (id % 32u == 0u) {  // kCompactScanLanes is whole words: the group's lane l % 32 == id % 32
      compact_offsets[compact_base_index(id)] = r.y;
      compact_offsets[compact_mask_index(id)] = word_masks[l / 32u];
    }
    if (n != 0u && runs + r.y < words) compact_offsets[runs + r.y] = r.x;
    if (id + 1u == cells && runs + r.y + v.y < words) compact_offsets[runs + r.y + v.y] = r.x + n;  // the total
  } else if (pc.pass == 3u) {
    if (id >= pairs) return;
    const uint c = compact_pairs[2u * id];
    const uint ref = compact_pairs[2u * id + 1u];
    const uint at = atomicAdd(compact_counts[c], 1u);
    if (at >= capacity) return;  // more references than the plan's (the host fails the build)
    compact_scattered[at] = ref;
    compact_scattered[capacity + at] = c;
  } else {
    if (id >= pairs) return;
    const uint ref = compact_scattered[id];
    const uint c = compact_scattered[capacity + id];
    const uvec2 run = compact_run(g, cells, c);
    const uint begin = run.x;
    const uint end = min(run.y, capacity);
    uint rank = 0u;
    for (uint j = begin; j < end; ++j) rank += compact_scattered[j] < ref ? 1u : 0u;
    compact_refs[begin + rank] = ref;
  }
}
