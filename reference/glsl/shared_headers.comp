#version 450
// Compiles every shared header as GLSL and calls each function once: the CTest
// "shared_headers_glsl" runs glslangValidator on it, so a C++-only construct in common/shared/
// fails the build's tests before it reaches the Vulkan port.
#extension GL_GOOGLE_include_directive : require
#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/records.h"
#include "gridrt/common/shared/transform.h"
#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/triangle.h"
#include "gridrt/common/shared/explain.h"
#include "gridrt/common/shared/portal.h"
layout(local_size_x = 1) in;
layout(std430, binding = 0) buffer B { GridParams g; ExplainEvent ev; HitRecord h; };
void main() {
  float pnum;
  uint pa = portal_exit_axis(vec3(0), vec3(1), vec3(0.5), vec3(1), pnum);
  bool pw = portal_texel_is_wall(pa) && portal_before_tmax(1.0f, 1.0f, 2.0f);
  uvec3 lo; uvec3 hi;
  triangle_cell_range(g, vec3(0), vec3(1), vec3(2), lo, hi);
  vec3 n = triangle_normal(vec3(0), vec3(1,0,0), vec3(0,1,0));
  bool a = plane_intersects_enlarged_sphere(vec3(0), n, cell_center(g, lo), g.sphere_r2, cell_test_scale(g)) &&
           triangle_overlaps_cell(g, vec3(0), vec3(1,0,0), vec3(0,1,0), n, lo);
  RaySetup rs;
  bool m = ray_setup(g, vec3(0), vec3(1), 0.0f, 1.0f, rs);
  TriangleTest r;
  uint code = moller_trumbore(vec3(0), vec3(1), vec3(0), vec3(1,0,0), vec3(0,1,0), 0.0f, 1.0f, 2.0f, r);
  vec2 bc = cramer_barycentrics(vec3(0), vec3(1,0,0), vec3(0,1,0), vec3(0.2));
  vec2 vals;
  bool l = gap_fill_left_surface(vec3(1), vec3(0), vec3(0,1,0), g.gap_fill_r2, vals);
  vec3 inv = dda_inverse_direction(vec3(1));
  vec3 ex = dda_exits(g, vec3(0), vec3(1), inv, lo);
  uvec3 c = lo;
  bool s = dda_step(g, vec3(1), dda_step_axis(ex), c);
  bool in_ = grid_contains(g, vec3(0.5)) && ray_valid(vec3(0), vec3(1), 0.0f, 1.0f);
  uvec3 t = slot_texel(c, 1u, g.capacity) + status_texel(c, g.capacity) + grid_image_extent(g);
  h.t = segment_sample_t(rs, 2u) + segment_elongated_begin(g, rs, 1u) + segment_elongated_end(g, rs, 1u) + moller_trumbore_t(r) + bc.x + vals.x + dda_cell_exit(ex) + segment_begin(rs, 0u) + segment_end(rs,0u);
  h.flags = code + uint(a) + uint(m) + uint(l) + uint(s) + uint(in_) + t.x + ref_pack(1u,2u) + ref_instance(5u) + ref_triangle(7u) + texel_index(t, uvec3(4u)) + texel_alpha(3u) + uint(alpha_keeps(4u));
  ev.kind = kEvRay;
}
