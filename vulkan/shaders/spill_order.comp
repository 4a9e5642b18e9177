#version 460
// spill_order.comp: the spill list's order pass (reference/build.cpp, spill_order), one invocation
// per entry of [first, stored): walk the entry's arrival list for the smallest larger reference
// (its successor in ascending order) and link to it; the entry with no smaller reference becomes
// the list's head. After the build's static pass (first = 0) and after every dynamic pass
// (first = static_count, push constant `dynamic` = 1).
//
// The walks are chains of dependent loads, as long as the list; each step a load from L2 took
// 0.3 us on the H200 (docs/BENCHMARKS.md, "The update's passes"). So when the entries
// [first, stored) fit in the workgroup's shared memory (kOrderShared of them: the device's
// maxComputeSharedMemorySize, 8 bytes each), every workgroup first copies their (ref, arrival)
// there, coalesced, and walks the chains in shared memory. Same walk, same links; past that size
// the walk reads the buffer as before.
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(local_size_x = 64) in;
layout(constant_id = kGridSpecOrderShared) const uint kOrderShared = 2048u;
layout(std430, binding = kGridBindSpill) buffer Spill {
  SpillHeader spill_header;
  SpillEntry spill_entries[];
};
layout(std430, binding = kGridBindSpillHeads) buffer SpillHeads { uint spill_heads[]; };
layout(push_constant) uniform Push { SpillOrderPush pc; };

shared uvec2 s_walk[kOrderShared];  // (ref, arrival) of entry first + k

void main() {
  const GridParams g = grid_params();
  const uint first = pc.dynamic != 0u ? spill_header.static_count : 0u;
  const uint stored = min(spill_header.count, spill_header.capacity);
  // A workgroup with no entry leaves at once (uniform: no barrier is skipped by some of it)
  if (first + gl_WorkGroupID.x * 64u >= stored) return;
  const uint n = stored - first;
  const bool in_shared = n <= kOrderShared;
  if (in_shared) {
    for (uint k = gl_LocalInvocationIndex; k < n; k += 64u)
      s_walk[k] = uvec2(spill_entries[first + k].ref, spill_entries[first + k].arrival);
    barrier();
  }
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
  for (uint j = spill_heads[arrival]; j != kSpillEnd;) {
    // The list's entries are this pass's (pushed since its heads were emptied): in the copy; an
    // index outside it is read from the buffer all the same
    const uint k = j - first;
    const uvec2 w = in_shared && k < n ? s_walk[k] : uvec2(spill_entries[j].ref, spill_entries[j].arrival);
    const uint r = w.x;
    if (r < e.ref) smallest = false;
    if (r > e.ref && r < next_ref) {
      next = j;
      next_ref = r;
    }
    j = w.y;
  }
  spill_entries[i].next = next;
  if (smallest) spill_heads[head] = i;
}
