// test_grid_util.h: helpers of the grid tests: hex printing, random and analytic scenes, a
// double-precision brute-force closest hit.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <sstream>
#include <string>

#include "common/scene.h"
#include "common/tracer.h"
#include "reference/grid.h"

namespace gridtest {

using namespace gridrt;

inline std::string hx(float f) { return std::to_string(f) + "[" + reference::hex(f) + "]"; }
inline std::string hx(glm::vec3 v) { return "(" + hx(v.x) + ", " + hx(v.y) + ", " + hx(v.z) + ")"; }
inline std::string hx(glm::uvec3 c) {
  return "(" + std::to_string(c.x) + ", " + std::to_string(c.y) + ", " + std::to_string(c.z) + ")";
}
inline std::string hx(const Ray& r) {
  return "ray org " + hx(r.org) + " dir " + hx(r.dir) + " tmin " + hx(r.tmin) + " tmax " + hx(r.tmax);
}
inline std::string hx(const Hit& h) {
  std::ostringstream os;
  os << "hit inst " << h.instance << " tri " << h.triangle << " t " << hx(h.t) << " u " << hx(h.u) << " v "
     << hx(h.v) << " flags " << h.flags;
  return os.str();
}

// `n` random triangles of edge ~size in the box [0, extent]^3, one mesh; `dynamic` more as a
// second, rotating and moving instance.
inline Scene random_scene(uint32_t n, float size, float extent, uint32_t seed, uint32_t dynamic = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(0.0f, extent), off(-size, size);
  Scene s;
  s.name = "random";
  auto make = [&](uint32_t count) {
    Mesh m;
    m.name = "tris";
    for (uint32_t i = 0; i < count; ++i) {
      const glm::vec3 c(pos(rng), pos(rng), pos(rng));
      for (int k = 0; k < 3; ++k) m.positions.push_back(c + glm::vec3(off(rng), off(rng), off(rng)));
      m.triangles.push_back({3 * i, 3 * i + 1, 3 * i + 2});
    }
    m.materials.assign(count, 0u);
    return m;
  };
  s.meshes.push_back(make(n));
  s.instances.push_back(Instance{.name = "static", .mesh = 0});
  if (dynamic) {
    s.meshes.push_back(make(dynamic));
    Instance d{.name = "dynamic", .mesh = 1, .dynamic = true};
    d.motion.axis = {0.3f, 1.0f, 0.2f};
    d.motion.pivot = glm::vec3(extent * 0.5f);
    d.motion.angular_speed = 0.7f;
    d.motion.path_points = {glm::vec3(0.0f), glm::vec3(0.1f * extent, 0.0f, 0.0f), glm::vec3(0.0f, 0.05f * extent, 0.1f * extent)};
    d.motion.path_period = 3.0f;
    s.instances.push_back(d);
  }
  s.finalize();
  return s;
}

struct RefHit {
  bool hit = false;
  double t = 0.0, u = 0.0, v = 0.0;
  uint32_t instance = shared::kNoInstance, triangle = 0;
};

// Double-precision Moller-Trumbore over every triangle of the grid's geometry buffer.
inline RefHit brute_force(const reference::GridData& g, const Ray& r) {
  RefHit best;
  const glm::dvec3 o(r.org), d(r.dir);
  for (uint32_t i = 0; i < g.instances.size(); ++i)
    for (uint32_t k = 0; k < g.instances[i].tri_count; ++k) {
      const shared::GridTriangle& t = g.triangles[g.instances[i].tri_offset + k];
      const glm::dvec3 v0(t.v0), e1 = glm::dvec3(t.v1) - v0, e2 = glm::dvec3(t.v2) - v0;
      const glm::dvec3 p = glm::cross(d, e2);
      const double det = glm::dot(e1, p);
      if (det == 0.0) continue;
      const double inv = 1.0 / det;
      const glm::dvec3 s = o - v0;
      const double u = glm::dot(s, p) * inv;
      if (u < 0.0 || u > 1.0) continue;
      const glm::dvec3 q = glm::cross(s, e1);
      const double v = glm::dot(d, q) * inv;
      if (v < 0.0 || u + v > 1.0) continue;
      const double tt = glm::dot(e2, q) * inv;
      if (!(tt > r.tmin && tt < r.tmax)) continue;
      if (!best.hit || tt < best.t) best = {true, tt, u, v, i, k};
    }
  return best;
}

inline Ray make_ray(glm::vec3 o, glm::vec3 d, float tmin = 0.0f, float tmax = INFINITY) {
  Ray r{};
  r.org = o;
  r.dir = d;
  r.tmin = tmin;
  r.tmax = tmax;
  r.launch_normal = glm::vec3(0.0f);
  r.launch_ref = shared::kNoRef;
  return r;
}

}  // namespace gridtest
