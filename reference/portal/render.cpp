// render.cpp: primary + two shadow rays per pixel through the portal tracer, with non-forking
// refraction, as three separate loops or as one loop with state transitions (trace.h).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>

#include "gridrt/common/camera.h"
#include "gridrt/common/parallel.h"
#include "gridrt/reference/portal/trace.h"
#include "gridrt/reference/portal/instance.h"

namespace gridrt::portal {

namespace sh = gridrt::shared;

bool refract_or_reflect(glm::vec3 d, glm::vec3 n, float eta, glm::vec3& out) {
  const float cosi = -glm::dot(n, d);
  const float k = 1.0f - eta * eta * (1.0f - cosi * cosi);
  if (k < 0.0f) {
    out = d + 2.0f * cosi * n;  // total internal reflection: the reflected ray instead
    return false;
  }
  out = glm::normalize(eta * d + (eta * cosi - std::sqrt(k)) * n);
  return true;
}

namespace {

enum Mode : uint32_t { kPrimary = 0, kShadowA = 1, kShadowB = 2, kDone = 3 };

// Everything one pixel carries: the current ray and div, and the primary hit for the shadow rays.
struct PixelState {
  uint32_t mode = kPrimary;
  uint32_t div = 0;
  VoxelRay ray;
  glm::vec3 filter{1.0f};      // accumulated colour filter (glass)
  uint32_t interfaces = 0;     // glass surfaces crossed or reflected from
  bool in_glass = false;
  uint32_t glass = 0;          // material of the glass the ray is in
  glm::vec3 glass_entry{0.0f};
  glm::vec3 point{0.0f}, normal{0.0f}, albedo{0.0f};
  uint32_t hit_div = 0;
  float light = 0.0f;          // sum over lights of visible * N.L
  glm::vec3 color{0.0f};
  glm::vec3 mip_acc{0.0f};     // mip-mapped space: light of the translucent coarse voxels passed (front to back)
  uint32_t steps_primary = 0, steps_shadow = 0, iterations = 0, refractions = 0, reflections = 0, shadow_rays = 0;
  bool cut = false;            // past the iteration limit: ended as background
};

struct Context {
  const PortalBuild& build;
  const RenderOptions& opt;
  glm::vec3 lights[2];
};

void finish(const Context& c, PixelState& s) {
  s.color = s.filter * s.albedo * (c.opt.ambient + (1.0f - c.opt.ambient) * 0.5f * s.light) + s.mip_acc;
  s.mode = kDone;
}

// Set up shadow ray `i` (0 or 1) or, past the last, finish the pixel.
void begin_shadow(const Context& c, PixelState& s, uint32_t i) {
  for (; i < 2; ++i) {
    const glm::vec3 to = c.lights[i] - s.point;
    if (glm::dot(to, s.normal) <= 0.0f) continue;  // the light is behind the surface
    s.ray.org = s.point;
    s.ray.dir = to;
    s.ray.tmin = 0.0f;
    s.ray.tmax = 1.0f;  // reaching t = 1 is reaching the light
    s.div = s.hit_div;  // the shadow ray starts in the div the primary ray ended in: no offset needed
    s.mode = kShadowA + i;
    ++s.shadow_rays;
    return;
  }
  finish(c, s);
}

void begin_primary(const Context& c, PixelState& s, const Ray& ray) {
  const PackedPortal& p = c.build.packed;
  s.ray = to_voxel_ray(p.origin, p.voxel_size, ray);
  const Start st = start_ray(p, s.ray);
  if (st.kind == Start::kMiss) {
    s.color = background_of(c.opt, c.build.world);
    s.mode = kDone;
  } else if (st.kind == Start::kInsideSolid) {
    s.albedo = c.build.world.materials[st.texel - sh::kPortalWallBit].color;
    s.color = s.albedo * c.opt.ambient;
    s.mode = kDone;
  } else {
    s.div = st.div;
    s.mode = kPrimary;
    // A camera in glass: the ray starts in that glass (its filter from here, its surface refracts)
    if (st.div != sh::kPortalExteriorDiv) {
      const DivInfo d = read_div_info(p, st.div);
      if (d.type == sh::kPortalDivGlass) {
        s.in_glass = true;
        s.glass = d.glass_material;
        s.glass_entry = s.ray.org + s.ray.tmin * s.ray.dir;
      }
    }
  }
}

glm::vec3 crossing(const VoxelRay& r, const Step& st) { return r.org + (st.num / st.ad) * r.dir; }

glm::vec3 crossing(const VoxelRay& r, float num, float ad) { return r.org + (num / ad) * r.dir; }

// Mip-mapped space: the primary ray meets coarse wall voxel `v` of level `level` (material m) on
// the plane (axis, num, ad; level space). Opaque (resolve): back to full resolution, the fine
// voxel's own hit, shaded with its shadow rays. Partly occupied: translucent, composited front to
// back with alpha = coverage (lit by both lights, unshadowed), and the ray goes on through the
// coarse voxel to the next one: a div of that level (the traversal resumes there), another coarse
// wall, or the outside.
void mip_surface(const Context& c, PixelState& s, uint32_t level, uint32_t axis, float num, float ad, glm::ivec3 v,
                 uint32_t m) {
  const PackedPortal& p = c.build.packed;
  const World& w = c.build.world;
  const glm::uvec3 ld = p.level_dims(level);
  for (uint32_t guard = 0; guard < ld.x + ld.y + ld.z + 3u; ++guard) {
    glm::vec3 n(0.0f);
    n[axis] = s.ray.dir[axis] > 0.0f ? -1.0f : 1.0f;
    const glm::vec3 x = crossing(s.ray, num, ad);
    if (p.resolve[m]) {
      glm::ivec3 wall, side;
      mip_fine_voxels(p, s.ray, level, axis, num, ad, v, wall, side);
      const uint16_t tw = p.start_at(0, wall), ts = p.start_at(0, side);
      s.point = x, s.normal = n;
      s.albedo = w.materials[sh::portal_texel_is_wall(tw) ? tw - sh::kPortalWallBit : m].color;
      if (sh::portal_texel_is_wall(ts)) {  // the fine voxel before the face is solid: no shadow ray leaves it
        finish(c, s);
        return;
      }
      s.hit_div = ts;
      begin_shadow(c, s, 0);
      return;
    }
    float lit = 0.0f;
    for (int i = 0; i < 2; ++i) lit += std::max(0.0f, glm::dot(n, glm::normalize(c.lights[i] - x)));
    const float shade = c.opt.ambient + (1.0f - c.opt.ambient) * 0.5f * lit;
    s.mip_acc += s.filter * (p.coverage[m] * shade) * w.materials[m].color;
    s.filter *= 1.0f - p.coverage[m];
    ++s.steps_primary, ++s.iterations;
    // Through the coarse voxel: its exit face and the voxel beyond.
    const VoxelRay rl = level_ray(s.ray, level);
    float en = 0.0f;
    const uint32_t a = sh::portal_exit_axis(glm::vec3(v), glm::vec3(v) + 1.0f, rl.org, rl.dir, en);
    const glm::ivec3 next = v + glm::ivec3(a < 3 && rl.dir[a] > 0.0f ? 1 : -1) * glm::ivec3(a == 0, a == 1, a == 2);
    if (a == 3 || !sh::portal_before_tmax(en, std::abs(rl.dir[a]), rl.tmax) || glm::any(glm::lessThan(next, glm::ivec3(0))) ||
        glm::any(glm::greaterThanEqual(glm::uvec3(next), ld))) {
      s.color = s.filter * background_of(c.opt, c.build.world) + s.mip_acc;
      s.mode = kDone;
      return;
    }
    const uint16_t t = p.start_at(level, next);
    if (!sh::portal_texel_is_wall(t)) {
      s.div = t;
      return;
    }
    axis = a, num = en, ad = std::abs(rl.dir[a]), v = next, m = t - sh::kPortalWallBit;
  }
  s.color = s.filter * background_of(c.opt, c.build.world) + s.mip_acc;  // not reached: the coarse voxels ahead are finite
  s.mode = kDone;
}

// A pixel whose loop reached `limit` iterations unfinished: its rays cycle between divs; it ends as
// background (sh::portal_pixel_iteration_limit).
void end_if_cut(const Context& c, PixelState& s, uint32_t limit) {
  if (s.mode == kDone || s.iterations < limit) return;
  s.color = background_of(c.opt, c.build.world);
  s.mode = kDone;
  s.cut = true;
}

glm::vec3 pow3(glm::vec3 f, float d) { return {std::pow(f.x, d), std::pow(f.y, d), std::pow(f.z, d)}; }

// The state transitions: what one step's result does to the pixel.
void transition(const Context& c, PixelState& s, const Step& st) {
  const PackedPortal& p = c.build.packed;
  const World& w = c.build.world;
  ++s.iterations;
  if (s.mode == kPrimary) {
    ++s.steps_primary;
    if (st.kind == StepKind::kNext) {
      const DivInfo nd = read_div_info(p, st.texel);
      const bool next_glass = nd.type == sh::kPortalDivGlass;
      if (next_glass == s.in_glass && (!next_glass || nd.glass_material == s.glass)) {
        const uint32_t from = s.div;
        s.div = st.texel;
        if (p.levels > 1 && !next_glass) {
          // Mip-mapped space: a coarser level from this plane on, when the level rule says so.
          const DivInfo cd = read_div_info(p, from);
          if (cd.type != sh::kPortalDivAir) return;
          const MipEnter me = mip_enter(p, s.ray, cd.level, st);
          if (!me.moved) return;
          if (!sh::portal_texel_is_wall(me.texel)) {
            s.div = me.texel;
            return;
          }
          const float sc = sh::portal_level_scale(me.level - cd.level);
          mip_surface(c, s, me.level, st.axis, st.num * sc, st.ad * sc, me.voxel, me.texel - sh::kPortalWallBit);
        }
        return;
      }
      const uint32_t gm = next_glass ? nd.glass_material : s.glass;  // the glass whose surface this is
      const glm::vec3 x = crossing(s.ray, st);
      glm::vec3 n(0.0f);
      n[st.axis] = s.ray.dir[st.axis] > 0.0f ? -1.0f : 1.0f;
      if (!c.opt.refraction) {  // glass as an opaque wall
        s.point = x, s.normal = n, s.albedo = w.materials[gm].color, s.hit_div = s.div;
        begin_shadow(c, s, 0);
        return;
      }
      if (++s.interfaces > c.opt.max_interfaces) {
        s.filter = glm::vec3(0.0f);
        s.color = glm::vec3(0.0f);
        s.mode = kDone;
        return;
      }
      const float n_from = s.in_glass ? w.materials[s.glass].ior : 1.0f;
      const float n_to = next_glass ? w.materials[nd.glass_material].ior : 1.0f;
      glm::vec3 d;
      if (refract_or_reflect(glm::normalize(s.ray.dir), n, n_from / n_to, d)) {
        ++s.refractions;
        if (s.in_glass) s.filter *= pow3(w.materials[s.glass].filter, glm::length(x - s.glass_entry));
        s.in_glass = next_glass;
        if (next_glass) s.glass = nd.glass_material, s.glass_entry = x;
        s.div = st.texel;
      } else {
        ++s.reflections;  // stays in the current div
      }
      s.ray.org = x;
      s.ray.dir = d;
      s.ray.tmin = 0.0f;
      s.ray.tmax = std::numeric_limits<float>::infinity();
      return;
    }
    if (st.kind == StepKind::kWall && p.levels > 1) {
      const DivInfo cd = read_div_info(p, s.div);
      if (cd.level > 0) {
        glm::ivec3 v = st.voxel;
        v[st.axis] += s.ray.dir[st.axis] > 0.0f ? 1 : -1;
        mip_surface(c, s, cd.level, st.axis, st.num, st.ad, v, st.texel - sh::kPortalWallBit);
        return;
      }
    }
    if (st.kind == StepKind::kWall) {
      const glm::vec3 x = crossing(s.ray, st);
      if (s.in_glass) s.filter *= pow3(w.materials[s.glass].filter, glm::length(x - s.glass_entry));
      s.point = x;
      s.normal = glm::vec3(0.0f);
      s.normal[st.axis] = s.ray.dir[st.axis] > 0.0f ? -1.0f : 1.0f;
      s.albedo = w.materials[st.texel - sh::kPortalWallBit].color;
      s.hit_div = s.div;
      begin_shadow(c, s, 0);
      return;
    }
    s.color = s.filter * background_of(c.opt, c.build.world) + s.mip_acc;  // outside, tmax or no direction
    s.mode = kDone;
    return;
  }
  // Shadow rays: reaching t = 1 (tmax) is reaching the light, as is leaving a voxelized scene's
  // world (World::open_outside); a wall, glass or a tile map's outside blocks.
  ++s.steps_shadow;
  const uint32_t i = s.mode - kShadowA;
  if (st.kind == StepKind::kNext) {
    const DivInfo nd = read_div_info(p, st.texel);
    const bool next_glass = nd.type == sh::kPortalDivGlass;
    if (next_glass == s.in_glass && (!next_glass || nd.glass_material == s.glass)) {
      s.div = st.texel;
      return;
    }
  } else if (st.kind == StepKind::kTmax || (st.kind == StepKind::kOutside && c.build.world.open_outside)) {
    s.light += glm::dot(s.normal, glm::normalize(s.ray.dir));
  }
  begin_shadow(c, s, i + 1);
}

}  // namespace

std::vector<glm::vec3> render(const PortalBuild& build, const Camera& camera, const RenderOptions& opt, RenderStats* stats) {
  if (build.packed.scale_log2) return render_instanced(build, camera, opt, stats);
  if (opt.width == 0 || opt.height == 0) throw Error("portal render: image size must be at least 1 x 1");
  const auto t0 = std::chrono::steady_clock::now();
  const World& w = build.world;
  Context c{build, opt, {}};
  for (int i = 0; i < 2; ++i)
    c.lights[i] = w.to_voxel(size_t(i) < w.lights.size() ? w.lights[size_t(i)] : camera.eye);
  camera_frame(camera);  // throws for a degenerate camera
  std::vector<glm::vec3> image(size_t(opt.width) * opt.height);
  std::vector<RenderStats> row_stats(opt.height);
  const PackedPortal& p = build.packed;
  const unsigned threads = thread_count_or_hardware(opt.threads);
  std::atomic<uint32_t> next{0};
  const uint32_t limit = sh::portal_pixel_iteration_limit(p.div_count, p.fine_dims(), opt.max_interfaces);
  auto work = [&] {
    std::vector<PixelState> row(opt.width);
    for (uint32_t y; (y = next.fetch_add(1)) < opt.height;) {
      for (uint32_t x = 0; x < opt.width; ++x) {
        row[x] = PixelState{};
        begin_primary(c, row[x], camera_ray(camera, opt.width, opt.height, x, y));
      }
      if (opt.state_machine) {
        // One loop: the same step for every kind of ray, transitions at the end of each iteration.
        for (uint32_t x = 0; x < opt.width; ++x) {
          PixelState& s = row[x];
          while (s.mode != kDone && s.iterations < limit) transition(c, s, step_ray(p, s.div, s.ray));
          end_if_cut(c, s, limit);
        }
      } else {
        // Three loops: every pixel's primary ray, then every first shadow ray, then every second.
        for (uint32_t mode = kPrimary; mode <= kShadowB; ++mode)
          for (uint32_t x = 0; x < opt.width; ++x) {
            PixelState& s = row[x];
            while (s.mode == mode && s.iterations < limit) transition(c, s, step_ray(p, s.div, s.ray));
            end_if_cut(c, s, limit);
          }
      }
      RenderStats& rs = row_stats[y];
      for (uint32_t x = 0; x < opt.width; ++x) {
        const PixelState& s = row[x];
        image[size_t(y) * opt.width + x] = s.color;
        rs.primary_rays += 1;
        rs.shadow_rays += s.shadow_rays;
        rs.primary_steps += s.steps_primary;
        rs.shadow_steps += s.steps_shadow;
        rs.loop_iterations += s.iterations;
        rs.refractions += s.refractions;
        rs.reflections += s.reflections;
        rs.cut_pixels += s.cut;
      }
    }
  };
  run_on_threads(threads, work);
  if (stats) {
    *stats = RenderStats{};
    for (const RenderStats& r : row_stats) {
      stats->primary_rays += r.primary_rays, stats->shadow_rays += r.shadow_rays;
      stats->primary_steps += r.primary_steps, stats->shadow_steps += r.shadow_steps;
      stats->loop_iterations += r.loop_iterations, stats->refractions += r.refractions, stats->reflections += r.reflections;
      stats->cut_pixels += r.cut_pixels;
    }
    stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  return image;
}

}  // namespace gridrt::portal
