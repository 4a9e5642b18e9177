#version 460
// gather_tiles.comp: the compute gather's second pass with kFrameGatherBoxes (the gather before its
// rasterizer, kept to be measured against it: gather_raster.comp), one workgroup per
// 8x8-pixel tile of the large triangles' boxes, dispatched indirectly, one invocation per pixel: the
// tile's triangle by binary search over the triangles' first tiles, then the pixel's camera ray
// against it; an accepted hit takes the pixel's key by a 64-bit atomic min, so the pixel ends with
// the smallest t, then the smallest reference.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "gather_visibility.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = kFrameBindGatherKeys) buffer GatherKeys64 { uint64_t gather_keys64[]; };

void main() {
  const CameraParams c = fp.camera;
  const uint tile = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 1u, 0u);
  if (tile >= tile_header.tiles) return;
  // The triangle whose tiles hold this one: the last whose first tile is <= tile
  uint lo = 0u;
  uint hi = tile_header.triangles;
  while (hi - lo > 1u) {
    const uint mid = (lo + hi) / 2u;
    if (tile_tris[mid].first <= tile) lo = mid;
    else hi = mid;
  }
  const uint ref = tile_tris[lo].ref;
  const uint t = tile - tile_tris[lo].first;
  const uint x0 = tile_tris[lo].box_lo & 0xFFFFu, y0 = tile_tris[lo].box_lo >> 16u;
  const uint across = ((tile_tris[lo].box_hi & 0xFFFFu) - x0) / 8u + 1u;
  const uvec2 px = uvec2(x0 + 8u * (t % across), y0 + 8u * (t / across)) + gl_LocalInvocationID.xy;
  // Within the box (its last column and row of tiles reach past it) and the screen: a triangle
  // crossing the near plane without bounds has hits outside its box nearer than the near plane,
  // which no pass of the gather takes (an outside sweep: the box gather took them here, the fine
  // pass at other pixels)
  if (px.x > (tile_tris[lo].box_hi & 0xFFFFu) || px.y > (tile_tris[lo].box_hi >> 16u)) return;
  if (px.x >= c.width || px.y >= c.height) return;
  const uint k = instances[ref_instance(ref)].tri_offset + ref_triangle(ref);
  uvec2 key;
  if (gather_key(ref, k, triangles[k], px, key)) atomicMin(gather_keys64[px.y * c.width + px.x], packUint2x32(key));
}
