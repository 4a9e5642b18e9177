#version 460
// portal_trace.comp: one invocation per ray, trace_portal (portal_trace.glsl, as
// reference/portal/trace.cpp); the explain ray (push constant) records its events.
#extension GL_GOOGLE_include_directive : require
#include "portal_trace.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = kPortalBindRays) readonly buffer Rays { RayRecord rays[]; };
layout(std430, binding = kPortalBindHits) writeonly buffer Hits { HitRecord hits[]; };
layout(push_constant) uniform Push { PortalTracePush pc; };

void main() {
  if (gl_GlobalInvocationID.x >= pc.ray_count) return;
  const uint i = pc.ray_offset + gl_GlobalInvocationID.x;
  explaining = kExplain && i == pc.explain_ray;
  explain_capacity = pc.explain_capacity;
  hits[i] = trace_portal(rays[i]);
}
