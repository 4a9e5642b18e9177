#version 460
// build.comp: the compute build (paper 2.1: "the practitioner may opt to use compute shaders"):
// one invocation per triangle of instances [first_instance, last_instance), the same build step
// (build.glsl) as the geometry shader. The pass's last workgroup to finish is the build list's
// dispatch step (worklist.h): the runs it appended become build_cells.comp's indirect dispatch,
// with no pass of their own between.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#define GRIDRT_BUILD_SUBGROUP  // build.glsl: the count pass's pairs and the runs a subgroup at a time
#include "build.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform Push { BuildPush pc; };

shared bool s_last;

void main() {
  if (gl_GlobalInvocationID.x < pc.tri_count) {
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
  // Every invocation's appends are done before the workgroup counts itself finished
  memoryBarrierBuffer();
  barrier();
  if (gl_LocalInvocationIndex == 0u) s_last = atomicAdd(build_header.done, 1u) == pc.groups - 1u;
  barrier();
  if (!s_last || gl_LocalInvocationIndex != 0u) return;
  // The dispatch step (work_list_dispatch.comp's): every workgroup's appends are in the counter
  // (read and reset atomically)
  memoryBarrierBuffer();
  const uint size = min(atomicExchange(build_header.appended, 0u), uint(build_items.length()) / 2u);
  const uvec3 groups = work_list_groups(size, 64u, pc.max_groups_x);
  build_header.groups_x = groups.x;
  build_header.groups_y = groups.y;
  build_header.groups_z = groups.z;
  build_header.size = size;
  build_header.dispatched += size;
  build_header.done = 0u;
}
