// grid_common.glsl: what every grid shader shares: the shared headers, the specialization
// constants, and the one descriptor set of the grid's buffers (ids and bindings: grid_interface.h).
#ifndef GRIDRT_GRID_COMMON_GLSL
#define GRIDRT_GRID_COMMON_GLSL

#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/records.h"
#include "gridrt/common/shared/transform.h"
#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/triangle.h"
#include "gridrt/common/shared/explain.h"
#include "gridrt/vulkan/shaders/build_input.h"
#include "gridrt/vulkan/shaders/grid_interface.h"

// Specialization constants: the values of GridParams that shape the code, so that unused paths
// (alpha keying, gap-fill, the other traversal or insertion) are not compiled in. The host sets
// them from the same GridParams it uploads (vulkan/grid.cpp, spec_for).
layout(constant_id = kGridSpecCapacity) const uint kCapacity = 4u;   // GridParams::capacity
layout(constant_id = kGridSpecInsertion) const uint kInsertion = 1u;  // GridParams::insertion
layout(constant_id = kGridSpecTraversal) const uint kTraversal = 0u;  // GridParams::traversal
layout(constant_id = kGridSpecFlags) const uint kFlags = 0u;      // GridParams::flags (kGrid* bits)
layout(constant_id = kGridSpecExplain) const bool kExplain = false; // trace: record the explain ray's events
layout(constant_id = kGridSpecRepeats) const uint kRepeats = 0u;    // GridParams::repeats
layout(constant_id = kGridSpecTriangleTest) const uint kTriangleTest = 0u; // GridParams::triangle_test

// A uniform buffer (std140 lays GridParams out as std430 does: no arrays, each vec3 followed by a
// scalar), so that a device may read its fields where they are used (NVIDIA: as constant-bank
// operands) instead of keeping them in registers through a loop.
layout(std140, binding = kGridBindParams) uniform ParamsBlock { GridParams params_buffer; };
layout(std430, binding = kGridBindInstances) readonly buffer Instances { GridInstance instances[]; };
layout(std430, binding = kGridBindTriangles) buffer Triangles { GridTriangle triangles[]; };
layout(std430, binding = kGridBindPlanes) buffer Planes { GridPlane planes[]; };
layout(std430, binding = kGridBindUvs) readonly buffer Uvs { GridTriangleUv uvs[]; };
layout(std430, binding = kGridBindMaterials) readonly buffer Materials { GridMaterial materials[]; };
layout(std430, binding = kGridBindTexels) readonly buffer Texels { uint texels[]; };
layout(std430, binding = kGridBindBuildInstances) readonly buffer BuildInstances { BuildInstance build_instances[]; };
layout(std430, binding = kGridBindPositions) readonly buffer Positions { vec4 positions[]; };
layout(std430, binding = kGridBindIndices) readonly buffer Indices { uint indices[]; };

// The grid's parameters with the specialized fields constant.
GridParams grid_params() {
  GridParams g = params_buffer;
  g.capacity = kCapacity;
  g.insertion = kInsertion;
  g.traversal = kTraversal;
  g.flags = kFlags;
  g.repeats = kRepeats;
  g.triangle_test = kTriangleTest;
  return g;
}

// World-space vertex `corner` (0..2) of `triangle` of `instance`: the mesh vertex through the
// instance's transform (shared::transform_point, as the reference).
vec3 world_vertex(uint instance, uint triangle, uint corner) {
  const uint index = indices[build_instances[instance].index_offset + 3u * triangle + corner];
  const vec3 p = positions[build_instances[instance].vertex_offset + index].xyz;
  return transform_point(build_instances[instance].transform, p);
}

#endif
