// tracer.cpp: the contract every tracer keeps (tracer.h): the checks before its own steps.
#include "gridrt/common/tracer.h"

#include <cmath>

namespace gridrt {

namespace {

void require_finite_time(const std::string& tracer, const char* what, float time) {
  if (!std::isfinite(time))
    throw Error(tracer + ": " + what + " at a time that is not finite (" + (std::isnan(time) ? "NaN" : "inf") +
                "): the dynamic instances' transforms would be NaN and their triangles lost");
}

}  // namespace

void Tracer::require_built(const char* what) const {
  if (!built()) throw Error(name() + ": " + what + " before a build (or after a build that failed)");
}

void Tracer::build(const Scene& scene, float time) {
  // Unbuilt first: a grid kept past a refused build may hold the very scene the caller changed
  built_ = false;
  require_finite_time(name(), "build", time);
  scene.validate();
  build_scene(scene, time);
  built_ = true;
}

void Tracer::update(float time) {
  require_built("update");
  require_finite_time(name(), "update", time);
  // An update that throws may leave some instances moved and others not: unbuilt until a build
  built_ = false;
  update_to(time);
  built_ = true;
}

void Tracer::trace(std::span<const Ray> rays, std::span<Hit> hits) {
  require_built("trace");
  if (hits.size() != rays.size())
    throw Error(name() + ": trace: " + std::to_string(hits.size()) + " hit records for " + std::to_string(rays.size()) +
                " rays (they must be as many)");
  trace_closest(rays, hits);
}

void Tracer::trace_any(std::span<const Ray> rays, std::span<Hit> hits) {
  require_built("trace");
  if (hits.size() != rays.size())
    throw Error(name() + ": trace_any: " + std::to_string(hits.size()) + " hit records for " +
                std::to_string(rays.size()) + " rays (they must be as many)");
  trace_occlusion(rays, hits);
}

}  // namespace gridrt
