// build.glsl: scene build (paper 2.1), the body of one build invocation, shared by the geometry
// shader of the raster pass (build.geom) and the compute build (build.comp). Same names and
// heading comments as reference/build.cpp.
#ifndef GRIDRT_BUILD_GLSL
#define GRIDRT_BUILD_GLSL

#include "grid_common.glsl"

layout(binding = 1, r32ui) uniform coherent uimage3D grid_image;
// The spill list (kGridSpill; the counter always) and its per-cell heads
layout(std430, binding = 13) buffer Spill {
  SpillHeader spill_header;
  SpillEntry spill_entries[];
};
layout(std430, binding = 14) buffer SpillHeads { uint spill_heads[]; };

// A reference no slot of `cell` took: counted, and with kGridSpill stored as (cell, ref) in the
// entry the counter gave it and pushed onto the arrival list of the cell's static or dynamic
// references (one exchange of the head: no loop, no order), while the list has room (past its
// capacity it is lost: the count says how many). The order pass links it in ascending order.
void spill_reference(GridParams g, uvec3 cell, uint ref) {
  const uint i = atomicAdd(spill_header.count, 1u);
  if ((g.flags & kGridSpill) == 0u || i >= spill_header.capacity) return;
  const uint c = cell_index(g, cell);
  spill_entries[i].cell = c;
  spill_entries[i].ref = ref;
  spill_entries[i].arrival = atomicExchange(spill_heads[spill_arrival_index(c, ref >= g.comparison_offset)], i);
}

// Paper: compare-and-swap blank -> ref into the first slot that takes it; when none does, flag
// the cell saturated (static or dynamic bit by the reference's kind) and spill the reference.
void insert_first_empty(GridParams g, uvec3 cell, uint ref) {
  for (uint s = 0u; s < g.capacity; ++s) {
    const uint old = imageAtomicCompSwap(grid_image, ivec3(cell_slot_texel(g, cell, s)), kBlank, ref);
    if (old == kBlank) return;
  }
  // Saturated: no slot took the reference
  const uint bit = ref < g.comparison_offset ? kStatusStatic : kStatusDynamic;
  imageAtomicOr(grid_image, ivec3(cell_status_texel(g, cell)), bit);
  spill_reference(g, cell, ref);
}

// Ours: an atomic-min cascade. The carried value v takes the smaller of itself and each slot in
// turn (old = atomicMin(slot, v); v = max(old, v)) until it is blank; the cell ends holding its
// `capacity` smallest references in ascending order whatever the timing. A value pushed out of
// the last slot is dropped: it flags the cell (static bit if it is static, else dynamic) and is
// spilled.
void insert_sorted(GridParams g, uvec3 cell, uint ref) {
  uint v = ref;
  for (uint s = 0u; s < g.capacity; ++s) {
    const uint old = imageAtomicMin(grid_image, ivec3(cell_slot_texel(g, cell, s)), v);
    v = max(old, v);
    if (v == kBlank) return;
  }
  // Saturated: the dropped value names the bit
  const uint bit = v < g.comparison_offset ? kStatusStatic : kStatusDynamic;
  imageAtomicOr(grid_image, ivec3(cell_status_texel(g, cell)), bit);
  spill_reference(g, cell, v);
}

// One build invocation: write the world-space triangle to the geometry buffer, insert its
// reference into every cell of its AABB range whose enlarged bounding sphere the triangle's plane
// passes through.
void build_invocation(uint instance, uint triangle, vec3 v0, vec3 v1, vec3 v2) {
  const GridParams g = grid_params();
  // Write the world-space triangle (the material was written by the host)
  const uint k = instances[instance].tri_offset + triangle;
  triangles[k].v0 = v0;
  triangles[k].v1 = v1;
  triangles[k].v2 = v2;
  // Skip zero-area triangles: no ray can hit them
  const vec3 n = triangle_normal(v0, v1, v2);
  const float nn = sh_dot(n, n);
  if (nn == 0.0f) return;
  // Cells of the AABB range whose enlarged bounding sphere meets the plane
  uvec3 lo;
  uvec3 hi;
  triangle_cell_range(g, v0, v1, v2, lo, hi);
  const uint ref = ref_pack(instance, triangle);
  for (uint z = lo.z; z <= hi.z; ++z)
    for (uint y = lo.y; y <= hi.y; ++y)
      for (uint x = lo.x; x <= hi.x; ++x) {
        const uvec3 cell = uvec3(x, y, z);
        if (!plane_intersects_enlarged_sphere(v0, n, nn, cell_center(g, cell), g.sphere_r2)) continue;
        if (g.insertion == kInsertSorted) insert_sorted(g, cell, ref);
        else insert_first_empty(g, cell, ref);
      }
}

#endif
