#include "verify/rays.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <unordered_map>

#include <bit>

#include <gmpxx.h>
#include <glm/gtc/matrix_transform.hpp>

#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/shared/grid.h"

namespace gridrt::verify {

namespace sh = gridrt::shared;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

const char* const kNames[kFamilies] = {"camera", "bounce", "random", "surface", "edge", "vertex",
                                       "axis",   "plane",  "lattice", "graze", "far",  "degenerate"};

Ray make_ray(glm::vec3 org, glm::vec3 dir, float tmin = 0.0f, float tmax = kInf) {
  Ray r{};
  r.org = org;
  r.dir = dir;
  r.tmin = tmin;
  r.tmax = tmax;
  r.launch_normal = glm::vec3(0.0f);
  r.launch_ref = sh::kNoRef;
  return r;
}

struct Rng {
  std::mt19937_64 gen;
  explicit Rng(uint64_t seed) : gen(seed) {}
  double uniform() { return double(gen() >> 11) * 0x1p-53; }
  float range(float lo, float hi) { return float(double(lo) + (double(hi) - double(lo)) * uniform()); }
  size_t index(size_t n) { return size_t(gen() % n); }
  glm::vec3 sphere() {
    const double z = 2.0 * uniform() - 1.0, phi = 2.0 * std::numbers::pi * uniform();
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    return glm::vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z));
  }
  glm::vec3 in_box(glm::vec3 lo, glm::vec3 hi) { return {range(lo.x, hi.x), range(lo.y, hi.y), range(lo.z, hi.z)}; }
  // Cosine-weighted around unit n
  glm::vec3 hemisphere(glm::vec3 n) {
    glm::vec3 d = sphere();
    if (glm::dot(d, n) < 0.0f) d = -d;
    return glm::normalize(d + n);
  }
};

glm::vec3 unit_normal(const std::array<glm::vec3, 3>& t) {
  const glm::vec3 n = glm::cross(t[1] - t[0], t[2] - t[0]);
  const float l = glm::length(n);
  return l > 0.0f && std::isfinite(l) ? n / l : glm::vec3(0.0f);
}

bool finite3(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Whether k (o + d) == target exactly (k = 1: the vertex; k = 2: a + b, twice the edge's midpoint),
// in integers (the floats scaled by 2^175).
mpz_class scaled(float f) {
  if (f == 0.0f) return 0;
  int e = 0;
  const float m = std::frexp(f, &e);
  mpz_class z = long(std::ldexp(double(m), 24));
  mpz_mul_2exp(z.get_mpz_t(), z.get_mpz_t(), mp_bitcnt_t(e - 24 + 175));
  return z;
}
bool passes_exactly(glm::vec3 o, glm::vec3 d, int k, glm::vec3 a, glm::vec3 b, bool midpoint) {
  for (int i = 0; i < 3; ++i) {
    const mpz_class lhs = k * (scaled(o[i]) + scaled(d[i]));
    const mpz_class rhs = midpoint ? scaled(a[i]) + scaled(b[i]) : scaled(a[i]);
    if (lhs != rhs) return false;
  }
  return true;
}

// A ray through `target` (a vertex) or through the midpoint of a-b (midpoint), exactly: the
// origin is drawn near it, the direction computed in double and kept only where the identity
// holds exactly (o + d == v, or 2 (o + d) == a + b: o + d is the midpoint). (The identity was
// o + 2d == a + b, which puts a + b, not the midpoint, on the ray: the edge family's rays passed
// through no edge, and found no tie in a thousand; an outside sweep saw the directions, about
// (a + b) / 4, leave the domain on a scene moved 2^21 away.)
// A ray whose direction is shorter than the domain's least (its largest component below 2^-20,
// shared::ray_domain) lengthened by a power of two, exactly (the same line; tmin and tmax shrunk by
// it, exactly too), so that it is traced: the families that aim at a feature's point, graze a face
// or head for a centroid made directions about the scene's size, and on a scene under 1e-5 units
// every such ray lay outside the domain and those families judged nothing (an outside sweep).
Ray scaled_into_domain(Ray r) {
  const float m = std::max({std::abs(r.dir.x), std::abs(r.dir.y), std::abs(r.dir.z)});
  if (!(m > 0.0f) || !std::isfinite(m) || m >= sh::kDomainMinDirection) return r;
  const int k = std::ilogb(sh::kDomainMinDirection) - std::ilogb(m) + 1;  // m 2^k in [2^-20, 2^-18)
  r.dir = glm::vec3(std::ldexp(r.dir.x, k), std::ldexp(r.dir.y, k), std::ldexp(r.dir.z, k));
  r.tmin = std::ldexp(r.tmin, -k);
  r.tmax = std::ldexp(r.tmax, -k);
  return r;
}

bool aim_exactly(Rng& rng, glm::vec3 a, glm::vec3 b, bool midpoint, float scale, Ray& out) {
  for (int attempt = 0; attempt < 24; ++attempt) {
    const glm::vec3 dir0 = rng.sphere();
    const glm::dvec3 target = midpoint ? (glm::dvec3(a) + glm::dvec3(b)) : glm::dvec3(a);
    const int k = midpoint ? 2 : 1;
    // The origin at least 2^-16 of the point's largest coordinate from it, 16 times the origin
    // epsilon (shared::origin_tmin): nearer, the point lies inside the ray's epsilon and no tracer
    // reaches it (far from the origin two rays in three of the scene-sized draws did)
    const double reach = std::max({std::abs(target.x), std::abs(target.y), std::abs(target.z)}) / double(k);
    const float r = std::max(scale * float(std::exp2(-12.0 * rng.uniform())), float(std::ldexp(reach, -16)));
    // origin: target / k' - dir * r, rounded; then d = (target - o) / k in double, rounded
    // (o read back through memory: in one build GCC 12 at -O2 was seen computing d below from the
    // double before its rounding to float, a debug print of o.x showing 52 bits, and the identity
    // failed on most draws; the build of this code rounds first either way, and the cause was not
    // found, so the floats traced are made explicit)
    const glm::vec3 o0 = glm::vec3((midpoint ? target * 0.5 : target) - glm::dvec3(dir0) * double(r));
    volatile float stored[3] = {o0.x, o0.y, o0.z};
    const glm::vec3 o(stored[0], stored[1], stored[2]);
    const glm::vec3 d = glm::vec3(target / double(k) - glm::dvec3(o));
    if (!(finite3(o) && finite3(d)) || d == glm::vec3(0.0f)) continue;
    if (!passes_exactly(o, d, k, a, b, midpoint)) continue;
    out = scaled_into_domain(make_ray(o, d));
    return true;
  }
  return false;
}

}  // namespace

const char* to_string(Family f) { return kNames[size_t(f)]; }

std::optional<Family> family_from_string(const std::string& name) {
  for (size_t i = 0; i < kFamilies; ++i)
    if (name == kNames[i]) return Family(i);
  return std::nullopt;
}

std::vector<Family> all_families() {
  std::vector<Family> f;
  for (size_t i = 0; i < kFamilies; ++i) f.push_back(Family(i));
  return f;
}

std::string family_list() {
  std::string s;
  for (size_t i = 0; i < kFamilies; ++i) s += (i ? ", " : "") + std::string(kNames[i]);
  return s;
}

size_t Topology::index_of(uint32_t r) const {
  const uint32_t inst = sh::ref_instance(r), t = sh::ref_triangle(r);
  if (inst + 1 >= instance_offset.size()) return SIZE_MAX;
  const size_t k = size_t(instance_offset[inst]) + t;
  if (k >= instance_offset[inst + 1]) return SIZE_MAX;
  return ref_to_index[k];
}

std::vector<uint32_t> Topology::neighbours(uint32_t index) const {
  std::vector<uint32_t> out;
  if (index >= corner.size()) return out;
  for (uint32_t p : corner[index])
    for (uint32_t n : by_vertex_index[p])
      if (n != index) out.push_back(n);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

Topology make_topology(const reference::GridData& grid) {
  Topology t;
  struct Key {
    uint32_t x, y, z;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    size_t operator()(const Key& k) const { return (size_t(k.x) * 0x9E3779B97F4A7C15ull) ^ (size_t(k.y) * 0xC2B2AE3D27D4EB4Full) ^ k.z; }
  };
  std::unordered_map<Key, uint32_t, KeyHash> ids;
  const auto id_of = [&](glm::vec3 p) {
    p += glm::vec3(0.0f);  // -0 and +0 are one position
    const Key k{std::bit_cast<uint32_t>(p.x), std::bit_cast<uint32_t>(p.y), std::bit_cast<uint32_t>(p.z)};
    auto [it, fresh] = ids.try_emplace(k, uint32_t(t.positions.size()));
    if (fresh) {
      t.positions.push_back(p);
      t.by_vertex_index.emplace_back();
    }
    return it->second;
  };
  t.instance_offset.push_back(0);
  for (const sh::GridInstance& in : grid.instances) t.instance_offset.push_back(t.instance_offset.back() + in.tri_count);
  t.ref_to_index.assign(t.instance_offset.back(), SIZE_MAX);
  for (uint32_t i = 0; i < grid.instances.size(); ++i)
    for (uint32_t k = 0; k < grid.instances[i].tri_count; ++k) {
      const sh::GridTriangle& g = grid.triangles[grid.instances[i].tri_offset + k];
      const std::array<glm::vec3, 3> v{g.v0, g.v1, g.v2};
      // A zero-area triangle, as the grid decides it (exactly: a cap whose float edges are parallel
      // has area, is inserted and is hit), is hit by no ray
      if (sh::triangle_zero_area(v[0], v[1], v[2])) continue;
      const uint32_t index = uint32_t(t.tri.size());
      t.ref_to_index[t.instance_offset[i] + k] = index;
      t.tri.push_back(v);
      t.ref.push_back(sh::ref_pack(i, k));
      std::array<uint32_t, 3> c{id_of(v[0]), id_of(v[1]), id_of(v[2])};
      t.corner.push_back(c);
      for (uint32_t p : c) t.by_vertex_index[p].push_back(index);
    }
  // Shared edges (two or more triangles) and vertices (three or more)
  std::map<std::pair<uint32_t, uint32_t>, uint32_t> edges;
  for (const auto& c : t.corner)
    for (int e = 0; e < 3; ++e) {
      const uint32_t a = c[e], b = c[(e + 1) % 3];
      edges[{std::min(a, b), std::max(a, b)}] += 1;
    }
  for (const auto& [e, n] : edges)
    if (n >= 2 && e.first != e.second) t.shared_edges.push_back(e);
  for (uint32_t p = 0; p < t.positions.size(); ++p)
    if (t.by_vertex_index[p].size() >= 3) t.shared_vertices.push_back(p);
  return t;
}

Scene translated(const Scene& scene, glm::vec3 offset) {
  Scene s = scene;
  const glm::mat4 m = glm::translate(glm::mat4(1.0f), offset);
  for (Instance& i : s.instances) {  // frozen at time 0 (a motion would turn about the old origin)
    i.transform = m * i.transform_at(0.0f);
    i.motion = Motion{};
    i.dynamic = false;
  }
  Camera c = scene.frame_camera();
  c.eye += offset;
  c.target += offset;
  s.camera = c;
  for (Light& l : s.lights)
    if (!l.directional) l.position += offset;
  s.name = scene.name + " (translated)";
  return s;
}

std::string translated_problem(const Scene& scene, glm::vec3 offset, const reference::GridOptions* grid) {
  Scene s = translated(scene, offset);
  try {
    s.finalize();
  } catch (const Error& e) {
    return e.what();
  }
  // The grid out there, where the scene's own can be chosen (else its error is the run's, not the
  // translation's)
  if (grid) {
    try {
      reference::choose_grid(scene, 0.0f, *grid);
    } catch (const Error&) {
      return "";
    }
  }
  try {
    if (grid) reference::choose_grid(s, 0.0f, *grid);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

Scene without_alpha(const Scene& scene) {
  Scene s = scene;
  for (Material& m : s.materials) m.alpha_texture = -1;
  return s;
}

namespace {

// One family's rays: what the generators read and where they write.
struct FamilyMaker {
  const Scene& scene;
  const Topology& topo;
  Tracer& oracle;
  const sh::GridParams& g;
  const glm::vec3 lo, hi;  // the grid's box
  const float scale;       // its diagonal
  const size_t n;          // rays wanted
  const Camera cam;
  Rng rng;
  FamilyRays& out;

  void push(const Ray& r, std::vector<uint32_t> aimed = {}) {
    out.rays.push_back(r);
    out.aimed.push_back(std::move(aimed));
  }

  // A camera's rays over a 16:9 image of about n pixels
  void camera_rays() {
    for (const Ray& r : camera_grid_rays(cam, n - std::min(n, out.rays.size()))) push(r);
  }

  // Off the oracle's primary hits: mirror and cosine-weighted, alternately
  void bounce_rays() {
    const uint32_t w = std::max<uint32_t>(1, uint32_t(std::sqrt(double(n) * 16.0 / 9.0)));
    const uint32_t h = std::max<uint32_t>(1, uint32_t((n + w - 1) / w));
    const GatherBuffer gb = make_gather(scene, oracle, cam, w, h, 0.0f);
    for (size_t p = 0; p < gb.size() && out.rays.size() < n; ++p) {
      if (!gb.valid[p]) continue;
      const glm::vec3 nrm = gb.normal[p];
      const glm::vec3 d = (p % 2) ? rng.hemisphere(nrm) : glm::reflect(gb.incident[p], nrm);
      Ray r = make_ray(gb.position[p], d);
      r.launch_normal = nrm;
      r.launch_ref = gb.launch_ref[p];
      push(r);
    }
  }

  // Origins in the grid's box, directions on the sphere
  void random_rays() {
    for (size_t i = 0; i < n; ++i) push(make_ray(rng.in_box(lo, hi), rng.sphere()));
  }

  // From a triangle's interior, vertex or edge midpoint: in front, behind or grazing
  void surface_rays() {
    if (topo.tri.empty()) return;
    for (size_t i = 0; i < n; ++i) {
      const size_t k = rng.index(topo.tri.size());
      const auto& t = topo.tri[k];
      const glm::vec3 nrm = unit_normal(t);
      if (nrm == glm::vec3(0.0f)) continue;
      glm::vec3 p;
      switch (i % 3) {
        case 0: {  // interior
          float a = float(rng.uniform()), b = float(rng.uniform());
          if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
          p = t[0] + a * (t[1] - t[0]) + b * (t[2] - t[0]);
          break;
        }
        case 1: p = t[rng.index(3)]; break;                                  // a vertex
        default: {                                                             // an edge midpoint
          const size_t e = rng.index(3);
          p = (t[e] + t[(e + 1) % 3]) * 0.5f;
        }
      }
      glm::vec3 d, ln = nrm;
      switch ((i / 3) % 3) {
        case 0: d = rng.hemisphere(nrm); break;                         // in front
        case 1: d = rng.hemisphere(-nrm), ln = -nrm; break;             // behind
        default: {                                                     // grazing, either side
          const glm::vec3 tg = glm::normalize(glm::cross(nrm, rng.sphere()));
          d = glm::normalize(tg + nrm * float(rng.uniform() < 0.5 ? 1e-4 : -1e-4));
        }
      }
      Ray r = make_ray(p, d);
      r.launch_normal = ln;
      r.launch_ref = topo.ref[k];
      push(r);
    }
  }

  // Through a shared edge's midpoint or a shared vertex, exactly
  void aimed_rays(bool edge) {
    const size_t pool = edge ? topo.shared_edges.size() : topo.shared_vertices.size();
    if (pool == 0) return;
    for (size_t i = 0; i < n * 4 && out.rays.size() < n; ++i) {
      ++out.attempts;
      Ray r;
      std::vector<uint32_t> aimed;
      if (edge) {
        const auto [pa, pb] = topo.shared_edges[rng.index(pool)];
        if (!aim_exactly(rng, topo.positions[pa], topo.positions[pb], true, 0.25f * scale, r)) continue;
        for (uint32_t k : topo.by_vertex_index[pa]) aimed.push_back(topo.ref[k]);
        for (uint32_t k : topo.by_vertex_index[pb]) aimed.push_back(topo.ref[k]);
      } else {
        const uint32_t pv = topo.shared_vertices[rng.index(pool)];
        if (!aim_exactly(rng, topo.positions[pv], topo.positions[pv], false, 0.25f * scale, r)) continue;
        for (uint32_t k : topo.by_vertex_index[pv]) aimed.push_back(topo.ref[k]);
      }
      push(r, std::move(aimed));
    }
  }

  // Axis-aligned, signed-zero and denormal directions
  void axis_rays() {
    const float denorm[] = {1e-40f, -1e-42f, 1.4e-45f, -3e-39f};
    for (size_t i = 0; i < n; ++i) {
      const glm::vec3 o = rng.in_box(lo, hi);
      glm::vec3 d(0.0f);
      const int k = int(rng.index(3));
      const float s = rng.uniform() < 0.5 ? -1.0f : 1.0f;
      switch (i % 4) {
        case 0:  // axis-aligned, the others +0 or -0
          d[k] = s;
          d[(k + 1) % 3] = rng.uniform() < 0.5 ? -0.0f : 0.0f;
          d[(k + 2) % 3] = rng.uniform() < 0.5 ? -0.0f : 0.0f;
          break;
        case 1: {  // one component zero (signed)
          const glm::vec3 u = rng.sphere();
          d = u;
          d[k] = rng.uniform() < 0.5 ? -0.0f : 0.0f;
          if (d == glm::vec3(0.0f)) d[(k + 1) % 3] = 1.0f;
          break;
        }
        case 2:  // axis-aligned plus denormal components
          d[k] = s;
          d[(k + 1) % 3] = denorm[rng.index(4)];
          d[(k + 2) % 3] = denorm[rng.index(4)];
          break;
        default: {  // a random direction with one denormal component
          d = rng.sphere();
          d[k] = denorm[rng.index(4)];
        }
      }
      push(make_ray(o, d));
    }
  }

  // In the plane of an axis-aligned triangle
  void plane_rays() {
    std::vector<size_t> flat;  // triangles whose vertices share one coordinate
    std::vector<int> axis_of;
    for (size_t k = 0; k < topo.tri.size(); ++k)
      for (int a = 0; a < 3; ++a)
        if (topo.tri[k][0][a] == topo.tri[k][1][a] && topo.tri[k][0][a] == topo.tri[k][2][a]) {
          flat.push_back(k);
          axis_of.push_back(a);
          break;
        }
    if (flat.empty()) return;
    for (size_t i = 0; i < n; ++i) {
      const size_t j = rng.index(flat.size());
      const auto& t = topo.tri[flat[j]];
      const int a = axis_of[j];
      glm::vec3 o = rng.in_box(lo, hi);
      o[a] = t[0][a];
      glm::vec3 d;
      if (i % 2) {
        d = (t[0] + t[1] + t[2]) * (1.0f / 3.0f) - o;  // towards the centroid, in the plane
      } else {
        d = rng.sphere();
      }
      d[a] = rng.uniform() < 0.5 ? -0.0f : 0.0f;
      if (d == glm::vec3(0.0f)) d[(a + 1) % 3] = 1.0f;
      push(scaled_into_domain(make_ray(o, d)));
    }
  }

  // From the cells' lattice planes, some along an axis
  void lattice_rays() {
    for (size_t i = 0; i < n; ++i) {
      glm::vec3 o = rng.in_box(lo, hi);
      const int planes = (i % 3 == 2) ? 3 : int(i % 3) + 1;  // one, two or all three coordinates
      int last_plane = 0;  // an axis whose coordinate was put on a cell plane
      for (int q = 0; q < planes; ++q) {
        const int a = planes == 3 ? q : int(rng.index(3));
        const uint32_t c = uint32_t(rng.index(g.cells[a] + 1));
        o[a] = g.origin[a] + float(c) * g.cell_size;
        last_plane = a;
      }
      glm::vec3 d = rng.sphere();
      if (i % 4 == 3) {  // along an axis, along the lattice
        d = glm::vec3(0.0f);
        d[rng.index(3)] = rng.uniform() < 0.5 ? -1.0f : 1.0f;
      } else if (i % 8 == 5) {
        // Leaving the plane by a subnormal component (1 / d overflows): an outside sweep's find,
        // the DDA's exit along that axis was 0 * inf = NaN and the walk left closed meshes
        static const float kSubnormal[4] = {1e-40f, -1e-40f, 1.401298464e-45f, -2.9e-39f};
        d[last_plane] = kSubnormal[rng.index(4)];
      }
      push(make_ray(o, d));
    }
  }

  // Grazing the largest triangles
  void graze_rays() {
    if (topo.tri.empty()) return;
    std::vector<size_t> order(topo.tri.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = k;
    const size_t big = std::min<size_t>(order.size(), 64);
    std::partial_sort(order.begin(), order.begin() + ptrdiff_t(big), order.end(), [&](size_t x, size_t y) {
      const auto area = [&](size_t k) {
        return glm::length(glm::cross(topo.tri[k][1] - topo.tri[k][0], topo.tri[k][2] - topo.tri[k][0]));
      };
      return area(x) > area(y);
    });
    for (size_t i = 0; i < n; ++i) {
      const auto& t = topo.tri[order[rng.index(big)]];
      const glm::vec3 nrm = unit_normal(t);
      float a = float(rng.uniform()), b = float(rng.uniform());
      if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
      const glm::vec3 q = t[0] + a * (t[1] - t[0]) + b * (t[2] - t[0]);
      const glm::vec3 tg = glm::normalize(glm::cross(nrm, rng.sphere()));
      const float len = glm::length(t[1] - t[0]) * float(0.1 + rng.uniform());
      const float h = len * float(std::exp2(-4.0 - 16.0 * rng.uniform())) * (rng.uniform() < 0.5 ? 1.0f : -1.0f);
      const glm::vec3 o = q + tg * len + nrm * h;
      push(scaled_into_domain(make_ray(o, q - o)));
    }
  }

  // From 1e4 to 1e6 away, aimed at the surfaces
  void far_rays() {
    if (topo.tri.empty()) return;
    const glm::vec3 center = (lo + hi) * 0.5f;
    for (size_t i = 0; i < n; ++i) {
      const auto& t = topo.tri[rng.index(topo.tri.size())];
      float a = float(rng.uniform()), b = float(rng.uniform());
      if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
      const glm::vec3 q = t[0] + a * (t[1] - t[0]) + b * (t[2] - t[0]);
      const float dist = float(std::pow(10.0, 4.0 + 2.0 * rng.uniform()));
      const glm::vec3 o = center + rng.sphere() * dist;
      glm::vec3 d = q - o;
      if (i % 2) d = glm::normalize(d);
      push(make_ray(o, d));
    }
  }

  // Outside the domain or empty: huge, tiny, inf and NaN, tmin >= tmax, tmin < 0
  void degenerate_rays() {
    const glm::vec3 c = (lo + hi) * 0.5f;
    for (size_t i = 0; i < n; ++i) {
      const glm::vec3 u = rng.sphere();
      Ray r = make_ray(rng.in_box(lo, hi), c - rng.in_box(lo, hi));
      if (r.dir == glm::vec3(0.0f)) r.dir = u;
      switch (i % 16) {
        case 0: r.dir = u * 1e19f; break;                    // huge (beyond Embree's limit)
        case 1: r.dir = u * 3e6f; break;                     // above 2^20
        case 2: r.dir = u * 1e-20f; break;                   // tiny
        case 3: r.dir = u * 5e-7f; break;                    // below 2^-20
        case 4: r.dir.x = kInf; break;
        case 5: r.dir.y = kNaN; break;
        case 6: r.org.z = kNaN; break;
        case 7: r.org.x = -kInf; break;
        case 8: r.dir = glm::vec3(0.0f); break;
        case 9: r.dir = glm::vec3(-0.0f, 0.0f, -0.0f); break;
        case 10: r.tmin = 2.0f, r.tmax = 1.0f; break;       // empty interval
        case 11: r.tmin = r.tmax = 0.5f; break;             // empty interval
        case 12: r.tmin = -1.0f; break;                      // tmin < 0
        case 13: r.tmin = kNaN; break;
        case 14: r.org = u * 3e18f, r.dir = -u; break;       // beyond Embree's limit, far outside
        default: r.org = c + u * 2e7f, r.org.x = 3e7f, r.dir = -u;  // beyond 2^24
      }
      push(r);
    }
  }
};

}  // namespace

FamilyRays make_family(Family f, const Scene& scene, const reference::GridData& grid, const Topology& topo,
                       Tracer& oracle, const FamilyOptions& opt) {
  FamilyRays out;
  out.family = f;
  const sh::GridParams& g = grid.params;
  FamilyMaker maker{scene,
                    topo,
                    oracle,
                    g,
                    g.origin,
                    g.upper,
                    glm::length(g.upper - g.origin),
                    opt.rays,
                    scene.frame_camera(),
                    Rng(opt.seed * 0x9E3779B97F4A7C15ull + uint64_t(f) + 1),
                    out};
  switch (f) {
    case Family::camera: maker.camera_rays(); break;
    case Family::bounce: maker.bounce_rays(); break;
    case Family::random: maker.random_rays(); break;
    case Family::surface: maker.surface_rays(); break;
    case Family::edge: maker.aimed_rays(true); break;
    case Family::vertex: maker.aimed_rays(false); break;
    case Family::axis: maker.axis_rays(); break;
    case Family::plane: maker.plane_rays(); break;
    case Family::lattice: maker.lattice_rays(); break;
    case Family::graze: maker.graze_rays(); break;
    case Family::far: maker.far_rays(); break;
    case Family::degenerate: maker.degenerate_rays(); break;
  }
  return out;
}

std::vector<Ray> rays_of_kind(const std::string& kind, const Scene& scene, const reference::GridData& grid,
                              Tracer& oracle, uint32_t width, uint32_t height, uint64_t seed) {
  if (kind == "primary") return rays_of_kind("camera", scene, grid, oracle, width, height, seed);
  if (kind == "glossy" || kind == "diffuse") {
    // The gather buffer asked for (it was a 16:9 one of about as many pixels, whatever the shape)
    const GatherBuffer gb = make_gather(scene, oracle, scene.frame_camera(), std::max(width, 1u), std::max(height, 1u), 0.0f);
    std::vector<Ray> rays;
    if (kind == "glossy") {
      for (const Ray& r : bounce_rays(scene, gb, 0))
        if (!is_unused(r)) rays.push_back(r);
      return rays;
    }
    Rng rng(seed);
    for (size_t p = 0; p < gb.size(); ++p) {
      if (!gb.valid[p]) continue;
      Ray r = make_ray(gb.position[p], rng.hemisphere(gb.normal[p]));
      r.launch_normal = gb.normal[p];
      r.launch_ref = gb.launch_ref[p];
      rays.push_back(r);
    }
    return rays;
  }
  const std::optional<Family> f = family_from_string(kind);
  if (!f) throw OptionsError("--rays: unknown kind '" + kind + "' (" + ray_kind_list() + ")");
  const Topology topo = make_topology(grid);
  FamilyOptions o;
  o.rays = size_t(width) * height;
  o.seed = seed;
  return make_family(*f, scene, grid, topo, oracle, o).rays;
}

bool is_ray_kind(const std::string& kind) {
  return kind == "auto" || kind == "glossy" || kind == "primary" || kind == "diffuse" || family_from_string(kind).has_value();
}

std::string ray_kind_list() { return "auto, glossy, primary, diffuse, " + family_list(); }

}  // namespace gridrt::verify
