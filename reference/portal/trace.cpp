// trace.cpp: portal traversal, voxel DDA, explain, tracers, renderer (trace.h).
#include "gridrt/reference/portal/trace.h"
#include "gridrt/common/parallel.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <limits>
#include <thread>

#include "gridrt/common/camera.h"
#include "gridrt/common/shared/portal.h"
#include "gridrt/reference/portal/instance.h"

namespace gridrt::portal {

namespace sh = gridrt::shared;

namespace {

template <class F>
void parallel_rows(size_t n, unsigned threads, F&& f) {
  parallel_for(n, threads, std::forward<F>(f));
}

std::string fmt(const char* f, ...) __attribute__((format(printf, 1, 2)));
std::string fmt(const char* f, ...) {
  char buf[512];
  va_list ap;
  va_start(ap, f);
  std::vsnprintf(buf, sizeof buf, f, ap);
  va_end(ap);
  return buf;
}


Hit miss_hit(uint32_t steps, uint32_t texels) {
  Hit h{};
  h.t = std::numeric_limits<float>::infinity();
  h.instance = sh::kNoInstance;
  h.triangle = 0;
  h.u = h.v = 0.0f;
  h.flags = 0;
  h.cells = steps;
  h.tests = texels;
  return h;
}

uint32_t voxel_linear(glm::uvec3 dims, glm::ivec3 v) { return uint32_t(v.x) + dims.x * (uint32_t(v.y) + dims.y * uint32_t(v.z)); }

// A wall hit on plane (axis, num, ad) of `ray`, entering solid voxel `wall`; `side` is the voxel
// index along the tangents (the voxel the ray was in when it crossed).
Hit wall_hit(glm::uvec3 dims, const VoxelRay& r, uint32_t axis, float num, float ad, glm::ivec3 side, glm::ivec3 wall,
             uint32_t material, uint32_t steps, uint32_t texels) {
  Hit h = miss_hit(steps, texels);
  const uint32_t t0 = sh::portal_tangent0(axis), t1 = sh::portal_tangent1(axis);
  h.t = sh::sh_div(num, ad);  // as the shaders compute it (rounding.h)
  h.instance = material;
  h.triangle = (voxel_linear(dims, wall) << sh::kPortalFaceBits) | sh::portal_hit_face(axis, r.dir[axis]);
  h.u = sh::portal_subtexel(num, ad, r.org[t0], r.dir[t0], uint32_t(side[t0]));
  h.v = sh::portal_subtexel(num, ad, r.org[t1], r.dir[t1], uint32_t(side[t1]));
  return h;
}

Hit inside_hit(glm::uvec3 dims, const VoxelRay& r, glm::ivec3 v, uint32_t material) {
  Hit h = miss_hit(1, 1);
  h.t = r.tmin;
  h.instance = material;
  h.triangle = (voxel_linear(dims, v) << sh::kPortalFaceBits) | sh::kPortalFaceInside;
  return h;
}

// Where a voxel-space ray starts: inside the world box (the voxel of org + tmin dir), entering it
// (entry axis and the boundary voxel), or missing it. Shared by the portal and the DDA.
struct Entry {
  enum Kind { kInside, kEnter, kMiss } kind = kMiss;
  glm::ivec3 voxel{0};
  uint32_t axis = 3;
  float num = 0, ad = 0;
};
Entry enter_world(glm::uvec3 dims, const VoxelRay& r) {
  Entry e;
  const glm::vec3 hi(dims);
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(r.org[a]) || !std::isfinite(r.dir[a])) return e;
  // An interval that holds nothing, or starts behind the origin (the grid's ray domain rejects a
  // negative tmin too): a miss, before any "started inside" hit at t = tmin
  if (!(r.tmin >= 0.0f) || !(r.tmin < r.tmax)) return e;
  const glm::vec3 q = r.org + r.tmin * r.dir;
  if (q.x >= 0.0f && q.y >= 0.0f && q.z >= 0.0f && q.x <= hi.x && q.y <= hi.y && q.z <= hi.z) {
    // The voxel the ray moves into: a point on a voxel plane belongs to the voxel ahead of it. On
    // the box's face, moving out of it or along it, that voxel is outside the world: the ray is
    // not inside (it was clamped into the boundary voxel, "inside a wall" there: an outside
    // sweep), and the entry test below decides (a miss for a ray leaving)
    bool ahead_inside = true;
    glm::ivec3 v(0);
    for (int a = 0; a < 3; ++a) {
      const float c = r.dir[a] < 0.0f ? std::ceil(q[a]) - 1.0f : std::floor(q[a]);
      if (c < 0.0f || c >= hi[a]) ahead_inside = false;
      else v[a] = int(c);
    }
    if (ahead_inside) {
      e.kind = Entry::kInside;
      e.voxel = v;
      return e;
    }
  }
  float num = 0.0f;
  const uint32_t a = sh::portal_entry_axis(glm::vec3(0.0f), hi, r.org, r.dir, num);
  if (a == 3) return e;
  const float ad = std::abs(r.dir[a]);
  if (num < r.tmin * ad) return e;                       // the box lies before tmin
  if (!sh::portal_before_tmax(num, ad, r.tmax)) return e;  // or after tmax
  e.kind = Entry::kEnter;
  e.axis = a, e.num = num, e.ad = ad;
  e.voxel[a] = r.dir[a] > 0.0f ? 0 : int(dims[a]) - 1;
  for (uint32_t b : {sh::portal_tangent0(a), sh::portal_tangent1(a)})
    e.voxel[b] = int(sh::portal_cross_index(a, num, ad, b, r.org[b], r.dir[b], 0u, dims[b]));
  return e;
}

uint16_t atlas_at(const PackedPortal& p, glm::uvec2 uv) { return p.atlas[size_t(uv.y) * p.atlas_width + uv.x]; }

}  // namespace

// A coarse wall of material `m` (level `level`, coarse voxel `v`) met on plane (axis, num, ad, level
// space): the first surface. An opaque coarse voxel (resolve) returns to full resolution: the fine
// voxel beyond the plane, its own material. A partly occupied one is reported as itself (its
// coarse material), at the fine voxel beyond the plane.
static Hit mip_surface_hit(const PackedPortal& p, const VoxelRay& r, uint32_t level, uint32_t a, float num, float ad, glm::ivec3 v,
                    uint32_t m, uint32_t steps, uint32_t texels, std::string* log) {
  glm::ivec3 wall, side;
  mip_fine_voxels(p, r, level, a, num, ad, v, wall, side);
  const float up = float(1 << level);
  uint32_t material = m;
  if (p.resolve[m]) {
    const uint16_t t0 = p.start_at(0, wall);
    ++texels;
    material = sh::portal_texel_is_wall(t0) ? t0 - sh::kPortalWallBit : m;
  }
  const Hit h = wall_hit(p.dims, r, a, num * up, ad * up, side, wall, material, steps, texels);
  if (log) {
    *log += fmt("hit: coarse voxel (%d, %d, %d) of level %u, material %u (coverage %g)%s: voxel (%d, %d, %d) face %s, "
                "material %u, t = %.9g\n", v.x, v.y, v.z, level, m, double(p.coverage[m]),
                p.resolve[m] ? ", opaque: back to full resolution" : ", translucent", wall.x, wall.y, wall.z,
                face_name(hit_face(h)), h.instance, double(h.t));
    if (!p.resolve[m])
      *log += "  (this account ends at the first translucent coarse voxel, an approximation of the fine ones: the\n"
              "  renderer blends it by its coverage and goes on; the voxel DDA, on the fine voxels, may differ here)\n";
  }
  return h;
}

const char* face_name(uint32_t f) {
  static const char* n[] = {"-X", "+X", "-Y", "+Y", "-Z", "+Z", "inside"};
  return n[std::min(f, 6u)];
}

std::string texel_text(uint32_t t) {
  if (t == sh::kPortalOutside) return fmt("0x%04X (outside the world)", t);
  if (t >= sh::kPortalWallBit) return fmt("0x%04X (wall, material %u)", t, t - sh::kPortalWallBit);
  return fmt("0x%04X (div %u)", t, t);
}

VoxelRay to_voxel_ray(glm::vec3 origin, float voxel_size, const Ray& ray) {
  VoxelRay r;
  const float inv = 1.0f / voxel_size;
  r.org = (ray.org - origin) * inv;
  r.dir = shared::portal_direction(ray.dir * inv);
  r.tmin = ray.tmin;
  r.tmax = ray.tmax;
  return r;
}

glm::ivec3 hit_voxel(const World& w, const Hit& h) {
  const uint32_t i = hit_voxel_index(h);
  return glm::ivec3(i % w.dims.x, (i / w.dims.x) % w.dims.y, i / (w.dims.x * w.dims.y));
}

Start start_ray(const PackedPortal& p, const VoxelRay& r) {
  Start s;
  const Entry e = enter_world(p.dims, r);
  if (e.kind == Entry::kMiss) return s;
  if (e.kind == Entry::kEnter) {
    s.kind = Start::kDiv;
    s.div = sh::kPortalExteriorDiv;
    return s;
  }
  s.voxel = e.voxel;
  s.texel = p.start[voxel_linear(p.dims, e.voxel)];
  if (sh::portal_texel_is_wall(s.texel)) {
    s.kind = Start::kInsideSolid;
    return s;
  }
  s.kind = Start::kDiv;
  s.div = s.texel;
  return s;
}

VoxelRay level_ray(const VoxelRay& r, uint32_t level) {
  if (level == 0) return r;
  const float s = sh::portal_level_scale(level);
  VoxelRay q = r;
  q.org = r.org * s;
  q.dir = r.dir * s;
  return q;
}

MipEnter mip_enter(const PackedPortal& p, const VoxelRay& r, uint32_t lc, const Step& s) {
  MipEnter m;
  if (p.levels <= 1) return m;
  const float maxad = std::max({std::abs(r.dir.x), std::abs(r.dir.y), std::abs(r.dir.z)});
  const uint32_t target = sh::portal_mip_level(s.num, s.ad, maxad, p.mip_distance, p.levels);
  if (target <= lc) return m;
  const uint32_t a = s.axis;
  const bool pos = r.dir[a] > 0.0f;
  const uint32_t plane = uint32_t(s.voxel[a]) + (pos ? 1u : 0u);
  const uint32_t l = sh::portal_mip_aligned_level(plane, lc, target);
  if (l == lc) return m;
  glm::ivec3 beyond = s.voxel;
  beyond[a] += pos ? 1 : -1;
  m.moved = true;
  m.level = l;
  for (int b = 0; b < 3; ++b) m.voxel[b] = int(uint32_t(beyond[b]) >> (l - lc));
  m.texel = p.start_at(l, m.voxel);
  return m;
}

void mip_fine_voxels(const PackedPortal& p, const VoxelRay& r, uint32_t level, uint32_t a, float num, float ad,
                     glm::ivec3 v, glm::ivec3& wall, glm::ivec3& side) {
  const int f = 1 << level;
  const float up = float(f);
  const float num0 = num * up, ad0 = ad * up;  // level-0 space (exact)
  const bool pos = r.dir[a] > 0.0f;
  wall[a] = pos ? v[a] * f : std::min(v[a] * f + f, int(p.dims[a])) - 1;
  for (uint32_t b : {sh::portal_tangent0(a), sh::portal_tangent1(a)})
    wall[b] = int(sh::portal_cross_index(a, num0, ad0, b, r.org[b], r.dir[b], uint32_t(v[b] * f),
                                         uint32_t(std::min(v[b] * f + f, int(p.dims[b])))));
  side = wall;
  side[a] += pos ? -1 : 1;
}

Step step_ray(const PackedPortal& p, uint32_t div, const VoxelRay& r0, glm::ivec3 base) {
  Step s;
  DivInfo d = read_div_info(p, div);
  d.lo += base;  // instanced subspaces: a block div in its instance tile
  const VoxelRay r = level_ray(r0, d.level);  // mip-mapped space: the div's level
  const glm::vec3 lo(d.lo), hi(d.lo + d.size);
  float num = 0.0f;
  if (d.type == sh::kPortalDivExterior) {
    // The exterior div: the face the ray enters the world box by (surfaced on the outside).
    const uint32_t a = sh::portal_entry_axis(lo, hi, r.org, r.dir, num);
    if (a == 3) return s;
    s.axis = a, s.num = num, s.ad = std::abs(r.dir[a]);
    s.face = 2 * a + (r.dir[a] > 0.0f ? 0u : 1u);
    s.voxel[a] = r.dir[a] > 0.0f ? d.lo[a] : d.lo[a] + d.size[a] - 1;
  } else {
    // 1. The exit face: three slab tests, only the face each direction component points to.
    const uint32_t a = sh::portal_exit_axis(lo, hi, r.org, r.dir, num);
    if (a == 3) return s;
    s.axis = a, s.num = num, s.ad = std::abs(r.dir[a]);
    if (!sh::portal_before_tmax(num, s.ad, r.tmax)) {
      s.kind = StepKind::kTmax;
      return s;
    }
    s.face = 2 * a + (r.dir[a] > 0.0f ? 1u : 0u);
    s.voxel[a] = r.dir[a] > 0.0f ? d.lo[a] + d.size[a] - 1 : d.lo[a];
  }
  // 2. The crossing voxel along the tangents, and the face texel there.
  const uint32_t a = s.axis, t0 = sh::portal_tangent0(a), t1 = sh::portal_tangent1(a);
  for (uint32_t b : {t0, t1})
    s.voxel[b] = int(sh::portal_cross_index(a, s.num, s.ad, b, r.org[b], r.dir[b], uint32_t(d.lo[b]),
                                            uint32_t(d.lo[b] + d.size[b])));
  s.texel_uv = d.face_uv[s.face] + glm::uvec2(uint32_t(s.voxel[t0] - d.lo[t0]), uint32_t(s.voxel[t1] - d.lo[t1]));
  s.texel = atlas_at(p, s.texel_uv);
  // 3. What the texel says.
  if (s.texel == sh::kPortalOutside) s.kind = StepKind::kOutside;
  else if (sh::portal_texel_is_wall(s.texel)) s.kind = StepKind::kWall;
  else s.kind = StepKind::kNext;
  return s;
}

// ---- Instanced subspaces (docs/PORTAL.md, "Instanced subspaces") -------------------------------

InstancedStart instanced_start(const PackedPortal& p, const VoxelRay& r) {
  InstancedStart s;
  const Entry e = enter_world(p.fine_dims(), r);  // fine space: the flattened world's decision
  if (e.kind == Entry::kMiss) return s;
  if (e.kind == Entry::kEnter) {
    s.kind = InstancedStart::kDiv;
    s.div = sh::kPortalExteriorDiv;
    return s;
  }
  s.voxel = e.voxel;
  s.tile = glm::ivec3(glm::uvec3(e.voxel) >> p.scale_log2);
  uint32_t t = p.start[voxel_linear(p.dims, s.tile)];
  s.texels = 1;
  if (sh::portal_texel_is_wall(t) && is_instance_material(p, t - sh::kPortalWallBit)) {
    t = block_start_texel(p, t - sh::kPortalWallBit, s.tile, s.voxel);  // inside an instance: its block's start map
    s.texels = 2;
  }
  if (sh::portal_texel_is_wall(t)) {
    s.kind = InstancedStart::kInsideSolid;
    s.material = t - sh::kPortalWallBit;
    return s;
  }
  s.kind = InstancedStart::kDiv;
  s.div = t;
  return s;
}

namespace {
// enter_instance: the ray crosses into instance tile `tile` (material m) at fine voxel `fine`
// (`side`: the fine voxel before the plane): the block's start texel there is its first div, or
// a wall met on this plane.
InstancedEvent enter_instance(const PackedPortal& p, InstancedEvent e, uint32_t m, glm::ivec3 tile, glm::ivec3 fine,
                              glm::ivec3 side, uint32_t& div, glm::ivec3& cur_tile, uint32_t& texels, std::string* log) {
  ++texels;
  const uint16_t bt = block_start_texel(p, m, tile, fine);
  if (log)
    *log += fmt("enter instance: block %u at tile (%d, %d, %d), fine voxel (%d, %d, %d), block start texel %s\n",
                m - p.instance_base, tile.x, tile.y, tile.z, fine.x, fine.y, fine.z, texel_text(bt).c_str());
  if (sh::portal_texel_is_wall(bt)) {
    e.kind = InstancedEvent::kWall;
    e.wall = fine, e.side = side, e.material = bt - sh::kPortalWallBit;
    return e;
  }
  e.kind = InstancedEvent::kContinue;
  div = bt;
  cur_tile = tile;
  return e;
}
}  // namespace

InstancedEvent instanced_advance(const PackedPortal& p, const VoxelRay& r, uint32_t& div, glm::ivec3& tile, const Step& st,
                                 uint32_t& texels, std::string* log) {
  InstancedEvent e;
  if (st.kind == StepKind::kNoDirection || st.kind == StepKind::kTmax) return e;
  ++texels;
  const int S = 1 << p.scale_log2;
  const bool in_block = div >= p.top_divs;
  const float up = in_block ? 1.0f : float(S);  // top-level planes in fine space (exact)
  const uint32_t a = st.axis;
  const int sg = r.dir[a] > 0.0f ? 1 : -1;
  e.axis = a, e.num = st.num * up, e.ad = st.ad * up;
  if (st.kind == StepKind::kNext) {
    e.kind = InstancedEvent::kContinue;
    div = st.texel;
    return e;
  }
  if (in_block) {
    glm::ivec3 beyond = st.voxel;
    beyond[a] += sg;
    if (st.kind == StepKind::kWall) {
      e.kind = InstancedEvent::kWall;
      e.wall = beyond, e.side = st.voxel, e.material = st.texel - sh::kPortalWallBit;
      return e;
    }
    // leave_instance: out of the block's box, back to the top level through the tile beyond the
    // face (recomputed from the exit, no stack): its start texel.
    glm::ivec3 nt = tile;
    nt[a] += sg;
    if (nt[a] < 0 || nt[a] >= int(p.dims[a])) {
      if (log) *log += "leave instance: beyond the world: miss\n";
      return e;
    }
    ++texels;
    const uint16_t tt = p.start[voxel_linear(p.dims, nt)];
    if (log)
      *log += fmt("leave instance: tile (%d, %d, %d) beyond, top-level start texel %s\n", nt.x, nt.y, nt.z,
                  texel_text(tt).c_str());
    if (!sh::portal_texel_is_wall(tt)) {
      e.kind = InstancedEvent::kContinue;
      div = tt;
      return e;
    }
    const uint32_t m = tt - sh::kPortalWallBit;
    if (is_instance_material(p, m)) return enter_instance(p, e, m, nt, beyond, st.voxel, div, tile, texels, log);
    e.kind = InstancedEvent::kWall;
    e.wall = beyond, e.side = st.voxel, e.material = m;
    return e;
  }
  if (st.kind == StepKind::kOutside) return e;
  // A top-level wall texel: the tile beyond the plane (the exterior div: the boundary tile).
  glm::ivec3 wt = st.voxel;
  if (div != sh::kPortalExteriorDiv) wt[a] += sg;
  const uint32_t m = st.texel - sh::kPortalWallBit;
  const glm::ivec3 fine = instance_fine_voxel(p, r, a, e.num, e.ad, wt);
  if (is_instance_material(p, m)) return enter_instance(p, e, m, wt, fine, fine, div, tile, texels, log);
  e.kind = InstancedEvent::kWall;
  e.wall = fine, e.side = fine, e.material = m;
  return e;
}

Hit trace_instanced(const PackedPortal& p, const Ray& ray, std::string* log) {
  const VoxelRay r = to_voxel_ray(p.origin, p.voxel_size, ray);
  const glm::uvec3 fd = p.fine_dims();
  if (log)
    *log += fmt("fine-voxel-space ray: org (%.6g, %.6g, %.6g) dir (%.6g, %.6g, %.6g) t in (%g, %g)\n", r.org.x, r.org.y,
                r.org.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax);
  const InstancedStart st = instanced_start(p, r);
  if (st.kind == InstancedStart::kMiss) {
    if (log) *log += "start: the ray never enters the world box: miss\n";
    return miss_hit(0, 0);
  }
  if (st.kind == InstancedStart::kInsideSolid) {
    if (log)
      *log += fmt("start: fine voxel (%d, %d, %d) of tile (%d, %d, %d): inside a wall of material %u\n", st.voxel.x,
                  st.voxel.y, st.voxel.z, st.tile.x, st.tile.y, st.tile.z, st.material);
    return inside_hit(fd, r, st.voxel, st.material);
  }
  if (log) {
    if (st.div == sh::kPortalExteriorDiv) *log += "start: outside the world box: exterior div 0\n";
    else
      *log += fmt("start: fine voxel (%d, %d, %d) of tile (%d, %d, %d): div %u%s\n", st.voxel.x, st.voxel.y, st.voxel.z,
                  st.tile.x, st.tile.y, st.tile.z, st.div, st.div >= p.top_divs ? " (in the instance)" : "");
  }
  uint32_t cur = st.div, steps = 0, texels = st.texels;
  glm::ivec3 tile = st.tile;
  const int S = 1 << p.scale_log2;
  const uint32_t limit = 4u * p.div_count + 16u + 4u * (fd.x + fd.y + fd.z);
  while (steps < limit) {
    const bool in_block = cur >= p.top_divs;
    const glm::ivec3 base = in_block ? tile * S : glm::ivec3(0);
    const Step s = step_ray(p, cur, r, base);
    ++steps;
    if (log) {
      DivInfo d = read_div_info(p, cur);
      d.lo += base;
      const char* unit = in_block ? "fine voxels" : "tiles";
      if (s.kind == StepKind::kNoDirection)
        *log += fmt("div %u: no face ahead (zero direction or missed box): miss\n", cur);
      else
        *log += fmt("div %u [%d,%d,%d .. %d,%d,%d) %s%s: %s face %s at t = %.7g, %s (%d, %d, %d)%s", cur, d.lo.x, d.lo.y,
                    d.lo.z, d.lo.x + d.size.x, d.lo.y + d.size.y, d.lo.z + d.size.z, unit,
                    cur == sh::kPortalExteriorDiv ? " (exterior)" : in_block ? " (block div)" : "",
                    cur == sh::kPortalExteriorDiv ? "enters by" : "exits by", face_name(s.face), double(s.num / s.ad),
                    in_block ? "fine voxel" : "tile", s.voxel.x, s.voxel.y, s.voxel.z,
                    s.kind == StepKind::kTmax ? ": beyond tmax, miss\n"
                                              : fmt(", atlas texel (%u, %u) = %s\n", s.texel_uv.x, s.texel_uv.y,
                                                    texel_text(s.texel).c_str()).c_str());
    }
    const InstancedEvent e = instanced_advance(p, r, cur, tile, s, texels, log);
    if (e.kind == InstancedEvent::kContinue) continue;
    if (e.kind == InstancedEvent::kMiss) return miss_hit(steps, texels);
    const Hit h = wall_hit(fd, r, e.axis, e.num, e.ad, e.side, e.wall, e.material, steps, texels);
    if (log)
      *log += fmt("hit: fine voxel (%d, %d, %d) face %s, material %u, t = %.9g, uv = (%.6g, %.6g)\n", e.wall.x, e.wall.y,
                  e.wall.z, face_name(hit_face(h)), h.instance, double(h.t), double(h.u), double(h.v));
    return h;
  }
  if (log) *log += "step limit reached: miss\n";
  return miss_hit(steps, texels);
}

Hit trace_portal(const PackedPortal& p, const Ray& ray, std::string* log) {
  if (p.scale_log2) return trace_instanced(p, ray, log);
  const VoxelRay r = to_voxel_ray(p.origin, p.voxel_size, ray);
  if (log) *log += fmt("voxel-space ray: org (%.6g, %.6g, %.6g) dir (%.6g, %.6g, %.6g) t in (%g, %g)\n", r.org.x, r.org.y,
                       r.org.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax);
  const Start st = start_ray(p, r);
  if (st.kind == Start::kMiss) {
    if (log) *log += "start: the ray never enters the world box: miss\n";
    return miss_hit(0, 0);
  }
  if (st.kind == Start::kInsideSolid) {
    if (log) *log += fmt("start: voxel (%d, %d, %d), start texel %s: the ray starts inside a wall\n", st.voxel.x, st.voxel.y,
                         st.voxel.z, texel_text(st.texel).c_str());
    return inside_hit(p.dims, r, st.voxel, st.texel - sh::kPortalWallBit);
  }
  if (log) {
    if (st.div == sh::kPortalExteriorDiv) *log += "start: outside the world box: exterior div 0\n";
    else *log += fmt("start: voxel (%d, %d, %d), start texel %s\n", st.voxel.x, st.voxel.y, st.voxel.z, texel_text(st.texel).c_str());
  }
  // A start in glass: glass is solid to this tracer (a change of medium is a surface, below), so a
  // ray starting in it starts inside, as in a wall (the DDA's World::at holds the glass's material)
  if (st.div != sh::kPortalExteriorDiv) {
    const DivInfo sd = read_div_info(p, st.div);
    if (sd.type == sh::kPortalDivGlass) {
      if (log) *log += fmt("  div %u is glass of material %u: the ray starts inside it\n", st.div, sd.glass_material);
      return inside_hit(p.dims, r, st.voxel, sd.glass_material);
    }
  }
  uint32_t cur = st.div, steps = 0, texels = st.div == sh::kPortalExteriorDiv ? 0 : 1;
  const uint32_t limit = 4u * p.div_count + 16u;
  while (steps < limit) {
    const DivInfo d = read_div_info(p, cur);
    ++steps;
    const Step s = step_ray(p, cur, r);
    if (s.kind == StepKind::kNoDirection) {
      if (log) *log += fmt("div %u: no face ahead (zero direction or missed box): miss\n", cur);
      return miss_hit(steps, texels);
    }
    if (log)
      *log += fmt("div %u [%d,%d,%d .. %d,%d,%d)%s%s: %s face %s at t = %.7g, voxel (%d, %d, %d)", cur, d.lo.x, d.lo.y, d.lo.z,
                  d.lo.x + d.size.x, d.lo.y + d.size.y, d.lo.z + d.size.z,
                  d.type == sh::kPortalDivExterior ? " (exterior)" : d.type == sh::kPortalDivGlass ? " (glass)" : "",
                  d.level ? fmt(" level %u", d.level).c_str() : "",
                  d.type == sh::kPortalDivExterior ? "enters by" : "exits by", face_name(s.face), double(s.num / s.ad),
                  s.voxel.x, s.voxel.y, s.voxel.z);
    if (s.kind == StepKind::kTmax) {
      if (log) *log += ": beyond tmax, miss\n";
      return miss_hit(steps, texels);
    }
    ++texels;
    if (log) *log += fmt(", atlas texel (%u, %u) = %s\n", s.texel_uv.x, s.texel_uv.y, texel_text(s.texel).c_str());
    if (s.kind == StepKind::kOutside) return miss_hit(steps, texels);
    glm::ivec3 wall = s.voxel;
    if (d.type != sh::kPortalDivExterior) wall[s.axis] += r.dir[s.axis] > 0.0f ? 1 : -1;
    if (s.kind == StepKind::kWall && d.level > 0)
      return mip_surface_hit(p, r, d.level, s.axis, s.num, s.ad, wall, s.texel - sh::kPortalWallBit, steps, texels, log);
    if (s.kind == StepKind::kWall) {
      const Hit h = wall_hit(p.dims, r, s.axis, s.num, s.ad, s.voxel, wall, s.texel - sh::kPortalWallBit, steps, texels);
      if (log) *log += fmt("hit: voxel (%d, %d, %d) face %s, material %u, t = %.9g, uv = (%.6g, %.6g)\n", wall.x, wall.y,
                           wall.z, face_name(hit_face(h)), h.instance, double(h.t), double(h.u), double(h.v));
      return h;
    }
    // Next div; a change of medium (air <-> glass) is a surface for this tracer.
    const DivInfo nd = read_div_info(p, s.texel);
    const uint32_t next_medium = nd.type == sh::kPortalDivGlass ? nd.glass_material : 0xFFFFFFFFu;
    const uint32_t cur_medium = d.type == sh::kPortalDivGlass ? d.glass_material : 0xFFFFFFFFu;
    if (next_medium != cur_medium) {
      const uint32_t m = next_medium != 0xFFFFFFFFu ? next_medium : cur_medium;
      const Hit h = wall_hit(p.dims, r, s.axis, s.num, s.ad, s.voxel, wall, m, steps, texels);
      if (log)
        *log += fmt("hit: glass surface, voxel (%d, %d, %d) face %s, material %u, t = %.9g\n"
                    "  (this account ends at the first change of medium; the renderer refracts there and goes on,\n"
                    "  so the pixel shows what lies behind: docs/PORTAL.md \"Renderer\")\n",
                    wall.x, wall.y, wall.z, face_name(hit_face(h)), m, double(h.t));
      return h;
    }
    cur = s.texel;
    if (p.levels > 1 && d.type == sh::kPortalDivAir) {
      // Mip-mapped space: a coarser level from this plane on, when the level rule says so.
      const MipEnter me = mip_enter(p, r, d.level, s);
      if (me.moved) {
        ++texels;
        if (log)
          *log += fmt("mip: level %u from here, coarse voxel (%d, %d, %d), start texel %s\n", me.level, me.voxel.x,
                      me.voxel.y, me.voxel.z, texel_text(me.texel).c_str());
        if (!sh::portal_texel_is_wall(me.texel)) {
          cur = me.texel;
        } else {
          const float sc = sh::portal_level_scale(me.level - d.level);
          return mip_surface_hit(p, r, me.level, s.axis, s.num * sc, s.ad * sc, me.voxel, me.texel - sh::kPortalWallBit,
                                 steps, texels, log);
        }
      }
    }
  }
  if (log) *log += "step limit reached: miss\n";
  return miss_hit(steps, texels);
}

namespace {
// The voxel DDA over any occupancy: `at(v)` the voxel's material or kEmpty, v within dims.
template <class At>
Hit dda_over(glm::uvec3 dims, glm::vec3 origin, float voxel_size, At at, const Ray& ray, std::string* log) {
  const VoxelRay r = to_voxel_ray(origin, voxel_size, ray);
  const Entry e = enter_world(dims, r);
  if (e.kind == Entry::kMiss) {
    if (log) *log += "dda: the ray never enters the world box: miss\n";
    return miss_hit(0, 0);
  }
  auto inside = [&](glm::ivec3 v) {
    return v.x >= 0 && v.y >= 0 && v.z >= 0 && uint32_t(v.x) < dims.x && uint32_t(v.y) < dims.y && uint32_t(v.z) < dims.z;
  };
  glm::ivec3 c = e.voxel;
  uint32_t steps = 1, tests = 1;
  if (at(c) != kEmpty) {
    if (e.kind == Entry::kInside) return inside_hit(dims, r, c, at(c));
    // Entering from outside straight into a wall: the boundary face.
    glm::ivec3 side = c;
    return wall_hit(dims, r, e.axis, e.num, e.ad, side, c, at(c), steps, tests);
  }
  const uint32_t limit = 3u * (dims.x + dims.y + dims.z) + 8u;
  while (steps < limit) {
    float num = 0.0f;
    const uint32_t a = sh::portal_exit_axis(glm::vec3(c), glm::vec3(c) + 1.0f, r.org, r.dir, num);
    if (a == 3) return miss_hit(steps, tests);
    const float ad = std::abs(r.dir[a]);
    if (!sh::portal_before_tmax(num, ad, r.tmax)) return miss_hit(steps, tests);
    glm::ivec3 n = c;
    n[a] += r.dir[a] > 0.0f ? 1 : -1;
    if (log) *log += fmt("dda: voxel (%d, %d, %d) -> (%d, %d, %d)\n", c.x, c.y, c.z, n.x, n.y, n.z);
    if (!inside(n)) return miss_hit(steps, tests);
    ++tests;
    if (at(n) != kEmpty) return wall_hit(dims, r, a, num, ad, c, n, at(n), steps, tests);
    c = n;
    ++steps;
  }
  return miss_hit(steps, tests);
}
}  // namespace

Hit trace_dda(const World& w, const Ray& ray, std::string* log) {
  return dda_over(w.dims, w.origin, w.voxel_size, [&](glm::ivec3 v) { return w.at(v); }, ray, log);
}

Hit trace_dda_instanced(const InstancedWorld& iw, const Ray& ray) {
  const uint32_t S = iw.scale;
  const World& t = iw.top;
  return dda_over(iw.fine_dims(), t.origin, t.voxel_size / float(S), [&](glm::ivec3 v) -> uint16_t {
    const glm::uvec3 f(v);
    const uint16_t m = t.voxels[t.index(f / S)];
    if (m == kEmpty || m < iw.instance_base) return m;
    const glm::uvec3 l = f % S;
    return iw.blocks[m - iw.instance_base].voxels[l.x + S * (l.y + size_t(S) * l.z)];
  }, ray, nullptr);
}

std::string explain_portal(const PackedPortal& p, const World& w, const Ray& ray) {
  if (p.scale_log2) {
    const glm::uvec3 f = p.fine_dims();
    std::string s = fmt("portal-cpu: instanced world '%s' %u x %u x %u tiles of %u^3 fine voxels (%u x %u x %u), %u divs "
                        "(%u top level, %u in %u blocks), atlas %u x %u\n", w.name.c_str(), p.dims.x, p.dims.y, p.dims.z,
                        1u << p.scale_log2, f.x, f.y, f.z, p.div_count, p.top_divs, p.div_count - p.top_divs, p.blocks,
                        p.atlas_width, p.atlas_height);
    s += fmt("ray: org (%.6g, %.6g, %.6g) dir (%.6g, %.6g, %.6g)\n", ray.org.x, ray.org.y, ray.org.z, ray.dir.x, ray.dir.y,
             ray.dir.z);
    const Hit h = trace_portal(p, ray, &s);
    if (is_miss(h)) s += fmt("result: miss after %u divs, %u texels read\n", h.cells, h.tests);
    else {
      const uint32_t i = hit_voxel_index(h);
      s += fmt("result: material %u ('%s') at fine voxel (%u, %u, %u) face %s, t = %.9g, after %u divs, %u texels read\n",
               h.instance, h.instance < w.materials.size() ? w.materials[h.instance].name.c_str() : "?", i % f.x,
               (i / f.x) % f.y, i / (f.x * f.y), face_name(hit_face(h)), double(h.t), h.cells, h.tests);
    }
    return s;
  }
  std::string s = fmt("portal-cpu: world '%s' %u x %u x %u voxels, %u divs, atlas %u x %u\n", w.name.c_str(), p.dims.x,
                      p.dims.y, p.dims.z, p.div_count, p.atlas_width, p.atlas_height);
  s += fmt("ray: org (%.6g, %.6g, %.6g) dir (%.6g, %.6g, %.6g)\n", ray.org.x, ray.org.y, ray.org.z, ray.dir.x, ray.dir.y,
           ray.dir.z);
  const Hit h = trace_portal(p, ray, &s);
  if (is_miss(h)) s += fmt("result: miss after %u divs, %u texels read\n", h.cells, h.tests);
  else {
    const glm::ivec3 v = hit_voxel(w, h);
    s += fmt("result: material %u ('%s') at voxel (%d, %d, %d) face %s, t = %.9g, after %u divs, %u texels read\n",
             h.instance, h.instance < w.materials.size() ? w.materials[h.instance].name.c_str() : "?", v.x, v.y, v.z,
             face_name(hit_face(h)), double(h.t), h.cells, h.tests);
  }
  const Hit g = trace_dda(w, ray);
  s += fmt("voxel DDA: %s after %u voxels%s\n", is_miss(g) ? "miss" : fmt("material %u, t = %.9g", g.instance, double(g.t)).c_str(),
           g.cells, (g.instance == h.instance && g.triangle == h.triangle) ? " (agrees)" : " (DIFFERS)");
  return s;
}

// ---- Tracers ---------------------------------------------------------------------------------

PortalTracer::PortalTracer(uint32_t resolution, PortalOptions options) : resolution_(resolution), options_(options) {}
PortalTracer::PortalTracer(World world, PortalOptions options) : resolution_(0), options_(options) {
  build_ = std::make_unique<PortalBuild>(build_portal(std::move(world), options_));
  set_built();
}
PortalTracer::PortalTracer(PortalBuild build, PortalOptions options)
    : resolution_(0), options_(options), build_(std::make_unique<PortalBuild>(std::move(build))) {
  set_built();
}
void PortalTracer::build_scene(const Scene& scene, float) {
  build_.reset();  // a build that throws leaves the tracer unbuilt (Tracer::build)
  build_ = std::make_unique<PortalBuild>(build_portal(voxelize(scene, resolution_ ? resolution_ : 64), options_));
}
const PortalBuild& PortalTracer::portal() const {
  if (!build_) throw Error("portal-cpu: not built");
  return *build_;
}
void PortalTracer::trace_closest(std::span<const Ray> rays, std::span<Hit> hits) {
  const PackedPortal& p = portal().packed;
  const size_t chunk = 4096;
  parallel_rows((rays.size() + chunk - 1) / chunk, options_.threads, [&](size_t c) {
    for (size_t i = c * chunk; i < std::min(rays.size(), (c + 1) * chunk); ++i) hits[i] = trace_portal(p, rays[i]);
  });
}
AccelDump PortalTracer::dump() const {
  AccelDump d;
  if (!build_) return d;  // not built: no atlas, as every tracer's dump
  d.kind = "portal";
  const PackedPortal& p = portal().packed;
  d.extent = glm::uvec3(p.atlas_width, p.atlas_height, 1);
  d.texels.assign(p.atlas.begin(), p.atlas.end());
  return d;
}
std::string PortalTracer::explain(const Ray& ray) const { return explain_portal(portal().packed, portal().world, ray); }

void VoxelDdaTracer::build_scene(const Scene& scene, float) {
  world_.reset();  // a build that throws leaves the tracer unbuilt (Tracer::build)
  world_ = voxelize(scene, resolution_ ? resolution_ : 64);
}
const World& VoxelDdaTracer::world() const {
  if (!world_) throw Error("voxel-dda: not built");
  return *world_;
}
void VoxelDdaTracer::trace_closest(std::span<const Ray> rays, std::span<Hit> hits) {
  const World& w = world();
  const size_t chunk = 4096;
  parallel_rows((rays.size() + chunk - 1) / chunk, 0, [&](size_t c) {
    for (size_t i = c * chunk; i < std::min(rays.size(), (c + 1) * chunk); ++i) hits[i] = trace_dda(w, rays[i]);
  });
}

}  // namespace gridrt::portal
