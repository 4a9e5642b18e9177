// gather_visibility.glsl: the compute gather's visibility (vulkan/frame.h): the triangle each
// pixel's camera ray meets first, decided by the ray test the CPU's gather makes (make_gather:
// primary rays through the exact traversal, common/shared/triangle.h moller_trumbore, the
// smaller t and then the smaller reference), not by the rasterizer's coverage and depth.
//   gather_bin.comp    per triangle: the screen box of the pixels its ray test can accept (the
//                      triangle clipped to the view frustum); a box of at most 16 pixels is
//                      tested there, a larger one appended to the list of large triangles with
//                      its count of 8x8-pixel tiles
//   gather_tiles.comp  per tile, one invocation per pixel: the ray test; an accepted hit takes
//                      the pixel's key (t bits << 32 | reference) by a 64-bit atomic min
// The box only limits the work (a pixel of margin on every side); the ray test decides.
#ifndef GRIDRT_GATHER_VISIBILITY_GLSL
#define GRIDRT_GATHER_VISIBILITY_GLSL

#include "frame_common.glsl"

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

// Camera space (right, up, forward) of a world point, as gather.vert computes it.
vec3 gather_camera_space(CameraParams c, vec3 p) {
  const vec3 q = p - c.eye;
  return vec3(sh_dot(q, c.right), sh_dot(q, c.up), sh_dot(q, c.forward));
}

// Continuous pixel coordinates of a camera-space point in front of the eye (pixel (x, y) covers
// [x, x + 1) x [y, y + 1); its ray passes through the centre): the inverse of camera_direction.
vec2 gather_project(CameraParams c, vec3 q) {
  const float sx = q.x / q.z, sy = q.y / q.z;
  return vec2((sx / (c.tan_half_fov * c.aspect) + 1.0f) * 0.5f * float(c.width),
              (1.0f - sy / c.tan_half_fov) * 0.5f * float(c.height));
}

// Clips the convex polygon poly[0, n) to the half-space dot(plane.xyz, p) + plane.w >= 0
// (Sutherland-Hodgman); returns the new vertex count (at most n + 1).
uint gather_clip(inout vec3 poly[9], uint n, vec4 plane) {
  vec3 kept[9];
  uint m = 0u;
  for (uint i = 0u; i < n; ++i) {
    const vec3 a = poly[i], b = poly[i + 1u == n ? 0u : i + 1u];
    const float da = dot(plane.xyz, a) + plane.w, db = dot(plane.xyz, b) + plane.w;
    if (da >= 0.0f && m < 9u) kept[m++] = a;
    if ((da >= 0.0f) != (db >= 0.0f) && m < 9u) kept[m++] = a + (da / (da - db)) * (b - a);
  }
  poly = kept;
  return m;
}

// The box (x0, y0, x1, y1, inclusive) of the pixels whose centre rays may meet the triangle: its
// part inside the view frustum (the near plane and the four sides, widened by two pixels) projected,
// a pixel of margin on every side; false when nothing is left.
bool gather_box(CameraParams c, float near_plane, vec3 v0, vec3 v1, vec3 v2, out uvec4 box) {
  box = uvec4(0u);
  vec3 poly[9];
  poly[0] = gather_camera_space(c, v0);
  poly[1] = gather_camera_space(c, v1);
  poly[2] = gather_camera_space(c, v2);
  const float kx = c.tan_half_fov * c.aspect * (1.0f + 4.0f / float(c.width));
  const float ky = c.tan_half_fov * (1.0f + 4.0f / float(c.height));
  uint n = gather_clip(poly, 3u, vec4(0.0f, 0.0f, 1.0f, -near_plane));
  n = n >= 3u ? gather_clip(poly, n, vec4(1.0f, 0.0f, kx, 0.0f)) : 0u;
  n = n >= 3u ? gather_clip(poly, n, vec4(-1.0f, 0.0f, kx, 0.0f)) : 0u;
  n = n >= 3u ? gather_clip(poly, n, vec4(0.0f, 1.0f, ky, 0.0f)) : 0u;
  n = n >= 3u ? gather_clip(poly, n, vec4(0.0f, -1.0f, ky, 0.0f)) : 0u;
  if (n < 3u) return false;
  vec2 lo = vec2(3.0e38f), hi = vec2(-3.0e38f);
  for (uint i = 0u; i < n; ++i) {
    const vec2 p = gather_project(c, vec3(poly[i].xy, max(poly[i].z, near_plane)));
    lo = min(lo, p);
    hi = max(hi, p);
  }
  // Pixel centres x + 0.5 in [lo, hi], widened by a pixel, clamped in float before converting
  const vec2 size = vec2(float(c.width), float(c.height));
  const vec2 first = clamp(floor(lo - 0.5f) - 1.0f, vec2(0.0f), size - 1.0f);
  const vec2 last = clamp(ceil(hi - 0.5f) + 1.0f, vec2(0.0f), size - 1.0f);
  if (!(first.x <= last.x && first.y <= last.y)) return false;  // NaN: nothing to test
  box = uvec4(uvec2(first), uvec2(last));
  return true;
}

// The 64-bit key of the pixel's ray (direction `dir`) against the triangle (t bits << 32 | ref; t >= 0, so its bits
// order as the floats), or false when the shared test rejects it or the alpha mask cuts it. The
// same test and alpha rule as the raster gather's fragment shader and the CPU's primary rays.
bool gather_key_along(uint ref, uint k, GridTriangle tri, vec3 dir, out uvec2 key) {
  key = uvec2(kNoRef, 0xFFFFFFFFu);
  const CameraParams c = fp.camera;
  TriangleTest r;
  if (moller_trumbore(c.eye, dir, tri.v0, tri.v1, tri.v2, 0.0f, sh_infinity(), sh_infinity(), r) != kTestAccepted)
    return false;
  const float t = moller_trumbore_t(r);
  if ((kFrameFlags & kFrameAlpha) != 0u) {
    const FrameMaterial m = fmaterials[tri.material];
    if (m.alpha_width != 0u) {
      const vec2 bc = cramer_barycentrics(tri.v0, tri.v1, tri.v2, point_at(c.eye, dir, t));
      const vec2 uv = interpolate_uv(uvs[k].uv0, uvs[k].uv1, uvs[k].uv2, bc.x, bc.y);
      const uvec2 xy = alpha_texel_coords(uv, m.alpha_width, m.alpha_height);
      if (!alpha_keeps(texel_alpha(diffuse_texels[m.alpha_offset + xy.y * m.alpha_width + xy.x]))) return false;
    }
  }
  key = uvec2(ref, floatBitsToUint(t));
  return true;
}

// The same for pixel px's camera ray (camera_direction; the rasterizer reads it from pixel_dirs).
bool gather_key(uint ref, uint k, GridTriangle tri, uvec2 px, out uvec2 key) {
  return gather_key_along(ref, k, tri, camera_direction(fp.camera, px.x, px.y), key);
}

#endif
