#version 460
// build.geom: the geometry shader of the raster build (paper 2.1): one invocation per triangle
// does the build step (build.glsl) and emits nothing; rasterization is discarded. A triangle whose
// AABB range holds more than kBuildRun cells hands them out in runs to build_cells.comp, as the
// compute build does: one invocation walking thousands of cells is cut short by lavapipe's loop
// limit (docs/VULKAN.md, "The raster build on lavapipe").
#extension GL_GOOGLE_include_directive : require
#include "build.glsl"

layout(triangles) in;
layout(points, max_vertices = 1) out;

layout(location = 0) in vec3 world[];
layout(location = 1) flat in uint instance_id[];
layout(location = 2) flat in uint triangle_id[];

void main() { build_invocation(instance_id[0], triangle_id[0], world[0], world[1], world[2], true); }
