#version 460
// test_raster.vert, with test_raster.geom: the paper's raster-pass machinery for
// tests/test_vulkan_context.cpp. One draw per instance (firstInstance = instance id); the vertex
// shader transforms its vertex and passes the instance id (gl_InstanceIndex) and the triangle id
// (gl_VertexIndex / 3) down, flat.
#extension GL_GOOGLE_include_directive : require
#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/transform.h"

layout(std430, binding = 0) readonly buffer Positions { vec4 positions[]; };  // xyz, per vertex
layout(std430, binding = 1) readonly buffer Transforms { Affine transforms[]; };

layout(location = 0) out vec3 world;
layout(location = 1) flat out uint instance_id;
layout(location = 2) flat out uint triangle_id;

void main() {
  world = transform_point(transforms[gl_InstanceIndex], positions[gl_VertexIndex].xyz);
  instance_id = uint(gl_InstanceIndex);
  triangle_id = uint(gl_VertexIndex) / 3u;
  gl_Position = vec4(0.0);
}
