#version 460
// clear_dynamic.comp: the clear pass of scene update (paper 2.2) over the dirty-cell list, 64
// listed cells per workgroup, dispatched indirectly (work_list_dispatch.comp made the dispatch);
// the comparison offset (static_instance_count << 16) as a push constant: per listed cell, blank
// every reference >= the comparison offset, slot by slot from the first one up to the first
// blank, reset the dynamic saturation bit, take the cell off the list. Same name and headings as
// reference/build.cpp.
#extension GL_GOOGLE_include_directive : require
#include "build.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform Push { uint comparison_offset; } pc;

void main() {
  const GridParams g = grid_params();
  const uint k = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 64u, gl_LocalInvocationID.x);
  if (k >= dirty_header.size) return;
  const uint i = dirty_items[k];
  const uvec3 cell = cell_of_linear_index(g, i);
  // Blank the dynamic references up to the first blank (the static ones precede them)
  for (uint s = first_slot_at_least(g, cell, pc.comparison_offset); s < g.capacity; ++s) {
    const ivec3 p = ivec3(cell_slot_texel(g, cell, s));
    if (imageLoad(grid_image, p).x == kBlank) break;
    imageAtomicExchange(grid_image, p, kBlank);
  }
  // Reset the dynamic saturation bit; the static one persists
  imageAtomicAnd(grid_image, ivec3(cell_status_texel(g, cell)), ~kStatusDynamic);
  // Off the list
  atomicAnd(dirty_items[dirty_bit_item(g, i)], ~dirty_bit(i));
}
