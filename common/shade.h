// shade.h: simple, deterministic shading of a gather buffer and its glossy bounce, for images.
#pragma once

#include <optional>
#include <span>
#include <vector>

#include "gridrt/common/gather.h"

namespace gridrt {

struct ShadeOptions {
  float ambient = 0.2f;    // added to the direct light
  float exposure = 1.0f;   // scales the colour before tone mapping
  // The gather's shadow rays (shadow_rays(), light-major) and their hits; empty: no shadows. A
  // light lights a pixel only if the pixel's ray to it is used and its hit a miss.
  std::span<const Ray> shadow_rays;
  std::span<const Hit> shadow_hits;
};

// RGB in [0, 1] per pixel (index y * width + x):
//   direct = albedo * (ambient + sum over lights of color * intensity * max(0, N.L) [/ d^2 for
//            point lights]), with shadow rays only the lights they reach; a headlight of intensity 1 (directional, from the camera's eye) if
//            the scene has no lights
//   albedo = material diffuse * diffuse texture at uv (nearest texel, the alpha-keying rule)
//   glossy material of glossiness g: (1 - g) * direct + g * bounce colour, where the bounce colour
//            is the albedo of the bounce hit (gap-fill hits: their triangle's albedo at its
//            centroid) times (ambient + its direct light, unshadowed), or scene.background on a
//            miss
//   a miss of the primary ray: scene.background
// then tone-mapped by clamping exposure * colour to [0, 1].
// bounce_rays and bounce_hits are per pixel as bounce_rays() made them (empty spans: no bounce).
std::vector<glm::vec3> shade(const Scene& scene, const GatherBuffer& gather, std::span<const Ray> bounce_rays,
                             std::span<const Hit> bounce_hits, const ShadeOptions& options = {});

// Albedo (diffuse colour times texture) of triangle `triangle` of instance `instance` at
// barycentrics (u, v).
glm::vec3 surface_albedo(const Scene& scene, uint32_t instance, uint32_t triangle, float u, float v);

}  // namespace gridrt
