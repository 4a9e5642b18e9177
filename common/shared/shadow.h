// shadow.h: the frame's shadow rays, written once for the CPU (common/gather.cpp, shadow_rays) and
// the GPU (the frame's trace makes them: trace.comp), so that both make the same rays bit for bit where division
// and square root are correctly rounded (compat.h rules; docs/SPEC.md, "Shadow rays"):
//  - one ray per gather texel and light, from the gather position (no offset: the trace never
//    accepts the launch triangle, kGridExcludeLaunchRef), launch normal and reference the texel's
//  - towards a point light: dir = light - position (unnormalized), t in (0, 1): the segment to the
//    light (scaled by a power of two where it leaves the traces' range [2^-20, 2^20], t in (0, 2^e)
//    then); towards a directional light: dir = the unit direction to it, t in (0, +inf)
//  - the empty ray (tmin = tmax = 0: every trace answers a miss, and shading leaves the light
//    out) where the texel has no surface, the light is at the texel, or the light is behind the
//    surface (dot(normal, dir) <= 0)
// The ray is occluded iff its trace reports a hit (gap-fill included), traced as an any-hit ray
// (kTraceAnyHit: the trace ends at the first accepted candidate; docs/SPEC.md "Any hit"), the
// same rule on both backends.
#ifndef GRIDRT_SHARED_SHADOW_H
#define GRIDRT_SHARED_SHADOW_H

#include "compat.h"
#include "rounding.h"
#include "records.h"
#include "bounce.h"

SH_BEGIN

// The most lights a frame traces shadow rays to (one ray per pixel and light); a scene with more
// is refused with shadows on (check_shadow_lights, common/shade.h).
SH_CONST uint kMaxShadowLights = 8u;

// The empty ray: an empty interval, so every tracer answers a miss.
SH_INLINE RayRecord empty_shadow_ray() {
  RayRecord r;
  r.org = vec3(0.0f);
  r.tmin = 0.0f;
  r.dir = vec3(0.0f, 0.0f, 1.0f);
  r.tmax = 0.0f;
  r.launch_normal = vec3(0.0f);
  r.launch_ref = kNoRef;
  return r;
}

// The shadow ray from gather position p (unit normal n facing the viewer, launch reference ref;
// kNoRef: no surface) towards a light at `light` (a point light), or in direction `light` (a
// directional light: the direction towards it, any length > 0).
SH_INLINE RayRecord shadow_ray(SH_IN(vec3) p, SH_IN(vec3) n, uint ref, SH_IN(vec3) light, bool directional) {
  if (ref == kNoRef) return empty_shadow_ray();
  SH_PRECISE vec3 to_light = light - p;
  if (directional) to_light = light;
  SH_PRECISE float d2 = sh_dot(to_light, to_light);
  if (!(d2 > 0.0f)) return empty_shadow_ray();
  SH_PRECISE float facing = sh_dot(n, to_light);
  if (!(facing > 0.0f)) return empty_shadow_ray();
  RayRecord r;
  r.org = p;
  r.tmin = 0.0f;
  r.dir = to_light;
  r.tmax = 1.0f;
  // A light farther than 2^20 (or nearer than 2^-20) along every axis: the direction scaled by a
  // power of two 2^-e into the traces' range, t in (0, 2^e): the same segment, exactly (a light 2e6
  // away gave a ray every trace rejects, so no shadow)
  SH_PRECISE vec3 ad = abs(to_light);
  SH_PRECISE float m = max(max(ad.x, ad.y), ad.z);
  if (!directional && (m > 1048576.0f || m < 9.5367431640625e-07f)) {
    const uint e = min((floatBitsToUint(m) >> 23u) & 0xFFu, 253u);  // m's biased exponent
    SH_PRECISE float down = uintBitsToFloat((254u - e) << 23u);       // 2^(127 - e)
    r.dir = to_light * down;
    r.tmax = uintBitsToFloat(e << 23u);                               // 2^(e - 127)
  }
  if (directional) {
    r.dir = sh_normalize(to_light);
    r.tmax = uintBitsToFloat(0x7F800000u);  // +inf
  }
  r.launch_normal = n;
  r.launch_ref = ref;
  return r;
}

SH_END

#endif
