#version 460
// spill_order.comp: the spill list's order pass (reference/build.cpp, spill_order), one invocation
// per entry of [first, stored): walk the entry's arrival list for the smallest larger reference
// (its successor in ascending order) and link to it; the entry with no smaller reference becomes
// the list's head. After the build's static pass (first = 0) and after every dynamic pass
// (first = static_count, push constant `dynamic` = 1).
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = kGridBindSpill) buffer Spill {
  SpillHeader spill_header;
  SpillEntry spill_entries[];
};
layout(std430, binding = kGridBindSpillHeads) buffer SpillHeads { uint spill_heads[]; };
layout(push_constant) uniform Push { SpillOrderPush pc; };

void main() {
  const GridParams g = grid_params();
  const uint first = pc.dynamic != 0u ? spill_header.static_count : 0u;
  const uint stored = min(spill_header.count, spill_header.capacity);
  const uint i = first + gl_GlobalInvocationID.x;
  if (i >= stored) return;
  const SpillEntry e = spill_entries[i];
  const bool dynamic = e.ref >= g.comparison_offset;
  uint head = spill_head_index(e.cell, dynamic);
  uint arrival = spill_arrival_index(e.cell, dynamic);
  if ((g.flags & kGridCompact) != 0u) {
    const uvec3 lo = uvec3(spill_heads[0], spill_heads[1], spill_heads[2]);
    const uvec3 hi = uvec3(spill_heads[4], spill_heads[5], spill_heads[6]);
    const uvec3 cell = cell_of_linear_index(g, e.cell);
    if (!region_contains(cell, lo, hi)) return;
    head = compact_head_index(region_index(cell, lo, hi));
    arrival = compact_arrival_index(region_index(cell, lo, hi));
  }
  uint next = kSpillEnd;
  uint next_ref = kBlank;
  bool smallest = true;
  for (uint j = spill_heads[arrival]; j != kSpillEnd; j = spill_entries[j].arrival) {
    const uint r = spill_entries[j].ref;
    if (r < e.ref) smallest = false;
    if (r > e.ref && r < next_ref) {
      next = j;
      next_ref = r;
    }
  }
  spill_entries[i].next = next;
  if (smallest) spill_heads[head] = i;
}
