// compat.h: the macro layer that lets one header be compiled as C++ (with GLM) and as GLSL
// (glslang, GL_GOOGLE_include_directive). Rules for every header in common/shared/:
//  - Only the subset of C++ that GLSL shares: no references, pointers, templates, methods,
//    namespaces-in-code, overloading on return type, recursion, or swizzle proxies.
//  - `uint` for index math (signed overflow is UB in C++, wraps in GLSL); no shift by >= 32.
//  - Float literals carry an `f` suffix (no double promotion in C++); unsigned ones a `u`.
//  - Decisions use + - * and comparisons only; a division appears only in reported values.
//  - No float `/`, `sqrt` or `inversesqrt`: sh_div, sh_rcp and sh_sqrt (rounding.h) are correctly
//    rounded on every device, the built-ins are not (2.5 ulp in Vulkan).
//    Unsigned integer division is sh_udiv (or `/` by a `u` literal); tests/lint/shared_math.cmake checks.
//  - Every float temporary that feeds a decision or a reported value is SH_PRECISE, so that the
//    GLSL compiler and driver do not contract a*b+c into an FMA (the C++ side is built with
//    -ffp-contract=off). dot/cross are written out as ordered sums (sh_dot, sh_cross).
//  - A vec3 is followed by one scalar in structs that live in buffers (std430 alignment); every
//    struct's size is static_assert-ed on the C++ side.
#ifndef GRIDRT_SHARED_COMPAT_H
#define GRIDRT_SHARED_COMPAT_H

#ifdef __cplusplus
#  include <cstdint>
#  include <glm/glm.hpp>
#  define SH_BEGIN namespace gridrt { namespace shared { \
     using glm::vec2; using glm::vec3; using glm::vec4; using glm::ivec3; using glm::uvec3; \
     using glm::uvec4; using glm::ivec2; using glm::uvec2; using uint = std::uint32_t; \
     using glm::min; using glm::max; using glm::clamp; using glm::floor; using glm::ceil; using glm::abs; \
     using glm::sqrt; using glm::floatBitsToUint; using glm::uintBitsToFloat; using glm::bitCount;
#  define SH_END } }
#  define SH_IN(T) const T&
#  define SH_OUT(T) T&
#  define SH_INOUT(T) T&
#  define SH_PRECISE
#  define SH_CONST inline constexpr
#  define SH_INLINE inline
#else
#  define SH_BEGIN
#  define SH_END
#  define SH_IN(T) in T
#  define SH_OUT(T) out T
#  define SH_INOUT(T) inout T
#  define SH_PRECISE precise
#  define SH_CONST const
#  define SH_INLINE
#endif

SH_BEGIN

// Dot and cross products as explicit, ordered sums: (x + y) + z, never fused.
// Unsigned integer division, exact on every device: named so that the shared math's one float
// rule (no float `/`, checked by tests/lint/shared_math.cmake) can tell it from a float division.
SH_INLINE uint sh_udiv(uint a, uint b) { return a / b; }

SH_INLINE float sh_dot(SH_IN(vec3) a, SH_IN(vec3) b) {
  SH_PRECISE float xy = a.x * b.x + a.y * b.y;
  SH_PRECISE float r = xy + a.z * b.z;
  return r;
}

SH_INLINE vec3 sh_cross(SH_IN(vec3) a, SH_IN(vec3) b) {
  SH_PRECISE float x = a.y * b.z - a.z * b.y;
  SH_PRECISE float y = a.z * b.x - a.x * b.z;
  SH_PRECISE float z = a.x * b.y - a.y * b.x;
  return vec3(x, y, z);
}

SH_END

#endif
