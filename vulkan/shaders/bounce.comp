#version 460
// bounce.comp: one glossy bounce ray per pixel off the gather buffer, as common/gather.cpp's
// bounce_rays makes it (common/shared/bounce.h); unused pixels get the empty ray, and here the hit
// the trace would give it (a miss: the empty interval, no cell visited, no test), so that the
// trace takes the rays alone. The pass runs only for a ray list: compacted (kFrameCompact), a
// pixel with a ray appends its index to the list; sorted (ray_sort.comp), the sort's first pass
// lists the pixels with a ray, in their keys' order.
#extension GL_GOOGLE_include_directive : require
#include "frame_common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
// The rays and hits as 16-byte words (record_words.glsl)
layout(std430, binding = kFrameBindRays) writeonly buffer RayWords { uvec4 ray_words[]; };
layout(std430, binding = kFrameBindHits) writeonly buffer HitWords { uvec4 hit_words[]; };
#include "record_words.glsl"

void main() {
  const CameraParams c = fp.camera;
  const uvec2 px = gl_GlobalInvocationID.xy;
  if (px.x >= c.width || px.y >= c.height) return;
  const uint p = px.y * c.width + px.x;
  const GatherTexel g = load_gather(p);
  float gloss = 0.0f, cos_max = 1.0f;
  if ((kFrameFlags & kFrameBounce) != 0u && g.launch_ref != kNoRef && g.material < fp.material_count) {
    gloss = fmaterials[g.material].glossiness;
    cos_max = fmaterials[g.material].cos_max;
  }
  const RayRecord ray = frame_bounce_ray(c, fp.frame, g, gloss, cos_max, px.x, px.y);
  uvec4 w0, w1, w2;
  ray_to_words(ray, w0, w1, w2);
  ray_words[3u * p] = w0;
  ray_words[3u * p + 1u] = w1;
  ray_words[3u * p + 2u] = w2;
  if (!(ray.tmax > 0.0f)) {
    hit_to_words(HitRecord(sh_infinity(), kNoInstance, 0u, 0.0f, 0.0f, 0u, 0u, 0u), w0, w1);
    hit_words[2u * p] = w0;
    hit_words[2u * p + 1u] = w1;
  } else if ((kFrameFlags & kFrameCompact) != 0u) {
    ray_list[atomicAdd(ray_list_header.appended, 1u)] = p;
  }
}
