#version 460
// ray_sort.comp: the frame's bounce rays sorted before their trace (FrameOptions::sort_bits;
// frame_input.h, kRaySort*). A subgroup's invocations wait for its longest ray; rays that leave
// from nearby points in nearby directions walk alike, so the trace takes them in the order of a
// key: the direction's cell on a cube of 16 x 16 cells a face (11 bits), then the origin's cell on
// a lattice of 128 a side over the grid, in Morton order (21 bits), as common/gather.h's
// coherent_ray_order keys a fixed list (over the grid's box, not the list's origins).
// The sort is a least-significant-digit radix sort of (key, pixel) pairs, 4 bits a pass over the
// key's top FrameOptions::sort_bits bits, each pass three dispatches:
//   count    (kRaySortSpecStage 0) a workgroup per block of kRaySortBlock pairs counts its
//            buckets into counts[bucket * blocks + block]; the first pass makes the keys from the
//            rays and writes the pairs (key, pixel) of A
//   scan     (1) a workgroup per bucket turns its row of counts into the pairs of that bucket in
//            the blocks before (in place), and writes the bucket's total after the rows
//   scatter  (2) each block again: a pair's place is the pairs of smaller buckets in all blocks,
//            those of its bucket in the blocks before, and those of its bucket before it in its own
//            block (each invocation's pairs consecutive: stable)
// A bucket is the pass's digit, or kRaySortNoRay for a pixel without a ray (bounce.comp gave it
// its miss already): the first pass puts those after every ray, and its scan writes the rays'
// count into the ray list's header, so that the later passes sort only the rays (most pixels
// have none where few surfaces are glossy) and the trace dispatches over them alone.
// The passes go A to B, then B to A; an even number of passes ends in A, whose first values are
// the ray list the trace takes (trace.comp, kGridSpecTraceList). Only the order depends on the
// sort: the trace writes each ray's hit at the ray's own index. Counting and ranking within a
// block go through shared memory, a column per invocation: no atomics, so the order is the keys'
// own (stable), whatever the scheduling.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/records.h"
#include "gridrt/common/shared/worklist.h"
#include "gridrt/vulkan/shaders/frame_input.h"

layout(local_size_x = 256) in;  // kRaySortThreads
layout(constant_id = kRaySortSpecStage) const uint kStage = 0u;

// The rays as 16-byte words (record_words.glsl: a RayRecord is three): the key reads the first two
layout(std430, binding = kRaySortBindRays) readonly buffer RayWords { uvec4 ray_words[]; };
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

// Ray i's key (above): 0xFFFFFFFF without a ray (tmax not above 0, as the trace's empty ray),
// 0xFFFFFFFE for a ray the trace rejects (a non-finite origin or direction, or a zero direction).
uint ray_sort_key(uint i) {
  const uvec4 w0 = ray_words[3u * i], w1 = ray_words[3u * i + 1u];
  const RayRecord ray = RayRecord(uintBitsToFloat(w0.xyz), uintBitsToFloat(w0.w), uintBitsToFloat(w1.xyz),
                                  uintBitsToFloat(w1.w), vec3(0.0f), 0u);
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

// A pair's bucket: the pass's digit of its key, or kRaySortNoRay without a ray (only in the
// first pass: the later ones take the rays alone).
uint digit_of(uint key) { return key == 0xFFFFFFFFu ? kRaySortNoRay : (key >> pc.shift) & (kRaySortDigits - 1u); }

// The pairs this pass sorts: the first pass every pixel; the later ones the rays, which the
// first pass's scan counted into the ray list's header.
uint pass_pairs() { return pc.first_pass != 0u ? pc.count : list_header.size; }

shared uint thread_counts[kRaySortBuckets * kRaySortThreads];  // [bucket][invocation]
shared uint run_sums[kRaySortThreads];
shared uint digit_base[kRaySortBuckets];

// The scatter's loads: this invocation's kRaySortItems consecutive pairs of its block, and their
// digits counted into its own column of thread_counts; returns how many lie within the pairs.
// (The loops are unrolled so that the loads of all its pairs are in flight at once.)
uint load_block(uint block, uint t, uint pairs, inout uint keys[kRaySortItems], inout uint values[kRaySortItems]) {
  const uint first = block * kRaySortBlock + t * kRaySortItems;
  [[unroll]] for (uint d = 0u; d < kRaySortBuckets; ++d) thread_counts[d * kRaySortThreads + t] = 0u;
  const uint n = first < pairs ? min(pairs - first, kRaySortItems) : 0u;
  if (pc.parity == 0u) {
    [[unroll]] for (uint i = 0u; i < kRaySortItems; ++i) {
      keys[i] = i < n ? keys_a[first + i] : 0u;
      values[i] = i < n ? values_a[first + i] : 0u;
    }
  } else {
    [[unroll]] for (uint i = 0u; i < kRaySortItems; ++i) {
      keys[i] = i < n ? keys_b[first + i] : 0u;
      values[i] = i < n ? values_b[first + i] : 0u;
    }
  }
  [[unroll]] for (uint i = 0u; i < kRaySortItems; ++i)
    if (i < n) thread_counts[digit_of(keys[i]) * kRaySortThreads + t] += 1u;
  return n;
}

// Invocation t's run of 16 entries of thread_counts' digit rows in their [digit][invocation]
// order summed: digit t / 16, invocations (t % 16) * 16 and the 15 after.
uint digit_run_sum(uint t) {
  uint run = 0u;
  [[unroll]] for (uint e = 0u; e < kRaySortDigits; ++e) run += thread_counts[t * kRaySortDigits + e];
  return run;
}

// Invocation t's run of kRaySortBuckets entries of thread_counts in its [bucket][invocation] order
// summed: entries t * kRaySortBuckets and the ones after (a run may span two buckets).
uint bucket_run_sum(uint t) {
  uint run = 0u;
  [[unroll]] for (uint e = 0u; e < kRaySortBuckets; ++e) run += thread_counts[t * kRaySortBuckets + e];
  return run;
}

// run_sums scanned (inclusive) across the workgroup.
void scan_run_sums(uint t) {
  [[unroll]] for (uint off = 1u; off < kRaySortThreads; off <<= 1u) {
    const uint add = t >= off ? run_sums[t - off] : 0u;
    barrier();
    run_sums[t] += add;
    barrier();
  }
}

// The count: each invocation counts the pairs i * kRaySortThreads + t of its block (any order
// counts alike; neighbouring invocations read neighbouring pairs), the first pass making the
// keys from the rays and writing A.
void count_pass(uint block, uint t) {
  const uint pairs = pass_pairs();
  if (block * kRaySortBlock >= pairs) {  // past the rays (a later pass): the whole workgroup
    if (t < kRaySortBuckets) counts[t * pc.blocks + block] = 0u;
    return;
  }
  [[unroll]] for (uint d = 0u; d < kRaySortDigits; ++d) thread_counts[d * kRaySortThreads + t] = 0u;
  [[unroll]] for (uint i = 0u; i < kRaySortItems; ++i) {
    const uint idx = block * kRaySortBlock + i * kRaySortThreads + t;
    if (idx >= pairs) break;
    uint key;
    if (pc.first_pass != 0u) {
      key = ray_sort_key(idx);
      keys_a[idx] = key;
      values_a[idx] = idx;
    } else {
      key = pc.parity == 0u ? keys_a[idx] : keys_b[idx];
    }
    const uint d = digit_of(key);
    if (d < kRaySortDigits) thread_counts[d * kRaySortThreads + t] += 1u;  // no ray: counted below
  }
  barrier();
  run_sums[t] = digit_run_sum(t);
  barrier();
  if (t < kRaySortDigits) {
    uint total = 0u;
    [[unroll]] for (uint j = 0u; j < kRaySortThreads / kRaySortDigits; ++j) total += run_sums[t * kRaySortDigits + j];
    counts[t * pc.blocks + block] = total;
    digit_base[t] = total;
  }
  barrier();
  if (t == 0u) {  // the block's pixels without a ray: all its pairs but the rays
    uint rays_in_block = 0u;
    [[unroll]] for (uint d = 0u; d < kRaySortDigits; ++d) rays_in_block += digit_base[d];
    counts[kRaySortNoRay * pc.blocks + block] = min(pairs - block * kRaySortBlock, kRaySortBlock) - rays_in_block;
  }
}

// Workgroup `digit`: its row of counts scanned in place (exclusive), its total after the rows.
void scan_pass(uint digit, uint t) {
  const uint per = (pc.blocks + kRaySortThreads - 1u) / kRaySortThreads;  // blocks an invocation takes
  const uint row = digit * pc.blocks, first = t * per;
  uint run = 0u;
  [[unroll]] for (uint i = 0u; i < 8u; ++i)
    if (i < per && first + i < pc.blocks) run += counts[row + first + i];
  for (uint i = 8u; i < per && first + i < pc.blocks; ++i) run += counts[row + first + i];
  run_sums[t] = run;
  barrier();
  scan_run_sums(t);
  uint at = run_sums[t] - run;
  for (uint i = 0u; i < per && first + i < pc.blocks; ++i) {
    const uint c = counts[row + first + i];
    counts[row + first + i] = at;
    at += c;
  }
  if (t == kRaySortThreads - 1u) {
    counts[kRaySortBuckets * pc.blocks + digit] = run_sums[t];
    // The first pass: the rays' count, which the later passes sort and the trace dispatches over
    // (a list of `size` items in workgroups of 64, as work_list_dispatch.comp writes one)
    if (pc.first_pass != 0u && digit == kRaySortNoRay) {
      const uint size = pc.count - run_sums[t];
      const uvec3 groups = work_list_groups(size, 64u, pc.max_groups_x);
      list_header.groups_x = groups.x;
      list_header.groups_y = groups.y;
      list_header.groups_z = groups.z;
      list_header.size = size;
    }
  }
}

void scatter_pass(uint block, uint t) {
  const uint pairs = pass_pairs();
  if (block * kRaySortBlock >= pairs) return;  // past the rays (a later pass): the whole workgroup
  uint keys[kRaySortItems], values[kRaySortItems];
  const uint n = load_block(block, t, pairs, keys, values);
  barrier();
  // The block's counts [bucket][invocation] scanned in that order (exclusive)
  const uint run = bucket_run_sum(t);
  run_sums[t] = run;
  barrier();
  scan_run_sums(t);
  uint at = run_sums[t] - run;
  [[unroll]] for (uint e = 0u; e < kRaySortBuckets; ++e) {
    const uint c = thread_counts[t * kRaySortBuckets + e];
    thread_counts[t * kRaySortBuckets + e] = at;
    at += c;
  }
  barrier();
  // Per bucket: where its pairs of this block start in the destination (the pairs of smaller
  // buckets, those of its bucket in the blocks before: the scan's), less the pairs of the block's
  // smaller buckets (thread_counts[d][0]), which every place below counts again
  if (t < kRaySortBuckets) {
    uint smaller = 0u;
    [[unroll]] for (uint d = 0u; d < kRaySortBuckets; ++d)
      if (d < t) smaller += counts[kRaySortBuckets * pc.blocks + d];
    digit_base[t] = smaller + counts[t * pc.blocks + block] - thread_counts[t * kRaySortThreads];
  }
  // Each pair's place within the block's sorted run (thread_counts[d][t]: the block's pairs of
  // smaller buckets, and of its bucket in the invocations before)
  uint local[kRaySortItems];
  [[unroll]] for (uint i = 0u; i < kRaySortItems; ++i) {
    const uint d = digit_of(keys[i]);
    uint earlier = 0u;  // this invocation's pairs of the same digit before it
    [[unroll]] for (uint k = 0u; k < i; ++k) earlier += digit_of(keys[k]) == d ? 1u : 0u;
    local[i] = thread_counts[d * kRaySortThreads + t] + earlier;
  }
  barrier();
  // The block's pairs in their sorted order in shared memory (thread_counts' room: keys, then
  // values), then written out by neighbouring invocations to neighbouring places: a digit's run of
  // the block goes to digit_base[d] + its place in the block
  [[unroll]] for (uint i = 0u; i < kRaySortItems; ++i)
    if (i < n) {
      thread_counts[local[i]] = keys[i];
      thread_counts[kRaySortBlock + local[i]] = values[i];
    }
  barrier();
  const uint in_block = min(pairs - block * kRaySortBlock, kRaySortBlock);
  [[unroll]] for (uint i = 0u; i < kRaySortItems; ++i) {
    const uint at_block = i * kRaySortThreads + t;
    if (at_block >= in_block) break;
    const uint key = thread_counts[at_block], value = thread_counts[kRaySortBlock + at_block];
    const uint to = digit_base[digit_of(key)] + at_block;
    if (pc.parity == 0u) {
      keys_b[to] = key;
      values_b[to] = value;
    } else {
      keys_a[to] = key;
      values_a[to] = value;
    }
  }
}

void main() {
  if (kStage == 1u) {
    scan_pass(gl_WorkGroupID.x, gl_LocalInvocationIndex);  // kRaySortBuckets workgroups
    return;
  }
  const uint block = gl_WorkGroupID.y * pc.groups_x + gl_WorkGroupID.x;
  if (block >= pc.blocks) return;  // the whole workgroup: no barrier is left waiting
  if (kStage == 0u) count_pass(block, gl_LocalInvocationIndex);
  else scatter_pass(block, gl_LocalInvocationIndex);
}
