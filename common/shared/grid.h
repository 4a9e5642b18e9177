// grid.h: the fixed-capacity grid's math, written once (paper sections 2.1-2.3, docs/SPEC.md).
// Compiled as C++ by the reference (reference/) and as GLSL by the Vulkan shaders; see compat.h
// for the rules. Everything here is a pure function of its arguments: the image, the atomics and
// the loops that call these functions live in reference/*.cpp and in the shaders, under the same
// names and heading comments.
//
// Units: positions in world units; ray parameters t in units of the ray's |dir| (RayRecord);
// "cell units" are multiples of GridParams::cell_size.
#ifndef GRIDRT_SHARED_GRID_H
#define GRIDRT_SHARED_GRID_H

#include "compat.h"
#include "records.h"
#include "rounding.h"
#include "worklist.h"

SH_BEGIN

// ---- Texels ----
SH_CONST uint kBlank = 0xFFFFFFFFu;     // an empty slot (paper: "blank reference")
SH_CONST uint kStatusStatic = 1u;       // status texel bit: a static reference found no slot
SH_CONST uint kStatusDynamic = 2u;      // status texel bit: a dynamic reference found no slot

// ---- Modes (GridParams::insertion, ::traversal, ::triangle_test) ----
SH_CONST uint kInsertFirstEmpty = 0u;   // paper: compare-and-swap into the first blank slot
SH_CONST uint kInsertSorted = 1u;       // ours: atomic-min cascade, slots stay sorted
SH_CONST uint kTraversalPaper = 0u;     // cell-sized segments sampled at their midpoints
SH_CONST uint kTraversalExact = 1u;     // 3D DDA over every pierced cell
SH_CONST uint kTriangleMoller = 0u;     // Moller-Trumbore, division-free decisions
SH_CONST uint kTriangleWatertight = 1u; // Woop, Benthin, Wald 2013: watertight, division-free

// ---- GridParams::flags ----
SH_CONST uint kGridExcludeLaunchRef = 1u;  // never accept the ray's launch triangle (by ref)
SH_CONST uint kGridAlphaKeying = 2u;       // alpha-keyed materials cut holes
SH_CONST uint kGridGapFill = 4u;           // paper-mode gap-fill in saturated cells
SH_CONST uint kGridSpill = 8u;             // references no slot took go to the spill list, and
                                           // the trace tests a saturated cell's spilled ones too
SH_CONST uint kGridSkipEmpty = 16u;        // exact traversal: the DDA jumps over boxes of empty
                                           // cells (the skip field, docs/SPEC.md "Empty-space skipping")
SH_CONST uint kGridCellBox = 32u;          // build: a cell takes a triangle only if the separating-axis
                                           // test finds no axis between the triangle and the padded cell
                                           // box too (triangle_overlaps_cell; docs/SPEC.md "Scene build", *Separating axes*)
SH_CONST uint kGridCompact = 64u;          // the compact layout (docs/SPEC.md "Compact layout"): static
                                           // references in one array ordered per cell (offsets, refs),
                                           // dynamic ones only in the spill list's dynamic lists, whose
                                           // heads exist for the dynamic region's cells alone; no image
SH_CONST uint kGridSparseOffsets = 1024u;  // the compact layout's offsets index the occupied cells only (an
                                           // occupancy mask per 32 cells, a start per occupied cell), where one
                                           // offset per cell would not fit the memory budget (docs/SPEC.md)
SH_CONST uint kGridSkipCovered = 2048u;   // exact traversal, compact layout, skip field: a cell whose static run
                                           // lies in the run of the neighbour the walk entered it from is not
                                           // tested again (the cover bits; docs/SPEC.md "Covered cells")
SH_CONST uint kGridMailbox = 128u;         // exact traversal: a reference tested earlier on the ray (one of
                                           // the last kMailboxSize tested) is not tested again; the paper
                                           // traversal and first-empty insertion ignore it (docs/SPEC.md "Mailbox")
// Bits 8-9: the scene axis laid along the image's x, the axis that carries the slots (0 x, 1 y,
// 2 z; choose_grid puts the axis with the fewest cells there, docs/SPEC.md "Slot axis and limits"). The
// image swaps that axis with x; every other axis keeps its place.
SH_CONST uint kGridSlotAxisShift = 8u;
SH_CONST uint kGridSlotAxisMask = 0x300u;

// ---- Paper traversal: what a sample landing in the previous step's cell does (GridParams::repeats) ----
SH_CONST uint kRepeatMerge = 0u;   // default: consecutive samples in one cell merge into one visit,
                                   // tested once against the union of their segments
SH_CONST uint kRepeatSkip = 1u;    // the literal reading: the repeated cell is skipped
SH_CONST uint kRepeatRetest = 2u;  // the cell is tested again with the new segment

// ---- Instance flags (GridInstance::flags) ----
SH_CONST uint kInstanceDynamic = 1u;     // re-inserted by every update
SH_CONST uint kInstanceAlphaKeyed = 2u;  // some triangle of the instance has an alpha mask

// Everything the build, update and trace passes read, computed once on the host (std430, UBO).
struct GridParams {
  vec3 origin;              // world position of the grid's lower corner
  float cell_size;          // edge of the cubic cells, world units
  uvec3 cells;              // cells per axis
  uint capacity;            // reference slots per cell; the status texel follows them
  vec3 upper;               // origin + cells * cell_size (host, float), the grid box's far corner
  float inv_cell_size;      // 1 / cell_size rounded once on the host; the only cell-size divisor
  float sphere_r2;          // (sphere_enlargement * cell_size * sqrt(3) / 2)^2, world units^2
  float aabb_padding;       // cell units added on each side of a triangle's AABB (cell range)
  float elongation;         // paper mode: segment elongation on each side, in segment lengths
  float gap_fill_r2;        // (gap_fill_distance * cell_size)^2, world units^2
  float self_hit_offset;    // hits need t * |dir| > self_hit_offset * cell_size
  uint comparison_offset;   // static_instance_count << 16: references >= it are dynamic
  uint insertion;           // kInsertFirstEmpty or kInsertSorted
  uint traversal;           // kTraversalPaper or kTraversalExact
  uint triangle_test;       // kTriangleMoller or kTriangleWatertight
  uint flags;               // kGrid* bits
  uint max_segments;        // safety bound on the steps of one ray (cells.x + cells.y + cells.z + 3)
  uint repeats;             // paper: kRepeatMerge, kRepeatSkip or kRepeatRetest
};

// One instance as the passes see it (std430, storage buffer).
struct GridInstance {
  uint tri_offset;  // index of its triangle 0 in the geometry buffer
  uint tri_count;   // triangles of its mesh
  uint flags;       // kInstance* bits
  uint pad0;        // std430 padding
};

// One world-space triangle of the geometry buffer, written by the build/update invocations.
struct GridTriangle {
  vec3 v0;        // vertex 0, world space (shared::transform_point of the mesh vertex)
  uint material;  // index into the material table
  vec3 v1;        // vertex 1
  uint pad0;      // std430 padding
  vec3 v2;        // vertex 2
  uint pad1;      // std430 padding
};

// Texture coordinates of a triangle (only read for alpha-keyed materials).
struct GridTriangleUv {
  vec2 uv0;
  vec2 uv1;
  vec2 uv2;
};

// A material as the trace pass sees it: where its alpha mask lives in the texel buffer.
struct GridMaterial {
  uint alpha_offset;  // first texel of the mask in the flat texel buffer (RGBA8 packed, a << 24)
  uint alpha_width;   // mask width in texels, 0 = not alpha keyed
  uint alpha_height;  // mask height in texels
  uint pad0;          // std430 padding
};

// The spill list (kGridSpill): every reference that finds no slot is appended as (cell, ref) to one
// storage buffer (a header, then the entries). Each cell has two lists of its entries, static and
// dynamic references, so that the update forgets the dynamic ones by resetting heads: the build
// pushes an entry onto its list's arrival list (one atomic exchange: the order of arrival), and
// the order pass (spill_order) links each list in ascending reference order, which the trace
// walks. The spill heads buffer holds per cell four heads (spill_head_index, spill_arrival_index).
// The counter counts every reference no slot took, with spill off too (then nothing is stored):
// it is how the grid knows whether a cell saturated.
SH_CONST uint kSpillEnd = 0xFFFFFFFFu;  // the end of a list (an empty head)
struct SpillHeader {
  uint count;         // references appended (atomic); entries [0, min(count, capacity)) are stored,
                      // count > capacity: the list overflowed and count - capacity are lost
  uint capacity;      // entries the buffer holds (0 with spill off), written by the host
  uint static_count;  // count after the build's static pass: the update's clear pass resets count
                      // to it (a dynamic reference never evicts a static one)
  uint pad0;          // std430 padding
};
struct SpillEntry {
  uint cell;     // the cell's linear index (cell_linear_index)
  uint ref;      // the reference no slot of it took
  uint arrival;  // the entry pushed before it onto the same arrival list, kSpillEnd at the end
  uint next;     // the entry with the next larger reference in the same list (the order pass)
};

// ---- References: (instance << 16) | triangle ----
SH_INLINE uint ref_pack(uint instance, uint triangle) {
  return (instance << 16u) | (triangle & 0xFFFFu);
}
SH_INLINE uint ref_instance(uint ref) { return ref >> 16u; }
SH_INLINE uint ref_triangle(uint ref) { return ref & 0xFFFFu; }

// ---- Texel addressing: image cell c's slot s at x = c.x * (capacity + 1) + s, status at s = capacity ----
// The scene axis that carries the slots (kGridSlotAxis* bits of flags).
SH_INLINE uint grid_slot_axis(SH_IN(GridParams) g) {
  return (g.flags & kGridSlotAxisMask) >> kGridSlotAxisShift;
}
// A scene cell (or cell count) as the image lays it out: the slot axis swapped with x.
SH_INLINE uvec3 image_cell(SH_IN(GridParams) g, SH_IN(uvec3) c) {
  uint a = grid_slot_axis(g);
  if (a == 1u) return uvec3(c.y, c.x, c.z);
  if (a == 2u) return uvec3(c.z, c.y, c.x);
  return c;
}
SH_INLINE uvec3 grid_image_extent(SH_IN(GridParams) g) {
  uvec3 n = image_cell(g, g.cells);
  return uvec3(n.x * (g.capacity + 1u), n.y, n.z);
}
// Slot s of an image cell (no axis swap: the layout primitive).
SH_INLINE uvec3 slot_texel(SH_IN(uvec3) cell, uint slot, uint capacity) {
  return uvec3(cell.x * (capacity + 1u) + slot, cell.y, cell.z);
}
SH_INLINE uvec3 status_texel(SH_IN(uvec3) cell, uint capacity) {
  return slot_texel(cell, capacity, capacity);
}
// Slot s and the status texel of scene cell `cell`: what every pass addresses.
SH_INLINE uvec3 cell_slot_texel(SH_IN(GridParams) g, SH_IN(uvec3) cell, uint slot) {
  return slot_texel(image_cell(g, cell), slot, g.capacity);
}
SH_INLINE uvec3 cell_status_texel(SH_IN(GridParams) g, SH_IN(uvec3) cell) {
  return status_texel(image_cell(g, cell), g.capacity);
}
// ---- The dirty-cell list of scene update (a work list, worklist.h; docs/SPEC.md "Scene update") ----
// Items: the linear indices of the cells the dynamic instances reached (x fastest), each once;
// after the items (one per cell at most) one bit per cell says whether it is listed.
SH_INLINE uint grid_cell_count(SH_IN(GridParams) g) { return g.cells.x * g.cells.y * g.cells.z; }
SH_INLINE uint cell_linear_index(SH_IN(GridParams) g, SH_IN(uvec3) cell) {
  return (cell.z * g.cells.y + cell.y) * g.cells.x + cell.x;
}
SH_INLINE uvec3 cell_of_linear_index(SH_IN(GridParams) g, uint i) {
  return uvec3(i % g.cells.x, sh_udiv(i, g.cells.x) % g.cells.y, sh_udiv(i, g.cells.x * g.cells.y));
}
// The item (word after the header) holding cell i's listed bit, and the bit.
SH_INLINE uint dirty_bit_item(SH_IN(GridParams) g, uint i) { return grid_cell_count(g) + i / 32u; }
SH_INLINE uint dirty_bit(uint i) { return 1u << (i % 32u); }
// Words of the whole buffer: header, items, bits.
SH_INLINE uint dirty_list_words(SH_IN(GridParams) g) {
  return kWorkListHeaderWords + grid_cell_count(g) + (grid_cell_count(g) + 31u) / 32u;
}

// The spill heads buffer, per cell: the smallest entry of its static list, of its dynamic list
// (what the trace walks), then the last arrival of each (what the build pushes onto).
// `cell` is the linear index (cell_linear_index, SpillEntry::cell).
SH_INLINE uint spill_head_index(uint cell, bool dynamic) { return 4u * cell + (dynamic ? 1u : 0u); }
SH_INLINE uint spill_arrival_index(uint cell, bool dynamic) { return 4u * cell + (dynamic ? 3u : 2u); }
// The compact layout (kGridCompact; docs/SPEC.md "Compact layout"). The spill heads buffer holds
// a header of kCompactHeadsHeader words, the dynamic region's box of cells (lo.xyz, pad, hi.xyz,
// pad: every cell a dynamic reference can reach over the animation), then per region cell (x
// fastest) two words: the ordered head of its dynamic list and its last arrival.
//
// The offsets buffer, without kGridSparseOffsets: cells + 1 words, cell i's static references are
// refs[offsets[i] .. offsets[i + 1]). With it, it indexes the runs of the occupied cells only (a
// cell is occupied when it holds a static reference; 95-97 % of a fine grid's cells hold none). Per word of 32 cells (cells
// 32 w .. 32 w + 31 in cell_linear_index order) two words: its base, the occupied cells before it,
// and its occupancy mask (bit b: cell 32 w + b is occupied). Then, from compact_runs_base, per
// occupied cell in cell order the start of its run, and last the total: the k-th occupied cell's
// static references are refs[offsets[runs + k] .. offsets[runs + k + 1]). So a cell costs a
// quarter of a byte plus 4 bytes if occupied, where one offset per cell cost 4.
SH_CONST uint kCompactHeadsHeader = 8u;
SH_CONST uint kCompactBlock = 256u;      // the offsets pass: cells per block of the scan
SH_CONST uint kCompactScanLanes = 1024u; // the offsets pass: lanes of the blocks' scan (one workgroup)
SH_INLINE bool region_contains(SH_IN(uvec3) c, SH_IN(uvec3) lo, SH_IN(uvec3) hi) {
  return c.x >= lo.x && c.y >= lo.y && c.z >= lo.z && c.x <= hi.x && c.y <= hi.y && c.z <= hi.z;
}
SH_INLINE uint region_index(SH_IN(uvec3) c, SH_IN(uvec3) lo, SH_IN(uvec3) hi) {
  uvec3 n = hi - lo + uvec3(1u);
  uvec3 r = c - lo;
  return (r.z * n.y + r.y) * n.x + r.x;
}
SH_INLINE uint region_cell_count(SH_IN(uvec3) lo, SH_IN(uvec3) hi) {
  uvec3 n = hi - lo + uvec3(1u);
  return n.x * n.y * n.z;
}
SH_INLINE uint compact_word_count(uint cells) { return (cells + 31u) / 32u; }
SH_INLINE uint compact_runs_base(uint cells) { return 2u * compact_word_count(cells); }
SH_INLINE uint compact_base_index(uint i) { return 2u * (i / 32u); }      // cell i's word's base
SH_INLINE uint compact_mask_index(uint i) { return 2u * (i / 32u) + 1u; }  // and its mask
SH_INLINE bool compact_occupied(uint mask, uint i) { return ((mask >> (i % 32u)) & 1u) != 0u; }
// Where the run of occupied cell i starts in the offsets buffer (its end is the next word): the
// word's base plus the occupied cells before i in its word.
SH_INLINE uint compact_run_index(uint cells, uint base, uint mask, uint i) {
  return compact_runs_base(cells) + base + uint(bitCount(mask & ((1u << (i % 32u)) - 1u)));
}
// The offsets buffer's words: the index, the occupied cells' starts and the total.
SH_INLINE uint compact_offsets_words(uint cells, uint occupied) { return compact_runs_base(cells) + occupied + 1u; }
SH_INLINE uint compact_head_index(uint region_cell) { return kCompactHeadsHeader + 2u * region_cell; }
SH_INLINE uint compact_arrival_index(uint region_cell) { return kCompactHeadsHeader + 2u * region_cell + 1u; }

// Linear index of a texel, x fastest (the layout of AccelDump::texels).
SH_INLINE uint texel_index(SH_IN(uvec3) texel, SH_IN(uvec3) extent) {
  return (texel.z * extent.y + texel.y) * extent.x + texel.x;
}

// ---- Cell coordinates ----
// A point in cell units relative to the grid's origin: (p - origin) * inv_cell_size.
SH_INLINE vec3 grid_local(SH_IN(GridParams) g, SH_IN(vec3) p) {
  SH_PRECISE vec3 d = p - g.origin;
  SH_PRECISE vec3 f = d * g.inv_cell_size;
  return f;
}

// floor of a local coordinate, clamped in float to [0, cells - 1] before the conversion (a huge,
// infinite or negative value never reaches the float -> uint conversion).
SH_INLINE uvec3 cell_of_local(SH_IN(GridParams) g, SH_IN(vec3) f) {
  vec3 fl = floor(f);
  vec3 hi = vec3(g.cells - uvec3(1u));
  vec3 c = min(max(fl, vec3(0.0f)), hi);
  return uvec3(c);
}

SH_INLINE uvec3 cell_of_point(SH_IN(GridParams) g, SH_IN(vec3) p) {
  return cell_of_local(g, grid_local(g, p));
}

// Whether a point lies in the grid box, judged on the same local coordinates as cell_of_point.
SH_INLINE bool grid_contains(SH_IN(GridParams) g, SH_IN(vec3) p) {
  vec3 f = grid_local(g, p);
  return f.x >= 0.0f && f.y >= 0.0f && f.z >= 0.0f && f.x < float(g.cells.x) &&
         f.y < float(g.cells.y) && f.z < float(g.cells.z);
}

// Centre of a cell: origin + (c + 0.5) * cell_size.
SH_INLINE vec3 cell_center(SH_IN(GridParams) g, SH_IN(uvec3) c) {
  SH_PRECISE vec3 k = vec3(c) + vec3(0.5f);
  SH_PRECISE vec3 w = k * g.cell_size;
  SH_PRECISE vec3 p = g.origin + w;
  return p;
}

// ---- Build: the triangle's cell range and the plane test (paper 2.1) ----
// The cells overlapping the triangle's AABB, padded by aabb_padding cell units on each side so
// that a triangle touching a cell face is in the cells on both sides.
SH_INLINE void triangle_cell_range(SH_IN(GridParams) g, SH_IN(vec3) v0, SH_IN(vec3) v1,
                                   SH_IN(vec3) v2, SH_OUT(uvec3) lo, SH_OUT(uvec3) hi) {
  vec3 f0 = grid_local(g, v0);
  vec3 f1 = grid_local(g, v1);
  vec3 f2 = grid_local(g, v2);
  SH_PRECISE vec3 fmin = min(min(f0, f1), f2) - vec3(g.aabb_padding);
  SH_PRECISE vec3 fmax = max(max(f0, f1), f2) + vec3(g.aabb_padding);
  lo = cell_of_local(g, fmin);
  hi = cell_of_local(g, fmax);
}

// The cell test's unit: the power of two S with S * cell_size in [1, 2) (from the bits of
// cell_size, a normal float). Scaling by S is exact, so a test evaluated in units of S^-1 (about a
// cell) takes the decisions it takes in world units wherever those stay in the normal range, and
// keeps them where world units would not: a model 1e-6 across squares products of about 1e-21
// into denormals (1e-42), which a device may flush to zero (lavapipe's geometry shaders do; its
// compute shaders do not), so that the raster and compute builds differed.
SH_INLINE float cell_test_scale(SH_IN(GridParams) g) {
  uint e = (floatBitsToUint(g.cell_size) >> 23u) & 0xFFu;
  return uintBitsToFloat((254u - e) << 23u);
}

// Plane vs enlarged cell bounding sphere, without sqrt or division: the plane through v0 with
// normal n passes within sqrt(r2) of `center` iff s*s <= r2 * nn with s = dot(n, center - v0) and
// nn = dot(n, n), evaluated in the cell test's unit (`scale` = cell_test_scale: n scaled by
// scale^2, center - v0 by scale, r2 by scale^2, each exactly). Finite while edges and the grid's
// extent stay below 2^20 cells; an overflow of both sides to +inf accepts (conservative).
SH_INLINE bool plane_intersects_enlarged_sphere(SH_IN(vec3) v0, SH_IN(vec3) n, SH_IN(vec3) center, float r2,
                                                float scale) {
  SH_PRECISE vec3 d = (center - v0) * scale;
  SH_PRECISE vec3 m = (n * scale) * scale;
  SH_PRECISE float s = sh_dot(m, d);
  SH_PRECISE float mm = sh_dot(m, m);
  SH_PRECISE float lhs = s * s;
  SH_PRECISE float r2s = (r2 * scale) * scale;
  SH_PRECISE float rhs = r2s * mm;
  return lhs <= rhs;
}

// ---- Build: the separating-axis test (kGridCellBox; docs/SPEC.md "Scene build", *Separating axes*) ----
// Akenine-Moller's triangle/box overlap test, in cell units (grid_local, the coordinates the cell
// range is made of) around the cell's centre m = cell + 0.5 (exact), the box's half edge
// h = 0.5 + aabb_padding + 8 u M / cell_size (u = 2^-24, M the grid corners' largest |coordinate|:
// the trace's cell boundaries origin + k cell_size are world-space floats, and they and the ray
// parameters computed from them round by up to about that much). The box's own three axes are
// the cell range's (triangle_cell_range, the same local coordinates and padding); this adds the triangle's plane and the nine products of an
// edge with a box axis. Any vector is a valid separating axis, so the rounded edges and normal
// may serve as axes; what must be conservative is the projection. On axis a the triangle projects
// to p_k = a . (f_k - m) and the box to [-r, r], r = h |a|_1; a vertex moved by the padding per
// component moves p_k by at most the padding's part of r, so the test forgives the same vertex
// rounding as the range. The float evaluation of p_k and r errs by less than 8 u (S + r)
// (S = max_k |a| . |f_k - m|, the sums' magnitude), and the test declares a separation
// only beyond r + kSatMargin (S + r), kSatMargin = 2^-20 = 16 u. A NaN or infinite projection
// (out-of-domain magnitudes) separates nothing: the cell keeps the triangle.
SH_CONST float kSatMargin = 9.5367431640625e-07f;  // 2^-20
SH_CONST float kSatWorldSlack = 4.76837158203125e-07f;  // 2^-21 = 8 u

// Whether axis `a` separates the triangle (its vertices relative to the centre, d0..d2) from the
// box of half edge h.
SH_INLINE bool sat_axis_separates(SH_IN(vec3) a, SH_IN(vec3) d0, SH_IN(vec3) d1, SH_IN(vec3) d2, float h) {
  SH_PRECISE float p0 = sh_dot(a, d0);
  SH_PRECISE float p1 = sh_dot(a, d1);
  SH_PRECISE float p2 = sh_dot(a, d2);
  SH_PRECISE vec3 aa = abs(a);
  SH_PRECISE float a1 = (aa.x + aa.y) + aa.z;
  SH_PRECISE float r = h * a1;
  SH_PRECISE float s0 = sh_dot(aa, abs(d0));
  SH_PRECISE float s1 = sh_dot(aa, abs(d1));
  SH_PRECISE float s2 = sh_dot(aa, abs(d2));
  SH_PRECISE float sum = max(max(s0, s1), s2) + r;
  SH_PRECISE float slack = kSatMargin * sum;
  SH_PRECISE float bound = r + slack;
  float lo = min(min(p0, p1), p2);
  float hi = max(max(p0, p1), p2);
  return lo > bound || hi < -bound;
}

// The triangle's plane and the nine edge x axis products: true when none separates the triangle
// (world vertices v0, v1, v2) from cell `cell` padded by aabb_padding.
SH_INLINE bool triangle_box_overlap(SH_IN(GridParams) g, SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2,
                                    SH_IN(uvec3) cell) {
  SH_PRECISE vec3 m = vec3(cell) + vec3(0.5f);
  // The half edge: the padding, and the rounding of the trace's world-space cell boundaries
  // (8 u of the grid's largest coordinate, in cell units)
  SH_PRECISE vec3 ao = max(abs(g.origin), abs(g.upper));
  SH_PRECISE float big = max(max(ao.x, ao.y), ao.z);
  SH_PRECISE float world = big * g.inv_cell_size;
  SH_PRECISE float slack = kSatWorldSlack * world;
  SH_PRECISE float h = (0.5f + g.aabb_padding) + slack;
  SH_PRECISE vec3 d0 = grid_local(g, v0) - m;
  SH_PRECISE vec3 d1 = grid_local(g, v1) - m;
  SH_PRECISE vec3 d2 = grid_local(g, v2) - m;
  SH_PRECISE vec3 e0 = d1 - d0;
  SH_PRECISE vec3 e1 = d2 - d1;
  SH_PRECISE vec3 e2 = d0 - d2;
  // The plane: its normal in cell units
  if (sat_axis_separates(sh_cross(e0, e1), d0, d1, d2, h)) return false;
  // Edge x x, edge x y, edge x z (written out: one component is 0)
  if (sat_axis_separates(vec3(0.0f, e0.z, -e0.y), d0, d1, d2, h)) return false;
  if (sat_axis_separates(vec3(0.0f, e1.z, -e1.y), d0, d1, d2, h)) return false;
  if (sat_axis_separates(vec3(0.0f, e2.z, -e2.y), d0, d1, d2, h)) return false;
  if (sat_axis_separates(vec3(-e0.z, 0.0f, e0.x), d0, d1, d2, h)) return false;
  if (sat_axis_separates(vec3(-e1.z, 0.0f, e1.x), d0, d1, d2, h)) return false;
  if (sat_axis_separates(vec3(-e2.z, 0.0f, e2.x), d0, d1, d2, h)) return false;
  if (sat_axis_separates(vec3(e0.y, -e0.x, 0.0f), d0, d1, d2, h)) return false;
  if (sat_axis_separates(vec3(e1.y, -e1.x, 0.0f), d0, d1, d2, h)) return false;
  if (sat_axis_separates(vec3(e2.y, -e2.x, 0.0f), d0, d1, d2, h)) return false;
  return true;
}

// ---- Build: the cell test, written once (build.cpp, build.glsl, plan/, the verify referee) ----
// Whether a cell of the triangle's range (triangle_cell_range) takes its reference: its plane
// passes through the cell's enlarged bounding sphere (paper 2.1; n its normal, dot(n, n) > 0)
// and, with kGridCellBox, no separating axis parts it from the padded cell box.
SH_INLINE bool triangle_overlaps_cell(SH_IN(GridParams) g, SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2,
                                      SH_IN(vec3) n, SH_IN(uvec3) cell) {
  if (!plane_intersects_enlarged_sphere(v0, n, cell_center(g, cell), g.sphere_r2, cell_test_scale(g))) return false;
  return (g.flags & kGridCellBox) == 0u || triangle_box_overlap(g, v0, v1, v2, cell);
}

// ---- Rays ----
SH_INLINE bool sh_finite(float x) { return (floatBitsToUint(x) & 0x7F800000u) != 0x7F800000u; }
SH_INLINE bool sh_nan(float x) {
  return (floatBitsToUint(x) & 0x7FFFFFFFu) > 0x7F800000u;
}
SH_INLINE float sh_infinity() { return uintBitsToFloat(0x7F800000u); }

// ---- The domain (docs/SPEC.md, "Domain") ----
// A ray is traced iff ray_domain() is kDomainOk; others miss with kHitRejected on every backend
// (the Embree oracle applies the same rule). Inside the domain every product the triangle tests
// form stays finite (watertight: |v - org| <= 2^25 and the largest |dir| component <= 2^20 give
// |T| < 2^121) and an accepted hit has T > 0 (tmin >= 0), so no test yields a NaN t.
SH_CONST float kDomainMaxCoordinate = 16777216.0f;     // 2^24: |org| and scene vertex components
// 2^-40: the least largest side of a scene's box. Below it the watertight test's T, a product of
// three coordinate differences (|T| ~ extent^3 for rays of unit length from within the scene's
// reach), falls out of float's normal range: t loses its bits, then every test rejects (a scene of
// 1e-15 rendered blank with exit 0; at 1e-13 t was off by 2,000 ulps, at 1e-12 by 2).
SH_CONST float kDomainMinExtent = 9.094947017729282e-13f;
SH_CONST float kDomainMinDirection = 9.5367431640625e-07f;  // 2^-20: the largest |dir| component,
SH_CONST float kDomainMaxDirection = 1048576.0f;       // 2^20:  at least / at most
SH_CONST uint kDomainOk = 0u;
SH_CONST uint kDomainNonFinite = 1u;   // a NaN or infinite component of org or dir
SH_CONST uint kDomainDirection = 2u;   // the largest |dir| component outside [2^-20, 2^20] (a zero dir)
SH_CONST uint kDomainOrigin = 3u;      // an |org| component above 2^24
SH_CONST uint kDomainInterval = 4u;    // tmin or tmax NaN, or tmin < 0

SH_INLINE uint ray_domain(SH_IN(vec3) org, SH_IN(vec3) dir, float tmin, float tmax) {
  if (!(sh_finite(org.x) && sh_finite(org.y) && sh_finite(org.z) && sh_finite(dir.x) && sh_finite(dir.y) &&
        sh_finite(dir.z)))
    return kDomainNonFinite;
  SH_PRECISE vec3 ad = abs(dir);
  SH_PRECISE float m = max(max(ad.x, ad.y), ad.z);
  if (!(m >= kDomainMinDirection && m <= kDomainMaxDirection)) return kDomainDirection;
  SH_PRECISE vec3 ao = abs(org);
  if (!(max(max(ao.x, ao.y), ao.z) <= kDomainMaxCoordinate)) return kDomainOrigin;
  if (sh_nan(tmin) || sh_nan(tmax) || tmin < 0.0f) return kDomainInterval;
  return kDomainOk;
}

// Whether the ray is traced (inside the domain).
SH_INLINE bool ray_valid(SH_IN(vec3) org, SH_IN(vec3) dir, float tmin, float tmax) {
  return ray_domain(org, dir, tmin, tmax) == kDomainOk;
}

// The origin epsilon (docs/SPEC.md, "Origin epsilon"): a ray's origin is a float point, often
// one rounded onto a surface (a bounce's launch point, an origin on a wall); the triangles through
// it (the launch triangle's neighbours across an edge or a vertex, a coplanar overlapping face, the
// wall) contain the exact origin, so the exact ray meets them at t = 0, which is no hit (t > tmin),
// while a float test finds them at a t just above 0. Every ray therefore needs
// t > kOriginEpsilon * (largest |org| component) / (largest |dir| component): 8 ulps of the
// origin's largest coordinate, along the ray.
SH_CONST float kOriginEpsilon = 9.5367431640625e-07f;  // 2^-20
// The direction the trace walks and tests: a component below the float's normal range
// (|d| < 2^-126, a subnormal) is taken as +0, by its exponent bits, the same on every backend.
// Its reciprocal overflows to inf, and an origin exactly on a cell plane then gave the DDA an exit
// of 0 * inf = NaN: the walk stepped along the wrong axis for ever and left the grid without the
// wall in front of it (an outside sweep: 5-7 % of such rays from inside closed meshes missed, on
// both backends alike); a flushing device read the component as 0 while the CPU did not. Over any
// span of the domain such a component moves the ray by less than 2^-80 of a unit, far below the
// padding of a triangle's cells, so no cell the ray needs is left out.
SH_INLINE vec3 traced_direction(SH_IN(vec3) dir) { return normal_or_zero3(dir); }

SH_INLINE float origin_tmin(SH_IN(vec3) org, SH_IN(vec3) dir, float tmin) {
  SH_PRECISE vec3 ao = abs(org);
  SH_PRECISE vec3 ad = abs(dir);
  SH_PRECISE float m = max(max(ao.x, ao.y), ao.z) * kOriginEpsilon;
  SH_PRECISE float d = max(max(ad.x, ad.y), ad.z);
  SH_PRECISE float eps = sh_div(m, d);
  return max(tmin, eps);
}

// Veltkamp's split: the high half (12 significant bits) of a; a - hi is the low half, exactly.
SH_INLINE float sh_split_high(float a) {
  SH_PRECISE float c = 4097.0f * a;
  SH_PRECISE float d = c - a;
  SH_PRECISE float hi = c - d;
  return hi;
}

// Dekker's product: the rounding error of p = fl(a * b), a * b - p, exactly (round to nearest,
// no overflow, the error a normal float: |a * b| above about 2^-100).
SH_INLINE float sh_product_error(float a, float b, float p) {
  SH_PRECISE float ah = sh_split_high(a);
  SH_PRECISE float al = a - ah;
  SH_PRECISE float bh = sh_split_high(b);
  SH_PRECISE float bl = b - bh;
  SH_PRECISE float e0 = ah * bh - p;
  SH_PRECISE float e1 = e0 + ah * bl;
  SH_PRECISE float e2 = e1 + al * bh;
  SH_PRECISE float e = e2 + al * bl;
  return e;
}

// Knuth's two-sum for a difference: x - y - s exactly, s = fl(x - y) (round to nearest, no
// overflow): an edge as the sum of two floats.
SH_INLINE float sh_difference_error(float x, float y, float s) {
  SH_PRECISE float my = -y;
  SH_PRECISE float bv = s - x;
  SH_PRECISE float av = s - bv;
  SH_PRECISE float ea = x - av;
  SH_PRECISE float eb = my - bv;
  SH_PRECISE float e = ea + eb;
  return e;
}

// One component a1 b2 - a2 b1 of the cross product of the exact edges a + la and b + lb: the two
// products' rounding errors taken exactly (Dekker), the low parts' products in float (they are
// an ulp of the high ones), their square dropped. Where a1 b2 and a2 b1 nearly cancel (a cap's
// edges) this keeps the component to a few ulps of itself, where fl(a1 b2) - fl(a2 b1) keeps it
// to an ulp of the products.
SH_INLINE float cross_term_refined(float a1, float b2, float a2, float b1, float la1, float lb2, float la2, float lb1) {
  SH_PRECISE float p = a1 * b2;
  SH_PRECISE float q = a2 * b1;
  SH_PRECISE float d = p - q;
  SH_PRECISE float ep = sh_product_error(a1, b2, p);
  SH_PRECISE float eq = sh_product_error(a2, b1, q);
  SH_PRECISE float e = ep - eq;
  SH_PRECISE float c1 = a1 * lb2;
  SH_PRECISE float c2 = la1 * b2;
  SH_PRECISE float c3 = a2 * lb1;
  SH_PRECISE float c4 = la2 * b1;
  SH_PRECISE float c12 = c1 + c2;
  SH_PRECISE float c34 = c3 + c4;
  SH_PRECISE float c = c12 - c34;
  SH_PRECISE float lo = e + c;
  SH_PRECISE float n = d + lo;
  return n;
}

// The scale of the normal's rounding: |a|_1 |b|_1 for n = a x b (plane_normal_scaled), at least |n|_1
// (for a normal made again from the exact edges, its own 1-norm plus 2^-20 of this).
// A cross product's error is about ulp * |a| |b| whatever its length |a| |b| sin(angle): on a
// "cap" (three vertices nearly on a line, its largest angle near 180 degrees) every pair of edges
// meets at a small angle, and the normal's direction is off by ulp / sin(angle) (2e-4 rad on a
// torus stretched 1e4 times; docs/ACCURACY.md, "cap slivers"). The surface rule measures the
// plane value's rounding with it.
SH_INLINE float plane_normal_scale(SH_IN(vec3) a, SH_IN(vec3) b) {
  SH_PRECISE vec3 aa = abs(a);
  SH_PRECISE vec3 ab = abs(b);
  SH_PRECISE float sa = aa.x + aa.y;
  SH_PRECISE float na = sa + aa.z;
  SH_PRECISE float sb = ab.x + ab.y;
  SH_PRECISE float nb = sb + ab.z;
  SH_PRECISE float s = na * nb;
  return s;
}

// A normal whose length is below this fraction of its rounding scale (the sine of the angle
// between its edges below 1/16: a largest angle above about 176 degrees) is made again from the
// exact edges (cross_term_refined).
SH_CONST float kPlaneRefine = 16.0f;

// The normal (v1 - v0) x (v2 - v0) of the watertight test's plane equation and of the surface
// rule, made as the cross product of the triangle's two shortest edges, taken cyclically (e0 = v1
// - v0, e1 = v2 - v1, e2 = v0 - v2; e0 x e1 = e1 x e2 = e2 x e0 exactly), and in `scale` its
// rounding scale (plane_normal_scale). A cross product's error is u / sin of the angle between its
// factors; the angle between the two shortest edges is the triangle's largest, at least 60
// degrees, where the two edges from a sliver's apex meet at its smallest: on a fan of 300 slivers
// (apex angle 1.2 degrees) the apex's pair put t up to 405 ulps from the exact t on rays of
// condition number below 100, the shortest pair 27 (Embree 25; docs/ACCURACY.md, "t against the
// exact t"). On a cap (three vertices nearly on a line) every pair meets at a small angle: there
// (kPlaneRefine) the normal is made again from the exact edges, whose rounding was most of its
// error (a cap made of a rounded edge midpoint met rays at a t 5 % off, before a triangle in front
// of it: an outside sweep).
// Ties go to the first of e0, e1, e2 as the longest.
SH_INLINE vec3 plane_normal_scaled(SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2, SH_OUT(float) scale) {
  SH_PRECISE vec3 e0 = v1 - v0;
  SH_PRECISE vec3 e1 = v2 - v1;
  SH_PRECISE vec3 e2 = v0 - v2;
  SH_PRECISE float l0 = sh_dot(e0, e0);
  SH_PRECISE float l1 = sh_dot(e1, e1);
  SH_PRECISE float l2 = sh_dot(e2, e2);
  // a = q - p, b = r - q
  vec3 p = v0;
  vec3 q = v1;
  vec3 r = v2;
  vec3 a = e0;
  vec3 b = e1;
  if (l0 >= l1 && l0 >= l2) {
    p = v1;
    q = v2;
    r = v0;
    a = e1;
    b = e2;
  } else if (l1 >= l2) {
    p = v2;
    q = v0;
    r = v1;
    a = e2;
    b = e0;
  }
  vec3 n = sh_cross(a, b);
  scale = plane_normal_scale(a, b);
  SH_PRECISE vec3 an = abs(n);
  SH_PRECISE float ns = an.x + an.y;
  SH_PRECISE float n1 = ns + an.z;
  SH_PRECISE float refine_below = n1 * kPlaneRefine;
  if (refine_below < scale) {
    SH_PRECISE vec3 la = vec3(sh_difference_error(q.x, p.x, a.x), sh_difference_error(q.y, p.y, a.y),
                              sh_difference_error(q.z, p.z, a.z));
    SH_PRECISE vec3 lb = vec3(sh_difference_error(r.x, q.x, b.x), sh_difference_error(r.y, q.y, b.y),
                              sh_difference_error(r.z, q.z, b.z));
    n.x = cross_term_refined(a.y, b.z, a.z, b.y, la.y, lb.z, la.z, lb.y);
    n.y = cross_term_refined(a.z, b.x, a.x, b.z, la.z, lb.x, la.x, lb.z);
    n.z = cross_term_refined(a.x, b.y, a.y, b.x, la.x, lb.y, la.y, lb.x);
    // Its rounding is now a few ulps of itself (and of the dropped low products, ulp^2 of the
    // edges'): the scale the surface rule measures with shrinks to that, or its band would stay
    // 1 / sin wider than the normal's error (a review's find)
    SH_PRECISE vec3 anr = abs(n);
    SH_PRECISE float nrs = anr.x + anr.y;
    SH_PRECISE float nr1 = nrs + anr.z;
    SH_PRECISE float dropped = scale * 9.5367431640625e-07f;  // 2^-20
    scale = nr1 + dropped;
  }
  return n;
}
SH_INLINE vec3 plane_normal(SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2) {
  float scale;
  return plane_normal_scaled(v0, v1, v2, scale);
}

// The normal of the build's cell test (the enlarged sphere's plane, the separating axes' normal):
// plane_normal, the cross product of the triangle's two shortest edges, made again from the exact
// edges on a cap. Not (v1 - v0) x (v2 - v0): on a needle whose apex is v0 the two long edges meet
// at its smallest angle and their rounded cross product was 18 degrees off (0.9 by 9e-8), so that
// the sphere test left the needle out of cells it crosses, and rays from inside a closed sphere
// escaped between its polar needles (an outside sweep's find, 49 of 3,000).
SH_INLINE vec3 triangle_normal(SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2) { return plane_normal(v0, v1, v2); }

// A zero-area triangle, never inserted (no ray can hit it): the cross product of its edges is
// exactly zero, taken with the edges scaled by the power of two S that brings their largest
// component into [1, 2) (exact: the same products scaled by S^2, so zero exactly where the
// world-space cross product is, wherever that one stays in the normal range). In world units a
// triangle with edges 4e-12 long has dot(n, n) about 1e-46, which underflows to zero: testing that
// dropped triangles that rays hit; and n itself underflows (or is flushed, on devices that flush
// denormals) for edges below about 1e-19, where S keeps them.
SH_INLINE bool triangle_zero_area(SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2) {
  SH_PRECISE vec3 e1 = v1 - v0;
  SH_PRECISE vec3 e2 = v2 - v0;
  vec3 a = max(abs(e1), abs(e2));
  float m = max(max(a.x, a.y), a.z);
  // m == 0: both edges are zero; m not finite: no finite scale (such a triangle is out of domain
  // and refused by the loaders; it has area here, as before)
  if (m == 0.0f) return true;
  if (!(m <= 3.40282347e38f)) return false;
  float s = sh_unit_scale(m);
  SH_PRECISE vec3 f1 = e1 * s;
  SH_PRECISE vec3 f2 = e2 * s;
  // (A subnormal component counts as zero, on every device: lavapipe's geometry stage flushed
  // one of a needle whose edges differ in length by 1e25, took it for zero-area and left it out of
  // the raster build, where the reference kept it: an outside sweep)
  SH_PRECISE vec3 n = sh_flush_subnormal3(sh_cross(f1, f2));
  if (n.x != 0.0f || n.y != 0.0f || n.z != 0.0f) return false;
  // The float edges are parallel (or one is zero); the exact ones may not be: a cap whose third
  // vertex is an edge's float-rounded midpoint lies off the line by that rounding, has area, and
  // rays the watertight test hands it across its shared edges fell through a closed mesh where it
  // was dropped (an outside sweep's find: 86 of 4,000 rays from inside escaped). Decided on the
  // exact edges instead: plane_normal_scaled's normal made again from them (its refinement, taken
  // where the float one is zero), of the vertices scaled by S (exact; a vertex that S would take
  // past float's range leaves the float decision standing). Its products drop only the edges'
  // rounding errors' own products, a relative 2^-48 of the edges' squares.
  SH_PRECISE vec3 w0 = v0 * s;
  SH_PRECISE vec3 w1 = v1 * s;
  SH_PRECISE vec3 w2 = v2 * s;
  vec3 aw = max(max(abs(w0), abs(w1)), abs(w2));
  if (!(max(max(aw.x, aw.y), aw.z) <= 3.40282347e38f)) return true;
  vec3 r = sh_flush_subnormal3(plane_normal(w0, w1, w2));
  return r.x == 0.0f && r.y == 0.0f && r.z == 0.0f;
}


// One triangle's plane (the plane buffer, beside the geometry buffer): plane_normal_scaled of its
// world-space vertices, its normal and the normal's rounding scale. The build invocation that
// writes the triangle makes it, so that a trace reads it only where a test gets past the edge
// functions (watertight_rest_plane), and no trace loop carries the normal's code: the cap's
// refinement in every test cost 10-15 % of the trace on the H200 (docs/BENCHMARKS.md, "The plane
// buffer"). The same function on the same vertex bits, so the same bits as made in the test.
struct GridPlane {
  vec3 n;       // plane_normal_scaled's normal
  float scale;  // its rounding scale (plane_normal_scale, or the refined normal's)
};
SH_INLINE GridPlane triangle_plane(SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2) {
  GridPlane p;
  float scale;
  p.n = plane_normal_scaled(v0, v1, v2, scale);
  p.scale = scale;
  return p;
}

// The vertex the surface rule's plane value n . (v - org) is taken at: of A, B, C (= v0, v1, v2 -
// org), the one with the smallest largest |component| (the vertex nearest the origin; ties to the
// first). The value's rounding is the normal's error times |v - org|: taken at v0, a launch point
// on a long face's far end put a neighbour's plane value at the noise of the normal times the
// face's length (0.2 units on a cap 5,400 long, where the exact value is 0). (The watertight
// test's distance takes its value at the vertex nearest the hit instead: hit_anchor.)
SH_INLINE vec3 plane_anchor(SH_IN(vec3) A, SH_IN(vec3) B, SH_IN(vec3) C) {
  SH_PRECISE vec3 aa = abs(A);
  SH_PRECISE vec3 ab = abs(B);
  SH_PRECISE vec3 ac = abs(C);
  SH_PRECISE float ma = max(max(aa.x, aa.y), aa.z);
  SH_PRECISE float mb = max(max(ab.x, ab.y), ab.z);
  SH_PRECISE float mc = max(max(ac.x, ac.y), ac.z);
  vec3 p = A;
  float mp = ma;
  if (mb < mp) {
    p = B;
    mp = mb;
  }
  if (mc < mp) p = C;
  return p;
}

// The surface rule (docs/SPEC.md, "Origin epsilon"): the epsilon above is a distance along the
// ray, and a face the ray grazes is met at a t that grows as 1 / cos: a ray launched from a
// sliver's edge, leaving nearly in its neighbour's plane, met that neighbour (through the origin)
// at 1.5 to 3.2 times the epsilon on cones of 64 to 1000 slivers. So for a ray launched from a
// surface, a candidate is also refused when the face's plane passes within tol of the origin:
// |n . P| <= tol * scale, P = the face's vertex nearest the origin less the origin (plane_anchor),
// scale = |a|_1 |b|_1 of the cross product n = a x b (plane_normal_scale: the normal's rounding
// scale, at least |n|_1), tol = kOriginEpsilon * max(largest |org| component, largest |P|
// component): 8 ulps of the origin's coordinates (where the launch point was rounded) or of P's,
// whichever is larger (the plane value's own rounding, n's few ulps times |P|, scales with the
// latter: a long needle's face launched from near the world's origin, its vertices a thousand
// times farther away, passed its own launch point by more than 8 ulps of the origin), n =
// plane_normal_scaled (the two shortest edges' cross product: on a sliver the apex's two edges
// are nearly parallel and their cross product too rounded to tell). A ray from a point of a plane meets the plane
// only at t = 0 or lies in it, so no hit is lost but one within that plane's rounding. Every
// product stays finite in the 2^24 domain; a zero-area face (n = 0) is refused, as det == 0
// already does.
// The watertight test makes the same decision from its own plane values (watertight_rest's
// `surface_tol`): no products of its own in the exact traversal's loop.
SH_INLINE float surface_rule_tol(SH_IN(vec3) org) {
  SH_PRECISE vec3 ao = abs(org);
  SH_PRECISE float tol = max(max(ao.x, ao.y), ao.z) * kOriginEpsilon;
  return tol;
}
// The tolerance for one face: the origin's (surface_rule_tol) or 8 ulps of the largest component
// of `a` = org - v0 (or v0 - org: the same magnitudes), whichever is larger.
SH_INLINE float surface_rule_face_tol(float origin_tol, SH_IN(vec3) a) {
  SH_PRECISE vec3 aa = abs(a);
  SH_PRECISE float face = max(max(aa.x, aa.y), aa.z) * kOriginEpsilon;
  return max(origin_tol, face);
}
// The rule's decision from a face's plane value `pnum` = n . P at its anchor P (plane_anchor) and
// the normal's scale (plane_normal_scale): |n . P| <= tol * scale, tol the face's
// (surface_rule_face_tol of the origin's and P).
SH_INLINE bool plane_near_origin(float pnum, float scale, float origin_tol, SH_IN(vec3) P) {
  SH_PRECISE float dist = abs(pnum);
  SH_PRECISE float bound = surface_rule_face_tol(origin_tol, P) * scale;
  return dist <= bound;
}
SH_INLINE bool origin_on_plane(SH_IN(vec3) org, SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2) {
  float scale;
  vec3 n = plane_normal_scaled(v0, v1, v2, scale);
  SH_PRECISE vec3 A = v0 - org;
  SH_PRECISE vec3 B = v1 - org;
  SH_PRECISE vec3 C = v2 - org;
  vec3 P = plane_anchor(A, B, C);
  SH_PRECISE float pnum = sh_dot(n, P);
  return plane_near_origin(pnum, scale, surface_rule_tol(org), P);
}

SH_INLINE vec3 point_at(SH_IN(vec3) org, SH_IN(vec3) dir, float t) {
  SH_PRECISE vec3 td = dir * t;
  SH_PRECISE vec3 p = org + td;
  return p;
}

// One slab of the grid-box clip; a zero direction component keeps or rejects the whole ray.
SH_INLINE bool clip_slab(float o, float d, float lo, float hi, SH_INOUT(float) t0,
                         SH_INOUT(float) t1) {
  if (d == 0.0f) return o >= lo && o <= hi;
  SH_PRECISE float inv = sh_rcp(d);
  SH_PRECISE float ta = (lo - o) * inv;
  SH_PRECISE float tb = (hi - o) * inv;
  t0 = max(t0, min(ta, tb));
  t1 = min(t1, max(ta, tb));
  return true;
}

// The ray's parameter interval inside the grid box [origin, upper] (one division per axis).
SH_INLINE bool clip_to_grid(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir,
                            SH_OUT(float) t0, SH_OUT(float) t1) {
  t0 = -sh_infinity();
  t1 = sh_infinity();
  bool ok = clip_slab(org.x, dir.x, g.origin.x, g.upper.x, t0, t1);
  ok = clip_slab(org.y, dir.y, g.origin.y, g.upper.y, t0, t1) && ok;
  ok = clip_slab(org.z, dir.z, g.origin.z, g.upper.z, t0, t1) && ok;
  return ok && t0 <= t1;
}

// x, with -0 made +0.
SH_INLINE float positive_zero(float x) { return floatBitsToUint(x) == 0x80000000u ? 0.0f : x; }

// Per-ray values both traversals start from, computed once per ray.
struct RaySetup {
  float seg_t;    // one cell edge in t units: cell_size / sqrt(dot(dir, dir))
  float t_start;  // max(tmin, grid entry): paper segment 0 starts here, the DDA starts here
  float t_end;    // min(tmax, grid exit)
  float t_lo;     // hits need t > t_lo = max(tmin, self_hit_offset * seg_t)
};

// False when the ray misses the grid box, its (tmin, tmax) interval lies outside it, or the
// interval is empty (tmin >= tmax, e.g. the unused rays of a gather buffer).
SH_INLINE bool ray_setup(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir, float tmin,
                         float tmax, SH_OUT(RaySetup) rs) {
  SH_PRECISE float dd = sh_dot(dir, dir);
  SH_PRECISE float len = sh_sqrt(dd);
  rs.seg_t = sh_div(g.cell_size, len);
  SH_PRECISE float self_t = g.self_hit_offset * rs.seg_t;
  rs.t_lo = max(tmin, self_t);
  float t0;
  float t1;
  bool hit = clip_to_grid(g, org, dir, t0, t1);
  // A zero as +0: min and max of -0 and +0 (an origin on the box's face, a slab's (lo - o) * inv)
  // may give either on a GPU, where C++'s give the first; the walk reads no sign of a zero, the
  // explain record prints it (taken by the bits: a compiler may fold a comparison with zero)
  rs.t_start = positive_zero(max(tmin, t0));
  rs.t_end = positive_zero(min(tmax, t1));
  return hit && rs.t_start <= rs.t_end && tmin < tmax;
}

// ---- Far origins (docs/SPEC.md "Far origins") ----
// The DDA's cell boundaries and the triangle tests both start from `x - org`, which rounds to the
// origin's ulps: where 64 ulps of the origin's largest coordinate exceed a cell (a camera 5e5 away
// from a model of cells 0.02 wide), the cells the DDA walks and the ray the tests see part by more
// than a cell, and a ray could pass a closed surface between the two. Such a ray is traced from
// its origin moved along it to just before the grid box: org + t_base dir, t_base the box entry
// less 2^-20 of it (more than the entry's and the move's rounding), computed once, the rest of the
// trace in the moved ray's parameter, and the hit's t reported as t_base + t. The moved origin
// lies off the ray by the rounding of t_base dir (about half an ulp of the origin's coordinates):
// the answer is the exact one of a ray whose origin moved within that, as the triangle tests'
// `v - org` already allowed; the walk and the tests now agree on which ray it is.
SH_CONST float kFarOriginRatio = 7.62939453125e-06f;      // 2^-17: 64 ulps of a coordinate
SH_CONST float kFarOriginBack = 0.99999904632568359375f;  // 1 - 2^-20
// 0 where the ray's origin is not far or the ray misses the grid box; else t_base.
SH_INLINE float far_origin_base(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir, float tmin, float tmax) {
  SH_PRECISE vec3 ao = abs(org);
  SH_PRECISE float reach = max(max(ao.x, ao.y), ao.z) * kFarOriginRatio;
  if (!(reach > g.cell_size)) return 0.0f;
  RaySetup rs;
  if (!ray_setup(g, org, dir, tmin, tmax, rs)) return 0.0f;
  SH_PRECISE float tb = rs.t_start * kFarOriginBack;
  return tb;
}

// ---- Paper traversal: segment k covers [t_start + k L, t_start + (k+1) L], L = seg_t ----
SH_INLINE float segment_t(SH_IN(RaySetup) rs, float k) {
  SH_PRECISE float kl = k * rs.seg_t;
  SH_PRECISE float t = rs.t_start + kl;
  return t;
}
SH_INLINE float segment_begin(SH_IN(RaySetup) rs, uint k) { return segment_t(rs, float(k)); }
SH_INLINE float segment_end(SH_IN(RaySetup) rs, uint k) { return segment_t(rs, float(k + 1u)); }
// The sample point's parameter: the segment's midpoint.
SH_INLINE float segment_sample_t(SH_IN(RaySetup) rs, uint k) {
  return segment_t(rs, float(k) + 0.5f);
}
// The elongated segment [k L - e L, (k+1) L + e L] the triangle tests use.
SH_INLINE float segment_elongated_begin(SH_IN(GridParams) g, SH_IN(RaySetup) rs, uint k) {
  SH_PRECISE float k0 = float(k) - g.elongation;
  return segment_t(rs, k0);
}
SH_INLINE float segment_elongated_end(SH_IN(GridParams) g, SH_IN(RaySetup) rs, uint k) {
  SH_PRECISE float k1 = float(k + 1u) + g.elongation;
  return segment_t(rs, k1);
}

// Gap-fill's "has the segment left the launch surface" test (paper 2.3), free of sqrt and
// division: with d = sample_point - org and n the launch normal, (dot(d, n))^2 >= g2 * dot(n, n); for
// rays without a launch normal (n == 0), dot(d, d) >= g2. `values` returns (lhs, rhs).
SH_INLINE bool gap_fill_left_surface(SH_IN(vec3) sample_point, SH_IN(vec3) org, SH_IN(vec3) n, float g2,
                                     SH_OUT(vec2) values) {
  SH_PRECISE vec3 d = sample_point - org;
  SH_PRECISE float nn = sh_dot(n, n);
  if (nn > 0.0f) {
    SH_PRECISE float s = sh_dot(d, n);
    SH_PRECISE float lhs = s * s;
    SH_PRECISE float rhs = g2 * nn;
    values = vec2(lhs, rhs);
    return lhs >= rhs;
  }
  SH_PRECISE float dd = sh_dot(d, d);
  values = vec2(dd, g2);
  return dd >= g2;
}

// ---- Exact traversal: 3D DDA (Amanatides-Woo) ----
// The parameter at which the ray leaves cell index c along one axis (d the direction component,
// inv = 1 / d): the far boundary origin + (c + 1) * cell_size for d > 0, the near one
// origin + c * cell_size for d < 0, +inf for d == 0. Recomputed from the cell index at each step
// (no accumulated tDelta).
SH_INLINE float dda_axis_exit(float origin, float cell_size, float o, float d, float inv, uint c) {
  if (d == 0.0f) return sh_infinity();
  uint k = d > 0.0f ? c + 1u : c;
  SH_PRECISE float w = float(k) * cell_size;
  SH_PRECISE float b = origin + w;
  SH_PRECISE float t = (b - o) * inv;
  return t;
}

SH_INLINE vec3 dda_exits(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir,
                         SH_IN(vec3) inv_dir, SH_IN(uvec3) cell) {
  return vec3(dda_axis_exit(g.origin.x, g.cell_size, org.x, dir.x, inv_dir.x, cell.x),
              dda_axis_exit(g.origin.y, g.cell_size, org.y, dir.y, inv_dir.y, cell.y),
              dda_axis_exit(g.origin.z, g.cell_size, org.z, dir.z, inv_dir.z, cell.z));
}

// 1 / d per axis (0 where d == 0; unused there). The DDA's one division (sh_rcp) per axis per ray.
SH_INLINE vec3 dda_inverse_direction(SH_IN(vec3) dir) {
  return vec3(dir.x != 0.0f ? sh_rcp(dir.x) : 0.0f, dir.y != 0.0f ? sh_rcp(dir.y) : 0.0f,
              dir.z != 0.0f ? sh_rcp(dir.z) : 0.0f);
}

// The axis the DDA steps along: the smallest exit, ties to the lower axis (x, then y, then z).
SH_INLINE uint dda_step_axis(SH_IN(vec3) exits) {
  if (exits.x <= exits.y && exits.x <= exits.z) return 0u;
  if (exits.y <= exits.z) return 1u;
  return 2u;
}

SH_INLINE float dda_cell_exit(SH_IN(vec3) exits) { return min(min(exits.x, exits.y), exits.z); }

// Step `cell` along `axis` in the direction of dir; false when that leaves the grid.
SH_INLINE bool dda_step(SH_IN(GridParams) g, SH_IN(vec3) dir, uint axis, SH_INOUT(uvec3) cell) {
  float d = axis == 0u ? dir.x : (axis == 1u ? dir.y : dir.z);
  uint c = axis == 0u ? cell.x : (axis == 1u ? cell.y : cell.z);
  uint n = axis == 0u ? g.cells.x : (axis == 1u ? g.cells.y : g.cells.z);
  if (d > 0.0f) {
    if (c + 1u >= n) return false;
    c = c + 1u;
  } else {
    if (c == 0u) return false;
    c = c - 1u;
  }
  if (axis == 0u) cell.x = c;
  if (axis == 1u) cell.y = c;
  if (axis == 2u) cell.z = c;
  return true;
}

// ---- The exact traversal's walk, written once (reference/trace.cpp, trace.comp, reference/policy.cpp) ----
// The walk is in a cell, or in a box of empty cells around it (radius r: the cells within
// Chebyshev distance r of `cell`, clipped to the grid); `exits` holds, per axis, the parameter at
// which the ray leaves the box along that axis, `t_exit` the smallest. r = 0 is the plain DDA's
// cell. The walk's only state is `cell`: exits are recomputed from it (no accumulated tDelta), so
// a walk that lands on a cell the plain DDA visits goes on exactly as the plain DDA.
struct DdaWalk {
  uvec3 cell;    // the cell the walk is in (the centre of the box)
  float t_exit;  // min(exits)
  vec3 exits;    // per axis, where the ray leaves the box through that axis's far face
  uint radius;   // the box's radius in cells (0: the cell alone)
};

// The walk's first cell: the one holding the ray's grid entry point at t_start.
SH_INLINE DdaWalk dda_walk_begin(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir, float t_start) {
  DdaWalk w;
  w.cell = cell_of_point(g, point_at(org, dir, t_start));
  w.t_exit = 0.0f;
  w.exits = vec3(0.0f);
  w.radius = 0u;
  return w;
}

// Along one axis, the box's last cell in the walk's direction: c + r (d > 0) or c - r (d < 0),
// clipped to the grid; c itself where d == 0.
SH_INLINE uint dda_axis_last(uint c, uint n, float d, uint r) {
  if (d > 0.0f) return min(c + min(r, n - 1u - c), n - 1u);
  if (d < 0.0f) return c - min(r, c);
  return c;
}

SH_INLINE uvec3 dda_box_last(SH_IN(GridParams) g, SH_IN(vec3) dir, SH_IN(uvec3) cell, uint r) {
  return uvec3(dda_axis_last(cell.x, g.cells.x, dir.x, r), dda_axis_last(cell.y, g.cells.y, dir.y, r),
               dda_axis_last(cell.z, g.cells.z, dir.z, r));
}

// The exits of the walk's box of radius r around its cell (r = 0: dda_exits of the cell).
SH_INLINE void dda_walk_exits(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) inv_dir, uint r,
                              SH_INOUT(DdaWalk) w) {
  w.radius = r;
  w.exits = dda_exits(g, org, dir, inv_dir, dda_box_last(g, dir, w.cell, r));
  w.t_exit = dda_cell_exit(w.exits);
}

// Along one axis that the walk does not leave the box through: the cell index the plain DDA holds
// when it takes the crossing (t, axis a) out of the box. The plain DDA takes the axes' crossings
// in the order of (exit parameter, axis) (a merge of per-axis sequences, each nondecreasing along
// the walk: docs/SPEC.md "Empty-space skipping"), so the index is the first k from c towards
// `last` whose crossing comes after (t, a): not (E(k) < t or (E(k) == t and this axis < a)). The
// search starts at the cell of the point at t (f: its local coordinate) and corrects it by
// comparing the crossings themselves, so rounding in f changes nothing.
SH_INLINE bool dda_crossing_before(float origin, float cell_size, float o, float d, float inv, uint k, float t,
                                   bool ties_before) {
  float e = dda_axis_exit(origin, cell_size, o, d, inv, k);
  return e < t || (e == t && ties_before);
}
SH_INLINE uint dda_axis_cell_at(float origin, float cell_size, float o, float d, float inv, uint c, uint last,
                                float f, float t, bool ties_before) {
  if (d == 0.0f || c == last) return c;
  uint lo = min(c, last);
  uint hi = max(c, last);
  float fl = floor(f);
  uint k = !(fl > float(lo)) ? lo : (fl >= float(hi) ? hi : uint(fl));
  // Back towards c while the crossing before k is not taken yet; then on while k's is taken
  if (d > 0.0f) {
    while (k > c && !dda_crossing_before(origin, cell_size, o, d, inv, k - 1u, t, ties_before)) k -= 1u;
    while (k < last && dda_crossing_before(origin, cell_size, o, d, inv, k, t, ties_before)) k += 1u;
  } else {
    while (k < c && !dda_crossing_before(origin, cell_size, o, d, inv, k + 1u, t, ties_before)) k += 1u;
    while (k > last && dda_crossing_before(origin, cell_size, o, d, inv, k, t, ties_before)) k -= 1u;
  }
  return k;
}

// Step the walk out of its box (dda_walk_exits) into the cell the plain DDA enters next when it
// leaves that box: with radius 0 one dda_step; false when that leaves the grid.
SH_INLINE bool dda_walk_next(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) inv_dir,
                             SH_INOUT(DdaWalk) w) {
  uint a = dda_step_axis(w.exits);
  if (w.radius != 0u) {
    // Ties: an axis below a takes an equal crossing first (x before y before z)
    float t = w.t_exit;
    vec3 f = grid_local(g, point_at(org, dir, t));
    uvec3 last = dda_box_last(g, dir, w.cell, w.radius);
    uvec3 c = w.cell;
    w.cell.x = a == 0u ? last.x : dda_axis_cell_at(g.origin.x, g.cell_size, org.x, dir.x, inv_dir.x, c.x, last.x, f.x, t, true);
    w.cell.y = a == 1u ? last.y : dda_axis_cell_at(g.origin.y, g.cell_size, org.y, dir.y, inv_dir.y, c.y, last.y, f.y, t, a > 1u);
    w.cell.z = a == 2u ? last.z : dda_axis_cell_at(g.origin.z, g.cell_size, org.z, dir.z, inv_dir.z, c.z, last.z, f.z, t, false);
  }
  return dda_step(g, dir, a, w.cell);
}

// ---- Which hit a trace reports (docs/SPEC.md "Any hit") ----
// kTraceClosestHit: the closest accepted candidate (ties: the smaller reference), the paper's.
// kTraceAnyHit: the first candidate the traversal accepts (launch triangle, interval, alpha
// keying and the tie rule against no earlier candidate, as for the closest), reported at once: the
// rest of its cell is not read. A ray has an accepted candidate in one mode iff it has one in the
// other and the walk up to it is the same, so it hits in one iff it hits in the other (gap-fill
// included): occlusion, which is all a shadow ray asks, is the closest hit's, in fewer tests. The
// hit's fields are those of the candidate it stopped at. Both backends take the same traversal
// order, so they agree on it in bits.
SH_CONST uint kTraceClosestHit = 0u;
SH_CONST uint kTraceAnyHit = 1u;

// ---- The exact traversal's mailbox (kGridMailbox; docs/SPEC.md "Mailbox") ----
// The exact traversal tests every reference against the whole ray (t_lo, tmax) with the best hit
// so far as the bound, so a second test of a reference, in a later cell, cannot change the hit:
// it is rejected again (the bound only shrinks), or it loses to the best hit (which is it, or
// nearer, or as near with a smaller reference). The mailbox holds the last kMailboxSize references
// tested on the ray, newest first (a shift register: constant indices only, so that the shader
// keeps it in registers); a reference it holds is not tested again. Written once: the reference
// trace and the trace shader call these under the same names.
SH_CONST uint kMailboxSize = 8u;
struct Mailbox {
  uint refs[kMailboxSize];  // kBlank where empty
};
// Whether the grid's trace takes the mailbox: kGridMailbox, exact traversal and sorted insertion
// only (first-empty insertion orders a cell's slots by the build's timing, and the mailbox's test
// count depends on the order: it would differ between runs and backends).
SH_INLINE bool mailbox_enabled(SH_IN(GridParams) g) {
  return (g.flags & kGridMailbox) != 0u && g.traversal == kTraversalExact && g.insertion == kInsertSorted;
}
SH_INLINE void mailbox_clear(SH_OUT(Mailbox) m) {
  for (uint i = 0u; i < kMailboxSize; ++i) m.refs[i] = kBlank;
}
SH_INLINE bool mailbox_holds(SH_IN(Mailbox) m, uint ref) {
  bool held = false;
  for (uint i = 0u; i < kMailboxSize; ++i) held = held || m.refs[i] == ref;
  return held;
}
// A reference about to be tested: it enters at the front, the oldest drops off the back.
SH_INLINE void mailbox_put(SH_INOUT(Mailbox) m, uint ref) {
  for (uint i = kMailboxSize - 1u; i > 0u; --i) m.refs[i] = m.refs[i - 1u];
  m.refs[0] = ref;
}

// ---- Paper traversal's visits, written once (reference/trace.cpp, trace.comp, reference/policy.cpp) ----
// The cell of segment k's sample point.
SH_INLINE uvec3 segment_cell(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(RaySetup) rs, uint k) {
  return cell_of_point(g, point_at(org, dir, segment_sample_t(rs, k)));
}
// The last segment of the visit that begins with segment k in `cell`: with kRepeatMerge the
// following segments whose samples fall into the same cell merge into it; otherwise k.
SH_INLINE uint segment_visit_last(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(RaySetup) rs, uint k,
                                  SH_IN(uvec3) cell) {
  uint last = k;
  if (g.repeats == kRepeatMerge) {
    while (last + 1u < g.max_segments && segment_begin(rs, last + 1u) < rs.t_end &&
           segment_cell(g, org, dir, rs, last + 1u) == cell)
      last += 1u;
  }
  return last;
}

// ---- The skip field (kGridSkipEmpty; docs/SPEC.md "Empty-space skipping") ----
// Per cell, its Chebyshev distance (in cells, capped at kSkipMaxDistance) to the nearest cell that
// holds a static reference: D = 0 for such a cell; D = d > 0 says every cell within distance d - 1
// is empty of static references. The dynamic instances' references are covered by one box of
// cells per dynamic instance (kSkipMaxBoxes at most: instance i joins box i % kSkipMaxBoxes), the
// union of its triangles' cell ranges, uploaded by each build and update; a cell's distance is the
// smaller of its static distance and its distance to every box.
// Buffer layout (words): the box count, 3 words of padding, kSkipMaxBoxes boxes of 8 words (lo.xyz,
// pad, hi.xyz, pad), then one byte per cell, 4 cells per word (cell i in bits 8 (i % 4) of word
// i / 4). A cell's byte (skip_byte): an empty cell's distance D in [1, kSkipMaxDistance]; an
// occupied cell's is 0, or with kGridSkipCovered and a cover bit set kSkipCoverTag | its cover bits
// ("Covered cells" below): the distance of an occupied cell is 0, so its byte is free to carry
// them, and the walk reads both in one load.
SH_CONST uint kSkipMaxDistance = 191u;
SH_CONST uint kSkipCoverTag = 192u;  // bits 6 and 7 set: an occupied cell's byte with cover bits
SH_CONST uint kSkipMaxBoxes = 8u;
SH_CONST uint kSkipBoxWords = 8u;
SH_CONST uint kSkipHeaderWords = 4u + kSkipMaxBoxes * kSkipBoxWords;
SH_INLINE uint skip_words(SH_IN(GridParams) g) { return kSkipHeaderWords + (grid_cell_count(g) + 3u) / 4u; }
SH_INLINE uint skip_distance_word(uint i) { return kSkipHeaderWords + i / 4u; }
SH_INLINE uint skip_distance_shift(uint i) { return 8u * (i % 4u); }
// A cell's byte from its static distance and cover bits (non-zero only where the distance is 0),
// and back.
SH_INLINE uint skip_byte(uint distance, uint cover) { return cover != 0u ? kSkipCoverTag | cover : distance; }
SH_INLINE uint skip_byte_distance(uint b) { return b >= kSkipCoverTag ? 0u : b; }
SH_INLINE uint skip_byte_cover(uint b) { return b >= kSkipCoverTag ? b & 63u : 0u; }
SH_INLINE uint skip_box_word(uint b) { return 4u + b * kSkipBoxWords; }

// ---- Covered cells (kGridSkipCovered; docs/SPEC.md "Covered cells") ----
// Per cell, 6 cover bits: bit 2 a + s (axis a; s = 0 the neighbour at index - 1 along a, s = 1 at
// index + 1) is set iff the cell's static run is not empty and every reference of it is in that
// neighbour's static run. The exact traversal tests every reference against the whole ray with
// the best hit so far as the bound, so on entering a cell through a face whose bit is set, the
// cell's static references were all tested in the cell it came from (or, that one covered too,
// earlier): their results cannot change, and the walk skips them (the dynamic list is still
// tested). Stored in the cell's skip byte (skip_byte), read with its distance.
SH_CONST uint kCoverNoFace = 6u;  // the walk's first cell: entered through no face (bit 6 is never set)
// The face a single DDA step along axis a enters the next cell through: the direction's sign along
// a says which neighbour the walk came from.
SH_INLINE uint skip_entry_face(SH_IN(vec3) dir, uint a) {
  float d = a == 0u ? dir.x : (a == 1u ? dir.y : dir.z);
  return 2u * a + (d > 0.0f ? 0u : 1u);
}
// The neighbour of cell c across face f, and whether it lies in the grid.
SH_INLINE bool skip_face_neighbour(SH_IN(GridParams) g, SH_IN(uvec3) c, uint f, SH_OUT(uvec3) n) {
  uint a = f / 2u;
  uint k = a == 0u ? c.x : (a == 1u ? c.y : c.z);
  uint size = a == 0u ? g.cells.x : (a == 1u ? g.cells.y : g.cells.z);
  bool inside = (f % 2u) == 0u ? k > 0u : k + 1u < size;
  uint m = (f % 2u) == 0u ? k - 1u : k + 1u;
  n = c;
  if (a == 0u) n.x = m;
  else if (a == 1u) n.y = m;
  else n.z = m;
  return inside;
}

// A dynamic instance's box: the cells of the padded local bounds [fmin, fmax] of its world-space
// vertices (componentwise min and max of grid_local over every vertex). Each of its triangles'
// triangle_cell_range lies inside: a triangle's min(f0, f1, f2) >= fmin, and the subtraction of the
// padding, floor and the clamp are monotone.
SH_INLINE void skip_box_of_bounds(SH_IN(GridParams) g, SH_IN(vec3) fmin, SH_IN(vec3) fmax, SH_OUT(uvec3) lo,
                                  SH_OUT(uvec3) hi) {
  SH_PRECISE vec3 a = fmin - vec3(g.aabb_padding);
  SH_PRECISE vec3 b = fmax + vec3(g.aabb_padding);
  lo = cell_of_local(g, a);
  hi = cell_of_local(g, b);
}

// Chebyshev distance from cell c to the box [lo, hi] of cells (0 inside).
SH_INLINE uint skip_box_distance(SH_IN(uvec3) c, SH_IN(uvec3) lo, SH_IN(uvec3) hi) {
  uint dx = c.x < lo.x ? lo.x - c.x : (c.x > hi.x ? c.x - hi.x : 0u);
  uint dy = c.y < lo.y ? lo.y - c.y : (c.y > hi.y ? c.y - hi.y : 0u);
  uint dz = c.z < lo.z ? lo.z - c.z : (c.z > hi.z ? c.z - hi.z : 0u);
  return max(max(dx, dy), dz);
}

// ---- The ray's dynamic boxes (kGridSkipEmpty; docs/SPEC.md "Empty-space skipping") ----
// A dynamic box lowers the distances only on the walks that can reach it. Once per ray, each box
// is asked whether the plain DDA walk of the ray (skipping off; the skipping walk visits a
// subsequence of its cells and passes the rest) can visit a cell of the box, in the walk's own
// arithmetic (dda_axis_exit, the same crossings). Along an axis with d > 0 the walk's index only
// grows from k0 (its first cell's, dda_walk_begin): it enters an index k > k0 at the crossing
// E(k - 1) and leaves it at E(k), E nondecreasing in k, and the walk's parameters (each cell's
// entry, the exit before it) never fall. So a visited cell whose index lies in [lo, hi] has its
// entry parameter at or after E(lo - 1) (no bound where k0 >= lo) and its exit at or before E(hi);
// and none does once k0 > hi. The same mirrored for d < 0; an axis with d == 0 keeps k0. A visited
// cell of the box, other than the first, puts its entry parameter inside every axis's interval
// and below t_end (the walk stops once an exit reaches t_end); the first cell, inside the box, has
// no lower bound on any axis. So where the intervals and (-inf, t_end] share no point, no cell of
// the box is on the walk, nor any of its dynamic references, and the box need not lower the
// distances of the cells the walk visits. A NaN crossing bounds nothing (the answer errs only
// towards "reached").
SH_INLINE bool skip_box_axis_reach(float origin, float cell_size, float o, float d, float inv, uint k0, uint lo,
                                   uint hi, SH_INOUT(float) t_lo, SH_INOUT(float) t_hi) {
  if (d == 0.0f) return k0 >= lo && k0 <= hi;
  if (d > 0.0f ? k0 > hi : k0 < lo) return false;
  // Entering the range (from below for d > 0: the crossing out of lo - 1; from above: out of hi + 1)
  if (d > 0.0f ? k0 < lo : k0 > hi) {
    float e = dda_axis_exit(origin, cell_size, o, d, inv, d > 0.0f ? lo - 1u : hi + 1u);
    if (e > t_lo) t_lo = e;
  }
  // Leaving it (the crossing out of hi for d > 0, out of lo for d < 0)
  float x = dda_axis_exit(origin, cell_size, o, d, inv, d > 0.0f ? hi : lo);
  if (x < t_hi) t_hi = x;
  return true;
}

SH_INLINE bool skip_box_reached(SH_IN(GridParams) g, SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) inv_dir,
                                SH_IN(uvec3) k0, float t_end, SH_IN(uvec3) lo, SH_IN(uvec3) hi) {
  float t_lo = -sh_infinity();
  float t_hi = t_end;
  bool x = skip_box_axis_reach(g.origin.x, g.cell_size, org.x, dir.x, inv_dir.x, k0.x, lo.x, hi.x, t_lo, t_hi);
  bool y = skip_box_axis_reach(g.origin.y, g.cell_size, org.y, dir.y, inv_dir.y, k0.y, lo.y, hi.y, t_lo, t_hi);
  bool z = skip_box_axis_reach(g.origin.z, g.cell_size, org.z, dir.z, inv_dir.z, k0.z, lo.z, hi.z, t_lo, t_hi);
  return x && y && z && !(t_lo > t_hi);
}

// The static distance by its definition, from a summed-volume table of the static occupancy:
// `sums` are the table's values at the 8 corners of the cube of radius r around c (clipped to the
// grid), skip_cube_corner names them. Count of occupied cells in the cube: inclusion-exclusion
// (exact in uint arithmetic: the count lies in [0, cells]).
// Corner j (bits: x, y, z) of the cube of radius r around c, in the table's 1-based coordinates
// (0 along an axis stands for "before the grid", whose sum is 0).
// Corner j of the box of cells [lo, hi] (inside the grid).
SH_INLINE uvec3 skip_box_corner(SH_IN(uvec3) lo, SH_IN(uvec3) hi, uint j) {
  return uvec3((j & 1u) != 0u ? hi.x + 1u : lo.x, (j & 2u) != 0u ? hi.y + 1u : lo.y, (j & 4u) != 0u ? hi.z + 1u : lo.z);
}
SH_INLINE uvec3 skip_cube_corner(SH_IN(GridParams) g, SH_IN(uvec3) c, uint r, uint j) {
  uvec3 lo = uvec3(c.x - min(r, c.x), c.y - min(r, c.y), c.z - min(r, c.z));
  uvec3 hi = min(c + uvec3(r), g.cells - uvec3(1u));
  return skip_box_corner(lo, hi, j);
}
// The sign of corner j in the inclusion-exclusion: + where an even number of axes take the low side.
SH_INLINE bool skip_corner_positive(uint j) {
  uint low = ((j & 1u) == 0u ? 1u : 0u) + ((j & 2u) == 0u ? 1u : 0u) + ((j & 4u) == 0u ? 1u : 0u);
  return (low % 2u) == 0u;
}
// Index of a 1-based table coordinate in the table (cells + 1 per axis, x fastest).
SH_INLINE uint skip_table_index(SH_IN(GridParams) g, SH_IN(uvec3) t) {
  return (t.z * (g.cells.y + 1u) + t.y) * (g.cells.x + 1u) + t.x;
}
SH_INLINE uint skip_table_words(SH_IN(GridParams) g) {
  return (g.cells.x + 1u) * (g.cells.y + 1u) * (g.cells.z + 1u);
}

// The search's bricks: kSkipBrick^3 cells (brick b holds cells kSkipBrick b + [0, kSkipBrick), the
// last along an axis clipped to the grid). A brick's distance B(b): the smallest R in
// [0, kSkipMaxBrickDistance) whose box of cells kSkipBrick (b - R) .. kSkipBrick (b + R + 1) - 1
// (clipped) holds an occupied cell, else kSkipMaxBrickDistance. It brackets the distance of each
// cell c of the brick: c lies within kSkipBrick - 1 of every cell of the brick along each axis, so
// kSkipBrick B - (kSkipBrick - 1) <= Ds(c) <= kSkipBrick B + kSkipBrick - 1 (skip_cell_window: a
// window of 2 kSkipBrick - 1 values, 3 probes of a binary search instead of 8).
SH_CONST uint kSkipBrick = 4u;
// The search's cap: the smallest R whose window reaches kSkipMaxDistance (kSkipBrick R + kSkipBrick
// - 1 >= kSkipMaxDistance). A brick with no occupied cell within R - 1 bricks gets R: its cells'
// distances are at least kSkipBrick R - (kSkipBrick - 1), and the window holds every capped value
// from there.
SH_CONST uint kSkipMaxBrickDistance = 47u;  // kSkipMaxDistance over kSkipBrick, rounded down (asserted below)
SH_INLINE uvec3 skip_bricks(SH_IN(GridParams) g) { return (g.cells + uvec3(3u)) / 4u; }  // kSkipBrick = 4
SH_INLINE uint skip_brick_count(SH_IN(GridParams) g) {
  uvec3 b = skip_bricks(g);
  return b.x * b.y * b.z;
}
SH_INLINE uvec3 skip_brick_of_index(SH_IN(GridParams) g, uint i) {
  uvec3 b = skip_bricks(g);
  return uvec3(i % b.x, sh_udiv(i, b.x) % b.y, sh_udiv(i, b.x * b.y));
}
SH_INLINE uint skip_brick_index(SH_IN(GridParams) g, SH_IN(uvec3) c) {
  uvec3 b = skip_bricks(g);
  uvec3 k = c / 4u;  // kSkipBrick
  return (k.z * b.y + k.y) * b.x + k.x;
}
// Corner j of the box of brick b's cells grown by R bricks, clipped to the grid.
SH_INLINE uvec3 skip_brick_corner(SH_IN(GridParams) g, SH_IN(uvec3) b, uint R, uint j) {
  uvec3 first = b * kSkipBrick;
  uint r = R * kSkipBrick;
  uvec3 lo = uvec3(first.x - min(r, first.x), first.y - min(r, first.y), first.z - min(r, first.z));
  uvec3 hi = min(first + uvec3(kSkipBrick - 1u + r), g.cells - uvec3(1u));
  return skip_box_corner(lo, hi, j);
}
// The window [lo, hi] of capped distances a cell of a brick at distance B can have.
SH_INLINE void skip_cell_window(uint B, SH_OUT(uint) lo, SH_OUT(uint) hi) {
  lo = min(max(kSkipBrick * B, kSkipBrick - 1u) - (kSkipBrick - 1u), kSkipMaxDistance);
  hi = min(kSkipBrick * B + kSkipBrick - 1u, kSkipMaxDistance);
}
// The build's scratch: the summed-volume table, then one word per brick (its distance).
SH_INLINE uint skip_scratch_words(SH_IN(GridParams) g) { return skip_table_words(g) + skip_brick_count(g); }

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::GridParams) == 96, "std430 layout of GridParams");
static_assert(gridrt::shared::kSkipBrick == 4u, "skip_bricks and skip_brick_index divide by 4");
static_assert(gridrt::shared::kSkipMaxDistance < gridrt::shared::kSkipCoverTag && gridrt::shared::kCoverNoFace == 6u,
              "a distance's byte never reads as cover bits; the 6 cover bits fit below kSkipCoverTag's bits");
static_assert(gridrt::shared::kSkipMaxBrickDistance * gridrt::shared::kSkipBrick <= gridrt::shared::kSkipMaxDistance &&
                  (gridrt::shared::kSkipMaxBrickDistance + 1u) * gridrt::shared::kSkipBrick > gridrt::shared::kSkipMaxDistance,
              "kSkipMaxBrickDistance is kSkipMaxDistance over kSkipBrick, rounded down");
static_assert(sizeof(gridrt::shared::GridInstance) == 16, "std430 layout of GridInstance");
static_assert(sizeof(gridrt::shared::GridTriangle) == 48, "std430 layout of GridTriangle");
static_assert(sizeof(gridrt::shared::GridTriangleUv) == 24, "std430 layout of GridTriangleUv");
static_assert(sizeof(gridrt::shared::GridMaterial) == 16, "std430 layout of GridMaterial");
static_assert(sizeof(gridrt::shared::SpillHeader) == 16, "std430 layout of SpillHeader");
static_assert(sizeof(gridrt::shared::SpillEntry) == 16, "std430 layout of SpillEntry");
#endif

#endif
