// rtx_input.h: what the ray tracing pipeline's shaders (rtx.rgen, rtx.rchit, rtx.rahit,
// rtx.rmiss) share with the host (vulkan/rtx.cpp): the push constants and the ray payload.
// compat.h rules.
#ifndef GRIDRT_VULKAN_RTX_INPUT_H
#define GRIDRT_VULKAN_RTX_INPUT_H

#include "gridrt/common/shared/compat.h"

SH_BEGIN

// RtxPush::mode bits
SH_CONST uint kRtxExcludeLaunchRef = 1u;  // never report the ray's launch triangle (kGridExcludeLaunchRef)
SH_CONST uint kRtxAlphaKeying = 2u;       // alpha-keyed instances cut holes (kGridAlphaKeying)
SH_CONST uint kRtxAnyHitAll = 4u;         // every triangle through the any-hit shader (ray flag NoOpaque)

// Traces of one ray at most: the first, and again past the launch triangle where opaque
// geometry reported it (rtx.rgen).
SH_CONST uint kRtxMaxTraces = 4u;

// Push constants of the ray tracing pipeline (every stage).
struct RtxPush {
  uint ray_offset;        // index of launch 0's ray in the ray and hit buffers
  uint ray_count;         // rays of this launch
  uint mode;              // kRtx* bits
  float cell_size;        // GridParams::cell_size: the self-hit offset's unit
  float self_hit_offset;  // GridParams::self_hit_offset: hits need t |dir| > this many cells
  uint pad0;
  uint pad1;
  uint pad2;
};

// The ray payload: what the closest-hit shader reports, and what the any-hit shader reads.
struct RtxPayload {
  float t;          // gl_HitTEXT of the closest hit
  uint ref;         // (instance << 16) | triangle of the closest hit, kNoRef on a miss
  float u;          // the hardware's barycentric weight of vertex 1
  float v;          // ... of vertex 2
  uint launch_ref;  // the launch triangle the any-hit shader ignores (kNoRef: none)
};

// Bindings of the ray tracing shaders' descriptor set (set 0).
SH_CONST uint kRtxBindTlas = 0u;
SH_CONST uint kRtxBindRays = 1u;
SH_CONST uint kRtxBindHits = 2u;
SH_CONST uint kRtxBindInstances = 3u;
SH_CONST uint kRtxBindTriangles = 4u;
SH_CONST uint kRtxBindUvs = 5u;
SH_CONST uint kRtxBindMaterials = 6u;
SH_CONST uint kRtxBindTexels = 7u;

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::RtxPush) == 32, "layout of RtxPush");
#endif

#endif
