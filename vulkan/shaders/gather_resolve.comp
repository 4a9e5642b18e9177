#version 460
// gather_resolve.comp: the gather buffer from the visible triangle per pixel (the raster pass's,
// copied to the visibility buffer; or the compute gather's key, whose low word it is), by
// gather_texel (frame_common.glsl) along the pixel's camera_direction. The compute gather's fine
// pass resolves its pixels itself (gather_fine.comp): this pass then runs only for the box gather
// and where the fine pass did not run (dispatched indirectly, GatherFineHeader).
#extension GL_GOOGLE_include_directive : require
#include "frame_common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
  const CameraParams c = fp.camera;
  const uvec2 px = gl_GlobalInvocationID.xy;
  if (px.x >= c.width || px.y >= c.height) return;
  const uint p = px.y * c.width + px.x;
  uint ref;
  if ((kFrameFlags & kFrameComputeGather) != 0u) {
    ref = gather_keys[2u * p];  // the key's low word; untouched keys are all ones: kNoRef
    visibility[p] = ref;
  } else {
    ref = visibility[p];
  }
  gather[p] = gather_texel(ref, camera_direction(c, px.x, px.y));
}
