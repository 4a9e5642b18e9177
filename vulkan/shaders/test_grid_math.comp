#version 460
// test_grid_math.comp: the per-ray and per-triangle functions of common/shared/grid.h and
// triangle.h on random rays and triangles, step by step, for tests/test_vulkan_math.cpp (which
// compares every value bit for bit with the C++ build and, on a device that rounds differently,
// names the first function that does).
#extension GL_GOOGLE_include_directive : require
#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/triangle.h"

layout(local_size_x = 64) in;

// Per case, kInStride floats: org [0..2], tmin [3], dir [4..6], tmax [7], v0 [8..10],
// v1 [11..13], v2 [14..16].
const uint kInStride = 20u;
// Per case, kOutStride words (see kGridMathNames in the test).
const uint kOutStride = 24u;

layout(std430, binding = 0) readonly buffer Params { GridParams g; };
layout(std430, binding = 1) readonly buffer Inputs { float inputs[]; };
layout(std430, binding = 2) writeonly buffer Outputs { uint outputs[]; };
layout(push_constant) uniform Push { uint count; } pc;

vec3 in3(uint b, uint k) { return vec3(inputs[b + k], inputs[b + k + 1u], inputs[b + k + 2u]); }
void put(uint o, uint k, float f) { outputs[o + k] = floatBitsToUint(f); }

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= pc.count) return;
  const uint b = i * kInStride, o = i * kOutStride;
  const vec3 org = in3(b, 0u), dir = in3(b, 4u), v0 = in3(b, 8u), v1 = in3(b, 11u), v2 = in3(b, 14u);
  const float tmin = inputs[b + 3u], tmax = inputs[b + 7u];

  // The steps of ray_setup, then ray_setup itself
  precise float dd = sh_dot(dir, dir);
  precise float len = sh_sqrt(dd);
  precise float seg = sh_div(g.cell_size, len);
  float seg_plain = g.cell_size / len;
  float t0;
  float t1;
  const bool clipped = clip_to_grid(g, org, dir, t0, t1);
  RaySetup rs;
  const bool meets = ray_setup(g, org, dir, tmin, tmax, rs);
  put(o, 0u, dd);
  put(o, 1u, len);
  put(o, 2u, seg);
  put(o, 3u, seg_plain);
  put(o, 4u, t0);
  put(o, 5u, t1);
  outputs[o + 6u] = (clipped ? 1u : 0u) | (meets ? 2u : 0u);
  put(o, 7u, rs.seg_t);
  put(o, 8u, rs.t_start);
  put(o, 9u, rs.t_end);
  put(o, 10u, rs.t_lo);

  // Moller-Trumbore, its reported t, Cramer's barycentrics at the hit point
  TriangleTest r;
  const uint code = moller_trumbore(org, dir, v0, v1, v2, tmin, tmax, sh_infinity(), r);
  outputs[o + 11u] = code;
  put(o, 12u, r.det);
  put(o, 13u, r.u_det);
  put(o, 14u, r.v_det);
  put(o, 15u, r.t_det);
  put(o, 16u, r.lo_det);
  put(o, 17u, r.hi_det);
  const float t = code == kTestAccepted ? moller_trumbore_t(r) : 0.0f;
  put(o, 18u, t);
  const vec2 bc = cramer_barycentrics(v0, v1, v2, point_at(org, dir, t));
  put(o, 19u, bc.x);
  put(o, 20u, bc.y);
  const vec3 inv = dda_inverse_direction(dir);
  put(o, 21u, inv.x);
  put(o, 22u, inv.y);
  put(o, 23u, inv.z);
}
