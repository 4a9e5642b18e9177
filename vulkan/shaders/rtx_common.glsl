// rtx_common.glsl: what the ray tracing shaders share: the shared headers, the push constants and
// the one descriptor set (bindings: rtx_input.h): the top-level acceleration structure, the
// frame's rays and the second hit buffer, and the grid's own tables (instances, the world-space
// geometry buffer the BLASes are built over, uvs, materials and alpha-mask texels).
#ifndef GRIDRT_RTX_COMMON_GLSL
#define GRIDRT_RTX_COMMON_GLSL

#extension GL_EXT_ray_tracing : require

#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/records.h"
#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/triangle.h"
#include "gridrt/vulkan/shaders/rtx_input.h"

layout(binding = kRtxBindTlas) uniform accelerationStructureEXT tlas;
layout(std430, binding = kRtxBindRays) readonly buffer Rays { RayRecord rays[]; };
layout(std430, binding = kRtxBindHits) writeonly buffer Hits { HitRecord hits[]; };
layout(std430, binding = kRtxBindInstances) readonly buffer Instances { GridInstance instances[]; };
layout(std430, binding = kRtxBindTriangles) readonly buffer Triangles { GridTriangle triangles[]; };
layout(std430, binding = kRtxBindUvs) readonly buffer Uvs { GridTriangleUv uvs[]; };
layout(std430, binding = kRtxBindMaterials) readonly buffer Materials { GridMaterial materials[]; };
layout(std430, binding = kRtxBindTexels) readonly buffer Texels { uint texels[]; };

layout(push_constant) uniform Push { RtxPush pc; };

#endif
