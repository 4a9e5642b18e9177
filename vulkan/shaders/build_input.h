// build_input.h: what the Vulkan build passes read besides the grid's own tables (common/shared/
// grid.h): the object-space meshes and, per instance, its transform at the frame's time. Shared
// by the host (vulkan/grid.cpp) and the shaders (compat.h rules).
#ifndef GRIDRT_VULKAN_BUILD_INPUT_H
#define GRIDRT_VULKAN_BUILD_INPUT_H

#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/transform.h"

SH_BEGIN

// One instance as the build reads it (std430, storage buffer).
struct BuildInstance {
  Affine transform;    // object to world at the frame's time (shared::to_affine)
  uint vertex_offset;  // first vertex of its mesh in the positions buffer
  uint index_offset;   // first index of its mesh in the indices buffer (3 per triangle)
  uint tri_offset;     // its triangle 0 in the geometry buffer (GridInstance::tri_offset)
  uint tri_count;      // triangles of its mesh
};

// Push constants of the build passes (raster and compute alike).
struct BuildPush {
  uint first_instance;  // instances [first_instance, last_instance) are inserted
  uint last_instance;
  uint tri_begin;       // compute: geometry-buffer index of invocation 0
  uint tri_count;       // compute: invocations of this dispatch
  uint groups;          // compute: workgroups of all the pass's dispatches (its last one writes the runs' dispatch)
  uint max_groups_x;    // compute: maxComputeWorkGroupCount[0]
  uint pad0;
  uint pad1;
};

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::BuildInstance) == 64, "std430 layout of BuildInstance");
static_assert(sizeof(gridrt::shared::BuildPush) == 32, "layout of BuildPush");
#endif

#endif
