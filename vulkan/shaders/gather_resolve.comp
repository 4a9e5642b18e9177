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
  if ((kFrameFlags & kFrameComputeGather) != 0u) {
    // The key: its low word the triangle (untouched keys are all ones: kNoRef), its high word the t
    // of the test that gave it
    const uint ref = gather_keys[2u * p];
    visibility[p] = ref;
    store_gather(p, gather_texel_at(ref, camera_direction(c, px.x, px.y), uintBitsToFloat(gather_keys[2u * p + 1u])));
    return;
  }
  store_gather(p, gather_texel(visibility[p], camera_direction(c, px.x, px.y)));
}
