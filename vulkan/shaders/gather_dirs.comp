#version 460
// gather_dirs.comp: the compute gather's pixel rays, once per frame (not with kFrameGatherBoxes):
// camera_direction of every pixel into pixel_dirs, which the bin and raster passes read instead of
// computing it again for each triangle that covers the pixel (its correctly rounded divisions and
// square root are the costliest part of a pixel's test). The same function, the same bits.
#extension GL_GOOGLE_include_directive : require
#include "frame_common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
  const CameraParams c = fp.camera;
  const uvec2 px = gl_GlobalInvocationID.xy;
  if (px.x >= c.width || px.y >= c.height) return;
  pixel_dirs[px.y * c.width + px.x] = vec4(camera_direction(c, px.x, px.y), 0.0f);
}
