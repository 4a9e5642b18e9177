#version 460
// build_cells.comp: the compute build's runs (build.glsl, kBuildRun): one invocation per
// (reference, run) of the build list, dispatched indirectly: the triangle as build.comp wrote it
// to the geometry buffer, its AABB range again, and the run's kBuildRun cells of that range.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#define GRIDRT_BUILD_SUBGROUP  // build.glsl: the count pass's pairs and the runs a subgroup at a time
#include "build.glsl"

layout(local_size_x = 64) in;

void main() {
  const GridParams g = grid_params();
  const uint item = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 64u, gl_LocalInvocationID.x);
  if (item >= build_header.size) return;
  const uint ref = build_items[2u * item];
  const uint run = build_items[2u * item + 1u];
  const GridTriangle tri = triangles[instances[ref_instance(ref)].tri_offset + ref_triangle(ref)];
  const vec3 n = triangle_normal(tri.v0, tri.v1, tri.v2);
  uvec3 lo;
  uvec3 hi;
  triangle_cell_range(g, tri.v0, tri.v1, tri.v2, lo, hi);
  const uvec3 size = hi - lo + 1u;
  const uint count = size.x * size.y * size.z;
  insert_range_cells(g, ref, tri.v0, tri.v1, tri.v2, n, lo, hi, run * kBuildRun, min(count, (run + 1u) * kBuildRun));
}
