// triangle.h: the ray/triangle test and the barycentrics of the fixed-capacity grid (paper 2.3),
// written once for the reference and the shaders (compat.h rules).
//  - moller_trumbore: Moller and Trumbore 1997/2005, every decision free of division (Embree
//    style: u, v, t scaled by det, the sign of det folded in, compared against bounds * |det|).
//  - cramer_barycentrics: Ericson 2004 (Real-Time Collision Detection, 3.4), one division.
#ifndef GRIDRT_SHARED_TRIANGLE_H
#define GRIDRT_SHARED_TRIANGLE_H

#include "alpha.h"
#include "compat.h"

SH_BEGIN

// Outcome of one triangle test (TriangleTest::code, ExplainEvent::code of a test event). The
// first failing condition, in this order, names the outcome.
SH_CONST uint kTestAccepted = 0u;    // inside, within the bounds, not farther than the best hit
SH_CONST uint kTestParallel = 1u;    // det == 0: ray parallel to the plane (or a zero-area triangle)
SH_CONST uint kTestOutsideU = 2u;    // u * det < 0: beyond edge v0-v2
SH_CONST uint kTestOutsideV = 3u;    // v * det < 0: beyond edge v0-v1
SH_CONST uint kTestOutsideUV = 4u;   // (u + v) * det > |det|: beyond edge v1-v2
SH_CONST uint kTestBehind = 5u;      // t * det <= t_lo * |det|: before the (elongated) segment
SH_CONST uint kTestBeyond = 6u;      // t * det >= t_hi * |det|: after the (elongated) segment
SH_CONST uint kTestNotCloser = 7u;   // t * det > best_t * |det|: the best hit so far is closer
SH_CONST uint kTestSelfHit = 8u;     // the ray's launch triangle (by reference); not tested
SH_CONST uint kTestAlphaKeyed = 9u;  // accepted geometrically, cut away by the alpha mask
SH_CONST uint kTestTieLost = 10u;    // reported t not smaller than the best (ties: smaller ref)

// The values a test decides on: everything scaled by |det|, so that no division is needed.
struct TriangleTest {
  float det;       // signed determinant dot(e1, cross(dir, e2)); < 0: back face
  float u_det;     // u * |det| (weight of v1)
  float v_det;     // v * |det| (weight of v2)
  float t_det;     // t * |det|
  float lo_det;    // t_lo * |det|
  float hi_det;    // t_hi * |det|
  float best_det;  // best_t * |det| (+inf without a best hit)
  uint code;       // kTest*
};

// Moller-Trumbore against the open interval (t_lo, t_hi), and not farther than best_t
// (t * det <= best_t * |det|; ties are settled by the caller on the reported t and the reference).
// Order of operations (both sides): e1 = v1 - v0, e2 = v2 - v0, p = cross(dir, e2),
// det = dot(e1, p), s = org - v0, U = dot(s, p), q = cross(s, e1), V = dot(dir, q),
// T = dot(e2, q); U, V, T multiplied by sign(det) (exact).
SH_INLINE uint moller_trumbore(SH_IN(vec3) org, SH_IN(vec3) dir, SH_IN(vec3) v0, SH_IN(vec3) v1,
                               SH_IN(vec3) v2, float t_lo, float t_hi, float best_t,
                               SH_OUT(TriangleTest) r) {
  // Determinant: the ray against the triangle's plane
  SH_PRECISE vec3 e1 = v1 - v0;
  SH_PRECISE vec3 e2 = v2 - v0;
  vec3 p = sh_cross(dir, e2);
  SH_PRECISE float det = sh_dot(e1, p);
  // Scaled barycentrics and distance, the sign of det folded in
  SH_PRECISE vec3 s = org - v0;
  vec3 q = sh_cross(s, e1);
  SH_PRECISE float sgn = det < 0.0f ? -1.0f : 1.0f;
  SH_PRECISE float ad = det * sgn;
  SH_PRECISE float u = sh_dot(s, p) * sgn;
  SH_PRECISE float v = sh_dot(dir, q) * sgn;
  SH_PRECISE float t = sh_dot(e2, q) * sgn;
  SH_PRECISE float uv = u + v;
  SH_PRECISE float lo = t_lo * ad;
  SH_PRECISE float hi = t_hi * ad;
  SH_PRECISE float best = best_t * ad;
  r.det = det;
  r.u_det = u;
  r.v_det = v;
  r.t_det = t;
  r.lo_det = lo;
  r.hi_det = hi;
  r.best_det = best;
  // Decisions: + - * and comparisons only
  if (det == 0.0f) r.code = kTestParallel;
  else if (u < 0.0f) r.code = kTestOutsideU;
  else if (v < 0.0f) r.code = kTestOutsideV;
  else if (uv > ad) r.code = kTestOutsideUV;
  else if (t <= lo) r.code = kTestBehind;
  else if (t >= hi) r.code = kTestBeyond;
  else if (t > best) r.code = kTestNotCloser;
  else r.code = kTestAccepted;
  return r.code;
}

// The reported distance of an accepted test: t_det * (1 / |det|), the one division.
SH_INLINE float moller_trumbore_t(SH_IN(TriangleTest) r) {
  SH_PRECISE float ad = abs(r.det);
  SH_PRECISE float inv = 1.0f / ad;
  SH_PRECISE float t = r.t_det * inv;
  return t;
}

// Barycentric weights (of v1, of v2) of point p by Cramer's rule (Ericson 2004): with
// e0 = v1 - v0, e1 = v2 - v0, e2 = p - v0 and the dot products dij,
// denom = d00 d11 - d01 d01, w1 = (d11 d20 - d01 d21) / denom, w2 = (d00 d21 - d01 d20) / denom,
// the division done once as a reciprocal. A point off the plane gets the weights of its
// projection. denom == 0 (degenerate) gives (0, 0).
SH_INLINE vec2 cramer_barycentrics(SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2, SH_IN(vec3) p) {
  SH_PRECISE vec3 e0 = v1 - v0;
  SH_PRECISE vec3 e1 = v2 - v0;
  SH_PRECISE vec3 e2 = p - v0;
  SH_PRECISE float d00 = sh_dot(e0, e0);
  SH_PRECISE float d01 = sh_dot(e0, e1);
  SH_PRECISE float d11 = sh_dot(e1, e1);
  SH_PRECISE float d20 = sh_dot(e2, e0);
  SH_PRECISE float d21 = sh_dot(e2, e1);
  SH_PRECISE float denom = d00 * d11 - d01 * d01;
  if (denom == 0.0f) return vec2(0.0f);
  SH_PRECISE float inv = 1.0f / denom;
  SH_PRECISE float w1 = (d11 * d20 - d01 * d21) * inv;
  SH_PRECISE float w2 = (d00 * d21 - d01 * d20) * inv;
  return vec2(w1, w2);
}

// The alpha of an RGBA8 texel packed as r | g << 8 | b << 16 | a << 24.
SH_INLINE uint texel_alpha(uint rgba) { return rgba >> 24u; }

// Whether an alpha value keeps the surface (alpha.h: alpha >= kAlphaCutoff).
SH_INLINE bool alpha_keeps(uint alpha) { return alpha >= kAlphaCutoff; }

SH_END

#endif
