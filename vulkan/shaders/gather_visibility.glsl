// gather_visibility.glsl: the compute gather's visibility (vulkan/frame.h): the triangle each
// pixel's camera ray meets first, decided by the ray test the CPU's gather makes (make_gather:
// primary rays through the exact traversal with the watertight test, gather_ray_test, the
// smaller t and then the smaller reference), not by the rasterizer's coverage and depth.
//   gather_bin.comp    per triangle: the screen box of the pixels its ray test can accept
//                      (common/shared/raster.h gather_box: the triangle clipped to the view
//                      frustum with a rounding bound, or across the near plane the edge
//                      functions' region); a box of at
//                      most 16 pixels is tested there, a larger one appended to the list of large
//                      triangles with its count of work items
//   gather_tiles.comp  per tile, one invocation per pixel: the ray test; an accepted hit takes
//                      the pixel's key (t bits << 32 | reference) by a 64-bit atomic min
// The box only limits the work; the ray test decides.
#ifndef GRIDRT_GATHER_VISIBILITY_GLSL
#define GRIDRT_GATHER_VISIBILITY_GLSL

#include "frame_common.glsl"
#include "gridrt/common/shared/raster.h"

// raster_tile_t_lo with GLSL's division (a few ulps, far within the depth plane's margin of 2^-10:
// docs/SPEC.md "Depth plane"): the fine pass takes it for every pair of a tile's list, where the
// correctly rounded sh_div cost more than the culling saved.
float raster_tile_t_lo_fast(vec4 depth, float t_lo, uint x0, uint y0, uint x1, uint y1) {
  const float p = raster_tile_p(depth, x0, y0, x1, y1);
  if (!(p > 0.0f)) return t_lo;
  const float t = depth.w / p;
  return t > t_lo ? t : t_lo;
}

// The instance holding geometry-buffer triangle `k`: the last whose offset is <= k (build.comp).
uint gather_instance_of(uint k, uint instance_count) {
  uint lo = 0u;
  uint hi = instance_count;
  while (hi - lo > 1u) {
    const uint mid = (lo + hi) / 2u;
    if (instances[mid].tri_offset <= k) lo = mid;
    else hi = mid;
  }
  return lo;
}

// The 64-bit key of the pixel's ray (direction `dir`, interval (tmin, inf): tmin its origin
// epsilon, origin_tmin) against the triangle (t bits << 32 | ref; t >= 0, so its bits order as
// the floats), or false when the shared test rejects it or the alpha mask cuts it. The same test,
// interval and alpha rule as the raster gather's fragment shader and the CPU's primary rays.
bool gather_key_along(uint ref, uint k, GridTriangle tri, vec3 dir, float tmin, out uvec2 key) {
  key = uvec2(kNoRef, 0xFFFFFFFFu);
  const CameraParams c = fp.camera;
  TriangleTest r;
  float weights_det;
  if (gather_ray_code(dir, tri, k, tmin, r, weights_det) != kTestAccepted) return false;
  const float t = moller_trumbore_t(r);
  if ((kFrameFlags & kFrameAlpha) != 0u) {
    const FrameMaterial m = fmaterials[tri.material];
    if (m.alpha_width != 0u) {
      const vec2 bc = test_barycentrics(r.u_det, r.v_det, weights_det);  // the test's own weights
      const vec2 uv = interpolate_uv(uvs[k].uv0, uvs[k].uv1, uvs[k].uv2, bc.x, bc.y);
      const uvec2 xy = alpha_texel_coords(uv, m.alpha_width, m.alpha_height);
      if (!alpha_keeps(texel_alpha(diffuse_texels[m.alpha_offset + xy.y * m.alpha_width + xy.x]))) return false;
    }
  }
  key = uvec2(ref, floatBitsToUint(t));
  return true;
}

// The same for pixel px's camera ray (camera_direction, origin_tmin; the rasterizer reads both from
// pixel_dirs).
bool gather_key(uint ref, uint k, GridTriangle tri, uvec2 px, out uvec2 key) {
  const vec3 dir = camera_direction(fp.camera, px.x, px.y);
  return gather_key_along(ref, k, tri, dir, origin_tmin(fp.camera.eye, dir, 0.0f), key);
}

#endif
