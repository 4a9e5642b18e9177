#version 460
// gather_dirs.comp: the compute gather's first pass (not with kFrameGatherBoxes), one invocation
// per pixel, one workgroup per 8x8-pixel screen tile:
//   pixel rays   camera_direction of every pixel into pixel_dirs (xyz) with its ray's origin
//                epsilon (w, origin_tmin), which the bin and raster passes read instead of
//                computing them again for each triangle that covers the pixel (their correctly
//                rounded divisions and square root are the costliest part of a pixel's test). The
//                same functions, the same bits.
//   clean state  the pixel's key "nothing" (all ones); per screen tile its depth bound unknown
//                (all ones) and its tile list's count 0; with buckets, the count of pairs past them 0. (The fills of kFrameGatherBoxes, here in
//                the pass that writes the pixels anyway: one pass and no fill commands.)
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "frame_common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = kFrameBindGatherKeys) buffer GatherKeys64 { uint64_t gather_keys64[]; };

void main() {
  const CameraParams c = fp.camera;
  const uvec2 px = gl_GlobalInvocationID.xy;
  if (gl_LocalInvocationIndex == 0u) {
    const uint tile = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    tile_depth[tile] = 0xFFFFFFFFu;
    tile_words[tile] = 0u;
    if (tile == 0u) fine_header.pairs = 0u;  // with buckets: the pairs past them
  }
  if (px.x >= c.width || px.y >= c.height) return;
  const uint p = px.y * c.width + px.x;
  // camera_direction, its column's and row's divisions read from the host's table
  const vec3 dir = camera_direction_steps(c, camera_steps[px.x], camera_steps[c.width + px.y]);
  pixel_dirs[p] = vec4(dir, origin_tmin(c.eye, dir, 0.0f));
  gather_keys64[p] = 0xFFFFFFFFFFFFFFFFul;
}
