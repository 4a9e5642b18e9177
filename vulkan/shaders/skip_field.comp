#version 460
// skip_field.comp: the skip field's static distances (kGridSkipEmpty; docs/SPEC.md "Empty-space
// skipping"), after the static references are in. Four passes, one pipeline, the pass a push
// constant (reference/build.cpp, skip_field_build and skip_table_pass, block by block):
//   0-2: the summed-volume table of the occupancy (slot 0 not blank): pass 0 one invocation per x
//        line, writing its running count; passes 1 and 2 add along y and z.
//   3:   one invocation per word of 4 cells: each cell's distance, the smallest r whose cube holds
//        an occupied cell, by binary search over [0, kSkipMaxDistance].
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 64) in;
layout(binding = kGridBindImage, r32ui) uniform readonly uimage3D grid_image;
layout(std430, binding = kGridBindOffsets) readonly buffer Offsets { uint compact_offsets[]; };
layout(std430, binding = kGridBindSkip) buffer Skip { uint skip[]; };
layout(std430, binding = kGridBindSkipTable) buffer SkipTable { uint table[]; };
layout(push_constant) uniform Push { SkipFieldPush pc; };

// Occupied cells in the cube of radius r around c, from the table.
uint skip_cube_count(GridParams g, uvec3 c, uint r) {
  uint count = 0u;
  for (uint j = 0u; j < 8u; ++j) {
    const uint v = table[skip_table_index(g, skip_cube_corner(g, c, r, j))];
    count = skip_corner_positive(j) ? count + v : count - v;
  }
  return count;
}

void main() {
  const GridParams g = grid_params();
  const uint item = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 64u, gl_LocalInvocationID.x);
  const uvec3 n = g.cells;
  if (pc.pass < 3u) {
    // The summed-volume table's passes
    const uvec3 lines = pc.pass == 0u ? uvec3(n.y, n.z, n.x) : (pc.pass == 1u ? uvec3(n.x, n.z, n.y) : uvec3(n.x, n.y, n.z));
    if (item >= lines.x * lines.y) return;
    const uint a = item % lines.x;
    const uint b = item / lines.x;
    uint sum = 0u;
    for (uint k = 0u; k < lines.z; ++k) {
      const uvec3 c = pc.pass == 0u ? uvec3(k, a, b) : (pc.pass == 1u ? uvec3(a, k, b) : uvec3(a, b, k));
      const uint i = skip_table_index(g, c + uvec3(1u));
      if (pc.pass == 0u) {
        const uint ci = cell_linear_index(g, c);
        const bool occupied = (g.flags & kGridCompact) != 0u ? compact_offsets[ci + 1u] > compact_offsets[ci]
                                                             : imageLoad(grid_image, ivec3(cell_slot_texel(g, c, 0u))).x != kBlank;
        sum += occupied ? 1u : 0u;
        table[i] = sum;
      } else {
        sum += table[i];
        table[i] = sum;
      }
    }
    return;
  }
  // The distances, one invocation per word (4 cells)
  const uint cells = grid_cell_count(g);
  if (item >= (cells + 3u) / 4u) return;
  uint packed = 0u;
  for (uint q = 0u; q < 4u && 4u * item + q < cells; ++q) {
    const uint i = 4u * item + q;
    const uvec3 c = cell_of_linear_index(g, i);
    uint lo = 0u;
    uint hi = kSkipMaxDistance;
    while (lo < hi) {
      const uint mid = (lo + hi) / 2u;
      if (skip_cube_count(g, c, mid) > 0u) hi = mid;
      else lo = mid + 1u;
    }
    packed |= lo << skip_distance_shift(i);
  }
  skip[kSkipHeaderWords + item] = packed;
}
