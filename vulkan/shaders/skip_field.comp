#version 460
// skip_field.comp: the skip field's static distances (kGridSkipEmpty; docs/SPEC.md "Empty-space
// skipping"), after the static references are in. Four passes, one pipeline, the pass a push
// constant (reference/build.cpp, skip_field_build and skip_table_pass, block by block):
//   0-2: the summed-volume table of the occupancy (slot 0 not blank): pass 0 one invocation per x
//        line, writing its running count; passes 1 and 2 add along y and z. Each line is read
//        kSkipLineBatch values at a time before they are written: the batch's loads are in flight
//        together (a load after a store to the same buffer is not moved above it).
//   3:   one invocation per cell (adjacent lanes, adjacent cells: the table's corners coalesce):
//        its distance, the smallest r whose cube holds an occupied cell, by binary search over
//        [0, kSkipMaxDistance]; the four cells of a word meet in shared memory, the word's first
//        lane writes it (the reference: one invocation per word).
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 64) in;
layout(binding = kGridBindImage, r32ui) uniform readonly uimage3D grid_image;
layout(std430, binding = kGridBindOffsets) readonly buffer Offsets { uint compact_offsets[]; };
layout(std430, binding = kGridBindSkip) buffer Skip { uint skip[]; };
layout(std430, binding = kGridBindSkipTable) buffer SkipTable { uint table[]; };
layout(push_constant) uniform Push { SkipFieldPush pc; };

const uint kSkipLineBatch = 8u;
shared uint words[64u / 4u];  // pass 3: the workgroup's cells' distances, 4 to a word

// Occupied cells in the cube of radius r around c, from the table.
uint skip_cube_count(GridParams g, uvec3 c, uint r) {
  uint count = 0u;
  for (uint j = 0u; j < 8u; ++j) {
    const uint v = table[skip_table_index(g, skip_cube_corner(g, c, r, j))];
    count = skip_corner_positive(j) ? count + v : count - v;
  }
  return count;
}

// Cell k of line (a, b) of table pass `pass` (along x, y, z).
uvec3 line_cell(uint pass, uint a, uint b, uint k) {
  return pass == 0u ? uvec3(k, a, b) : (pass == 1u ? uvec3(a, k, b) : uvec3(a, b, k));
}

// The table's word of cell c (1-based: index 0 along an axis is "before the grid").
uint line_table_index(GridParams g, uvec3 c) {
  const uint i = skip_table_index(g, c + uvec3(1u));
  return i;
}

// Pass 0's value of cell c: 1 if it is occupied.
uint occupancy(GridParams g, uvec3 c) {
  const uint ci = cell_linear_index(g, c);
  const bool occupied = (g.flags & kGridCompact) != 0u ? compact_offsets[ci + 1u] > compact_offsets[ci]
                                                       : imageLoad(grid_image, ivec3(cell_slot_texel(g, c, 0u))).x != kBlank;
  return occupied ? 1u : 0u;
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
    for (uint k0 = 0u; k0 < lines.z; k0 += kSkipLineBatch) {
      uint v[kSkipLineBatch];
      for (uint q = 0u; q < kSkipLineBatch; ++q) {
        const uvec3 c = line_cell(pc.pass, a, b, min(k0 + q, lines.z - 1u));  // past the end: unused
        v[q] = pc.pass == 0u ? occupancy(g, c) : table[line_table_index(g, c)];
      }
      for (uint q = 0u; q < kSkipLineBatch && k0 + q < lines.z; ++q) {
        sum += v[q];
        table[line_table_index(g, line_cell(pc.pass, a, b, k0 + q))] = sum;
      }
    }
    return;
  }
  // The distances, one invocation per cell (every lane reaches the barriers)
  const uint cells = grid_cell_count(g);
  const uint l = gl_LocalInvocationID.x;
  if (l < 64u / 4u) words[l] = 0u;
  barrier();
  if (item < cells) {
    const uint i = item;
    const uvec3 c = cell_of_linear_index(g, i);
    uint lo = 0u;
    uint hi = kSkipMaxDistance;
    while (lo < hi) {
      const uint mid = (lo + hi) / 2u;
      if (skip_cube_count(g, c, mid) > 0u) hi = mid;
      else lo = mid + 1u;
    }
    atomicOr(words[l / 4u], lo << skip_distance_shift(i));
  }
  barrier();
  if (item < cells && item % 4u == 0u) skip[kSkipHeaderWords + item / 4u] = words[l / 4u];
}
