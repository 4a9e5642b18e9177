// tracer_contract.h: the Tracer contract (common/tracer.h) as a program using gridrt as a library
// meets it, checked on any tracer (the reference grid, Embree, the Vulkan port): what the command
// line refuses is refused, and a build that fails leaves no half-made tracer behind (an outside
// sweep of the library interface: each case here crashed, or answered misses without a word,
// before).
#pragma once

#include <catch2/catch.hpp>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "gridrt/common/tracer.h"
#include "tests/test_grid_util.h"

namespace gridtest {

using namespace gridrt;

// A finalized scene every build refuses: one triangle whose box is below the domain's 2^-40 floor
inline Scene refused_scene() {
  Scene s;
  s.name = "tiny";
  Mesh m;
  m.name = "speck";
  m.positions = {glm::vec3(0.0f), glm::vec3(1e-14f, 0.0f, 0.0f), glm::vec3(0.0f, 1e-14f, 0.0f)};
  m.triangles = {{0u, 1u, 2u}};
  m.materials = {0u};
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "speck", .mesh = 0});
  s.finalize();
  return s;
}

// Rays from outside the random scene's box towards its middle: most of them hit
inline std::vector<Ray> inward_rays(uint32_t n) {
  std::vector<Ray> rays;
  for (uint32_t i = 0; i < n; ++i) {
    const float a = 0.37f * float(i), b = 0.11f * float(i);
    const glm::vec3 o = glm::vec3(5.0f) + 30.0f * glm::vec3(std::cos(a) * std::cos(b), std::sin(b), std::sin(a) * std::cos(b));
    rays.push_back(make_ray(o, glm::vec3(5.0f) + glm::vec3(0.01f * float(i % 7)) - o));
  }
  return rays;
}

inline size_t hit_count(Tracer& t, const std::vector<Ray>& rays) {
  std::vector<Hit> hits(rays.size());
  t.trace(rays, hits);
  size_t n = 0;
  for (const Hit& h : hits) n += !is_miss(h);
  return n;
}

// Every check of the contract on one tracer, made by `make`
inline void check_contract(const std::function<std::unique_ptr<Tracer>()>& make) {
  const Scene good = random_scene(2000, 0.6f, 10.0f, 7, 20);
  const Scene bad = refused_scene();
  const std::vector<Ray> rays = inward_rays(256);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();

  // Before any build: trace and update refused
  {
    auto t = make();
    std::vector<Hit> hits(rays.size());
    REQUIRE_THROWS_AS(t->trace(rays, hits), Error);
    REQUIRE_THROWS_AS(t->update(0.5f), Error);
  }
  auto t = make();
  t->build(good, 0.0f);
  const size_t hits_good = hit_count(*t, rays);
  REQUIRE(hits_good > rays.size() / 4);

  // A time that is not finite: refused, and the grid is left as it was
  for (float time : {nan, inf, -inf}) {
    REQUIRE_THROWS_WITH(t->update(time), Catch::Contains("not finite"));
    REQUIRE(t->built());
    REQUIRE(hit_count(*t, rays) == hits_good);
    auto fresh = make();
    REQUIRE_THROWS_WITH(fresh->build(good, time), Catch::Contains("not finite"));
    REQUIRE_FALSE(fresh->built());
  }

  // A build that fails after a good one: unbuilt, so update and trace are refused, not a crash or
  // every ray a miss; a good build after it works again
  REQUIRE_THROWS_AS(t->build(bad, 0.0f), Error);
  REQUIRE_FALSE(t->built());
  std::vector<Hit> hits(rays.size());
  REQUIRE_THROWS_WITH(t->trace(rays, hits), Catch::Contains("before a build"));
  REQUIRE_THROWS_WITH(t->trace_any(rays, hits), Catch::Contains("before a build"));
  REQUIRE_THROWS_WITH(t->update(0.5f), Catch::Contains("before a build"));
  REQUIRE(t->dump().texels.empty());
  t->build(good, 0.0f);
  REQUIRE(hit_count(*t, rays) == hits_good);
  // A build refused by its checks after a good one: unbuilt too (the grid kept past it held the very
  // scene the caller had changed, and update crashed reading it)
  {
    Scene held = good;
    auto h = make();
    h->build(held, 0.0f);
    held.instances[0].mesh = 7;
    REQUIRE_THROWS_WITH(h->build(held, 0.0f), Catch::Contains("uses mesh 7"));
    REQUIRE_FALSE(h->built());
    REQUIRE_THROWS_WITH(h->update(0.5f), Catch::Contains("before a build"));
    REQUIRE_THROWS_WITH(h->build(good, nan), Catch::Contains("not finite"));
    REQUIRE_FALSE(h->built());
  }
  // and hits and rays of different counts
  std::vector<Hit> short_hits(rays.size() - 1);
  REQUIRE_THROWS_WITH(t->trace(rays, short_hits), Catch::Contains("must be as many"));

  // A scene made in code and never finalized, with an index out of range: refused by name
  Scene raw;
  raw.name = "raw";
  raw.materials.push_back(Material{.name = "m"});
  Mesh m;
  m.name = "broken";
  m.positions = {glm::vec3(0.0f), glm::vec3(1.0f, 0.0f, 0.0f), glm::vec3(0.0f, 1.0f, 0.0f)};
  m.triangles = {{0u, 1u, 100000000u}};
  m.materials = {0u};
  raw.meshes.push_back(m);
  raw.instances.push_back(Instance{.name = "i", .mesh = 0});
  REQUIRE_THROWS_WITH(make()->build(raw, 0.0f), Catch::Contains("uses vertex 100000000 of 3"));
  raw.meshes[0].triangles = {{0u, 1u, 2u}};
  raw.meshes[0].materials = {5u};
  REQUIRE_THROWS_WITH(make()->build(raw, 0.0f), Catch::Contains("material index 5 of 1"));
  raw.meshes[0].materials = {0u};
  raw.instances[0].mesh = 3;
  REQUIRE_THROWS_WITH(make()->build(raw, 0.0f), Catch::Contains("uses mesh 3 of 1"));
  // Static after dynamic (finalize orders them): the dynamic ids would be offset wrongly
  raw.instances = {Instance{.name = "d", .mesh = 0, .dynamic = true}, Instance{.name = "s", .mesh = 0}};
  REQUIRE_THROWS_WITH(make()->build(raw, 0.0f), Catch::Contains("static after a dynamic one"));
  // The same scene finalized builds
  raw.finalize();
  make()->build(raw, 0.0f);
}

}  // namespace gridtest
