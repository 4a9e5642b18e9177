#version 460
// gather_scan.comp: the compute gather's tile lists between their count and their scatter
// (gather_pairs.comp), one workgroup of 256: the tiles' counts scanned in order, 2048 at a time
// (8 consecutive per invocation, a workgroup scan of their sums in shared memory). Each tile's
// start is written, and its count becomes the scatter's cursor (the start); the total is the
// frame's pairs. Pairs over the capacity: the fine pass gets no workgroup, the item pass
// (gather_raster.comp) keeps its dispatch and the resolve (gather_resolve.comp) gets its
// workgroups; else the fine pass one workgroup per tile (it resolves its pixels), the item pass and
// the resolve none.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "frame_common.glsl"

layout(local_size_x = 256) in;
layout(push_constant) uniform Push { GatherFinePush pc; };

shared uint64_t s_sum[256];  // 64 bits: no count can wrap the sums

void main() {
  const uint lid = gl_LocalInvocationID.x;
  uint64_t carry = 0ul;
  for (uint base = 0u; base < pc.tiles; base += 2048u) {
    // This invocation's 8 counts and their sum
    uint v[8];
    uint64_t sum = 0ul;
    for (uint j = 0u; j < 8u; ++j) {
      const uint i = base + 8u * lid + j;
      v[j] = i < pc.tiles ? tile_words[i] : 0u;
      sum += v[j];
    }
    // Inclusive scan of the sums (Hillis-Steele)
    s_sum[lid] = sum;
    barrier();
    for (uint d = 1u; d < 256u; d *= 2u) {
      const uint64_t add = lid >= d ? s_sum[lid - d] : 0ul;
      barrier();
      s_sum[lid] += add;
      barrier();
    }
    // Starts past the capacity are never read (the pairs overflowed: no scatter, no fine pass)
    uint64_t at = carry + s_sum[lid] - sum;
    for (uint j = 0u; j < 8u; ++j) {
      const uint i = base + 8u * lid + j;
      if (i < pc.tiles) {
        tile_words[pc.tiles + i] = uint(at);  // the start
        tile_words[i] = uint(at);             // the scatter's cursor
      }
      at += v[j];
    }
    carry += s_sum[255];
    barrier();  // s_sum is read before the next block rewrites it
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
