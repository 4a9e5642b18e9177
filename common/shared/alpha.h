// alpha.h: alpha keying, the uv -> texel rule shared by the reference, the shaders and the Embree
// oracle's filter. A hit is kept when the alpha-mask texel under its uv has alpha >= 128
// (texel alpha < 0.5 means no surface, as the real scenes' masks are drawn).
#ifndef GRIDRT_SHARED_ALPHA_H
#define GRIDRT_SHARED_ALPHA_H

#include "compat.h"

SH_BEGIN

SH_CONST uint kAlphaCutoff = 128u;  // keep the surface where alpha >= 128 (of 255)

// Interpolated texture coordinates at barycentrics (u, v): uv0 + u (uv1 - uv0) + v (uv2 - uv0).
SH_INLINE vec2 interpolate_uv(SH_IN(vec2) uv0, SH_IN(vec2) uv1, SH_IN(vec2) uv2, float u, float v) {
  SH_PRECISE float s = uv0.x + u * (uv1.x - uv0.x) + v * (uv2.x - uv0.x);
  SH_PRECISE float t = uv0.y + u * (uv1.y - uv0.y) + v * (uv2.y - uv0.y);
  return vec2(s, t);
}

// Nearest texel of a repeating texture, row 0 = first row of the file, v = 0 at the last row.
// frac(x) = x - floor(x) lies in [0, 1]; the product with the size is clamped to size - 1. A uv
// that interpolated to an infinity (corners near +-3e38) gives a NaN there: texel 0, taken by a
// comparison (max(NaN, 0) is either on a GPU, and a NaN's conversion to uint undefined).
SH_INLINE uvec2 alpha_texel_coords(SH_IN(vec2) uv, uint width, uint height) {
  SH_PRECISE float fu = uv.x - floor(uv.x);
  SH_PRECISE float fv = uv.y - floor(uv.y);
  SH_PRECISE float xf = fu * float(width);
  SH_PRECISE float yf = (1.0f - fv) * float(height);
  uint x = xf >= 1.0f ? min(uint(xf), width - 1u) : 0u;
  uint y = yf >= 1.0f ? min(uint(yf), height - 1u) : 0u;
  return uvec2(x, y);
}

SH_END

#endif
