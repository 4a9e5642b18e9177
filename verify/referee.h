// referee.h: the exact referee. A ray and a triangle, both given as floats, are intersected in
// exact integer arithmetic (GMP): every float is an integer times 2^-175 at most (denormals
// included), so scaling by 2^175 makes org, dir and the vertices integers and the Moller-Trumbore
// quantities det = e1 . (dir x e2), U = s . (dir x e2), V = dir . (s x e1), T = e2 . (s x e1)
// exact integers; t = T / det is compared as a fraction, never rounded. A hit is a closed one
// (u >= 0, v >= 0, u + v <= 1) with tmin < t < tmax; det == 0 (the ray parallel to the plane, or
// in it) is no hit. Differences between a tracer and Embree are judged against the exact closest
// hit among candidate triangles (both answers, every triangle Embree finds along the ray, the
// triangles aimed at, and those sharing a vertex with any of them).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gridrt/common/tracer.h"
#include "verify/rays.h"

namespace gridrt {
class EmbreeTracer;
}

namespace gridrt::verify {

// One ray against one triangle, exactly.
struct ExactTest {
  bool hit = false;       // closed triangle, tmin < t < tmax
  bool boundary = false;  // a hit exactly on an edge or a vertex (a barycentric exactly 0)
  bool parallel = false;  // det == 0
  double t = 0.0;         // t rounded to double (hits only)
  double plane_t = 0.0;   // where the ray meets the triangle's plane, rounded (det != 0)
  double margin = 0.0;    // min(u, v, 1 - u - v), rounded (det != 0): < 0 outside
  std::shared_ptr<const struct Fraction> exact;  // t = T / det as exact integers (hits only)
};
ExactTest exact_test(const Ray& ray, const glm::vec3& v0, const glm::vec3& v1, const glm::vec3& v2);
// The same with the lower bound given: a hit needs t > t_lo (exact_test uses origin_tmin).
ExactTest exact_test_from(const glm::vec3& org, const glm::vec3& dir, float t_lo, float tmax, const glm::vec3& v0,
                          const glm::vec3& v1, const glm::vec3& v2);
// -1, 0, 1 as a's t is smaller, equal, larger than b's (both hits).
int compare_t(const ExactTest& a, const ExactTest& b);
// t of a hit rounded to float (round to nearest, from the exact fraction).
float exact_t_float(const ExactTest& a);

// How one ray's answer compares with Embree's, judged exactly.
enum class Verdict {
  agree,          // the same record (triangle, or both miss; both rejected)
  tie,            // different triangles, both exactly at the closest t (a shared edge or vertex,
                  // or coplanar overlapping faces)
  near,           // one answer is the same point within rounding, on another triangle: its
                  // triangle is met within kNearMargin of its boundary (or hit exactly) at a t
                  // within kNearT (relative) of the exact closest, or passes within kNearUlps of
                  // the exact hit point, or is hit at an exact t within kNearKappa u (kappa_a +
                  // kappa_b) t of the closest, the two faces' conditioning (not wrong: float
                  // tests cannot tell them apart)
  embree_wrong,   // the tracer is exactly right, Embree is not
  grid_wrong,     // the tracer is wrong (and it is no crack), or rejects what the domain accepts
                  // or the reverse, or reports a NaN t
  crack,          // the exact closest hit lies on an edge or vertex, and the tracer reports
                  // nothing or something farther
  unresolved,     // the tracer is not exactly right for the ray as given, but it is for the ray it
                  // traced: the scene as seen from the origin in float (every vertex v - org rounded
                  // to float, the tests' first step), the ray moved perpendicular to itself by at
                  // most kNearUlps ulps of the largest coordinate involved (the rounding of the
                  // tests' next steps), or near an outline (exact_for_moved_origin); a miss only
                  // where such a ray misses every triangle (docs/ACCURACY.md, "The referee's rule
                  // for rounded inputs"); counted, not failed
};
inline constexpr size_t kVerdicts = 7;
const char* to_string(Verdict v);

struct Judgement {
  Verdict verdict = Verdict::agree;
  bool exact_hit = false;   // the exact closest hit exists (among the candidates)
  uint32_t exact_ref = 0;   // its triangle
  double exact_t = 0.0;
  std::string why;          // one line for reports
};

class Referee {
 public:
  Referee(const reference::GridData& grid, const Topology& topo, EmbreeTracer& embree);
  // Judges `got` (the tracer) against `want` (Embree) on `ray`; `aimed` are extra candidates.
  Judgement judge(const Ray& ray, const Hit& got, const Hit& want, const std::vector<uint32_t>& aimed) const;
  // The exact test of one ref.
  ExactTest test(const Ray& ray, uint32_t ref) const;
  // Whether `got` is the exact answer of the ray as traced (the unresolved verdict): the exact
  // closest hit (or a tie with it), or a miss, among every triangle near the ray, in the scene as
  // seen from the origin in float (each vertex v - org rounded to float), for the ray itself or the
  // ray moved perpendicular to its direction by at most a radius (below). The moved rays tried: a polar grid of the disc of that radius, and
  // just inside and just outside every edge of the triangles near the ray (where the answer
  // changes), so a region of the disc whose answer is `got` is found unless it is narrower than
  // 1e-4 of the radius. A hit is also accepted where the ray passes within that radius of both
  // got's triangle and an outline of the surfaces (an edge of one triangle, of more than two, or
  // between a face turned towards the ray and one turned away): there the rounding of each vertex
  // (not a rigid move) can fold the outline over the ray. A miss only by a moved ray that misses
  // every triangle.
  // The radius: kNearUlps ulps of the largest coordinate of the origin, the hit point and the
  // vertices as traced (v - org) of got's triangle and of `exact` (the exact closest hit's
  // triangle; kNoRef: none), whose rounding the tests' decisions carry: a needle's face whose
  // vertices lie a thousand times farther from the origin than its hit point is rounded at their
  // scale, not the origin's.
  bool exact_for_moved_origin(const Ray& ray, const Hit& got, uint32_t exact) const;
  // Whether the point at t along the ray lies within kNearUlps ulps (of the largest coordinate of
  // the origin and the point) of an open edge: an edge of exactly one triangle, a T-junction's
  // (a vertex on another triangle's edge) or the surface's border. The surface's two sides there
  // are different edges, rounded apart in every float test (each vertex v - org, then the
  // shear), so a ray through that seam may miss both: a miss there is unresolved, not wrong.
  bool near_open_edge(const Ray& ray, double t) const;
  // The indices (into the topology) of every triangle that passes within `reach` of the ray's line,
  // not wholly behind its origin: a superset of those the ray or a ray moved by `reach` can hit.
  std::vector<size_t> near_line(const Ray& ray, double reach) const;

 private:
  const reference::GridData& grid_;
  const Topology& topo_;
  EmbreeTracer& embree_;
};

// The t bound on well-conditioned hits (docs/ACCURACY.md, "t against the exact t"): |t - exact| in
// ulps of the float t, where the condition number kappa = (|org| + max |v_i| + t |dir|) /
// (t |dir| |cos|) is at most kWellConditioned; there the exact traversal's t is within kTBoundUlps.
inline constexpr double kWellConditioned = 100.0;
// kappa of a ray's hit at `t` on triangle `tri` (infinity where the triangle or the direction is
// degenerate, or t <= 0).
double condition_number(const Ray& ray, const std::array<glm::vec3, 3>& tri, double t);
// The "near" verdict for two faces met at t's within their conditioning: |t_a - t_b| <=
// kNearKappa u (kappa_a + kappa_b) t, u = 2^-24 (docs/ACCURACY.md, "The referee's verdicts").
inline constexpr double kNearKappa = 4.0;
inline constexpr uint32_t kTBoundUlps = 32;
// The "near" verdict's tolerances: barycentric margin and relative t.
inline constexpr double kNearMargin = 1.0e-5;
inline constexpr double kNearT = 1.0e-5;
// ... or the answer's triangle passes within kNearUlps ulps (of the largest coordinate of the
// origin and the exact hit point) of the exact hit point, at a t as close: the rounding of the
// ray's inputs (v - org), which no float test avoids (far origins, scenes far from the origin).
inline constexpr double kNearUlps = 16.0;

}  // namespace gridrt::verify
