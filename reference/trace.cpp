// trace.cpp: scene trace (paper 2.3): one ray, paper segments or the exact DDA. The Vulkan trace
// shader follows this file block by block, with the same names and heading comments.
#include <bit>
#include <limits>

#include "gridrt/reference/grid.h"

namespace gridrt::reference {

using namespace gridrt::shared;

namespace {

// The state of one ray's traversal (the shader's locals).
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
  float best_u;
  float best_v;
  uint best_flags;
  uint cells;
  uint tests;
  Mailbox mailbox;  // exact traversal, kGridMailbox: the last references tested
  uint mode;        // kTraceClosestHit or kTraceAnyHit
  WatertightRay wray;  // the watertight test's per-ray part (triangle_test_code)
  float surface_tol;   // the surface rule's tolerance (a ray launched from a surface), else -1
  uint box_mask;       // the dynamic boxes the walk can reach (skip_box_reached), bit b for box b
  ExplainRecord* ex;
};

// Any hit (kTraceAnyHit): a candidate is accepted, so the trace stops reading references.
bool found_any(const TraceState& st) { return st.mode == kTraceAnyHit && st.has_best; }

void emit(TraceState& st, uint kind, uint code, uint ref, uint step, uvec3 cell, uint slot, vec4 f0,
          vec4 f1) {
  if (st.ex) st.ex->events.push_back(ExplainEvent{kind, code, ref, step, cell, slot, f0, f1});
}

// Test one reference of a cell against the interval (t_lo, t_hi); the closest accepted hit so far
// is kept (ties: the smaller reference).
void test_reference(const GridData& grid, TraceState& st, uint ref, uint step, uvec3 cell, uint slot,
                    float t_lo, float t_hi) {
  const GridParams& g = grid.params;
  // Self-hit: the launch triangle
  if ((g.flags & kGridExcludeLaunchRef) != 0u && ref == st.launch_ref) {
    emit(st, kEvTest, kTestSelfHit, ref, step, cell, slot, vec4(0.0f), vec4(0.0f));
    return;
  }
  // The mailbox: a reference tested earlier on the ray is not tested again
  if (mailbox_enabled(g)) {
    if (mailbox_holds(st.mailbox, ref)) {
      emit(st, kEvTest, kTestMailboxed, ref, step, cell, slot, vec4(0.0f), vec4(0.0f));
      return;
    }
    mailbox_put(st.mailbox, ref);
  }
  const GridInstance inst = grid.instances[ref_instance(ref)];
  const uint k = inst.tri_offset + ref_triangle(ref);
  const GridTriangle tri = grid.triangles[k];
  // The triangle test (Moller-Trumbore or watertight) against the elongated segment; without
  // events to record, its code alone where its first rejections decide it (triangle_test_code).
  // The watertight test reads the triangle's plane from the plane buffer where its edge functions
  // leave it going (watertight_rest_plane): no normal made in the loop
  TriangleTest r{};
  const float best = st.has_best ? st.best_t : sh_infinity();
  uint code;
  float weights_det = 0.0f;  // what the test's weights u_det, v_det are scaled by (test_barycentrics)
  if (g.triangle_test == kTriangleWatertight) {
    WatertightEdges e;
    watertight_edges(st.org, st.wray, tri.v0, tri.v1, tri.v2, e);
    if (st.ex == nullptr && watertight_mixed(e)) code = watertight_outside_code(e);
    else code = watertight_rest_plane(st.org, st.dir, tri.v1, tri.v2, e, grid.planes[k], t_lo, t_hi, best, st.surface_tol, r);
    weights_det = abs(e.det);
  } else {
    code = st.ex ? triangle_test(g.triangle_test, st.org, st.dir, tri.v0, tri.v1, tri.v2, t_lo, t_hi, best, st.surface_tol, r)
                 : triangle_test_code(g.triangle_test, st.org, st.dir, st.wray, tri.v0, tri.v1, tri.v2, t_lo, t_hi, best,
                                      st.surface_tol, r);
    weights_det = abs(r.det);
  }
  st.tests += 1u;
  float t = 0.0f;
  vec2 bc = vec2(0.0f);
  if (code == kTestAccepted || (st.ex != nullptr && code == kTestOriginPlane)) {  // the refused one's t: for its event
    // Barycentrics: the test's own weights, clamped into the triangle (test_barycentrics; what
    // triangle_barycentrics makes again from the ray and the triangle)
    t = moller_trumbore_t(r);
    bc = test_barycentrics(r.u_det, r.v_det, weights_det);
    // The surface rule: a ray launched from a surface hits no face whose plane passes through its
    // origin (within 8 ulps); the watertight test decided it above, from its own plane values
    if (code == kTestAccepted && g.triangle_test != kTriangleWatertight && st.launch_ref != kNoRef &&
        origin_on_plane(st.org, tri.v0, tri.v1, tri.v2))
      code = kTestOriginPlane;
    // Alpha keying: the mask texel under the interpolated uv
    if (code == kTestAccepted && (g.flags & kGridAlphaKeying) != 0u && (inst.flags & kInstanceAlphaKeyed) != 0u) {
      const GridMaterial mat = grid.materials[tri.material];
      if (mat.alpha_width != 0u) {
        const GridTriangleUv tuv = grid.uvs[inst.tri_offset + ref_triangle(ref)];
        const vec2 uv = interpolate_uv(tuv.uv0, tuv.uv1, tuv.uv2, bc.x, bc.y);
        const uvec2 xy = alpha_texel_coords(uv, mat.alpha_width, mat.alpha_height);
        const uint alpha = texel_alpha(grid.texels[mat.alpha_offset + xy.y * mat.alpha_width + xy.x]);
        const bool keep = alpha_keeps(alpha);
        emit(st, kEvAlpha, keep ? 1u : 0u, ref, step, uvec3(xy.x, xy.y, tri.material), alpha,
             vec4(bc.x, bc.y, uv.x, uv.y), vec4(0.0f));
        if (!keep) code = kTestAlphaKeyed;
      }
    }
    // Tie rule: equal t keeps the smaller reference
    if (code == kTestAccepted && st.has_best && !(t < st.best_t || (t == st.best_t && ref < st.best_ref)))
      code = kTestTieLost;
  }
  emit(st, kEvTest, code, ref, step, cell, slot, vec4(r.det, r.u_det, r.v_det, r.t_det),
       vec4(r.lo_det, r.hi_det, r.best_det, t));
  if (code != kTestAccepted) return;
  // A new best hit
  emit(st, kEvCandidate, 0u, ref, step, cell, slot, vec4(t, bc.x, bc.y, st.has_best ? st.best_t : sh_infinity()),
       vec4(0.0f));
  st.has_best = true;
  st.best_t = t;
  st.best_ref = ref;
  st.best_u = bc.x;
  st.best_v = bc.y;
  st.best_flags = r.det < 0.0f ? kHitBackFace : 0u;
}

// Every reference of a cell, slot by slot up to the first blank; returns the last one read.
uint test_cell(const GridData& grid, TraceState& st, uvec3 cell, uint step, float t_lo, float t_hi) {
  const GridParams& g = grid.params;
  uint last = kBlank;
  for (uint s = 0u; s < g.capacity; ++s) {
    const uint ref = imageLoad(grid.image, ivec3(cell_slot_texel(g, cell, s)));
    emit(st, kEvSlot, 0u, ref, step, cell, s, vec4(0.0f), vec4(0.0f));
    if (ref == kBlank) break;
    last = ref;
    test_reference(grid, st, ref, step, cell, s, t_lo, t_hi);
    if (found_any(st)) break;
  }
  return last;
}

// The spilled references of a saturated cell (kGridSpill): the status texel says whether the cell
// dropped any; then its static and its dynamic spill lists are walked, each in ascending
// reference order (linked so by the order pass, whatever the order of the appends), and every entry is
// tested like a slot's reference. So the cell's references are all tested, in an order the same on
// every backend: after the slots', ascending.
void test_spilled(const GridData& grid, TraceState& st, uvec3 cell, uint step, float t_lo, float t_hi) {
  const GridParams& g = grid.params;
  const uint status = imageLoad(grid.image, ivec3(cell_status_texel(g, cell)));
  emit(st, kEvStatus, status, kBlank, step, cell, g.capacity, vec4(0.0f), vec4(0.0f));
  if (status == 0u) return;
  const uint appended = grid.spill_header.count;
  emit(st, kEvSpillScan, min(appended, grid.spill_header.capacity), kBlank, step, cell, appended, vec4(0.0f),
       vec4(0.0f));
  uint k = 0u;
  for (uint list = 0u; list < 2u; ++list) {
    uint i = grid.spill_heads[spill_head_index(cell_linear_index(g, cell), list == 1u)];
    while (i != kSpillEnd && k < grid.spill_header.capacity && !found_any(st)) {
      const SpillEntry e = grid.spill[i];
      emit(st, kEvSpilled, 0u, e.ref, step, cell, k, vec4(0.0f), vec4(0.0f));
      test_reference(grid, st, e.ref, step, cell, k, t_lo, t_hi);
      k += 1u;
      i = e.next;
    }
  }
}

// The compact layout (kGridCompact): a cell's static references are its run in refs (compact_run:
// dense offsets, or the index of occupied cells with kGridSparseOffsets), one event per reference,
// its index in the run as the slot, in ascending order;
// then, for a cell of the dynamic region, its dynamic spill list (the region's head: its status is
// kStatusDynamic where the list is not empty). Cells outside the region read no head.
// With kGridSkipCovered, a cell entered through a face whose cover bit is set (`covered`; `face`
// the face the walk entered through, kCoverNoFace for its first cell) reads no reference of its
// run: each was tested in the neighbour the walk came from (kEvCovered instead of the run's slots).
void test_compact_cell(const GridData& grid, TraceState& st, uvec3 cell, uint step, float t_lo, float t_hi,
                       uint face, bool covered) {
  const GridParams& g = grid.params;
  const uint i = cell_linear_index(g, cell);
  uint begin = 0u;
  uint end = 0u;
  compact_run(grid, i, begin, end);
  if (covered) {
    emit(st, kEvCovered, face, kBlank, step, cell, end - begin, vec4(0.0f), vec4(0.0f));
  } else {
    for (uint j = begin; j < end; ++j) {
      const uint ref = grid.refs[j];
      emit(st, kEvSlot, 0u, ref, step, cell, j - begin, vec4(0.0f), vec4(0.0f));
      test_reference(grid, st, ref, step, cell, j - begin, t_lo, t_hi);
      if (found_any(st)) return;
    }
    // The run's end, as the image's first blank slot
    emit(st, kEvSlot, 0u, kBlank, step, cell, end - begin, vec4(0.0f), vec4(0.0f));
  }
  const uvec3 lo = uvec3(grid.spill_heads[0], grid.spill_heads[1], grid.spill_heads[2]);
  const uvec3 hi = uvec3(grid.spill_heads[4], grid.spill_heads[5], grid.spill_heads[6]);
  if (!region_contains(cell, lo, hi)) return;
  uint e = grid.spill_heads[compact_head_index(region_index(cell, lo, hi))];
  const uint status = e != kSpillEnd ? kStatusDynamic : 0u;
  emit(st, kEvStatus, status, kBlank, step, cell, end - begin, vec4(0.0f), vec4(0.0f));
  if (status == 0u) return;
  const uint appended = grid.spill_header.count;
  emit(st, kEvSpillScan, min(appended, grid.spill_header.capacity), kBlank, step, cell, appended, vec4(0.0f),
       vec4(0.0f));
  uint k = 0u;
  while (e != kSpillEnd && k < grid.spill_header.capacity && !found_any(st)) {
    const SpillEntry entry = grid.spill[e];
    emit(st, kEvSpilled, 0u, entry.ref, step, cell, k, vec4(0.0f), vec4(0.0f));
    test_reference(grid, st, entry.ref, step, cell, k, t_lo, t_hi);
    k += 1u;
    e = entry.next;
  }
}

Hit report(TraceState& st, uint step) {
  Hit h{};
  h.t = st.best_t + st.t_base;
  h.instance = ref_instance(st.best_ref);
  h.triangle = ref_triangle(st.best_ref);
  h.u = st.best_u;
  h.v = st.best_v;
  h.flags = st.best_flags;
  h.cells = st.cells;
  h.tests = st.tests;
  emit(st, kEvReport, h.flags, st.best_ref, step, uvec3(0u), 0u, vec4(h.t, h.u, h.v, 0.0f), vec4(0.0f));
  return h;
}

Hit miss(TraceState& st, uint code, uint step, uint flags) {
  Hit h{};
  h.t = sh_infinity();
  h.instance = kNoInstance;
  h.triangle = 0u;
  h.flags = flags;
  h.cells = st.cells;
  h.tests = st.tests;
  emit(st, kEvMiss, code, kBlank, step, uvec3(0u), 0u, vec4(0.0f), vec4(0.0f));
  return h;
}

// The end of a traversal: the best candidate if there is one (hits found by elongation past the
// last segment are real triangle hits), else a miss.
Hit finish(TraceState& st, uint code, uint step) { return st.has_best ? report(st, step) : miss(st, code, step, 0u); }

// Gap-fill (paper 2.3): a saturated cell without a reported hit reports a false hit at the
// segment's midpoint with the last reference read, once the segment has left the launch surface.
bool gap_fill(const GridData& grid, TraceState& st, uvec3 cell, uint step, uint last_ref, vec3 sample,
              float t_mid, Hit& out) {
  const GridParams& g = grid.params;
  vec2 values;
  const bool left = gap_fill_left_surface(sample, st.org, st.launch_normal, g.gap_fill_r2, values);
  const bool inside = t_mid > st.rs.t_lo && t_mid < st.tmax;
  const uint code = !left ? kGapTooClose : (!inside ? kGapOutsideRay : kGapApplied);
  emit(st, kEvGapFill, code, last_ref, step, cell, 0u, vec4(values.x, values.y, t_mid, 0.0f), vec4(0.0f));
  if (code != kGapApplied) return false;
  const GridInstance inst = grid.instances[ref_instance(last_ref)];
  const GridTriangle tri = grid.triangles[inst.tri_offset + ref_triangle(last_ref)];
  const vec2 bc = cramer_barycentrics(tri.v0, tri.v1, tri.v2, sample);
  st.has_best = true;
  st.best_t = t_mid;
  st.best_ref = last_ref;
  st.best_u = bc.x;
  st.best_v = bc.y;
  st.best_flags = kHitGapFill;
  out = report(st, step);
  return true;
}

// ---- Paper traversal: cell-sized segments, sampled at their midpoints ----
Hit trace_paper(const GridData& grid, TraceState& st) {
  const GridParams& g = grid.params;
  uvec3 prev = uvec3(0xFFFFFFFFu);
  uint k = 0u;
  while (k < g.max_segments) {
    // The segment and its sample point (a midpoint past the grid's exit is clamped into the
    // boundary cell: closed rooms have their walls on the grid boundary)
    const float seg_begin = segment_begin(st.rs, k);
    if (seg_begin >= st.rs.t_end) return finish(st, seg_begin >= st.tmax ? kMissTmax : kMissLeftGrid, k);
    const uvec3 cell = segment_cell(g, st.org, st.dir, st.rs, k);
    // Visited-cell tracking: a straight ray does not come back to a convex cell
    if (cell == prev && g.repeats == kRepeatSkip) {
      emit(st, kEvCellSkipped, 0u, kBlank, k, cell, 0u,
           vec4(point_at(st.org, st.dir, segment_sample_t(st.rs, k)), segment_sample_t(st.rs, k)), vec4(0.0f));
      // A skipped step still reports a candidate that now lies before the segment's end
      if (st.has_best && st.best_t < segment_end(st.rs, k)) return report(st, k);
      k += 1u;
      continue;
    }
    prev = cell;
    // Merge the following segments whose samples fall into the same cell: one visit
    const uint last = segment_visit_last(g, st.org, st.dir, st.rs, k, cell);
    const float seg_end = segment_end(st.rs, last);
    const float t_mid = segment_t(st.rs, float(k + last + 1u) * 0.5f);
    const vec3 sample = point_at(st.org, st.dir, t_mid);
    st.cells += 1u;
    // Test the cell's references against the elongated segment
    const float t_lo = max(st.rs.t_lo, segment_elongated_begin(g, st.rs, k));
    const float t_hi = min(st.tmax, segment_elongated_end(g, st.rs, last));
    emit(st, kEvCell, last - k, kBlank, k, cell, 0u, vec4(sample, t_mid), vec4(seg_begin, seg_end, t_lo, t_hi));
    const uint last_ref = test_cell(grid, st, cell, k, t_lo, t_hi);
    // A saturated cell's spilled references
    if ((g.flags & kGridSpill) != 0u && last_ref != kBlank && !found_any(st))
      test_spilled(grid, st, cell, k, t_lo, t_hi);
    // Report the closest hit once it lies before the segment's end ("t < 1"); any hit at once
    if (st.has_best && (st.mode == kTraceAnyHit || st.best_t < seg_end)) return report(st, k);
    // Gap-fill in a saturated cell
    if ((g.flags & kGridGapFill) != 0u && last_ref != kBlank) {
      const uint status = imageLoad(grid.image, ivec3(cell_status_texel(g, cell)));
      emit(st, kEvStatus, status, kBlank, k, cell, g.capacity, vec4(0.0f), vec4(0.0f));
      Hit h;
      if (status != 0u && gap_fill(grid, st, cell, k, last_ref, sample, t_mid, h)) return h;
    }
    k = last + 1u;
  }
  return finish(st, kMissStepLimit, g.max_segments);
}

// The dynamic boxes the ray's walk can reach (shared/grid.h, "The ray's dynamic boxes"): bit b for
// box b. `k0`: the walk's first cell.
uint skip_box_mask(const GridData& grid, const TraceState& st, vec3 inv_dir, uvec3 k0) {
  uint mask = 0u;
  const uint boxes = grid.skip[0];
  for (uint b = 0u; b < boxes; ++b) {
    const uint w = skip_box_word(b);
    const uvec3 lo = uvec3(grid.skip[w], grid.skip[w + 1u], grid.skip[w + 2u]);
    const uvec3 hi = uvec3(grid.skip[w + 4u], grid.skip[w + 5u], grid.skip[w + 6u]);
    if (skip_box_reached(grid.params, st.org, st.dir, inv_dir, k0, st.rs.t_end, lo, hi)) mask |= 1u << b;
  }
  return mask;
}

// The skip field's distance of a cell (kGridSkipEmpty): its static distance, lowered to its
// distance to every dynamic box the walk can reach (shared/grid.h, "The skip field"); `cover` its
// cover bits (kGridSkipCovered), from the same byte.
uint skip_distance(const GridData& grid, const TraceState& st, uvec3 cell, uint& cover) {
  const uint i = cell_linear_index(grid.params, cell);
  const uint byte = (grid.skip[skip_distance_word(i)] >> skip_distance_shift(i)) & 0xFFu;
  cover = skip_byte_cover(byte);
  uint d = skip_byte_distance(byte);
  uint m = st.box_mask;  // its set bits, lowest first (the shader's findLSB)
  while (m != 0u && d > 0u) {
    const uint b = uint(std::countr_zero(m));
    m &= m - 1u;
    const uint w = skip_box_word(b);
    const uvec3 lo = uvec3(grid.skip[w], grid.skip[w + 1u], grid.skip[w + 2u]);
    const uvec3 hi = uvec3(grid.skip[w + 4u], grid.skip[w + 5u], grid.skip[w + 6u]);
    d = min(d, skip_box_distance(cell, lo, hi));
  }
  return d;
}

// ---- Exact traversal: 3D DDA over every pierced cell ----
Hit trace_exact(const GridData& grid, TraceState& st) {
  const GridParams& g = grid.params;
  // Enter the grid at t_start
  const vec3 inv_dir = dda_inverse_direction(st.dir);
  DdaWalk w = dda_walk_begin(g, st.org, st.dir, st.rs.t_start);
  float t_entry = st.rs.t_start;
  // The dynamic boxes the walk can reach: the others lower no distance on it
  st.box_mask = (g.flags & kGridSkipEmpty) != 0u ? skip_box_mask(grid, st, inv_dir, w.cell) : 0u;
  // The face the walk entered the cell through (kGridSkipCovered; the first cell: none)
  uint face = kCoverNoFace;
  for (uint k = 0u; k < g.max_segments; ++k) {
    // Empty-space skipping: an empty cell's distance d to the nearest reference; the walk passes
    // the box of radius d - 1 around it at once (docs/SPEC.md "Empty-space skipping")
    uint cover = 0u;
    const uint d = (g.flags & kGridSkipEmpty) != 0u ? skip_distance(grid, st, w.cell, cover) : 0u;
    dda_walk_exits(g, st.org, st.dir, inv_dir, d > 0u ? d - 1u : 0u, w);
    const float t_exit = w.t_exit;
    const uvec3 cell = w.cell;
    st.cells += 1u;
    if (d == 0u) {
      // Test the cell's references against the whole ray
      emit(st, kEvCell, 0u, kBlank, k, cell, 0u, vec4(point_at(st.org, st.dir, t_entry), t_entry),
           vec4(t_entry, t_exit, st.rs.t_lo, st.tmax));
      if ((g.flags & kGridCompact) != 0u) {
        // The compact layout: the cell's run, then its dynamic list
        test_compact_cell(grid, st, cell, k, st.rs.t_lo, st.tmax, face, ((cover >> face) & 1u) != 0u);
      } else {
        const uint last_ref = test_cell(grid, st, cell, k, st.rs.t_lo, st.tmax);
        // A saturated cell's spilled references
        if ((g.flags & kGridSpill) != 0u && last_ref != kBlank && !found_any(st))
          test_spilled(grid, st, cell, k, st.rs.t_lo, st.tmax);
      }
    } else {
      emit(st, kEvSkip, d, kBlank, k, cell, st.box_mask, vec4(point_at(st.org, st.dir, t_entry), t_entry),
           vec4(t_entry, t_exit, st.rs.t_lo, st.tmax));
    }
    // Report the closest hit once it lies inside this cell (or box) or before; any hit at once
    if (st.has_best && (st.mode == kTraceAnyHit || st.best_t <= t_exit)) return report(st, k);
    if (t_exit >= st.rs.t_end) return finish(st, t_exit >= st.tmax ? kMissTmax : kMissLeftGrid, k);
    // Step to the next cell: the face it is entered through is the step's (after a box of empty
    // cells too: the neighbour across it is then one of the box's, whose run is empty)
    face = skip_entry_face(st.dir, dda_step_axis(w.exits));
    if (!dda_walk_next(g, st.org, st.dir, inv_dir, w)) return finish(st, kMissLeftGrid, k);
    t_entry = t_exit;
  }
  return finish(st, kMissStepLimit, g.max_segments);
}

}  // namespace

// ---- Scene trace (paper 2.3) ----
Hit scene_trace(const GridData& grid, const Ray& ray, ExplainRecord* explain, uint mode) {
  const GridParams& g = grid.params;
  TraceState st{};
  st.org = ray.org;
  st.dir = traced_direction(ray.dir);  // a subnormal component taken as 0
  st.tmin = origin_tmin(ray.org, st.dir, ray.tmin);  // the origin epsilon
  st.tmax = ray.tmax;
  st.launch_normal = ray.launch_normal;
  st.launch_ref = ray.launch_ref;
  st.has_best = false;
  st.best_t = 0.0f;
  st.best_ref = kBlank;
  if (mailbox_enabled(g)) mailbox_clear(st.mailbox);
  st.mode = mode;
  st.wray = watertight_ray(st.dir);
  st.ex = explain;
  if (explain) {
    explain->ray = ray;
    explain->params = g;
    explain->mode = mode;
  }
  emit(st, kEvRay, 0u, ray.launch_ref, 0u, uvec3(0u), 0u, vec4(ray.org, ray.tmin), vec4(ray.dir, ray.tmax));
  // Reject rays with NaN/inf values or a zero direction
  if (!ray_valid(ray.org, ray.dir, ray.tmin, ray.tmax)) {
    emit(st, kEvRejected, 0u, kBlank, 0u, uvec3(0u), 0u, vec4(0.0f), vec4(0.0f));
    return miss(st, kMissOutsideGrid, 0u, kHitRejected);
  }
  // A far origin: moved along the ray to just before the grid box (docs/SPEC.md "Far origins")
  st.t_base = far_origin_base(g, st.org, st.dir, st.tmin, st.tmax);
  if (st.t_base > 0.0f) {
    st.org = ray.org + st.dir * st.t_base;
    st.tmin = max(st.tmin - st.t_base, 0.0f);
    st.tmax = st.tmax - st.t_base;
  }
  // The surface rule's tolerance (a ray launched from a surface), else none: from the origin the
  // trace tests from (moved, for a far origin)
  st.surface_tol = st.launch_ref != kNoRef ? surface_rule_tol(st.org) : -1.0f;
  // Per-ray setup: segment length, the grid box
  const bool meets = ray_setup(g, st.org, st.dir, st.tmin, st.tmax, st.rs);
  emit(st, kEvSetup, g.traversal, kBlank, 0u, uvec3(0u), meets ? 1u : 0u,
       vec4(st.rs.seg_t, st.rs.t_start, st.rs.t_end, st.rs.t_lo), vec4(st.launch_normal, st.t_base));
  if (!meets) return miss(st, kMissOutsideGrid, 0u, 0u);
  Hit h = g.traversal == kTraversalExact ? trace_exact(grid, st) : trace_paper(grid, st);
  if (explain) explain->hit = h;
  return h;
}

}  // namespace gridrt::reference
