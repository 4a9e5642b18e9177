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
      // A hit's barycentrics made again after the test (triangle_barycentrics) are the weights the
      // test recorded, over the determinant they are scaled by: the same bits
      if (want == sh::kTestAccepted || want == sh::kTestOriginPlane) {
        float den = std::abs(full.det);
        if (which == sh::kTriangleWatertight) {
          sh::WatertightEdges e;
          sh::watertight_edges(c.org, sh::watertight_ray(c.dir), c.v0, c.v1, c.v2, e);
          den = std::abs(e.det);
        }
        const glm::vec2 again = sh::triangle_barycentrics(which, c.org, c.dir, sh::watertight_ray(c.dir), c.v0, c.v1, c.v2);
        const glm::vec2 recorded = sh::test_barycentrics(full.u_det, full.v_det, den);
        REQUIRE(std::memcmp(&again, &recorded, sizeof again) == 0);
      }
    }
    WARN(cases.size() << " cases: " << early << " decided by the first rejections, " << accepted << " accepted");
    // The corpus exercises both halves
    CHECK(early > cases.size() / 10);
    CHECK(accepted > cases.size() / 20);
    // Origins in the triangle's plane: the rule refuses some, only where it applies
    if (which == sh::kTriangleWatertight && launched) CHECK(refused > 0);
  }
}

TEST_CASE("The watertight test's inside decision is exact for its sheared coordinates: small triangles seen from "
          "far away, edge functions that round to zero",
          "[unit][watertight]") {
  // An outside sweep's find: a triangle 0.08 wide, a ray from 4e4 away passing 4e4 from it; the
  // edge functions' products (about 1e9) rounded to the same floats, U = W = 0 counted as inside,
  // and the ray hit it. The signs must be those of the exact edge functions of the same float
  // sheared coordinates (the shader's), computed here in double (each product of two floats is
  // exact in double, so the difference's sign is)
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  auto rv = [&](float s) { return vec3(u(rng), u(rng), u(rng)) * s; };
  int zeros = 0, refined = 0, inside = 0;
  for (int i = 0; i < 200000; ++i) {
    const float size = std::ldexp(1.0f, -int(rng() % 12));            // 1 .. 2^-11
    const float far = std::ldexp(1.0f, 8 + int(rng() % 10));           // 2^8 .. 2^17 away
    const vec3 c = rv(4.0f);
    const vec3 v0 = c + rv(size), v1 = c + rv(size), v2 = c + rv(size);
    const vec3 org = c + rv(far);
    // Aimed at the triangle, or off it by up to a few hundred of its sizes, or by up to its
    // distance (where products of the sheared coordinates dwarf the triangle's edge functions)
    const float miss = i % 2 ? size * float(1 << (rng() % 10)) : far * std::ldexp(1.0f, -int(rng() % 8));
    const vec3 dir = glm::normalize((c + rv(miss)) - org);
    const sh::WatertightRay w = sh::watertight_ray(dir);
    const auto comp = [](vec3 v, uint32_t k) { return k == 0 ? v.x : (k == 1 ? v.y : v.z); };
    const auto shear = [&](vec3 v, float& x, float& y) {
      const vec3 a = v - org;  // float, as the test
      const float z = comp(a, w.kz);
      const float ax = comp(a, w.kx) * w.dz, bx = w.dx * z, ay = comp(a, w.ky) * w.dz, by = w.dy * z;
      x = ax - bx;
      y = ay - by;
    };
    float ax, ay, bx, by, cx, cy;
    shear(v0, ax, ay);
    shear(v1, bx, by);
    shear(v2, cx, cy);
    const auto sign = [](double v) { return (v > 0.0) - (v < 0.0); };
    const int su = sign(double(cx) * by - double(cy) * bx);
    const int sv = sign(double(ax) * cy - double(ay) * cx);
    const int sw = sign(double(bx) * ay - double(by) * ax);
    const bool exact_inside = !((su < 0 || sv < 0 || sw < 0) && (su > 0 || sv > 0 || sw > 0));
    sh::WatertightEdges e;
    sh::watertight_edges(org, w, v0, v1, v2, e);
    INFO("case " << i);
    REQUIRE(sign(e.U) == su);
    REQUIRE(sign(e.V) == sv);
    REQUIRE(sign(e.W) == sw);
    const float u0 = cx * by - cy * bx, v0f = ax * cy - ay * cx, w0 = bx * ay - by * ax;
    zeros += (u0 == 0.0f) + (v0f == 0.0f) + (w0 == 0.0f);
    refined += (u0 == 0.0f && su != 0) + (v0f == 0.0f && sv != 0) + (w0 == 0.0f && sw != 0);
    sh::TriangleTest r;
    const uint32_t code = sh::watertight(org, dir, v0, v1, v2, 0.0f, std::numeric_limits<float>::infinity(),
                                         std::numeric_limits<float>::infinity(), -1.0f, r);
    const bool outside = code == sh::kTestOutsideU || code == sh::kTestOutsideV || code == sh::kTestOutsideUV;
    REQUIRE(outside == !exact_inside);
    inside += exact_inside;
  }
  WARN(zeros << " edge functions rounded to zero, " << refined << " of them not zero exactly; " << inside
             << " rays inside");
  // The cases the refinement exists for occur, and both answers do
  CHECK(refined > 100);
  CHECK(inside > 1000);
}

// An outside sweep's find: the dot products' form of Cramer's rule (denom = d00 d11 - d01^2)
// squared a sliver's condition, weights in steps of 1/8 on a 1000:1 strip (alpha masks and uv
// sampled at the wrong texel), and underflowed below edges of 3e-10 (weights (1, 0)). The weights
// in the plane the triangle projects onto largest keep to the exact ones.
// A hit's weights (triangle_barycentrics) against the exact weights of the float ray's meeting
// with the float triangle (double precision, Cramer's rule on the ray and two edges), for
// triangles at the origin and moved to 1e5 and 1e7: the test's weights are made from the vertices
// relative to the origin, so their error does not grow with the distance from the origin (worst
// 2e-5 to 1e-4 on these random, some ill-conditioned, triangles, at every offset). Cramer's rule
// at the rounded hit point (what the alpha key took before) is off by the point's rounding over
// the triangle's size: measured alongside, 0.09 to 0.17 at 1e5, and required 100 times worse.
TEST_CASE("triangle_barycentrics: a hit's weights are exact within rounding wherever the triangle lies",
          "[unit][triangle]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0), s(-1.0, 1.0);
  for (const double offset : {0.0, 1e5, 1e7}) {
    for (uint32_t which : {sh::kTriangleMoller, sh::kTriangleWatertight}) {
      double worst = 0.0, worst_point = 0.0;
      int hits = 0;
      for (int i = 0; i < 2000; ++i) {
        const double size = offset > 1e6 ? 64.0 : 0.5;  // 1e7's ulp is 1: a triangle wider than it
        const glm::dvec3 base(offset, -0.3 * offset, 0.7 * offset);
        const glm::vec3 v0(base + size * glm::dvec3(s(rng), s(rng), s(rng))), v1(base + size * glm::dvec3(s(rng), s(rng), s(rng))),
            v2(base + size * glm::dvec3(s(rng), s(rng), s(rng)));
        double a = u(rng), b = u(rng);
        if (a + b > 1.0) a = 1.0 - a, b = 1.0 - b;
        const glm::dvec3 d0(v0), d1(v1), d2(v2), e0 = d1 - d0, e1 = d2 - d0;
        const glm::dvec3 target = d0 + a * e0 + b * e1;
        const glm::vec3 org(target + 4.0 * size * glm::dvec3(s(rng), s(rng), s(rng)));
        const glm::vec3 dir(target - glm::dvec3(org));
        // The exact weights of the float ray's meeting with the float triangle
        const glm::dvec3 od(org), dd(dir), q = od - d0, p = glm::cross(dd, e1);
        const double det = glm::dot(e0, p);
        if (std::abs(det) < 1e-3 * glm::length(e0) * glm::length(e1) * glm::length(dd)) continue;  // grazing
        const glm::dvec3 qe = glm::cross(q, e0);
        const double w1 = glm::dot(q, p) / det, w2 = glm::dot(dd, qe) / det;
        if (!(w1 > 1e-3 && w2 > 1e-3 && w1 + w2 < 1.0 - 1e-3)) continue;
        sh::TriangleTest r{};
        if (sh::triangle_test(which, org, dir, v0, v1, v2, 0.0f, INFINITY, INFINITY, -1.0f, r) != sh::kTestAccepted) continue;
        hits += 1;
        const glm::vec2 got = sh::triangle_barycentrics(which, org, dir, sh::watertight_ray(dir), v0, v1, v2);
        worst = std::max({worst, std::abs(got.x - w1), std::abs(got.y - w2)});
        const glm::vec2 at_point =
            sh::cramer_barycentrics(v0, v1, v2, sh::point_at(org, dir, sh::moller_trumbore_t(r)));
        worst_point = std::max({worst_point, std::abs(at_point.x - w1), std::abs(at_point.y - w2)});
      }
      INFO("offset " << offset << (which == sh::kTriangleWatertight ? ", watertight" : ", Moller-Trumbore") << ": "
                     << hits << " hits, worst weight error " << worst << " (Cramer's at the hit point: " << worst_point << ")");
      REQUIRE(hits > 1000);
      CHECK(worst < 5e-4);
      if (offset == 1e5) CHECK(worst_point > 100.0 * worst);
    }
  }
}

TEST_CASE("cramer_barycentrics: slivers and tiny triangles get their exact weights within rounding", "[unit][triangle]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  struct Tri {
    glm::dvec3 v0, v1, v2;
    double tol;
  };
  const std::vector<Tri> tris = {
      {{0, 0, 0}, {2, 0, 0}, {2, 0.002, 0}, 2e-4},                   // 1000:1 strip
      {{1, 2, 3}, {11.95, 2.3, 3.1}, {11.6, 2.6, 3.05}, 2e-4},       // a 36:1 sliver off the origin
      {{0.5, 0.5, 0.5}, {0.5 + 3e-10, 0.5, 0.5}, {0.5, 0.5 + 3e-10, 0.5}, 2e-2},  // tiny, at 0.5: p rounds at 0.5's ulp
      {{0, 0, 0}, {3e-10, 0, 0}, {0, 3e-10, 1e-10}, 1e-4},           // tiny, at the origin
  };
  for (size_t k = 0; k < tris.size(); ++k) {
    const Tri& t = tris[k];
    const glm::vec3 v0(t.v0), v1(t.v1), v2(t.v2);
    double worst = 0.0;
    for (int i = 0; i < 200; ++i) {
      double a = u(rng), b = u(rng);
      if (a + b > 1.0) a = 1.0 - a, b = 1.0 - b;
      // The point from the float vertices, in double, rounded once; its exact weights by least squares
      const glm::dvec3 e0 = glm::dvec3(v1) - glm::dvec3(v0), e1 = glm::dvec3(v2) - glm::dvec3(v0);
      const glm::vec3 p(glm::dvec3(v0) + a * e0 + b * e1);
      const glm::dvec3 q = glm::dvec3(p) - glm::dvec3(v0);
      const double d00 = glm::dot(e0, e0), d01 = glm::dot(e0, e1), d11 = glm::dot(e1, e1);
      const double d20 = glm::dot(q, e0), d21 = glm::dot(q, e1), den = d00 * d11 - d01 * d01;
      const double w1 = (d11 * d20 - d01 * d21) / den, w2 = (d00 * d21 - d01 * d20) / den;
      const glm::vec2 got = sh::cramer_barycentrics(v0, v1, v2, p);
      worst = std::max({worst, std::abs(double(got.x) - std::clamp(w1, 0.0, 1.0)), std::abs(double(got.y) - std::clamp(w2, 0.0, 1.0))});
    }
    INFO("triangle " << k << ": worst weight error " << worst);
    CHECK(worst <= t.tol);
  }
}
