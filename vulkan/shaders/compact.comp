#version 460
// compact.comp: the compact layout's passes after the static count pass (reference/build.cpp,
// same names; docs/SPEC.md "Compact layout"), one pass per dispatch (push constant `pass`):
//   0 block sums    one invocation per block of kCompactBlock cells: the sum of its counts
//   1 block scan    one workgroup of kCompactScanLanes lanes: each lane sums its share of the
//                   blocks, lane 0 scans the lanes' sums, each lane writes its blocks' offsets
//   2 offsets       one invocation per block: its cells' offsets (exclusive), which also become the
//                   scatter's cursors; the last block writes offsets[cells], the total
//   3 scatter       one invocation per (cell, ref) pair: the reference into its cell's run at the
//                   cell's cursor (atomic add)
//   4 order         one invocation per pair: its rank in its cell's scattered run is its place in
//                   the ordered run (the references of a cell are distinct)
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 1024) in;  // kCompactScanLanes: pass 1 is one workgroup
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
layout(std430, binding = kGridBindCompactScattered) buffer CompactScattered { uint compact_scattered[]; };
layout(std430, binding = kGridBindCompactBlocks) buffer CompactBlocks { uint compact_blocks[]; };

shared uint lane_sum[kCompactScanLanes];

void main() {
  const GridParams g = grid_params();
  const uint cells = grid_cell_count(g);
  const uint blocks = (cells + kCompactBlock - 1u) / kCompactBlock;
  const uint pairs = min(compact_pair_count, uint(compact_pairs.length()) / 2u);
  const uint id = gl_GlobalInvocationID.x;
  if (pc.pass == 0u) {
    if (id >= blocks) return;
    uint sum = 0u;
    for (uint i = id * kCompactBlock; i < min(cells, (id + 1u) * kCompactBlock); ++i) sum += compact_counts[i];
    compact_blocks[id] = sum;
  } else if (pc.pass == 1u) {
    const uint l = gl_LocalInvocationID.x;
    const uint per_lane = (blocks + kCompactScanLanes - 1u) / kCompactScanLanes;
    uint sum = 0u;
    for (uint b = l * per_lane; b < min(blocks, (l + 1u) * per_lane); ++b) sum += compact_blocks[b];
    lane_sum[l] = sum;
    barrier();
    if (l == 0u) {
      uint running = 0u;
      for (uint k = 0u; k < kCompactScanLanes; ++k) {
        const uint s = lane_sum[k];
        lane_sum[k] = running;
        running += s;
      }
    }
    barrier();
    uint r = lane_sum[l];
    for (uint b = l * per_lane; b < min(blocks, (l + 1u) * per_lane); ++b) {
      const uint s = compact_blocks[b];
      compact_blocks[b] = r;
      r += s;
    }
  } else if (pc.pass == 2u) {
    if (id >= blocks) return;
    uint r = compact_blocks[id];
    const uint end = min(cells, (id + 1u) * kCompactBlock);
    for (uint i = id * kCompactBlock; i < end; ++i) {
      const uint n = compact_counts[i];
      compact_offsets[i] = r;
      compact_counts[i] = r;  // the scatter's cursor
      r += n;
    }
    if (end == cells) compact_offsets[cells] = r;
  } else if (pc.pass == 3u) {
    if (id >= pairs) return;
    const uint c = compact_pairs[2u * id];
    const uint ref = compact_pairs[2u * id + 1u];
    const uint at = atomicAdd(compact_counts[c], 1u);
    compact_scattered[at] = ref;
  } else {
    if (id >= pairs) return;
    const uint c = compact_pairs[2u * id];
    const uint ref = compact_pairs[2u * id + 1u];
    const uint begin = compact_offsets[c];
    const uint end = compact_offsets[c + 1u];
    uint rank = 0u;
    for (uint j = begin; j < end; ++j) rank += compact_scattered[j] < ref ? 1u : 0u;
    compact_refs[begin + rank] = ref;
  }
}
