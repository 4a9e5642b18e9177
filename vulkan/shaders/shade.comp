#version 460
// shade.comp: the frame's colour per pixel, as common/shade.cpp's shade() computes it: albedo times (ambient + direct light); glossy materials mix in the bounce hit's albedo
// times its light (gap-fill hits: their triangle at its centroid), the environment on a miss;
// clamped, sRGB-encoded into RGBA8. With shadows (kFrameShadows) a light lights a pixel only if
// the pixel's shadow ray to it (shadow.comp) is used and its hit a miss.
#extension GL_GOOGLE_include_directive : require
#include "frame_common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

vec3 material_albedo(uint material, vec2 uv) {
  if (material >= fp.material_count) return vec3(0.0f);
  const FrameMaterial m = fmaterials[material];
  vec3 c = m.diffuse;
  if ((kFrameFlags & kFrameTextures) != 0u && m.texture_width != 0u) {
    const uvec2 xy = alpha_texel_coords(uv, m.texture_width, m.texture_height);
    const uint texel = diffuse_texels[m.texture_offset + xy.y * m.texture_width + xy.x];
    c *= vec3(float(texel & 255u), float((texel >> 8u) & 255u), float((texel >> 16u) & 255u)) * (1.0f / 255.0f);
  }
  return c;
}

// Light arriving at p with unit normal n; a headlight without lights. `pixel`: whose shadow rays
// decide (kNoRef: unshadowed, the bounce hit's light).
vec3 direct_light(vec3 p, vec3 n, uint pixel) {
  if (fp.light_count == 0u) {
    const vec3 to_eye = fp.camera.eye - p;
    const float len = sqrt(sh_dot(to_eye, to_eye));
    return len > 0.0f ? vec3(max(0.0f, sh_dot(n, to_eye / len))) : vec3(0.0f);
  }
  vec3 e = vec3(0.0f);
  for (uint i = 0u; i < fp.light_count; ++i) {
    const FrameLight l = lights[i];
    const bool directional = l.directional != 0.0f;
    const vec3 to_light = directional ? l.position : l.position - p;
    const float d2 = sh_dot(to_light, to_light);
    if (!(d2 > 0.0f)) continue;
    const vec3 L = to_light / sqrt(d2);
    const float cosine = sh_dot(n, L);
    if (cosine <= 0.0f) continue;
    if ((kFrameFlags & kFrameShadows) != 0u && pixel != kNoRef) {
      const uint k = (1u + i) * (fp.camera.width * fp.camera.height) + pixel;
      if ((rays[k].tmin == 0.0f && rays[k].tmax == 0.0f) || hits[k].instance != kNoInstance) continue;
    }
    e += l.radiance * cosine / (directional ? 1.0f : d2);
  }
  return e;
}

uint srgb8(float c) {
  if (!(c > 0.0f)) return 0u;
  if (c >= 1.0f) return 255u;
  const float s = c <= 0.0031308f ? 12.92f * c : 1.055f * pow(c, 1.0f / 2.4f) - 0.055f;
  return uint(s * 255.0f + 0.5f);
}

void main() {
  const CameraParams cam = fp.camera;
  const uvec2 px = gl_GlobalInvocationID.xy;
  if (px.x >= cam.width || px.y >= cam.height) return;
  const uint p = px.y * cam.width + px.x;
  const GatherTexel g = load_gather(p);
  vec3 c = fp.background;
  if (g.launch_ref != kNoRef) {
    const vec3 albedo = material_albedo(g.material, g.uv);
    c = albedo * (fp.ambient + direct_light(g.position, g.normal, p));
    const float gloss = g.material < fp.material_count ? fmaterials[g.material].glossiness : 0.0f;
    if ((kFrameFlags & kFrameBounce) != 0u && gloss > 0.0f) {
      const RayRecord r = rays[p];
      const HitRecord h = hits[p];
      vec3 b = fp.background;
      if (!(r.tmin == 0.0f && r.tmax == 0.0f) && h.instance != kNoInstance) {
        // The bounce hit's albedo (gap-fill: the triangle's centroid) and its normal
        const bool gap = (h.flags & kHitGapFill) != 0u;
        const float u = gap ? 1.0f / 3.0f : h.u, v = gap ? 1.0f / 3.0f : h.v;
        const uint k = instances[h.instance].tri_offset + h.triangle;
        const GridTriangle tri = triangles[k];
        const vec3 a = material_albedo(tri.material, interpolate_uv(uvs[k].uv0, uvs[k].uv1, uvs[k].uv2, u, v));
        const vec3 hp = r.org + h.t * r.dir;
        const vec4 n = gather_normal(tri.v0, tri.v1, tri.v2, r.dir);
        b = a * (fp.ambient + direct_light(hp, n.w > 0.0f ? n.xyz : vec3(0.0f, 1.0f, 0.0f), kNoRef));
      }
      if (!(r.tmin == 0.0f && r.tmax == 0.0f)) c = (1.0f - gloss) * c + gloss * b;
    }
  }
  c = clamp(c * fp.exposure, vec3(0.0f), vec3(1.0f));
  image[p] = srgb8(c.x) | (srgb8(c.y) << 8u) | (srgb8(c.z) << 16u) | (255u << 24u);
}
