// test_gather.cpp: gather buffer, bounce rays and shading.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/shade.h"

using namespace gridrt;

namespace {

// A floor quad (y = 0, glossiness `gloss`) and a red wall behind it (z = -3), camera above.
Scene mirror_scene(float gloss) {
  Scene s;
  s.name = "mirror";
  s.materials = {Material{.name = "floor", .diffuse = {0.5f, 0.5f, 0.5f}, .glossiness = gloss},
                 Material{.name = "red", .diffuse = {1.0f, 0.0f, 0.0f}}};
  Mesh floor;
  floor.name = "floor";
  floor.positions = {{-20, 0, 3}, {20, 0, 3}, {20, 0, -3}, {-20, 0, -3}};
  floor.triangles = {{0, 1, 2}, {0, 2, 3}};
  floor.materials = {0, 0};
  Mesh wall;
  wall.name = "wall";
  wall.positions = {{-30, -1, -3}, {30, -1, -3}, {30, 30, -3}, {-30, 30, -3}};
  wall.triangles = {{0, 1, 2}, {0, 2, 3}};
  wall.materials = {1, 1};
  s.meshes = {floor, wall};
  s.instances = {Instance{.name = "floor", .mesh = 0}, Instance{.name = "wall", .mesh = 1}};
  s.camera = Camera{.eye = {0, 2, 4}, .target = {0, 0, 0}, .vfov_degrees = 50.0f};
  s.lights.push_back(Light{.position = {0, 1, 1}, .intensity = 1.0f, .directional = true});
  s.finalize();
  return s;
}

}  // namespace

TEST_CASE("Gather: positions on the surface, normals facing the viewer, launch refs", "[unit][oracle]") {
  const Scene s = mirror_scene(0.5f);
  EmbreeTracer tracer(2);
  tracer.build(s, 0.0f);
  const GatherBuffer g = make_gather(s, tracer, *s.camera, 32, 24);
  REQUIRE(g.size() == 32u * 24u);
  size_t floor = 0;
  for (size_t p = 0; p < g.size(); ++p) {
    REQUIRE(g.valid[p]);  // the wall fills the background
    CHECK(glm::dot(g.normal[p], g.incident[p]) < 0.0f);
    CHECK(std::abs(glm::length(g.normal[p]) - 1.0f) < 1e-6f);
    CHECK(g.launch_ref[p] == ((g.hit[p].instance << 16) | g.hit[p].triangle));
    if (g.hit[p].instance == 0) {
      ++floor;
      CHECK(std::abs(g.position[p].y) < 1e-5f);
      CHECK(g.normal[p] == glm::vec3(0, 1, 0));
      CHECK(g.material[p] == 0u);
    } else {
      CHECK(std::abs(g.position[p].z + 3.0f) < 1e-5f);
      CHECK(g.material[p] == 1u);
    }
  }
  CHECK(floor > 100);
}

TEST_CASE("Gather: from a camera far away the positions still lie on the surface", "[unit][oracle]") {
  // eye + t * dir rounds at the eye's distance: a camera 4,000 units away put the position about
  // 1e-4 off a unit sphere, and its shadow rays met the neighbouring triangles (an outside sweep).
  // The point at the hit's weights rounds at the surface's own scale.
  Scene s = mirror_scene(0.5f);
  for (const float d : {1.0e3f, 4.0e3f, 4.0e5f}) {
    s.camera = Camera{.eye = {0.0f, 0.6f * d, 0.8f * d}, .target = {0, 0, 0}, .vfov_degrees = 2000.0f / d};
    EmbreeTracer tracer(2);
    tracer.build(s, 0.0f);
    const GatherBuffer g = make_gather(s, tracer, *s.camera, 32, 24);
    size_t floor = 0;
    for (size_t p = 0; p < g.size(); ++p) {
      if (!g.valid[p] || g.hit[p].instance != 0) continue;
      ++floor;
      INFO("camera " << d << " away, pixel " << p << ": y = " << g.position[p].y);
      CHECK(g.position[p].y == 0.0f);  // the floor's vertices have y = 0 exactly
    }
    CHECK(floor > 40);
  }
}

TEST_CASE("Bounce rays: deterministic, normalized, in the hemisphere, mirror at glossiness 1", "[unit][oracle]") {
  for (float gloss : {1.0f, 0.6f, 0.1f}) {
    CAPTURE(gloss);
    const Scene s = mirror_scene(gloss);
    EmbreeTracer tracer(2);
    tracer.build(s, 0.0f);
    const GatherBuffer g = make_gather(s, tracer, *s.camera, 40, 30);
    const std::vector<Ray> a = bounce_rays(s, g, 7), b = bounce_rays(s, g, 7), c = bounce_rays(s, g, 8);
    REQUIRE(a.size() == g.size());
    CHECK(std::memcmp(a.data(), b.data(), a.size() * sizeof(Ray)) == 0);
    size_t used = 0, differs = 0;
    for (size_t p = 0; p < a.size(); ++p) {
      const bool glossy = g.valid[p] && g.material[p] == 0u;
      CHECK(is_unused(a[p]) == !glossy);
      if (!glossy) {
        CHECK(a[p].launch_ref == shared::kNoRef);
        continue;
      }
      ++used;
      CHECK(std::abs(glm::length(a[p].dir) - 1.0f) < 1e-6f);
      CHECK(glm::dot(a[p].dir, g.normal[p]) > 0.0f);
      CHECK(a[p].org == g.position[p]);
      CHECK(a[p].launch_ref == g.launch_ref[p]);
      CHECK(a[p].launch_normal == g.normal[p]);
      CHECK(a[p].tmin == 0.0f);
      CHECK(std::isinf(a[p].tmax));
      const glm::vec3 mirror = glm::normalize(glm::reflect(g.incident[p], g.normal[p]));
      if (gloss == 1.0f) {
        CHECK(glm::length(a[p].dir - mirror) < 1e-6f);
        CHECK(a[p].dir == c[p].dir);  // no randomness at all
      } else {
        // Within the cone of half-angle (1 - g) pi / 2 of the mirror direction (before folding,
        // which only happens near grazing angles, not on this floor).
        CHECK(glm::dot(a[p].dir, mirror) >= std::cos((1.0f - gloss) * 1.5707964f) - 1e-5f);
        differs += a[p].dir != c[p].dir;
      }
    }
    CHECK(used > 300);
    if (gloss < 1.0f) CHECK(differs > used * 9 / 10);  // another frame, other directions
  }
}

TEST_CASE("Shade: a mirror floor shows the red wall - deterministic, in [0, 1]", "[unit][oracle]") {
  const Scene s = mirror_scene(1.0f);
  EmbreeTracer tracer(2);
  tracer.build(s, 0.0f);
  const GatherBuffer g = make_gather(s, tracer, *s.camera, 40, 30);
  const std::vector<Ray> rays = bounce_rays(s, g, 0);
  std::vector<Hit> hits(rays.size());
  tracer.trace(rays, hits);
  const std::vector<glm::vec3> img = shade(s, g, rays, hits);
  const std::vector<glm::vec3> again = shade(s, g, rays, hits);
  CHECK(std::memcmp(img.data(), again.data(), img.size() * sizeof(glm::vec3)) == 0);
  size_t red_reflections = 0;
  for (size_t p = 0; p < img.size(); ++p) {
    for (int k = 0; k < 3; ++k) CHECK((img[p][k] >= 0.0f && img[p][k] <= 1.0f));
    if (!is_unused(rays[p])) {
      // The launch triangle is never its own bounce hit.
      CHECK((hits[p].instance != 0u || hits[p].t > 0.0f));
      if (!is_miss(hits[p]) && hits[p].instance == 1u) {
        ++red_reflections;
        CHECK(img[p].r > 0.0f);
        CHECK(img[p].g == 0.0f);
      }
    }
  }
  CHECK(red_reflections > 50);
  // Without bounce hits, glossy pixels show their own (grey) albedo only.
  const std::vector<glm::vec3> plain = shade(s, g, {}, {});
  for (size_t p = 0; p < img.size(); ++p)
    if (g.valid[p] && g.material[p] == 0u) CHECK(plain[p].r == plain[p].g);
}

TEST_CASE("The atrium renders: every pixel shaded, the bounce sees the scene", "[oracle][scenes]") {
  const Scene s = make_builtin("atrium");
  EmbreeTracer tracer;
  tracer.build(s, 0.5f);
  const GatherBuffer g = make_gather(s, tracer, *s.camera, 64, 48, 0.5f);
  const std::vector<Ray> rays = bounce_rays(s, g, 1);
  std::vector<Hit> hits(rays.size());
  tracer.trace(rays, hits);
  const std::vector<glm::vec3> img = shade(s, g, rays, hits);
  size_t valid = 0, bounced = 0;
  for (size_t p = 0; p < g.size(); ++p) {
    valid += g.valid[p];
    bounced += !is_unused(rays[p]) && !is_miss(hits[p]);
  }
  CHECK(valid > g.size() / 2);
  CHECK(bounced > 100);
}
