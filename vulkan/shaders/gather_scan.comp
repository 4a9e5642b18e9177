#version 460
// gather_scan.comp: the compute gather's tile lists between their count and their scatter
// (gather_pairs.comp): each tile's start, the sum of the counts of the tiles before it, in blocks
// of kGatherScanBlock tiles. Up to kGatherScanMaxGroups workgroups of 256, each a run of
// consecutive blocks: it first sums every count before its run (read again by each workgroup:
// no workgroup waits for another), then scans its blocks in order. A block's counts go through
// shared memory (read and written in whole rows of the buffer, 256 consecutive words an
// instruction); each invocation sums 16 consecutive counts there, the sums are scanned by
// subgroup arithmetic, then across the subgroups. The counts stay (the scatter counts them
// down). The workgroup with the last tile writes the frame's pairs and whether they overflowed:
// pairs over the capacity, the item pass (gather_raster.comp) keeps its dispatch and the fine
// pass reads no list (it only resolves what the item pass left); else the item pass gets none.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "frame_common.glsl"

layout(local_size_x = 256) in;
layout(push_constant) uniform Push { GatherFinePush pc; };

const uint kScanPerInvocation = kGatherScanBlock / 256u;  // 16
// The block's counts, then their starts; a word of padding every 32 (an invocation's 16
// consecutive words fall in different banks from its neighbours')
shared uint s_words[kGatherScanBlock + kGatherScanBlock / 32u];
shared uint64_t s_sum[256];  // 64 bits: nothing wraps

uint padded(uint i) { return i + i / 32u; }

// The inclusive scan of x over the subgroup, exact in 64 bits with 32-bit subgroup arithmetic:
// x < 2^36 (16 counts) split into its low 16 bits and the rest (below 2^20); with at most 128
// invocations a subgroup their scans stay below 2^23 and 2^27: neither wraps.
uint64_t subgroup_inclusive_add64(uint64_t x) {
  const uint lo = subgroupInclusiveAdd(uint(x & 0xFFFFul));
  const uint hi = subgroupInclusiveAdd(uint(x >> 16));
  return (uint64_t(hi) << 16) + uint64_t(lo);
}

void main() {
  const uint lid = gl_LocalInvocationID.x;
  const uint blocks = (pc.tiles + kGatherScanBlock - 1u) / kGatherScanBlock;
  const uint run = (blocks + gl_NumWorkGroups.x - 1u) / gl_NumWorkGroups.x;
  const uint first = min(pc.tiles, gl_WorkGroupID.x * run * kGatherScanBlock);
  const uint last = min(pc.tiles, first + run * kGatherScanBlock);
  if (first == last) return;  // no block (the same for the whole workgroup)
  // The counts before the run: per invocation, then a tree in shared memory
  uint64_t carry = 0ul;
  for (uint i = lid; i < first; i += 256u) carry += tile_words[i];
  s_sum[lid] = carry;
  barrier();
  for (uint d = 128u; d > 0u; d /= 2u) {
    if (lid < d) s_sum[lid] += s_sum[lid + d];
    barrier();
  }
  carry = s_sum[0];
  barrier();  // s_sum[0] is read before the blocks rewrite it
  for (uint base = first; base < last; base += kGatherScanBlock) {
    // The block's counts, row by row (zero past the run)
    for (uint r = 0u; r < kScanPerInvocation; ++r) {
      const uint i = r * 256u + lid;
      s_words[padded(i)] = base + i < last ? tile_words[base + i] : 0u;
    }
    barrier();
    // This invocation's 16 consecutive counts and their sum (below 16 * 2^32)
    uint v[kScanPerInvocation];
    uint64_t sum = 0ul;
    for (uint j = 0u; j < kScanPerInvocation; ++j) {
      v[j] = s_words[padded(kScanPerInvocation * lid + j)];
      sum += v[j];
    }
    // Inclusive scan of the sums: within the subgroup, then the subgroups before this one
    const uint64_t inclusive = subgroup_inclusive_add64(sum);
    if (gl_SubgroupInvocationID == gl_SubgroupSize - 1u) s_sum[gl_SubgroupID] = inclusive;
    barrier();
    uint64_t at = carry;
    for (uint s = 0u; s < gl_SubgroupID; ++s) at += s_sum[s];
    const uint64_t block_end = at + inclusive;  // on the last invocation: the carry of the next block
    // The starts, in place of the counts in shared memory (past the capacity they are never read:
    // the pairs overflowed, no scatter, no fine pass)
    at += inclusive - sum;
    for (uint j = 0u; j < kScanPerInvocation; ++j) {
      s_words[padded(kScanPerInvocation * lid + j)] = uint(at);
      at += v[j];
    }
    barrier();
    if (lid == 255u) s_sum[0] = block_end;
    for (uint r = 0u; r < kScanPerInvocation; ++r) {
      const uint i = r * 256u + lid;
      if (base + i < last) tile_words[pc.tiles + base + i] = s_words[padded(i)];
    }
    barrier();
    carry = s_sum[0];
    barrier();  // shared memory is read before the next block rewrites it
  }
  if (lid == 0u && last == pc.tiles) {
    const bool overflow = carry > uint64_t(pc.capacity);
    fine_header.pairs = uint(min(carry, uint64_t(0xFFFFFFFFu)));
    fine_header.overflow = overflow ? 1u : 0u;
    if (!overflow) tile_header.groups_x = 0u;
  }
}
