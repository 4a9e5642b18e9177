// embree_tracer.h: the Embree 3 oracle (docs/ARCHITECTURE.md, "Layers").
//
// Conventions, chosen so that its hit records compare with the grid's by value:
// - World-space geometry: one Embree triangle geometry per instance, geomID == instance index,
//   vertices transformed with shared::transform_point (common/shared/transform.h), the very float
//   operations of the grid build, so both see bit-identical triangles. RTC_SCENE_FLAG_ROBUST.
// - Hits: t along the ray's (unnormalized) direction (Embree computes it with an approximate
//   reciprocal refined by Newton: within ~2 ulps of the correctly rounded quotient, not bit-equal
//   to the grid's single division), instance = geomID, triangle = primID,
//   u, v = Embree's barycentrics (p = (1-u-v) v0 + u v1 + v v2, the HitRecord convention),
//   flags: kHitBackFace when (v1-v0) x (v2-v0) of the world-space triangle has a positive dot
//   product with the ray direction. cells = 0, tests = 0 (Embree does not count).
// - Misses: instance = shared::kNoInstance, triangle = 0, t = +inf, u = v = 0.
// - Ray interval: hits need tmin < t < tmax, strictly (tmin raised by the origin epsilon,
//   shared::origin_tmin), for the t Embree reports (its inclusive
//   [tnear, tfar] is narrowed by one ulp at each end). tmin >= tmax:
//   a miss.
// - Rejected rays: those outside the domain (shared::ray_domain: a NaN or infinite component, the
//   largest |dir| component outside [2^-20, 2^20], an |org| component above 2^24, tmin < 0 or a
//   NaN tmin or tmax): flags = kHitRejected, a miss; never handed to Embree (whose validity
//   assertion aborts the process on components above about 1.8e18), and counted (rejected_rays).
// - Self-hits: a ray with launch_ref != kNoRef ignores exactly that triangle (instance, triangle)
//   wherever along the ray it would be hit (a context filter function); other triangles of the
//   same instance are hit normally.
// - Alpha keying: a triangle whose material has an alpha texture is no surface where the texel
//   under its interpolated uv (shared::interpolate_uv, shared::alpha_texel_coords) has alpha
//   < shared::kAlphaCutoff (an intersection filter attached only to geometries whose mesh uses
//   an alpha-keyed material). A mesh without uvs samples uv (0, 0).
// - trace() runs on all hardware threads, in blocks of rays; results do not depend on threads.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "gridrt/common/tracer.h"

namespace gridrt {

class EmbreeTracer : public Tracer {
 public:
  // threads = 0: all hardware threads.
  explicit EmbreeTracer(unsigned threads = 0);
  ~EmbreeTracer() override;
  EmbreeTracer(const EmbreeTracer&) = delete;
  EmbreeTracer& operator=(const EmbreeTracer&) = delete;

  std::string name() const override { return "embree"; }
  void build_scene(const Scene& scene, float time) override;
  void update_to(float time) override;
  void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) override;

  // Closest hit of one ray, on the calling thread.
  Hit trace_one(const Ray& ray) const;
  // Every triangle (instance << 16 | triangle) Embree intersects along the ray within its
  // interval, in no particular order (the launch triangle excluded; alpha masks applied).
  std::vector<uint32_t> hits_along(const Ray& ray) const;
  // Rays rejected since construction (outside the domain; not passed to Embree).
  uint64_t rejected_rays() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gridrt
