#version 460
// gather_scan.comp: the compute gather's tile lists between their count and their scatter
// (gather_pairs.comp), one workgroup of 256: the tiles' counts scanned in order, 4096 at a time.
// A block's counts go through shared memory (read and written in whole rows of the buffer: one
// invocation a word, 256 consecutive words an instruction; each invocation's 16 consecutive
// counts are summed there, the sums scanned by subgroup arithmetic, then across the subgroups).
// Each tile's start is written, and its count becomes the scatter's cursor (the start); the total
// is the frame's pairs. Pairs over the capacity: the fine pass gets no workgroup, the item pass
// (gather_raster.comp) keeps its dispatch and the resolve (gather_resolve.comp) gets its
// workgroups; else the fine pass one workgroup per tile (it resolves its pixels), the item pass
// and the resolve none.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "frame_common.glsl"

layout(local_size_x = 256) in;
layout(push_constant) uniform Push { GatherFinePush pc; };

const uint kScanPerInvocation = 16u;
const uint kScanBlock = 256u * kScanPerInvocation;
// The block's counts, then their starts; a word of padding every 32 (an invocation's 16
// consecutive words fall in different banks from its neighbours')
shared uint s_words[kScanBlock + kScanBlock / 32u];
shared uint64_t s_subgroup_sum[256];  // per subgroup of the block, its sum (64 bits: nothing wraps)
shared uint64_t s_block_sum;

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
  uint64_t carry = 0ul;
  for (uint base = 0u; base < pc.tiles; base += kScanBlock) {
    // The block's counts, row by row (zero past the last tile)
    for (uint r = 0u; r < kScanPerInvocation; ++r) {
      const uint i = r * 256u + lid;
      s_words[padded(i)] = base + i < pc.tiles ? tile_words[base + i] : 0u;
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
    if (gl_SubgroupInvocationID == gl_SubgroupSize - 1u) s_subgroup_sum[gl_SubgroupID] = inclusive;
    barrier();
    uint64_t at = carry;
    for (uint s = 0u; s < gl_SubgroupID; ++s) at += s_subgroup_sum[s];
    if (lid == 255u) s_block_sum = at + inclusive;
    // The starts, in place of the counts (past the capacity they are never read: the pairs
    // overflowed, no scatter, no fine pass)
    at += inclusive - sum;
    for (uint j = 0u; j < kScanPerInvocation; ++j) {
      s_words[padded(kScanPerInvocation * lid + j)] = uint(at);
      at += v[j];
    }
    barrier();
    // Row by row: the start, and the scatter's cursor
    for (uint r = 0u; r < kScanPerInvocation; ++r) {
      const uint i = r * 256u + lid;
      if (base + i < pc.tiles) {
        const uint start = s_words[padded(i)];
        tile_words[pc.tiles + base + i] = start;
        tile_words[base + i] = start;
      }
    }
    carry = s_block_sum;
    barrier();  // shared memory is read before the next block rewrites it
  }
  if (lid == 0u) {
    const bool overflow = carry > uint64_t(pc.capacity);
    const uvec3 groups = overflow ? uvec3(0u, 1u, 1u) : work_list_groups(pc.tiles, 1u, pc.max_groups_x);
    fine_header.groups_x = groups.x;
    fine_header.groups_y = groups.y;
    fine_header.groups_z = groups.z;
    fine_header.pairs = uint(min(carry, uint64_t(0xFFFFFFFFu)));
    fine_header.overflow = overflow ? 1u : 0u;
    if (!overflow) tile_header.groups_x = 0u;
    const CameraParams c = fp.camera;
    fine_header.resolve_x = overflow ? (c.width + 7u) / 8u : 0u;
    fine_header.resolve_y = (c.height + 7u) / 8u;
    fine_header.resolve_z = 1u;
  }
}
