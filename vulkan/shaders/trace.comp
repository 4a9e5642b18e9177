#version 460
// trace.comp: scene trace (paper 2.3), one invocation per ray: paper segments or the exact DDA,
// alpha keying and gap-fill, as specialization constants. This file follows reference/trace.cpp
// block by block, with the same names and heading comments; the explain ray (push constant)
// writes the same events as the reference's explain into the explain buffer. Where the shader
// departs from it, without explain and for speed only (the same hits in bits): the exact
// traversal over the compact layout runs trace_exact_flat, trace_exact's walk as one loop (the
// same tests in the same order); the reported hit's barycentrics are divided once in report(),
// from the best candidate's recorded weights, not at every candidate; and the frame's traces make each pixel's bounce or shadow ray themselves
// from the gather buffer (kTraceRays).
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"
#include "gridrt/common/shared/bounce.h"
#include "gridrt/common/shared/shadow.h"
#include "gridrt/vulkan/shaders/frame_input.h"

layout(local_size_x = 64) in;
layout(binding = kGridBindImage, r32ui) uniform readonly uimage3D grid_image;
// The rays and hits (RayRecord, HitRecord) as 16-byte words: load_ray, store_hit below
// The spill list and its heads (kGridSpill): read only here.
layout(std430, binding = kGridBindSpill) readonly buffer Spill {
  SpillHeader spill_header;
  SpillEntry spill_entries[];
};
layout(std430, binding = kGridBindSpillHeads) readonly buffer SpillHeads { uint spill_heads[]; };
// The skip field (kGridSkipEmpty; common/shared/grid.h): the dynamic boxes, then a byte per cell,
// its distance or (kGridSkipCovered) its cover bits.
layout(std430, binding = kGridBindSkip) readonly buffer Skip { uint skip[]; };
// The compact layout (kGridCompact): per cell its run of static references.
layout(std430, binding = kGridBindOffsets) readonly buffer Offsets { uint compact_offsets[]; };
// The same buffer as words of its index: a cell's word's base and occupancy mask in one load
layout(std430, binding = kGridBindOffsets) readonly buffer OffsetWords { uvec2 compact_words[]; };
uvec2 compact_word(uint i) { return compact_words[i / 32u]; }
layout(std430, binding = kGridBindRefs) readonly buffer Refs { uint compact_refs[]; };
layout(std430, binding = kGridBindExplain) buffer Explain {
  uint explain_count;  // events written (may exceed the capacity: then the tail is lost)
  uint explain_pad0;
  uint explain_pad1;
  uint explain_pad2;
  ExplainEvent explain_events[];
};
// Compacted rays (specialization constant kGridSpecTraceList): invocation k traces the ray ray_list[k] of the
// frame's work list of real bounce rays (common/shared/worklist.h), dispatched indirectly.
layout(constant_id = kGridSpecTraceList) const bool kTraceList = false;
layout(std430, binding = kGridBindRayList) readonly buffer RayList {
  WorkListHeader ray_list_header;
  uint ray_list[];
};
// Which hit the trace reports (kTraceClosestHit, or kTraceAnyHit for the frame's shadow rays): a
// constant, so that the closest-hit pipeline carries no test of the mode.
layout(constant_id = kGridSpecTraceMode) const uint kTraceMode = kTraceClosestHit;
// The frame's traces (specialization constant kGridSpecTraceRays; an image's rays, in tiles): each
// pixel's bounce ray, or its shadow ray towards the push constant's light, is made here from the
// pixel's gather texel, as bounce.comp and common/gather.cpp's bounce_rays and shadow_rays make
// them (common/shared/bounce.h, shadow.h), written to the ray buffer (shading and `gridrt diff`
// read it) and traced: the frame has no pass between the gather and the trace, and the rays are
// not read back from memory.
layout(constant_id = kGridSpecTraceRays) const uint kTraceRays = kTraceRaysBuffer;
// On llvmpipe only: flag a ray whose loops near the driver's limit (kHitLoopSpent, grid_interface.h)
layout(constant_id = kGridSpecLoopGuard) const bool kLoopGuard = false;
layout(std430, binding = kGridBindGather) readonly buffer GatherWords { uvec4 gather_words[]; };  // GatherTexels
layout(std430, binding = kGridBindFrameParams) readonly buffer FrameParamsBuffer { FrameParams fp; };
layout(std430, binding = kGridBindFrameMaterials) readonly buffer FrameMaterials { FrameMaterial fmaterials[]; };
layout(std430, binding = kGridBindRays) writeonly buffer RaysOut { uvec4 ray_words_out[]; };
// The rays and hits as 16-byte words (record_words.glsl)
layout(std430, binding = kGridBindRays) readonly buffer RayWords { uvec4 ray_words[]; };
layout(std430, binding = kGridBindHits) writeonly buffer HitWords { uvec4 hit_words[]; };
#include "record_words.glsl"

RayRecord load_ray(uint i) { return ray_from_words(ray_words[3u * i], ray_words[3u * i + 1u], ray_words[3u * i + 2u]); }

void store_hit(uint i, HitRecord h) {
  uvec4 w0, w1;
  hit_to_words(h, w0, w1);
  hit_words[2u * i] = w0;
  hit_words[2u * i + 1u] = w1;
}

void store_ray_out(uint i, RayRecord r) {
  uvec4 w0, w1, w2;
  ray_to_words(r, w0, w1, w2);
  ray_words_out[3u * i] = w0;
  ray_words_out[3u * i + 1u] = w1;
  ray_words_out[3u * i + 2u] = w2;
}

// The frame's bounce ray of pixel px (frame_input.h's frame_bounce_ray, as bounce.comp makes it).
RayRecord trace_bounce_ray(uvec2 px, GatherTexel t) {
  float gloss = 0.0f, cos_max = 1.0f;
  if (t.launch_ref != kNoRef && t.material < fp.material_count) {
    gloss = fmaterials[t.material].glossiness;
    cos_max = fmaterials[t.material].cos_max;
  }
  return frame_bounce_ray(fp.camera, fp.frame, t, gloss, cos_max, px.x, px.y);
}

layout(push_constant) uniform Push { TracePush pc; };

// The state of one ray's traversal (reference/trace.cpp, TraceState).
struct TraceState {
  vec3 org;
  vec3 dir;
  float tmin;
  float tmax;
  vec3 launch_normal;
  uint launch_ref;
  RaySetup rs;
  float t_base;  // a far origin's move along the ray (far_origin_base), else 0
  bool has_best;
  float best_t;
  uint best_ref;
  float best_u;     // the best hit's weights; without events to record, the test's u_det and
  float best_v;     // v_det until report() divides them by best_det (test_barycentrics)
  float best_det;
  uint best_flags;
  uint cells;
  uint tests;
  uint skips;       // references the mailbox skipped (counted for kLoopGuard only)
  Mailbox mailbox;  // exact traversal, kGridMailbox: the last references tested
  uint mode;        // kTraceClosestHit or kTraceAnyHit
  WatertightRay wray;  // the watertight test's per-ray part (triangle_test_code)
  float surface_tol;   // the surface rule's tolerance (a ray launched from a surface), else -1
  uint box_mask;       // the dynamic boxes the walk can reach (skip_box_reached), bit b for box b
};

TraceState st;
bool explaining = false;

// Any hit (kTraceAnyHit): a candidate is accepted, so the trace stops reading references.
bool found_any() { return st.mode == kTraceAnyHit && st.has_best; }

void emit(uint kind, uint code, uint ref, uint step, uvec3 cell, uint slot, vec4 f0, vec4 f1) {
  if (!kExplain || !explaining) return;
  const uint i = explain_count;
  if (i < pc.explain_capacity) explain_events[i] = ExplainEvent(kind, code, ref, step, cell, slot, f0, f1);
  explain_count = i + 1u;
}

// Test one reference of a cell against the interval (t_lo, t_hi); the closest accepted hit so far
// is kept (ties: the smaller reference).
void test_reference(GridParams g, uint ref, uint step, uvec3 cell, uint slot, float t_lo, float t_hi) {
  // Self-hit: the launch triangle
  if ((g.flags & kGridExcludeLaunchRef) != 0u && ref == st.launch_ref) {
    emit(kEvTest, kTestSelfHit, ref, step, cell, slot, vec4(0.0f), vec4(0.0f));
    return;
  }
  // The mailbox: a reference tested earlier on the ray is not tested again
  if (mailbox_enabled(g)) {
    if (mailbox_holds(st.mailbox, ref)) {
      if (kLoopGuard) st.skips += 1u;
      emit(kEvTest, kTestMailboxed, ref, step, cell, slot, vec4(0.0f), vec4(0.0f));
      return;
    }
    mailbox_put(st.mailbox, ref);
  }
  const GridInstance inst = instances[ref_instance(ref)];
  const uint k = inst.tri_offset + ref_triangle(ref);
  const GridTriangle tri = triangles[k];
  // The triangle test (Moller-Trumbore or watertight) against the elongated segment; without
  // events to record, its code alone where its first rejections decide it (triangle_test_code).
  // The watertight test reads the triangle's plane from the plane buffer where its edge functions
  // leave it going (watertight_rest_plane): no normal made in the loop
  TriangleTest r;
  const float best = st.has_best ? st.best_t : sh_infinity();
  uint code;
  float weights_det = 0.0f;  // what the test's weights u_det, v_det are scaled by (test_barycentrics)
  if (g.triangle_test == kTriangleWatertight) {
    WatertightEdges e;
    watertight_edges(st.org, st.wray, tri.v0, tri.v1, tri.v2, e);
    if (!kExplain && watertight_mixed(e)) code = watertight_outside_code(e);
    else code = watertight_rest_plane(st.org, st.dir, tri.v1, tri.v2, e, planes[k], t_lo, t_hi, best, st.surface_tol, r);
    weights_det = abs(e.det);
  } else {
    code = kExplain ? triangle_test(g.triangle_test, st.org, st.dir, tri.v0, tri.v1, tri.v2, t_lo, t_hi, best, st.surface_tol, r)
                    : triangle_test_code(g.triangle_test, st.org, st.dir, st.wray, tri.v0, tri.v1, tri.v2, t_lo, t_hi,
                                         best, st.surface_tol, r);
    weights_det = abs(r.det);
  }
  st.tests += 1u;
  float t = 0.0f;
  vec2 bc = vec2(0.0f);
  if (code == kTestAccepted || (kExplain && code == kTestOriginPlane)) {  // the refused one's t: for its event
    // Barycentrics: the test's own weights (test_barycentrics; without events to record, only
    // where alpha keying reads them: a new best keeps u_det, v_det and their determinant, and
    // report() divides them once, for the hit it reports: the same operations, the same bits)
    t = moller_trumbore_t(r);
    if (kExplain) bc = test_barycentrics(r.u_det, r.v_det, weights_det);
    // The surface rule: a ray launched from a surface hits no face whose plane passes through its
    // origin (within 8 ulps); the watertight test decided it above, from its own plane values
    if (code == kTestAccepted && g.triangle_test != kTriangleWatertight && st.launch_ref != kNoRef &&
        origin_on_plane(st.org, tri.v0, tri.v1, tri.v2))
      code = kTestOriginPlane;
    // Alpha keying: the mask texel under the interpolated uv
    if (code == kTestAccepted && (g.flags & kGridAlphaKeying) != 0u && (inst.flags & kInstanceAlphaKeyed) != 0u) {
      const GridMaterial mat = materials[tri.material];
      if (mat.alpha_width != 0u) {
        if (!kExplain) bc = test_barycentrics(r.u_det, r.v_det, weights_det);
        const GridTriangleUv tuv = uvs[inst.tri_offset + ref_triangle(ref)];
        const vec2 uv = interpolate_uv(tuv.uv0, tuv.uv1, tuv.uv2, bc.x, bc.y);
        const uvec2 xy = alpha_texel_coords(uv, mat.alpha_width, mat.alpha_height);
        const uint alpha = texel_alpha(texels[mat.alpha_offset + xy.y * mat.alpha_width + xy.x]);
        const bool keep = alpha_keeps(alpha);
        emit(kEvAlpha, keep ? 1u : 0u, ref, step, uvec3(xy.x, xy.y, tri.material), alpha,
             vec4(bc.x, bc.y, uv.x, uv.y), vec4(0.0f));
        if (!keep) code = kTestAlphaKeyed;
      }
    }
    // Tie rule: equal t keeps the smaller reference
    if (code == kTestAccepted && st.has_best && !(t < st.best_t || (t == st.best_t && ref < st.best_ref)))
      code = kTestTieLost;
  }
  emit(kEvTest, code, ref, step, cell, slot, vec4(r.det, r.u_det, r.v_det, r.t_det),
       vec4(r.lo_det, r.hi_det, r.best_det, t));
  if (code != kTestAccepted) return;
  // A new best hit
  emit(kEvCandidate, 0u, ref, step, cell, slot, vec4(t, bc.x, bc.y, st.has_best ? st.best_t : sh_infinity()),
       vec4(0.0f));
  st.has_best = true;
  st.best_t = t;
  st.best_ref = ref;
  if (kExplain) {
    st.best_u = bc.x;
    st.best_v = bc.y;
  } else {  // report() divides them
    st.best_u = r.u_det;
    st.best_v = r.v_det;
    st.best_det = weights_det;
  }
  st.best_flags = r.det < 0.0f ? kHitBackFace : 0u;
}

// Every reference of a cell, slot by slot up to the first blank; returns the last one read.
uint test_cell(GridParams g, uvec3 cell, uint step, float t_lo, float t_hi) {
  uint last = kBlank;
  for (uint s = 0u; s < g.capacity; ++s) {
    const uint ref = imageLoad(grid_image, ivec3(cell_slot_texel(g, cell, s))).x;
    emit(kEvSlot, 0u, ref, step, cell, s, vec4(0.0f), vec4(0.0f));
    if (ref == kBlank) break;
    last = ref;
    test_reference(g, ref, step, cell, s, t_lo, t_hi);
    if (found_any()) break;
  }
  return last;
}

// The spilled references of a saturated cell (kGridSpill): the status texel says whether the cell
// dropped any; then its static and its dynamic spill lists are walked, each in ascending
// reference order (linked so by the order pass, whatever the order of the appends), and every entry is
// tested like a slot's reference. So the cell's references are all tested, in an order the same on
// every backend: after the slots', ascending.
void test_spilled(GridParams g, uvec3 cell, uint step, float t_lo, float t_hi) {
  const uint status = imageLoad(grid_image, ivec3(cell_status_texel(g, cell))).x;
  emit(kEvStatus, status, kBlank, step, cell, g.capacity, vec4(0.0f), vec4(0.0f));
  if (status == 0u) return;
  const uint appended = spill_header.count;
  emit(kEvSpillScan, min(appended, spill_header.capacity), kBlank, step, cell, appended, vec4(0.0f), vec4(0.0f));
  uint k = 0u;
  for (uint list = 0u; list < 2u; ++list) {
    uint i = spill_heads[spill_head_index(cell_linear_index(g, cell), list == 1u)];
    while (i != kSpillEnd && k < spill_header.capacity && !found_any()) {
      const SpillEntry e = spill_entries[i];
      emit(kEvSpilled, 0u, e.ref, step, cell, k, vec4(0.0f), vec4(0.0f));
      test_reference(g, e.ref, step, cell, k, t_lo, t_hi);
      k += 1u;
      i = e.next;
    }
  }
}

// The compact layout (kGridCompact): a cell's static references are its run in refs,
// refs[offsets[i] .. offsets[i + 1]), or with kGridSparseOffsets found through the index of
// occupied cells (its word's occupancy mask: none if its bit is clear; else the word's base plus
// the occupied cells before it in the word is its place among the runs' starts) (one event per reference, its index in the run as the slot), in ascending order;
// then, for a cell of the dynamic region, its dynamic spill list (the region's head: its status is
// kStatusDynamic where the list is not empty). Cells outside the region read no head.
uvec3 region_lo;
uvec3 region_hi;
// With kGridSkipCovered, a cell entered through a face whose cover bit is set (`covered`; `face`
// the face the walk entered through, kCoverNoFace for its first cell) reads no reference of its
// run: each was tested in the neighbour the walk came from (kEvCovered instead of the run's slots).
void test_compact_cell(GridParams g, uvec3 cell, uint step, float t_lo, float t_hi, uint face, bool covered) {
  const uint i = cell_linear_index(g, cell);
  uint begin = 0u;
  uint end = 0u;
  if ((g.flags & kGridSparseOffsets) == 0u) {
    begin = compact_offsets[i];
    end = compact_offsets[i + 1u];
  } else {
    const uvec2 word = compact_word(i);
    if (compact_occupied(word.y, i)) {
      const uint k = compact_run_index(grid_cell_count(g), word.x, word.y, i);
      begin = compact_offsets[k];
      end = compact_offsets[k + 1u];
    }
  }
  if (covered) {
    emit(kEvCovered, face, kBlank, step, cell, end - begin, vec4(0.0f), vec4(0.0f));
  } else {
    for (uint j = begin; j < end; ++j) {
      const uint ref = compact_refs[j];
      emit(kEvSlot, 0u, ref, step, cell, j - begin, vec4(0.0f), vec4(0.0f));
      test_reference(g, ref, step, cell, j - begin, t_lo, t_hi);
      if (found_any()) return;
    }
    // The run's end, as the image's first blank slot
    emit(kEvSlot, 0u, kBlank, step, cell, end - begin, vec4(0.0f), vec4(0.0f));
  }
  if (!region_contains(cell, region_lo, region_hi)) return;
  uint e = spill_heads[compact_head_index(region_index(cell, region_lo, region_hi))];
  const uint status = e != kSpillEnd ? kStatusDynamic : 0u;
  emit(kEvStatus, status, kBlank, step, cell, end - begin, vec4(0.0f), vec4(0.0f));
  if (status == 0u) return;
  const uint appended = spill_header.count;
  emit(kEvSpillScan, min(appended, spill_header.capacity), kBlank, step, cell, appended, vec4(0.0f), vec4(0.0f));
  uint k = 0u;
  while (e != kSpillEnd && k < spill_header.capacity && !found_any()) {
    const SpillEntry entry = spill_entries[e];
    emit(kEvSpilled, 0u, entry.ref, step, cell, k, vec4(0.0f), vec4(0.0f));
    test_reference(g, entry.ref, step, cell, k, t_lo, t_hi);
    k += 1u;
    e = entry.next;
  }
}

HitRecord report(uint step) {
  // Without events to record, the reported hit's barycentrics are made here from the weights its
  // test recorded (test_reference kept u_det, v_det and their determinant): the same quotients as
  // at the candidate. (Made again from the ray and the triangle instead, the watertight test's
  // edge functions once a ray, the H200's trace was 2.4-6.7 % slower: docs/BENCHMARKS.md "A hit's
  // barycentrics carried out of the loop".) A gap-fill hit keeps those gap_fill made at its
  // sample point.
  if (!kExplain && (st.best_flags & kHitGapFill) == 0u) {
    const vec2 bc = test_barycentrics(st.best_u, st.best_v, st.best_det);
    st.best_u = bc.x;
    st.best_v = bc.y;
  }
  HitRecord h;
  precise float t = st.best_t + st.t_base;
  h.t = t;
  h.instance = ref_instance(st.best_ref);
  h.triangle = ref_triangle(st.best_ref);
  h.u = st.best_u;
  h.v = st.best_v;
  h.flags = st.best_flags;
  h.cells = st.cells;
  h.tests = st.tests;
  emit(kEvReport, h.flags, st.best_ref, step, uvec3(0u), 0u, vec4(h.t, h.u, h.v, 0.0f), vec4(0.0f));
  return h;
}

HitRecord miss(uint code, uint step, uint flags) {
  HitRecord h;
  h.t = sh_infinity();
  h.instance = kNoInstance;
  h.triangle = 0u;
  h.u = 0.0f;
  h.v = 0.0f;
  h.flags = flags;
  h.cells = st.cells;
  h.tests = st.tests;
  emit(kEvMiss, code, kBlank, step, uvec3(0u), 0u, vec4(0.0f), vec4(0.0f));
  return h;
}

// The end of a traversal: the best candidate if there is one (hits found by elongation past the
// last segment are real triangle hits), else a miss.
HitRecord finish(uint code, uint step) { return st.has_best ? report(step) : miss(code, step, 0u); }

// Gap-fill (paper 2.3): a saturated cell without a reported hit reports a false hit at the
// segment's midpoint with the last reference read, once the segment has left the launch surface.
bool gap_fill(GridParams g, uvec3 cell, uint step, uint last_ref, vec3 sample_point, float t_mid,
              out HitRecord result) {
  vec2 values;
  const bool left = gap_fill_left_surface(sample_point, st.org, st.launch_normal, g.gap_fill_r2, values);
  const bool inside = t_mid > st.rs.t_lo && t_mid < st.tmax;
  const uint code = !left ? kGapTooClose : (!inside ? kGapOutsideRay : kGapApplied);
  emit(kEvGapFill, code, last_ref, step, cell, 0u, vec4(values.x, values.y, t_mid, 0.0f), vec4(0.0f));
  if (code != kGapApplied) return false;
  const GridInstance inst = instances[ref_instance(last_ref)];
  const GridTriangle tri = triangles[inst.tri_offset + ref_triangle(last_ref)];
  const vec2 bc = cramer_barycentrics(tri.v0, tri.v1, tri.v2, sample_point);
  st.has_best = true;
  st.best_t = t_mid;
  st.best_ref = last_ref;
  st.best_u = bc.x;
  st.best_v = bc.y;
  st.best_flags = kHitGapFill;
  result = report(step);
  return true;
}

// ---- Paper traversal: cell-sized segments, sampled at their midpoints ----
HitRecord trace_paper(GridParams g) {
  uvec3 prev = uvec3(0xFFFFFFFFu);
  uint k = 0u;
  while (k < g.max_segments) {
    // The segment and its sample point (a midpoint past the grid's exit is clamped into the
    // boundary cell: closed rooms have their walls on the grid boundary)
    const float seg_begin = segment_begin(st.rs, k);
    if (seg_begin >= st.rs.t_end) return finish(seg_begin >= st.tmax ? kMissTmax : kMissLeftGrid, k);
    const uvec3 cell = segment_cell(g, st.org, st.dir, st.rs, k);
    // Visited-cell tracking: a straight ray does not come back to a convex cell
    if (cell == prev && g.repeats == kRepeatSkip) {
      emit(kEvCellSkipped, 0u, kBlank, k, cell, 0u,
           vec4(point_at(st.org, st.dir, segment_sample_t(st.rs, k)), segment_sample_t(st.rs, k)), vec4(0.0f));
      // A skipped step still reports a candidate that now lies before the segment's end
      if (st.has_best && st.best_t < segment_end(st.rs, k)) return report(k);
      k += 1u;
      continue;
    }
    prev = cell;
    // Merge the following segments whose samples fall into the same cell: one visit
    const uint last = segment_visit_last(g, st.org, st.dir, st.rs, k, cell);
    const float seg_end = segment_end(st.rs, last);
    const float t_mid = segment_t(st.rs, float(k + last + 1u) * 0.5f);
    const vec3 sample_point = point_at(st.org, st.dir, t_mid);
    st.cells += 1u;
    // Test the cell's references against the elongated segment
    const float t_lo = max(st.rs.t_lo, segment_elongated_begin(g, st.rs, k));
    const float t_hi = min(st.tmax, segment_elongated_end(g, st.rs, last));
    emit(kEvCell, last - k, kBlank, k, cell, 0u, vec4(sample_point, t_mid), vec4(seg_begin, seg_end, t_lo, t_hi));
    const uint last_ref = test_cell(g, cell, k, t_lo, t_hi);
    // A saturated cell's spilled references
    if ((g.flags & kGridSpill) != 0u && last_ref != kBlank && !found_any()) test_spilled(g, cell, k, t_lo, t_hi);
    // Report the closest hit once it lies before the segment's end ("t < 1"); any hit at once
    if (st.has_best && (st.mode == kTraceAnyHit || st.best_t < seg_end)) return report(k);
    // Gap-fill in a saturated cell
    if ((g.flags & kGridGapFill) != 0u && last_ref != kBlank) {
      const uint status = imageLoad(grid_image, ivec3(cell_status_texel(g, cell))).x;
      emit(kEvStatus, status, kBlank, k, cell, g.capacity, vec4(0.0f), vec4(0.0f));
      HitRecord h;
      if (status != 0u && gap_fill(g, cell, k, last_ref, sample_point, t_mid, h)) return h;
    }
    k = last + 1u;
  }
  return finish(kMissStepLimit, g.max_segments);
}

// The skip field's header (the box count and the dynamic boxes), copied to shared memory by the
// workgroup at its start: every visited cell reads it.
shared uint skip_header[kSkipHeaderWords];

// The dynamic boxes the ray's walk can reach (shared/grid.h, "The ray's dynamic boxes"): bit b for
// box b. `k0`: the walk's first cell.
uint skip_box_mask(GridParams g, vec3 inv_dir, uvec3 k0) {
  uint mask = 0u;
  const uint boxes = skip_header[0];
  for (uint b = 0u; b < boxes; ++b) {
    const uint w = skip_box_word(b);
    const uvec3 lo = uvec3(skip_header[w], skip_header[w + 1u], skip_header[w + 2u]);
    const uvec3 hi = uvec3(skip_header[w + 4u], skip_header[w + 5u], skip_header[w + 6u]);
    if (skip_box_reached(g, st.org, st.dir, inv_dir, k0, st.rs.t_end, lo, hi)) mask |= 1u << b;
  }
  return mask;
}

// The skip field's distance of a cell (kGridSkipEmpty): its static distance, lowered to its
// distance to every dynamic box the walk can reach (shared/grid.h, "The skip field"); `cover` its
// cover bits (kGridSkipCovered), from the same byte.
uint skip_distance(GridParams g, uvec3 cell, out uint cover) {
  const uint i = cell_linear_index(g, cell);
  const uint cell_byte = (skip[skip_distance_word(i)] >> skip_distance_shift(i)) & 0xFFu;
  cover = skip_byte_cover(cell_byte);
  uint d = skip_byte_distance(cell_byte);
  uint m = st.box_mask;
  while (m != 0u && d > 0u) {
    const uint b = uint(findLSB(m));
    m &= m - 1u;
    const uint w = skip_box_word(b);
    const uvec3 lo = uvec3(skip_header[w], skip_header[w + 1u], skip_header[w + 2u]);
    const uvec3 hi = uvec3(skip_header[w + 4u], skip_header[w + 5u], skip_header[w + 6u]);
    d = min(d, skip_box_distance(cell, lo, hi));
  }
  return d;
}

// ---- Exact traversal: 3D DDA over every pierced cell ----
HitRecord trace_exact(GridParams g) {
  // Enter the grid at t_start
  const vec3 inv_dir = dda_inverse_direction(st.dir);
  DdaWalk w = dda_walk_begin(g, st.org, st.dir, st.rs.t_start);
  float t_entry = st.rs.t_start;
  // The dynamic boxes the walk can reach: the others lower no distance on it
  st.box_mask = (g.flags & kGridSkipEmpty) != 0u ? skip_box_mask(g, inv_dir, w.cell) : 0u;
  if ((g.flags & kGridCompact) != 0u) {
    region_lo = uvec3(spill_heads[0], spill_heads[1], spill_heads[2]);
    region_hi = uvec3(spill_heads[4], spill_heads[5], spill_heads[6]);
  }
  // The face the walk entered the cell through (kGridSkipCovered; the first cell: none)
  uint face = kCoverNoFace;
  for (uint k = 0u; k < g.max_segments; ++k) {
    // Empty-space skipping: an empty cell's distance d to the nearest reference; the walk passes
    // the box of radius d - 1 around it at once (docs/SPEC.md "Empty-space skipping")
    uint cover = 0u;
    const uint d = (g.flags & kGridSkipEmpty) != 0u ? skip_distance(g, w.cell, cover) : 0u;
    dda_walk_exits(g, st.org, st.dir, inv_dir, d > 0u ? d - 1u : 0u, w);
    const float t_exit = w.t_exit;
    const uvec3 cell = w.cell;
    st.cells += 1u;
    if (d == 0u) {
      // Test the cell's references against the whole ray
      emit(kEvCell, 0u, kBlank, k, cell, 0u, vec4(point_at(st.org, st.dir, t_entry), t_entry),
           vec4(t_entry, t_exit, st.rs.t_lo, st.tmax));
      if ((g.flags & kGridCompact) != 0u) {
        // The compact layout: the cell's run, then its dynamic list
        test_compact_cell(g, cell, k, st.rs.t_lo, st.tmax, face, ((cover >> face) & 1u) != 0u);
      } else {
        const uint last_ref = test_cell(g, cell, k, st.rs.t_lo, st.tmax);
        // A saturated cell's spilled references
        if ((g.flags & kGridSpill) != 0u && last_ref != kBlank && !found_any())
          test_spilled(g, cell, k, st.rs.t_lo, st.tmax);
      }
    } else {
      emit(kEvSkip, d, kBlank, k, cell, st.box_mask, vec4(point_at(st.org, st.dir, t_entry), t_entry),
           vec4(t_entry, t_exit, st.rs.t_lo, st.tmax));
    }
    // Report the closest hit once it lies inside this cell (or box) or before; any hit at once
    if (st.has_best && (st.mode == kTraceAnyHit || st.best_t <= t_exit)) return report(k);
    if (t_exit >= st.rs.t_end) return finish(t_exit >= st.tmax ? kMissTmax : kMissLeftGrid, k);
    // Step to the next cell, entered through the step's face
    face = skip_entry_face(st.dir, dda_step_axis(w.exits));
    if (!dda_walk_next(g, st.org, st.dir, inv_dir, w)) return finish(kMissLeftGrid, k);
    t_entry = t_exit;
  }
  return finish(kMissStepLimit, g.max_segments);
}

// ---- Exact traversal, compact layout, without events: the same walk as one loop ----
// trace_exact's cells and tests in the same order with the same results, written as one loop
// whose every iteration either tests one reference (of the cell's run, then of its dynamic list)
// or finishes the cell and enters the next (Aila and Laine's "if-if" form): a subgroup's
// invocations whose cells hold fewer references step on while the others still test, instead of
// waiting at the end of each cell. The explain pipeline keeps trace_exact, which mirrors the
// reference block by block.
// The dynamic region's bounds (the heads' first 8 words: lo, then hi), copied to shared memory by
// the workgroup at its start, so that no invocation keeps them in registers through its walk.
shared uint region_words[8];
uint flat_j;      // the cell's run still to test: compact_refs[flat_j .. flat_end); past the run,
uint flat_end;    // flat_j - flat_end counts the dynamic list's entries read
uint flat_e;      // then its dynamic list from entry flat_e (kSpillEnd: none)

void flat_enter(GridParams g, vec3 inv_dir, inout DdaWalk w, uint face) {
  // Sparse offsets: the cell's word of the index is loaded beside its skip distance, not after it
  // (an occupied cell's chain of dependent loads, skip distance and word, run bounds, references,
  // is then as long as with dense offsets; an empty cell's word is loaded for nothing)
  const uint i = cell_linear_index(g, w.cell);
  const bool sparse = (g.flags & kGridSparseOffsets) != 0u;
  const uvec2 word = sparse ? compact_word(i) : uvec2(0u);
  uint cover = 0u;
  const uint d = (g.flags & kGridSkipEmpty) != 0u ? skip_distance(g, w.cell, cover) : 0u;
  dda_walk_exits(g, st.org, st.dir, inv_dir, d > 0u ? d - 1u : 0u, w);
  st.cells += 1u;
  flat_j = 0u;
  flat_end = 0u;
  flat_e = kSpillEnd;
  if (d != 0u) return;
  // A covered cell (kGridSkipCovered, its bits in the byte of its distance): its run was tested in
  // the cell the walk came from, and its bounds are not loaded
  if (((cover >> face) & 1u) == 0u) {
    if (!sparse) {
      flat_j = compact_offsets[i];
      flat_end = compact_offsets[i + 1u];
    } else if (compact_occupied(word.y, i)) {
      const uint k = compact_run_index(grid_cell_count(g), word.x, word.y, i);
      flat_j = compact_offsets[k];
      flat_end = compact_offsets[k + 1u];
    }
  }
  const uvec3 lo = uvec3(region_words[0], region_words[1], region_words[2]);
  const uvec3 hi = uvec3(region_words[4], region_words[5], region_words[6]);
  if (region_contains(w.cell, lo, hi)) flat_e = spill_heads[compact_head_index(region_index(w.cell, lo, hi))];
}

HitRecord trace_exact_flat(GridParams g) {
  const vec3 inv_dir = dda_inverse_direction(st.dir);
  DdaWalk w = dda_walk_begin(g, st.org, st.dir, st.rs.t_start);
  st.box_mask = (g.flags & kGridSkipEmpty) != 0u ? skip_box_mask(g, inv_dir, w.cell) : 0u;
  if (g.max_segments == 0u) return finish(kMissStepLimit, g.max_segments);
  uint k = 0u;
  flat_enter(g, inv_dir, w, kCoverNoFace);
  for (;;) {
    // The next reference of the cell: of its run, else of its dynamic list; one test_reference
    // for both (one copy of the test in the code, which the invocations of either share)
    bool more = true;
    uint ref;
    if (flat_j < flat_end) {
      ref = compact_refs[flat_j];
      flat_j += 1u;
    } else if (flat_e != kSpillEnd && flat_j - flat_end < spill_header.capacity) {
      const SpillEntry entry = spill_entries[flat_e];
      ref = entry.ref;
      flat_j += 1u;
      flat_e = entry.next;
    } else {
      more = false;
    }
    if (more) {
      test_reference(g, ref, k, w.cell, 0u, st.rs.t_lo, st.tmax);
      if (found_any()) flat_j = flat_end, flat_e = kSpillEnd;
      continue;
    }
    // The cell (or box) is done: report the closest hit once it lies inside it or before
    if (st.has_best && (st.mode == kTraceAnyHit || st.best_t <= w.t_exit)) return report(k);
    if (w.t_exit >= st.rs.t_end) return finish(w.t_exit >= st.tmax ? kMissTmax : kMissLeftGrid, k);
    const uint face = skip_entry_face(st.dir, dda_step_axis(w.exits));
    if (!dda_walk_next(g, st.org, st.dir, inv_dir, w)) return finish(kMissLeftGrid, k);
    k += 1u;
    if (k >= g.max_segments) return finish(kMissStepLimit, g.max_segments);
    flat_enter(g, inv_dir, w, face);
  }
  return finish(kMissStepLimit, g.max_segments);
}

// ---- Scene trace (paper 2.3) ----
HitRecord scene_trace(GridParams g, RayRecord ray, uint mode) {
  st.org = ray.org;
  st.dir = traced_direction(ray.dir);  // a subnormal component taken as 0
  st.tmin = origin_tmin(ray.org, st.dir, ray.tmin);  // the origin epsilon
  st.tmax = ray.tmax;
  st.launch_normal = ray.launch_normal;
  st.launch_ref = ray.launch_ref;
  st.has_best = false;
  st.best_t = 0.0f;
  st.best_ref = kBlank;
  st.best_u = 0.0f;
  st.best_v = 0.0f;
  st.best_det = 0.0f;
  st.best_flags = 0u;
  st.cells = 0u;
  st.tests = 0u;
  st.skips = 0u;
  if (mailbox_enabled(g)) mailbox_clear(st.mailbox);
  st.mode = mode;
  st.wray = watertight_ray(st.dir);
  emit(kEvRay, 0u, ray.launch_ref, 0u, uvec3(0u), 0u, vec4(ray.org, ray.tmin), vec4(ray.dir, ray.tmax));
  // Reject rays with NaN/inf values or a zero direction
  if (!ray_valid(ray.org, ray.dir, ray.tmin, ray.tmax)) {
    emit(kEvRejected, 0u, kBlank, 0u, uvec3(0u), 0u, vec4(0.0f), vec4(0.0f));
    return miss(kMissOutsideGrid, 0u, kHitRejected);
  }
  // A far origin: moved along the ray to just before the grid box (docs/SPEC.md "Far origins")
  st.t_base = far_origin_base(g, st.org, st.dir, st.tmin, st.tmax);
  if (st.t_base > 0.0f) {
    precise vec3 moved = ray.org + st.dir * st.t_base;
    st.org = moved;
    precise float tmin_moved = st.tmin - st.t_base;
    st.tmin = max(tmin_moved, 0.0f);
    precise float tmax_moved = st.tmax - st.t_base;
    st.tmax = tmax_moved;
  }
  // The surface rule's tolerance (a ray launched from a surface), else none: from the origin the
  // trace tests from (moved, for a far origin)
  st.surface_tol = st.launch_ref != kNoRef ? surface_rule_tol(st.org) : -1.0f;
  // Per-ray setup: segment length, the grid box
  const bool meets = ray_setup(g, st.org, st.dir, st.tmin, st.tmax, st.rs);
  emit(kEvSetup, g.traversal, kBlank, 0u, uvec3(0u), meets ? 1u : 0u,
       vec4(st.rs.seg_t, st.rs.t_start, st.rs.t_end, st.rs.t_lo), vec4(st.launch_normal, st.t_base));
  if (!meets) return miss(kMissOutsideGrid, 0u, 0u);
  if (g.traversal == kTraversalExact && !kExplain && (g.flags & kGridCompact) != 0u) return trace_exact_flat(g);
  return g.traversal == kTraversalExact ? trace_exact(g) : trace_paper(g);
}

// On llvmpipe (kLoopGuard), a ray whose estimated loop iterations reach the budget carries
// kHitLoopSpent, and the host refuses the trace (check_loop_limit, vulkan/grid.h)
HitRecord loop_guarded(HitRecord h) {
  if (kLoopGuard && llvmpipe_loop_estimate(kTraversal == kTraversalExact, (kFlags & kGridCompact) != 0u,
                                           mailbox_enabled(grid_params()), h.tests, st.skips, h.cells) >= kLlvmpipeLoopBudget)
    h.flags |= kHitLoopSpent;
  return h;
}

void main() {
  if ((kFlags & kGridSkipEmpty) != 0u && kTraversal == kTraversalExact) {
    for (uint w = gl_LocalInvocationIndex; w < kSkipHeaderWords; w += 64u) skip_header[w] = skip[w];
    barrier();
  }
  if ((kFlags & kGridCompact) != 0u && kTraversal == kTraversalExact) {
    if (gl_LocalInvocationIndex < 8u) region_words[gl_LocalInvocationIndex] = spill_heads[gl_LocalInvocationIndex];
    barrier();
  }
  if (pc.tiled_width != 0u) {
    // An image's rays (the frame's bounce rays, or its shadow rays toward one light, or with
    // kTraceRaysBoth the bounce rays in the workgroups of z = 0 and the shadow rays in those of
    // z = 1, one dispatch), an 8x8 pixel tile a workgroup: a subgroup's rays leave neighbouring
    // pixels (8x4 of them on a 32-wide subgroup, not 32 of a row), so they tend to walk the same
    // cells and stop together
    const uvec2 px = gl_WorkGroupID.xy * 8u + uvec2(gl_LocalInvocationID.x & 7u, gl_LocalInvocationID.x >> 3u);
    if (px.x >= pc.tiled_width || px.y >= pc.tiled_height) return;
    const bool bounce = kTraceRays == kTraceRaysBoth && gl_WorkGroupID.z == 0u;  // both: the bounce rays' half
    const uint r = (bounce ? 0u : pc.ray_offset) + px.y * pc.tiled_width + px.x;
    if (kTraceRays == kTraceRaysBoth) {
      const uint g = px.y * pc.tiled_width + px.x;
      const GatherTexel t = gather_from_words(gather_words[3u * g], gather_words[3u * g + 1u], gather_words[3u * g + 2u]);
      const RayRecord ray = bounce ? trace_bounce_ray(px, t)
                                   : shadow_ray(t.position, t.normal, t.launch_ref, vec3(pc.light_x, pc.light_y, pc.light_z),
                                                pc.light_directional != 0u);
      store_ray_out(r, ray);
      store_hit(r, loop_guarded(scene_trace(grid_params(), ray, bounce ? kTraceClosestHit : kTraceAnyHit)));
      return;
    }
    if (kTraceRays != kTraceRaysBuffer) {
      const uint g = px.y * pc.tiled_width + px.x;
      const GatherTexel t = gather_from_words(gather_words[3u * g], gather_words[3u * g + 1u], gather_words[3u * g + 2u]);
      const RayRecord ray = kTraceRays == kTraceRaysBounce
                                ? trace_bounce_ray(px, t)
                                : shadow_ray(t.position, t.normal, t.launch_ref, vec3(pc.light_x, pc.light_y, pc.light_z),
                                             pc.light_directional != 0u);
      store_ray_out(r, ray);
      store_hit(r, loop_guarded(scene_trace(grid_params(), ray, kTraceMode)));
      return;
    }
    store_hit(r, loop_guarded(scene_trace(grid_params(), load_ray(r), kTraceMode)));
    return;
  }
  if (kTraceList) {
    const uint k = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 64u, gl_LocalInvocationID.x);
    if (k >= ray_list_header.size) return;
    const uint r = ray_list[k];
    store_hit(r, loop_guarded(scene_trace(grid_params(), load_ray(r), kTraceMode)));
    return;
  }
  if (gl_GlobalInvocationID.x >= pc.ray_count) return;
  const uint i = pc.ray_offset + gl_GlobalInvocationID.x;
  explaining = kExplain && i == pc.explain_ray;
  store_hit(i, loop_guarded(scene_trace(grid_params(), load_ray(i), kTraceMode)));
}
