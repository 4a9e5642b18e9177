// test_grid_util.h: helpers of the grid tests: hex printing, random and analytic scenes, a
// double-precision brute-force closest hit.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <sstream>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/scene.h"
#include "gridrt/common/shared/bounce.h"
#include "gridrt/common/tracer.h"
#include "gridrt/reference/grid.h"

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

// Two small triangles at opposite corners of a long box [0, 10] x [0, 0.1] x [0, 0.1]: on a grid
// of hundreds of cells along x the middle cells lie farther than kSkipMaxDistance from both.
inline Scene far_apart_scene() {
  Scene s;
  s.name = "far apart";
  Mesh m;
  m.name = "two";
  m.positions = {{0.0f, 0.0f, 0.0f}, {0.01f, 0.0f, 0.0f}, {0.0f, 0.01f, 0.01f},
                 {10.0f, 0.1f, 0.1f}, {9.99f, 0.1f, 0.1f}, {10.0f, 0.09f, 0.09f}};
  m.triangles = {{0, 1, 2}, {3, 4, 5}};
  m.materials.assign(2, 0u);
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "static", .mesh = 0});
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

// A closed cone of 2n triangles: n around its apex and n around the centre of its base disk (two
// vertices of valence n: the case no uniform grid escapes, every triangle in the apex's cell). The
// base lies `height` below the apex (-z), a ring of `radius`.
inline Mesh fan_mesh(glm::vec3 apex, float radius, float height, uint32_t n, const char* name = "fan") {
  Mesh m;
  m.name = name;
  const glm::vec3 base = apex - glm::vec3(0.0f, 0.0f, height);
  m.positions = {apex, base};
  for (uint32_t i = 0; i < n; ++i) {
    const double a = 2.0 * 3.14159265358979 * double(i) / double(n);
    m.positions.push_back(base + glm::vec3(radius * float(std::cos(a)), radius * float(std::sin(a)), 0.0f));
  }
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t a = 2 + i, b = 2 + (i + 1) % n;
    m.triangles.push_back({0, a, b});
    m.triangles.push_back({1, b, a});
  }
  m.materials.assign(m.triangles.size(), 0u);
  return m;
}

// The closed box [lo, hi] seen from inside: 12 triangles.
inline Mesh box_mesh(glm::vec3 lo, glm::vec3 hi, const char* name = "room") {
  Mesh m;
  m.name = name;
  for (int k = 0; k < 8; ++k) m.positions.push_back({(k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z});
  const uint32_t quads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  for (const auto& q : quads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  m.materials.assign(m.triangles.size(), 0u);
  return m;
}

// The room [0, 8]^3 with a static fan (fan_mesh) of 2n triangles about (4.3, 4.3, 4.6) and, with
// `moving`, a second fan of 2 * moving triangles, dynamic, that moves along x from 2 cells away into
// the first one's cell and back (path period 4 s: there at t = 2).
inline Scene fan_scene(uint32_t n, uint32_t moving = 0) {
  Scene s;
  s.name = "fan";
  s.meshes.push_back(box_mesh(glm::vec3(0.0f), glm::vec3(8.0f)));
  s.meshes.push_back(fan_mesh({4.3f, 4.3f, 4.6f}, 0.45f, 0.5f, n));
  s.instances.push_back(Instance{.name = "room", .mesh = 0});
  s.instances.push_back(Instance{.name = "fan", .mesh = 1});
  if (moving) {
    s.meshes.push_back(fan_mesh({2.6f, 4.45f, 4.5f}, 0.3f, 0.4f, moving, "moving fan"));
    Instance d{.name = "moving fan", .mesh = 2, .dynamic = true};
    d.motion.path_points = {glm::vec3(0.0f), glm::vec3(2.0f, 0.0f, 0.0f)};
    d.motion.path_period = 4.0f;
    s.instances.push_back(d);
  }
  s.finalize();
  return s;
}

// A wall of 8 x 4 unit quads (64 triangles) in the plane z = 0, turning once a second about a
// skew axis through (0, 0, 0.125), and a small box on a path of period 16 s: the spill list's
// forecast samples the motions at 16 times over the longest period, t = 0, 1, ..., 15, and finds
// the wall at the same angle every time, where it crosses the fewest cells; half a turn later it
// crosses about 1.4 times as many (an outside tester's scene). Dynamic instances only, cell 0.25.
// `split`: each unit quad cut into split x split quads.
inline Scene turning_wall_scene(uint32_t split = 1) {
  Scene s;
  s.name = "turning wall";
  Mesh wall;
  wall.name = "wall";
  const uint32_t nx = 8 * split, ny = 4 * split;
  for (uint32_t y = 0; y <= ny; ++y)
    for (uint32_t x = 0; x <= nx; ++x) wall.positions.push_back({float(x) / float(split) - 4.0f, float(y) / float(split), 0.0f});
  for (uint32_t y = 0; y < ny; ++y)
    for (uint32_t x = 0; x < nx; ++x) {
      const uint32_t a = y * (nx + 1) + x;
      wall.triangles.push_back({a, a + 1, a + nx + 2});
      wall.triangles.push_back({a, a + nx + 2, a + nx + 1});
    }
  wall.materials.assign(wall.triangles.size(), 0u);
  s.meshes.push_back(std::move(wall));
  s.meshes.push_back(box_mesh(glm::vec3(-1.0f), glm::vec3(1.0f), "box"));
  Instance w{.name = "wall", .mesh = 0, .dynamic = true};
  w.transform = glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, -2.0f, 0.125f));
  w.motion.axis = glm::normalize(glm::vec3(0.57735f, 0.57735f, 1.57735f));
  w.motion.pivot = glm::vec3(0.0f, 0.0f, 0.125f);
  w.motion.angular_speed = 6.2831853f;
  s.instances.push_back(w);
  Instance b{.name = "slow", .mesh = 1, .dynamic = true};
  b.transform = glm::translate(glm::mat4(1.0f), glm::vec3(3.0f, 0.0f, 3.0f)) * glm::scale(glm::mat4(1.0f), glm::vec3(0.2f));
  b.motion.path_points = {glm::vec3(0.0f), glm::vec3(0.0f, 0.0f, -0.5f)};
  b.motion.path_period = 16.0f;
  s.instances.push_back(b);
  s.finalize();
  return s;
}

// A 16 x 16 checkerboard alpha mask (texel (x, y) opaque where x + y is even; row 0 at v = 1) on a
// quad 0.25 wide (texels 0.0156 units), instance 1, over a wall 2 units below it, instance 0, all at
// `offset`; the quad's corner at `offset` itself, uv (0, 0) there and (1, 1) at offset + (0.25,
// 0.25, 0). The camera looks down at the quad from 2 units above. A grid of 8 cells a side has
// cells 2 units wide: at 1e5 more than 64 ulps of the coordinates, so no origin is moved
// (docs/SPEC.md "Far origins") and the GPU frame takes the eye.
constexpr uint32_t kFarAlphaTexels = 16;
inline Scene far_alpha_scene(glm::dvec3 offset) {
  const auto at = [&](double x, double y, double z) { return glm::vec3(offset + glm::dvec3(x, y, z)); };
  Scene scene;
  scene.name = "far-alpha";
  Texture tex;
  tex.width = tex.height = kFarAlphaTexels;
  tex.has_alpha = true;
  for (uint32_t y = 0; y < kFarAlphaTexels; ++y)
    for (uint32_t x = 0; x < kFarAlphaTexels; ++x)
      tex.rgba.insert(tex.rgba.end(), {255, 255, 255, uint8_t((x + y) % 2 == 0 ? 255 : 0)});
  scene.textures.push_back(tex);
  scene.materials = {Material{.name = "wall"}, Material{.name = "mask", .alpha_texture = 0}};
  Mesh wall;
  wall.name = "wall";
  wall.positions = {at(-8, -8, -2), at(8, -8, -2), at(8, 8, -2), at(-8, 8, -2)};
  wall.triangles = {{0, 1, 2}, {0, 2, 3}};
  wall.materials = {0u, 0u};
  Mesh leaf;
  leaf.name = "leaf";
  leaf.positions = {at(0, 0, 0), at(0.25, 0, 0), at(0.25, 0.25, 0), at(0, 0.25, 0)};
  leaf.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  leaf.triangles = {{0, 1, 2}, {0, 2, 3}};
  leaf.materials = {1u, 1u};
  scene.meshes = {wall, leaf};
  scene.instances = {Instance{.name = "wall", .mesh = 0}, Instance{.name = "leaf", .mesh = 1}};
  scene.camera = Camera{.eye = at(0.125, 0.125, 2.0), .target = at(0.125, 0.125, 0.0), .up = {0, 1, 0}, .vfov_degrees = 9.0f};
  scene.finalize();
  return scene;
}

// The instance a ray meets in far_alpha_scene: its exact meeting with the quad's plane (double
// precision, from the float ray and the float quad) on an opaque texel gives the quad (1), on a
// cut one or off the quad the wall (0); -1 where the meeting lies within 1 % of a texel of a
// texel's edge, or the ray does not go down.
inline int far_alpha_truth(const Scene& scene, const Ray& r) {
  const glm::dvec3 lo(scene.meshes[1].positions[0]), hi(scene.meshes[1].positions[2]);
  const glm::dvec3 od(r.org), dd(r.dir);
  if (!(dd.z < 0.0)) return -1;
  const double t = (lo.z - od.z) / dd.z;
  const double u = (od.x + t * dd.x - lo.x) / (hi.x - lo.x), v = (od.y + t * dd.y - lo.y) / (hi.y - lo.y);
  const double xs = u * kFarAlphaTexels, ys = (1.0 - v) * kFarAlphaTexels;
  const auto near_edge = [](double s) { return std::abs(s - std::round(s)) < 0.01; };
  if (near_edge(xs) || near_edge(ys)) return -1;
  if (!(u > 0.0 && u < 1.0 && v > 0.0 && v < 1.0)) return 0;
  return (int(xs) + int(ys)) % 2 == 0 ? 1 : 0;
}

// The image layout's case of the same: a static slab of 6 large parallel quads in the cell layer
// z in [0, 0.25) (every cell of it saturated at capacity 4: the list's static entries), and a
// wall of 8 x 4 unit quads parallel to it on a path from z = 1.125 (empty cells, a few references
// each: nothing spills) into the slab's layer at t = 1 (every reference spills), period 2 s.
inline Scene wall_into_slab_scene() {
  Scene s = turning_wall_scene();
  s.name = "wall into slab";
  Mesh slab;
  slab.name = "slab";
  for (uint32_t k = 0; k < 6; ++k) {
    const float z = 0.03f + 0.03f * float(k);
    const uint32_t b = uint32_t(slab.positions.size());
    for (int q = 0; q < 4; ++q) slab.positions.push_back({(q & 1) ? 4.37f : -4.41f, (q & 2) ? 2.43f : -2.39f, z});
    slab.triangles.push_back({b, b + 1, b + 3});
    slab.triangles.push_back({b, b + 3, b + 2});
  }
  slab.materials.assign(slab.triangles.size(), 0u);
  s.meshes.push_back(std::move(slab));
  s.instances.clear();
  s.instances.push_back(Instance{.name = "slab", .mesh = 2});
  Instance w{.name = "wall", .mesh = 0, .dynamic = true};
  w.transform = glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, -2.0f, 0.125f));
  w.motion.path_points = {glm::vec3(0.0f, 0.0f, 1.0f), glm::vec3(0.0f)};
  w.motion.path_period = 2.0f;
  s.instances.push_back(w);
  s.finalize();
  return s;
}

// The spill list's growth tests' case for a layout (tests/test_spill.cpp, tests/test_vulkan_spill.cpp):
// the compact layout spills every dynamic reference, and the turning wall outgrows the forecast;
// the image layout spills only from full cells (the slab's, four slots a cell), its static entries
// first (a grown list keeps them), and the wall moving into the slab outgrows it (the forecast
// sampling t = 0 alone: its 16 samples over the period would include t = 1). `peak`: the time of
// the most references spilled.
struct SpillGrowthCase {
  Scene scene;
  reference::GridOptions options;
  float peak = 0.0f;
};
inline SpillGrowthCase spill_growth_case(reference::GridOptions::Layout layout) {
  const bool compact = layout == reference::GridOptions::Layout::compact;
  SpillGrowthCase c{compact ? turning_wall_scene() : wall_into_slab_scene(), {}, compact ? 0.5f : 1.0f};
  c.options.traversal = reference::Traversal::exact;
  c.options.layout = layout;
  c.options.cell_size = 0.25f;
  c.options.threads = 2;
  if (!compact) c.options.capacity = 4, c.options.capacity_time_samples = 1;
  return c;
}

// Rays at the fans: from random points of the room towards random points of random fan triangles
// (of the grid's geometry buffer, instances >= 1), and random rays through the middle of the room.
inline std::vector<Ray> fan_rays(const reference::GridData& g, uint32_t count, uint32_t seed);

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

// Rays over the grid's box: random ones from inside and outside (a third with a finite tmax),
// axis-parallel ones, and rays from lattice points along lattice diagonals (ties between the
// axes' crossings). The skipping and covered-cell tests walk them.
inline std::vector<Ray> walk_rays(const shared::GridParams& g, uint32_t seed) {
  std::vector<Ray> rays;
  std::mt19937 rng(seed);
  const glm::vec3 lo = g.origin, ext = g.upper - g.origin;
  std::uniform_real_distribution<float> u(-0.2f, 1.2f), d(-1.0f, 1.0f);
  for (uint32_t i = 0; i < 3000; ++i) {
    glm::vec3 dir(d(rng), d(rng), d(rng));
    if (i % 7 == 0) dir[i % 3] = 0.0f;
    if (i % 11 == 0) dir = glm::vec3(0.0f), dir[(i / 11) % 3] = d(rng) < 0.0f ? -1.0f : 1.0f;
    if (glm::dot(dir, dir) < 1e-6f) dir = {0.0f, 0.0f, 1.0f};
    const glm::vec3 o = lo + ext * glm::vec3(u(rng), u(rng), u(rng));
    rays.push_back(make_ray(o, dir, 0.0f, (i % 3) ? INFINITY : 0.3f * glm::length(ext)));
  }
  std::uniform_int_distribution<uint32_t> cx(0, g.cells.x), cy(0, g.cells.y), cz(0, g.cells.z), s(0, 7);
  for (uint32_t i = 0; i < 1000; ++i) {
    const glm::vec3 o = g.origin + g.cell_size * glm::vec3(float(cx(rng)), float(cy(rng)), float(cz(rng)));
    const uint32_t k = s(rng);
    const glm::vec3 dir((k & 1) ? -1.0f : 1.0f, (k & 2) ? -1.0f : 1.0f, (k & 4) ? -2.0f : (i % 2 ? 1.0f : 0.0f));
    rays.push_back(make_ray(o, dir));
  }
  return rays;
}

inline std::vector<Ray> fan_rays(const reference::GridData& g, uint32_t count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(0.3f, 7.7f), unit(0.0f, 1.0f);
  std::vector<Ray> rays;
  const uint32_t first = g.instances.size() > 1 ? g.instances[1].tri_offset : 0u;
  const uint32_t tris = uint32_t(g.triangles.size()) - first;
  for (uint32_t i = 0; i < count; ++i) {
    const glm::vec3 o(pos(rng), pos(rng), pos(rng));
    glm::vec3 target(pos(rng), pos(rng), pos(rng));
    if (i % 4 != 3 && tris > 0) {
      const shared::GridTriangle& t = g.triangles[first + std::uniform_int_distribution<uint32_t>(0, tris - 1)(rng)];
      float a = unit(rng), b = unit(rng);
      if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
      target = t.v0 + a * (t.v1 - t.v0) + b * (t.v2 - t.v0);
    }
    const glm::vec3 d = target - o;
    rays.push_back(make_ray(o, glm::dot(d, d) > 1e-6f ? d : glm::vec3(0.0f, 0.0f, 1.0f)));
  }
  return rays;
}

// Rays from random points of the box [0, extent]^3, three in four toward a point of a random
// triangle of any instance (the compact layout's tests, CPU and Vulkan).
inline std::vector<Ray> box_rays(const reference::GridData& g, uint32_t count, float extent, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(0.0f, extent), unit(0.0f, 1.0f);
  std::vector<Ray> rays;
  for (uint32_t i = 0; i < count; ++i) {
    const glm::vec3 o(pos(rng), pos(rng), pos(rng));
    glm::vec3 target(pos(rng), pos(rng), pos(rng));
    if (i % 4 != 3) {
      const shared::GridTriangle& t = g.triangles[std::uniform_int_distribution<size_t>(0, g.triangles.size() - 1)(rng)];
      float a = unit(rng), b = unit(rng);
      if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
      target = t.v0 + a * (t.v1 - t.v0) + b * (t.v2 - t.v0);
    }
    const glm::vec3 d = target - o;
    rays.push_back(make_ray(o, glm::dot(d, d) > 1e-6f ? d : glm::vec3(0.0f, 0.0f, 1.0f)));
  }
  return rays;
}

// Rays leaving random triangles of the geometry buffer (origin on the triangle, launch_ref and its
// normal set) toward random points, half of them as segments (tmax 1, a point light), the rest
// unbounded (a directional light); plus random rays through the box.
inline std::vector<Ray> leaving_rays(const reference::GridData& g, uint32_t count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f), d(-1.0f, 1.0f);
  const glm::vec3 lo = g.params.origin, ext = g.params.upper - g.params.origin;
  std::vector<Ray> rays;
  for (uint32_t i = 0; i < count; ++i) {
    const glm::vec3 target = lo + ext * glm::vec3(unit(rng), unit(rng), unit(rng));
    if (i % 5 == 4) {
      rays.push_back(make_ray(lo + ext * glm::vec3(unit(rng), unit(rng), unit(rng)),
                                        glm::vec3(d(rng), d(rng), d(rng)) + glm::vec3(1e-3f)));
      continue;
    }
    // A triangle of some instance, through its record in the instance table
    const uint32_t inst = std::uniform_int_distribution<uint32_t>(0, uint32_t(g.instances.size()) - 1)(rng);
    const shared::GridInstance& in = g.instances[inst];
    if (in.tri_count == 0) continue;
    const uint32_t tri = std::uniform_int_distribution<uint32_t>(0, in.tri_count - 1)(rng);
    const shared::GridTriangle& t = g.triangles[in.tri_offset + tri];
    float a = unit(rng), b = unit(rng);
    if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
    const glm::vec3 o = t.v0 + a * (t.v1 - t.v0) + b * (t.v2 - t.v0);
    glm::vec3 n = glm::cross(t.v1 - t.v0, t.v2 - t.v0);
    if (glm::dot(n, n) > 0.0f) n = glm::normalize(n);
    const glm::vec3 dir = target - o;
    if (!(glm::dot(dir, dir) > 1e-6f)) continue;
    Ray r = make_ray(o, (i % 2) ? dir : glm::normalize(dir), 0.0f, (i % 2) ? 1.0f : INFINITY);
    r.launch_ref = (inst << 16) | tri;
    r.launch_normal = n;
    rays.push_back(r);
  }
  return rays;
}

// A sheet every interior pixel's camera ray passes through a vertex of, exactly: for a w x w
// image, the vertex of pixel (x, y) is 4 x camera_direction(x, y) (a power of two: the ray's
// point at t = 4 in bits), the grid of vertices cut into two triangles a quad, diagonals
// alternating; a backdrop at 16 behind it (material 1). Every ray through a vertex meets its six
// triangles exactly at their shared corner: a test that is not watertight lets some pass, to the
// backdrop. An outside sweep's scene (Moller-Trumbore's gather showed the backdrop at 85 of 1,024
// pixels).
inline Scene pixel_vertex_sheet(uint32_t w) {
  Scene s;
  s.name = "pixel-vertex-sheet";
  s.materials = {Material{.name = "sheet", .diffuse = {0.8f, 0.1f, 0.1f}},
                 Material{.name = "backdrop", .diffuse = {0.1f, 0.1f, 0.8f}}};
  s.camera = Camera{.eye = {0, 0, 0}, .target = {0, 0, -1}, .up = {0, 1, 0}, .vfov_degrees = 90.0f};
  const shared::CameraParams c = camera_params(*s.camera, w, w);
  Mesh m;
  m.name = "sheet";
  for (uint32_t y = 0; y < w; ++y)
    for (uint32_t x = 0; x < w; ++x) m.positions.push_back(4.0f * shared::camera_direction(c, x, y));
  for (uint32_t y = 0; y + 1 < w; ++y)
    for (uint32_t x = 0; x + 1 < w; ++x) {
      const uint32_t a = y * w + x, b = a + 1, cc = a + w, d = cc + 1;
      if ((x + y) % 2) {
        m.triangles.push_back({a, cc, b});
        m.triangles.push_back({b, cc, d});
      } else {
        m.triangles.push_back({a, cc, d});
        m.triangles.push_back({a, d, b});
      }
    }
  m.materials.assign(m.triangles.size(), 0u);
  const uint32_t k = uint32_t(m.positions.size());
  m.positions.insert(m.positions.end(), {{-40, -40, -16}, {40, -40, -16}, {40, 40, -16}, {-40, 40, -16}});
  m.triangles.push_back({k, k + 1, k + 2});
  m.triangles.push_back({k, k + 2, k + 3});
  m.materials.push_back(1u);
  m.materials.push_back(1u);
  s.meshes = {m};
  s.instances = {Instance{.name = "sheet", .mesh = 0}};
  s.lights.push_back(Light{.position = {0.3f, 0.5f, 1.0f}, .intensity = 1.0f, .directional = true});
  s.finalize();
  return s;
}

// The interior pixels (not on the image's border) of a w x w gather of pixel_vertex_sheet whose
// ray does not stop on the sheet (material 0): the backdrop or nothing.
inline size_t sheet_pixels_missed(const GatherBuffer& g, uint32_t w) {
  size_t missed = 0;
  for (uint32_t y = 1; y + 1 < w; ++y)
    for (uint32_t x = 1; x + 1 < w; ++x) {
      const size_t p = size_t(y) * w + x;
      missed += !g.valid[p] || g.material[p] != 0u;
    }
  return missed;
}

}  // namespace gridtest
