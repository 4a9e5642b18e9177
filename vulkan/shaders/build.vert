#version 460
// build.vert: the raster pass of scene build (paper 2.1). One draw per instance with
// firstInstance = the instance's id and 3 vertices per triangle, no vertex buffers: the vertex
// transforms its mesh vertex and passes the instance id (gl_InstanceIndex) and the triangle id
// (gl_VertexIndex / 3) down, flat, to build.geom.
#extension GL_GOOGLE_include_directive : require
#include "grid_common.glsl"

layout(location = 0) out vec3 world;
layout(location = 1) flat out uint instance_id;
layout(location = 2) flat out uint triangle_id;

void main() {
  const uint instance = uint(gl_InstanceIndex);
  const uint vertex = uint(gl_VertexIndex);
  world = world_vertex(instance, vertex / 3u, vertex % 3u);
  instance_id = instance;
  triangle_id = vertex / 3u;
  gl_Position = vec4(0.0);
}
