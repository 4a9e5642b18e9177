#include "gridrt/common/shade.h"

#include <algorithm>
#include <cmath>

#include "gridrt/common/shared/transform.h"
// alpha.h calls min/max unqualified (GLSL built-ins); bring GLM's into gridrt::shared first.
namespace gridrt::shared {
using glm::floor;
using glm::max;
using glm::min;
}  // namespace gridrt::shared
#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/bounce.h"

namespace gridrt {

namespace {

glm::vec3 material_albedo(const Scene& scene, uint32_t material, glm::vec2 uv) {
  if (material >= scene.materials.size()) return glm::vec3(0.0f);
  const Material& m = scene.materials[material];
  glm::vec3 c = m.diffuse;
  if (m.diffuse_texture >= 0) {
    const Texture& t = scene.textures[m.diffuse_texture];
    if (t.width > 0 && t.height > 0) {
      const glm::uvec2 xy = shared::alpha_texel_coords(uv, t.width, t.height);
      const glm::u8vec4 texel = t.texel(xy.x, xy.y);
      c *= glm::vec3(texel.r, texel.g, texel.b) * (1.0f / 255.0f);
    }
  }
  return c;
}

// Light arriving at p with unit normal n, from every light (or the headlight at `eye`, the frame
// camera's); with shadow rays (`shadow_hits` non-empty) only the lights whose ray from pixel `pixel`
// is used and unoccluded.
glm::vec3 direct_light(const Scene& scene, glm::vec3 eye, glm::vec3 p, glm::vec3 n, const ShadeOptions* shadows = nullptr,
                       size_t pixel = 0, size_t pixels = 0) {
  glm::vec3 e(0.0f);
  if (scene.lights.empty()) {
    const glm::vec3 to_eye = eye - p;
    const float len = glm::length(to_eye);
    return len > 0.0f ? glm::vec3(std::max(0.0f, glm::dot(n, to_eye / len))) : glm::vec3(0.0f);
  }
  for (size_t i = 0; i < scene.lights.size(); ++i) {
    const Light& l = scene.lights[i];
    glm::vec3 to_light = l.directional ? l.position : l.position - p;
    const float d2 = glm::dot(to_light, to_light);
    if (!(d2 > 0.0f)) continue;
    const glm::vec3 L = to_light / std::sqrt(d2);
    const float cos = glm::dot(n, L);
    if (cos <= 0.0f) continue;
    if (shadows) {
      const size_t k = i * pixels + pixel;
      if (is_unused(shadows->shadow_rays[k]) || !is_miss(shadows->shadow_hits[k])) continue;
    }
    e += l.color * l.intensity * cos / (l.directional ? 1.0f : d2);
  }
  return e;
}

}  // namespace

glm::vec3 surface_albedo(const Scene& scene, uint32_t instance, uint32_t triangle, float u, float v) {
  if (instance >= scene.instances.size()) return glm::vec3(0.0f);
  const Mesh& mesh = scene.meshes[scene.instances[instance].mesh];
  if (triangle >= mesh.triangles.size()) return glm::vec3(0.0f);
  glm::vec2 uv(0.0f);
  if (!mesh.uvs.empty()) {
    const glm::uvec3 t = mesh.triangles[triangle];
    uv = shared::interpolate_uv(mesh.uvs[t[0]], mesh.uvs[t[1]], mesh.uvs[t[2]], u, v);
  }
  return material_albedo(scene, mesh.materials.empty() ? 0u : mesh.materials[triangle], uv);
}

std::vector<glm::vec3> shade(const Scene& scene, const GatherBuffer& g, std::span<const Ray> bounce_rays,
                             std::span<const Hit> bounce_hits, const ShadeOptions& options) {
  const bool bounce = !bounce_hits.empty();
  if (bounce && (bounce_hits.size() != g.size() || bounce_rays.size() != g.size()))
    throw Error("shade: bounce rays and hits must have one entry per pixel");
  const bool shadowed = !options.shadow_hits.empty();
  if (shadowed && (options.shadow_hits.size() != g.size() * scene.lights.size() ||
                   options.shadow_rays.size() != options.shadow_hits.size()))
    throw Error("shade: shadow rays and hits must have one entry per light and pixel");
  std::vector<glm::vec3> out(g.size(), scene.background);
  // The headlight's eye, once: a scene without a camera frames its bounds, a walk over every vertex
  // (made per pixel, 65,535 instances shaded 160 x 90 pixels in 1.2 s: an outside sweep's repro)
  const glm::vec3 eye = scene.lights.empty() ? scene.frame_camera().eye : glm::vec3(0.0f);
  for (size_t p = 0; p < g.size(); ++p) {
    if (!g.valid[p]) continue;
    const glm::vec3 albedo = material_albedo(scene, g.material[p], g.uv[p]);
    glm::vec3 c = albedo * (options.ambient + direct_light(scene, eye, g.position[p], g.normal[p],
                                                            shadowed ? &options : nullptr, p, g.size()));
    const float gloss = g.material[p] < scene.materials.size() ? scene.materials[g.material[p]].glossiness : 0.0f;
    if (bounce && gloss > 0.0f && !is_unused(bounce_rays[p])) {
      const Hit& h = bounce_hits[p];
      glm::vec3 b = scene.background;
      if (!is_miss(h) && h.instance < scene.instances.size()) {
        const bool gap = (h.flags & shared::kHitGapFill) != 0u;
        const float u = gap ? 1.0f / 3.0f : h.u, v = gap ? 1.0f / 3.0f : h.v;
        const glm::vec3 a = surface_albedo(scene, h.instance, h.triangle, u, v);
        const Ray& r = bounce_rays[p];
        const glm::vec3 hp = r.org + h.t * r.dir;
        // The bounce hit's normal, facing the bounce ray: gather_normal, as the shader takes it (a
        // plain cross product's length underflowed for edges about 1e-12, and every such hit was
        // shaded as facing +y on the CPU alone: an outside sweep)
        glm::vec3 n(0.0f, 1.0f, 0.0f);
        const Mesh& mesh = scene.meshes[scene.instances[h.instance].mesh];
        if (h.triangle < mesh.triangles.size()) {
          const shared::Affine m = shared::to_affine(scene.instances[h.instance].transform_at(g.time));
          const glm::uvec3 t = mesh.triangles[h.triangle];
          const glm::vec4 nn = shared::gather_normal(shared::transform_point(m, mesh.positions[t[0]]),
                                                     shared::transform_point(m, mesh.positions[t[1]]),
                                                     shared::transform_point(m, mesh.positions[t[2]]), r.dir);
          if (nn.w > 0.0f) n = glm::vec3(nn);
        }
        b = a * (options.ambient + direct_light(scene, eye, hp, n));
      }
      c = (1.0f - gloss) * c + gloss * b;
    }
    out[p] = c;
  }
  for (glm::vec3& c : out) c = glm::clamp(c * options.exposure, glm::vec3(0.0f), glm::vec3(1.0f));
  return out;
}

}  // namespace gridrt
