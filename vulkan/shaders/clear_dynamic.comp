#version 460
// clear_dynamic.comp: the clear pass of scene update (paper 2.2) over the dirty-cell list, one
// workgroup of 64 invocations per listed cell, dispatched indirectly (work_list_dispatch.comp
// made the dispatch); the comparison offset (static_instance_count << 16) as a push constant: per
// listed cell, blank every reference >= the comparison offset from the first such slot up to the
// first blank, the invocations taking every 64th slot; reset the dynamic saturation bit, empty the
// cell's dynamic spill list, take the cell off the list (the spill counter went back to the static
// count by a copy before the pass). Same name and headings as reference/build.cpp.
#extension GL_GOOGLE_include_directive : require
#include "build.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform Push { ClearPush pc; };

shared uint first_dynamic;

void main() {
  const GridParams g = grid_params();
  const uint k = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 1u, 0u);
  if (k >= dirty_header.size) return;  // the whole workgroup
  const uint i = dirty_items[k];
  const uvec3 cell = cell_of_linear_index(g, i);
  const uint lane = gl_LocalInvocationID.x;
  // The first dynamic slot (the static references precede the dynamic ones)
  if (lane == 0u) first_dynamic = first_slot_at_least(g, cell, pc.comparison_offset);
  barrier();
  // Blank the dynamic references up to the first blank, every 64th slot per invocation (a slot
  // found blank ends the invocation's walk: the blanks form the cell's tail)
  for (uint s = first_dynamic + lane; s < g.capacity; s += 64u)
    if (imageAtomicExchange(grid_image, ivec3(cell_slot_texel(g, cell, s)), kBlank) == kBlank) break;
  if (lane != 0u) return;
  // Reset the dynamic saturation bit; the static one persists
  imageAtomicAnd(grid_image, ivec3(cell_status_texel(g, cell)), ~kStatusDynamic);
  // Empty the dynamic spill list; the static one persists (every cell a dynamic reference was
  // spilled in is listed: the reference reached it)
  if ((g.flags & kGridSpill) != 0u) {
    spill_heads[spill_head_index(i, true)] = kSpillEnd;
    spill_heads[spill_arrival_index(i, true)] = kSpillEnd;
  }
  // Off the list
  atomicAnd(dirty_items[dirty_bit_item(g, i)], ~dirty_bit(i));
}
