#include "verify/referee.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <cstdio>
#include <cstdlib>

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
  return exact_test_from(ray.org, ray.dir, sh::origin_tmin(ray.org, ray.dir, ray.tmin), ray.tmax, v0, v1, v2);
}

ExactTest exact_test_from(const glm::vec3& org, const glm::vec3& dir, float t_lo, float tmax, const glm::vec3& v0,
                          const glm::vec3& v1, const glm::vec3& v2) {
  ExactTest r;
  const V3 o = scaled(org), d = scaled(dir), a = scaled(v0), b = scaled(v1), c = scaled(v2);
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
  if (!(Ts > scaled(t_lo) * det)) return r;
  if (std::isfinite(tmax) && !(Ts < scaled(tmax) * det)) return r;
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

double condition_number(const Ray& ray, const std::array<glm::vec3, 3>& t, double exact_t) {
  const glm::dvec3 n = glm::cross(glm::dvec3(t[1]) - glm::dvec3(t[0]), glm::dvec3(t[2]) - glm::dvec3(t[0]));
  const glm::dvec3 d(ray.dir);
  const double nn = glm::length(n), dd = glm::length(d);
  const double td = exact_t * dd;
  const double cosv = nn > 0.0 && dd > 0.0 ? std::abs(glm::dot(n, d)) / (nn * dd) : 0.0;
  if (!(td > 0.0 && cosv > 0.0)) return std::numeric_limits<double>::infinity();
  const double vm = std::max({glm::length(glm::dvec3(t[0])), glm::length(glm::dvec3(t[1])), glm::length(glm::dvec3(t[2]))});
  return (glm::length(glm::dvec3(ray.org)) + vm + td) / (td * cosv);
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
  // The surface rule (both tracers', in their float arithmetic: a rule on the inputs, as the
  // origin epsilon is): a ray launched from a surface hits no face whose plane passes within 8
  // ulps of its origin
  if (ray.launch_ref != sh::kNoRef && sh::origin_on_plane(ray.org, t[0], t[1], t[2])) return {};
  return exact_test(ray, t[0], t[1], t[2]);
}

std::vector<size_t> Referee::near_line(const Ray& ray, double reach) const {
  const glm::dvec3 o(ray.org), d = glm::normalize(glm::dvec3(ray.dir));
  std::vector<size_t> out;
  for (size_t k = 0; k < topo_.tri.size(); ++k) {
    const auto& t = topo_.tri[k];
    // The triangle's distance from the line is at least that of its box in any direction across it
    double lo_x = INFINITY, hi_x = -INFINITY, lo_y = INFINITY, hi_y = -INFINITY, lo_z = INFINITY, hi_z = -INFINITY, along = -INFINITY;
    for (const glm::vec3& v : t) {
      const glm::dvec3 a = glm::dvec3(v) - o;
      along = std::max(along, glm::dot(a, d));
      lo_x = std::min(lo_x, a.x), hi_x = std::max(hi_x, a.x);
      lo_y = std::min(lo_y, a.y), hi_y = std::max(hi_y, a.y);
      lo_z = std::min(lo_z, a.z), hi_z = std::max(hi_z, a.z);
    }
    if (along < -reach) continue;  // wholly behind the origin
    // Box [lo, hi] (relative to the origin) against the line s d, inflated by reach: slab test
    double t0 = -INFINITY, t1 = INFINITY;
    bool hit = true;
    const double lo[3] = {lo_x - reach, lo_y - reach, lo_z - reach}, hi[3] = {hi_x + reach, hi_y + reach, hi_z + reach};
    for (int a = 0; a < 3 && hit; ++a) {
      if (d[a] == 0.0) {
        hit = lo[a] <= 0.0 && hi[a] >= 0.0;
        continue;
      }
      const double ta = lo[a] / d[a], tb = hi[a] / d[a];
      t0 = std::max(t0, std::min(ta, tb));
      t1 = std::min(t1, std::max(ta, tb));
    }
    if (hit && t0 <= t1) out.push_back(k);
  }
  return out;
}

bool Referee::near_open_edge(const Ray& ray, double t) const {
  const glm::dvec3 o(ray.org), p = o + glm::dvec3(ray.dir) * t;
  const double delta = kNearUlps * 0x1p-24 * std::max(max_abs(o), max_abs(p));
  const auto uses = [&](uint32_t a, uint32_t b) {
    size_t n = 0;
    for (size_t k : topo_.by_vertex_index[a]) {
      const auto& c = topo_.corner[k];
      n += (c[0] == b || c[1] == b || c[2] == b) ? 1 : 0;
    }
    return n;
  };
  for (size_t k : near_line(ray, 2.0 * delta)) {
    const auto& tri = topo_.tri[k];
    if (point_triangle_distance(p, tri[0], tri[1], tri[2]) > delta) continue;
    for (int e = 0; e < 3; ++e) {
      const uint32_t a = topo_.corner[k][e], b = topo_.corner[k][(e + 1) % 3];
      if (a == b || uses(a, b) != 1) continue;
      const glm::dvec3 va(tri[e]), ab = glm::dvec3(tri[(e + 1) % 3]) - va;
      const double len2 = glm::dot(ab, ab);
      const double s = len2 > 0.0 ? std::clamp(glm::dot(p - va, ab) / len2, 0.0, 1.0) : 0.0;
      if (glm::length(p - (va + ab * s)) <= delta) return true;
    }
  }
  return false;
}

// The most points exact_for_moved_origin tries on the outlines near the ray (5 an edge)
constexpr size_t kMaxOutlinePoints = 2000;

bool Referee::exact_for_moved_origin(const Ray& ray, const Hit& got, uint32_t exact) const {
  // The ray as traced: both triangle tests start from v - org rounded to float per vertex (the
  // watertight test for all three vertices; the same rounding of a shared vertex in every
  // triangle, so the surface stays closed). In that frame the origin is 0; the tests' later
  // steps (the shear, the edge functions) round relative to |v - org| |dir|, which moving the ray
  // perpendicular to itself by kNearUlps ulps of the largest coordinate covers.
  const auto ref_of = [](const Hit& h) { return sh::ref_pack(h.instance, h.triangle); };
  const bool miss = is_miss(got);
  if (got.flags & sh::kHitGapFill) return false;
  const glm::dvec3 o(ray.org), dd(ray.dir);
  const double reach_pt = miss || !std::isfinite(got.t) ? 0.0 : max_abs(o + dd * double(got.t));
  // The vertices as traced of got's triangle and the exact closest's: their rounding scale
  double reach_tri = 0.0;
  for (const uint32_t r : {miss ? sh::kNoRef : ref_of(got), exact}) {
    const size_t k = r == sh::kNoRef ? SIZE_MAX : topo_.index_of(r);
    if (k == SIZE_MAX) continue;
    for (int c = 0; c < 3; ++c) reach_tri = std::max(reach_tri, max_abs(glm::dvec3(topo_.tri[k][c] - ray.org)));
  }
  const double delta = kNearUlps * 0x1p-24 * std::max({max_abs(o), reach_pt, reach_tri});
  const std::vector<size_t> near = near_line(ray, 2.0 * delta);
  const size_t got_index = miss ? SIZE_MAX : topo_.index_of(ref_of(got));
  if (!miss && got_index == SIZE_MAX) return false;
  const size_t gi = miss ? SIZE_MAX : size_t(std::find(near.begin(), near.end(), got_index) - near.begin());
  if (!miss && gi == near.size()) return false;
  // The triangles as traced (float v - org), and their projections across the ray (double)
  const float t_lo = sh::origin_tmin(ray.org, ray.dir, ray.tmin);
  const glm::dvec3 dn = glm::normalize(dd);
  const glm::dvec3 b1 = glm::normalize(std::abs(dn.x) < 0.6 ? glm::cross(dn, glm::dvec3(1, 0, 0)) : glm::cross(dn, glm::dvec3(0, 1, 0)));
  const glm::dvec3 b2 = glm::cross(dn, b1);
  std::vector<std::array<glm::vec3, 3>> traced(near.size());
  std::vector<std::array<glm::dvec2, 3>> flat(near.size());
  std::vector<int> facing(near.size());  // sign of the normal along the ray
  double extent = delta;
  for (size_t i = 0; i < near.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      traced[i][c] = topo_.tri[near[i]][c] - ray.org;  // float: the tests' rounding
      const glm::dvec3 a(traced[i][c]);
      flat[i][c] = glm::dvec2(glm::dot(a, b1), glm::dot(a, b2));
      extent = std::max(extent, max_abs(a));
    }
    const auto& t = topo_.tri[near[i]];
    facing[i] = glm::dot(glm::cross(glm::dvec3(t[1]) - glm::dvec3(t[0]), glm::dvec3(t[2]) - glm::dvec3(t[0])), dn) < 0.0 ? -1 : 1;
  }
  // The surface rule's refusals (the tracers' float decision on the ray as given)
  std::vector<char> refused(near.size(), 0);
  if (ray.launch_ref != sh::kNoRef)
    for (size_t i = 0; i < near.size(); ++i) {
      const auto& t = topo_.tri[near[i]];
      refused[i] = sh::origin_on_plane(ray.org, t[0], t[1], t[2]) ? 1 : 0;
    }
  // Coincident triangles (the same three vertices as traced, in any order) give the same exact
  // test: one of each group is tested (a scene of 3,000 copies of one triangle tested every copy
  // at every offset, seconds a ray: an outside sweep). A group counts where one of its members
  // may be hit (not the launch triangle, not refused by the surface rule).
  std::vector<size_t> rep(near.size());
  std::vector<char> usable(near.size(), 0);  // per representative: some member may be hit
  {
    std::map<std::array<uint32_t, 9>, size_t> first_of;
    for (size_t i = 0; i < near.size(); ++i) {
      std::array<std::array<uint32_t, 3>, 3> v;
      for (int c = 0; c < 3; ++c)
        for (int a = 0; a < 3; ++a) v[size_t(c)][size_t(a)] = std::bit_cast<uint32_t>(traced[i][c][a]);
      std::sort(v.begin(), v.end());
      std::array<uint32_t, 9> key;
      for (size_t c = 0; c < 3; ++c)
        for (size_t a = 0; a < 3; ++a) key[3 * c + a] = v[c][a];
      rep[i] = first_of.emplace(key, i).first->second;
      if (topo_.ref[near[i]] != ray.launch_ref && !refused[i]) usable[rep[i]] = 1;
    }
  }
  // The triangles by 2D bin, for the per-offset tests
  constexpr int kBins = 16;
  std::vector<std::vector<size_t>> bins(kBins * kBins);
  const auto bin_of = [&](double x) { return std::clamp(int(std::floor((x / delta + 1.0) * 0.5 * kBins)), 0, kBins - 1); };
  for (size_t i = 0; i < near.size(); ++i) {
    double lx = INFINITY, hx = -INFINITY, ly = INFINITY, hy = -INFINITY;
    for (const glm::dvec2& p : flat[i]) lx = std::min(lx, p.x), hx = std::max(hx, p.x), ly = std::min(ly, p.y), hy = std::max(hy, p.y);
    if (lx > delta * 1.01 || hx < -delta * 1.01 || ly > delta * 1.01 || hy < -delta * 1.01) continue;
    for (int y = bin_of(ly); y <= bin_of(hy); ++y)
      for (int x = bin_of(lx); x <= bin_of(hx); ++x) bins[size_t(y * kBins + x)].push_back(i);
  }
  const double tol = 1e-9 * extent;  // the projection's own rounding, generously
  const auto may_contain = [&](size_t i, glm::dvec2 q) {
    bool pos = false, neg = false;
    for (int e = 0; e < 3; ++e) {
      const glm::dvec2 a = flat[i][e], b = flat[i][(e + 1) % 3], ab = b - a;
      const double len = glm::length(ab);
      const double side = ab.x * (q.y - a.y) - ab.y * (q.x - a.x);
      if (side > tol * len) pos = true;
      if (side < -tol * len) neg = true;
    }
    return !(pos && neg);
  };
  // Whether the ray moved by q (across it, |q| <= delta) gives got: a miss where it misses every
  // triangle; a hit where it hits got's triangle, and nothing more than delta nearer (the depth's
  // rounding)
  const auto gives_got = [&](glm::dvec2 q) {
    if (glm::length(q) > delta * (1.0 + 1e-9)) return false;
    const glm::vec3 org(glm::dvec3(q.x * b1 + q.y * b2));  // the moved origin, in the traced frame
    ExactTest best, g;
    size_t best_i = SIZE_MAX;
    for (size_t i : bins[size_t(bin_of(q.y) * kBins + bin_of(q.x))]) {
      if (rep[i] != i || !may_contain(i, q)) continue;
      const ExactTest x = exact_test_from(org, ray.dir, t_lo, ray.tmax, traced[i][0], traced[i][1], traced[i][2]);
      if (!x.hit) continue;
      // got's own triangle, where it may be hit (the launch triangle and the surface rule's
      // refusals, decided on the ray as given, are not)
      if (!miss && rep[gi] == i && topo_.ref[near[gi]] != ray.launch_ref && !refused[gi]) g = x;
      if (!usable[i]) continue;
      if (!best.hit || compare_t(x, best) < 0) best = x, best_i = i;
    }
    if (miss) return !best.hit;
    return best.hit && g.hit && (best_i == rep[gi] || (g.t - best.t) * glm::length(dd) <= delta);
  };
  // Where the answer can change within the disc: the answer's own edges, and the outline of the
  // surfaces as seen along the ray (edges of one triangle, of more than two, or between a front and
  // a back face). Tried: the ray itself, points just inside and outside each such edge at its point
  // nearest the ray, and a polar grid of the disc.
  std::vector<glm::dvec2> offsets{glm::dvec2(0.0)};
  const double eta = 1e-4 * delta;
  bool outline_near = false;
  const auto add_edge_points = [&](size_t i, int e) {
    const glm::dvec2 a = flat[i][e], b = flat[i][(e + 1) % 3], ab = b - a;
    const glm::dvec2 centroid = (flat[i][0] + flat[i][1] + flat[i][2]) / 3.0;
    const double len2 = glm::dot(ab, ab);
    const double s = len2 > 0.0 ? std::clamp(-glm::dot(a, ab) / len2, 0.0, 1.0) : 0.0;
    const glm::dvec2 c = a + ab * s;  // the edge's point nearest the ray
    if (glm::length(c) > delta) return false;
    glm::dvec2 n = len2 > 0.0 ? glm::dvec2(-ab.y, ab.x) / std::sqrt(len2) : glm::dvec2(0.0);
    if (glm::dot(n, centroid - c) < 0.0) n = -n;  // inward
    for (double f : {1.0, 0.01}) {
      offsets.push_back(c + n * (eta * f));  // just inside
      offsets.push_back(c - n * (eta * f));  // just outside
    }
    offsets.push_back(c + (centroid - c) * 1e-3);  // toward the centroid (slivers)
    return true;
  };
  if (!miss) {
    for (int e = 0; e < 3; ++e) add_edge_points(gi, e);
    const glm::dvec2 centroid = (flat[gi][0] + flat[gi][1] + flat[gi][2]) / 3.0;
    if (glm::length(centroid) <= delta) offsets.push_back(centroid);
  }
  for (double r : {0.125, 0.25, 0.5, 1.0})
    for (int k = 0; k < 16; ++k) offsets.push_back(r * delta * glm::dvec2(std::cos(k * M_PI / 8), std::sin(k * M_PI / 8)));
  for (const glm::dvec2& q : offsets)
    if (gives_got(q)) return true;
  offsets.clear();
  {
    std::map<std::pair<uint32_t, uint32_t>, std::vector<std::pair<size_t, int>>> edges;  // position pair -> (near index, edge)
    for (size_t i = 0; i < near.size(); ++i)
      for (int e = 0; e < 3; ++e) {
        const uint32_t a = topo_.corner[near[i]][e], b = topo_.corner[near[i]][(e + 1) % 3];
        edges[{std::min(a, b), std::max(a, b)}].push_back({i, e});
      }
    for (const auto& [key, uses] : edges) {
      const bool outline = uses.size() != 2 || facing[uses[0].first] != facing[uses[1].first];
      if (outline)
        for (const auto& [i, e] : uses) outline_near = add_edge_points(i, e) || outline_near;
    }
  }
  // A disc that holds thousands of outlines (an origin so far that its rounding is many times the
  // scene: 0.03 against a model 1e-4 wide): each point tries every triangle exactly, and one ray
  // took 34 s (an outside sweep). The input resolves nothing there: the ray is unresolved
  if (offsets.size() > kMaxOutlinePoints) return true;
  for (const glm::dvec2& q : offsets)
    if (gives_got(q)) return true;
  // A hit where the ray passes within delta of an outline of the surfaces and of got's triangle:
  // the rounding of each vertex (not a rigid move of the ray) can fold the outline over the ray,
  // so the surface behind it is as good as the input resolves
  if (!miss && outline_near) {
    double dist = INFINITY;
    for (int e = 0; e < 3; ++e) {
      const glm::dvec2 a = flat[gi][e], b = flat[gi][(e + 1) % 3], ab = b - a;
      const double len2 = glm::dot(ab, ab);
      const double s = len2 > 0.0 ? std::clamp(-glm::dot(a, ab) / len2, 0.0, 1.0) : 0.0;
      dist = std::min(dist, glm::length(a + ab * s));
    }
    if (may_contain(gi, glm::dvec2(0.0)) || dist <= delta) return true;
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
  {  // every triangle the exact ray can meet (Embree's float hits may miss some)
    const double reach = 0x1p-20 * std::max(max_abs(glm::dvec3(ray.org)), 1.0);
    for (size_t k : near_line(ray, reach)) cand.push_back(topo_.ref[k]);
  }
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
  // Seeds on the same three vertices (coincident copies) have the same neighbours, each other
  // included: one of them is enough (3,000 copies of one triangle sorted 3,000 neighbour lists of
  // 9,000 a ray, a minute for 10 rays: an outside sweep)
  {
    std::sort(seeds.begin(), seeds.end());
    seeds.erase(std::unique(seeds.begin(), seeds.end()), seeds.end());
    std::set<std::array<uint32_t, 3>> done;
    for (uint32_t r : seeds) {
      const size_t i = topo_.index_of(r);
      if (i == SIZE_MAX) continue;
      std::array<uint32_t, 3> c = topo_.corner[i];
      std::sort(c.begin(), c.end());
      if (done.insert(c).second) add_neighbours(r);
    }
  }
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
  std::string near_why = "the same point within rounding, on another triangle";
  const auto near = [&](const Hit& h) {
    if (is_miss(h) || !best.hit || (h.flags & sh::kHitGapFill)) return false;
    const ExactTest e = test(ray, ref_of(h));
    if (!e.parallel && e.margin >= -kNearMargin && std::abs(e.plane_t - best.t) <= kNearT * std::abs(best.t))
      return true;
    // Two faces met at t's closer than their conditioning lets any float test order: rounding
    // the inputs by u moves an exact t by about kappa u t (kappa the ray's condition number on
    // that triangle, as for the t bound), so faces whose exact t's differ by less than
    // kNearKappa u (kappa_a + kappa_b) t come out of a float test in either order, or at one t
    // (faces 1 ulp apart met by a grazing ray: kappa 1e3 to 1e4, the grid's t the same in bits
    // for both, the tie rule taking the lower reference: an outside sweep's find)
    if (e.hit) {
      const size_t kg = topo_.index_of(ref_of(h)), kb = topo_.index_of(best_ref);
      if (kg != SIZE_MAX && kb != SIZE_MAX) {
        const double kappa = condition_number(ray, topo_.tri[kg], e.t) + condition_number(ray, topo_.tri[kb], best.t);
        if (std::abs(e.t - best.t) <= kNearKappa * 0x1p-24 * kappa * std::abs(best.t)) {
          char why[200];
          std::snprintf(why, sizeof why,
                        "another face at a t within its conditioning of the exact closest (kappa %.3g + %.3g): no "
                        "float test orders them", condition_number(ray, topo_.tri[kg], e.t),
                        condition_number(ray, topo_.tri[kb], best.t));
          near_why = why;
          return true;
        }
      }
    }
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
    j.why = near_why;
  } else {
    bool farther = is_miss(got);
    if (!farther && !(got.flags & sh::kHitGapFill)) {
      const ExactTest e = test(ray, ref_of(got));
      farther = !e.hit || compare_t(e, best) > 0;
    }
    // A crack is a ray that passes through the surface at an edge or vertex: where the ray only
    // touches an outline there (a silhouette edge or vertex, the surface on one side of the ray),
    // a ray moved within the inputs' rounding gets the tracer's answer, and no rule of a triangle
    // test can promise the touch: such a ray is unresolved, not a crack
    const bool moved = exact_for_moved_origin(ray, got, best.hit ? best_ref : sh::kNoRef);
    const bool at_edge = best.hit && best.boundary && farther;
    if (!moved && is_miss(got) && best.hit && near_open_edge(ray, best.t)) {
      j.verdict = Verdict::unresolved;
      j.why = "a miss within rounding of an open edge (a T-junction's or a border's): each triangle's edge there "
              "is its own, rounded apart from the other side's in any float test";
    } else if (at_edge && !moved) {
      j.verdict = Verdict::crack;
      j.why = is_miss(got) ? "passes through an edge or vertex and hits nothing"
                           : "passes through an edge or vertex and reports a farther triangle";
    } else if (moved) {
      j.verdict = Verdict::unresolved;
      j.why = at_edge       ? "touches an outline at an edge or vertex: the ray as traced (v - org in float), moved "
                              "within its rounding, gets the same answer"
              : is_miss(got) ? "a miss: the ray as traced (v - org in float), moved within its rounding, misses every triangle"
                             : "the exact answer of the ray as traced (v - org in float), moved within its rounding";
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
