#version 460
// gather.frag: the visible triangle's reference (instance << 16 | triangle) into the R32_UINT
// attachment; the depth test keeps the nearest. Alpha keying (specialized): the pixel's camera
// ray meets the triangle where the shared test puts it, and the mask texel under the uv of
// the test's own weights there (watertight_barycentrics) decides, as the grid's trace decides it (trace.comp, alpha keying).
#extension GL_GOOGLE_include_directive : require
#include "frame_common.glsl"

layout(location = 0) flat in uint in_ref;
layout(location = 0) out uint out_ref;

void main() {
  if ((kFrameFlags & kFrameAlpha) != 0u) {
    const uint k = instances[ref_instance(in_ref)].tri_offset + ref_triangle(in_ref);
    const GridTriangle tri = triangles[k];
    const FrameMaterial m = fmaterials[tri.material];
    if (m.alpha_width != 0u) {
      const CameraParams c = fp.camera;
      const uvec2 px = uvec2(gl_FragCoord.xy);
      const vec3 dir = camera_direction(c, px.x, px.y);
      TriangleTest r;
      gather_ray_test(dir, tri, k, 0.0f, r);
      if (r.det != 0.0f) {
        const vec2 bc = watertight_barycentrics(c.eye, watertight_ray(dir), tri.v0, tri.v1, tri.v2);
        const vec2 uv = interpolate_uv(uvs[k].uv0, uvs[k].uv1, uvs[k].uv2, bc.x, bc.y);
        const uvec2 xy = alpha_texel_coords(uv, m.alpha_width, m.alpha_height);
        if (!alpha_keeps(texel_alpha(diffuse_texels[m.alpha_offset + xy.y * m.alpha_width + xy.x]))) discard;
      }
    }
  }
  out_ref = in_ref;
}
