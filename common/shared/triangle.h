// triangle.h: the ray/triangle test and the barycentrics of the fixed-capacity grid (paper 2.3),
// written once for the reference and the shaders (compat.h rules).
//  - moller_trumbore: Moller and Trumbore 1997/2005, every decision free of division (Embree
//    style: u, v, t scaled by det, the sign of det folded in, compared against bounds * |det|).
//  - watertight: Woop, Benthin and Wald 2013 ("Watertight ray/triangle intersection", JCGT 2(1)),
//    with the shear scaled by the ray's dominant direction component instead of divided by it, so
//    that it needs no division at all (see the function).
//  - triangle_barycentrics: a hit's weights, the test's own (u, v or V, W over the determinant).
//  - cramer_barycentrics: Ericson 2004 (Real-Time Collision Detection, 3.4), one division: the
//    weights of a point that is no test's hit (a gap-fill sample).
#ifndef GRIDRT_SHARED_TRIANGLE_H
#define GRIDRT_SHARED_TRIANGLE_H

#include "alpha.h"
#include "compat.h"
#include "grid.h"

SH_BEGIN

// Outcome of one triangle test (TriangleTest::code, ExplainEvent::code of a test event). The
// first failing condition, in this order, names the outcome.
SH_CONST uint kTestAccepted = 0u;    // inside, within the bounds, not farther than the best hit
SH_CONST uint kTestParallel = 1u;    // det zero or subnormal: ray parallel to the plane (or a zero-area triangle)
SH_CONST uint kTestOutsideU = 2u;    // u * det < 0: beyond edge v0-v2
SH_CONST uint kTestOutsideV = 3u;    // v * det < 0: beyond edge v0-v1
SH_CONST uint kTestOutsideUV = 4u;   // (u + v) * det > |det|: beyond edge v1-v2
SH_CONST uint kTestBehind = 5u;      // t * det <= t_lo * |det|: before the (elongated) segment
SH_CONST uint kTestBeyond = 6u;      // t * det >= t_hi * |det|: after the (elongated) segment
SH_CONST uint kTestNotCloser = 7u;   // t * det > closest_bound(best_t) * |det|: the best hit so far is closer
SH_CONST uint kTestSelfHit = 8u;     // the ray's launch triangle (by reference); not tested
SH_CONST uint kTestAlphaKeyed = 9u;  // accepted geometrically, cut away by the alpha mask
SH_CONST uint kTestTieLost = 10u;    // reported t not smaller than the best (ties: smaller ref)
SH_CONST uint kTestMailboxed = 11u;  // exact traversal, kGridMailbox: tested earlier on this ray (in the
                                     // mailbox), not tested again: the result cannot change
SH_CONST uint kTestOriginPlane = 12u;  // accepted geometrically, refused by the surface rule: the face's
                                       // plane passes within 8 ulps of the origin (origin_on_plane)

// The values a test decides on: everything scaled by |det|, so that no division is needed.
struct TriangleTest {
  float det;       // signed determinant dot(e1, cross(dir, e2)); < 0: back face
  float u_det;     // u * |det| (weight of v1)
  float v_det;     // v * |det| (weight of v2)
  float t_det;     // t * |det|
  float lo_det;    // t_lo * |det|
  float hi_det;    // t_hi * |det|
  float best_det;  // closest_bound(best_t) * |det| (+inf without a best hit)
  uint code;       // kTest*
};

// The bound of the tests' "not closer" rejection: best_t raised by two ulps (+inf, and values
// within two ulps of the largest float, give +inf). The rejection compares products
// (T > bound * |det|); with best_t itself it could drop a candidate whose reported t
// (T / |det|, correctly rounded) equals best_t, and which one survived would then depend on the
// order of the tests. Two ulps above, a rejected candidate's reported t exceeds best_t (docs/
// SPEC.md, "Moller-Trumbore"), so every candidate that could tie or win reaches the caller's tie
// rule on the reported t and the reference, and the closest hit is the smallest (t, reference)
// whatever the order.
SH_INLINE float closest_bound(float best_t) {
  const uint b = floatBitsToUint(best_t);
  return b >= 0x7F7FFFFEu ? uintBitsToFloat(0x7F800000u) : uintBitsToFloat(b + 2u);
}

// Moller-Trumbore against the open interval (t_lo, t_hi), and not farther than best_t
// (t * det <= closest_bound(best_t) * |det|; ties and near ties are settled by the caller on the
// reported t and the reference).
// Order of operations (both sides): e1 = v1 - v0, e2 = v2 - v0, p = cross(dir, e2),
// det = dot(e1, p), s = org - v0, U = dot(s, p), q = cross(s, e1), V = dot(dir, q),
// T = dot(e2, q); U, V, T multiplied by sign(det) (exact).
// Its first half: the determinant and u (triangle_test_code() stops after it when they reject).
struct MollerFirst {
  vec3 e1;    // v1 - v0
  vec3 e2;    // v2 - v0
  vec3 s;     // org - v0
  float det;  // dot(e1, cross(dir, e2))
  float sgn;  // sign(det)
  float u;    // dot(s, cross(dir, e2)) * sgn
};
SH_INLINE void moller_trumbore_first(SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) v0, SH_IN(vec3) v1,
                                     SH_IN(vec3) v2, SH_OUT(MollerFirst) m) {
  // Determinant: the ray against the triangle's plane
  SH_PRECISE vec3 e1 = v1 - v0;
  SH_PRECISE vec3 e2 = v2 - v0;
  vec3 p = sh_cross(dir, e2);
  SH_PRECISE float det = sh_dot(e1, p);
  // Scaled barycentrics and distance, the sign of det folded in
  SH_PRECISE vec3 s = org - v0;
  SH_PRECISE float sgn = det < 0.0f ? -1.0f : 1.0f;
  SH_PRECISE float u = sh_dot(s, p) * sgn;
  m.e1 = e1;
  m.e2 = e2;
  m.s = s;
  m.det = det;
  m.sgn = sgn;
  m.u = u;
}

// Its second half, from its first `m` (moller_trumbore_first of the same ray and triangle).
SH_INLINE uint moller_trumbore_rest(SH_IN(vec3) dir, SH_IN(MollerFirst) m, float t_lo, float t_hi, float best_t,
                                    SH_OUT(TriangleTest) r) {
  SH_PRECISE vec3 e1 = m.e1;
  SH_PRECISE vec3 e2 = m.e2;
  SH_PRECISE vec3 s = m.s;
  SH_PRECISE float det = m.det;
  SH_PRECISE float sgn = m.sgn;
  SH_PRECISE float u = m.u;
  vec3 q = sh_cross(s, e1);
  SH_PRECISE float ad = det * sgn;
  SH_PRECISE float v = sh_dot(dir, q) * sgn;
  SH_PRECISE float t = sh_dot(e2, q) * sgn;
  SH_PRECISE float uv = u + v;
  SH_PRECISE float lo = t_lo * ad;
  SH_PRECISE float hi = t_hi * ad;
  SH_PRECISE float best = closest_bound(best_t) * ad;
  r.det = det;
  r.u_det = u;
  r.v_det = v;
  r.t_det = t;
  r.lo_det = lo;
  r.hi_det = hi;
  r.best_det = best;
  // Decisions: + - * and comparisons only
  if (sh_zero_or_subnormal(det)) r.code = kTestParallel;
  else if (u < 0.0f) r.code = kTestOutsideU;
  else if (v < 0.0f) r.code = kTestOutsideV;
  else if (uv > ad) r.code = kTestOutsideUV;
  else if (t <= lo) r.code = kTestBehind;
  else if (t >= hi) r.code = kTestBeyond;
  else if (t > best) r.code = kTestNotCloser;
  else r.code = kTestAccepted;
  return r.code;
}

SH_INLINE uint moller_trumbore(SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) v0, SH_IN(vec3) v1,
                               SH_IN(vec3) v2, float t_lo, float t_hi, float best_t,
                               SH_OUT(TriangleTest) r) {
  MollerFirst m;
  moller_trumbore_first(org, dir, v0, v1, v2, m);
  return moller_trumbore_rest(dir, m, t_lo, t_hi, best_t, r);
}

// Component k (0 x, 1 y, 2 z) of v, without dynamic vector indexing.
SH_INLINE float sh_component(SH_IN(vec3) v, uint k) { return k == 0u ? v.x : (k == 1u ? v.y : v.z); }

// Watertight test (Woop, Benthin, Wald 2013) against (t_lo, t_hi) and not farther than best_t, in
// the same TriangleTest as moller_trumbore (det's sign: < 0 for a back face, as there).
// Steps: kz = the axis of the largest |dir| component (ties x, y, z), kx, ky the next two
// cyclically. The paper shears the vertices relative to org by S = (dx/dz, dy/dz, 1/dz); here
// every sheared coordinate is multiplied by dz instead: a.x = A[kx]*dz - dx*A[kz] (A = v0 - org,
// likewise a.y, b, c). The 2D edge functions U = c.x b.y - c.y b.x, V = a.x c.y - a.y c.x,
// W = b.x a.y - b.y a.x are then the paper's times dz^2 (same signs). A vertex's sheared
// coordinates depend only on the vertex and the ray, and an edge shared by two triangles gives
// both the same products in the opposite order, so its edge function is exactly negated: a ray
// through a shared edge or vertex is inside at least one of the triangles (no hole). Zero edge
// functions count as inside; an edge function that rounds to zero is computed again exactly
// (the paper re-tests zeros in double precision; GLSL has no portable double, so here in float
// with Dekker's exact products: edge_function_refined), so a zero left is a true zero of the
// sheared coordinates; both triangles of a shared edge then accept and the tie rule picks
// one. det = U + V + W. The distance: with n = (v1 - v0) x (v2 - v0) and P the vertex nearest the
// origin less org (plane_anchor) and H that of the largest weight (hit_anchor), T = -n.H and
// D = -n.dir (t = n.H / n.dir, the plane equation) where |n.dir| * 2^12 >= |n|_1 |dir|_1 (the
// ray not grazing the plane), else T = U A[kz] + V B[kz] + W C[kz] = t * det * dz and
// D = det * dz; all t decisions compare T against bounds times |D|, the sign of D folded in.
// Recorded: det = D (its sign is that of moller_trumbore's det: < 0 a back face), u_det = V,
// v_det = W (times sign(det), so scaled by |det|, not |D|), t_det = T, lo/hi/best times |D|;
// moller_trumbore_t then reports t = T / |D|. Float range: products of three coordinates
// (|org - v| * |dir|^2, |v1 - v0|^2 |dir| ...) stay finite for coordinates and directions below
// about 1e12.
// The watertight test's first half: the permutation, the sheared vertices and the edge functions
// (watertight() below; triangle_test_code() stops after it when they reject).
struct WatertightEdges {
  vec3 A;     // v0 - org
  float dz;   // dir's dominant component
  float az;   // A, B, C along the dominant axis
  float bz;
  float cz;
  float U;    // edge functions: the weights of v0, v1, v2 times det
  float V;
  float W;
  float det;  // U + V + W
};
// The test's part that depends on the ray alone: the permutation (kz the dominant axis of the
// direction, kx and ky the next two cyclically) and the direction's components in it. watertight()
// makes it for each test; a trace can make it once per ray (the same values).
struct WatertightRay {
  uint kx;
  uint ky;
  uint kz;
  float dx;
  float dy;
  float dz;
};
SH_INLINE WatertightRay watertight_ray(SH_IN(vec3) dir) {
  // Permutation: kz the dominant axis of the direction
  SH_PRECISE vec3 adir = abs(dir);
  WatertightRay w;
  w.kz = adir.x >= adir.y ? (adir.x >= adir.z ? 0u : 2u) : (adir.y >= adir.z ? 1u : 2u);
  w.kx = w.kz == 2u ? 0u : w.kz + 1u;
  w.ky = w.kx == 2u ? 0u : w.kx + 1u;
  w.dx = sh_component(dir, w.kx);
  w.dy = sh_component(dir, w.ky);
  w.dz = sh_component(dir, w.kz);
  return w;
}

// An edge function e = fl(fl(x y) - fl(z w)) taken again where it rounded to zero. Rounding is
// monotone, so a non-zero e has the exact sign of x y - z w; a zero one only says that the two
// rounded products are equal (two floats differ by zero only when equal), and then x y - z w is
// exactly the difference of their rounding errors, rounded once here: its sign is exact, and it
// is exactly negated for the same products in the other order (a shared edge). Without it, two
// products of coordinates far larger than the triangle round to the same float (1e4 from the
// origin, a triangle 0.1 wide), U = W = 0 counted as inside, and a ray 4e4 from a triangle hit it.
SH_INLINE float edge_function_refined(float e, float x, float y, float z, float w) {
  if (e != 0.0f) return e;
  SH_PRECISE float p = x * y;
  SH_PRECISE float q = z * w;
  SH_PRECISE float ep = sh_product_error(x, y, p);
  SH_PRECISE float eq = sh_product_error(z, w, q);
  SH_PRECISE float d = ep - eq;
  return d;
}

SH_INLINE void watertight_edges(SH_IN(vec3) org, SH_IN(WatertightRay) w, SH_IN(vec3) v0, SH_IN(vec3) v1,
                                SH_IN(vec3) v2, SH_OUT(WatertightEdges) e) {
  uint kx = w.kx;
  uint ky = w.ky;
  uint kz = w.kz;
  float dx = w.dx;
  float dy = w.dy;
  float dz = w.dz;
  // Vertices relative to the origin, sheared (scaled by dz, no division)
  SH_PRECISE vec3 A = v0 - org;
  SH_PRECISE vec3 B = v1 - org;
  SH_PRECISE vec3 C = v2 - org;
  SH_PRECISE float az = sh_component(A, kz);
  SH_PRECISE float bz = sh_component(B, kz);
  SH_PRECISE float cz = sh_component(C, kz);
  SH_PRECISE float ax = sh_component(A, kx) * dz - dx * az;
  SH_PRECISE float ay = sh_component(A, ky) * dz - dy * az;
  SH_PRECISE float bx = sh_component(B, kx) * dz - dx * bz;
  SH_PRECISE float by = sh_component(B, ky) * dz - dy * bz;
  SH_PRECISE float cx = sh_component(C, kx) * dz - dx * cz;
  SH_PRECISE float cy = sh_component(C, ky) * dz - dy * cz;
  // Edge functions (the weights of v0, v1, v2 times det)
  SH_PRECISE float U0 = cx * by - cy * bx;
  SH_PRECISE float V0 = ax * cy - ay * cx;
  SH_PRECISE float W0 = bx * ay - by * ax;
  // Zeros taken again exactly: the signs are then exact for the sheared coordinates
  SH_PRECISE float U = edge_function_refined(U0, cx, by, cy, bx);
  SH_PRECISE float V = edge_function_refined(V0, ax, cy, ay, cx);
  SH_PRECISE float W = edge_function_refined(W0, bx, ay, by, ax);
  SH_PRECISE float uv = U + V;
  SH_PRECISE float det = uv + W;
  e.A = A;
  e.dz = dz;
  e.az = az;
  e.bz = bz;
  e.cz = cz;
  e.U = U;
  e.V = V;
  e.W = W;
  e.det = det;
}

// Inside iff U, V, W do not have mixed signs.
SH_INLINE bool watertight_mixed(SH_IN(WatertightEdges) e) {
  return (e.U < 0.0f || e.V < 0.0f || e.W < 0.0f) && (e.U > 0.0f || e.V > 0.0f || e.W > 0.0f);
}

// The code of a test whose edge functions have mixed signs (watertight()'s first three cases).
SH_INLINE uint watertight_outside_code(SH_IN(WatertightEdges) e) {
  SH_PRECISE float sdet = e.det < 0.0f ? -1.0f : 1.0f;
  SH_PRECISE float u = e.V * sdet;
  SH_PRECISE float v = e.W * sdet;
  return u < 0.0f ? kTestOutsideU : (v < 0.0f ? kTestOutsideV : kTestOutsideUV);
}

// Of A, B, C (= v0, v1, v2 - org), the vertex whose weight (U, V, W: the edge functions, the
// weights of v0, v1, v2 times det; of one sign where the test goes on) is largest in magnitude, ties
// to the first: the vertex nearest the hit in the triangle's own measure, where the plane value
// for t is taken (a ray through a vertex of a cap then meets the plane at that vertex's own t).
SH_INLINE vec3 hit_anchor(SH_IN(vec3) A, SH_IN(vec3) B, SH_IN(vec3) C, float U, float V, float W) {
  SH_PRECISE float au = abs(U);
  SH_PRECISE float av = abs(V);
  SH_PRECISE float aw = abs(W);
  vec3 h = A;
  float best = au;
  if (av > best) {
    h = B;
    best = av;
  }
  if (aw > best) h = C;
  return h;
}

// The watertight test's second half, from its edge functions `e` (watertight_edges of the ray)
// and the triangle's plane (triangle_plane of v0, v1, v2: made here by watertight_rest, read from
// the plane buffer by a trace). `surface_tol`: the surface rule's tolerance for a ray launched from a surface
// (surface_rule_tol(org)), negative for any other ray: an accepted candidate whose plane passes
// within the face's tolerance (surface_rule_face_tol of it and A) of the origin is refused
// (kTestOriginPlane), origin_on_plane's decision made from the test's own plane values (the same
// normal and anchor: A of `e` and v1, v2 - org made again, in the same bits as
// watertight_edges's).
SH_INLINE uint watertight_rest_plane(SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) v1, SH_IN(vec3) v2,
                                     SH_IN(WatertightEdges) e, SH_IN(GridPlane) plane, float t_lo, float t_hi,
                                     float best_t, float surface_tol, SH_OUT(TriangleTest) r) {
  SH_PRECISE vec3 adir = abs(dir);
  SH_PRECISE vec3 A = e.A;
  SH_PRECISE float dz = e.dz;
  SH_PRECISE float az = e.az;
  SH_PRECISE float bz = e.bz;
  SH_PRECISE float cz = e.cz;
  SH_PRECISE float U = e.U;
  SH_PRECISE float V = e.V;
  SH_PRECISE float W = e.W;
  SH_PRECISE float det = e.det;
  // Distance times det * dz, the sign of D = det * dz folded in
  SH_PRECISE float tu = U * az;
  SH_PRECISE float tv = V * bz;
  SH_PRECISE float tw = W * cz;
  SH_PRECISE float tuv = tu + tv;
  SH_PRECISE float T = tuv + tw;
  SH_PRECISE float D = det * dz;
  // The distance from the plane equation: with n = (v1 - v0) x (v2 - v0), t = n.H / n.dir, as a
  // fraction -n.H / -n.dir (H: hit_anchor; the denominator's sign that of D and of
  // moller_trumbore's det). Its error follows the problem's condition (docs/ACCURACY.md, "t
  // against the exact t"): a few ulps over the sine of the angle between the ray and the plane,
  // the normal being a few ulps of itself (plane_normal_scaled). T / D, a weighted mean of the
  // vertices' depths, is off by the edge functions' rounding over their sum, which on a cap or a
  // sliver is that much larger again (a ray grazing a stretched torus met a cap at t 1 % off,
  // behind its neighbour: an outside review's find). So the plane's fraction wherever n.dir is
  // not 0 and, where the ray grazes the plane (|n.dir| < 2^-12 |n|_1 |dir|_1), has the sign of D
  // (the edge functions' orientation); a grazing ray's t is then clamped into the triangle's
  // depth range (the t's at which the ray reaches its vertices' depths along the dominant axis,
  // where the true t lies), which the plane's fraction may leave as n.dir nears its rounding and
  // T / D never does. T / D is kept where n.dir is 0 or has the other sign.
  SH_PRECISE vec3 nrm = plane.n;
  SH_PRECISE float nscale = plane.scale;
  SH_PRECISE float pden = sh_dot(nrm, dir);
  SH_PRECISE vec3 anrm = abs(nrm);
  SH_PRECISE float nsum = anrm.x + anrm.y;
  SH_PRECISE float n1 = nsum + anrm.z;
  SH_PRECISE float dsum = adir.x + adir.y;
  SH_PRECISE float d1 = dsum + adir.z;
  SH_PRECISE float nd = n1 * d1;
  SH_PRECISE float apden = abs(pden);
  SH_PRECISE float scaled_den = apden * 4096.0f;
  // The distance's plane value at the vertex of the largest weight (hit_anchor): the normal's
  // error moves n . (v - org) / n . dir by its error times |v - hit| / |n . dir|, so the vertex
  // nearest the hit; the surface rule's at the vertex nearest the origin (plane_anchor), as
  // origin_on_plane takes it
  SH_PRECISE vec3 B = v1 - org;
  SH_PRECISE vec3 C = v2 - org;
  vec3 H = hit_anchor(A, B, C, U, V, W);
  SH_PRECISE float hnum = sh_dot(nrm, H);
  vec3 P = plane_anchor(A, B, C);
  SH_PRECISE float pnum = sh_dot(nrm, P);
  bool on_plane = surface_tol >= 0.0f && plane_near_origin(pnum, nscale, surface_tol, P);
  SH_PRECISE float mpden = -pden;
  bool grazing = scaled_den < nd;
  bool same_side = (mpden < 0.0f) == (D < 0.0f);
  if (pden != 0.0f && (!grazing || same_side)) {
    D = mpden;
    T = -hnum;
  } else {
    grazing = false;  // T / D: within the depth range already
  }
  SH_PRECISE float sgn = D < 0.0f ? -1.0f : 1.0f;
  SH_PRECISE float sdet = det < 0.0f ? -1.0f : 1.0f;
  SH_PRECISE float ad = D * sgn;
  SH_PRECISE float t = T * sgn;
  if (grazing) {
    // The depth range: vertex i is reached at t = z_i / |dz|, z_i its depth along kz times sign(dz)
    SH_PRECISE float sz = dz < 0.0f ? -1.0f : 1.0f;
    SH_PRECISE float adz = dz * sz;
    SH_PRECISE float za = az * sz;
    SH_PRECISE float zb = bz * sz;
    SH_PRECISE float zc = cz * sz;
    SH_PRECISE float zlo = min(min(za, zb), zc);
    SH_PRECISE float zhi = max(max(za, zb), zc);
    SH_PRECISE float tz = t * adz;
    SH_PRECISE float tlo = zlo * ad;
    SH_PRECISE float thi = zhi * ad;
    if (tz < tlo) {
      t = zlo;
      ad = adz;
    } else if (tz > thi) {
      t = zhi;
      ad = adz;
    }
    D = ad * sgn;
  }
  SH_PRECISE float lo = t_lo * ad;
  SH_PRECISE float hi = t_hi * ad;
  SH_PRECISE float best = closest_bound(best_t) * ad;
  SH_PRECISE float u = V * sdet;
  SH_PRECISE float v = W * sdet;
  // D has the sign of moller_trumbore's det (< 0: back face)
  r.det = D;
  r.u_det = u;
  r.v_det = v;
  r.t_det = t;
  r.lo_det = lo;
  r.hi_det = hi;
  r.best_det = best;
  // Decisions: + - * and comparisons only; inside iff U, V, W do not have mixed signs
  bool mixed = watertight_mixed(e);
  if (mixed && u < 0.0f) r.code = kTestOutsideU;
  else if (mixed && v < 0.0f) r.code = kTestOutsideV;
  else if (mixed) r.code = kTestOutsideUV;
  else if (sh_zero_or_subnormal(det) || sh_zero_or_subnormal(D)) r.code = kTestParallel;
  else if (t <= lo) r.code = kTestBehind;
  else if (t >= hi) r.code = kTestBeyond;
  else if (t > best) r.code = kTestNotCloser;
  else if (on_plane) r.code = kTestOriginPlane;
  else r.code = kTestAccepted;
  return r.code;
}
SH_INLINE uint watertight_rest(SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2,
                               SH_IN(WatertightEdges) e, float t_lo, float t_hi, float best_t,
                               float surface_tol, SH_OUT(TriangleTest) r) {
  return watertight_rest_plane(org, dir, v1, v2, e, triangle_plane(v0, v1, v2), t_lo, t_hi, best_t, surface_tol, r);
}

SH_INLINE uint watertight(SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) v0, SH_IN(vec3) v1,
                          SH_IN(vec3) v2, float t_lo, float t_hi, float best_t, float surface_tol,
                          SH_OUT(TriangleTest) r) {
  WatertightEdges e;
  watertight_edges(org, watertight_ray(dir), v0, v1, v2, e);
  return watertight_rest(org, dir, v0, v1, v2, e, t_lo, t_hi, best_t, surface_tol, r);
}

// The triangle test GridParams::triangle_test names. `surface_tol`: the watertight test's surface
// rule (watertight_rest; negative: none); Moller-Trumbore ignores it (its caller asks
// origin_on_plane).
SH_INLINE uint triangle_test(uint which, SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) v0,
                             SH_IN(vec3) v1, SH_IN(vec3) v2, float t_lo, float t_hi, float best_t,
                             float surface_tol, SH_OUT(TriangleTest) r) {
  if (which == kTriangleWatertight) return watertight(org, dir, v0, v1, v2, t_lo, t_hi, best_t, surface_tol, r);
  return moller_trumbore(org, dir, v0, v1, v2, t_lo, t_hi, best_t, r);
}

// triangle_test()'s code for every input, `r` filled only where the test gets past its first
// rejections (there `r` is triangle_test()'s; elsewhere undefined): the watertight test stops
// after its edge functions when they have mixed signs, Moller-Trumbore after its determinant and
// u when det is 0 or u < 0 (else each goes on from where it stopped). The same operations in the same order up to there, so the same code;
// for a trace that records no events (the trace shader but for its explain ray), where most tests
// miss and skip the plane's cross and dot products. tests/test_triangle_code.cpp holds it to
// triangle_test()'s code and record on every case of its corpus.
// `w`: watertight_ray(dir), made once per ray by the caller (the same values as made here).
SH_INLINE uint triangle_test_code(uint which, SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(WatertightRay) w,
                                  SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2, float t_lo, float t_hi,
                                  float best_t, float surface_tol, SH_OUT(TriangleTest) r) {
  if (which == kTriangleWatertight) {
    WatertightEdges e;
    watertight_edges(org, w, v0, v1, v2, e);
    if (watertight_mixed(e)) {
      r.code = watertight_outside_code(e);
      return r.code;
    }
    return watertight_rest(org, dir, v0, v1, v2, e, t_lo, t_hi, best_t, surface_tol, r);
  }
  MollerFirst m;
  moller_trumbore_first(org, dir, v0, v1, v2, m);
  if (sh_zero_or_subnormal(m.det) || m.u < 0.0f) {
    r.code = sh_zero_or_subnormal(m.det) ? kTestParallel : kTestOutsideU;
    return r.code;
  }
  return moller_trumbore_rest(dir, m, t_lo, t_hi, best_t, r);
}

// A power of two that brings |d| into [2^-126, 2^126], where its reciprocal is a normal float:
// 2^-64 above 2^126, 2^64 below 2^-126 (a subnormal, exact when scaled), else 1. A quotient n / d
// is then taken as (n s) * (1 / (d s)): both scalings exact but where n s underflows, and there
// the quotient is below 2^-188 (n s < 2^-126 with 1 / (d s) <= 2^-62), which rounds to 0 either
// way, on a device that flushes subnormals or not.
SH_INLINE float sh_reciprocal_scale(float ad) {
  return ad > uintBitsToFloat(0x7E800000u) ? 5.42101086242752217e-20f
                                           : (ad < uintBitsToFloat(0x00800000u) ? 18446744073709551616.0f : 1.0f);
}

// The reported distance of an accepted test: t_det * (1 / |det|), a correctly rounded reciprocal
// and a product (within 2 ulps of T / |det| below: docs/SPEC.md "The not closer bound"). Where
// |det| is above 2^126 the reciprocal would lose its bits as a subnormal: there both are scaled by
// 2^-64 first (sh_reciprocal_scale: exact), the same two roundings. (A subnormal |det| is no
// accepted test: kTestParallel. Where one reached here unscaled, the reciprocal overflowed: a
// triangle of edges 1e-20 at distance 1 was reported at t = inf, an outside review.) One
// reciprocal in the code, not a second division for the rare case: the trace's loop inlines it,
// and a second correctly rounded division there made the trace 3 to 11 % slower on the H200
// (docs/BENCHMARKS.md "One division in the trace's loop").
SH_INLINE float moller_trumbore_t(SH_IN(TriangleTest) r) {
  SH_PRECISE float ad = abs(r.det);
  float s = sh_reciprocal_scale(ad);
  SH_PRECISE float ds = ad * s;
  SH_PRECISE float ts = r.t_det * s;
  SH_PRECISE float inv = sh_rcp(ds);
  SH_PRECISE float t = ts * inv;
  return t;
}

// Weights (of v1, of v2) clamped into the triangle by comparisons only (a NaN weight becomes 0),
// the same bits on every device: u = min(max(w1, 0), 1), v = min(max(w2, 0), 1 - u).
SH_INLINE vec2 clamp_barycentrics(float w1, float w2) {
  SH_PRECISE float u = w1 > 0.0f ? w1 : 0.0f;
  u = u < 1.0f ? u : 1.0f;
  SH_PRECISE float v = w2 > 0.0f ? w2 : 0.0f;
  SH_PRECISE float room = 1.0f - u;
  v = v < room ? v : room;
  return vec2(u, v);
}

// Two weights over their determinant, (a / d, b / d) clamped into the triangle
// (clamp_barycentrics: the two roundings can put their sum an ulp past 1), with one correctly
// rounded reciprocal. A determinant outside [2^-126, 2^126] (edges below about 1e-19): its
// reciprocal would overflow or be subnormal, so the three are scaled into range first
// (sh_reciprocal_scale, by a power of two: exact). `d` of either sign: the quotients are the same
// bits as of (-a, -b, -d).
SH_INLINE vec2 barycentric_quotients(float a, float b, float d) {
  float s = sh_reciprocal_scale(abs(d));
  SH_PRECISE float ds = d * s;
  SH_PRECISE float sa = a * s;
  SH_PRECISE float sb = b * s;
  SH_PRECISE float inv = sh_rcp(ds);
  SH_PRECISE float w1 = sa * inv;
  SH_PRECISE float w2 = sb * inv;
  return clamp_barycentrics(w1, w2);
}

// Barycentric weights (of v1, of v2) of point p by Cramer's rule in the plane the triangle
// projects onto largest: with e0 = v1 - v0, e1 = v2 - v0, e2 = p - v0 and n = e0 x e1, the two
// coordinates (i, j) other than n's largest component (ties: x, then y), det(a, b) = a_i b_j -
// a_j b_i, w1 = det(e2, e1) / det(e0, e1), w2 = det(e0, e2) / det(e0, e1), the division done once
// as a reciprocal (det(e0, e1) is that component of n). A point off the plane gets the weights of
// its projection along that axis. det(e0, e1) == 0 (degenerate) gives (0, 0). The weights are then
// clamped into the triangle (clamp_barycentrics): a hit point far from the ray's origin carries
// more rounding than a small triangle is wide, and its unclamped weights were anything (190.7 and
// -125.2 measured).
// Not the dot products' form (denom = d00 d11 - d01^2, Ericson 2004), which squares the triangle's
// condition: an outside sweep found weights in steps of 1/8 on a 1000:1 strip (its denominator 8
// ulps of d00 d11: alpha masks sampled at the wrong texel in 1,197 of 5,760 pixels against Embree,
// and a Sponza sliver of 36:1 at (1/12, 0.168) where the exact weights are (0.0829, 0.1691)), and
// its fourth powers of the edges underflowed below edges of 3e-10 (weights (1, 0): alpha masks
// ignored). The projected determinants are products of two edges: no cancellation beyond the
// triangle's own (n's component is exact on the strip), no underflow above edges of 1e-19.
SH_INLINE vec2 cramer_barycentrics(SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2, SH_IN(vec3) p) {
  SH_PRECISE vec3 e0 = v1 - v0;
  SH_PRECISE vec3 e1 = v2 - v0;
  SH_PRECISE vec3 e2 = p - v0;
  vec3 n = sh_cross(e0, e1);
  SH_PRECISE vec3 an = abs(n);
  // The plane (i, j): drop n's largest axis
  SH_PRECISE vec2 a = vec2(e0.x, e0.y);
  SH_PRECISE vec2 b = vec2(e1.x, e1.y);
  SH_PRECISE vec2 c = vec2(e2.x, e2.y);
  if (an.x >= an.y && an.x >= an.z) {
    a = vec2(e0.y, e0.z);
    b = vec2(e1.y, e1.z);
    c = vec2(e2.y, e2.z);
  } else if (an.y >= an.z) {
    a = vec2(e0.z, e0.x);
    b = vec2(e1.z, e1.x);
    c = vec2(e2.z, e2.x);
  }
  SH_PRECISE float ab0 = a.x * b.y;
  SH_PRECISE float ab1 = a.y * b.x;
  SH_PRECISE float denom = ab0 - ab1;
  if (denom == 0.0f) return vec2(0.0f);
  SH_PRECISE float cb0 = c.x * b.y;
  SH_PRECISE float cb1 = c.y * b.x;
  SH_PRECISE float n1 = cb0 - cb1;
  SH_PRECISE float ac0 = a.x * c.y;
  SH_PRECISE float ac1 = a.y * c.x;
  SH_PRECISE float n2 = ac0 - ac1;
  return barycentric_quotients(n1, n2, denom);
}

// ---- A hit's barycentrics: the triangle test's own weights ----
// The weights (of v1, of v2) of an accepted hit are those its test decided inside on: Moller-
// Trumbore's u and v over its |det|, the watertight test's V and W over |U + V + W| (the edge
// functions; each times the determinant's sign). Their quotients are taken with one correctly
// rounded reciprocal (sh_reciprocal_scale keeps it normal, as in moller_trumbore_t) and clamped
// into the triangle (clamp_barycentrics: the two roundings can put u + v an ulp past 1).
// Not Cramer's rule at the hit point (cramer_barycentrics of org + t dir): that point rounds to
// the ulps of its coordinates, 0.008 units at 1e5 from the origin, and an alpha mask's edge was
// decided at a point off the ray (keyed quads moved to 1e5: 16 of 1,296 pixels differed from
// Embree's, which keys on its own test's u and v; docs/ACCURACY.md "Alpha keying far from the
// origin"). The test's weights are made from the vertices relative to the origin (org - v0, the
// sheared v - org), so they do not depend on where the ray and the triangle lie. Cramer's rule
// stays for points that are no test's hit (a gap-fill hit's sample point).
SH_INLINE vec2 test_barycentrics(float u_det, float v_det, float ad) { return barycentric_quotients(u_det, v_det, ad); }

// Moller-Trumbore's weights of the ray and triangle: the same operations in the same order as
// moller_trumbore_first and moller_trumbore_rest, so the same u, v and det as the test made.
SH_INLINE vec2 moller_trumbore_barycentrics(SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) v0, SH_IN(vec3) v1,
                                            SH_IN(vec3) v2) {
  MollerFirst m;
  moller_trumbore_first(org, dir, v0, v1, v2, m);
  SH_PRECISE vec3 s = m.s;
  SH_PRECISE vec3 e1 = m.e1;
  vec3 q = sh_cross(s, e1);
  SH_PRECISE float ad = m.det * m.sgn;
  SH_PRECISE float v = sh_dot(dir, q) * m.sgn;
  return test_barycentrics(m.u, v, ad);
}

// The watertight test's weights (watertight_edges of the same ray, `w` its watertight_ray): V and
// W over U + V + W, each times the sign of that sum, as watertight_rest_plane records them.
SH_INLINE vec2 watertight_barycentrics(SH_IN(vec3) org, SH_IN(WatertightRay) w, SH_IN(vec3) v0, SH_IN(vec3) v1,
                                       SH_IN(vec3) v2) {
  WatertightEdges e;
  watertight_edges(org, w, v0, v1, v2, e);
  SH_PRECISE float sdet = e.det < 0.0f ? -1.0f : 1.0f;
  SH_PRECISE float ad = e.det * sdet;
  SH_PRECISE float u = e.V * sdet;
  SH_PRECISE float v = e.W * sdet;
  return test_barycentrics(u, v, ad);
}

// The weights of the test GridParams::triangle_test names (`w`: watertight_ray(dir)), made again
// after the test from the ray and the triangle: the same inputs, the same operations, the same
// bits as the test's record (tests/test_triangle_code.cpp holds them to it). The trace-cost
// policy's estimator takes them; the trace divides the weights its test recorded instead.
SH_INLINE vec2 triangle_barycentrics(uint which, SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(WatertightRay) w,
                                     SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2) {
  if (which == kTriangleWatertight) return watertight_barycentrics(org, w, v0, v1, v2);
  return moller_trumbore_barycentrics(org, dir, v0, v1, v2);
}

// The gather's weights of a pixel's visible triangle (its position and uv): Moller-Trumbore's of the
// camera ray, made the same way by the CPU's gather (common/gather.cpp) and the GPU's resolve. Not
// the gather test's own (the watertight test's, which keys the alpha mask): the resolve makes them
// again for every pixel, and the watertight test's edge functions (the permutation, the exact
// re-test of zeros) cost the compute gather 0.008 ms a frame on the H200 where these cost about
// what Cramer's rule at the hit point did (docs/BENCHMARKS.md, "A hit's barycentrics: the test's
// own weights"). Both are made from the vertices relative to the eye.
SH_INLINE vec2 gather_barycentrics(SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2, SH_IN(vec3) eye, SH_IN(vec3) dir) {
  return moller_trumbore_barycentrics(eye, dir, v0, v1, v2);
}

// The point of the triangle at barycentrics `bc` (the weights of v1 and v2): v0 + u e0 + v e1, its
// rounding at the triangle's own scale. A launch point (the gather's position, where bounce and
// shadow rays start): eye + t * dir rounds at the eye's distance instead, and a camera 4,000 units
// from a unit sphere put it 1e-4 inside, where shadow rays met the neighbouring triangles
// (speckles on a lit convex surface, a mirror reflecting itself: an outside sweep).
SH_INLINE vec3 surface_point(SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2, SH_IN(vec2) bc) {
  SH_PRECISE vec3 e0 = v1 - v0;
  SH_PRECISE vec3 e1 = v2 - v0;
  SH_PRECISE vec3 a = e0 * bc.x;
  SH_PRECISE vec3 b = e1 * bc.y;
  SH_PRECISE vec3 ab = a + b;
  SH_PRECISE vec3 p = v0 + ab;
  return p;
}

// The alpha of an RGBA8 texel packed as r | g << 8 | b << 16 | a << 24.
SH_INLINE uint texel_alpha(uint rgba) { return rgba >> 24u; }

// Whether an alpha value keeps the surface (alpha.h: alpha >= kAlphaCutoff).
SH_INLINE bool alpha_keeps(uint alpha) { return alpha >= kAlphaCutoff; }

SH_END

#endif
