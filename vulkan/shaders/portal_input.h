// portal_input.h: what the Vulkan portal passes read besides the three textures (atlas, div info,
// start map): the world's mapping and sizes, the renderer's camera, lights and options, the wall
// materials, one pixel's state between the separate loops, and the explain events. Shared by the
// host (vulkan/portal.cpp) and the shaders (compat.h rules).
#ifndef GRIDRT_VULKAN_PORTAL_INPUT_H
#define GRIDRT_VULKAN_PORTAL_INPUT_H

#include "gridrt/common/shared/compat.h"

SH_BEGIN

// The packed portal's scalars (reference/portal/build.h, PackedPortal).
struct PortalParams {
  vec3 origin;          // world position of voxel corner (0, 0, 0)
  float inv_voxel_size; // 1.0f / voxel_size, computed on the host as to_voxel_ray does
  uvec3 dims;           // voxels per axis
  uint div_count;       // stored divs (div 0 is the exterior div)
  uint atlas_width;     // texels per atlas row
  uint info_width;      // texels per div-info row (a multiple of 8)
  uint levels;          // mip-mapped space: levels (1: none)
  float mip_distance;   // the level rule's distance (fine voxels)
  // Instanced subspaces (PackedPortal): scale_log2 0 for none; top_divs = div_count then.
  uint scale_log2;      // fine voxels per tile edge: 2^scale_log2
  uint instance_base;   // material of block 0's instances
  uint blocks;          // blocks
  uint top_divs;        // divs of the top level (block divs follow)
  uint block_start;     // atlas texel (row-major) of block 0's start map
  uint pad0;
  uint pad1;
  uint pad2;
};

// The renderer's constants (reference/portal/render.cpp: Context and RenderOptions).
struct PortalRenderParams {
  vec3 eye;             // camera position (world space)
  float tan_half_fov;   // CameraFrame::tan_half_fov
  vec3 right;           // CameraFrame::right
  uint width;           // image width
  vec3 up;              // CameraFrame::up
  uint height;          // image height
  vec3 forward;         // CameraFrame::forward
  float ambient;        // RenderOptions::ambient
  vec3 light0;          // voxel-space position of the first light
  uint max_interfaces;  // RenderOptions::max_interfaces
  vec3 light1;          // voxel-space position of the second light
  uint refraction;      // RenderOptions::refraction (0 or 1)
  vec3 background;      // RenderOptions::background
  uint open_outside;    // World::open_outside (0 or 1): a shadow ray leaving the world reaches its light
};

// A wall material as the renderer reads it (WallMaterial).
struct PortalMaterial {
  vec3 color;   // albedo
  float ior;    // index of refraction (glass)
  vec3 glass_filter;  // colour filter per unit length inside the glass (`filter` is reserved in GLSL)
  uint glass;   // 1 for glass
  float coverage;  // mip-mapped space: the coarse material's opacity (1 for the world's own)
  uint resolve;    // 1: an opaque coarse voxel, resolved at full resolution
  uint pad0;
  uint pad1;
};

// One pixel between passes (reference/portal/render.cpp, PixelState), and its result.
struct PortalPixel {
  vec3 org;          // the current ray (voxel space)
  float tmin;
  vec3 dir;
  float tmax;
  vec3 filter_acc;   // accumulated colour filter (glass)
  uint mode;         // 0 primary, 1 shadow A, 2 shadow B, 3 done
  vec3 glass_entry;  // where the ray entered the glass it is in
  uint div;          // the current div
  vec3 point;        // the primary hit
  uint interfaces;   // glass surfaces crossed or reflected from
  vec3 normal;       // its normal
  uint in_glass;     // 1 inside glass
  vec3 albedo;       // its material colour
  uint glass;        // the material of the glass the ray is in
  vec3 color;        // the pixel's linear RGB once mode is 3
  float light;       // sum over lights of visible * N.L
  uint hit_div;      // the div the primary ray ended in
  uint steps_primary;
  uint steps_shadow;
  uint iterations;
  uint refractions;
  uint reflections;
  uint shadow_rays;
  uint cut;          // 1: its rays ran past portal_pixel_iteration_limit, ended as background
  vec3 mip_acc;      // mip-mapped space: light of the translucent coarse voxels passed
  uint pad1;
  ivec3 tile;        // instanced subspaces: the instance tile of the current block div
  uint pad2;
  ivec3 hit_tile;    // the tile of hit_div
  uint pad3;
};

// One explain event of the traced ray: the start, then one per div visited.
struct PortalExplainEvent {
  uint kind;     // 0 start, 1 step, 2 mip: a coarser level (div = level, voxel = coarse voxel, texel = its
                 // start texel), 3 mip: a coarse wall met (div = level, voxel = coarse voxel, texel = material),
                 // 4 enter instance (div = block, face = tile x | y << 8 | z << 16, voxel = fine voxel, texel =
                 // block start texel), 5 leave instance (voxel = the tile beyond, texel = its start texel;
                 // step 1: beyond the world)
  uint div;      // start: the start div (or wall texel); step: the div left
  uint face;     // step: the face left by (exterior: entered by)
  uint texel;    // the texel read (start: the start-map texel)
  ivec3 voxel;   // start: the start voxel; step: the crossing voxel
  uint step;     // step kind (reference StepKind: 0 next, 1 wall, 2 outside, 3 tmax, 4 none)
  uvec2 texel_uv;// step: atlas coordinates read
  float num;     // step: the plane's distance ahead
  float ad;      // step: |dir[axis]|
};

// Bindings of every portal pass's descriptor set (set 0).
SH_CONST uint kPortalBindAtlas = 0u;  // R16_UINT 2D, sampled
SH_CONST uint kPortalBindInfo = 1u;  // RGBA8_UINT 2D, sampled
SH_CONST uint kPortalBindStart = 2u;  // R16_UINT 3D, sampled
SH_CONST uint kPortalBindParams = 3u;  // PortalParams
SH_CONST uint kPortalBindRays = 4u;  // RayRecord[]
SH_CONST uint kPortalBindHits = 5u;  // HitRecord[]
SH_CONST uint kPortalBindExplain = 6u;  // count + PortalExplainEvent[]
SH_CONST uint kPortalBindRenderParams = 7u;  // PortalRenderParams
SH_CONST uint kPortalBindMaterials = 8u;  // PortalMaterial[]
SH_CONST uint kPortalBindPixels = 9u;  // PortalPixel[]
// Specialization-constant id: portal_trace records the explain ray's events.
SH_CONST uint kPortalSpecExplain = 0u;

// Push constants of portal_trace.comp.
struct PortalTracePush {
  uint ray_offset;        // index of invocation 0's ray
  uint ray_count;         // rays of this dispatch
  uint explain_ray;       // the ray whose events are recorded (kPortalNoExplain: none)
  uint explain_capacity;  // events the explain buffer holds
};
SH_CONST uint kPortalNoExplain = 0xFFFFFFFFu;

// Push constants of portal_render.comp.
struct PortalRenderPush {
  uint pass;  // 0: state machine; 1, 2, 3: the separate loops (primary, shadow A, shadow B)
};

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::PortalParams) == 80, "std430 layout of PortalParams");
static_assert(sizeof(gridrt::shared::PortalRenderParams) == 112, "std430 layout of PortalRenderParams");
static_assert(sizeof(gridrt::shared::PortalMaterial) == 48, "std430 layout of PortalMaterial");
static_assert(sizeof(gridrt::shared::PortalPixel) == 208, "std430 layout of PortalPixel");
static_assert(sizeof(gridrt::shared::PortalExplainEvent) == 48, "std430 layout of PortalExplainEvent");
static_assert(sizeof(gridrt::shared::PortalTracePush) == 16, "layout of PortalTracePush");
static_assert(sizeof(gridrt::shared::PortalRenderPush) == 4, "layout of PortalRenderPush");
#endif

#endif
