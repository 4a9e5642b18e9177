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

// After the parameters, the camera's per-column and per-row steps (camera_step_x of columns
// 0..width-1, then camera_step_y of rows 0..height-1), made by the host with the same functions
layout(std430, binding = kFrameBindParams) readonly buffer ParamsBuffer {
  FrameParams fp;
  float camera_steps[];
};
layout(std430, binding = kFrameBindInstances) readonly buffer Instances { GridInstance instances[]; };
layout(std430, binding = kFrameBindTriangles) readonly buffer Triangles { GridTriangle triangles[]; };
layout(std430, binding = kFrameBindPlanes) readonly buffer Planes { GridPlane planes[]; };
layout(std430, binding = kFrameBindUvs) readonly buffer Uvs { GridTriangleUv uvs[]; };
layout(std430, binding = kFrameBindVisibility) buffer Visibility { uint visibility[]; };  // launch ref per pixel
layout(std430, binding = kFrameBindGather) buffer Gather { GatherTexel gather[]; };
// The gather texels as 16-byte words (record_words.glsl): load_gather, store_gather below
layout(std430, binding = kFrameBindGather) buffer GatherWords { uvec4 gather_words[]; };
#include "record_words.glsl"

GatherTexel load_gather(uint p) {
  return gather_from_words(gather_words[3u * p], gather_words[3u * p + 1u], gather_words[3u * p + 2u]);
}

void store_gather(uint p, GatherTexel g) {
  uvec4 w0, w1, w2;
  gather_to_words(g, w0, w1, w2);
  gather_words[3u * p] = w0;
  gather_words[3u * p + 1u] = w1;
  gather_words[3u * p + 2u] = w2;
}
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
// The rasterizer's tile lists (GatherFineHeader): counts (the scatter counts them down), starts, pairs
layout(std430, binding = kFrameBindTileBins) buffer TileBins {
  GatherFineHeader fine_header;
  uint tile_words[];
};

// The gather's ray test of a camera ray (origin the eye, interval (tmin, inf), no surface rule):
// the watertight test, whatever the trace's, as the CPU's gather traces it (plan::gather_options):
// no camera ray passes between two triangles of a closed mesh, as no pixel passes between them in
// the paper's raster pass. `k`: the triangle's index in the geometry buffer, whose plane the test
// reads from the plane buffer (watertight_rest_plane).
uint gather_ray_test(vec3 dir, GridTriangle tri, uint k, float tmin, out TriangleTest r) {
  WatertightEdges e;
  watertight_edges(fp.camera.eye, watertight_ray(dir), tri.v0, tri.v1, tri.v2, e);
  return watertight_rest_plane(fp.camera.eye, dir, tri.v1, tri.v2, e, planes[k], tmin, sh_infinity(), sh_infinity(),
                               -1.0f, r);
}
// Its code alone (triangle_test_code): it stops after the edge functions where their signs are
// mixed (`r` then undefined), and reads the plane only where it goes on. `weights_det`: what the
// test's weights r.u_det and r.v_det are scaled by, |U + V + W| (test_barycentrics), so that the
// alpha key takes the test's own weights without making the edge functions again.
uint gather_ray_code(vec3 dir, GridTriangle tri, uint k, float tmin, out TriangleTest r, out float weights_det) {
  WatertightEdges e;
  watertight_edges(fp.camera.eye, watertight_ray(dir), tri.v0, tri.v1, tri.v2, e);
  weights_det = abs(e.det);
  if (watertight_mixed(e)) return watertight_outside_code(e);
  return watertight_rest_plane(fp.camera.eye, dir, tri.v1, tri.v2, e, planes[k], tmin, sh_infinity(), sh_infinity(),
                               -1.0f, r);
}

// The gather texel of a pixel whose camera ray (direction `dir`: camera_direction) meets `ref`, its
// visible triangle (kNoRef: none), at `t`: the t of the gather's ray test (gather_ray_test), so
// position, normal, uv and material are computed exactly as common/gather.cpp computes them from a
// traced primary hit (make_gather). The compute gather's key carries that t (its high word: the
// test that gave the key made it, and a test's t does not depend on its interval, which decides
// only whether it accepts), so its resolve does not test the triangle again.
GatherTexel gather_texel_at(uint ref, vec3 dir, float t) {
  const CameraParams c = fp.camera;
  GatherTexel g = GatherTexel(vec3(0.0f), 0xFFFFFFFFu, vec3(0.0f), kNoRef, vec2(0.0f), 0.0f, 0u);
  if (ref == kNoRef) return g;
  const uint k = instances[ref_instance(ref)].tri_offset + ref_triangle(ref);
  const GridTriangle tri = triangles[k];
  // Barycentrics: the camera ray's Moller-Trumbore weights (gather_barycentrics), as the CPU's
  // gather makes them
  const vec4 n = gather_normal(tri.v0, tri.v1, tri.v2, dir);
  if (n.w > 0.0f) {
    const vec2 bc = gather_barycentrics(tri.v0, tri.v1, tri.v2, c.eye, dir);
    g.position = surface_point(tri.v0, tri.v1, tri.v2, bc);
    g.material = tri.material;
    g.normal = n.xyz;
    g.launch_ref = ref;
    g.uv = interpolate_uv(uvs[k].uv0, uvs[k].uv1, uvs[k].uv2, bc.x, bc.y);
    g.t = t;
  }
  return g;
}

// The same for a visible triangle alone (the raster pass's visibility buffer): t from the gather's
// ray test of it (no surface where its determinant is 0: the test never accepted it).
GatherTexel gather_texel(uint ref, vec3 dir) {
  if (ref == kNoRef) return GatherTexel(vec3(0.0f), 0xFFFFFFFFu, vec3(0.0f), kNoRef, vec2(0.0f), 0.0f, 0u);
  const uint k = instances[ref_instance(ref)].tri_offset + ref_triangle(ref);
  TriangleTest r;
  gather_ray_test(dir, triangles[k], k, 0.0f, r);
  if (r.det == 0.0f) return GatherTexel(vec3(0.0f), 0xFFFFFFFFu, vec3(0.0f), kNoRef, vec2(0.0f), 0.0f, 0u);
  return gather_texel_at(ref, dir, moller_trumbore_t(r));
}

#endif
