#version 460
// build.comp: the compute build (paper 2.1: "the practitioner may opt to use compute shaders"):
// one invocation per triangle of instances [first_instance, last_instance), the same build step
// (build.glsl) as the geometry shader.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#define GRIDRT_BUILD_SUBGROUP  // build.glsl: the count pass's pairs and the runs a subgroup at a time
#include "build.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform Push { BuildPush pc; };

void main() {
  if (gl_GlobalInvocationID.x >= pc.tri_count) return;
  const uint global = pc.tri_begin + gl_GlobalInvocationID.x;
  // The instance holding this triangle: the last whose offset is <= global
  uint lo = pc.first_instance, hi = pc.last_instance;
  while (hi - lo > 1u) {
    const uint mid = (lo + hi) / 2u;
    if (instances[mid].tri_offset <= global) lo = mid;
    else hi = mid;
  }
  const uint instance = lo;
  const uint triangle = global - instances[instance].tri_offset;
  build_invocation(instance, triangle, world_vertex(instance, triangle, 0u),
                   world_vertex(instance, triangle, 1u), world_vertex(instance, triangle, 2u), true);
}
