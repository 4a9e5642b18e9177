// portal_trace.glsl: the portal tracer on the GPU ("A Novel Raytracing Algorithm for GPU": stackless traversal of divs, only
// the current div index as state). It follows reference/portal/trace.cpp function by function,
// with the same names and heading comments; the per-ray math is common/shared/portal.h, the same
// functions the reference calls. The textures are the reference's PackedPortal as the paper stores
// them: the atlas R16_UINT, the div info RGBA8_UINT (8 texels per div, lexicographically packed),
// the start map R16_UINT 3D, all read by point-sampled texel fetches.
#ifndef GRIDRT_PORTAL_TRACE_GLSL
#define GRIDRT_PORTAL_TRACE_GLSL

#extension GL_EXT_samplerless_texture_functions : require

#include "gridrt/common/shared/compat.h"
#include "gridrt/common/shared/records.h"
#include "gridrt/common/shared/portal.h"
#include "gridrt/vulkan/shaders/portal_input.h"

// The descriptor set of every portal pass (bindings: portal_input.h).
layout(binding = kPortalBindAtlas) uniform utexture2D atlas_tex;  // R16_UINT
layout(binding = kPortalBindInfo) uniform utexture2D info_tex;   // RGBA8_UINT
layout(binding = kPortalBindStart) uniform utexture3D start_tex;  // R16_UINT
layout(std430, binding = kPortalBindParams) readonly buffer ParamsBuffer { PortalParams params; };
layout(std430, binding = kPortalBindMaterials) readonly buffer Materials { PortalMaterial materials[]; };
layout(std430, binding = kPortalBindExplain) buffer Explain {
  uint explain_count;  // events written (may exceed the capacity: then the tail is lost)
  uint explain_pad0;
  uint explain_pad1;
  uint explain_pad2;
  PortalExplainEvent explain_events[];
};

// Step kinds (reference StepKind).
const uint kStepNext = 0u;
const uint kStepWall = 1u;
const uint kStepOutside = 2u;
const uint kStepTmax = 3u;
const uint kStepNoDirection = 4u;

// A ray in voxel space (org and dir mapped by the world's origin and voxel size; t unchanged).
struct VoxelRay {
  vec3 org;
  vec3 dir;
  float tmin;
  float tmax;
};

// Decoded div info of one div (reference DivInfo).
struct DivInfo {
  ivec3 lo;
  ivec3 size;
  uint type;
  uint glass_material;
  uint level;      // mip level (the high nibble of the type byte)
  uvec2 face_uv[6];
};

// One step's result (reference Step).
struct Step {
  uint kind;
  uint axis;       // axis of the plane crossed
  float num;       // that plane's distance ahead: t = num / ad
  float ad;        // |dir[axis]|
  uint face;       // the div face left (exterior div: the world face entered)
  ivec3 voxel;     // exterior: the boundary voxel entered; else the voxel on this side of the face
  uvec2 texel_uv;  // atlas coordinates read
  uint texel;      // the atlas texel value
};

// Where a ray starts (reference Start).
const uint kStartDiv = 0u;
const uint kStartInsideSolid = 1u;
const uint kStartMiss = 2u;
struct Start {
  uint kind;
  uint div;
  ivec3 voxel;
  uint texel;
};

// Where a voxel-space ray starts relative to the world box (reference Entry).
const uint kEntryInside = 0u;
const uint kEntryEnter = 1u;
const uint kEntryMiss = 2u;
struct Entry {
  uint kind;
  ivec3 voxel;
  uint axis;
  float num;
  float ad;
};

VoxelRay to_voxel_ray(RayRecord ray) {
  VoxelRay r;
  const float inv = params.inv_voxel_size;
  precise vec3 o = (ray.org - params.origin) * inv;
  precise vec3 d = ray.dir * inv;
  r.org = o;
  r.dir = portal_direction(d);
  r.tmin = ray.tmin;
  r.tmax = ray.tmax;
  return r;
}

uint voxel_linear(uvec3 dims, ivec3 v) { return uint(v.x) + dims.x * (uint(v.y) + dims.y * uint(v.z)); }

HitRecord miss_hit(uint steps, uint texels) {
  HitRecord h;
  h.t = uintBitsToFloat(0x7F800000u);  // +infinity
  h.instance = kNoInstance;
  h.triangle = 0u;
  h.u = 0.0f;
  h.v = 0.0f;
  h.flags = 0u;
  h.cells = steps;
  h.tests = texels;
  return h;
}

// A wall hit on plane (axis, num, ad) of `r`, entering solid voxel `wall`; `side` is the voxel
// index along the tangents (the voxel the ray was in when it crossed).
HitRecord wall_hit(uvec3 dims, VoxelRay r, uint axis, float num, float ad, ivec3 side, ivec3 wall, uint material,
                   uint steps, uint texels) {
  HitRecord h = miss_hit(steps, texels);
  const uint t0 = portal_tangent0(axis);
  const uint t1 = portal_tangent1(axis);
  precise float t = sh_div(num, ad);  // correctly rounded (rounding.h): the same bits on every device
  h.t = t;
  h.instance = material;
  h.triangle = (voxel_linear(dims, wall) << kPortalFaceBits) | portal_hit_face(axis, r.dir[axis]);
  h.u = portal_subtexel(num, ad, r.org[t0], r.dir[t0], uint(side[t0]));
  h.v = portal_subtexel(num, ad, r.org[t1], r.dir[t1], uint(side[t1]));
  return h;
}

HitRecord inside_hit(uvec3 dims, VoxelRay r, ivec3 v, uint material) {
  HitRecord h = miss_hit(1u, 1u);
  h.t = r.tmin;
  h.instance = material;
  h.triangle = (voxel_linear(dims, v) << kPortalFaceBits) | kPortalFaceInside;
  return h;
}

bool finite_float(float x) { return !isinf(x) && !isnan(x); }

// Where a voxel-space ray starts: inside the world box (the voxel of org + tmin dir), entering it
// (entry axis and the boundary voxel), or missing it. Shared by the portal and the DDA.
Entry enter_world(uvec3 dims, VoxelRay r) {
  Entry e;
  e.kind = kEntryMiss;
  e.voxel = ivec3(0);
  e.axis = 3u;
  e.num = 0.0f;
  e.ad = 0.0f;
  const vec3 hi = vec3(dims);
  for (uint a = 0u; a < 3u; a++)
    if (!finite_float(r.org[a]) || !finite_float(r.dir[a])) return e;
  // An empty interval, or one behind the origin: a miss (reference enter_world)
  if (!(r.tmin >= 0.0f) || !(r.tmin < r.tmax)) return e;
  precise vec3 q = r.org + r.tmin * r.dir;
  if (q.x >= 0.0f && q.y >= 0.0f && q.z >= 0.0f && q.x <= hi.x && q.y <= hi.y && q.z <= hi.z) {
    // The voxel the ray moves into: a point on a voxel plane belongs to the voxel ahead of it; on the
    // box's face, moving out or along it, that voxel is outside: not inside (reference enter_world)
    bool ahead_inside = true;
    ivec3 v = ivec3(0);
    for (uint a = 0u; a < 3u; a++) {
      const float c = r.dir[a] < 0.0f ? ceil(q[a]) - 1.0f : floor(q[a]);
      if (c < 0.0f || c >= hi[a]) ahead_inside = false;
      else v[a] = int(c);
    }
    if (ahead_inside) {
      e.kind = kEntryInside;
      e.voxel = v;
      return e;
    }
  }
  float num = 0.0f;
  const uint a = portal_entry_axis(vec3(0.0f), hi, r.org, r.dir, num);
  if (a == 3u) return e;
  const float ad = abs(r.dir[a]);
  precise float lim = r.tmin * ad;
  if (num < lim) return e;                             // the box lies before tmin
  if (!portal_before_tmax(num, ad, r.tmax)) return e;  // or after tmax
  e.kind = kEntryEnter;
  e.axis = a;
  e.num = num;
  e.ad = ad;
  e.voxel[a] = r.dir[a] > 0.0f ? 0 : int(dims[a]) - 1;
  const uint b0 = portal_tangent0(a);
  const uint b1 = portal_tangent1(a);
  e.voxel[b0] = int(portal_cross_index(a, num, ad, b0, r.org[b0], r.dir[b0], 0u, dims[b0]));
  e.voxel[b1] = int(portal_cross_index(a, num, ad, b1, r.org[b1], r.dir[b1], 0u, dims[b1]));
  return e;
}

uint atlas_at(uvec2 uv) { return texelFetch(atlas_tex, ivec2(uv), 0).r; }

// Decoded div info of div `d` (reads the RGBA8 texels only): texel k of div d is texel 8 d + k of
// the row-major info texture.
uvec4 div_info_texel(uint d, uint k) {
  const uint idx = d * 8u + k;
  return texelFetch(info_tex, ivec2(idx % params.info_width, idx / params.info_width), 0);
}
DivInfo read_div_info(uint d) {
  DivInfo info;
  for (uint f = 0u; f < 6u; f++) {
    const uvec4 t = div_info_texel(d, f);
    info.face_uv[f] = uvec2(t.x | (t.z << 8), t.y | (t.w << 8));
  }
  const uvec4 s = div_info_texel(d, 6u);
  const uvec4 o = div_info_texel(d, 7u);
  info.size = ivec3(s.xyz);
  info.glass_material = s.w;
  info.lo = ivec3(o.xyz);
  info.type = o.w & kPortalTypeMask;
  info.level = o.w >> kPortalLevelShift;
  return info;
}

// ---- Mip-mapped space (reference: level_ray, mip_enter, mip_fine_voxels) ----
// The start texel of voxel v of level `level`: the block of the start texture at depth start_z.
uint start_at(uint level, ivec3 v) {
  uint z = 0u;
  for (uint l = 0u; l < level; l++) z += portal_level_dims(params.dims, l).z;
  return texelFetch(start_tex, ivec3(v.x, v.y, int(z) + v.z), 0).r;
}

// Scalings by a power of two are exact, so these products need no `precise` (a fused use of an
// exact product rounds as the separate operations do).
VoxelRay level_ray(VoxelRay r, uint level) {
  if (level == 0u) return r;
  const float sc = portal_level_scale(level);
  VoxelRay q = r;
  vec3 o = r.org * sc;
  vec3 d = r.dir * sc;
  q.org = o;
  q.dir = d;
  return q;
}

struct MipEnter {
  bool moved;
  uint level;
  ivec3 voxel;
  uint texel;
};

// The crossing voxel along the tangents and the plane (Step, below).
struct StepPlane {
  uint axis;
  float num;
  float ad;
  ivec3 voxel;
};

MipEnter mip_enter(VoxelRay r, uint lc, StepPlane s) {
  MipEnter m;
  m.moved = false;
  m.level = 0u;
  m.voxel = ivec3(0);
  m.texel = 0u;
  if (params.levels <= 1u) return m;
  const float maxad = max(max(abs(r.dir.x), abs(r.dir.y)), abs(r.dir.z));
  const uint target = portal_mip_level(s.num, s.ad, maxad, params.mip_distance, params.levels);
  if (target <= lc) return m;
  const uint a = s.axis;
  const bool pos = r.dir[a] > 0.0f;
  const uint plane = uint(s.voxel[a]) + (pos ? 1u : 0u);
  const uint l = portal_mip_aligned_level(plane, lc, target);
  if (l == lc) return m;
  ivec3 beyond = s.voxel;
  beyond[a] += pos ? 1 : -1;
  m.moved = true;
  m.level = l;
  for (uint b = 0u; b < 3u; b++) m.voxel[b] = int(uint(beyond[b]) >> (l - lc));
  m.texel = start_at(l, m.voxel);
  return m;
}

void mip_fine_voxels(VoxelRay r, uint level, uint a, float num, float ad, ivec3 v, out ivec3 wall, out ivec3 side) {
  const int f = 1 << level;
  const float up = float(f);
  float num0 = num * up;
  float ad0 = ad * up;
  const bool pos = r.dir[a] > 0.0f;
  wall = ivec3(0);
  wall[a] = pos ? v[a] * f : min(v[a] * f + f, int(params.dims[a])) - 1;
  const uint b0 = portal_tangent0(a);
  const uint b1 = portal_tangent1(a);
  wall[b0] = int(portal_cross_index(a, num0, ad0, b0, r.org[b0], r.dir[b0], uint(v[b0] * f),
                                    uint(min(v[b0] * f + f, int(params.dims[b0])))));
  wall[b1] = int(portal_cross_index(a, num0, ad0, b1, r.org[b1], r.dir[b1], uint(v[b1] * f),
                                    uint(min(v[b1] * f + f, int(params.dims[b1])))));
  side = wall;
  side[a] += pos ? -1 : 1;
}

Start start_ray(VoxelRay r) {
  Start s;
  s.kind = kStartMiss;
  s.div = 0u;
  s.voxel = ivec3(0);
  s.texel = 0u;
  const Entry e = enter_world(params.dims, r);
  if (e.kind == kEntryMiss) return s;
  if (e.kind == kEntryEnter) {
    s.kind = kStartDiv;
    s.div = kPortalExteriorDiv;
    return s;
  }
  s.voxel = e.voxel;
  s.texel = texelFetch(start_tex, e.voxel, 0).r;
  if (portal_texel_is_wall(s.texel)) {
    s.kind = kStartInsideSolid;
    return s;
  }
  s.kind = kStartDiv;
  s.div = s.texel;
  return s;
}

// `base`: instanced subspaces: a block div's box offset by its instance tile's corner (fine voxels).
Step step_ray(uint div, VoxelRay r0, ivec3 base) {
  Step s;
  s.kind = kStepNoDirection;
  s.axis = 3u;
  s.num = 0.0f;
  s.ad = 0.0f;
  s.face = 0u;
  s.voxel = ivec3(0);
  s.texel_uv = uvec2(0u);
  s.texel = 0u;
  DivInfo d = read_div_info(div);
  d.lo += base;  // instanced subspaces: a block div in its instance tile
  const VoxelRay r = level_ray(r0, d.level);  // mip-mapped space: the div's level
  const vec3 lo = vec3(d.lo);
  const vec3 hi = vec3(d.lo + d.size);
  float num = 0.0f;
  if (d.type == kPortalDivExterior) {
    // The exterior div: the face the ray enters the world box by (surfaced on the outside).
    const uint a = portal_entry_axis(lo, hi, r.org, r.dir, num);
    if (a == 3u) return s;
    s.axis = a;
    s.num = num;
    s.ad = abs(r.dir[a]);
    s.face = 2u * a + (r.dir[a] > 0.0f ? 0u : 1u);
    s.voxel[a] = r.dir[a] > 0.0f ? d.lo[a] : d.lo[a] + d.size[a] - 1;
  } else {
    // 1. The exit face: three slab tests, only the face each direction component points to.
    const uint a = portal_exit_axis(lo, hi, r.org, r.dir, num);
    if (a == 3u) return s;
    s.axis = a;
    s.num = num;
    s.ad = abs(r.dir[a]);
    if (!portal_before_tmax(num, s.ad, r.tmax)) {
      s.kind = kStepTmax;
      return s;
    }
    s.face = 2u * a + (r.dir[a] > 0.0f ? 1u : 0u);
    s.voxel[a] = r.dir[a] > 0.0f ? d.lo[a] + d.size[a] - 1 : d.lo[a];
  }
  // 2. The crossing voxel along the tangents, and the face texel there.
  const uint a = s.axis;
  const uint t0 = portal_tangent0(a);
  const uint t1 = portal_tangent1(a);
  s.voxel[t0] = int(portal_cross_index(a, s.num, s.ad, t0, r.org[t0], r.dir[t0], uint(d.lo[t0]),
                                       uint(d.lo[t0] + d.size[t0])));
  s.voxel[t1] = int(portal_cross_index(a, s.num, s.ad, t1, r.org[t1], r.dir[t1], uint(d.lo[t1]),
                                       uint(d.lo[t1] + d.size[t1])));
  s.texel_uv = d.face_uv[s.face] + uvec2(uint(s.voxel[t0] - d.lo[t0]), uint(s.voxel[t1] - d.lo[t1]));
  s.texel = atlas_at(s.texel_uv);
  // 3. What the texel says.
  if (s.texel == kPortalOutside) s.kind = kStepOutside;
  else if (portal_texel_is_wall(s.texel)) s.kind = kStepWall;
  else s.kind = kStepNext;
  return s;
}

// ---- Explain: the explained ray's own record (vulkan/portal.cpp turns it into text) ----
layout(constant_id = kPortalSpecExplain) const bool kExplain = false;  // record the explain ray's events
bool explaining = false;
uint explain_capacity = 0u;

void emit(uint kind, uint div, uint face, uint texel, ivec3 voxel, uint step, uvec2 texel_uv, float num, float ad) {
  if (!kExplain || !explaining) return;
  const uint i = explain_count;
  if (i < explain_capacity)
    explain_events[i] = PortalExplainEvent(kind, div, face, texel, voxel, step, texel_uv, num, ad);
  explain_count = i + 1u;
}

// A coarse wall of material `m` (level `level`, coarse voxel `v`) met on plane (axis, num, ad, level
// space): the first surface (reference mip_surface_hit).
HitRecord mip_surface_hit(VoxelRay r, uint level, uint a, float num, float ad, ivec3 v, uint m, uint steps, uint texels) {
  ivec3 wall;
  ivec3 side;
  mip_fine_voxels(r, level, a, num, ad, v, wall, side);
  const float up = float(1 << level);
  uint material = m;
  if (materials[m].resolve != 0u) {
    const uint t0 = start_at(0u, wall);
    ++texels;
    material = portal_texel_is_wall(t0) ? t0 - kPortalWallBit : m;
  }
  emit(3u, level, 0u, m, v, 0u, uvec2(0u), 0.0f, 0.0f);
  float num0 = num * up;
  float ad0 = ad * up;
  return wall_hit(params.dims, r, a, num0, ad0, side, wall, material, steps, texels);
}

// ---- Instanced subspaces (reference/portal/trace.cpp: instanced_start, instanced_advance, trace_instanced) ----

bool is_instance_material(uint m) {
  return portal_is_instance(m, params.scale_log2, params.instance_base, params.blocks);
}

uvec3 fine_dims() { return params.dims << params.scale_log2; }

ivec3 instance_fine_voxel(VoxelRay r, uint a, float num, float ad, ivec3 tile) {
  return portal_instance_fine_voxel(a, num, ad, r.org, r.dir, tile, params.scale_log2);
}

uint block_start_texel(uint m, ivec3 tile, ivec3 fine) {
  const uint i = portal_block_start_index(params.block_start, m - params.instance_base, params.scale_log2, tile, fine);
  return atlas_at(uvec2(i % params.atlas_width, i / params.atlas_width));
}

const uint kInstancedDiv = 0u;
const uint kInstancedInsideSolid = 1u;
const uint kInstancedMiss = 2u;
struct InstancedStart {
  uint kind;
  uint div;
  ivec3 tile;
  ivec3 voxel;
  uint material;
  uint texels;
};

InstancedStart instanced_start(VoxelRay r) {
  InstancedStart s;
  s.kind = kInstancedMiss;
  s.div = 0u;
  s.tile = ivec3(0);
  s.voxel = ivec3(0);
  s.material = 0u;
  s.texels = 0u;
  const Entry e = enter_world(fine_dims(), r);  // fine space: the flattened world's decision
  if (e.kind == kEntryMiss) return s;
  if (e.kind == kEntryEnter) {
    s.kind = kInstancedDiv;
    s.div = kPortalExteriorDiv;
    return s;
  }
  s.voxel = e.voxel;
  s.tile = ivec3(uvec3(e.voxel) >> params.scale_log2);
  uint t = texelFetch(start_tex, s.tile, 0).r;
  s.texels = 1u;
  if (portal_texel_is_wall(t) && is_instance_material(t - kPortalWallBit)) {
    t = block_start_texel(t - kPortalWallBit, s.tile, s.voxel);  // inside an instance: its block's start map
    s.texels = 2u;
  }
  if (portal_texel_is_wall(t)) {
    s.kind = kInstancedInsideSolid;
    s.material = t - kPortalWallBit;
    return s;
  }
  s.kind = kInstancedDiv;
  s.div = t;
  return s;
}

const uint kEventContinue = 0u;
const uint kEventWall = 1u;
const uint kEventMiss = 2u;
struct InstancedEvent {
  uint kind;
  uint axis;
  float num;  // fine space: t = num / ad
  float ad;
  ivec3 wall;
  ivec3 side;
  uint material;
};

// enter_instance: into instance tile `tile` (material m) at fine voxel `fine`.
InstancedEvent enter_instance(InstancedEvent e, uint m, ivec3 tile, ivec3 fine, ivec3 side, inout uint div,
                              inout ivec3 cur_tile, inout uint texels) {
  ++texels;
  const uint bt = block_start_texel(m, tile, fine);
  emit(4u, m - params.instance_base, uint(tile.x) | (uint(tile.y) << 8) | (uint(tile.z) << 16), bt, fine, 0u, uvec2(0u),
       0.0f, 0.0f);
  if (portal_texel_is_wall(bt)) {
    e.kind = kEventWall;
    e.wall = fine;
    e.side = side;
    e.material = bt - kPortalWallBit;
    return e;
  }
  e.kind = kEventContinue;
  div = bt;
  cur_tile = tile;
  return e;
}

InstancedEvent instanced_advance(VoxelRay r, inout uint div, inout ivec3 tile, Step st, inout uint texels) {
  InstancedEvent e;
  e.kind = kEventMiss;
  e.axis = 0u;
  e.num = 0.0f;
  e.ad = 0.0f;
  e.wall = ivec3(0);
  e.side = ivec3(0);
  e.material = 0u;
  if (st.kind == kStepNoDirection || st.kind == kStepTmax) return e;
  ++texels;
  const int S = 1 << params.scale_log2;
  const bool in_block = div >= params.top_divs;
  const float up = in_block ? 1.0f : float(S);  // top-level planes in fine space (exact)
  const uint a = st.axis;
  const int sg = r.dir[a] > 0.0f ? 1 : -1;
  e.axis = a;
  float fn = st.num * up;
  float fa = st.ad * up;
  e.num = fn;
  e.ad = fa;
  if (st.kind == kStepNext) {
    e.kind = kEventContinue;
    div = st.texel;
    return e;
  }
  if (in_block) {
    ivec3 beyond = st.voxel;
    beyond[a] += sg;
    if (st.kind == kStepWall) {
      e.kind = kEventWall;
      e.wall = beyond;
      e.side = st.voxel;
      e.material = st.texel - kPortalWallBit;
      return e;
    }
    // leave_instance: back to the top level through the tile beyond the block's face.
    ivec3 nt = tile;
    nt[a] += sg;
    if (nt[a] < 0 || nt[a] >= int(params.dims[a])) {
      emit(5u, 0u, 0u, 0u, nt, 1u, uvec2(0u), 0.0f, 0.0f);
      return e;
    }
    ++texels;
    const uint tt = texelFetch(start_tex, nt, 0).r;
    emit(5u, 0u, 0u, tt, nt, 0u, uvec2(0u), 0.0f, 0.0f);
    if (!portal_texel_is_wall(tt)) {
      e.kind = kEventContinue;
      div = tt;
      return e;
    }
    const uint m = tt - kPortalWallBit;
    if (is_instance_material(m)) return enter_instance(e, m, nt, beyond, st.voxel, div, tile, texels);
    e.kind = kEventWall;
    e.wall = beyond;
    e.side = st.voxel;
    e.material = m;
    return e;
  }
  if (st.kind == kStepOutside) return e;
  ivec3 wt = st.voxel;
  if (div != kPortalExteriorDiv) wt[a] += sg;
  const uint m = st.texel - kPortalWallBit;
  const ivec3 fine = instance_fine_voxel(r, a, e.num, e.ad, wt);
  if (is_instance_material(m)) return enter_instance(e, m, wt, fine, fine, div, tile, texels);
  e.kind = kEventWall;
  e.wall = fine;
  e.side = fine;
  e.material = m;
  return e;
}

// The step of div `div` (a block div: in instance tile `tile`).
Step step_instanced(uint div, ivec3 tile, VoxelRay r) {
  const ivec3 base = div >= params.top_divs ? tile * (1 << params.scale_log2) : ivec3(0);
  return step_ray(div, r, base);
}

HitRecord trace_instanced(RayRecord ray) {
  const VoxelRay r = to_voxel_ray(ray);
  const uvec3 fd = fine_dims();
  const InstancedStart st = instanced_start(r);
  emit(0u, st.kind == kInstancedInsideSolid ? st.material : st.div, 0u, 0u, st.voxel, st.kind, uvec2(0u), 0.0f, 0.0f);
  if (st.kind == kInstancedMiss) return miss_hit(0u, 0u);
  if (st.kind == kInstancedInsideSolid) return inside_hit(fd, r, st.voxel, st.material);
  uint cur = st.div;
  uint steps = 0u;
  uint texels = st.texels;
  ivec3 tile = st.tile;
  const uint limit = 4u * params.div_count + 16u + 4u * (fd.x + fd.y + fd.z);
  while (steps < limit) {
    const Step s = step_instanced(cur, tile, r);
    ++steps;
    emit(1u, cur, s.face, s.texel, s.voxel, s.kind, s.texel_uv, s.num, s.ad);
    const InstancedEvent e = instanced_advance(r, cur, tile, s, texels);
    if (e.kind == kEventContinue) continue;
    if (e.kind == kEventMiss) return miss_hit(steps, texels);
    return wall_hit(fd, r, e.axis, e.num, e.ad, e.side, e.wall, e.material, steps, texels);
  }
  return miss_hit(steps, texels);
}

HitRecord trace_portal(RayRecord ray) {
  if (params.scale_log2 != 0u) return trace_instanced(ray);
  const VoxelRay r = to_voxel_ray(ray);
  const Start st = start_ray(r);
  emit(0u, st.div, 0u, st.texel, st.voxel, st.kind, uvec2(0u), 0.0f, 0.0f);
  if (st.kind == kStartMiss) return miss_hit(0u, 0u);
  if (st.kind == kStartInsideSolid) return inside_hit(params.dims, r, st.voxel, st.texel - kPortalWallBit);
  // A start in glass: inside it, as in a wall (reference trace_portal)
  if (st.div != kPortalExteriorDiv) {
    const DivInfo sd = read_div_info(st.div);
    if (sd.type == kPortalDivGlass) return inside_hit(params.dims, r, st.voxel, sd.glass_material);
  }
  uint cur = st.div;
  uint steps = 0u;
  uint texels = st.div == kPortalExteriorDiv ? 0u : 1u;
  const uint limit = 4u * params.div_count + 16u;
  while (steps < limit) {
    const DivInfo d = read_div_info(cur);
    ++steps;
    const Step s = step_ray(cur, r, ivec3(0));
    emit(1u, cur, s.face, s.texel, s.voxel, s.kind, s.texel_uv, s.num, s.ad);
    if (s.kind == kStepNoDirection) return miss_hit(steps, texels);
    if (s.kind == kStepTmax) return miss_hit(steps, texels);
    ++texels;
    if (s.kind == kStepOutside) return miss_hit(steps, texels);
    ivec3 wall = s.voxel;
    if (d.type != kPortalDivExterior) wall[s.axis] += r.dir[s.axis] > 0.0f ? 1 : -1;
    if (s.kind == kStepWall && d.level > 0u)
      return mip_surface_hit(r, d.level, s.axis, s.num, s.ad, wall, s.texel - kPortalWallBit, steps, texels);
    if (s.kind == kStepWall)
      return wall_hit(params.dims, r, s.axis, s.num, s.ad, s.voxel, wall, s.texel - kPortalWallBit, steps, texels);
    // Next div; a change of medium (air <-> glass) is a surface for this tracer.
    const DivInfo nd = read_div_info(s.texel);
    const uint next_medium = nd.type == kPortalDivGlass ? nd.glass_material : 0xFFFFFFFFu;
    const uint cur_medium = d.type == kPortalDivGlass ? d.glass_material : 0xFFFFFFFFu;
    if (next_medium != cur_medium) {
      const uint m = next_medium != 0xFFFFFFFFu ? next_medium : cur_medium;
      return wall_hit(params.dims, r, s.axis, s.num, s.ad, s.voxel, wall, m, steps, texels);
    }
    cur = s.texel;
    if (params.levels > 1u && d.type == kPortalDivAir) {
      // Mip-mapped space: a coarser level from this plane on, when the level rule says so.
      const MipEnter me = mip_enter(r, d.level, StepPlane(s.axis, s.num, s.ad, s.voxel));
      if (me.moved) {
        ++texels;
        emit(2u, me.level, 0u, me.texel, me.voxel, 0u, uvec2(0u), 0.0f, 0.0f);
        if (!portal_texel_is_wall(me.texel)) {
          cur = me.texel;
        } else {
          const float sc = portal_level_scale(me.level - d.level);
          float ln = s.num * sc;
          float la = s.ad * sc;
          return mip_surface_hit(r, me.level, s.axis, ln, la, me.voxel, me.texel - kPortalWallBit, steps, texels);
        }
      }
    }
  }
  return miss_hit(steps, texels);
}

#endif
