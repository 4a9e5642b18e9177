#version 460
// gather_dirs.comp: the compute gather's pixel rays, once per frame (not with kFrameGatherBoxes):
// camera_direction of every pixel into pixel_dirs (xyz) with its ray's origin epsilon (w,
// origin_tmin), which the bin and raster passes read instead of computing them again for each
// triangle that covers the pixel (their correctly rounded divisions and square root are the
// costliest part of a pixel's test). The same functions, the same bits.
#extension GL_GOOGLE_include_directive : require
#include "frame_common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
  const CameraParams c = fp.camera;
  const uvec2 px = gl_GlobalInvocationID.xy;
  if (px.x >= c.width || px.y >= c.height) return;
  const vec3 dir = camera_direction(c, px.x, px.y);
  pixel_dirs[px.y * c.width + px.x] = vec4(dir, origin_tmin(c.eye, dir, 0.0f));
}
