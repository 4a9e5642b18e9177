// bounce.h: the per-pixel math of the paper's frame, written once for the CPU (common/gather.cpp)
// and the GPU (vulkan/shaders/gather_resolve.comp, bounce.comp), so that both produce the same
// primary rays, gather texels and glossy bounce rays, bit for bit where division and square root
// are correctly rounded (lavapipe; compat.h rules):
//  - camera_direction: the primary ray of a pixel centre (common/camera.h, camera_ray)
//  - gather_normal: the unit geometric normal of the launch triangle, facing the viewer
//  - pixel_random: two uniform floats per (x, y, frame) from a PCG hash (Jarzynski, Olano 2020)
//  - sh_sin_cos: sine and cosine by range reduction and polynomials, + - * only (the C library's
//    and the driver's sin/cos differ by ulps, so neither is used)
//  - bounce_direction: the glossy reflection (mirror about the normal, perturbed within a cone,
//    folded into the normal's hemisphere)
#ifndef GRIDRT_SHARED_BOUNCE_H
#define GRIDRT_SHARED_BOUNCE_H

#include "compat.h"
#include "rounding.h"

SH_BEGIN

// The camera as the per-pixel code reads it (camera_frame on the host; std430).
struct CameraParams {
  vec3 eye;           // pinhole
  float tan_half_fov; // tan(vfov / 2)
  vec3 right;         // unit, camera_frame
  float aspect;       // width / height, as float(width) / float(height)
  vec3 up;            // unit
  uint width;         // image width in pixels
  vec3 forward;       // unit, towards the target
  uint height;        // image height in pixels
};

// One pixel of the GPU gather buffer (std430, 48 bytes). launch_ref == kNoRef: no surface.
struct GatherTexel {
  vec3 position;    // org + t * dir (world)
  uint material;    // index into the scene's materials (kNoMaterial if none)
  vec3 normal;      // unit geometric normal, facing the viewer
  uint launch_ref;  // instance << 16 | triangle
  vec2 uv;          // interpolated texture coordinates
  float t;          // the primary ray's parametric distance
  uint pad0;
};

// v / |v|, as glm::normalize computes it: v * (1 / sqrt(dot(v, v))), with the correctly rounded
// sh_sqrt and sh_rcp (IEEE sqrt and / on the CPU; the GLSL built-ins are not exact on every device).
SH_INLINE vec3 sh_normalize(SH_IN(vec3) v) {
  SH_PRECISE float dd = sh_dot(v, v);
  SH_PRECISE float len = sh_sqrt(dd);
  SH_PRECISE float inv = sh_rcp(len);
  SH_PRECISE vec3 r = v * inv;
  return r;
}

// camera_direction (below): the unit direction of the ray through the centre of pixel (x, y), row 0
// at the top (camera_ray: sx and sy in the order it computes them). Its two divisions depend on
// the column or the row alone: camera_step_x and camera_step_y (the rasterizer's starting pass
// reads them from a table the host made with these functions: the same bits), then
// camera_direction_steps.
SH_INLINE float camera_step_x(SH_IN(CameraParams) c, uint x) { return sh_div(2.0f * (float(x) + 0.5f), float(c.width)); }
SH_INLINE float camera_step_y(SH_IN(CameraParams) c, uint y) { return sh_div(2.0f * (float(y) + 0.5f), float(c.height)); }

SH_INLINE vec3 camera_direction_steps(SH_IN(CameraParams) c, float fx, float fy) {
  SH_PRECISE float sx = ((fx - 1.0f) * c.tan_half_fov) * c.aspect;
  SH_PRECISE float sy = (1.0f - fy) * c.tan_half_fov;
  SH_PRECISE vec3 a = c.right * sx;
  SH_PRECISE vec3 b = c.up * sy;
  SH_PRECISE vec3 d0 = c.forward + a;
  SH_PRECISE vec3 d = d0 + b;
  return sh_normalize(d);
}

SH_INLINE vec3 camera_direction(SH_IN(CameraParams) c, uint x, uint y) {
  return camera_direction_steps(c, camera_step_x(c, x), camera_step_y(c, y));
}

// Unit geometric normal of triangle (a, b, c), flipped to face against `dir`; w = 0 when the
// triangle has no area (then the pixel has no surface). The cross product is normalized in units
// that bring its largest component into [1, 2) (sh_unit_scale: the same bits wherever dot(n, n)
// stays in the normal range), so that a triangle whose dot(n, n) would underflow (edges about
// 4e-12) or overflow (about 1e10) still has its normal. Divided by its length through one
// reciprocal, as sh_normalize (within about 1.5 ulps of the quotients; three correctly rounded
// divisions per pixel cost the compute gather's fine pass more: docs/BENCHMARKS.md, "The bin pass's
// camera constants once, the gather normal by one reciprocal").
SH_INLINE vec4 gather_normal(SH_IN(vec3) a, SH_IN(vec3) b, SH_IN(vec3) c, SH_IN(vec3) dir) {
  SH_PRECISE vec3 e1 = b - a;
  SH_PRECISE vec3 e2 = c - a;
  vec3 n0 = sh_cross(e1, e2);
  vec3 an = abs(n0);
  float m = max(max(an.x, an.y), an.z);
  if (!(m > 0.0f && m <= 3.40282347e38f)) return vec4(0.0f);
  SH_PRECISE vec3 n = n0 * sh_unit_scale(m);
  SH_PRECISE float dd = sh_dot(n, n);
  SH_PRECISE float len = sh_sqrt(dd);
  if (!(len > 0.0f)) return vec4(0.0f);
  SH_PRECISE float inv = sh_rcp(len);
  SH_PRECISE vec3 u = n * inv;
  if (sh_dot(u, dir) > 0.0f) u = -u;  // facing the viewer
  return vec4(u, 1.0f);
}

// PCG-style integer hash (Jarzynski and Olano 2020, "Hash Functions for GPU Rendering").
SH_INLINE uint pcg_hash(uint v) {
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

// The per-pixel random numbers of the bounce: two uniform floats in [0, 1) (24 bits each).
SH_INLINE vec2 pixel_random(uint x, uint y, uint frame) {
  uint h1 = pcg_hash(x ^ pcg_hash(y ^ pcg_hash(frame)));
  uint h2 = pcg_hash(h1);
  SH_PRECISE float a = float(h1 >> 8u) * 5.96046448e-8f;  // 2^-24 exactly
  SH_PRECISE float b = float(h2 >> 8u) * 5.96046448e-8f;
  return vec2(a, b);
}

// (sin a, cos a) for a in [0, 2 pi] (the bounce's azimuth): a = k pi/2 + r with |r| <= pi/4
// (Cody-Waite, two constants), Taylor polynomials to degree 9 and 8 in r (error below 4e-8 on
// [-pi/4, pi/4]), the quadrant k mod 4 swapping and negating them. + - * and floor only.
SH_INLINE vec2 sh_sin_cos(float a) {
  SH_PRECISE float kf = floor(a * 0.636619772f + 0.5f);
  SH_PRECISE float r0 = a - kf * 1.57079637f;
  SH_PRECISE float r = r0 + kf * 4.37113883e-8f;
  SH_PRECISE float r2 = r * r;
  SH_PRECISE float ps = ((2.75573192e-6f * r2 - 1.98412698e-4f) * r2 + 8.33333333e-3f) * r2 - 1.66666667e-1f;
  SH_PRECISE float s = r + (r * r2) * ps;
  SH_PRECISE float pc = ((2.48015873e-5f * r2 - 1.38888889e-3f) * r2 + 4.16666667e-2f) * r2 - 0.5f;
  SH_PRECISE float c = 1.0f + r2 * pc;
  uint k = uint(max(kf, 0.0f)) & 3u;
  if (k == 0u) return vec2(s, c);
  if (k == 1u) return vec2(c, -s);
  if (k == 2u) return vec2(-s, -c);
  return vec2(-c, s);
}

// The glossy bounce direction (common/gather.h, bounce_rays): the mirror direction of unit `d`
// about unit `n`; for gloss < 1 a direction uniform in the cone of half-angle (1 - gloss) pi/2
// about it (cos_max = cos of that angle, computed once per material by the host), with the
// random numbers xi; folded back into n's hemisphere; the mirror direction where that fails.
SH_INLINE vec3 bounce_direction(SH_IN(vec3) d, SH_IN(vec3) n, float gloss, float cos_max, SH_IN(vec2) xi) {
  // Mirror direction about the gather normal
  SH_PRECISE float dn2 = 2.0f * sh_dot(d, n);
  SH_PRECISE vec3 m0 = d - n * dn2;
  vec3 mirror = sh_normalize(m0);
  if (!(gloss < 1.0f)) return mirror;
  // Uniform direction in the cone about the mirror direction
  SH_PRECISE float cos_t = 1.0f - xi.x * (1.0f - cos_max);
  SH_PRECISE float sin_t = sh_sqrt(max(0.0f, 1.0f - cos_t * cos_t));
  SH_PRECISE float phi = 6.28318548f * xi.y;
  vec2 sc = sh_sin_cos(phi);
  // An orthonormal basis (t, b) around the mirror direction (Duff et al. 2017)
  SH_PRECISE float sgn = (floatBitsToUint(mirror.z) & 0x80000000u) != 0u ? -1.0f : 1.0f;
  SH_PRECISE float ia = sh_div(-1.0f, sgn + mirror.z);
  SH_PRECISE float ic = (mirror.x * mirror.y) * ia;
  SH_PRECISE vec3 t = vec3(1.0f + ((sgn * mirror.x) * mirror.x) * ia, sgn * ic, -sgn * mirror.x);
  SH_PRECISE vec3 b = vec3(ic, sgn + (mirror.y * mirror.y) * ia, -mirror.y);
  SH_PRECISE vec3 side = t * sc.y + b * sc.x;
  SH_PRECISE vec3 dir0 = mirror * cos_t + side * sin_t;
  vec3 dir = sh_normalize(dir0);
  // Fold directions below the surface back into the normal's hemisphere
  SH_PRECISE float dn = sh_dot(dir, n);
  if (dn < 0.0f) {
    SH_PRECISE vec3 f = dir - n * (2.0f * dn);
    dir = sh_normalize(f);
  }
  if (!(sh_dot(dir, n) > 0.0f)) dir = mirror;
  return dir;
}

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::CameraParams) == 64, "std430 layout of CameraParams");
static_assert(sizeof(gridrt::shared::GatherTexel) == 48, "std430 layout of GatherTexel");
#endif

#endif
