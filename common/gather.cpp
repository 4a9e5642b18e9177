#include "common/gather.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "common/camera.h"
#include "common/shared/transform.h"

namespace gridrt {

namespace {

// PCG-style integer hash (Jarzynski and Olano 2020, "Hash Functions for GPU Rendering").
uint32_t pcg_hash(uint32_t v) {
  const uint32_t state = v * 747796405u + 2891336453u;
  const uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

// An orthonormal basis around unit vector n (Duff et al. 2017).
void basis(const glm::vec3& n, glm::vec3& t, glm::vec3& b) {
  const float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  const float c = n.x * n.y * a;
  t = glm::vec3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
  b = glm::vec3(c, sign + n.y * n.y * a, -n.y);
}

}  // namespace

glm::vec2 pixel_random(uint32_t x, uint32_t y, uint32_t frame) {
  const uint32_t h1 = pcg_hash(x ^ pcg_hash(y ^ pcg_hash(frame)));
  const uint32_t h2 = pcg_hash(h1);
  return glm::vec2(float(h1 >> 8) * (1.0f / 16777216.0f), float(h2 >> 8) * (1.0f / 16777216.0f));
}

GatherBuffer make_gather(const Scene& scene, Tracer& tracer, const Camera& camera, uint32_t width,
                         uint32_t height, float time) {
  if (width == 0 || height == 0) throw Error("gather buffer: image size must be at least 1 x 1");
  GatherBuffer g;
  g.width = width;
  g.height = height;
  g.time = time;
  const size_t n = g.size();
  std::vector<Ray> rays(n);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x) rays[size_t(y) * width + x] = camera_ray(camera, width, height, x, y);
  g.hit.resize(n);
  tracer.trace(rays, g.hit);

  g.valid.assign(n, 0);
  g.position.assign(n, glm::vec3(0.0f));
  g.normal.assign(n, glm::vec3(0.0f));
  g.incident.resize(n);
  g.material.assign(n, kNoMaterial);
  g.uv.assign(n, glm::vec2(0.0f));
  g.launch_ref.assign(n, shared::kNoRef);
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
    glm::vec3 nrm = glm::cross(b - a, c - a);
    const float len = glm::length(nrm);
    if (!(len > 0.0f)) continue;
    nrm /= len;
    if (glm::dot(nrm, r.dir) > 0.0f) nrm = -nrm;  // facing the viewer
    g.valid[p] = 1;
    g.position[p] = r.org + h.t * r.dir;
    g.normal[p] = nrm;
    g.material[p] = mesh.materials.empty() ? 0u : mesh.materials[h.triangle];
    if (!mesh.uvs.empty()) {
      const float w = 1.0f - h.u - h.v;
      g.uv[p] = w * mesh.uvs[t[0]] + h.u * mesh.uvs[t[1]] + h.v * mesh.uvs[t[2]];
    }
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
  const float half_pi = 0.5f * std::numbers::pi_v<float>;
  for (uint32_t y = 0; y < g.height; ++y)
    for (uint32_t x = 0; x < g.width; ++x) {
      const size_t p = size_t(y) * g.width + x;
      if (!g.valid[p] || g.material[p] >= scene.materials.size()) continue;
      const float gloss = scene.materials[g.material[p]].glossiness;
      if (!(gloss > 0.0f)) continue;
      const glm::vec3 d = g.incident[p], n = g.normal[p];
      // Mirror direction about the gather normal.
      const glm::vec3 mirror = glm::normalize(d - 2.0f * glm::dot(d, n) * n);
      glm::vec3 dir = mirror;
      if (gloss < 1.0f) {
        // Uniform direction in the cone of half-angle (1 - g) pi/2 about the mirror direction.
        const glm::vec2 xi = pixel_random(x, y, frame);
        const float cos_max = std::cos((1.0f - gloss) * half_pi);
        const float cos_t = 1.0f - xi.x * (1.0f - cos_max);
        const float sin_t = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
        const float phi = 2.0f * std::numbers::pi_v<float> * xi.y;
        glm::vec3 t, b;
        basis(mirror, t, b);
        dir = glm::normalize(cos_t * mirror + sin_t * (std::cos(phi) * t + std::sin(phi) * b));
        // Fold directions below the surface back into the normal's hemisphere.
        const float dn = glm::dot(dir, n);
        if (dn < 0.0f) dir = glm::normalize(dir - 2.0f * dn * n);
        if (!(glm::dot(dir, n) > 0.0f)) dir = mirror;
      }
      Ray& r = rays[p];
      r.org = g.position[p];
      r.dir = dir;
      r.tmin = 0.0f;
      r.tmax = std::numeric_limits<float>::infinity();
      r.launch_normal = n;
      r.launch_ref = g.launch_ref[p];
    }
  return rays;
}

}  // namespace gridrt
