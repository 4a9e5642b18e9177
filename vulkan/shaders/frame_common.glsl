// frame_common.glsl: the descriptor set of the frame passes (bindings: frame_input.h):
// the grid's instances, geometry buffer and uvs, and the frame's own buffers.
#ifndef GRIDRT_FRAME_COMMON_GLSL
#define GRIDRT_FRAME_COMMON_GLSL

#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/records.h"
#include "gridrt/common/shared/transform.h"
#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/triangle.h"
#include "gridrt/common/shared/bounce.h"
#include "gridrt/common/shared/shadow.h"
#include "gridrt/common/shared/worklist.h"
#include "gridrt/vulkan/shaders/frame_input.h"

layout(constant_id = kFrameSpecFlags) const uint kFrameFlags = 3u;  // kFrame* bits

layout(std430, binding = kFrameBindParams) readonly buffer ParamsBuffer { FrameParams fp; };
layout(std430, binding = kFrameBindInstances) readonly buffer Instances { GridInstance instances[]; };
layout(std430, binding = kFrameBindTriangles) readonly buffer Triangles { GridTriangle triangles[]; };
layout(std430, binding = kFrameBindUvs) readonly buffer Uvs { GridTriangleUv uvs[]; };
layout(std430, binding = kFrameBindVisibility) buffer Visibility { uint visibility[]; };  // launch ref per pixel
layout(std430, binding = kFrameBindGather) buffer Gather { GatherTexel gather[]; };
layout(std430, binding = kFrameBindMaterials) readonly buffer Materials { FrameMaterial fmaterials[]; };
layout(std430, binding = kFrameBindDiffuseTexels) readonly buffer DiffuseTexels { uint diffuse_texels[]; };
layout(std430, binding = kFrameBindLights) readonly buffer Lights { FrameLight lights[]; };
layout(std430, binding = kFrameBindRays) buffer Rays { RayRecord rays[]; };
layout(std430, binding = kFrameBindHits) buffer Hits { HitRecord hits[]; };
layout(std430, binding = kFrameBindImage) buffer Image { uint image[]; };  // RGBA8, sRGB-encoded
// The compacted bounce rays: a work list of the indices of the pixels with a bounce ray
layout(std430, binding = kFrameBindRayList) buffer RayList {
  WorkListHeader ray_list_header;
  uint ray_list[];
};
// The compute gather: per pixel a 64-bit key (t bits << 32 | reference), words low then high
// (gather_tiles.comp declares the same buffer as uint64_t for its atomic min)
layout(std430, binding = kFrameBindGatherKeys) buffer GatherKeys { uint gather_keys[]; };
// The compute gather's large triangles (GatherTileHeader, then their set-up records)
layout(std430, binding = kFrameBindTileList) buffer TileList {
  GatherTileHeader tile_header;
  GatherRasterTriangle tile_tris[];
};
// The rasterizer's depth bound per 8x8-pixel tile: t bits no pixel of the tile is above
layout(std430, binding = kFrameBindTileDepth) buffer TileDepth { uint tile_depth[]; };
// The rasterizer's pixel ray directions (camera_direction, once per pixel and frame; w unused)
layout(std430, binding = kFrameBindPixelDirs) buffer PixelDirs { vec4 pixel_dirs[]; };
// The rasterizer's tile lists (GatherFineHeader): counts (then cursors, then ends), starts, pairs
layout(std430, binding = kFrameBindTileBins) buffer TileBins {
  GatherFineHeader fine_header;
  uint tile_words[];
};

#endif
