// test_oracle.cpp: the Embree oracle against analytic truth.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/embree/embree_tracer.h"

using namespace gridrt;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Distance in units in the last place between two finite floats of the same sign.
int64_t ulps(float a, float b) {
  int32_t ia, ib;
  std::memcpy(&ia, &a, 4);
  std::memcpy(&ib, &b, 4);
  return std::abs(int64_t(ia) - int64_t(ib));
}
// Embree reports t = T * rcp(det) (an approximate reciprocal refined by one Newton step), not the
// correctly rounded quotient: exact values come back within a couple of ulps.
constexpr int64_t kTUlps = 2;
bool t_near(float t, float exact) { return std::isfinite(t) && ulps(t, exact) <= kTUlps; }

Ray make_ray(glm::vec3 org, glm::vec3 dir, float tmin = 0.0f, float tmax = kInf, uint32_t launch_ref = shared::kNoRef) {
  Ray r;
  r.org = org;
  r.dir = dir;
  r.tmin = tmin;
  r.tmax = tmax;
  r.launch_normal = glm::vec3(0.0f);
  r.launch_ref = launch_ref;
  return r;
}

// The square [x0, x1] x [y0, y1] at height z, facing +z, uv = (x, y) mapped onto [0, 1]^2.
Mesh quad_mesh(float x0, float x1, float y0, float y1, float z, uint32_t material = 0) {
  Mesh m;
  m.name = "quad";
  m.positions = {{x0, y0, z}, {x1, y0, z}, {x1, y1, z}, {x0, y1, z}};
  m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  m.materials = {material, material};
  return m;
}

// A UV sphere of radius r about the origin: nlat bands, nlon segments, poles welded (closed).
Mesh sphere_mesh(float r, unsigned nlat, unsigned nlon) {
  Mesh m;
  m.name = "sphere";
  const float pi = 3.14159265358979f;
  m.positions.push_back({0, r, 0});
  for (unsigned i = 1; i < nlat; ++i)
    for (unsigned j = 0; j < nlon; ++j) {
      const float th = pi * float(i) / float(nlat), ph = 2.0f * pi * float(j) / float(nlon);
      m.positions.push_back({r * std::sin(th) * std::cos(ph), r * std::cos(th), r * std::sin(th) * std::sin(ph)});
    }
  m.positions.push_back({0, -r, 0});
  const uint32_t bottom = uint32_t(m.positions.size() - 1);
  auto at = [&](unsigned i, unsigned j) { return 1u + (i - 1) * nlon + (j % nlon); };
  for (unsigned j = 0; j < nlon; ++j) {
    m.triangles.push_back({0, at(1, j + 1), at(1, j)});
    m.triangles.push_back({bottom, at(nlat - 1, j), at(nlat - 1, j + 1)});
  }
  for (unsigned i = 1; i + 1 < nlat; ++i)
    for (unsigned j = 0; j < nlon; ++j) {
      m.triangles.push_back({at(i, j), at(i, j + 1), at(i + 1, j + 1)});
      m.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i + 1, j)});
    }
  m.materials.assign(m.triangles.size(), 0u);
  return m;
}

Scene one_mesh_scene(Mesh m) {
  Scene s;
  s.name = "test";
  s.meshes.push_back(std::move(m));
  s.instances.push_back(Instance{.name = "i", .mesh = 0});
  s.finalize();
  return s;
}

// Two unit quads facing +z, "front" at z = 0 and "back" at z = -1.
Scene two_quads() {
  Scene s;
  s.name = "quads";
  s.meshes = {quad_mesh(-1, 1, -1, 1, 0), quad_mesh(-1, 1, -1, 1, -1)};
  s.instances = {Instance{.name = "front", .mesh = 0}, Instance{.name = "back", .mesh = 1}};
  s.finalize();
  return s;
}

}  // namespace

TEST_CASE("Oracle: axis-aligned quads, exact t, barycentrics, back faces", "[oracle]") {
  const Scene s = two_quads();
  EmbreeTracer tracer(2);
  tracer.build(s, 0.0f);
  const Hit h = tracer.trace_one(make_ray({0.25f, 0.5f, 5.0f}, {0, 0, -1}));
  CHECK(t_near(h.t, 5.0f));
  CHECK(h.instance == 0u);
  CHECK(h.flags == 0u);  // the quad faces +z, towards the ray's origin
  // p = (1-u-v) v0 + u v1 + v v2 of the hit triangle reproduces the hit point.
  const glm::uvec3 t = s.meshes[0].triangles[h.triangle];
  const auto& P = s.meshes[0].positions;
  const glm::vec3 p = (1.0f - h.u - h.v) * P[t[0]] + h.u * P[t[1]] + h.v * P[t[2]];
  CHECK(p.x == Approx(0.25f).margin(1e-6));
  CHECK(p.y == Approx(0.5f).margin(1e-6));
  // t is in units of |dir|.
  CHECK(t_near(tracer.trace_one(make_ray({0.25f, 0.5f, 5.0f}, {0, 0, -2})).t, 2.5f));
  // From below: the back quad first, seen from behind.
  const Hit b = tracer.trace_one(make_ray({0.25f, 0.5f, -5.0f}, {0, 0, 1}));
  CHECK(t_near(b.t, 4.0f));
  CHECK(b.instance == 1u);
  CHECK(b.flags == shared::kHitBackFace);
  // Outside the quads: a miss, as documented.
  const Hit m = tracer.trace_one(make_ray({2.0f, 0.0f, 5.0f}, {0, 0, -1}));
  CHECK(is_miss(m));
  CHECK(std::isinf(m.t));
  CHECK(m.flags == 0u);
}

TEST_CASE("Oracle: rays parallel to a quad miss - tmin and tmax are strict", "[oracle]") {
  const Scene s = two_quads();
  EmbreeTracer tracer(1);
  tracer.build(s, 0.0f);
  CHECK(is_miss(tracer.trace_one(make_ray({-3.0f, 0.1f, 0.0f}, {1, 0, 0}))));   // in the plane
  CHECK(is_miss(tracer.trace_one(make_ray({-3.0f, 0.1f, 0.5f}, {1, 0.2f, 0}))));  // above it
  const glm::vec3 o(0.1f, 0.2f, 5.0f), d(0, 0, -1);
  // Strict bounds on the reported t: t == tmax and t == tmin are outside.
  const float t5 = tracer.trace_one(make_ray(o, d)).t;
  REQUIRE(t_near(t5, 5.0f));
  CHECK(is_miss(tracer.trace_one(make_ray(o, d, 0.0f, t5))));
  CHECK(tracer.trace_one(make_ray(o, d, 0.0f, std::nextafter(t5, kInf))).t == t5);
  CHECK(t_near(tracer.trace_one(make_ray(o, d, t5)).t, 6.0f));  // the back quad
  CHECK(tracer.trace_one(make_ray(o, d, std::nextafter(t5, 0.0f))).t == t5);
  CHECK(tracer.trace_one(make_ray(o, d, 5.5f, 5.9f)).instance == shared::kNoInstance);
  CHECK(is_miss(tracer.trace_one(make_ray(o, d, 3.0f, 2.0f))));  // empty interval
  // negative tmin: outside the domain (shared::ray_domain), rejected like the grid rejects it
  CHECK((tracer.trace_one(make_ray(o, d, -1.0f)).flags & shared::kHitRejected) != 0);
}

TEST_CASE("Oracle: NaN, inf and zero-direction rays are rejected", "[oracle][badinput]") {
  const Scene s = one_mesh_scene(quad_mesh(-1, 1, -1, 1, 0));
  EmbreeTracer tracer(2);
  tracer.build(s, 0.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<Ray> rays = {
      make_ray({nan, 0, 5}, {0, 0, -1}), make_ray({0, 0, 5}, {0, nan, -1}), make_ray({kInf, 0, 5}, {0, 0, -1}),
      make_ray({0, 0, 5}, {0, 0, -kInf}), make_ray({0, 0, 5}, {0, 0, 0}), make_ray({0, 0, 5}, {0, 0, -1}, nan),
      make_ray({0, 0, 5}, {0, 0, -1}, 0.0f, nan)};
  rays.push_back(make_ray({0, 0, 5}, {0, 0, -1}));  // a good one among them
  std::vector<Hit> hits(rays.size());
  tracer.trace(rays, hits);
  for (size_t i = 0; i + 1 < rays.size(); ++i) {
    CAPTURE(i);
    CHECK(hits[i].flags == shared::kHitRejected);
    CHECK(is_miss(hits[i]));
  }
  CHECK(t_near(hits.back().t, 5.0f));
  CHECK(hits.back().flags == 0u);
}

TEST_CASE("Oracle: launch_ref excludes exactly the launch triangle", "[oracle]") {
  const Scene s = two_quads();
  EmbreeTracer tracer(1);
  tracer.build(s, 0.0f);
  const glm::vec3 o(0.5f, -0.5f, 5.0f), d(0, 0, -1);
  const Hit first = tracer.trace_one(make_ray(o, d));
  REQUIRE(first.instance == 0u);
  const uint32_t ref = (first.instance << 16) | first.triangle;
  const Hit skipped = tracer.trace_one(make_ray(o, d, 0.0f, kInf, ref));
  CHECK(skipped.instance == 1u);
  CHECK(t_near(skipped.t, 6.0f));
  // Another triangle of the same instance as launch_ref changes nothing.
  const Hit other = tracer.trace_one(make_ray(o, d, 0.0f, kInf, (0u << 16) | (1u - first.triangle)));
  CHECK(other.instance == 0u);
  CHECK(other.triangle == first.triangle);
  // A ray leaving the surface from a point on it, with tmin 0, does not hit its own triangle.
  const Hit bounce = tracer.trace_one(make_ray({0.5f, -0.5f, 0.0f}, {0.1f, 0.2f, 1.0f}, 0.0f, kInf, ref));
  CHECK(is_miss(bounce));
}

TEST_CASE("Oracle: alpha-masked quad in front of an opaque one", "[oracle]") {
  Scene s;
  s.name = "alpha";
  // 4 x 4 checkerboard: texel (x, y) opaque where (x + y) is even; row 0 is the top (v = 1).
  Texture tex;
  tex.width = tex.height = 4;
  tex.has_alpha = true;
  for (uint32_t y = 0; y < 4; ++y)
    for (uint32_t x = 0; x < 4; ++x) {
      const uint8_t a = (x + y) % 2 == 0 ? 255 : 0;
      tex.rgba.insert(tex.rgba.end(), {200, 100, 50, a});
    }
  s.textures.push_back(tex);
  s.materials = {Material{.name = "mask", .diffuse_texture = 0, .alpha_texture = 0}, Material{.name = "opaque"}};
  s.meshes = {quad_mesh(0, 1, 0, 1, 0, 0), quad_mesh(0, 1, 0, 1, -1, 1)};
  s.instances = {Instance{.name = "mask", .mesh = 0}, Instance{.name = "wall", .mesh = 1}};
  s.finalize();
  REQUIRE(s.has_alpha_masks());
  EmbreeTracer tracer(2);
  tracer.build(s, 0.0f);
  std::vector<Ray> rays;
  std::vector<bool> opaque;
  for (int j = 0; j < 16; ++j)
    for (int i = 0; i < 16; ++i) {
      const float u = (float(i) + 0.5f) / 16.0f, v = (float(j) + 0.5f) / 16.0f;
      rays.push_back(make_ray({u, v, 3.0f}, {0, 0, -1}));
      const int x = int(u * 4.0f), y = 3 - int(v * 4.0f);
      opaque.push_back((x + y) % 2 == 0);
    }
  std::vector<Hit> hits(rays.size());
  tracer.trace(rays, hits);
  for (size_t k = 0; k < rays.size(); ++k) {
    CAPTURE(k, rays[k].org.x, rays[k].org.y);
    CHECK(hits[k].instance == (opaque[k] ? 0u : 1u));
    CHECK(t_near(hits[k].t, opaque[k] ? 3.0f : 4.0f));
  }
}

TEST_CASE("Oracle: a tessellated sphere within its tessellation bound, watertight", "[oracle]") {
  const float r = 2.0f;
  const Scene s = one_mesh_scene(sphere_mesh(r, 24, 48));
  const Mesh& m = s.meshes[0];
  // Every point of a triangle with its corners on the sphere lies between the triangle's plane
  // distance from the centre and r; the bound is the smallest plane distance.
  double r_in = r;
  for (const glm::uvec3& t : m.triangles) {
    const glm::dvec3 a(m.positions[t[0]]), b(m.positions[t[1]]), c(m.positions[t[2]]);
    const glm::dvec3 n = glm::normalize(glm::cross(b - a, c - a));
    r_in = std::min(r_in, std::abs(glm::dot(n, a)));
  }
  REQUIRE(r_in > 0.99 * r);
  EmbreeTracer tracer;
  tracer.build(s, 0.0f);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  std::vector<Ray> rays;
  for (int k = 0; k < 2000; ++k) {
    glm::vec3 o(U(rng), U(rng), U(rng));
    o = glm::normalize(o) * 6.0f;
    const glm::vec3 target = glm::vec3(U(rng), U(rng), U(rng)) * float(r_in) * 0.57f;  // inside r_in
    rays.push_back(make_ray(o, target - o));
  }
  std::vector<Hit> hits(rays.size());
  tracer.trace(rays, hits);
  for (size_t k = 0; k < rays.size(); ++k) {
    REQUIRE_FALSE(is_miss(hits[k]));
    const glm::dvec3 o(rays[k].org), d(rays[k].dir);
    const double dist = glm::length(o + double(hits[k].t) * d);
    CHECK(dist >= r_in - 1e-4);
    CHECK(dist <= r + 1e-4);
    // The analytic sphere's entry point is no farther than the mesh's.
    const double b = glm::dot(o, d), a = glm::dot(d, d), c = glm::dot(o, o) - double(r) * r;
    const double t_sphere = (-b - std::sqrt(b * b - a * c)) / a;
    CHECK(hits[k].t >= t_sphere - 1e-5);
    CHECK(hits[k].flags == 0u);
  }
  // Watertight: rays aimed exactly at vertices and at edge midpoints, from outside and from the
  // centre, never miss.
  std::vector<Ray> edge_rays;
  for (const glm::uvec3& t : m.triangles)
    for (int e = 0; e < 3; ++e) {
      const glm::vec3 a = m.positions[t[e]], b = m.positions[t[(e + 1) % 3]];
      for (const glm::vec3 target : {a, 0.5f * (a + b)}) {
        edge_rays.push_back(make_ray({0.0f, 0.0f, 0.0f}, target));
        edge_rays.push_back(make_ray(3.0f * target + glm::vec3(0.01f, 0.02f, 0.0f), -2.0f * target));
      }
    }
  std::vector<Hit> edge_hits(edge_rays.size());
  tracer.trace(edge_rays, edge_hits);
  size_t misses = 0;
  for (const Hit& h : edge_hits) misses += is_miss(h) ? 1 : 0;
  CHECK(misses == 0);
}

TEST_CASE("Oracle: update moves a dynamic instance, static ones stay", "[oracle]") {
  Scene s;
  s.name = "moving";
  s.meshes = {quad_mesh(-1, 1, -1, 1, 0), quad_mesh(-1, 1, -1, 1, -2)};
  Instance mover{.name = "mover", .mesh = 0, .dynamic = true};
  mover.motion.path_points = {{0, 0, 0}, {5, 0, 0}};
  mover.motion.path_period = 2.0f;  // at t = 1 the quad is 5 units along x
  s.instances = {Instance{.name = "floor", .mesh = 1}, mover};
  s.finalize();
  REQUIRE(s.instances[1].dynamic);
  EmbreeTracer tracer(2);
  tracer.build(s, 0.0f);
  const Ray down = make_ray({0.0f, 0.0f, 5.0f}, {0, 0, -1});
  const Ray right = make_ray({5.0f, 0.0f, 5.0f}, {0, 0, -1});
  CHECK(tracer.trace_one(down).instance == 1u);  // the mover, at t 5
  CHECK(t_near(tracer.trace_one(down).t, 5.0f));
  CHECK(is_miss(tracer.trace_one(right)));
  tracer.update(1.0f);
  CHECK(tracer.trace_one(down).instance == 0u);  // the static floor below, at t 7
  CHECK(t_near(tracer.trace_one(down).t, 7.0f));
  CHECK(tracer.trace_one(right).instance == 1u);
  tracer.update(0.0f);
  CHECK(tracer.trace_one(down).instance == 1u);
}

TEST_CASE("Oracle: the Cornell box is closed, no primary or random ray escapes", "[oracle][scenes]") {
  const Scene s = make_builtin("cornell");
  EmbreeTracer tracer;
  tracer.build(s, 0.0f);
  std::vector<Ray> rays;
  for (uint32_t y = 0; y < 48; ++y)
    for (uint32_t x = 0; x < 64; ++x) rays.push_back(camera_ray(*s.camera, 64, 48, x, y));
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  for (int k = 0; k < 4000; ++k) rays.push_back(make_ray({2.78f, 2.0f, 1.0f}, {U(rng), U(rng), U(rng)}));
  std::vector<Hit> hits(rays.size());
  tracer.trace(rays, hits);
  size_t misses = 0;
  for (const Hit& h : hits) misses += is_miss(h) ? 1 : 0;
  CHECK(misses == 0);
}

TEST_CASE("Oracle: the atrium's foliage cuts rays, its teapots move", "[oracle][scenes]") {
  const Scene s = make_builtin("atrium");
  EmbreeTracer tracer;
  tracer.build(s, 0.0f);
  const uint32_t first_dynamic = s.static_instance_count();
  std::vector<Ray> rays;
  for (uint32_t y = 0; y < 60; ++y)
    for (uint32_t x = 0; x < 80; ++x) rays.push_back(camera_ray(*s.camera, 80, 60, x, y));
  std::vector<Hit> a(rays.size()), b(rays.size());
  tracer.trace(rays, a);
  tracer.update(2.0f);
  tracer.trace(rays, b);
  size_t dynamic_hits = 0, changed = 0;
  for (size_t k = 0; k < rays.size(); ++k) {
    dynamic_hits += !is_miss(a[k]) && a[k].instance >= first_dynamic;
    changed += a[k].instance != b[k].instance || a[k].t != b[k].t;
    // Static geometry not covered by a teapot at either time is hit identically.
    if (!is_miss(a[k]) && a[k].instance < first_dynamic && !is_miss(b[k]) && b[k].instance < first_dynamic)
      CHECK(a[k].t == b[k].t);
  }
  CHECK(dynamic_hits > 50);
  CHECK(changed > 50);
}

// Hidden: ./gridrt_tests "[.bench]" prints the oracle's throughput on the atrium and writes
// atrium.ppm (primary + glossy bounce, shaded) to the current folder.
#include <chrono>
#include <fstream>
#include "gridrt/common/gather.h"
#include "gridrt/common/shade.h"
TEST_CASE("Oracle throughput on the atrium", "[.bench]") {
  const Scene s = make_builtin("atrium");
  EmbreeTracer tracer;
  tracer.build(s, 1.0f);
  const uint32_t w = 640, h = 480;
  const auto t0 = std::chrono::steady_clock::now();
  const GatherBuffer g = make_gather(s, tracer, *s.camera, w, h, 1.0f);
  const auto t1 = std::chrono::steady_clock::now();
  const std::vector<Ray> rays = bounce_rays(s, g, 0);
  std::vector<Hit> hits(rays.size());
  const auto t2 = std::chrono::steady_clock::now();
  tracer.trace(rays, hits);
  const auto t3 = std::chrono::steady_clock::now();
  const std::vector<glm::vec3> img = shade(s, g, rays, hits);
  const double primary = std::chrono::duration<double>(t1 - t0).count();
  const double bounce = std::chrono::duration<double>(t3 - t2).count();
  size_t used = 0;
  for (const Ray& r : rays) used += !is_unused(r);
  WARN("triangles " << s.triangle_count() << ", primary " << w * h / primary / 1e6 << " Mrays/s (incl. gather), bounce "
                    << used << " glossy rays, " << double(used) / bounce / 1e6 << " Mrays/s");
  std::ofstream ppm("atrium.ppm", std::ios::binary);
  ppm << "P6\n" << w << " " << h << "\n255\n";
  for (const glm::vec3& c : img)
    for (int k = 0; k < 3; ++k) ppm.put(char(uint8_t(std::lround(std::sqrt(c[k]) * 255.0f))));
}

#include "tests/tracer_contract.h"

TEST_CASE("Library: Embree keeps the Tracer contract - failed builds, times, unfinalized scenes", "[unit][oracle]") {
  gridtest::check_contract([] { return std::make_unique<EmbreeTracer>(); });
}
