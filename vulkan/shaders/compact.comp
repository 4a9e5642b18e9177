#version 460
// compact.comp: the compact layout's passes after the static count pass (reference/build.cpp,
// same names; docs/SPEC.md "Compact layout"), one pass per dispatch (push constant `pass`). The
// arrays they leave (offsets, refs) are the reference's in every bit; the work is organized for a
// GPU (coalesced loads, no invocation walking a block alone), not as the reference's loops:
//   0 group sums    one workgroup per group of kCompactScanLanes cells, a lane per cell
//                   (coalesced): the group's sum (a workgroup scan in shared memory)
//   1 group scan    one workgroup: the groups' sums scanned kCompactScanLanes at a time
//                   (coalesced; a workgroup scan per chunk, the running total carried)
//   2 offsets       one workgroup per group, a lane per cell: its offset (exclusive: the group's
//                   offset plus the workgroup scan), which also becomes the scatter's cursor; the
//                   last cell's lane writes offsets[cells], the total
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

shared uint scan_lanes[kCompactScanLanes];

// The workgroup's inclusive scan of `v` (lane order), Hillis-Steele in shared memory; `total` is
// the sum over the workgroup. Every lane calls it (barriers).
uint workgroup_inclusive_scan(uint v, out uint total) {
  const uint l = gl_LocalInvocationID.x;
  scan_lanes[l] = v;
  barrier();
  for (uint d = 1u; d < kCompactScanLanes; d *= 2u) {
    const uint t = l >= d ? scan_lanes[l - d] : 0u;
    barrier();
    v += t;
    scan_lanes[l] = v;
    barrier();
  }
  total = scan_lanes[kCompactScanLanes - 1u];
  barrier();  // every lane has read the total before the array is written again
  return v;
}

void main() {
  const GridParams g = grid_params();
  const uint cells = grid_cell_count(g);
  const uint groups = (cells + kCompactScanLanes - 1u) / kCompactScanLanes;
  const uint pairs = min(compact_pair_count, uint(compact_pairs.length()) / 2u);
  const uint capacity = uint(compact_scattered.length()) / 2u;
  const uint l = gl_LocalInvocationID.x;
  const uint id = gl_GlobalInvocationID.x;
  if (pc.pass == 0u) {
    const uint n = id < cells ? compact_counts[id] : 0u;
    uint total;
    workgroup_inclusive_scan(n, total);
    if (l == 0u) compact_blocks[gl_WorkGroupID.x] = total;
  } else if (pc.pass == 1u) {
    uint carry = 0u;
    for (uint base = 0u; base < groups; base += kCompactScanLanes) {
      const uint s = base + l < groups ? compact_blocks[base + l] : 0u;
      uint total;
      const uint incl = workgroup_inclusive_scan(s, total);
      if (base + l < groups) compact_blocks[base + l] = carry + incl - s;
      carry += total;
    }
  } else if (pc.pass == 2u) {
    const uint n = id < cells ? compact_counts[id] : 0u;
    uint total;
    const uint incl = workgroup_inclusive_scan(n, total);
    if (id >= cells) return;
    const uint r = compact_blocks[gl_WorkGroupID.x] + incl - n;
    compact_offsets[id] = r;
    compact_counts[id] = r;  // the scatter's cursor
    if (id + 1u == cells) compact_offsets[cells] = r + n;
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
    const uint begin = compact_offsets[c];
    const uint end = min(compact_offsets[c + 1u], capacity);
    uint rank = 0u;
    for (uint j = begin; j < end; ++j) rank += compact_scattered[j] < ref ? 1u : 0u;
    compact_refs[begin + rank] = ref;
  }
}
