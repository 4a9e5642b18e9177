#version 460
// grid_init.comp: the image before the build, after vkCmdClearColorImage made every texel blank:
// every status texel 0, one invocation per cell.
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 64) in;
layout(binding = 1, r32ui) uniform writeonly uimage3D grid_image;

void main() {
  const GridParams g = grid_params();
  const uint i = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 64u, gl_LocalInvocationID.x);
  if (i >= grid_cell_count(g)) return;
  imageStore(grid_image, ivec3(cell_status_texel(g, cell_of_linear_index(g, i))), uvec4(0u));
}
