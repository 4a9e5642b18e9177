#include "gridrt/common/gather.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "gridrt/common/camera.h"
#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/bounce.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/shadow.h"
#include "gridrt/common/shared/transform.h"
#include "gridrt/common/shared/triangle.h"

namespace gridrt {

namespace {

// 7 bits to every third bit of 21.
uint32_t spread3_7(uint32_t v) {
  uint32_t out = 0;
  for (uint32_t b = 0; b < 7; ++b) out |= ((v >> b) & 1u) << (3 * b);
  return out;
}

// The direction's face of the cube (the axis of its largest component, and its sign) and its cell
// of 16 x 16 on that face: 6 * 256 bins, 11 bits.
uint32_t direction_bin(glm::vec3 d) {
  const glm::vec3 a = glm::abs(d);
  const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
  const float m = a[axis];
  const float u = d[(axis + 1) % 3] / m, v = d[(axis + 2) % 3] / m;  // in [-1, 1]
  const uint32_t face = uint32_t(axis * 2 + (d[axis] < 0.0f ? 1 : 0));
  const uint32_t iu = uint32_t(std::clamp((u + 1.0f) * 8.0f, 0.0f, 15.0f));
  const uint32_t iv = uint32_t(std::clamp((v + 1.0f) * 8.0f, 0.0f, 15.0f));
  return (face * 16u + iu) * 16u + iv;
}

bool finite3(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

std::vector<uint32_t> coherent_ray_order(std::span<const Ray> rays) {
  auto usable = [](const Ray& r) { return !is_unused(r) && finite3(r.org) && finite3(r.dir) && r.dir != glm::vec3(0.0f); };
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (const Ray& r : rays)
    if (usable(r)) {
      lo = glm::min(lo, r.org);
      hi = glm::max(hi, r.org);
    }
  const glm::vec3 extent = glm::max(hi - lo, glm::vec3(std::numeric_limits<float>::min()));
  std::vector<std::pair<uint32_t, uint32_t>> keyed(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    uint32_t key = 0xFFFFFFFFu;
    if (usable(r)) {
      // The origin's lattice cell, in double: an extent near float's largest does not overflow
      uint32_t m = 0;
      for (int a = 0; a < 3; ++a) {
        const double f = (double(r.org[a]) - double(lo[a])) / double(extent[a]) * 128.0;
        m |= spread3_7(uint32_t(std::clamp(f, 0.0, 127.0))) << a;
      }
      key = direction_bin(r.dir) << 21 | m;
    }
    keyed[i] = {key, uint32_t(i)};
  }
  std::stable_sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<uint32_t> order(rays.size());
  for (size_t k = 0; k < keyed.size(); ++k) order[k] = keyed[k].second;
  return order;
}

glm::vec2 pixel_random(uint32_t x, uint32_t y, uint32_t frame) { return shared::pixel_random(x, y, frame); }

float cone_cos_max(float glossiness) {
  return std::cos((1.0f - glossiness) * (0.5f * std::numbers::pi_v<float>));
}

GatherBuffer GatherBuffer::blank(uint32_t width, uint32_t height) {
  GatherBuffer g;
  g.width = width;
  g.height = height;
  const size_t n = g.size();
  g.valid.assign(n, 0);
  g.position.assign(n, glm::vec3(0.0f));
  g.normal.assign(n, glm::vec3(0.0f));
  g.incident.assign(n, glm::vec3(0.0f));
  g.material.assign(n, kNoMaterial);
  g.uv.assign(n, glm::vec2(0.0f));
  g.launch_ref.assign(n, shared::kNoRef);
  g.hit.assign(n, Hit{0.0f, shared::kNoInstance, 0, 0.0f, 0.0f, 0, 0, 0});
  return g;
}

GatherBuffer make_gather(const Scene& scene, Tracer& tracer, const Camera& camera, uint32_t width,
                         uint32_t height, float time) {
  if (width == 0 || height == 0) throw Error("gather buffer: image size must be at least 1 x 1");
  GatherBuffer g = GatherBuffer::blank(width, height);
  g.time = time;
  const size_t n = g.size();
  const std::vector<Ray> rays = camera_rays(camera, width, height);
  tracer.trace(rays, g.hit);

  std::vector<shared::Affine> transforms(scene.instances.size());
  for (size_t i = 0; i < scene.instances.size(); ++i) transforms[i] = shared::to_affine(scene.instances[i].transform_at(time));
  for (size_t p = 0; p < n; ++p) {
    const Ray& r = rays[p];
    const Hit& h = g.hit[p];
    g.incident[p] = r.dir;
    if (is_miss(h) || h.instance >= scene.instances.size()) continue;
    const Mesh& mesh = scene.meshes[scene.instances[h.instance].mesh];
    if (h.triangle >= mesh.triangles.size()) continue;
    const glm::uvec3 t = mesh.triangles[h.triangle];
    const glm::vec3 a = shared::transform_point(transforms[h.instance], mesh.positions[t[0]]);
    const glm::vec3 b = shared::transform_point(transforms[h.instance], mesh.positions[t[1]]);
    const glm::vec3 c = shared::transform_point(transforms[h.instance], mesh.positions[t[2]]);
    // The unit normal facing the viewer, the hit point and its uv (common/shared/bounce.h, as
    // the GPU gather computes them)
    const glm::vec4 nrm = shared::gather_normal(a, b, c, r.dir);
    if (!(nrm.w > 0.0f)) continue;
    g.valid[p] = 1;
    // On the triangle at the camera ray's weights (shared/triangle.h gather_barycentrics, as the
    // GPU's resolve makes them; surface_point), not eye + t * dir
    const glm::vec2 bc = shared::gather_barycentrics(a, b, c, r.org, r.dir);
    g.position[p] = shared::surface_point(a, b, c, bc);
    g.normal[p] = glm::vec3(nrm);
    g.material[p] = mesh.materials.empty() ? 0u : mesh.materials[h.triangle];
    if (!mesh.uvs.empty()) g.uv[p] = shared::interpolate_uv(mesh.uvs[t[0]], mesh.uvs[t[1]], mesh.uvs[t[2]], bc.x, bc.y);
    g.launch_ref[p] = (h.instance << 16) | h.triangle;
  }
  return g;
}

std::vector<Ray> bounce_rays(const Scene& scene, const GatherBuffer& g, uint32_t frame) {
  Ray unused;
  unused.org = glm::vec3(0.0f);
  unused.dir = glm::vec3(0.0f, 0.0f, 1.0f);
  unused.tmin = 0.0f;
  unused.tmax = 0.0f;
  unused.launch_normal = glm::vec3(0.0f);
  unused.launch_ref = shared::kNoRef;
  std::vector<Ray> rays(g.size(), unused);
  std::vector<float> cos_max(scene.materials.size());
  for (size_t m = 0; m < scene.materials.size(); ++m) cos_max[m] = cone_cos_max(scene.materials[m].glossiness);
  for (uint32_t y = 0; y < g.height; ++y)
    for (uint32_t x = 0; x < g.width; ++x) {
      const size_t p = size_t(y) * g.width + x;
      if (!g.valid[p] || g.material[p] >= scene.materials.size()) continue;
      const float gloss = scene.materials[g.material[p]].glossiness;
      if (!(gloss > 0.0f)) continue;
      // The glossy direction (common/shared/bounce.h, as the GPU computes it)
      const glm::vec3 dir = shared::bounce_direction(g.incident[p], g.normal[p], gloss, cos_max[g.material[p]],
                                                     shared::pixel_random(x, y, frame));
      Ray& r = rays[p];
      r.org = g.position[p];
      r.dir = dir;
      r.tmin = 0.0f;
      r.tmax = std::numeric_limits<float>::infinity();
      r.launch_normal = g.normal[p];
      r.launch_ref = g.launch_ref[p];
    }
  return rays;
}

bool shadows_for(ShadowMode mode, const Scene& scene) {
  // Asked for on a scene without lights: no shadow ray to trace (an outside sweep: it ran, exit 0)
  if (mode == ShadowMode::on && scene.lights.empty())
    throw OptionsError("--shadows on: the scene has no lights, so there is no shadow ray to trace (leave it out, or "
                       "give the scene a light)");
  return mode == ShadowMode::on || (mode == ShadowMode::automatic && !scene.lights.empty());
}

void check_shadow_lights(const Scene& scene) {
  if (scene.lights.size() > shared::kMaxShadowLights)
    throw Error("shadows: the scene has " + std::to_string(scene.lights.size()) + " lights; shadow rays are traced to " +
                std::to_string(shared::kMaxShadowLights) + " at most (--shadows off renders it unshadowed)");
}

std::vector<Ray> shadow_rays(const Scene& scene, const GatherBuffer& g) {
  check_shadow_lights(scene);
  const size_t pixels = g.size();
  std::vector<Ray> rays(scene.lights.size() * pixels, shared::empty_shadow_ray());
  for (size_t i = 0; i < scene.lights.size(); ++i) {
    const Light& l = scene.lights[i];
    for (size_t p = 0; p < pixels; ++p)
      if (g.valid[p])
        rays[i * pixels + p] = shared::shadow_ray(g.position[p], g.normal[p], g.launch_ref[p], l.position, l.directional);
  }
  return rays;
}

}  // namespace gridrt
