#version 460
// skip_field.comp: the skip field's static distances (kGridSkipEmpty; docs/SPEC.md "Empty-space
// skipping"), after the static references are in. Four passes, one pipeline, the pass a push
// constant (reference/build.cpp, skip_field_build and skip_table_pass, block by block):
//   0-2: the summed-volume table of the occupancy (slot 0 not blank): pass 0 the running count
//        along each z line, passes 1 and 2 add along y and x (the reference: x, y, z, one
//        invocation per line; the sums are exact, so the order of the axes changes no value). A
//        workgroup takes skip_lines(pass) lines, each cut into 64 / skip_lines segments, a lane per
//        segment: the lane sums its segment, the segments' sums meet in shared memory, and the
//        lane walks its segment again writing the running sums from the sum of the segments
//        before it. Along z and y, 16 lines of adjacent x (their loads coalesce), 4 segments each;
//        along x, one line of 64 segments (adjacent lanes, adjacent runs of cells). The occupancy
//        pass runs along z: its two offsets a cell are read by lanes of adjacent x. Loads are
//        issued kSkipLineBatch at a time before they are used, so that a batch is in flight
//        together (a load after a store to the same buffer is not moved above it).
//   3:   one invocation per brick (kSkipBrick^3 cells): its distance, the smallest R whose grown
//        box holds an occupied cell, by binary search over [0, kSkipMaxBrickDistance], written
//        after the table (skip_scratch_words).
//   4:   one invocation per cell (adjacent lanes, adjacent cells: the table's corners coalesce):
//        its distance, the smallest r whose cube holds an occupied cell, by binary search over the
//        window its brick's distance leaves (skip_cell_window); the four cells of a word meet in
//        shared memory, the word's first lane writes it (the reference: one invocation per word).
//        With kGridSkipCovered, an occupied cell's cover bits (skip_cover_bits) go in its byte
//        instead of the distance 0 (skip_byte).
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 64) in;
layout(binding = kGridBindImage, r32ui) uniform readonly uimage3D grid_image;
layout(std430, binding = kGridBindOffsets) readonly buffer Offsets { uint compact_offsets[]; };
layout(std430, binding = kGridBindRefs) readonly buffer Refs { uint compact_refs[]; };
layout(std430, binding = kGridBindSkip) buffer Skip { uint skip[]; };
layout(std430, binding = kGridBindSkipTable) buffer SkipTable { uint table[]; };
layout(push_constant) uniform Push { SkipFieldPush pc; };

const uint kSkipLineBatch = 8u;
shared uint words[64u / 4u];  // pass 4: the workgroup's cells' bytes, 4 to a word
shared uint segment_sums[64];  // passes 0-2: each lane's segment sum

// Lines a workgroup of passes 0-2 takes (record_skip_field on the host): 16 along z and y (4
// segments each), 1 along x (64 segments).
uint skip_lines(uint pass) { return pass == 2u ? 1u : 16u; }

// Occupied cells in the cube of radius r around c, from the table.
uint skip_cube_count(GridParams g, uvec3 c, uint r) {
  uint count = 0u;
  for (uint j = 0u; j < 8u; ++j) {
    const uint v = table[skip_table_index(g, skip_cube_corner(g, c, r, j))];
    count = skip_corner_positive(j) ? count + v : count - v;
  }
  return count;
}

// Occupied cells in the box of brick b grown by R bricks, from the table.
uint skip_brick_count(GridParams g, uvec3 b, uint R) {
  uint count = 0u;
  for (uint j = 0u; j < 8u; ++j) {
    const uint v = table[skip_table_index(g, skip_brick_corner(g, b, R, j))];
    count = skip_corner_positive(j) ? count + v : count - v;
  }
  return count;
}

// Cell k of line (a, b) of table pass `pass` (along z, y, x).
uvec3 line_cell(uint pass, uint a, uint b, uint k) {
  return pass == 0u ? uvec3(a, b, k) : (pass == 1u ? uvec3(a, k, b) : uvec3(k, a, b));
}

// The table's word of cell c (1-based: index 0 along an axis is "before the grid").
uint line_table_index(GridParams g, uvec3 c) {
  const uint i = skip_table_index(g, c + uvec3(1u));
  return i;
}

// Pass 0's value of cell c: 1 if it is occupied.
uint occupancy(GridParams g, uvec3 c) {
  const uint ci = cell_linear_index(g, c);
  const bool occupied = (g.flags & kGridCompact) == 0u
                            ? imageLoad(grid_image, ivec3(cell_slot_texel(g, c, 0u))).x != kBlank
                        : (g.flags & kGridSparseOffsets) != 0u ? compact_occupied(compact_offsets[compact_mask_index(ci)], ci)
                                                               : compact_offsets[ci + 1u] > compact_offsets[ci];
  return occupied ? 1u : 0u;
}

// A cell's run in the ordered references (the reference's compact_run): [begin, end), empty for a
// cell that holds none.
uvec2 cover_run(GridParams g, uint cells, uint i) {
  if ((g.flags & kGridSparseOffsets) == 0u) return uvec2(compact_offsets[i], compact_offsets[i + 1u]);
  const uint mask = compact_offsets[compact_mask_index(i)];
  if (!compact_occupied(mask, i)) return uvec2(0u);
  const uint k = compact_run_index(cells, compact_offsets[compact_base_index(i)], mask, i);
  if (k + 1u >= uint(compact_offsets.length())) return uvec2(0u);  // past the index (as compact_run)
  return uvec2(compact_offsets[k], compact_offsets[k + 1u]);
}

// Whether the sorted run b lies in the sorted run a (one merge walk; the reference's run_within).
bool run_within(uvec2 b, uvec2 a) {
  if (b.y - b.x > a.y - a.x) return false;
  uint j = a.x;
  for (uint k = b.x; k < b.y; ++k) {
    const uint r = compact_refs[k];
    while (j < a.y && compact_refs[j] < r) ++j;
    if (j == a.y || compact_refs[j] != r) return false;
    ++j;
  }
  return true;
}

// A cell's cover bits (shared/grid.h "Covered cells"): bit f set iff its static run is not empty
// and lies in the run of its neighbour across face f (the reference's skip_cover_bits).
uint skip_cover_bits(GridParams g, uint cells, uvec3 c) {
  const uvec2 b = cover_run(g, cells, cell_linear_index(g, c));
  if (b.y == b.x) return 0u;
  uint bits = 0u;
  for (uint f = 0u; f < 6u; ++f) {
    uvec3 n;
    if (!skip_face_neighbour(g, c, f, n)) continue;
    const uvec2 a = cover_run(g, cells, cell_linear_index(g, n));
    if (a.y > a.x && run_within(b, a)) bits |= 1u << f;
  }
  return bits;
}

void main() {
  const GridParams g = grid_params();
  const uint item = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 64u, gl_LocalInvocationID.x);
  const uvec3 n = g.cells;
  if (pc.pass < 3u) {
    // The summed-volume table's passes (every lane reaches the barrier)
    const uvec3 lines = pc.pass == 0u ? uvec3(n.x, n.y, n.z) : (pc.pass == 1u ? uvec3(n.x, n.z, n.y) : uvec3(n.y, n.z, n.x));
    const uint per_group = skip_lines(pc.pass);
    const uint segments = 64u / per_group;
    const uint l = gl_LocalInvocationID.x;
    const uint line = (item / 64u) * per_group + l % per_group;
    const uint segment = l / per_group;
    const bool on = line < lines.x * lines.y;
    const uint a = line % lines.x;
    const uint b = line / lines.x;
    const uint seg_len = (lines.z + segments - 1u) / segments;
    const uint k_begin = on ? min(segment * seg_len, lines.z) : 0u;
    const uint k_end = on ? min(k_begin + seg_len, lines.z) : 0u;
    // The segment's sum
    uint sum = 0u;
    for (uint k0 = k_begin; k0 < k_end; k0 += kSkipLineBatch) {
      uint v[kSkipLineBatch];
      for (uint q = 0u; q < kSkipLineBatch; ++q) {
        const uvec3 c = line_cell(pc.pass, a, b, min(k0 + q, k_end - 1u));  // past the end: unused
        v[q] = pc.pass == 0u ? occupancy(g, c) : table[line_table_index(g, c)];
      }
      for (uint q = 0u; q < kSkipLineBatch && k0 + q < k_end; ++q) sum += v[q];
    }
    segment_sums[l] = sum;
    barrier();
    // The running sums from the line's segments before this one
    uint run = 0u;
    for (uint j = 0u; j < segment; ++j) run += segment_sums[j * per_group + l % per_group];
    for (uint k0 = k_begin; k0 < k_end; k0 += kSkipLineBatch) {
      uint v[kSkipLineBatch];
      for (uint q = 0u; q < kSkipLineBatch; ++q) {
        const uvec3 c = line_cell(pc.pass, a, b, min(k0 + q, k_end - 1u));
        v[q] = pc.pass == 0u ? occupancy(g, c) : table[line_table_index(g, c)];
      }
      for (uint q = 0u; q < kSkipLineBatch && k0 + q < k_end; ++q) {
        run += v[q];
        table[line_table_index(g, line_cell(pc.pass, a, b, k0 + q))] = run;
      }
    }
    return;
  }
  if (pc.pass == 3u) {
    // The bricks' distances
    if (item >= skip_brick_count(g)) return;
    const uvec3 b = skip_brick_of_index(g, item);
    uint lo = 0u;
    uint hi = kSkipMaxBrickDistance;
    while (lo < hi) {
      const uint mid = (lo + hi) / 2u;
      if (skip_brick_count(g, b, mid) > 0u) hi = mid;
      else lo = mid + 1u;
    }
    table[skip_table_words(g) + item] = lo;
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
    uint lo;
    uint hi;
    skip_cell_window(table[skip_table_words(g) + skip_brick_index(g, c)], lo, hi);
    while (lo < hi) {
      const uint mid = (lo + hi) / 2u;
      if (skip_cube_count(g, c, mid) > 0u) hi = mid;
      else lo = mid + 1u;
    }
    const uint cover = (g.flags & kGridSkipCovered) != 0u && lo == 0u ? skip_cover_bits(g, cells, c) : 0u;
    atomicOr(words[l / 4u], skip_byte(lo, cover) << skip_distance_shift(i));
  }
  barrier();
  if (item < cells && item % 4u == 0u) skip[kSkipHeaderWords + item / 4u] = words[l / 4u];
}
