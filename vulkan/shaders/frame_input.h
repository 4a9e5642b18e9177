// frame_input.h: what the passes of the paper's frame read besides the grid's tables (vulkan/
// frame.h): the frame's parameters, the materials and lights as shading reads them. Shared by
// the host (vulkan/frame.cpp) and the shaders (compat.h rules).
#ifndef GRIDRT_VULKAN_FRAME_INPUT_H
#define GRIDRT_VULKAN_FRAME_INPUT_H

#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/bounce.h"
#include "gridrt/common/shared/raster.h"
#include "gridrt/common/shared/records.h"
#include "gridrt/common/shared/shadow.h"

SH_BEGIN

// Feature bits of the frame passes (specialization constant kFrameFlags, vulkan/frame.cpp).
SH_CONST uint kFrameBounce = 1u;    // glossy materials: make and shade bounce rays
SH_CONST uint kFrameTextures = 2u;  // some material has a diffuse texture
SH_CONST uint kFrameAlpha = 4u;     // alpha keying: some material has a mask (and the grid keys them)
SH_CONST uint kFrameCompact = 8u;   // the bounce appends its real rays to a list; the trace takes only those
SH_CONST uint kFrameComputeGather = 16u;  // the gather's visibility by compute (gather_bin/tiles.comp), not raster
SH_CONST uint kFrameShadows = 32u;  // the scene has lights: shadow rays (shadow.comp), traced, shade by them
SH_CONST uint kFrameGatherBoxes = 64u;  // with kFrameComputeGather: every pixel of a triangle's 8x8 box tiles
                                        // (gather_tiles.comp), not the rasterizer (gather_raster.comp)

struct FrameParams {
  CameraParams camera;   // the primary rays' camera
  vec3 background;       // environment colour on a miss
  uint light_count;      // 0: a headlight at the eye
  float ambient;         // ShadeOptions::ambient
  float exposure;        // ShadeOptions::exposure
  float near_plane;      // the raster gather's near plane (camera space, world units)
  uint frame;            // the bounce's per-pixel sequence number
  uint material_count;   // entries of the material table
  uint pad0;
  uint pad1;
  uint pad2;
  RasterCamera raster;   // the rasterizer's camera constants (raster_camera: made once, by the host)
};

// The compute gather's list of large triangles (gather_bin.comp appends; gather_raster.comp, or
// gather_tiles.comp with kFrameGatherBoxes, reads): this header, then one GatherRasterTriangle per
// triangle. Its work items (32x32-pixel bins of the screen its box touches; with kFrameGatherBoxes
// 8x8-pixel tiles of its box) are numbered consecutively in list order.
struct GatherTileHeader {
  uint groups_x;    // VkDispatchIndirectCommand of the item pass: one workgroup per item
  uint groups_y;
  uint groups_z;
  uint tiles;       // items of the frame (written by the dispatch step)
  uint triangles;   // large triangles of the frame (written by the dispatch step)
  uint done;        // the bin pass's workgroups that finished (its last one runs the dispatch step)
  uint counter_lo;  // the append counter, 64 bits: items (low word) and triangles (high word),
  uint counter_hi;  // so one atomic gives a triangle both its list index and its first item
};

// A large triangle of the compute gather, set up once (common/shared/raster.h raster_setup).
struct GatherRasterTriangle {
  vec3 edge0;       // the edge functions over pixel indices (a, b, c: a x + b y + c)
  float t_lo;       // a lower bound of the ray test's t over the triangle (per-tile depth culling)
  vec3 edge1;
  uint ref;         // instance << 16 | triangle
  vec3 edge2;
  uint first;       // its first work item
  uint box_lo;      // screen box x0 | y0 << 16 (inclusive)
  uint box_hi;      // x1 | y1 << 16
  uint index;       // its index in the geometry buffer
  uint pad0;
  vec4 depth;       // the depth plane (raster_setup_depth): raster_tile_t_lo's bound over a tile
};

// The rasterizer's tile lists (gather_pairs.comp, gather_scan.comp, gather_fine.comp): per 8x8-pixel
// screen tile the large triangles that may cover it. This header, then `tiles` words of counts
// (the scatter counts them down to 0), `tiles` words of starts (a tile's list ends where the
// next one starts, the last at `pairs`), then the pairs' words (a triangle's index in the list of
// large triangles), `capacity` of them. With buckets (GatherFinePush.scatter 2): `tiles` words of
// counts (the pairs the tile was offered, its bucket filled up to `capacity`), then per tile its
// bucket of `capacity` words, then the pairs past their buckets (gather_past.comp), two words each
// (the tile, the triangle), `past_capacity` of them; the header's `pairs` counts those (the
// starting pass clears it), `overflow` is not written.
struct GatherFineHeader {
  uint items_x;     // VkDispatchIndirectCommand of the count and scatter passes: 64 work items
  uint items_y;     //   (32x32-pixel bins) per workgroup (written by the dispatch step)
  uint items_z;
  uint pairs;       // (tile, large triangle) pairs of the frame (written by the scan)
  uint overflow;    // 1: more pairs than the capacity; the item pass runs, and the fine pass (one
  uint pad0;        //   workgroup per screen tile, dispatched directly) reads no list: it only
  uint pad1;        //   resolves
  uint pad2;
};

// Push constants of gather_pairs.comp, gather_scan.comp and gather_fine.comp.
struct GatherFinePush {
  uint tiles;         // 8x8-pixel screen tiles
  uint capacity;      // pair words after the counts and starts; with buckets, a tile's bucket
  uint scatter;       // gather_pairs.comp: 0 counts the pairs, 1 writes them, 2 writes them to
                      // buckets of `capacity` words a tile (gather_fine.comp: 2 reads buckets)
  uint past_capacity; // with buckets: the pairs past their buckets the past pass can take
};

// Pixels of a side of the rasterizer's bins (its work items) and tiles (its depth culling).
SH_CONST uint kGatherBinSize = 32u;
SH_CONST uint kGatherTileSize = 8u;
// The scan of the tile lists' counts (gather_scan.comp): blocks of 4096 tiles, at most 64
// workgroups (each several consecutive blocks, after summing the counts before its first)
SH_CONST uint kGatherScanBlock = 4096u;
SH_CONST uint kGatherScanMaxGroups = 64u;

// A material as shading reads it.
struct FrameMaterial {
  vec3 diffuse;          // Material::diffuse
  float glossiness;      // Material::glossiness
  float cos_max;         // cone_cos_max(glossiness)
  uint texture_offset;   // first texel of the diffuse texture in the texel buffer (RGBA8 packed)
  uint texture_width;    // 0: no texture
  uint texture_height;
  uint alpha_offset;     // first texel of the alpha mask in the texel buffer (full resolution)
  uint alpha_width;      // 0: no mask
  uint alpha_height;
  uint pad0;
};

// A light; radiance = colour * intensity.
struct FrameLight {
  vec3 position;         // point light position, or the direction towards a directional light
  float directional;     // 1: directional, 0: point light (1/d^2 falloff)
  vec3 radiance;
  float pad0;
};

// Bindings of the frame passes' descriptor set (set 0; every one a storage buffer).
SH_CONST uint kFrameBindParams = 0u;
SH_CONST uint kFrameBindInstances = 1u;
SH_CONST uint kFrameBindTriangles = 2u;
SH_CONST uint kFrameBindUvs = 3u;
SH_CONST uint kFrameBindVisibility = 4u;
SH_CONST uint kFrameBindGather = 5u;
SH_CONST uint kFrameBindMaterials = 6u;
SH_CONST uint kFrameBindDiffuseTexels = 7u;
SH_CONST uint kFrameBindLights = 8u;
SH_CONST uint kFrameBindRays = 9u;
SH_CONST uint kFrameBindHits = 10u;
SH_CONST uint kFrameBindImage = 11u;
SH_CONST uint kFrameBindRayList = 12u;
SH_CONST uint kFrameBindGatherKeys = 13u;
SH_CONST uint kFrameBindTileList = 14u;
SH_CONST uint kFrameBindTileDepth = 15u;  // the rasterizer's per-tile depth bound (t bits)
SH_CONST uint kFrameBindPixelDirs = 16u;  // the rasterizer's camera_direction per pixel (vec4)
SH_CONST uint kFrameBindTileBins = 17u;  // the rasterizer's tile lists (GatherFineHeader, counts, starts, pairs)
SH_CONST uint kFrameBindPlanes = 18u;  // the grid's plane buffer (GridPlane per triangle)
SH_CONST uint kFrameBindingCount = 19u;
// Specialization-constant id of the frame passes' feature bits (kFrame* above); clear of the
// grid's ids (grid_interface.h), which the frame's trace pipeline also sets.
SH_CONST uint kFrameSpecFlags = 10u;

// Push constants of gather_bin.comp.
struct GatherBinPush {
  uint triangle_count;  // triangles of the geometry buffer
  uint instance_count;
  uint max_groups_x;    // the device's maxComputeWorkGroupCount[0] (the dispatch step's work lists)
  uint pad0;
};

// The frame's bounce ray of pixel (x, y) from its gather texel t, as common/gather.cpp's
// bounce_rays makes it (the same functions): the glossy direction about the texel's normal, from
// its position, leaving its launch triangle; the empty ray where the texel has no surface or its
// material has no gloss. `gloss` and `cos_max`: the texel's material's (FrameMaterial; 0 where
// the texel's material is outside the table). bounce.comp and the trace (trace.comp, the frame's
// bounce trace) both make the frame's bounce rays with it.
SH_INLINE RayRecord frame_bounce_ray(SH_IN(CameraParams) c, uint frame, SH_IN(GatherTexel) t, float gloss,
                                     float cos_max, uint x, uint y) {
  if (t.launch_ref == kNoRef || !(gloss > 0.0f)) return empty_shadow_ray();
  RayRecord r;
  r.org = t.position;
  r.tmin = 0.0f;
  r.dir = bounce_direction(camera_direction(c, x, y), t.normal, gloss, cos_max, pixel_random(x, y, frame));
  r.tmax = uintBitsToFloat(0x7F800000u);  // +inf
  r.launch_normal = t.normal;
  r.launch_ref = t.launch_ref;
  return r;
}

// The bounce rays sorted before their trace (ray_sort.comp; FrameOptions::sort_bits): a
// least-significant-digit radix sort of (key, pixel) pairs, a digit of 4 bits a pass, each pass a
// count of the digits per block of kRaySortBlock pairs, their scan, then their stable scatter. Only the order
// in which the trace takes the rays depends on it: each pixel's ray and hit stay the same.
SH_CONST uint kRaySortThreads = 256u;  // invocations of a workgroup
SH_CONST uint kRaySortItems = 8u;      // consecutive pairs an invocation takes
SH_CONST uint kRaySortBlock = 2048u;   // pairs a workgroup takes: kRaySortThreads * kRaySortItems
SH_CONST uint kRaySortDigits = 16u;    // values of a digit (4 bits)
SH_CONST uint kRaySortNoRay = 16u;     // the bucket after the digits': pixels without a ray (the first pass's)
SH_CONST uint kRaySortBuckets = 17u;   // a pass's buckets: the digits, then kRaySortNoRay
SH_CONST uint kRaySortSpecStage = 0u;  // specialization constant: 0, the count; 1, the scan; 2, the scatter
SH_CONST uint kRaySortLattice = 128u;  // the origin lattice's cells a side (7 bits an axis)
SH_CONST uint kRaySortBindRays = 0u;   // the frame's rays (the bounce rays first)
SH_CONST uint kRaySortBindKeysA = 1u;
SH_CONST uint kRaySortBindKeysB = 2u;
SH_CONST uint kRaySortBindListA = 3u;  // the ray list (WorkListHeader, then the pixels: A's values)
SH_CONST uint kRaySortBindValuesB = 4u;
SH_CONST uint kRaySortBindCounts = 5u;  // per bucket, per block: kRaySortBuckets x blocks, bucket-major; then the buckets' totals
SH_CONST uint kRaySortBindingCount = 6u;

struct RaySortPush {
  vec3 lattice_lo;     // the origin's lattice cell: (org - lattice_lo) * lattice_scale, per axis
  uint count;          // pairs (the image's pixels)
  vec3 lattice_scale;
  uint shift;          // the pass's digit: bits shift .. shift + 3 of the key
  uint blocks;         // blocks of kRaySortBlock pairs (workgroups of a pass)
  uint parity;         // 0: A to B; 1: B to A
  uint first_pass;     // the first pass: its count makes the keys from the rays and writes A's pairs, it
                       // takes every pixel (those without a ray last), its scan writes the rays' count
                       // into the ray list's header
  uint groups_x;       // workgroups in a row of the dispatch (it wraps into rows past the device's limit)
  uint max_groups_x;   // maxComputeWorkGroupCount[0]: the trace's dispatch over the ray list
};

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::RaySortPush) == 52, "layout of RaySortPush");
static_assert(gridrt::shared::kRaySortBlock == gridrt::shared::kRaySortThreads * gridrt::shared::kRaySortItems,
              "ray_sort.comp: a block is its workgroup's invocations' pairs");
static_assert(gridrt::shared::kRaySortBuckets == gridrt::shared::kRaySortNoRay + 1 &&
                  gridrt::shared::kRaySortDigits * gridrt::shared::kRaySortDigits == gridrt::shared::kRaySortThreads,
              "ray_sort.comp: the no-ray bucket after the digits; the count's runs of 16 entries a digit's row");
static_assert(gridrt::shared::kRaySortDigits * gridrt::shared::kRaySortThreads >= 2 * gridrt::shared::kRaySortBlock,
              "ray_sort.comp stages a block's keys and values in thread_counts' room");
static_assert(sizeof(gridrt::shared::FrameParams) == 160, "std430 layout of FrameParams");
static_assert(sizeof(gridrt::shared::FrameMaterial) == 48, "std430 layout of FrameMaterial");
static_assert(sizeof(gridrt::shared::FrameLight) == 32, "std430 layout of FrameLight");
static_assert(sizeof(gridrt::shared::GatherTileHeader) == 32, "std430 layout of GatherTileHeader");
static_assert(sizeof(gridrt::shared::GatherRasterTriangle) == 80, "std430 layout of GatherRasterTriangle");
static_assert(sizeof(gridrt::shared::GatherBinPush) == 16, "layout of GatherBinPush");
static_assert(sizeof(gridrt::shared::GatherFineHeader) == 32, "std430 layout of GatherFineHeader");
static_assert(sizeof(gridrt::shared::GatherFinePush) == 16, "layout of GatherFinePush");
#endif

#endif
