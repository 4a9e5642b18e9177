#version 460
// test_shared_math.comp: evaluates the shared math of common/shared/{compat,transform,alpha}.h
// on the inputs of tests/test_vulkan_math.cpp, which compares every result bit for bit with the
// same C++ functions.
#extension GL_GOOGLE_include_directive : require
#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/transform.h"
#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/rounding.h"

layout(local_size_x = 64) in;

// Per case, kInStride floats: a[0..2] b[3..5] (dot, cross); affine rows [0..11], point [12..14]
// (transform); uv0 [15,16] uv1 [17,18] uv2 [19,20] u [21] v [22] (interpolate_uv); uv [23,24],
// width [25] and height [26] as uint bits (alpha_texel_coords).
const uint kInStride = 28u;
// Per case, kOutStride words: dot [0], cross [1..3], transform [4..6], uv [7,8], texel [9,10],
// and the operations the shared headers use for reported values: sh_div(a.x, b.x) [11],
// sh_rcp(a.y) [12], sh_sqrt(|a.z|) [13] (rounding.h), floor(b.y) [14].
const uint kOutStride = 16u;

layout(std430, binding = 0) readonly buffer Inputs { float inputs[]; };
layout(std430, binding = 1) writeonly buffer Outputs { uint outputs[]; };
layout(push_constant) uniform Push { uint count; } pc;

float at(uint base, uint k) { return inputs[base + k]; }
vec3 at3(uint base, uint k) { return vec3(inputs[base + k], inputs[base + k + 1u], inputs[base + k + 2u]); }
vec4 at4(uint base, uint k) {
  return vec4(inputs[base + k], inputs[base + k + 1u], inputs[base + k + 2u], inputs[base + k + 3u]);
}

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= pc.count) return;
  const uint b = i * kInStride, o = i * kOutStride;

  const vec3 a = at3(b, 0u), c = at3(b, 3u);
  outputs[o + 0u] = floatBitsToUint(sh_dot(a, c));
  const vec3 x = sh_cross(a, c);
  outputs[o + 1u] = floatBitsToUint(x.x);
  outputs[o + 2u] = floatBitsToUint(x.y);
  outputs[o + 3u] = floatBitsToUint(x.z);

  const Affine m = Affine(at4(b, 0u), at4(b, 4u), at4(b, 8u));
  const vec3 p = transform_point(m, at3(b, 12u));
  outputs[o + 4u] = floatBitsToUint(p.x);
  outputs[o + 5u] = floatBitsToUint(p.y);
  outputs[o + 6u] = floatBitsToUint(p.z);

  const vec2 uv = interpolate_uv(vec2(at(b, 15u), at(b, 16u)), vec2(at(b, 17u), at(b, 18u)),
                                 vec2(at(b, 19u), at(b, 20u)), at(b, 21u), at(b, 22u));
  outputs[o + 7u] = floatBitsToUint(uv.x);
  outputs[o + 8u] = floatBitsToUint(uv.y);

  const uvec2 t = alpha_texel_coords(vec2(at(b, 23u), at(b, 24u)), floatBitsToUint(at(b, 25u)),
                                     floatBitsToUint(at(b, 26u)));
  outputs[o + 9u] = t.x;
  outputs[o + 10u] = t.y;
  precise float q = sh_div(at(b, 0u), at(b, 3u));
  precise float r = sh_rcp(at(b, 1u));
  precise float w = sh_sqrt(abs(at(b, 2u)));
  outputs[o + 11u] = floatBitsToUint(q);
  outputs[o + 12u] = floatBitsToUint(r);
  outputs[o + 13u] = floatBitsToUint(w);
  outputs[o + 14u] = floatBitsToUint(floor(at(b, 4u)));
  outputs[o + 15u] = 0u;
}
