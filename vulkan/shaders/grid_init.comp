#version 460
// grid_init.comp: the image before the build: every slot blank, every status texel 0. One
// invocation per texel.
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
layout(binding = kGridBindImage, r32ui) uniform writeonly uimage3D grid_image;

void main() {
  const uvec3 p = gl_GlobalInvocationID;
  const uvec3 extent = uvec3(imageSize(grid_image));
  if (any(greaterThanEqual(p, extent))) return;
  const bool status = p.x % (kCapacity + 1u) == kCapacity;
  imageStore(grid_image, ivec3(p), uvec4(status ? 0u : kBlank));
}
