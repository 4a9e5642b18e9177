#version 460
// portal_render.comp: primary + two shadow rays per pixel through the portal tracer, with
// non-forking refraction (reference/portal/render.cpp, function by function, same names and
// heading comments). Push constant `pass`: 0 runs the single-loop state machine (the paper's FSM:
// one loop, the same step_ray for every kind of ray, transitions at the end of each iteration);
// 1, 2, 3 are the three separate loops (all primary rays, then all first shadow rays, then all
// second), one dispatch each, the pixel's state kept in the pixel buffer between them.
//
// The host math of the reference is mirrored exactly: glm::normalize is v * (1 / sqrt(dot(v, v))),
// glm::dot the ordered sum sh_dot, glm::length sqrt(dot(v, v)), every temporary `precise`; each
// division and square root is the correctly rounded sh_div / sh_sqrt (common/shared/rounding.h),
// as IEEE's `/` and std::sqrt on the CPU, since the device's own are not on every GPU (NVIDIA's
// differ by 1-3 ulps). The one function that is not the reference's to the bit is pow (std::pow on
// the CPU): the glass filter.
#extension GL_GOOGLE_include_directive : require
#include "portal_trace.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = kPortalBindRenderParams) readonly buffer RenderParamsBuffer { PortalRenderParams rp; };
layout(std430, binding = kPortalBindPixels) buffer Pixels { PortalPixel pixels[]; };
layout(push_constant) uniform Push { PortalRenderPush pc; };

const uint kPrimary = 0u;
const uint kShadowA = 1u;
const uint kShadowB = 2u;
const uint kDone = 3u;

float infinity() { return uintBitsToFloat(0x7F800000u); }

// glm::normalize and glm::length, as GLM computes them.
vec3 ref_normalize(vec3 v) {
  precise float len = sh_sqrt(sh_dot(v, v));
  precise float inv = sh_div(1.0f, len);
  precise vec3 r = v * inv;
  return r;
}
float ref_length(vec3 v) {
  precise float len = sh_sqrt(sh_dot(v, v));
  return len;
}

// Refraction of unit direction `d` at a surface with unit normal `n` facing the incoming ray,
// eta = n_from / n_to. Returns false (and the reflected direction) on total internal reflection.
bool refract_or_reflect(vec3 d, vec3 n, float eta, out vec3 o) {
  precise float cosi = -sh_dot(n, d);
  precise float k = 1.0f - eta * eta * (1.0f - cosi * cosi);
  if (k < 0.0f) {
    precise vec3 r = d + 2.0f * cosi * n;  // total internal reflection: the reflected ray instead
    o = r;
    return false;
  }
  precise vec3 v = eta * d + (eta * cosi - sh_sqrt(k)) * n;
  o = ref_normalize(v);
  return true;
}

// The ray through the centre of pixel (x, y) (common/camera.cpp, camera_ray).
RayRecord camera_ray(uint x, uint y) {
  // Pixel centre in normalized device coordinates, [-1, 1], y up.
  precise float sx = (sh_div(2.0f * (float(x) + 0.5f), float(rp.width)) - 1.0f) * rp.tan_half_fov *
                     sh_div(float(rp.width), float(rp.height));
  precise float sy = (1.0f - sh_div(2.0f * (float(y) + 0.5f), float(rp.height))) * rp.tan_half_fov;
  precise vec3 v = rp.forward + sx * rp.right + sy * rp.up;
  RayRecord ray;
  ray.org = rp.eye;
  ray.dir = ref_normalize(v);
  ray.tmin = 0.0f;
  ray.tmax = infinity();
  ray.launch_normal = vec3(0.0f);
  ray.launch_ref = kNoRef;
  return ray;
}

void finish(inout PortalPixel s) {
  precise float shade = rp.ambient + (1.0f - rp.ambient) * 0.5f * s.light;
  precise vec3 c = s.filter_acc * s.albedo * shade + s.mip_acc;
  s.color = c;
  s.mode = kDone;
}

vec3 light_position(uint i) { return i == 0u ? rp.light0 : rp.light1; }

// Set up shadow ray `i` (0 or 1) or, past the last, finish the pixel.
void begin_shadow(inout PortalPixel s, uint i) {
  for (; i < 2u; ++i) {
    precise vec3 to = light_position(i) - s.point;
    if (sh_dot(to, s.normal) <= 0.0f) continue;  // the light is behind the surface
    s.org = s.point;
    s.dir = to;
    s.tmin = 0.0f;
    s.tmax = 1.0f;      // reaching t = 1 is reaching the light
    s.div = s.hit_div;  // the shadow ray starts in the div the primary ray ended in: no offset needed
    s.tile = s.hit_tile;
    s.mode = kShadowA + i;
    ++s.shadow_rays;
    return;
  }
  finish(s);
}

void begin_primary(inout PortalPixel s, RayRecord ray) {
  const VoxelRay r = to_voxel_ray(ray);
  s.org = r.org;
  s.dir = r.dir;
  s.tmin = r.tmin;
  s.tmax = r.tmax;
  if (params.scale_log2 != 0u) {  // instanced subspaces
    const InstancedStart is = instanced_start(r);
    if (is.kind == kInstancedMiss) {
      s.color = rp.background;
      s.mode = kDone;
    } else if (is.kind == kInstancedInsideSolid) {
      s.albedo = materials[is.material].color;
      precise vec3 c = s.albedo * rp.ambient;
      s.color = c;
      s.mode = kDone;
    } else {
      s.div = is.div;
      s.tile = is.tile;
      s.mode = kPrimary;
    }
    return;
  }
  const Start st = start_ray(r);
  if (st.kind == kStartMiss) {
    s.color = rp.background;
    s.mode = kDone;
  } else if (st.kind == kStartInsideSolid) {
    s.albedo = materials[st.texel - kPortalWallBit].color;
    precise vec3 c = s.albedo * rp.ambient;
    s.color = c;
    s.mode = kDone;
  } else {
    s.div = st.div;
    s.mode = kPrimary;
    // A camera in glass: the ray starts in that glass (reference begin_primary)
    if (st.div != kPortalExteriorDiv) {
      const DivInfo d = read_div_info(st.div);
      if (d.type == kPortalDivGlass) {
        s.in_glass = 1u;
        s.glass = d.glass_material;
        precise vec3 e = r.org + r.tmin * r.dir;
        s.glass_entry = e;
      }
    }
  }
}

VoxelRay pixel_ray(PortalPixel s) { return VoxelRay(s.org, s.dir, s.tmin, s.tmax); }

vec3 crossing(PortalPixel s, Step st) {
  precise float t = sh_div(st.num, st.ad);
  precise vec3 x = s.org + t * s.dir;
  return x;
}

vec3 crossing_at(PortalPixel s, float num, float ad) {
  precise float t = sh_div(num, ad);
  precise vec3 x = s.org + t * s.dir;
  return x;
}

// Mip-mapped space: the primary ray meets coarse wall voxel `v` of level `level` (material m) on
// the plane (axis, num, ad; level space). Opaque (resolve): back to full resolution, the fine
// voxel's own hit, shaded with its shadow rays. Partly occupied: translucent, composited front to
// back with alpha = coverage (lit by both lights, unshadowed), and the ray goes on through the
// coarse voxel to the next one: a div of that level (the traversal resumes there), another coarse
// wall, or the outside.
void mip_surface(inout PortalPixel s, uint level, uint axis, float num, float ad, ivec3 v, uint m) {
  const uvec3 ld = portal_level_dims(params.dims, level);
  for (uint guard = 0u; guard < ld.x + ld.y + ld.z + 3u; ++guard) {
    vec3 n = vec3(0.0f);
    n[axis] = s.dir[axis] > 0.0f ? -1.0f : 1.0f;
    const vec3 x = crossing_at(s, num, ad);
    if (materials[m].resolve != 0u) {
      ivec3 wall;
      ivec3 side;
      mip_fine_voxels(pixel_ray(s), level, axis, num, ad, v, wall, side);
      const uint tw = start_at(0u, wall);
      const uint ts = start_at(0u, side);
      s.point = x;
      s.normal = n;
      s.albedo = materials[portal_texel_is_wall(tw) ? tw - kPortalWallBit : m].color;
      if (portal_texel_is_wall(ts)) {  // the fine voxel before the face is solid: no shadow ray leaves it
        finish(s);
        return;
      }
      s.hit_div = ts;
      begin_shadow(s, 0u);
      return;
    }
    precise float lit = 0.0f;
    for (uint i = 0u; i < 2u; i++) {
      precise vec3 to = light_position(i) - x;
      lit = lit + max(0.0f, sh_dot(n, ref_normalize(to)));
    }
    precise float shade = rp.ambient + (1.0f - rp.ambient) * 0.5f * lit;
    const float cov = materials[m].coverage;
    precise vec3 add = s.filter_acc * (cov * shade) * materials[m].color;
    precise vec3 acc = s.mip_acc + add;
    s.mip_acc = acc;
    precise vec3 f = s.filter_acc * (1.0f - cov);
    s.filter_acc = f;
    ++s.steps_primary;
    ++s.iterations;
    // Through the coarse voxel: its exit face and the voxel beyond.
    const VoxelRay rl = level_ray(pixel_ray(s), level);
    float en = 0.0f;
    const uint a = portal_exit_axis(vec3(v), vec3(v) + 1.0f, rl.org, rl.dir, en);
    ivec3 next = v;
    if (a < 3u) next[a] += rl.dir[a] > 0.0f ? 1 : -1;
    if (a == 3u || !portal_before_tmax(en, abs(rl.dir[a]), rl.tmax) || any(lessThan(next, ivec3(0))) ||
        any(greaterThanEqual(uvec3(next), ld))) {
      precise vec3 c = s.filter_acc * rp.background + s.mip_acc;
      s.color = c;
      s.mode = kDone;
      return;
    }
    const uint t = start_at(level, next);
    if (!portal_texel_is_wall(t)) {
      s.div = t;
      return;
    }
    axis = a;
    num = en;
    ad = abs(rl.dir[a]);
    v = next;
    m = t - kPortalWallBit;
  }
  precise vec3 c = s.filter_acc * rp.background + s.mip_acc;  // not reached: the coarse voxels ahead are finite
  s.color = c;
  s.mode = kDone;
}

vec3 pow3(vec3 f, float d) { return vec3(pow(f.x, d), pow(f.y, d), pow(f.z, d)); }

// The state transitions: what one step's result does to the pixel.
// Instanced subspaces (reference/portal/instance.cpp, render_instanced): no glass, no mip levels;
// the state is the div and, in a block div, its tile.
void transition_instanced(inout PortalPixel s, Step st) {
  ++s.iterations;
  uint texels = 0u;
  const uint from = s.div;
  const ivec3 from_tile = s.tile;
  if (s.mode == kPrimary) {
    ++s.steps_primary;
    const InstancedEvent e = instanced_advance(pixel_ray(s), s.div, s.tile, st, texels);
    if (e.kind == kEventContinue) return;
    if (e.kind == kEventWall) {
      s.point = crossing_at(s, e.num, e.ad);
      s.normal = vec3(0.0f);
      s.normal[e.axis] = s.dir[e.axis] > 0.0f ? -1.0f : 1.0f;
      s.albedo = materials[e.material].color;
      s.hit_div = from;
      s.hit_tile = from_tile;
      begin_shadow(s, 0u);
      return;
    }
    precise vec3 c = s.filter_acc * rp.background + s.mip_acc;
    s.color = c;
    s.mode = kDone;
    return;
  }
  ++s.steps_shadow;
  const uint i = s.mode - kShadowA;
  if (st.kind == kStepTmax) {
    precise float l = s.light + sh_dot(s.normal, ref_normalize(s.dir));
    s.light = l;
    begin_shadow(s, i + 1u);
    return;
  }
  const InstancedEvent e = instanced_advance(pixel_ray(s), s.div, s.tile, st, texels);
  if (e.kind == kEventContinue) return;
  begin_shadow(s, i + 1u);
}

void transition(inout PortalPixel s, Step st) {
  if (params.scale_log2 != 0u) {
    transition_instanced(s, st);
    return;
  }
  ++s.iterations;
  if (s.mode == kPrimary) {
    ++s.steps_primary;
    if (st.kind == kStepNext) {
      const DivInfo nd = read_div_info(st.texel);
      const bool next_glass = nd.type == kPortalDivGlass;
      const bool in_glass = s.in_glass != 0u;
      if (next_glass == in_glass && (!next_glass || nd.glass_material == s.glass)) {
        const uint from = s.div;
        s.div = st.texel;
        if (params.levels > 1u && !next_glass) {
          // Mip-mapped space: a coarser level from this plane on, when the level rule says so.
          const DivInfo cd = read_div_info(from);
          if (cd.type != kPortalDivAir) return;
          const MipEnter me = mip_enter(pixel_ray(s), cd.level, StepPlane(st.axis, st.num, st.ad, st.voxel));
          if (!me.moved) return;
          if (!portal_texel_is_wall(me.texel)) {
            s.div = me.texel;
            return;
          }
          const float sc = portal_level_scale(me.level - cd.level);
          float ln = st.num * sc;
          float la = st.ad * sc;
          mip_surface(s, me.level, st.axis, ln, la, me.voxel, me.texel - kPortalWallBit);
        }
        return;
      }
      const uint gm = next_glass ? nd.glass_material : s.glass;  // the glass whose surface this is
      const vec3 x = crossing(s, st);
      vec3 n = vec3(0.0f);
      n[st.axis] = s.dir[st.axis] > 0.0f ? -1.0f : 1.0f;
      if (rp.refraction == 0u) {  // glass as an opaque wall
        s.point = x;
        s.normal = n;
        s.albedo = materials[gm].color;
        s.hit_div = s.div;
        begin_shadow(s, 0u);
        return;
      }
      if (++s.interfaces > rp.max_interfaces) {
        s.filter_acc = vec3(0.0f);
        s.color = vec3(0.0f);
        s.mode = kDone;
        return;
      }
      const float n_from = in_glass ? materials[s.glass].ior : 1.0f;
      const float n_to = next_glass ? materials[nd.glass_material].ior : 1.0f;
      precise float eta = sh_div(n_from, n_to);
      vec3 d;
      if (refract_or_reflect(ref_normalize(s.dir), n, eta, d)) {
        ++s.refractions;
        if (in_glass) {
          precise vec3 f = s.filter_acc * pow3(materials[s.glass].glass_filter, ref_length(x - s.glass_entry));
          s.filter_acc = f;
        }
        s.in_glass = next_glass ? 1u : 0u;
        if (next_glass) {
          s.glass = nd.glass_material;
          s.glass_entry = x;
        }
        s.div = st.texel;
      } else {
        ++s.reflections;  // stays in the current div
      }
      s.org = x;
      s.dir = d;
      s.tmin = 0.0f;
      s.tmax = infinity();
      return;
    }
    if (st.kind == kStepWall && params.levels > 1u) {
      const DivInfo cd = read_div_info(s.div);
      if (cd.level > 0u) {
        ivec3 v = st.voxel;
        v[st.axis] += s.dir[st.axis] > 0.0f ? 1 : -1;
        mip_surface(s, cd.level, st.axis, st.num, st.ad, v, st.texel - kPortalWallBit);
        return;
      }
    }
    if (st.kind == kStepWall) {
      const vec3 x = crossing(s, st);
      if (s.in_glass != 0u) {
        precise vec3 f = s.filter_acc * pow3(materials[s.glass].glass_filter, ref_length(x - s.glass_entry));
        s.filter_acc = f;
      }
      s.point = x;
      s.normal = vec3(0.0f);
      s.normal[st.axis] = s.dir[st.axis] > 0.0f ? -1.0f : 1.0f;
      s.albedo = materials[st.texel - kPortalWallBit].color;
      s.hit_div = s.div;
      begin_shadow(s, 0u);
      return;
    }
    precise vec3 c = s.filter_acc * rp.background + s.mip_acc;  // outside, tmax or no direction
    s.color = c;
    s.mode = kDone;
    return;
  }
  // Shadow rays: reaching t = 1 (tmax) is reaching the light, as is leaving a voxelized scene's
  // world (open_outside); a wall, glass or a tile map's outside blocks.
  ++s.steps_shadow;
  const uint i = s.mode - kShadowA;
  if (st.kind == kStepNext) {
    const DivInfo nd = read_div_info(st.texel);
    const bool next_glass = nd.type == kPortalDivGlass;
    if (next_glass == (s.in_glass != 0u) && (!next_glass || nd.glass_material == s.glass)) {
      s.div = st.texel;
      return;
    }
  } else if (st.kind == kStepTmax || (st.kind == kStepOutside && rp.open_outside != 0u)) {
    precise float l = s.light + sh_dot(s.normal, ref_normalize(s.dir));
    s.light = l;
  }
  begin_shadow(s, i + 1u);
}

PortalPixel new_pixel() {
  PortalPixel s;
  s.org = vec3(0.0f);
  s.tmin = 0.0f;
  s.dir = vec3(0.0f, 0.0f, 1.0f);
  s.tmax = 0.0f;
  s.filter_acc = vec3(1.0f);
  s.mode = kPrimary;
  s.glass_entry = vec3(0.0f);
  s.div = 0u;
  s.point = vec3(0.0f);
  s.interfaces = 0u;
  s.normal = vec3(0.0f);
  s.in_glass = 0u;
  s.albedo = vec3(0.0f);
  s.glass = 0u;
  s.color = vec3(0.0f);
  s.light = 0.0f;
  s.hit_div = 0u;
  s.steps_primary = 0u;
  s.steps_shadow = 0u;
  s.iterations = 0u;
  s.refractions = 0u;
  s.reflections = 0u;
  s.shadow_rays = 0u;
  s.cut = 0u;
  s.mip_acc = vec3(0.0f);
  s.pad1 = 0u;
  s.tile = ivec3(0);
  s.pad2 = 0u;
  s.hit_tile = ivec3(0);
  s.pad3 = 0u;
  return s;
}

void main() {
  const uint x = gl_GlobalInvocationID.x;
  const uint y = gl_GlobalInvocationID.y;
  if (x >= rp.width || y >= rp.height) return;
  const uint p = y * rp.width + x;
  PortalPixel s;
  if (pc.pass <= 1u) {
    s = new_pixel();
    begin_primary(s, camera_ray(x, y));
  } else {
    s = pixels[p];
  }
  // Bounded (reference end_if_cut): a pixel whose rays cycle between divs ends as background
  // A loop that ends with its ray unfinished was cut: by the limit, or by llvmpipe, which ends an
  // invocation's loops after 65,535 iterations in all (docs/VULKAN.md); either way counted, never a
  // silent black pixel
  const uint limit = portal_pixel_iteration_limit(params.div_count, fine_dims(), rp.max_interfaces);
  bool unfinished;
  if (pc.pass == 0u) {
    // One loop: the same step for every kind of ray, transitions at the end of each iteration.
    while (s.mode != kDone && s.iterations < limit) transition(s, step_instanced(s.div, s.tile, pixel_ray(s)));
    unfinished = s.mode != kDone;
  } else {
    // One of the three loops: this pass's kind of ray only.
    const uint mode = pc.pass - 1u;
    while (s.mode == mode && s.iterations < limit) transition(s, step_instanced(s.div, s.tile, pixel_ray(s)));
    unfinished = s.mode == mode;
  }
  if (unfinished) {
    s.color = rp.background;
    s.mode = kDone;
    s.cut = 1u;
  }
  pixels[p] = s;
}
