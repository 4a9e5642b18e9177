// verify.h: a tracer against Embree on the adversarial ray families (rays.h), every difference
// judged by the exact referee (referee.h). Used by `gridrt verify` and the Catch2 tests.
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gridrt/common/tracer.h"
#include "verify/referee.h"
#include "verify/rays.h"

namespace gridrt {
class EmbreeTracer;
}

namespace gridrt::verify {

struct Example {
  size_t ray = 0;
  Verdict verdict = Verdict::agree;
  std::string why, ray_hex, got_hex, want_hex;
};

struct FamilyResult {
  std::string name;               // the family's name ("translated" for the moved scene)
  size_t rays = 0;
  size_t outside = 0;             // rays outside the domain (both must reject them)
  size_t embree_rejected = 0;     // rays the oracle did not take (never handed to Embree)
  std::array<size_t, kVerdicts> verdicts{};  // per Verdict
  size_t attempts = 0;            // edge/vertex: exact constructions tried
  // t of the tracer's (and Embree's) hits against the exact t, in ulps of the float t, over the
  // well-conditioned hits (kappa <= kWellConditioned, referee.h) that are exact hits
  size_t t_checked = 0;
  uint32_t max_ulps = 0, max_ulps_embree = 0;
  double mean_ulps = 0.0;
  size_t nan_t = 0;               // records with a NaN t (never allowed)
  std::vector<Example> examples;  // the first few differences that are not agreements
  size_t count(Verdict v) const { return verdicts[size_t(v)]; }
  size_t failures() const { return count(Verdict::grid_wrong) + count(Verdict::crack) + nan_t; }
};

struct VerifyOptions {
  FamilyOptions family;
  std::vector<Family> families = all_families();
  bool translated = true;           // also the scene moved by `offset` (camera, random, surface, edge, vertex)
  glm::vec3 offset{1.0e5f, -5.0e4f, 7.5e4f};
  size_t examples = 3;
  unsigned threads = 0;
};

// The tracer must already be built on `scene` (time 0); `grid` is the reference grid of the same
// options (its triangles and lattice aim the rays); `embree` built on the same scene.
FamilyResult verify_family(Family f, const Scene& scene, Tracer& tracer, const reference::GridData& grid,
                           const Topology& topo, EmbreeTracer& embree, const VerifyOptions& options);

// Every family of `options` on `scene`, building the tracers with `make` (a fresh tracer for a
// scene): the reference grid for the aiming, the tracer under test, Embree.
using TracerFactory = std::function<std::unique_ptr<Tracer>(const Scene&)>;
std::vector<FamilyResult> verify_scene(const Scene& scene, const reference::GridOptions& grid_options,
                                       const TracerFactory& make, const VerifyOptions& options);

std::string to_table(const std::vector<FamilyResult>& results);
nlohmann::json to_json(const std::vector<FamilyResult>& results);

}  // namespace gridrt::verify
