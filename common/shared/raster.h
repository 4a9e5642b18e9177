// raster.h: the conservative bounds the compute gather's rasterizer (Laine and Karras, "High-
// Performance Software Rasterization on GPUs", HPG 2011: triangle setup once, then tile, then
// pixel rejection, per-tile depth culling) uses to skip (triangle, pixel) pairs. They never decide
// a pixel: every pair they keep is decided by the gather's own ray test (the watertight test from the
// eye along camera_direction, common/shared/triangle.h and bounce.h), so the gather's result is
// the same whichever pairs they skip, provided they skip only pairs that test rejects or that
// cannot win the pixel. docs/SPEC.md ("The gather as a rasterizer") derives the bounds:
//  - raster_setup: per triangle, three edge functions over pixel indices, E(x, y) = a x + b y + c,
//    the homogeneous (2D) rasterization edges of the planes through the eye and each edge
//    (Olano and Greer 1997), oriented by the side of the eye, plus a slack of 2^-13 of their
//    magnitude (the ray test's rounding is below about 2^-19 of it), and a lower bound of the ray
//    test's t over the whole triangle; false (no rejection, t bound 0) where those bounds do not
//    hold: the eye within a hair of the triangle's plane, float range exceeded or underflowed.
//    raster_setup_depth gives also the triangle's depth plane: the inverse of a lower bound of t
//    as an affine function over pixel indices.
//  - raster_tile_t_lo: the depth plane's lower bound of t over a pixel rectangle (an 8x8 tile):
//    above the triangle's own wherever the plane is farther there than at its nearest vertex.
//  - raster_pixel_may_hit: all three edge functions >= 0 at the pixel (the ray test may accept).
//  - raster_rect_may_hit: for each edge, its largest value over a pixel rectangle (a corner)
//    is >= 0 (some pixel of the rectangle may be accepted).
#ifndef GRIDRT_SHARED_RASTER_H
#define GRIDRT_SHARED_RASTER_H

#include "bounce.h"
#include "compat.h"
#include "rounding.h"

SH_BEGIN

// The camera's constants of the bounds below, the same for every triangle of a frame: made once by
// raster_camera (the GPU frame reads them from its parameters, FrameParams::raster, which the host
// makes with this function: the same bits as the CPU's).
struct RasterCamera {
  float gx;    // 2 tan aspect / width: sx from one pixel index to the next
  float gy;    // 2 tan / height: sy likewise
  float ox;    // sx(0), the first column's
  float oy;    // sy(0), the first row's
  float kx;    // the frustum's sides, widened by two pixels (tangent units)
  float ky;
  float px;    // pixels per tangent unit
  float py;
  float cx;    // the pixel indices of the view's centre
  float cy;
  float dmax;  // 1 + tan aspect + tan: a bound of a pixel direction's |d|_1 in camera units
  float pad0;
};

SH_INLINE RasterCamera raster_camera(SH_IN(CameraParams) c) {
  RasterCamera rc;
  SH_PRECISE float tx = c.tan_half_fov * c.aspect;
  SH_PRECISE float ty = c.tan_half_fov;
  rc.gx = sh_div(2.0f * tx, float(c.width));
  rc.gy = sh_div(2.0f * ty, float(c.height));
  SH_PRECISE float ox = 0.5f * rc.gx - tx;
  SH_PRECISE float oy = ty - 0.5f * rc.gy;
  rc.ox = ox;
  rc.oy = oy;
  SH_PRECISE float kx = tx * (1.0f + sh_div(4.0f, float(c.width)));
  SH_PRECISE float ky = ty * (1.0f + sh_div(4.0f, float(c.height)));
  rc.kx = kx;
  rc.ky = ky;
  rc.px = sh_div(0.5f * float(c.width), tx);
  rc.py = sh_div(0.5f * float(c.height), ty);
  SH_PRECISE float cx = 0.5f * float(c.width) - 0.5f;
  SH_PRECISE float cy = 0.5f * float(c.height) - 0.5f;
  rc.cx = cx;
  rc.cy = cy;
  SH_PRECISE float dmax = (1.0f + tx) + ty;
  rc.dmax = dmax;
  rc.pad0 = 0.0f;
  return rc;
}

// |v|_1, an upper bound of |v| (no square root needed).
SH_INLINE float raster_norm1(SH_IN(vec3) v) {
  SH_PRECISE float s = abs(v.x) + abs(v.y);
  SH_PRECISE float r = s + abs(v.z);
  return r;
}

// One edge function over pixel indices (x, y): sigma * dot(n, d(x, y)) with
// d(x, y) = forward + sx(x) right + sy(y) up the unnormalized ray direction of camera_direction,
// sx = ((2x + 1) / width - 1) tan aspect, sy = (1 - (2y + 1) / height) tan; plus `slack`.
// gx, gy, ox, oy: raster_camera's.
SH_INLINE vec3 raster_edge(SH_IN(CameraParams) c, SH_IN(RasterCamera) rc, SH_IN(vec3) n, float sigma, float slack) {
  const float gx = rc.gx, gy = rc.gy, ox = rc.ox, oy = rc.oy;
  SH_PRECISE float nf = sh_dot(n, c.forward);
  SH_PRECISE float nr = sh_dot(n, c.right) * sigma;
  SH_PRECISE float nu = sh_dot(n, c.up) * sigma;
  SH_PRECISE float c0 = nf * sigma + nr * ox;
  SH_PRECISE float c1 = c0 + nu * oy;
  SH_PRECISE float cz = c1 + slack;
  return vec3(nr * gx, -(nu * gy), cz);
}

// The triangle's setup (see the header comment). e0, e1, e2: the edges opposite v0, v1, v2 (in
// exact arithmetic the ray test's edge conditions: the watertight test's U, V, W >= 0, as
// Moller-Trumbore's (u + v) <= det, u >= 0 and v >= 0); t_lo: a lower bound of the ray test's
// t at every pixel it accepts. Returns false where the bounds are not guaranteed: then every edge
// is (0, 0, 1) (keeps every pixel) and t_lo is 0. `depth`: the depth plane (a, b, c, k): at every
// pixel (x, y) of a rectangle where the test accepts, t >= k / P with P the largest value of
// a x + b y + c over the rectangle (raster_tile_t_lo); (0, 0, 1, 0) where no bound is given.
SH_INLINE bool raster_setup_depth(SH_IN(CameraParams) c, SH_IN(RasterCamera) rc, SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2,
                                  SH_OUT(vec3) e0, SH_OUT(vec3) e1, SH_OUT(vec3) e2, SH_OUT(float) t_lo,
                                  SH_OUT(vec4) depth) {
  e0 = vec3(0.0f, 0.0f, 1.0f);
  e1 = e0;
  e2 = e0;
  t_lo = 0.0f;
  depth = vec4(0.0f, 0.0f, 1.0f, 0.0f);
  SH_PRECISE vec3 q0 = v0 - c.eye;
  SH_PRECISE vec3 q1 = v1 - c.eye;
  SH_PRECISE vec3 q2 = v2 - c.eye;
  SH_PRECISE vec3 d01 = v1 - v0;
  SH_PRECISE vec3 d12 = v2 - v1;
  SH_PRECISE vec3 d20 = v0 - v2;
  SH_PRECISE vec3 d02 = v2 - v0;
  SH_PRECISE float m = max(raster_norm1(q0), max(raster_norm1(q1), raster_norm1(q2)));
  SH_PRECISE float l = max(raster_norm1(d01), max(raster_norm1(d12), raster_norm1(d20)));
  // The eye's side of the plane: sign(dot(q0, e1 x e2)), reliable where it is far from 0
  vec3 n = sh_cross(d01, d02);
  SH_PRECISE float qn = sh_dot(q0, n);
  SH_PRECISE float ml = (m + l) * l;
  SH_PRECISE float mll = ml * l;
  // Float range: the magnitudes neither overflow nor come near the subnormals (NaN fails too)
  if (!(mll > 1.0e-30f && mll < 1.0e30f && m < 1.0e30f)) return false;
  // The eye's side, reliable: |q0 . n| far above the test's rounding of t det (about 10 eps M L^2)
  if (!(abs(qn) > 0.0000152587890625f * mll)) return false;  // 2^-16
  SH_PRECISE float sigma = qn < 0.0f ? -1.0f : 1.0f;
  const float dmax = rc.dmax;
  SH_PRECISE float slack = (0.0001220703125f * ml) * dmax;  // 2^-13
  e0 = raster_edge(c, rc, sh_cross(q1, d12), sigma, slack);
  e1 = raster_edge(c, rc, sh_cross(q2, d20), sigma, slack);
  e2 = raster_edge(c, rc, sh_cross(q0, d01), sigma, slack);
  // t >= the nearest vertex depth along forward (t >= z at the hit), less the rounding of z, of
  // the test's t (relative: 2^-17 (M + L) L^2 / |q0 . n|, at most 1/2 here) and a margin of 2^-10
  SH_PRECISE float z = min(sh_dot(q0, c.forward), min(sh_dot(q1, c.forward), sh_dot(q2, c.forward)));
  SH_PRECISE float z_lo = z - 0.0000152587890625f * (m + l);  // 2^-16
  SH_PRECISE float rel = sh_div(0.00000762939453125f * mll, abs(qn));  // 2^-17
  SH_PRECISE float keep = (1.0f - 0.0009765625f) - rel;       // 1 - 2^-10 - rel
  SH_PRECISE float t_bound = z_lo * keep;
  t_lo = z_lo > 0.0f && keep > 0.0f ? t_bound : 0.0f;
  // The depth plane: at an accepted pixel t = |q0 . n| |d| / |d . n| along the unit direction
  // d / |d| (|d| >= 1), and sigma (d . n) = |d . n| there, an affine function of the pixel indices
  // like the edges'. Its slack, 2^-13 L^2 Dmax, covers the rounding of n (a few eps L^2 per
  // component, whatever the triangle's area), of the function, and of the pixel's unit direction;
  // the numerator takes the test's relative rounding rel and the margin as t_lo does.
  SH_PRECISE float slack_n = (0.0001220703125f * (l * l)) * dmax;  // 2^-13
  SH_PRECISE float k = abs(qn) * keep;
  if (keep > 0.0f) depth = vec4(raster_edge(c, rc, n, sigma, slack_n), k);
  return true;
}

// raster_setup_depth without the depth plane.
SH_INLINE bool raster_setup(SH_IN(CameraParams) c, SH_IN(RasterCamera) rc, SH_IN(vec3) v0, SH_IN(vec3) v1,
                            SH_IN(vec3) v2, SH_OUT(vec3) e0, SH_OUT(vec3) e1, SH_OUT(vec3) e2, SH_OUT(float) t_lo) {
  vec4 depth;
  return raster_setup_depth(c, rc, v0, v1, v2, e0, e1, e2, t_lo, depth);
}

SH_INLINE float raster_edge_at(SH_IN(vec3) e, float x, float y) {
  SH_PRECISE float ex = e.x * x;
  SH_PRECISE float ey = e.y * y;
  SH_PRECISE float s = ex + ey;
  SH_PRECISE float r = s + e.z;
  return r;
}

// Whether the ray test may accept pixel (x, y).
SH_INLINE bool raster_pixel_may_hit(SH_IN(vec3) e0, SH_IN(vec3) e1, SH_IN(vec3) e2, uint x, uint y) {
  const float fx = float(x), fy = float(y);
  return raster_edge_at(e0, fx, fy) >= 0.0f && raster_edge_at(e1, fx, fy) >= 0.0f && raster_edge_at(e2, fx, fy) >= 0.0f;
}

// An edge's largest value over the pixels [x0, x1] x [y0, y1] (an affine function: at a corner).
SH_INLINE float raster_edge_max(SH_IN(vec3) e, uint x0, uint y0, uint x1, uint y1) {
  return raster_edge_at(e, float(e.x > 0.0f ? x1 : x0), float(e.y > 0.0f ? y1 : y0));
}

// A lower bound of the ray test's t at every pixel of [x0, x1] x [y0, y1] it accepts: the larger
// of the triangle's t_lo and the depth plane's k / P (P its largest value over the rectangle, at a
// corner; every accepted pixel has its sigma (d . n) <= P). P <= 0 (no pixel there can be
// accepted) or no plane: t_lo. The division is sh_div here, as all the shared math's; the
// shaders take the same bound with GLSL's division (frame_common.glsl raster_tile_t_lo_fast: a
// bound, not a result, and a correctly rounded division cost more than the culling saved, "The
// depth plane's bound per tile" in docs/BENCHMARKS.md), whose error of a few ulps is far within
// the margin of 2^-10 in k.
SH_INLINE float raster_tile_p(SH_IN(vec4) depth, uint x0, uint y0, uint x1, uint y1) {
  return raster_edge_max(vec3(depth.x, depth.y, depth.z), x0, y0, x1, y1);
}
SH_INLINE float raster_tile_t_lo(SH_IN(vec4) depth, float t_lo, uint x0, uint y0, uint x1, uint y1) {
  const float p = raster_tile_p(depth, x0, y0, x1, y1);
  if (!(p > 0.0f)) return t_lo;
  const float t = sh_div(depth.w, p);
  return t > t_lo ? t : t_lo;
}

// Whether the ray test may accept some pixel of [x0, x1] x [y0, y1] (inclusive).
SH_INLINE bool raster_rect_may_hit(SH_IN(vec3) e0, SH_IN(vec3) e1, SH_IN(vec3) e2, uint x0, uint y0, uint x1,
                                   uint y1) {
  return raster_edge_max(e0, x0, y0, x1, y1) >= 0.0f && raster_edge_max(e1, x0, y0, x1, y1) >= 0.0f &&
         raster_edge_max(e2, x0, y0, x1, y1) >= 0.0f;
}

// ---- The gather's screen box: the pixels a triangle's ray test may accept ----
//
// A convex polygon of at most 9 vertices (a triangle clipped by up to six half-spaces or
// half-planes gains at most one vertex per clip).
struct GatherPolygon {
  vec3 v[9];
  uint n;
};

// A polygon of no vertices (every slot zeroed: GLSL and C++ alike start from defined values).
SH_INLINE GatherPolygon gather_polygon_empty() {
  GatherPolygon poly;
  poly.n = 0u;
  for (uint i = 0u; i < 9u; ++i) poly.v[i] = vec3(0.0f);
  return poly;
}

// The side of `plane` a point is on: dot(plane.xyz, p) + plane.w (>= 0: kept by gather_clip).
SH_INLINE float gather_plane_side(vec4 plane, SH_IN(vec3) p) {
  SH_PRECISE float d = sh_dot(vec3(plane.x, plane.y, plane.z), p) + plane.w;
  return d;
}

// Clips `poly` to the half-space dot(plane.xyz, p) + plane.w >= 0 (Sutherland-Hodgman); a 2D
// polygon is clipped with its points as (x, y, 0) and the line as (a, b, 0, c).
SH_INLINE GatherPolygon gather_clip(SH_IN(GatherPolygon) poly, vec4 plane) {
  GatherPolygon kept = gather_polygon_empty();
  for (uint i = 0u; i < poly.n; ++i) {
    const vec3 a = poly.v[i];
    const vec3 b = poly.v[i + 1u == poly.n ? 0u : i + 1u];
    SH_PRECISE float da = gather_plane_side(plane, a);
    SH_PRECISE float db = gather_plane_side(plane, b);
    if (da >= 0.0f && kept.n < 9u) kept.v[kept.n++] = a;
    if ((da >= 0.0f) != (db >= 0.0f) && kept.n < 9u) {
      SH_PRECISE float s = sh_div(da, da - db);
      SH_PRECISE vec3 ab = b - a;
      SH_PRECISE vec3 step = ab * s;
      SH_PRECISE vec3 cut = a + step;
      kept.v[kept.n++] = cut;
    }
  }
  return kept;
}

// The inclusive pixel box (x0, y0, x1, y1) of the pixels in the continuous pixel-index bounds
// [lo, hi] (x from floor(lo.x) to ceil(hi.x): a pixel's worth of rounding either way is kept),
// clamped to the image; false when that is empty or NaN.
SH_INLINE bool gather_box_of(SH_IN(CameraParams) c, vec2 lo, vec2 hi, SH_OUT(uvec4) box) {
  box = uvec4(0u);
  const vec2 size = vec2(float(c.width), float(c.height));
  if (!(hi.x >= -1.0f && hi.y >= -1.0f && lo.x <= size.x && lo.y <= size.y)) return false;  // off the image, NaN
  const vec2 first = clamp(floor(lo), vec2(0.0f), size - 1.0f);
  const vec2 last = clamp(ceil(hi), vec2(0.0f), size - 1.0f);
  if (!(first.x <= last.x && first.y <= last.y)) return false;
  box = uvec4(uvec2(first), uvec2(last));
  return true;
}

// The box of the pixels where all three edge functions of raster_setup may be >= 0: the image
// rectangle, a pixel wider on every side, clipped by the three lines E_i = 0 in pixel-index space.
// Every pixel the ray test accepts has all three computed E_i >= 0 (the slack), and the clipped
// region rounds by far less than the pixel the box is widened by, so the box holds every such
// pixel: hits at any depth in front of the eye, with no near plane and no projection of vertices
// (the triangle may cross the eye's plane).
SH_INLINE bool gather_edge_box(SH_IN(CameraParams) c, SH_IN(vec3) e0, SH_IN(vec3) e1, SH_IN(vec3) e2,
                               SH_OUT(uvec4) box) {
  const float w = float(c.width), h = float(c.height);
  GatherPolygon poly = gather_polygon_empty();
  poly.v[0] = vec3(-1.0f, -1.0f, 0.0f);
  poly.v[1] = vec3(w, -1.0f, 0.0f);
  poly.v[2] = vec3(w, h, 0.0f);
  poly.v[3] = vec3(-1.0f, h, 0.0f);
  poly.n = 4u;
  poly = gather_clip(poly, vec4(e0.x, e0.y, 0.0f, e0.z));
  poly = gather_clip(poly, vec4(e1.x, e1.y, 0.0f, e1.z));
  poly = gather_clip(poly, vec4(e2.x, e2.y, 0.0f, e2.z));
  box = uvec4(0u);
  if (poly.n == 0u) return false;
  vec2 lo = vec2(3.0e38f), hi = vec2(-3.0e38f);
  for (uint i = 0u; i < poly.n; ++i) {
    lo = min(lo, vec2(poly.v[i].x, poly.v[i].y));
    hi = max(hi, vec2(poly.v[i].x, poly.v[i].y));
  }
  return gather_box_of(c, lo, hi, box);
}

// Camera space (right, up, forward) of a world point.
SH_INLINE vec3 gather_camera_space(SH_IN(CameraParams) c, SH_IN(vec3) p) {
  SH_PRECISE vec3 q = p - c.eye;
  return vec3(sh_dot(q, c.right), sh_dot(q, c.up), sh_dot(q, c.forward));
}

// The frustum box of a triangle given in camera space (gather_camera_space): the triangle clipped
// to the view frustum (the near plane and the four sides widened by two pixels) and projected;
// hits nearer than the near plane are left out. Each projected vertex is widened by a bound of its rounding and of the ray
// test's: `rounding` M (1 + |sx| + |sy|) / z in tangent units (M = max |q_i|_1 over the vertices'
// camera-space coordinates, z the vertex's depth); the gather's `rounding` is
// kGatherFrustumRounding, 2^-16 (512 eps: the errors are a few eps M in position), which at the
// near plane may cover the image. (A `rounding` of 0 is the box before this bound, for tests.)
SH_CONST float kGatherFrustumRounding = 0.0000152587890625f;  // 2^-16

// One vertex of the clipped polygon, projected and widened by the rounding bound, into [lo, hi]
// (gather_frustum_box; `m`, `px`, `py`, `cx`, `cy` as made there).
SH_INLINE void gather_frustum_extend(SH_IN(vec3) q, float near_plane, float rounding, float m, float px, float py,
                                     float cx, float cy, SH_INOUT(vec2) lo, SH_INOUT(vec2) hi) {
  // Projected with one reciprocal (a few ulps of the tangents, far inside the bound)
  SH_PRECISE float rz = sh_rcp(max(q.z, near_plane));
  SH_PRECISE float sx = q.x * rz;
  SH_PRECISE float sy = q.y * rz;
  SH_PRECISE vec2 p = vec2(sx * px + cx, cy - sy * py);
  SH_PRECISE float s = (1.0f + abs(sx)) + abs(sy);
  SH_PRECISE float e = ((rounding * m) * rz) * s;
  SH_PRECISE vec2 r = vec2(e * px, e * py);
  lo = min(lo, p - r);
  hi = max(hi, p + r);
}

SH_INLINE bool gather_frustum_box(SH_IN(CameraParams) c, SH_IN(RasterCamera) rc, float near_plane, SH_IN(vec3) q0,
                                  SH_IN(vec3) q1, SH_IN(vec3) q2, float rounding, SH_OUT(uvec4) box) {
  box = uvec4(0u);
  SH_PRECISE float m = max(raster_norm1(q0), max(raster_norm1(q1), raster_norm1(q2)));
  const float kx = rc.kx, ky = rc.ky;
  // The clip planes: near, then the four sides widened by two pixels
  const vec4 near = vec4(0.0f, 0.0f, 1.0f, -near_plane);
  const vec4 left = vec4(1.0f, 0.0f, kx, 0.0f);
  const vec4 right = vec4(-1.0f, 0.0f, kx, 0.0f);
  const vec4 bottom = vec4(0.0f, 1.0f, ky, 0.0f);
  const vec4 top = vec4(0.0f, -1.0f, ky, 0.0f);
  // Pixels per tangent unit, and the pixel indices of the view's centre
  const float px = rc.px, py = rc.py, cx = rc.cx, cy = rc.cy;
  vec2 lo = vec2(3.0e38f), hi = vec2(-3.0e38f);
  // A triangle with every vertex on the kept side of every plane is its own clipped polygon
  // (each clip keeps its vertices, in order): projected as it is, without the polygon (most
  // triangles; the same operations in the same order as the loop below, so the same box)
  bool inside = true;
  for (uint i = 0u; i < 3u; ++i) {
    const vec3 q = i == 0u ? q0 : (i == 1u ? q1 : q2);
    inside = inside && gather_plane_side(near, q) >= 0.0f && gather_plane_side(left, q) >= 0.0f &&
             gather_plane_side(right, q) >= 0.0f && gather_plane_side(bottom, q) >= 0.0f &&
             gather_plane_side(top, q) >= 0.0f;
  }
  if (inside) {
    gather_frustum_extend(q0, near_plane, rounding, m, px, py, cx, cy, lo, hi);
    gather_frustum_extend(q1, near_plane, rounding, m, px, py, cx, cy, lo, hi);
    gather_frustum_extend(q2, near_plane, rounding, m, px, py, cx, cy, lo, hi);
    return gather_box_of(c, lo, hi, box);
  }
  GatherPolygon poly = gather_polygon_empty();
  poly.v[0] = q0;
  poly.v[1] = q1;
  poly.v[2] = q2;
  poly.n = 3u;
  poly = gather_clip(poly, near);
  if (poly.n >= 3u) poly = gather_clip(poly, left);
  if (poly.n >= 3u) poly = gather_clip(poly, right);
  if (poly.n >= 3u) poly = gather_clip(poly, bottom);
  if (poly.n >= 3u) poly = gather_clip(poly, top);
  if (poly.n < 3u) return false;
  for (uint i = 0u; i < poly.n; ++i)
    gather_frustum_extend(poly.v[i], near_plane, rounding, m, px, py, cx, cy, lo, hi);
  return gather_box_of(c, lo, hi, box);
}

// The gather's box of a triangle: the pixels whose camera rays its ray test may accept, found
// from the cheapest bound that holds (docs/SPEC.md, "The gather as a rasterizer"). False: no
// pixel to test.
//  - wholly behind the eye's plane (every depth below -2^-20 M; depths round by a few eps M):
//    no ray of the image meets it;
//  - wholly beyond the near plane: every hit is, and the frustum box holds them;
//  - crossing the near plane: the edge functions' box, every accepted pixel at any depth; where
//    raster_setup gives no bounds (the eye within a hair of the plane) the frustum box, which
//    leaves out the hits nearer than the near plane.
SH_INLINE bool gather_box(SH_IN(CameraParams) c, SH_IN(RasterCamera) rc, float near_plane, SH_IN(vec3) v0, SH_IN(vec3) v1, SH_IN(vec3) v2,
                          SH_OUT(uvec4) box) {
  box = uvec4(0u);
  const vec3 q0 = gather_camera_space(c, v0);
  const vec3 q1 = gather_camera_space(c, v1);
  const vec3 q2 = gather_camera_space(c, v2);
  SH_PRECISE float m = max(raster_norm1(q0), max(raster_norm1(q1), raster_norm1(q2)));
  if (max(q0.z, max(q1.z, q2.z)) < -0.00000095367431640625f * m) return false;  // 2^-20
  if (min(q0.z, min(q1.z, q2.z)) >= near_plane)
    return gather_frustum_box(c, rc, near_plane, q0, q1, q2, kGatherFrustumRounding, box);
  vec3 e0, e1, e2;
  float t_lo;
  if (raster_setup(c, rc, v0, v1, v2, e0, e1, e2, t_lo)) return gather_edge_box(c, e0, e1, e2, box);
  return gather_frustum_box(c, rc, near_plane, q0, q1, q2, kGatherFrustumRounding, box);
}

SH_END

#endif
