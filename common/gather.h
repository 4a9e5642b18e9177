// gather.h: the gather buffer the paper traces its glossy bounce from (one primary hit per
// pixel), and the bounce rays leaving it.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "gridrt/common/scene.h"
#include "gridrt/common/tracer.h"

namespace gridrt {

inline constexpr uint32_t kNoMaterial = 0xFFFFFFFFu;

// Per pixel (index y * width + x, row 0 at the top), what the primary ray found.
struct GatherBuffer {
  uint32_t width = 0, height = 0;
  float time = 0.0f;                  // scene time the geometry was at
  std::vector<uint8_t> valid;         // 1: the primary ray hit a surface
  std::vector<glm::vec3> position;    // org + t * dir (world)
  std::vector<glm::vec3> normal;      // unit geometric normal of the hit triangle, facing the viewer
  std::vector<glm::vec3> incident;    // unit direction of the primary ray
  std::vector<uint32_t> material;     // index into Scene::materials, kNoMaterial if invalid
  std::vector<glm::vec2> uv;          // interpolated texture coordinates (0 if the mesh has none)
  std::vector<uint32_t> launch_ref;   // instance << 16 | triangle, shared::kNoRef if invalid
  std::vector<Hit> hit;               // the primary hit records

  size_t size() const { return size_t(width) * height; }
  // width x height pixels where no primary ray hit a surface (the state before a gather).
  static GatherBuffer blank(uint32_t width, uint32_t height);
};

// Trace one primary ray per pixel through `tracer` (already built and updated to `time`) and fill
// the gather buffer. World-space triangles for the normal come from shared::transform_point at
// `time`, the same vertices every tracer sees.
GatherBuffer make_gather(const Scene& scene, Tracer& tracer, const Camera& camera, uint32_t width,
                         uint32_t height, float time = 0.0f);

// One glossy-reflection ray per pixel (index y * width + x), so that bounce hits line up with the
// gather buffer. A valid pixel whose material has glossiness g > 0 gets the mirror direction of its
// primary ray about the gather normal, perturbed within a cone of half-angle (1 - g) * pi / 2 by a
// deterministic per-pixel hash of (x, y, frame) (PCG), folded into the normal's hemisphere; g = 1
// gives the mirror direction exactly. Origin: the gather position; tmin 0, tmax +inf;
// launch_normal: the gather normal; launch_ref: the gather launch reference.
// Unused pixels (invalid, or not glossy) get an empty ray: org 0, dir (0, 0, 1), tmin = tmax = 0,
// launch_ref kNoRef. Its interval is empty, so every tracer answers a miss (is_unused tells them
// apart from real rays; shade() ignores their hits).
std::vector<Ray> bounce_rays(const Scene& scene, const GatherBuffer& gather, uint32_t frame);
inline bool is_unused(const Ray& r) { return r.tmin == 0.0f && r.tmax == 0.0f; }

// The shadow rays of the gather buffer (common/shared/shadow.h, as the GPU frame makes them): one per
// light and pixel, light-major (index light * width * height + y * width + x), at most
// shared::kMaxShadowLights lights (more: an Error). A valid pixel gets the ray from its gather
// position towards the light (point: dir = light - position, t in (0, 1); directional: the unit
// direction, t in (0, +inf)), launch normal and reference the pixel's; an invalid pixel, a light
// behind the surface or at the position gets the empty ray (is_unused). Occluded iff traced to a hit.
std::vector<Ray> shadow_rays(const Scene& scene, const GatherBuffer& gather);

// Whether a frame traces shadow rays: on, off, or automatic = on iff the scene has lights (the
// effects a scene calls for, Features::shadows). Both backends' frames follow it. on for a scene
// without lights throws OptionsError (nothing to trace).
enum class ShadowMode { off, on, automatic };
bool shadows_for(ShadowMode mode, const Scene& scene);
// Throws Error if the scene has more lights than shadow rays are traced to (kMaxShadowLights).
void check_shadow_lights(const Scene& scene);

// An order of a ray list in which neighbouring rays walk alike (bench --ray-order sorted): by a
// 32-bit key, the direction's cell on a cube of 16 x 16 cells a face (11 bits), then the origin's
// cell on a lattice of 128 per axis over the used rays' origins, in Morton order (21 bits); equal
// keys keep the list's order, and the empty rays (is_unused) and rays with a non-finite origin or
// direction come last. Returns the permutation: ray order[k] goes k-th.
std::vector<uint32_t> coherent_ray_order(std::span<const Ray> rays);

// The per-pixel random numbers of bounce_rays: two uniform floats in [0, 1).
glm::vec2 pixel_random(uint32_t x, uint32_t y, uint32_t frame);

// cos((1 - glossiness) pi / 2): the cosine of the bounce cone's half-angle, once per material (the
// host computes it for the GPU too, so both use the same value).
float cone_cos_max(float glossiness);

}  // namespace gridrt
