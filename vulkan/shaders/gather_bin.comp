#version 460
// gather_bin.comp: the compute gather's first pass (gather_visibility.glsl), one invocation per
// triangle of the geometry buffer: its screen box; a box of at most 16 pixels is tested here, a
// larger one cut into 8x8-pixel tiles appended to the tile list (one atomic per subgroup). Where
// the list is full, the invocation tests its box itself.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "gather_visibility.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = 13) buffer GatherKeys64 { uint64_t gather_keys64[]; };
layout(push_constant) uniform Push {
  uint triangle_count;  // triangles of the geometry buffer
  uint instance_count;
  uint tile_capacity;   // items the tile list holds
} pc;

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
  // Append the tiles: one atomic per subgroup
  const uint total = subgroupAdd(tiles);
  const uint before = subgroupExclusiveAdd(tiles);
  uint base = 0u;
  if (subgroupElect()) base = atomicAdd(tile_header.appended, total);
  base = subgroupBroadcastFirst(base);
  if (here) {
    for (uint y = box.y; y <= box.w; ++y)
      for (uint x = box.x; x <= box.z; ++x) {
        uvec2 key;
        if (gather_key(ref, k, tri, uvec2(x, y), key))
          atomicMin(gather_keys64[y * c.width + x], packUint2x32(key));
      }
    return;
  }
  if (tiles == 0u) return;
  const uint first = base + before;
  const uint across = (box.z - box.x) / 8u + 1u;
  if (first <= pc.tile_capacity && tiles <= pc.tile_capacity - first) {
    for (uint i = 0u; i < tiles; ++i) {
      const uint x = box.x + 8u * (i % across), y = box.y + 8u * (i / across);
      tile_items[2u * (first + i)] = ref;
      tile_items[2u * (first + i) + 1u] = x | (y << 16u);
    }
    return;
  }
  // The list is full: test the box here
  for (uint y = box.y; y <= box.w; ++y)
    for (uint x = box.x; x <= box.z; ++x) {
      uvec2 key;
      if (gather_key(ref, k, tri, uvec2(x, y), key))
        atomicMin(gather_keys64[y * c.width + x], packUint2x32(key));
    }
}
