#version 460
// gather_bin.comp: the compute gather's first pass (gather_visibility.glsl), one invocation per
// triangle of the geometry buffer: its screen box; a box of at most 16 pixels is tested here, a
// larger one appended to the list of large triangles with its count of 8x8-pixel tiles (one 64-bit
// atomic per subgroup gives each its list index and its first tile; gather_tiles.comp finds a
// tile's triangle by binary search, so no invocation writes its tiles one by one).
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "gather_visibility.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = kFrameBindGatherKeys) buffer GatherKeys64 { uint64_t gather_keys64[]; };
layout(std430, binding = kFrameBindTileList) buffer TileCounter {
  uint tile_counter_header[6];
  uint64_t tile_counter;  // GatherTileHeader::counter_lo, counter_hi
};
layout(push_constant) uniform Push { GatherBinPush pc; };

void main() {
  const CameraParams c = fp.camera;
  const uint k = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 64u, gl_LocalInvocationID.x);
  uint tiles = 0u;
  uint ref = kNoRef;
  uvec4 box = uvec4(0u);
  bool here = false;  // a small box, tested by this invocation
  GridTriangle tri;
  if (k < pc.triangle_count) {
    const uint instance = gather_instance_of(k, pc.instance_count);
    ref = ref_pack(instance, k - instances[instance].tri_offset);
    tri = triangles[k];
    // Zero-area triangles are never hit (the grid does not insert them)
    const vec3 n = triangle_normal(tri.v0, tri.v1, tri.v2);
    if (sh_dot(n, n) != 0.0f && gather_box(c, fp.near_plane, tri.v0, tri.v1, tri.v2, box)) {
      here = (box.z - box.x + 1u) * (box.w - box.y + 1u) <= 16u;
      if (!here) tiles = ((box.z - box.x) / 8u + 1u) * ((box.w - box.y) / 8u + 1u);
    }
  }
  // Append the large triangles: one 64-bit atomic per subgroup (triangles high, tiles low)
  const uint large = tiles != 0u ? 1u : 0u;
  const uint total_tiles = subgroupAdd(tiles), total_large = subgroupAdd(large);
  const uint tiles_before = subgroupExclusiveAdd(tiles), large_before = subgroupExclusiveAdd(large);
  uvec2 base = uvec2(0u);
  if (subgroupElect() && total_large != 0u)
    base = unpackUint2x32(atomicAdd(tile_counter, packUint2x32(uvec2(total_tiles, total_large))));
  base = subgroupBroadcastFirst(base);
  if (large != 0u) {
    const uint j = base.y + large_before;
    tile_items[4u * j] = ref;
    tile_items[4u * j + 1u] = base.x + tiles_before;
    tile_items[4u * j + 2u] = box.x | (box.y << 16u);
    tile_items[4u * j + 3u] = box.z | (box.w << 16u);
    return;
  }
  if (!here) return;
  for (uint y = box.y; y <= box.w; ++y)
    for (uint x = box.x; x <= box.z; ++x) {
      uvec2 key;
      if (gather_key(ref, k, tri, uvec2(x, y), key)) atomicMin(gather_keys64[y * c.width + x], packUint2x32(key));
    }
}
