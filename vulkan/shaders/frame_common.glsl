// frame_common.glsl: the descriptor set of the frame passes (vulkan/frame.cpp, FrameBinding):
// the grid's instances, geometry buffer and uvs, and the frame's own buffers.
#ifndef GRIDRT_FRAME_COMMON_GLSL
#define GRIDRT_FRAME_COMMON_GLSL

#include "common/shared/compat.h"
#include "common/shared/records.h"
#include "common/shared/transform.h"
#include "common/shared/alpha.h"
#include "common/shared/grid.h"
#include "common/shared/triangle.h"
#include "common/shared/bounce.h"
#include "vulkan/shaders/frame_input.h"

layout(constant_id = 10) const uint kFrameFlags = 3u;  // kFrame* bits

layout(std430, binding = 0) readonly buffer ParamsBuffer { FrameParams fp; };
layout(std430, binding = 1) readonly buffer Instances { GridInstance instances[]; };
layout(std430, binding = 2) readonly buffer Triangles { GridTriangle triangles[]; };
layout(std430, binding = 3) readonly buffer Uvs { GridTriangleUv uvs[]; };
layout(std430, binding = 4) buffer Visibility { uint visibility[]; };  // launch ref per pixel
layout(std430, binding = 5) buffer Gather { GatherTexel gather[]; };
layout(std430, binding = 6) readonly buffer Materials { FrameMaterial fmaterials[]; };
layout(std430, binding = 7) readonly buffer DiffuseTexels { uint diffuse_texels[]; };
layout(std430, binding = 8) readonly buffer Lights { FrameLight lights[]; };
layout(std430, binding = 9) buffer Rays { RayRecord rays[]; };
layout(std430, binding = 10) buffer Hits { HitRecord hits[]; };
layout(std430, binding = 11) buffer Image { uint image[]; };  // RGBA8, sRGB-encoded

#endif
