// test_triangle_code.cpp: triangle_test_code (common/shared/triangle.h), the triangle test that
// stops at its first rejections (the traces without events), against triangle_test on a corpus of
// hard and random cases, both tests: the same code on every case, and the same record on every case
// it does not stop early (every accepted test among them).
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "gridrt/common/shared/triangle.h"

namespace sh = gridrt::shared;
using glm::vec3;

namespace {

struct Case {
  vec3 org, dir, v0, v1, v2;
  float t_lo, t_hi, best;
};

// Hard cases by construction, then random ones: rays through vertices, along and across shared
// edges, grazing and in-plane rays, axis-parallel directions (zero components, ties of the
// dominant axis), degenerate triangles (a point, repeated vertices, collinear), tiny and huge
// coordinates, intervals that end at the hit, and a best hit at and around it.
std::vector<Case> corpus() {
  std::vector<Case> cases;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), w(0.0f, 1.0f);
  const float inf = std::numeric_limits<float>::infinity();
  auto rv = [&](float s) { return vec3(u(rng), u(rng), u(rng)) * s; };
  for (int i = 0; i < 40000; ++i) {
    const float scale = std::ldexp(1.0f, int(rng() % 40) - 20);  // 2^-20 .. 2^19
    vec3 v0 = rv(scale), v1 = rv(scale), v2 = rv(scale);
    switch (i % 8) {
      case 1: v1 = v0; break;                                   // repeated vertex
      case 2: v2 = v0 + 0.5f * (v1 - v0); break;                // collinear
      case 3: v1 = v0, v2 = v0; break;                          // a point
      default: break;
    }
    // The target: a vertex, a point on an edge, inside, or outside
    float a = w(rng), b = w(rng);
    if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
    vec3 target = v0 + a * (v1 - v0) + b * (v2 - v0);
    switch ((i / 8) % 6) {
      case 0: target = (i % 3 == 0) ? v0 : (i % 3 == 1 ? v1 : v2); break;
      case 1: target = v0 + w(rng) * (v1 - v0); break;          // on an edge
      case 2: target = v1 + w(rng) * (v2 - v1); break;
      case 3: target = v0 + 1.5f * (v1 - v0) + 0.3f * (v2 - v0); break;  // outside
      default: break;
    }
    vec3 org = target + rv(scale * 4.0f);
    switch ((i / 48) % 5) {
      case 0: org = target + rv(scale); break;
      case 1: {  // in the plane or grazing it
        const vec3 in_plane = v0 + u(rng) * (v1 - v0) + u(rng) * (v2 - v0);
        org = in_plane + glm::cross(v1 - v0, v2 - v0) * (i % 2 ? 0.0f : 1e-4f);
        break;
      }
      case 2: org = target + vec3(u(rng), 0.0f, 0.0f) * scale; break;  // axis-parallel ray
      case 3: org = target + vec3(1.0f, 1.0f, u(rng) > 0.0f ? 1.0f : -1.0f) * scale; break;  // tied axes
      default: break;
    }
    vec3 dir = target - org;
    if (!(glm::dot(dir, dir) > 0.0f)) dir = vec3(0.0f, 0.0f, 1.0f);
    // Intervals and best hits around t = 1 (the target)
    float t_lo = 0.0f, t_hi = inf, best = inf;
    switch ((i / 240) % 5) {
      case 1: t_hi = 1.0f; break;
      case 2: t_lo = 1.0f; break;
      case 3: best = 1.0f; break;
      case 4: best = 0.999f, t_lo = 0.5f, t_hi = 2.0f; break;
      default: break;
    }
    cases.push_back({org, dir, v0, v1, v2, t_lo, t_hi, best});
  }
  return cases;
}

}  // namespace

TEST_CASE("triangle_test_code gives triangle_test's code on every case and its record where it does not stop early",
          "[unit][triangle]") {
  const std::vector<Case> cases = corpus();
  for (uint32_t which : {sh::kTriangleMoller, sh::kTriangleWatertight})
  for (const bool launched : {false, true}) {
    INFO((which == sh::kTriangleWatertight ? "watertight" : "Moller-Trumbore") << (launched ? ", surface rule" : ""));
    size_t early = 0, accepted = 0, refused = 0;
    for (size_t i = 0; i < cases.size(); ++i) {
      const Case& c = cases[i];
      // A ray launched from a surface: the surface rule's tolerance (the watertight test decides it)
      const float stol = launched ? sh::surface_rule_tol(c.org) : -1.0f;
      sh::TriangleTest full{}, fast{};
      const uint32_t want = sh::triangle_test(which, c.org, c.dir, c.v0, c.v1, c.v2, c.t_lo, c.t_hi, c.best, stol, full);
      const uint32_t got = sh::triangle_test_code(which, c.org, c.dir, sh::watertight_ray(c.dir), c.v0, c.v1, c.v2,
                                                     c.t_lo, c.t_hi, c.best, stol, fast);
      INFO("case " << i);
      REQUIRE(got == want);
      REQUIRE(fast.code == want);
      // The watertight test's rule from its own plane values is origin_on_plane's decision (what
      // the Moller-Trumbore trace, the Embree oracle and the referee ask)
      if (which == sh::kTriangleWatertight && launched && (want == sh::kTestAccepted || want == sh::kTestOriginPlane))
        REQUIRE((want == sh::kTestOriginPlane) == sh::origin_on_plane(c.org, c.v0, c.v1, c.v2));
      if (which != sh::kTriangleWatertight || !launched) REQUIRE(want != sh::kTestOriginPlane);
      refused += want == sh::kTestOriginPlane;
      // Where it stops early: only on its first rejections
      const bool stops = which == sh::kTriangleWatertight
                             ? (want == sh::kTestOutsideU || want == sh::kTestOutsideV || want == sh::kTestOutsideUV)
                             : (want == sh::kTestParallel || want == sh::kTestOutsideU);
      if (stops) {
        early += 1;
        continue;
      }
      REQUIRE(std::memcmp(&fast, &full, sizeof full) == 0);
      accepted += want == sh::kTestAccepted;
    }
    WARN(cases.size() << " cases: " << early << " decided by the first rejections, " << accepted << " accepted");
    // The corpus exercises both halves
    CHECK(early > cases.size() / 10);
    CHECK(accepted > cases.size() / 20);
    // Origins in the triangle's plane: the rule refuses some, only where it applies
    if (which == sh::kTriangleWatertight && launched) CHECK(refused > 0);
  }
}
