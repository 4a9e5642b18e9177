// tracer.h: the one interface every tracer implements (docs/ARCHITECTURE.md,
// "Layers"): build from a scene, update for a new time, trace a batch of rays into hit records,
// hand back the acceleration structure as plain data.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "gridrt/common/scene.h"
#include "gridrt/common/shared/records.h"

namespace gridrt {

using Ray = shared::RayRecord;  // org, tmin, dir, tmax, launch normal and launch reference
using Hit = shared::HitRecord;  // t, instance, triangle, barycentrics, flags

inline bool is_miss(const Hit& h) { return h.instance == shared::kNoInstance; }

// What a tracer's acceleration structure looks like as plain data, for differential tests.
struct AccelDump {
  std::string kind;              // "grid", "portal", "" (none, e.g. Embree)
  glm::uvec3 extent{0};          // image extent in texels (grid: cells_x * (capacity+1), y, z)
  std::vector<uint32_t> texels;  // x fastest, then y, then z
};

// Which effects a frame simulates (only what the scene calls for: for_scene).
struct Features {
  bool alpha_keying = true;
  bool update = true;
  bool gap_fill = true;
  bool glossy = true;
  bool shadows = true;
  static Features for_scene(const Scene& scene);  // only what the scene calls for
};

class Tracer {
 public:
  virtual ~Tracer() = default;
  virtual std::string name() const = 0;
  // Build everything for `scene` at time `time` (static and dynamic instances). The scene must
  // outlive the tracer.
  virtual void build(const Scene& scene, float time) = 0;
  // Move the dynamic instances to `time`.
  virtual void update(float time) = 0;
  // Closest hit (or miss) of every ray; hits.size() == rays.size().
  virtual void trace(std::span<const Ray> rays, std::span<Hit> hits) = 0;
  // Any hit (or miss) of every ray, for occlusion (shadow rays): a hit exactly where trace()
  // reports one, but not necessarily the closest (the grid's tracers stop at the first accepted
  // candidate: docs/SPEC.md "Any hit"). By default the closest hit.
  virtual void trace_any(std::span<const Ray> rays, std::span<Hit> hits) { trace(rays, hits); }
  virtual AccelDump dump() const { return {}; }
};

}  // namespace gridrt
