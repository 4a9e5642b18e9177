#version 460
// ray_sort.comp: the frame's bounce rays sorted before their trace (FrameOptions::sort_bits;
// frame_input.h, kRaySort*). A subgroup's invocations wait for its longest ray; rays that leave
// from nearby points in nearby directions walk alike, so the trace takes them in the order of a
// key: the direction's cell on a cube of 16 x 16 cells a face (11 bits), then the origin's cell on
// a lattice of 128 a side over the grid, in Morton order (21 bits), as common/gather.h's
// coherent_ray_order keys a fixed list (over the grid's box, not the list's origins). Pixels
// without a ray go last. The sort is a least-significant-digit radix sort of (key, pixel) pairs, 4
// bits a pass over the key's top FrameOptions::sort_bits bits, each pass two dispatches:
//   count    (kRaySortSpecStage 0) a workgroup per block of kRaySortBlock pairs counts its
//            digits into counts[digit * blocks + block]; the first pass makes the keys from the
//            rays and writes the pairs (key, pixel) of A
//   scatter  (kRaySortSpecStage 1) each block again: a pair's place is the pairs of smaller
//            digits in all blocks, those of its digit in the blocks before, and those of its
//            digit before it in its own block (each invocation's pairs consecutive: stable)
// The passes go A to B, then B to A; an even number of passes ends in A, whose values are the
// ray list the trace takes (trace.comp, kGridSpecTraceList). Only the order depends on the sort:
// the trace writes each ray's hit at the ray's own index.
#extension GL_GOOGLE_include_directive : require
#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/records.h"
#include "gridrt/common/shared/worklist.h"
#include "gridrt/vulkan/shaders/frame_input.h"

layout(local_size_x = 256) in;  // kRaySortThreads
layout(constant_id = kRaySortSpecStage) const uint kStage = 0u;

layout(std430, binding = kRaySortBindRays) readonly buffer Rays { RayRecord rays[]; };
layout(std430, binding = kRaySortBindKeysA) buffer KeysA { uint keys_a[]; };
layout(std430, binding = kRaySortBindKeysB) buffer KeysB { uint keys_b[]; };
layout(std430, binding = kRaySortBindListA) buffer ListA {
  WorkListHeader list_header;
  uint values_a[];
};
layout(std430, binding = kRaySortBindValuesB) buffer ValuesB { uint values_b[]; };
layout(std430, binding = kRaySortBindCounts) buffer Counts { uint counts[]; };
layout(push_constant) uniform Push { RaySortPush pc; };

// Morton order of a 7-bit lattice coordinate: its bit b at bit 3 b.
uint spread7(uint v) {
  uint bits = 0u;
  for (uint b = 0u; b < 7u; ++b) bits |= ((v >> b) & 1u) << (3u * b);
  return bits;
}

bool finite3(vec3 v) { return !any(isnan(v)) && !any(isinf(v)); }

// A ray's key (above): 0xFFFFFFFF without a ray (tmax not above 0, as the trace's empty ray),
// 0xFFFFFFFE for a ray the trace rejects (a non-finite origin or direction, or a zero direction).
uint ray_sort_key(RayRecord ray) {
  if (!(ray.tmax > 0.0f)) return 0xFFFFFFFFu;
  const vec3 a = abs(ray.dir);
  const uint axis = a.x >= a.y && a.x >= a.z ? 0u : (a.y >= a.z ? 1u : 2u);
  const float m = a[axis];
  if (!finite3(ray.org) || !finite3(ray.dir) || !(m > 0.0f)) return 0xFFFFFFFEu;
  const float u = ray.dir[(axis + 1u) % 3u] / m, v = ray.dir[(axis + 2u) % 3u] / m;
  const uint face = axis * 2u + (ray.dir[axis] < 0.0f ? 1u : 0u);
  const uint iu = uint(clamp((u + 1.0f) * 8.0f, 0.0f, 15.0f)), iv = uint(clamp((v + 1.0f) * 8.0f, 0.0f, 15.0f));
  const vec3 c = clamp((ray.org - pc.lattice_lo) * pc.lattice_scale, vec3(0.0f), vec3(float(kRaySortLattice - 1u)));
  const uvec3 l = uvec3(c);
  return ((face * 16u + iu) * 16u + iv) << 21u | spread7(l.x) | spread7(l.y) << 1u | spread7(l.z) << 2u;
}

uint digit_of(uint key) { return (key >> pc.shift) & (kRaySortDigits - 1u); }

shared uint block_counts[kRaySortDigits];                    // count: the block's digits
shared uint thread_counts[kRaySortDigits * kRaySortThreads];  // scatter: [digit][invocation]
shared uint run_sums[kRaySortThreads];
shared uint part_before[kRaySortThreads];  // [j * 16 + digit]: counts of the blocks before, in turns j
shared uint part_total[kRaySortThreads];
shared uint digit_base[kRaySortDigits];

void count_pass(uint block, uint t) {
  if (t < kRaySortDigits) block_counts[t] = 0u;
  barrier();
  for (uint i = 0u; i < kRaySortItems; ++i) {
    const uint idx = block * kRaySortBlock + i * kRaySortThreads + t;  // any order counts alike
    if (idx >= pc.count) break;
    uint key;
    if (pc.make_keys != 0u) {
      key = ray_sort_key(rays[idx]);
      keys_a[idx] = key;
      values_a[idx] = idx;
    } else {
      key = pc.parity == 0u ? keys_a[idx] : keys_b[idx];
    }
    atomicAdd(block_counts[digit_of(key)], 1u);
  }
  barrier();
  if (t < kRaySortDigits) counts[t * pc.blocks + block] = block_counts[t];
}

void scatter_pass(uint block, uint t) {
  // This invocation's pairs, consecutive in the source
  uint keys[kRaySortItems], values[kRaySortItems];
  const uint first = block * kRaySortBlock + t * kRaySortItems;
  for (uint d = 0u; d < kRaySortDigits; ++d) thread_counts[d * kRaySortThreads + t] = 0u;
  for (uint i = 0u; i < kRaySortItems; ++i) {
    const uint idx = first + i;
    keys[i] = 0u;
    values[i] = 0u;
    if (idx < pc.count) {
      keys[i] = pc.parity == 0u ? keys_a[idx] : keys_b[idx];
      values[i] = pc.parity == 0u ? values_a[idx] : values_b[idx];
      thread_counts[digit_of(keys[i]) * kRaySortThreads + t] += 1u;  // its own column
    }
  }
  // The counts of all blocks: per digit, those before this block and all, in 16 turns
  {
    const uint d = t % kRaySortDigits, j = t / kRaySortDigits;
    uint before = 0u, total = 0u;
    for (uint b = j; b < pc.blocks; b += kRaySortThreads / kRaySortDigits) {
      const uint c = counts[d * pc.blocks + b];
      total += c;
      if (b < block) before += c;
    }
    part_before[t] = before;
    part_total[t] = total;
  }
  barrier();
  // The block's counts [digit][invocation] scanned in that order: invocation t sums 16 in a run
  uint run = 0u;
  for (uint e = 0u; e < kRaySortDigits; ++e) run += thread_counts[t * kRaySortDigits + e];
  run_sums[t] = run;
  barrier();
  for (uint off = 1u; off < kRaySortThreads; off <<= 1u) {
    const uint add = t >= off ? run_sums[t - off] : 0u;
    barrier();
    run_sums[t] += add;
    barrier();
  }
  uint at = run_sums[t] - run;  // exclusive
  for (uint e = 0u; e < kRaySortDigits; ++e) {
    const uint c = thread_counts[t * kRaySortDigits + e];
    thread_counts[t * kRaySortDigits + e] = at;
    at += c;
  }
  barrier();
  // Per digit: where its pairs of this block start in the destination, less the pairs of the
  // block's smaller digits (thread_counts[d][0]), which every place below counts again
  if (t == 0u) {
    uint smaller = 0u;
    for (uint d = 0u; d < kRaySortDigits; ++d) {
      uint before = 0u, total = 0u;
      for (uint j = 0u; j < kRaySortThreads / kRaySortDigits; ++j) {
        before += part_before[j * kRaySortDigits + d];
        total += part_total[j * kRaySortDigits + d];
      }
      digit_base[d] = smaller + before - thread_counts[d * kRaySortThreads];
      smaller += total;
    }
  }
  barrier();
  for (uint i = 0u; i < kRaySortItems; ++i) {
    if (first + i >= pc.count) break;
    const uint d = digit_of(keys[i]);
    uint earlier = 0u;  // this invocation's pairs of the same digit before it
    for (uint k = 0u; k < i; ++k) earlier += digit_of(keys[k]) == d ? 1u : 0u;
    const uint to = digit_base[d] + thread_counts[d * kRaySortThreads + t] + earlier;
    if (pc.parity == 0u) {
      keys_b[to] = keys[i];
      values_b[to] = values[i];
    } else {
      keys_a[to] = keys[i];
      values_a[to] = values[i];
    }
  }
}

void main() {
  const uint block = gl_WorkGroupID.y * pc.groups_x + gl_WorkGroupID.x;
  if (block >= pc.blocks) return;  // the whole workgroup: no barrier is left waiting
  if (kStage == 0u) count_pass(block, gl_LocalInvocationIndex);
  else scatter_pass(block, gl_LocalInvocationIndex);
}
