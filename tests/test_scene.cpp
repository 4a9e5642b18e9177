#include <catch2/catch.hpp>

#include "gridrt/common/camera.h"
#include "gridrt/common/scene.h"
#include "gridrt/plan/plan.h"
#include "gridrt/common/shared/grid.h"

#include <algorithm>
#include <cmath>

using namespace gridrt;
namespace sh = gridrt::shared;

namespace {
Mesh strip(uint32_t triangles) {
  Mesh m;
  m.name = "strip";
  for (uint32_t i = 0; i <= triangles + 1; ++i) m.positions.push_back({float(i), float(i % 2), 0.0f});
  for (uint32_t t = 0; t < triangles; ++t) m.triangles.push_back({t, t + 1, t + 2});
  m.materials.assign(triangles, 0u);
  return m;
}

// A scene of one triangle (a, b, c), one instance, no camera.
Scene one_triangle(const std::string& name, glm::vec3 a, glm::vec3 b, glm::vec3 c) {
  Scene s;
  s.name = name;
  Mesh m;
  m.positions = {a, b, c};
  m.triangles = {{0, 1, 2}};
  m.materials = {0};
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "a", .mesh = 0});
  return s;
}
}  // namespace

TEST_CASE("A mesh over 65,536 triangles is split into instances of at most 65,536", "[unit][scene]") {
  Scene s;
  s.name = "big";
  s.meshes.push_back(strip(65536 * 2 + 5));
  s.instances.push_back(Instance{.name = "a", .mesh = 0});
  s.instances.push_back(Instance{.name = "b", .mesh = 0, .dynamic = true});
  s.finalize();
  REQUIRE(s.meshes.size() == 3);
  REQUIRE(s.instances.size() == 6);
  CHECK(s.meshes[0].triangle_count() == 65536);
  CHECK(s.meshes[1].triangle_count() == 65536);
  CHECK(s.meshes[2].triangle_count() == 5);
  CHECK(s.triangle_count() == 2ull * (65536 * 2 + 5));
  // Static instances come first, dynamic after.
  CHECK(s.static_instance_count() == 3);
  for (size_t i = 0; i < 3; ++i) CHECK_FALSE(s.instances[i].dynamic);
  for (size_t i = 3; i < 6; ++i) CHECK(s.instances[i].dynamic);
  // The pieces cover the original triangles in order, vertex for vertex.
  const Mesh orig = strip(65536 * 2 + 5);
  const Mesh& p2 = s.meshes[2];
  for (uint32_t t = 0; t < 5; ++t)
    for (int k = 0; k < 3; ++k)
      CHECK(p2.positions[p2.triangles[t][k]] == orig.positions[orig.triangles[65536 * 2 + t][k]]);
}

TEST_CASE("A mesh of exactly 65,536 triangles is not split", "[unit][scene]") {
  Scene s;
  s.meshes.push_back(strip(65536));
  s.instances.push_back(Instance{.mesh = 0});
  s.finalize();
  CHECK(s.meshes.size() == 1);
}

TEST_CASE("More than 65,535 instances is a clear error", "[unit][scene]") {
  Scene s;
  s.meshes.push_back(strip(1));
  for (uint32_t i = 0; i < 65535; ++i) s.instances.push_back(Instance{.mesh = 0});
  Scene ok = s;
  REQUIRE_NOTHROW(ok.finalize());
  s.instances.push_back(Instance{.mesh = 0});
  REQUIRE_THROWS_WITH(s.finalize(), Catch::Contains("65,535"));
}

TEST_CASE("Non-finite coordinates and empty scenes are rejected", "[unit][scene][badinput]") {
  Scene empty;
  REQUIRE_THROWS_WITH(empty.finalize(), Catch::Contains("empty"));
  Scene nan;
  nan.meshes.push_back(strip(2));
  nan.meshes[0].positions[1].y = std::numeric_limits<float>::quiet_NaN();
  nan.instances.push_back(Instance{.mesh = 0});
  REQUIRE_THROWS_WITH(nan.finalize(), Catch::Contains("non-finite"));
  Scene inf;
  inf.meshes.push_back(strip(2));
  inf.instances.push_back(Instance{.mesh = 0});
  inf.instances[0].transform[3][0] = std::numeric_limits<float>::infinity();
  REQUIRE_THROWS_WITH(inf.finalize(), Catch::Contains("non-finite"));
}

TEST_CASE("An instance whose transform is not affine is refused when the scene loads", "[unit][scene][badinput]") {
  // A .gridscene's last row was ignored (an outside sweep): the transform the file names is not
  // the one the grid would build with. Every source ends in finalize, which refuses it.
  for (const int k : {0, 1, 2, 3}) {
    Scene s;
    s.meshes.push_back(strip(2));
    s.instances.push_back(Instance{.name = "skewed", .mesh = 0});
    s.instances[0].transform[k][3] = k == 3 ? 2.0f : 0.5f;  // column-major: [k][3] is the last row
    INFO("the last row's element " << k);
    REQUIRE_THROWS_WITH(s.finalize(), Catch::Contains("'skewed'") && Catch::Contains("not affine"));
  }
  Scene ok;
  ok.meshes.push_back(strip(2));
  ok.instances.push_back(Instance{.name = "moved", .mesh = 0});
  ok.instances[0].transform[3] = glm::vec4(5.0f, -2.0f, 1.0f, 1.0f);  // a translation stays affine
  REQUIRE_NOTHROW(ok.finalize());
}

TEST_CASE("The camera framed for a scene without one is usable at any scale and distance from the origin", "[unit][scene][badinput]") {
  // A single triangle at subnormal size, tiny beside its distance from the origin, and huge: the
  // framed camera must give a finite eye distinct from the target and a resolvable view vector.
  for (const float scale : {1e-40f, 1e-30f, 1.0f, 1e18f})
    for (const float offset : {0.0f, 1e6f, -3e7f}) {
      INFO("scale " << scale << ", offset " << offset);
      Scene s = one_triangle("speck", {offset, offset, offset}, {offset + scale, offset, offset},
                             {offset, offset + scale, offset});
      const glm::vec3 e = s.bounds(0.0f).extent();
      if (std::max({e.x, e.y, e.z}) <= 0.0f) {
        CHECK_THROWS_WITH(s.finalize(), Catch::Contains("no extent"));  // the offset swallowed the size
        continue;
      }
      REQUIRE_NOTHROW(s.finalize());
      const Camera c = s.frame_camera();
      CHECK(c.eye != c.target);
      const CameraFrame f = camera_frame(c);
      CHECK(std::isfinite(glm::length(f.forward)));
      CHECK(std::abs(glm::length(f.forward) - 1.0f) < 1e-5f);
    }
}

TEST_CASE("A camera whose eye lies outside the ray domain is refused when the scene loads", "[unit][scene][badinput]") {
  Scene s;
  s.name = "far-eye";
  s.meshes.push_back(strip(2));
  s.instances.push_back(Instance{.name = "a", .mesh = 0});
  s.camera = Camera{.eye = {3e18f, 1e17f, 2e17f}, .target = {0, 0, 0}, .up = {0, 1, 0}};
  CHECK_THROWS_WITH(s.finalize(), Catch::Contains("beyond 2^24"));
  s.camera = Camera{.eye = {1.6e7f, 0, 0}, .target = {0, 0, 0}, .up = {0, 1, 0}};  // just inside
  CHECK_NOTHROW(s.finalize());
}

TEST_CASE("The camera framed for a scene without one keeps its eye in the ray domain, and survives being made the scene's own", "[unit][scene][badinput]") {
  // A model reaching near the domain's edge (whose whole bounding sphere would need an eye beyond
  // it), and one beyond it (the grid refuses that one): the framed eye is inside, and the scene with
  // it as its camera (as a model loads, and as its cache stores it) passes the same validation.
  for (const float reach : {1e7f, 1.6e7f, 1e15f}) {
    INFO("reach " << reach);
    Scene s = reach > sh::kDomainMaxCoordinate
                  ? one_triangle("wide", {reach, 1, 1}, {1, 1, 1}, {0, 1, 1})  // a fuzzer's find
                  : one_triangle("wide", {-reach, 0, 0}, {reach, 0, 0}, {0, reach, 0});
    REQUIRE_NOTHROW(s.finalize());
    const Camera c = s.frame_camera();
    CHECK(std::max({std::abs(c.eye.x), std::abs(c.eye.y), std::abs(c.eye.z)}) <= sh::kDomainMaxCoordinate);
    // The primary ray through the image's centre is a valid ray, and points at the target
    CHECK(sh::ray_valid(c.eye, glm::normalize(c.target - c.eye), 0.0f, sh::sh_infinity()));
    s.camera = c;
    CHECK_NOTHROW(s.finalize());
  }
}

TEST_CASE("A small model far from the origin is framed to be seen, not a speck", "[unit][scene]") {
  // A triangle 0.1 across at (1e5, 2e5, -1e5): its bounding sphere must fill a fair part of the
  // framed view (it used to sit 2^-10 of the centre's reach away: one pixel in 64)
  const glm::vec3 o(1e5f, 2e5f, -1e5f);
  Scene s = one_triangle("far-speck", o, o + glm::vec3(0.1f, 0.0f, 0.0f), o + glm::vec3(0.0f, 0.1f, 0.0f));
  REQUIRE_NOTHROW(s.finalize());
  const Camera c = s.frame_camera();
  REQUIRE(c.eye != c.target);
  const Bounds b = s.bounds(0.0f);
  const float radius = 0.5f * glm::length(b.extent());
  const float half_view = glm::length(c.eye - c.target) * std::tan(glm::radians(c.vfov_degrees) * 0.5f);
  INFO("radius " << radius << ", half view " << half_view);
  CHECK(radius / half_view > 0.05f);
}

TEST_CASE("A scene's camera whose up is parallel to its view is refused when the scene loads", "[unit][scene][badinput]") {
  Scene s;
  s.name = "up";
  s.meshes.push_back(strip(2));
  s.instances.push_back(Instance{.name = "a", .mesh = 0});
  s.camera = Camera{.eye = {0, 5, 0}, .target = {0, 0, 0}, .up = {0, 1, 0}};
  CHECK_THROWS_WITH(s.finalize(), Catch::Contains("parallel"));
}

// An outside sweep: an up of 1e-22 (dot(up, up) subnormal) gave a frame of a few bits, a wrong
// picture with exit 0; 1e-30 and 1e20 were refused as underflowing or overflowing, and a view
// direction 1e-22 long likewise. Any finite, non-zero length now gives its direction's frame, in
// the bits of the same direction at unit scale (the vectors are scaled by powers of two).
TEST_CASE("A camera's up and view of any finite length give the frame of their direction", "[unit][scene][badinput]") {
  const Camera unit{.eye = {0, 5, 15}, .target = {0, 1, 0}, .up = {0.3f, 1.0f, 0.2f}};
  const CameraFrame f0 = camera_frame(unit);
  for (const float k : {0x1p-74f, 0x1p-100f, 0x1p-120f, 0x1p-20f, 0x1p20f, 0x1p66f, 0x1p100f}) {
    INFO("scale " << k);
    Camera c = unit;
    c.up = unit.up * k;  // exact: a power of two, within the normal range for these components
    const CameraFrame f = camera_frame(c);
    CHECK(f.forward == f0.forward);
    CHECK(f.right == f0.right);
    CHECK(f.up == f0.up);
    // The view 2^k times shorter or longer, from an eye at the origin
    Camera v{.eye = {0, 0, 0}, .target = (unit.target - unit.eye), .up = unit.up};
    const CameraFrame g0 = camera_frame(v);
    v.target = v.target * k;
    const CameraFrame g = camera_frame(v);
    CHECK(g.forward == g0.forward);
    CHECK(g.right == g0.right);
    // The scene accepts it as the frame takes it
    Scene s;
    s.name = "cam";
    s.meshes.push_back(strip(2));
    s.instances.push_back(Instance{.name = "a", .mesh = 0});
    s.camera = c;
    CHECK_NOTHROW(s.finalize());
  }
  // Zero stays refused, by name; a field of view that is 180 in single precision says so
  Scene s;
  s.name = "cam";
  s.meshes.push_back(strip(2));
  s.instances.push_back(Instance{.name = "a", .mesh = 0});
  s.camera = Camera{.eye = {0, 5, 15}, .target = {0, 1, 0}, .up = {0, 0, 0}};
  CHECK_THROWS_WITH(Scene(s).finalize(), Catch::Contains("up is zero"));
  s.camera = Camera{.eye = {0, 5, 15}, .target = {0, 1, 0}, .up = {0, 1, 0}, .vfov_degrees = float(179.9999999)};
  CHECK_THROWS_WITH(Scene(s).finalize(), Catch::Contains("180 degrees in single precision, lies outside (0, 180)"));
}

#include "gridrt/common/shared/shadow.h"

// An outside sweep's finds: a point light 2e6 away made shadow rays every trace rejects (the
// direction beyond 2^20), so it cast no shadow; a directional light's direction of length 1e20
// overflowed dot(v, v) and lit nothing, one of 1e-25 was refused as zero. The light's segment is
// now scaled by a power of two into the traces' range (the same segment), and a direction of any
// finite length is brought into range by the scene.
TEST_CASE("Lights at any distance: shadow rays within the traces' domain on the light's segment, directions of any length",
          "[unit][scene][shadows]") {
  namespace sh = gridrt::shared;
  const glm::vec3 p(0.25f, 0.0f, -0.5f), n(0.0f, 1.0f, 0.0f);
  for (float d : {1e-12f, 1e-7f, 1e-3f, 1.0f, 1e5f, 2e6f, 3e7f, 1e20f, 3e38f})
    for (const glm::vec3 towards : {glm::vec3(0, 1, 0), glm::vec3(0.3f, 0.9f, -0.2f), glm::vec3(-1e-3f, 1, 1e-3f)}) {
      const glm::vec3 light = p + towards * d;
      const sh::RayRecord r = sh::shadow_ray(p, n, 7u, light, false);
      INFO("distance " << d << " towards " << towards.x << "," << towards.y << "," << towards.z);
      if (!(glm::dot(light - p, light - p) > 0.0f)) {  // the light at the point (underflow): no ray
        CHECK(r.tmax == 0.0f);
        continue;
      }
      REQUIRE(sh::ray_domain(r.org, r.dir, r.tmin, r.tmax) == sh::kDomainOk);
      // The segment's end is the light: r.dir * r.tmax is light - p, exactly (a power of two apart)
      const glm::vec3 end = r.dir * r.tmax;
      CHECK(end == light - p);
      // In range already: the ray of before, unchanged
      const float m = std::max(std::max(std::abs(end.x), std::abs(end.y)), std::abs(end.z));
      if (m >= 0x1p-20f && m <= 0x1p20f) CHECK((r.dir == light - p && r.tmax == 1.0f));
    }
  // Directional lights: a direction of any finite length lights as the unit one, a zero one is refused
  for (float len : {1e-30f, 1e-25f, 1e-6f, 1.0f, 1e6f, 1e20f, 3e38f}) {
    Scene s = one_triangle("dir", {0, 0, 0}, {1, 0, 0}, {0, 0, 1});
    s.lights.push_back(Light{.position = glm::vec3(0.0f, 0.6f, 0.8f) * len, .directional = true});
    s.finalize();
    INFO("length " << len);
    const glm::vec3 u = glm::normalize(s.lights[0].position);
    CHECK(std::abs(u.y - 0.6f) < 1e-6f);
    CHECK(std::abs(u.z - 0.8f) < 1e-6f);
    const sh::RayRecord r = sh::shadow_ray({0.2f, 0.0f, 0.2f}, {0, 1, 0}, 1u, s.lights[0].position, true);
    CHECK(sh::ray_domain(r.org, r.dir, r.tmin, r.tmax) == sh::kDomainOk);
  }
  Scene z = one_triangle("zero", {0, 0, 0}, {1, 0, 0}, {0, 0, 1});
  z.lights.push_back(Light{.position = glm::vec3(0.0f), .directional = true});
  CHECK_THROWS_WITH(z.finalize(), Catch::Contains("zero direction"));
}

TEST_CASE("Motions at large times keep their phase: a path's loop and a turn's angle reduced in double", "[unit][scene]") {
  // An outside tester's find: the path's phase was time / period in float, which near 1e6 s keeps
  // no digit of a short loop; the angle was the float product, a step of 1/16 rad near 1e6 rad
  Motion m;
  m.path_points = {glm::vec3(0.0f), glm::vec3(1.0f, 0.0f, 0.0f)};
  m.path_period = 0.001f;
  for (const float t : {999999.9375f, 524288.5f, 0.25e-3f, 1.0f / 3.0f}) {
    INFO("t = " << t);
    double phase = std::fmod(double(t) / double(m.path_period), 1.0);
    const double s = phase * 2.0;
    const double x = s < 1.0 ? s : 2.0 - s;  // out along x in the first half loop, back in the second
    CHECK(std::abs(double(m.at(t)[3].x) - x) <= 1e-5);
  }
  Motion r;
  r.angular_speed = 1.0f;
  r.axis = glm::vec3(0.0f, 0.0f, 1.0f);
  for (const float t : {999999.9375f, 123456.789f, 2.5f}) {
    INFO("t = " << t);
    const double a = std::fmod(double(t), 2.0 * 3.14159265358979323846);
    const glm::vec4 p = r.at(t) * glm::vec4(1.0f, 0.0f, 0.0f, 1.0f);
    CHECK(std::abs(double(p.x) - std::cos(a)) <= 1e-6);
    CHECK(std::abs(double(p.y) - std::sin(a)) <= 1e-6);
  }
}

TEST_CASE("The least extent is judged on the box over the motions, whatever the time asked", "[unit][scene][badinput]") {
  // An outside tester's find: two triangles 1e-13 across, one on a 10-unit path, were refused at
  // t = 0 (both at the origin) and accepted at t = 2.5
  Scene s;
  s.name = "tiny";
  Mesh m;
  m.name = "t";
  m.positions = {{0, 0, 0}, {1e-13f, 0, 0}, {0, 1e-13f, 0}};
  m.triangles = {{0u, 1u, 2u}};
  m.materials = {0u};
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "a", .mesh = 0});
  s.finalize();
  CHECK_THROWS_WITH(s.require_extent(0.0f, "grid"), Catch::Contains("spans only"));
  Instance b{.name = "b", .mesh = 0, .dynamic = true};
  b.motion.path_points = {glm::vec3(0.0f), glm::vec3(10.0f, 0.0f, 0.0f)};
  b.motion.path_period = 10.0f;
  s.instances.push_back(b);
  s.finalize();
  for (const float t : {0.0f, 2.5f, 10.0f}) CHECK_NOTHROW(s.require_extent(t, "grid"));
}

TEST_CASE("An empty mesh on a path bounds nothing: the grid is the other instances'", "[unit][scene][badinput]") {
  // An outside sweep: an empty mesh's instance moving along a path (a .gridscene may hold one) was
  // refused as "its bounds over the animation ... are not finite", a static or rotating one not
  Scene s;
  s.name = "empty mover";
  Mesh m;
  m.name = "t";
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.triangles = {{0u, 1u, 2u}};
  m.materials = {0u};
  s.meshes.push_back(m);
  Mesh e;
  e.name = "empty";
  s.meshes.push_back(e);
  s.instances.push_back(Instance{.name = "a", .mesh = 0});
  Instance b{.name = "b", .mesh = 1, .dynamic = true};
  b.motion.path_points = {glm::vec3(0.0f), glm::vec3(10.0f, 0.0f, 0.0f)};
  b.motion.path_period = 10.0f;
  s.instances.push_back(b);
  s.finalize();
  for (const float t : {0.0f, 2.5f}) {
    const Bounds bb = plan::animation_bounds(s, t);
    CHECK(bb.lo == glm::vec3(0.0f));
    CHECK(bb.hi == glm::vec3(1.0f, 1.0f, 0.0f));
  }
}
