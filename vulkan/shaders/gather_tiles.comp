#version 460
// gather_tiles.comp: the compute gather's second pass (gather_visibility.glsl), one workgroup per
// (triangle, 8x8-pixel tile) of the tile list, dispatched indirectly, one invocation per pixel:
// the pixel's camera ray against the triangle; an accepted hit takes the pixel's key by a 64-bit
// atomic min, so the pixel ends with the smallest t, then the smallest reference.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "gather_visibility.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = 13) buffer GatherKeys64 { uint64_t gather_keys64[]; };

void main() {
  const CameraParams c = fp.camera;
  const uint item = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 1u, 0u);
  if (item >= tile_header.size) return;
  const uint ref = tile_items[2u * item];
  const uint origin = tile_items[2u * item + 1u];
  const uvec2 px = uvec2(origin & 0xFFFFu, origin >> 16u) + gl_LocalInvocationID.xy;
  if (px.x >= c.width || px.y >= c.height) return;
  const uint k = instances[ref_instance(ref)].tri_offset + ref_triangle(ref);
  const GridTriangle tri = triangles[k];
  const uint p = px.y * c.width + px.x;
  if ((kFrameFlags & kFrameGatherCull) != 0u) {
    // Depth cull: a hit on the triangle lies at least its smallest camera depth away along the
    // unit ray (t >= z); a pixel already holding a nearer hit keeps it (the key only decreases, so
    // a stale read only lets more through)
    const float z = min(min(gather_camera_space(c, tri.v0).z, gather_camera_space(c, tri.v1).z),
                        gather_camera_space(c, tri.v2).z) * 0.99999f;
    if (z > 0.0f && gather_keys[2u * p + 1u] < floatBitsToUint(z)) return;
  }
  uvec2 key;
  if (gather_key(ref, k, tri, px, key)) atomicMin(gather_keys64[p], packUint2x32(key));
}
