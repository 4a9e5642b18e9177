#version 460
// shadow.comp: the frame's shadow rays, one per pixel and light (light-major, after the bounce
// rays in the ray buffer: ray (1 + light) * pixels + pixel), as common/gather.cpp's shadow_rays
// makes them (common/shared/shadow.h). Compiled in only for a scene with lights (kFrameShadows).
#extension GL_GOOGLE_include_directive : require
#include "frame_common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
  const CameraParams c = fp.camera;
  const uvec2 px = gl_GlobalInvocationID.xy;
  if ((kFrameFlags & kFrameShadows) == 0u || px.x >= c.width || px.y >= c.height) return;
  const uint pixels = c.width * c.height;
  const uint p = px.y * c.width + px.x;
  const GatherTexel g = gather[p];
  for (uint i = 0u; i < fp.light_count; ++i) {
    const FrameLight l = lights[i];
    rays[(1u + i) * pixels + p] = shadow_ray(g.position, g.normal, g.launch_ref, l.position, l.directional != 0.0f);
  }
}
