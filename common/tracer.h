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
  // "grid" (the image layout: the 3D image, extent shared::grid_image_extent, the slot axis's
  // cells times capacity + 1 along x), "grid-compact" (the offsets, then the references, as one
  // row: extent (words, 1, 1)), "portal", or "" (none, e.g. Embree)
  std::string kind;
  glm::uvec3 extent{0};          // in texels
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

// Every tracer behind one contract, kept here once (the public calls check, then call the
// tracer's own step): a scene is checked before it is built (Scene::validate: a scene never
// finalized, or changed since so that it breaks a rule, is refused naming the rule, where it
// crashed or traced garbage); a time must be finite (a NaN time made a spinning instance's
// transform NaN, and its triangles vanished without a word); a build that throws, refused by
// these checks or failing while building, leaves the tracer unbuilt, so that update and trace
// then throw until a build succeeds (an earlier grid was half replaced: update crashed and trace
// answered misses; a grid kept past a refused build still read the scene the caller had changed,
// and crashed); hits.size() == rays.size().
class Tracer {
 public:
  virtual ~Tracer() = default;
  virtual std::string name() const = 0;
  // Build everything for `scene` at time `time` (static and dynamic instances). The scene must
  // outlive the tracer.
  void build(const Scene& scene, float time);
  // Move the dynamic instances to `time`.
  void update(float time);
  // Closest hit (or miss) of every ray.
  void trace(std::span<const Ray> rays, std::span<Hit> hits);
  // Any hit (or miss) of every ray, for occlusion (shadow rays): a hit exactly where trace()
  // reports one, but not necessarily the closest (the grid's tracers stop at the first accepted
  // candidate: docs/SPEC.md "Any hit").
  void trace_any(std::span<const Ray> rays, std::span<Hit> hits);
  virtual AccelDump dump() const { return {}; }
  // A build succeeded and nothing has failed since (a tracer that wraps another answers for it)
  virtual bool built() const { return built_; }

 protected:
  // For a tracer made ready by its constructor (a portal tracer from a world or a build)
  void set_built() { built_ = true; }
  // The tracer's own steps, called once the contract's checks pass
  virtual void build_scene(const Scene& scene, float time) = 0;
  virtual void update_to(float time) = 0;
  virtual void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) = 0;
  // By default the closest hit
  virtual void trace_occlusion(std::span<const Ray> rays, std::span<Hit> hits) { trace_closest(rays, hits); }

 private:
  void require_built(const char* what) const;
  bool built_ = false;
};

}  // namespace gridrt
