#include "verify/referee.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <gmpxx.h>

#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/common/shared/grid.h"

namespace gridrt::verify {

namespace sh = gridrt::shared;

struct Fraction {
  mpz_class T, det;  // t = T / det, det > 0
};

namespace {

// Every float is m * 2^e with |m| < 2^24 and e >= -149 - 23: times 2^kScale it is an integer.
constexpr int kScale = 175;

mpz_class scaled(float f) {
  if (f == 0.0f) return 0;
  int e = 0;
  const float m = std::frexp(f, &e);                    // f = m 2^e, 0.5 <= |m| < 1
  const long mi = long(std::ldexp(double(m), 24));      // exact: 24 significant bits
  mpz_class z = mi;
  const int shift = e - 24 + kScale;                    // >= 3 for the smallest denormal
  mpz_mul_2exp(z.get_mpz_t(), z.get_mpz_t(), mp_bitcnt_t(shift));
  return z;
}

struct V3 {
  mpz_class x, y, z;
};
V3 scaled(const glm::vec3& v) { return {scaled(v.x), scaled(v.y), scaled(v.z)}; }
V3 sub(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 cross(const V3& a, const V3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
mpz_class dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// Distance from p to the triangle abc (Ericson 2004, 5.1.5), in double.
double point_triangle_distance(glm::dvec3 p, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) {
  const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  glm::dvec3 q;
  if (d1 <= 0 && d2 <= 0) return glm::length(p - a);
  const glm::dvec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return glm::length(p - b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return glm::length(p - (a + ab * (d1 / (d1 - d3))));
  const glm::dvec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return glm::length(p - c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return glm::length(p - (a + ac * (d2 / (d2 - d6))));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return glm::length(p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))));
  const double denom = 1.0 / (va + vb + vc);
  q = a + ab * (vb * denom) + ac * (vc * denom);
  return glm::length(p - q);
}

double max_abs(glm::dvec3 v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

}  // namespace

ExactTest exact_test(const Ray& ray, const glm::vec3& v0, const glm::vec3& v1, const glm::vec3& v2) {
  ExactTest r;
  const V3 o = scaled(ray.org), d = scaled(ray.dir), a = scaled(v0), b = scaled(v1), c = scaled(v2);
  const V3 e1 = sub(b, a), e2 = sub(c, a), s = sub(o, a);
  const V3 p = cross(d, e2);
  mpz_class det = dot(e1, p);
  if (det == 0) {
    r.parallel = true;
    return r;
  }
  const V3 q = cross(s, e1);
  mpz_class U = dot(s, p), V = dot(d, q), T = dot(e2, q);
  if (det < 0) det = -det, U = -U, V = -V, T = -T;
  const mpz_class UV = U + V;
  r.plane_t = mpq_class(T, det).get_d();
  r.margin = std::min({mpq_class(U, det).get_d(), mpq_class(V, det).get_d(), mpq_class(det - UV, det).get_d()});
  if (U < 0 || V < 0 || UV > det) return r;
  // tmin < t < tmax: T 2^kScale against tmin (times 2^kScale) * det
  mpz_class Ts = T;
  mpz_mul_2exp(Ts.get_mpz_t(), Ts.get_mpz_t(), kScale);
  if (!(Ts > scaled(sh::origin_tmin(ray.org, ray.dir, ray.tmin)) * det)) return r;
  if (std::isfinite(ray.tmax) && !(Ts < scaled(ray.tmax) * det)) return r;
  r.hit = true;
  r.boundary = U == 0 || V == 0 || UV == det;
  r.t = mpq_class(T, det).get_d();
  r.exact = std::make_shared<const Fraction>(Fraction{T, det});
  return r;
}

int compare_t(const ExactTest& a, const ExactTest& b) {
  const mpz_class l = a.exact->T * b.exact->det, r = b.exact->T * a.exact->det;
  return l < r ? -1 : (l > r ? 1 : 0);
}

float exact_t_float(const ExactTest& a) {
  const mpq_class q(a.exact->T, a.exact->det);
  const float f = float(q.get_d());
  // The nearest of f and its neighbours (get_d truncates; the double then rounds once more)
  float best = f;
  mpq_class best_err = abs(mpq_class(double(f)) - q);
  for (float g : {std::nextafter(f, -INFINITY), std::nextafter(f, INFINITY)}) {
    if (!std::isfinite(g)) continue;
    const mpq_class err = abs(mpq_class(double(g)) - q);
    if (err < best_err) best = g, best_err = err;
  }
  return best;
}

const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::agree: return "agree";
    case Verdict::tie: return "tie";
    case Verdict::near: return "near";
    case Verdict::embree_wrong: return "embree_wrong";
    case Verdict::grid_wrong: return "grid_wrong";
    case Verdict::crack: return "crack";
    case Verdict::unresolved: return "unresolved";
  }
  return "?";
}

Referee::Referee(const reference::GridData& grid, const Topology& topo, EmbreeTracer& embree)
    : grid_(grid), topo_(topo), embree_(embree) {}

ExactTest Referee::test(const Ray& ray, uint32_t ref) const {
  const size_t i = topo_.index_of(ref);
  if (i == SIZE_MAX) return {};
  if (ref == ray.launch_ref) return {};  // the launch triangle is never hit (both tracers' rule)
  const auto& t = topo_.tri[i];
  return exact_test(ray, t[0], t[1], t[2]);
}

bool Referee::exact_for_moved_origin(const Ray& ray, const Hit& got, std::vector<uint32_t> cand) const {
  // The float tests round v - org to the ulps of the larger of |v| and |org|: an answer that is the
  // exact one for the ray with its origin moved by at most kNearUlps of those ulps (the 26
  // neighbours of the origin on a cube of that half-width, and at half of it) is as good as
  // float inputs allow. The candidates: the given ones, the answer's triangle and its neighbours.
  const auto ref_of = [](const Hit& h) { return sh::ref_pack(h.instance, h.triangle); };
  const bool miss = is_miss(got);
  if (!miss) {
    cand.push_back(ref_of(got));
    const size_t i = topo_.index_of(ref_of(got));
    if (i != SIZE_MAX)
      for (uint32_t n : topo_.neighbours(uint32_t(i))) cand.push_back(topo_.ref[n]);
  }
  const glm::dvec3 o(ray.org);
  const double reach = std::max(max_abs(o), miss || !std::isfinite(got.t) ? 0.0 : max_abs(o + glm::dvec3(ray.dir) * double(got.t)));
  const double delta = kNearUlps * 0x1p-24 * reach;
  for (double scale : {1.0, 0.5})
    for (int e = 0; e < 27; ++e) {
      if (e == 13) continue;  // the origin itself
      Ray moved = ray;
      moved.org = glm::vec3(o + glm::dvec3(e % 3 - 1, e / 3 % 3 - 1, e / 9 - 1) * (delta * scale));
      ExactTest best;
      uint32_t best_ref = 0;
      for (uint32_t r : cand) {
        const ExactTest x = test(moved, r);
        if (x.hit && (!best.hit || compare_t(x, best) < 0 || (compare_t(x, best) == 0 && r < best_ref))) best = x, best_ref = r;
      }
      if (miss ? !best.hit : best.hit && best_ref == ref_of(got)) return true;
      if (!miss && best.hit) {
        const ExactTest g = test(moved, ref_of(got));
        if (g.hit && compare_t(g, best) == 0) return true;  // a tie at the closest t
      }
    }
  return false;
}

Judgement Referee::judge(const Ray& ray, const Hit& got, const Hit& want, const std::vector<uint32_t>& aimed) const {
  Judgement j;
  const bool inside = sh::ray_domain(ray.org, ray.dir, ray.tmin, ray.tmax) == sh::kDomainOk;
  const bool got_rejected = (got.flags & sh::kHitRejected) != 0;
  if (!inside) {
    if (got_rejected && is_miss(got)) return j;
    j.verdict = Verdict::grid_wrong;
    j.why = "accepts a ray outside the domain";
    return j;
  }
  if (got_rejected) {
    j.verdict = Verdict::grid_wrong;
    j.why = "rejects a ray inside the domain";
    return j;
  }
  if (!is_miss(got) && std::isnan(got.t)) {
    j.verdict = Verdict::grid_wrong;
    j.why = "NaN t";
    return j;
  }
  const auto ref_of = [](const Hit& h) { return sh::ref_pack(h.instance, h.triangle); };
  const bool same = is_miss(got) == is_miss(want) && (is_miss(got) || ref_of(got) == ref_of(want));
  if (same && aimed.empty() && !(got.flags & sh::kHitGapFill)) return j;

  // Candidates: both answers, Embree's every hit, the aimed triangles, and their neighbours
  std::vector<uint32_t> cand = embree_.hits_along(ray);
  std::vector<uint32_t> seeds = aimed;
  if (!is_miss(got)) seeds.push_back(ref_of(got));
  if (!is_miss(want)) seeds.push_back(ref_of(want));
  seeds.insert(seeds.end(), cand.begin(), cand.end());
  const auto add_neighbours = [&](uint32_t ref) {
    const size_t i = topo_.index_of(ref);
    if (i == SIZE_MAX) return;
    for (uint32_t n : topo_.neighbours(uint32_t(i))) cand.push_back(topo_.ref[n]);
  };
  cand.insert(cand.end(), seeds.begin(), seeds.end());
  for (uint32_t r : seeds) add_neighbours(r);
  std::sort(cand.begin(), cand.end());
  cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
  ExactTest best;
  uint32_t best_ref = 0;
  const auto closest_of = [&](const std::vector<uint32_t>& refs) {
    for (uint32_t r : refs) {
      const ExactTest e = test(ray, r);
      if (!e.hit) continue;
      if (!best.hit || compare_t(e, best) < 0 || (compare_t(e, best) == 0 && r < best_ref)) best = e, best_ref = r;
    }
  };
  closest_of(cand);
  if (best.hit) {  // the closest one's neighbours too (a fan around the point)
    std::vector<uint32_t> more;
    const size_t i = topo_.index_of(best_ref);
    for (uint32_t n : topo_.neighbours(uint32_t(i)))
      if (!std::binary_search(cand.begin(), cand.end(), topo_.ref[n])) more.push_back(topo_.ref[n]);
    closest_of(more);
  }
  j.exact_hit = best.hit;
  j.exact_ref = best_ref;
  j.exact_t = best.hit ? best.t : 0.0;

  // Whether an answer is exactly right, or off only by the side of an edge it passes within rounding of
  const auto right = [&](const Hit& h) {
    if (h.flags & sh::kHitGapFill) return false;
    if (is_miss(h)) return !best.hit;
    if (!best.hit) return false;
    const ExactTest e = test(ray, ref_of(h));
    return e.hit && compare_t(e, best) == 0;
  };
  const auto near = [&](const Hit& h) {
    if (is_miss(h) || !best.hit || (h.flags & sh::kHitGapFill)) return false;
    const ExactTest e = test(ray, ref_of(h));
    if (!e.parallel && e.margin >= -kNearMargin && std::abs(e.plane_t - best.t) <= kNearT * std::abs(best.t))
      return true;
    // Within the rounding of the ray's inputs: float tests form v - org, which is rounded to the
    // ulps of the larger coordinate; the answer is the same point when its triangle passes within
    // kNearUlps of those ulps of the exact hit point, at a t as close
    const size_t k = topo_.index_of(ref_of(h));
    if (k == SIZE_MAX) return false;
    const glm::dvec3 o(ray.org), d(ray.dir);
    const glm::dvec3 p = o + d * best.t;
    const double delta = kNearUlps * 0x1p-24 * std::max(max_abs(o), max_abs(p));
    const auto& t = topo_.tri[k];
    return point_triangle_distance(p, t[0], t[1], t[2]) <= delta &&
           std::abs(double(h.t) - best.t) * glm::length(d) <= delta + kNearT * best.t * glm::length(d);
  };
  const bool g_ok = right(got), w_ok = right(want);
  if (same && g_ok) return j;
  if (g_ok && w_ok) {
    j.verdict = Verdict::tie;
    j.why = "both exactly at the closest t";
  } else if (g_ok) {
    j.verdict = near(want) ? Verdict::near : Verdict::embree_wrong;
    j.why = "Embree's answer is not the exact closest hit";
  } else if (near(got)) {
    j.verdict = Verdict::near;
    j.why = "the same point within rounding, on another triangle";
  } else {
    bool farther = is_miss(got);
    if (!farther && !(got.flags & sh::kHitGapFill)) {
      const ExactTest e = test(ray, ref_of(got));
      farther = !e.hit || compare_t(e, best) > 0;
    }
    // Whether the origin's rounding exceeds the triangles involved
    const auto longest_edge = [&](uint32_t ref) {
      const size_t k = topo_.index_of(ref);
      if (k == SIZE_MAX) return 0.0;
      const auto& t = topo_.tri[k];
      return std::max({glm::length(glm::dvec3(t[1]) - glm::dvec3(t[0])), glm::length(glm::dvec3(t[2]) - glm::dvec3(t[1])),
                       glm::length(glm::dvec3(t[0]) - glm::dvec3(t[2]))});
    };
    double size = 0.0;
    if (!is_miss(got)) size = std::max(size, longest_edge(ref_of(got)));
    if (!is_miss(want)) size = std::max(size, longest_edge(ref_of(want)));
    if (best.hit) size = std::max(size, longest_edge(best_ref));
    const double delta = kNearUlps * 0x1p-24 * max_abs(glm::dvec3(ray.org));
    if (delta >= size) {
      j.verdict = Verdict::unresolved;
      j.why = "the origin's rounding exceeds the triangles' size";
    } else if (best.hit && best.boundary && farther) {
      j.verdict = Verdict::crack;
      j.why = is_miss(got) ? "passes through an edge or vertex and hits nothing"
                           : "passes through an edge or vertex and reports a farther triangle";
    } else if (exact_for_moved_origin(ray, got, cand)) {
      j.verdict = Verdict::unresolved;
      j.why = "the exact answer of the ray with its origin moved within its rounding";
    } else {
      j.verdict = Verdict::grid_wrong;
      j.why = (got.flags & sh::kHitGapFill) ? "a gap-fill voxel"
              : is_miss(got)               ? "misses the exact closest hit"
              : !best.hit                  ? "hits where nothing is hit exactly"
                                           : "reports another triangle than the exact closest";
    }
  }
  return j;
}

}  // namespace gridrt::verify
