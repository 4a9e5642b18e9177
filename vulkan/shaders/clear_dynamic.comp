#version 460
// clear_dynamic.comp: the clear pass of scene update (paper 2.2), in workgroups of 4x4x4 cells
// (the paper's choice), the comparison offset (static_instance_count << 16) as a push constant:
// per cell, blank every reference >= the comparison offset, slot by slot up to the first blank,
// reset the dynamic saturation bit and empty the cell's dynamic spill list; the first invocation
// resets the spill counter to the static references' count. Same name and headings as reference/build.cpp.
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
layout(binding = 1, r32ui) uniform coherent uimage3D grid_image;
layout(std430, binding = 13) buffer Spill {
  SpillHeader spill_header;
  SpillEntry spill_entries[];
};
layout(std430, binding = 14) buffer SpillHeads { uint spill_heads[]; };
layout(push_constant) uniform Push { uint comparison_offset; } pc;

void main() {
  const GridParams g = grid_params();
  // Drop the dynamic references' spill entries
  if (gl_GlobalInvocationID == uvec3(0u)) spill_header.count = spill_header.static_count;
  const uvec3 cell = gl_GlobalInvocationID;
  if (cell.x >= g.cells.x || cell.y >= g.cells.y || cell.z >= g.cells.z) return;
  // Blank the dynamic references up to the first blank
  for (uint s = 0u; s < g.capacity; ++s) {
    const ivec3 p = ivec3(cell_slot_texel(g, cell, s));
    const uint ref = imageLoad(grid_image, p).x;
    if (ref == kBlank) break;
    if (ref >= pc.comparison_offset) imageAtomicExchange(grid_image, p, kBlank);
  }
  // Reset the dynamic saturation bit; the static one persists
  imageAtomicAnd(grid_image, ivec3(cell_status_texel(g, cell)), ~kStatusDynamic);
  // Empty the dynamic spill list; the static one persists
  if ((g.flags & kGridSpill) != 0u) {
    const uint c = cell_index(g, cell);
    spill_heads[spill_head_index(c, true)] = kSpillEnd;
    spill_heads[spill_arrival_index(c, true)] = kSpillEnd;
  }
}
