// rounding.h: correctly rounded division and square root, written once for the reference (C++)
// and the shaders (GLSL), so that both compute the same bits on any device whose + - * and
// integer arithmetic are exact (docs/SPEC.md, "Division and square root").
//
// GLSL's `/` and `sqrt` are not correctly rounded on every device (2.5 ulp in the Vulkan
// specification, 1-3 ulps measured on NVIDIA; a divisor over 2^126 gives 0 there). Each function
// here takes the device's quotient or root of the operands' significands as a first
// approximation, computes the exact remainder of that approximation in 32-bit integer arithmetic,
// and corrects it to the correctly rounded result (round to nearest, ties to even), then puts the
// exponent back with integer operations:
//  - a, b (finite, nonzero) are split into integer significands A, B in [2^23, 2^24) and
//    exponents: a = A 2^(ea - 150). Subnormal operands are normalized here (findMSB), so they are
//    exact too, wherever the device hands them over unflushed.
//  - Q approximates A 2^s / B in [2^23, 2^24] (s = 23 or 24). The remainder R = A 2^s - Q B is
//    exact when computed modulo 2^32 (uint wraps in C++ and GLSL) as long as |R| < 2^31, that
//    is, while Q is within 64 units of the quotient (A 2^s and Q B have 48 bits; only their
//    difference's low 32 are needed, and those the wrapping products give exactly).
//  - Q moves by round(R / B) units (a quotient of two 24-bit significands is never halfway
//    between two 24-bit ones). Overflow, underflow and subnormal results are rounded from Q with
//    the sign of R as the sticky bit, ties to even.
// Floats enter only as the first approximation (a quotient of two numbers in [1, 2), within the
// Vulkan precision's domain) and its conversion to an integer, so neither FMA contraction nor a
// flush to zero can change the result.
//
// Guaranteed: sh_div, sh_rcp and sh_sqrt return the IEEE 754 binary32 result rounded to nearest
// even, for every input (zeros, infinities, subnormals, NaN: a NaN is returned as 0x7FC00000),
// provided the approximation they are handed is within 64 ulps (division) or 16 ulps (square
// root); the device's `/` and `sqrt` are (2.5 ulp in Vulkan, for these operands in [1, 4)). A device that flushes subnormal *inputs* before they reach these functions (an
// arithmetic result that was subnormal) computes on zero instead; the functions themselves return
// subnormal results as their exact bits.
#ifndef GRIDRT_SHARED_ROUNDING_H
#define GRIDRT_SHARED_ROUNDING_H

#include "compat.h"

SH_BEGIN

#ifdef __cplusplus
using glm::findMSB;
#endif

SH_CONST uint kShQuietNan = 0x7FC00000u;
SH_CONST uint kShInfinityBits = 0x7F800000u;

// A finite, nonzero float's (bits without the sign) integer significand in [2^23, 2^24) and its
// biased exponent e: x = sig 2^(e - 150); e <= 0 for subnormals (normalized here). Zero gives 0.
SH_INLINE uint sh_split(uint x, SH_OUT(int) e) {
  uint f = (x >> 23u) & 0xFFu;
  uint m = x & 0x7FFFFFu;
  if (f != 0u) {
    e = int(f);
    return m | 0x800000u;
  }
  uint sh = uint(23 - findMSB(m));  // findMSB(0) = -1: sh = 24, and 0 << 24 = 0
  e = 1 - int(sh);
  return m << sh;
}

// The significand of x as a float in [1, 2) (subnormals normalized; anything for 0, inf, NaN).
SH_INLINE float sh_significand(float x) {
  int e;
  uint sig = sh_split(floatBitsToUint(x) & 0x7FFFFFFFu, e);
  return uintBitsToFloat(0x3F800000u | (sig & 0x7FFFFFu));
}

// ---- Division ----

// a / b correctly rounded, given q0, an approximation of sh_significand(a) / sh_significand(b)
// (a number in (1/2, 2)) within 64 ulps. q0 outside (1/4, 4) or NaN is replaced by 1 (the result
// is then correctly rounded only where 1 happens to be within 64 ulps). Deterministic for any q0.
SH_INLINE float sh_div_correct(float a, float b, float q0) {
  uint ba = floatBitsToUint(a);
  uint bb = floatBitsToUint(b);
  uint sgn = (ba ^ bb) & 0x80000000u;
  uint xa = ba & 0x7FFFFFFFu;
  uint xb = bb & 0x7FFFFFFFu;
  // NaN operands, 0 / 0, inf / inf; then the infinite and zero quotients
  if (xa > kShInfinityBits || xb > kShInfinityBits || (xa == 0u && xb == 0u) ||
      (xa == kShInfinityBits && xb == kShInfinityBits))
    return uintBitsToFloat(kShQuietNan);
  if (xa == kShInfinityBits || xb == 0u) return uintBitsToFloat(sgn | kShInfinityBits);
  if (xa == 0u || xb == kShInfinityBits) return uintBitsToFloat(sgn);

  // Integer significands and the result's biased exponent (before rounding): the quotient of the
  // significands is Q 2^-s with Q in [2^23, 2^24]
  int ea;
  int eb;
  uint A = sh_split(xa, ea);
  uint B = sh_split(xb, eb);
  bool ge = A >= B;
  uint s = ge ? 23u : 24u;
  int er = ea - eb + (ge ? 127 : 126);

  // First approximation, as an integer (q0 2^s is exact; the conversion truncates)
  if (!(q0 > 0.25f && q0 < 4.0f)) q0 = 1.0f;
  SH_PRECISE float qs = q0 * (ge ? 8388608.0f : 16777216.0f);
  uint Q = uint(qs);

  // The exact remainder R = A 2^s - Q B, modulo 2^32 (exact while |R| < 2^31: |Q - A 2^s / B| <= 65)
  int R = int((A << s) - Q * B);

  // Round to nearest: move Q by round(R / B) units, so that |R| <= B / 2. k = floor((r2 + B) / 2B)
  // by comparisons where it is at most 3 (the device's quotient within 2.5 ulps: always), by the
  // integer division only beyond (a GPU has no integer divider: some 30 instructions)
  uint r2 = R < 0 ? uint(-R) * 2u : uint(R) * 2u;
  if (r2 > B) {
    uint k = r2 < 3u * B ? 1u : (r2 < 5u * B ? 2u : 3u);
    if (r2 >= 7u * B) k = (r2 + B) / (2u * B);
    if (R > 0) {
      Q = Q + k;
      R = R - int(k * B);
    } else {
      Q = Q - k;
      R = R + int(k * B);
    }
  }
  // No tie here: A 2^(s+1) = (2Q + 1) B would give the odd part of A (24 bits at most) the 25
  // bits of 2Q + 1. Ties occur only among subnormal results, below.
  // Rounded up to the next binade
  if (Q >= 0x1000000u) {
    Q = Q >> 1u;
    er = er + 1;
  }

  // Assemble: overflow, normal, or subnormal (rounded again from Q, with R as the sticky bit)
  if (er >= 255) return uintBitsToFloat(sgn | kShInfinityBits);
  if (er >= 1) return uintBitsToFloat(sgn | (uint(er) << 23u) | (Q & 0x7FFFFFu));
  uint sh = uint(1 - er);
  if (sh >= 25u) return uintBitsToFloat(sgn);  // below half the smallest subnormal
  uint keep = Q >> sh;
  uint lost = Q & ((1u << sh) - 1u);
  uint halfway = 1u << (sh - 1u);
  bool up = lost > halfway || (lost == halfway && (R > 0 || (R == 0 && (keep & 1u) != 0u)));
  return uintBitsToFloat(sgn | (keep + (up ? 1u : 0u)));
}

// a / b, correctly rounded (the device's quotient of the significands, corrected).
SH_INLINE float sh_div(float a, float b) {
  SH_PRECISE float q0 = sh_significand(a) / sh_significand(b);
  return sh_div_correct(a, b, q0);
}

// 1 / b, correctly rounded.
SH_INLINE float sh_rcp(float b) { return sh_div(1.0f, b); }

// ---- Square root ----

// The number whose square root sh_sqrt_correct wants approximated: a's significand, times 2 when
// that makes a's exponent even, in [1, 4).
SH_INLINE float sh_sqrt_significand(float a) {
  int e;
  uint sig = sh_split(floatBitsToUint(a) & 0x7FFFFFFFu, e);
  SH_PRECISE float m = uintBitsToFloat(0x3F800000u | (sig & 0x7FFFFFu));
  SH_PRECISE float m2 = m * 2.0f;
  return (e & 1) != 0 ? m : m2;
}

// sqrt(a) correctly rounded, given s0, an approximation of sqrt(sh_sqrt_significand(a)) (in
// [1, 2)) within 16 ulps. s0 outside (1/2, 4) or NaN is replaced by 1. -0 gives -0, a negative
// number or NaN gives NaN.
SH_INLINE float sh_sqrt_correct(float a, float s0) {
  uint ba = floatBitsToUint(a);
  if (ba == 0u || ba == 0x80000000u || ba == kShInfinityBits) return a;
  if (ba > kShInfinityBits) return uintBitsToFloat(kShQuietNan);  // NaN or negative

  // a = A 2^(e - 150) = N 2^(2 E - 300), N = A 2^t with t = 23 or 24 (E integer), so that
  // sqrt(a) = sqrt(N) 2^(E - 150) with sqrt(N) in [2^23, 2^24): E is the result's biased exponent
  int e;
  uint A = sh_split(ba, e);
  bool odd = (e & 1) != 0;
  uint t = odd ? 23u : 24u;
  int er = (e + (odd ? 127 : 126)) / 2;

  // First approximation, as an integer
  if (!(s0 > 0.5f && s0 < 4.0f)) s0 = 1.0f;
  SH_PRECISE float ss = s0 * 8388608.0f;
  uint S = uint(ss);

  // The exact remainder R = N - S^2, modulo 2^32 (exact while |R| < 2^31: |S - sqrt(N)| < 2^6)
  int R = int((A << t) - S * S);

  // Round to nearest (no ties: sqrt(N) is never a half-integer): -S < R <= S. A coarse step of
  // round(R / 2S) units, then at most one unit.
  uint ar = R < 0 ? uint(-R) : uint(R);
  if (ar > S) {
    // k = floor((ar + S) / 2S), by comparisons up to 3 (as in the division)
    uint k = ar < 3u * S ? 1u : (ar < 5u * S ? 2u : 3u);
    if (ar >= 7u * S) k = (ar + S) / (2u * S);
    S = R > 0 ? S + k : S - k;
    R = int((A << t) - S * S);
  }
  if (R > int(S)) {
    R = R - int(2u * S + 1u);
    S = S + 1u;
  } else if (R <= -int(S)) {
    S = S - 1u;
    R = R + int(2u * S + 1u);
  }
  if (S >= 0x1000000u) {
    S = S >> 1u;
    er = er + 1;
  }
  return uintBitsToFloat((uint(er) << 23u) | (S & 0x7FFFFFu));
}

// sqrt(a), correctly rounded (the device's root of the significand, corrected).
SH_INLINE float sh_sqrt(float a) {
  SH_PRECISE float s0 = sqrt(sh_sqrt_significand(a));
  return sh_sqrt_correct(a, s0);
}

// The power of two S that brings m (> 0, finite) into [1, 2) (a denormal m: 2^126, which brings
// it at least to its own exponent's range). Scaling by S is exact wherever it neither overflows nor
// underflows, and commutes with every rounding: products, sums, sqrt and / of scaled values are
// the unscaled ones scaled, so a computation done in scaled units keeps its decisions and, after
// the scale cancels, its bits, while its squares stay in the normal range.
SH_INLINE float sh_unit_scale(float m) {
  uint e = (floatBitsToUint(m) >> 23u) & 0xFFu;
  return uintBitsToFloat((254u - max(e, 1u)) << 23u);
}

// Subnormals (below 2^-126 in magnitude, told by their exponent bits, the same on every backend),
// which a device may flush in any stage: normal_or_zero takes one as +0 (the directions the grid
// and the portal tracer step with: traced_direction, portal_direction), sh_flush_subnormal as a
// zero of its sign, as a flushing device does (world-space vertices: transform_point).
SH_INLINE float normal_or_zero(float d) { return (floatBitsToUint(d) & 0x7F800000u) == 0u ? 0.0f : d; }
SH_INLINE vec3 normal_or_zero3(SH_IN(vec3) v) { return vec3(normal_or_zero(v.x), normal_or_zero(v.y), normal_or_zero(v.z)); }
// Whether x is a zero or a subnormal (its exponent bits all zero; NaN and inf are not). A triangle
// test's determinant there is taken as zero: built of subnormal products, which devices may flush
// (lavapipe's compute stages did for a triangle 1e-20 across: another t than the reference's),
// it decides nothing on every device alike (docs/SPEC.md "Moller-Trumbore").
SH_INLINE bool sh_zero_or_subnormal(float x) { return (floatBitsToUint(x) & 0x7F800000u) == 0u; }

SH_INLINE float sh_flush_subnormal(float x) {
  uint b = floatBitsToUint(x);
  return (b & 0x7F800000u) == 0u ? uintBitsToFloat(b & 0x80000000u) : x;
}
SH_INLINE vec3 sh_flush_subnormal3(SH_IN(vec3) v) {
  return vec3(sh_flush_subnormal(v.x), sh_flush_subnormal(v.y), sh_flush_subnormal(v.z));
}

SH_END

#endif
