#version 460
// test_raster.geom: writes each transformed triangle to the output buffer at
// instance * triangles_per_instance + triangle, and emits nothing (rasterizer discard).
layout(triangles) in;
layout(points, max_vertices = 1) out;

layout(location = 0) in vec3 world[];
layout(location = 1) flat in uint instance_id[];
layout(location = 2) flat in uint triangle_id[];

struct Out { vec4 v0; vec4 v1; vec4 v2; };  // xyz, w = id bits
layout(std430, binding = 2) writeonly buffer Triangles { Out triangles[]; };
layout(push_constant) uniform Push { uint triangles_per_instance; } pc;

void main() {
  const uint slot = instance_id[0] * pc.triangles_per_instance + triangle_id[0];
  triangles[slot].v0 = vec4(world[0], uintBitsToFloat(instance_id[0]));
  triangles[slot].v1 = vec4(world[1], uintBitsToFloat(triangle_id[0]));
  triangles[slot].v2 = vec4(world[2], uintBitsToFloat(instance_id[2] << 16 | triangle_id[2]));
}
