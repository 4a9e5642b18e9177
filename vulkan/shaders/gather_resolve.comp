#version 460
// gather_resolve.comp: the gather buffer from the visible triangle per pixel (the raster pass's,
// copied to the visibility buffer; or the compute gather's key, whose low word it is). The
// pixel's camera ray (common/shared/bounce.h, camera_direction) meets that triangle where the
// shared Moller-Trumbore test puts it, so position, normal, uv and material are computed exactly
// as common/gather.cpp computes them from a traced primary hit (make_gather).
#extension GL_GOOGLE_include_directive : require
#include "frame_common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
  const CameraParams c = fp.camera;
  const uvec2 px = gl_GlobalInvocationID.xy;
  if (px.x >= c.width || px.y >= c.height) return;
  const uint p = px.y * c.width + px.x;
  const vec3 dir = camera_direction(c, px.x, px.y);
  GatherTexel g = GatherTexel(vec3(0.0f), 0xFFFFFFFFu, vec3(0.0f), kNoRef, vec2(0.0f), 0.0f, 0u);
  uint ref;
  if ((kFrameFlags & kFrameComputeGather) != 0u) {
    ref = gather_keys[2u * p];  // the key's low word; untouched keys are all ones: kNoRef
    visibility[p] = ref;
  } else {
    ref = visibility[p];
  }
  if (ref != kNoRef) {
    const uint k = instances[ref_instance(ref)].tri_offset + ref_triangle(ref);
    const GridTriangle tri = triangles[k];
    // The primary hit: t of the shared triangle test, barycentrics by Cramer's rule
    TriangleTest r;
    moller_trumbore(c.eye, dir, tri.v0, tri.v1, tri.v2, 0.0f, sh_infinity(), sh_infinity(), r);
    const vec4 n = gather_normal(tri.v0, tri.v1, tri.v2, dir);
    if (r.det != 0.0f && n.w > 0.0f) {
      const float t = moller_trumbore_t(r);
      const vec3 pos = point_at(c.eye, dir, t);
      const vec2 bc = cramer_barycentrics(tri.v0, tri.v1, tri.v2, pos);
      g.position = pos;
      g.material = tri.material;
      g.normal = n.xyz;
      g.launch_ref = ref;
      g.uv = interpolate_uv(uvs[k].uv0, uvs[k].uv1, uvs[k].uv2, bc.x, bc.y);
      g.t = t;
    }
  }
  gather[p] = g;
}
