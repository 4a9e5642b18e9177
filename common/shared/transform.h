// transform.h: object-to-world transform of a vertex, written once so that the grid build (CPU
// and GPU) and the Embree oracle see the very same world-space triangles, bit for bit.
#ifndef GRIDRT_SHARED_TRANSFORM_H
#define GRIDRT_SHARED_TRANSFORM_H

#include "compat.h"
#include "rounding.h"

SH_BEGIN

// A 3x4 affine transform as three rows (x, y, z) of vec4: p' = row . (p, 1).
struct Affine {
  vec4 row0;
  vec4 row1;
  vec4 row2;
};

// ((m.x * p.x + m.y * p.y) + m.z * p.z) + m.w, never fused.
// Every product and partial sum subnormal is taken as a zero too (the products of a 1e-20 scale
// and a 1e-20 coordinate were kept by the CPU and the compute build and flushed by lavapipe's
// raster build: an outside review), so no stage sees a subnormal a device could flush.
SH_INLINE float affine_row(SH_IN(vec4) m, SH_IN(vec3) p) {
  SH_PRECISE float x = sh_flush_subnormal(m.x * p.x);
  SH_PRECISE float y = sh_flush_subnormal(m.y * p.y);
  SH_PRECISE float z = sh_flush_subnormal(m.z * p.z);
  SH_PRECISE float xy = sh_flush_subnormal(x + y);
  SH_PRECISE float xyz = sh_flush_subnormal(xy + z);
  SH_PRECISE float r = xyz + m.w;
  return r;
}

// A mesh vertex in world space. Subnormal coordinates, of the vertex and of the result, are taken
// as zeros: a device may flush them in any stage (lavapipe's vertex and geometry stages do, its
// compute stages do not), and the raster build's vertices then differed from the reference's and
// the compute build's (a vertex at y = 1e-40: hit against miss; a triangle scaled by 1e-39 dropped:
// an outside sweep). Flushed here, every backend and the oracle see the same vertex.
// The result's coordinates below 2^-100 in magnitude (kTinyCoordinate) are zeros too: then no edge
// of a triangle, the difference of two coordinates (at least ulp(2^-100) = 2^-123 apart), is
// subnormal either (a triangle of normal coordinates about 1e-38 and subnormal edges was taken for
// zero-area by lavapipe's geometry stage and left out of the raster build, kept by the reference:
// an outside sweep).
SH_CONST uint kTinyCoordinateBits = 0x0D800000u;  // 2^-100
SH_INLINE float sh_flush_tiny(float x) {
  uint b = floatBitsToUint(x);
  return (b & 0x7FFFFFFFu) < kTinyCoordinateBits ? uintBitsToFloat(b & 0x80000000u) : x;
}
SH_INLINE vec3 transform_point(SH_IN(Affine) m, SH_IN(vec3) p) {
  vec3 q = sh_flush_subnormal3(p);
  vec3 r = vec3(affine_row(m.row0, q), affine_row(m.row1, q), affine_row(m.row2, q));
  return vec3(sh_flush_tiny(r.x), sh_flush_tiny(r.y), sh_flush_tiny(r.z));
}

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::Affine) == 48, "std430 layout of Affine");
namespace gridrt::shared {
// The rows of a column-major glm::mat4 (its last row must be 0 0 0 1).
inline Affine to_affine(const glm::mat4& m) {
  return {glm::vec4(m[0][0], m[1][0], m[2][0], m[3][0]), glm::vec4(m[0][1], m[1][1], m[2][1], m[3][1]),
          glm::vec4(m[0][2], m[1][2], m[2][2], m[3][2])};
}
}  // namespace gridrt::shared
#endif

#endif
