// grid_interface.h: the interface between the Vulkan grid's host code (vulkan/grid.cpp) and its
// shaders (grid_common.glsl, build.glsl, trace.comp, spill_order.comp, ...): the bindings of the
// one descriptor set, the specialization-constant ids, the push constants and the explain
// buffer's header. The host builds its descriptor layout and specialization from these names and
// the shaders declare their layouts with them, so that the two sides cannot disagree. compat.h
// rules (C++ and GLSL).
#ifndef GRIDRT_VULKAN_GRID_INTERFACE_H
#define GRIDRT_VULKAN_GRID_INTERFACE_H

#include "gridrt/common/shared/compat.h"

SH_BEGIN

// Bindings of the grid's descriptor set (set 0). Every one is a storage buffer but the image and
// the parameters (a uniform buffer).
SH_CONST uint kGridBindParams = 0u;          // GridParams (uniform buffer, std140)
SH_CONST uint kGridBindImage = 1u;           // the 3D image of references (r32ui storage image)
SH_CONST uint kGridBindInstances = 2u;       // GridInstance[]
SH_CONST uint kGridBindTriangles = 3u;       // GridTriangle[] (the geometry buffer)
SH_CONST uint kGridBindUvs = 4u;             // GridTriangleUv[]
SH_CONST uint kGridBindMaterials = 5u;       // GridMaterial[]
SH_CONST uint kGridBindTexels = 6u;          // alpha masks, RGBA8 packed
SH_CONST uint kGridBindBuildInstances = 7u;  // BuildInstance[] (build_input.h)
SH_CONST uint kGridBindPositions = 8u;       // object-space vertices (vec4)
SH_CONST uint kGridBindIndices = 9u;         // 3 indices per triangle
SH_CONST uint kGridBindRays = 10u;           // RayRecord[]
SH_CONST uint kGridBindHits = 11u;           // HitRecord[]
SH_CONST uint kGridBindExplain = 12u;        // explain header, then ExplainEvent[]
SH_CONST uint kGridBindDirty = 13u;          // the dirty-cell list (shared::dirty_list_words)
SH_CONST uint kGridBindRayList = 14u;        // WorkListHeader, then ray indices (worklist.h)
SH_CONST uint kGridBindBuildList = 15u;      // the compute build's runs of cells (build.glsl)
SH_CONST uint kGridBindSpill = 16u;          // SpillHeader, then SpillEntry[]
SH_CONST uint kGridBindSpillHeads = 17u;     // four heads per cell
SH_CONST uint kGridBindSkip = 18u;           // the skip field (shared::skip_words; kGridSkipEmpty)
SH_CONST uint kGridBindSkipTable = 19u;      // its summed-volume table (the build only)
// The compact layout (kGridCompact; docs/SPEC.md "Compact layout"); 16-byte stand-ins otherwise
SH_CONST uint kGridBindOffsets = 20u;        // cells + 1 offsets into the references
SH_CONST uint kGridBindRefs = 21u;           // the static references, ordered per cell
SH_CONST uint kGridBindCompactCounts = 22u;  // the build only: per cell its count, then its cursor
SH_CONST uint kGridBindCompactPairs = 23u;   // the build only: the pair count (4 words), (cell, ref) pairs
SH_CONST uint kGridBindCompactScattered = 24u;  // the build only: the references as scattered
SH_CONST uint kGridBindCompactBlocks = 25u;  // the build only: the scan's block sums, then offsets
// The frame's traces that make their rays (kGridSpecTraceRays; 256-byte stand-ins otherwise)
SH_CONST uint kGridBindGather = 26u;          // GatherTexel[] (common/shared/bounce.h)
SH_CONST uint kGridBindFrameParams = 27u;     // FrameParams (vulkan/shaders/frame_input.h)
SH_CONST uint kGridBindFrameMaterials = 28u;  // FrameMaterial[]
SH_CONST uint kGridBindPlanes = 29u;         // GridPlane[] (the plane buffer: one per triangle)
SH_CONST uint kGridBindingCount = 30u;

// Specialization-constant ids of the grid's shaders: the GridParams fields that shape the code.
SH_CONST uint kGridSpecCapacity = 0u;      // GridParams::capacity
SH_CONST uint kGridSpecInsertion = 1u;     // GridParams::insertion
SH_CONST uint kGridSpecTraversal = 2u;     // GridParams::traversal
SH_CONST uint kGridSpecFlags = 3u;         // GridParams::flags (kGrid* bits)
SH_CONST uint kGridSpecExplain = 4u;       // trace: record the explain ray's events
SH_CONST uint kGridSpecRepeats = 5u;       // GridParams::repeats
SH_CONST uint kGridSpecTriangleTest = 6u;  // GridParams::triangle_test
SH_CONST uint kGridSpecTraceList = 7u;     // trace: rays from the ray list (dispatched indirectly)
SH_CONST uint kGridSpecTraceMode = 8u;     // trace: which hit, kTraceClosestHit or kTraceAnyHit (shared/grid.h)
SH_CONST uint kGridSpecTraceRays = 9u;     // trace: where an image's rays come from (kTraceRays*)
SH_CONST uint kGridSpecOrderShared = 10u;   // spill_order.comp: entries its shared copy holds (from maxComputeSharedMemorySize)
SH_CONST uint kGridSpecLoopGuard = 11u;     // trace: on llvmpipe, flag rays whose loops near its limit (kHitLoopSpent)

// llvmpipe, Mesa's CPU driver, ends every loop of a shader invocation once its loops have run
// 65,535 iterations in all, and says nothing (vulkan/grid.h). The trace estimates a ray's
// iterations from what it did: tests, references the mailbox skipped (each a pass of the reference
// loop and the mailbox's compare, counted as dear as a test) and cells (per layout, measured on
// Mesa 22.3, vulkan/grid.h), and on llvmpipe (kGridSpecLoopGuard) sets kHitLoopSpent in the hit
// record of a ray whose estimate reaches kLlvmpipeLoopBudget (3/4 of the limit). The host refuses a
// trace where any ray carries it (check_loop_limit). The reference never sets the bit: it exists
// only where the port cannot be trusted. Counts are clamped at 2^16 so that the sum fits 32 bits.
SH_CONST uint kHitLoopSpent = 0x80000000u;
SH_CONST uint kLlvmpipeLoopBudget = 49152u;
SH_CONST uint kLlvmpipeIterationsPerCell = 14u;
// The exact traversal's loop iterations per test (the paper's: 1.5 per test or cell, below)
SH_INLINE uint llvmpipe_iterations_per_test(bool compact, bool mailbox) {
  return compact ? (mailbox ? 22u : 14u) : (mailbox ? 10u : 2u);
}
SH_INLINE uint llvmpipe_loop_estimate(bool exact, bool compact, bool mailbox, uint tests, uint skips, uint cells) {
  const uint t = min(tests, 65536u), s = min(skips, 65536u), c = min(cells, 65536u);
  // The paper traversal's segments and slots: 1.5 (tests + cells), refused from 32,768 of them
  if (!exact) return (3u * (t + s + c)) / 2u;
  return llvmpipe_iterations_per_test(compact, mailbox) * (t + s) + kLlvmpipeIterationsPerCell * c;
}

// Where the trace's rays come from (kGridSpecTraceRays): the ray buffer, or (the frame's traces,
// an image's rays in tiles) made by the trace from each pixel's gather texel, as the frame's passes
// would make them, and written to the ray buffer before their trace.
SH_CONST uint kTraceRaysBuffer = 0u;  // read from the ray buffer
SH_CONST uint kTraceRaysBounce = 1u;  // the glossy bounce ray (common/shared/bounce.h, as bounce.comp)
SH_CONST uint kTraceRaysShadow = 2u;  // the shadow ray towards TracePush's light (common/shared/shadow.h)
// Both in one dispatch: workgroups of z = 0 trace the bounce rays (rays 0.., closest hit), those of
// z = 1 the shadow rays towards TracePush's light (rays ray_offset.., any hit)
SH_CONST uint kTraceRaysBoth = 3u;

// Push constants of trace.comp.
struct TracePush {
  uint ray_offset;        // index of invocation 0's ray
  uint ray_count;         // rays of this dispatch
  uint explain_ray;       // the ray whose events are recorded (kNoExplain: none)
  uint explain_capacity;  // events the explain buffer holds
  // Rays of an image, a workgroup per 8x8 pixel tile (0: a row of 64 rays a workgroup): the
  // dispatch's workgroup (x, y) traces the rays ray_offset + y * tiled_width + x of its tile
  uint tiled_width;
  uint tiled_height;
  // The light of a shadow trace that makes its rays (kTraceRaysShadow, tiled only): the
  // point light's position or the direction towards a directional light, as shadow_ray takes it
  float light_x;
  float light_y;
  float light_z;
  uint light_directional;  // 1: directional, 0: point light
};
SH_CONST uint kNoExplain = 0xFFFFFFFFu;

// Push constants of clear_dynamic.comp.
struct ClearPush {
  uint comparison_offset;  // GridParams::comparison_offset: references >= it are dynamic
};

// Push constants of spill_order.comp.
struct SpillOrderPush {
  uint dynamic;  // 0: order the static entries, 1: the dynamic ones
};

// Push constants of compact.comp.
struct CompactPush {
  uint pass;  // 0 block sums, 1 the blocks' scan, 2 offsets and cursors, 3 scatter, 4 order
};

// Push constants of skip_field.comp.
struct SkipFieldPush {
  uint pass;  // 0-2: the summed-volume table along z, y, x; 3: the bricks' distances; 4: the cells'
};

// The explain buffer: this header, then the events.
struct ExplainHeader {
  uint count;  // events written (may exceed the capacity: then the tail is lost)
  uint pad0;
  uint pad1;
  uint pad2;
};

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::TracePush) == 40, "layout of TracePush");
static_assert(sizeof(gridrt::shared::ClearPush) == 4, "layout of ClearPush");
static_assert(sizeof(gridrt::shared::SpillOrderPush) == 4, "layout of SpillOrderPush");
static_assert(sizeof(gridrt::shared::SkipFieldPush) == 4, "layout of SkipFieldPush");
static_assert(sizeof(gridrt::shared::CompactPush) == 4, "layout of CompactPush");
static_assert(sizeof(gridrt::shared::ExplainHeader) == 16, "std430 layout of ExplainHeader");
#endif

#endif
