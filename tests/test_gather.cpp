// test_gather.cpp: gather buffer, bounce rays and shading.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/shade.h"
#include "gridrt/plan/options.h"
#include "gridrt/reference/grid.h"
#include "tests/test_grid_util.h"
#include "tests/run_tool.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

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

// A UV sphere of radius 1 at the origin: `n` segments, n / 2 rings, its triangles wound outward
// (every face's normal points away from the centre).
Scene sphere_scene(int n) {
  Scene s;
  s.name = "sphere";
  s.materials = {Material{.name = "white", .diffuse = {0.8f, 0.8f, 0.8f}}};
  Mesh m;
  m.name = "sphere";
  const int rings = n / 2;
  m.positions.push_back({0.0f, 1.0f, 0.0f});
  for (int r = 1; r < rings; ++r)
    for (int k = 0; k < n; ++k) {
      const double th = 3.14159265358979 * r / rings, ph = 2.0 * 3.14159265358979 * k / n;
      m.positions.push_back(glm::vec3(float(std::sin(th) * std::cos(ph)), float(std::cos(th)),
                                      float(std::sin(th) * std::sin(ph))));
    }
  m.positions.push_back({0.0f, -1.0f, 0.0f});
  const uint32_t south = uint32_t(m.positions.size() - 1);
  auto at = [&](int r, int k) { return uint32_t(1 + (r - 1) * n + (k % n)); };
  for (int k = 0; k < n; ++k) {
    m.triangles.push_back({0u, at(1, k + 1), at(1, k)});
    m.triangles.push_back({south, at(rings - 1, k), at(rings - 1, k + 1)});
    for (int r = 1; r + 1 < rings; ++r) {
      m.triangles.push_back({at(r, k), at(r, k + 1), at(r + 1, k)});
      m.triangles.push_back({at(r, k + 1), at(r + 1, k + 1), at(r + 1, k)});
    }
  }
  m.materials.assign(m.triangles.size(), 0u);
  s.meshes = {m};
  s.instances = {Instance{.name = "sphere", .mesh = 0}};
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

TEST_CASE("Gather: a closed sphere seen from far away shows a front face at every pixel it covers", "[unit][oracle]") {
  // The camera rays of a far camera pass a mesh's shared edges with rounding far above the
  // triangles' scale: Moller-Trumbore's test lets some through between two front faces, to a back
  // face (7 of 14,400 pixels at 4,000 units: an outside sweep). The exact traversal's watertight
  // test, which the gather takes with it (plan::gather_options), computes a shared edge's function
  // once for both faces: no ray passes between them.
  Scene s = sphere_scene(64);
  for (const float d : {1.0e3f, 4.0e3f, 3.0e4f}) {
    s.camera = Camera{.eye = {0.6f * d, 0.3f * d, 0.74f * d}, .target = {0, 0, 0}, .vfov_degrees = 150.0f / d};
    reference::GridOptions o;
    o.traversal = reference::Traversal::exact;  // the watertight test by default
    reference::ReferenceGridTracer tracer(plan::gather_options(o));
    tracer.build(s, 0.0f);
    const GatherBuffer g = make_gather(s, tracer, *s.camera, 120, 90);
    size_t covered = 0;
    for (size_t p = 0; p < g.size(); ++p) {
      if (!g.valid[p]) continue;
      ++covered;
      const glm::uvec3 tri = s.meshes[0].triangles[g.hit[p].triangle];
      const glm::vec3 v0 = s.meshes[0].positions[tri.x], v1 = s.meshes[0].positions[tri.y],
                      v2 = s.meshes[0].positions[tri.z];
      const glm::vec3 nrm = glm::cross(v1 - v0, v2 - v0);
      INFO("camera " << d << " away, pixel " << p << ": triangle " << g.hit[p].triangle);
      CHECK(glm::dot(nrm, g.incident[p]) < 0.0f);  // a front face: the ray comes from outside
    }
    CHECK(covered > 2000);
  }
}

TEST_CASE("Gather: no camera ray through a shared vertex passes between the triangles around it", "[unit][oracle]") {
  // An outside sweep's find: every interior pixel's ray passes exactly through a vertex of the
  // sheet; the gather's test is the watertight one (plan::gather_options) on either traversal.
  const uint32_t w = 32;
  const Scene s = gridtest::pixel_vertex_sheet(w);
  for (const auto traversal : {reference::Traversal::paper, reference::Traversal::exact})
    for (const auto test : {reference::GridOptions::TriangleTest::automatic, reference::GridOptions::TriangleTest::moller}) {
      reference::GridOptions o;
      o.traversal = traversal;
      o.triangle_test = test;
      reference::ReferenceGridTracer tracer(plan::gather_options(o));
      tracer.build(s, 0.0f);
      const GatherBuffer g = make_gather(s, tracer, *s.camera, w, w);
      INFO("traversal " << (traversal == reference::Traversal::exact ? "exact" : "paper") << ", test "
                        << (test == reference::GridOptions::TriangleTest::moller ? "moller" : "auto"));
      CHECK(gridtest::sheet_pixels_missed(g, w) == 0);
    }
  // Moller-Trumbore's own test lets rays through: the scene does test watertightness
  reference::GridOptions mt;
  mt.traversal = reference::Traversal::exact;
  mt.triangle_test = reference::GridOptions::TriangleTest::moller;
  reference::ReferenceGridTracer tracer(mt);
  tracer.build(s, 0.0f);
  CHECK(gridtest::sheet_pixels_missed(make_gather(s, tracer, *s.camera, w, w), w) > 10);
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

TEST_CASE("bench: the CPU's rows trace each frame's own rays, from a gather at the frame's time", "[cli][gather]") {
  // The CPU's gather was made once at time 0 and every timed frame traced its rays against a grid
  // whose instances had moved (an outside sweep: 6 shadow rays where the frame had 7)
  const Scene s = make_builtin("atrium");
  const auto count_at = [&](float time, bool shadow) {
    reference::ReferenceGridTracer tracer(plan::gather_options(reference::GridOptions{}));
    tracer.build(s, time);
    const GatherBuffer g = make_gather(s, tracer, s.frame_camera(), 64, 36, time);
    const std::vector<Ray> rays = shadow ? shadow_rays(s, g) : bounce_rays(s, g, 0);
    return size_t(std::count_if(rays.begin(), rays.end(), [](const Ray& r) { return !is_unused(r); }));
  };
  // frames 0, 1, 2 at 1, 2, 3 s (--fps 1): the last one's shadow rays are reported
  const size_t last = count_at(3.0f, true), first = count_at(1.0f, false);
  REQUIRE(last != count_at(0.0f, true));  // the frames differ, so the count says which gather was used
  const std::filesystem::path json = std::filesystem::temp_directory_path() / "gridrt-bench-frame-gathers.json";
  const gridrt::test::Run r = gridrt::test::run_tool("bench builtin:atrium --backend cpu --width 64 --height 36 --frames 3 --warmup 0 --fps 1 --json " +
                         json.string());
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  std::ifstream in(json);
  const nlohmann::json j = nlohmann::json::parse(in);
  CHECK(j["backends"]["cpu"]["shadow_rays"].get<size_t>() == last);
  CHECK(j["rays_per_frame"].get<size_t>() == first);
  std::filesystem::remove(json);
}

TEST_CASE("coherent_ray_order: a permutation, stable, the empty and broken rays last, rays grouped by direction",
          "[unit]") {
  // Rays from random origins in random directions, with empty rays (is_unused) and rays with a NaN
  // or infinite component among them
  std::vector<Ray> rays;
  uint32_t state = 12345u;
  const auto next = [&] {
    state = state * 1664525u + 1013904223u;
    return float(state >> 8) / float(1u << 24) * 2.0f - 1.0f;  // [-1, 1)
  };
  std::vector<bool> broken;
  for (int i = 0; i < 2000; ++i) {
    Ray r = gridtest::make_ray(glm::vec3(next(), next(), next()) * 100.0f, glm::vec3(next(), next(), next()));
    bool bad = false;
    if (i % 97 == 0) {
      r.tmin = r.tmax = 0.0f;  // empty
      bad = true;
    } else if (i % 131 == 0) {
      r.org.y = std::numeric_limits<float>::quiet_NaN();
      bad = true;
    } else if (i % 173 == 0) {
      r.dir.x = std::numeric_limits<float>::infinity();
      bad = true;
    } else if (r.dir == glm::vec3(0.0f)) {
      bad = true;
    }
    rays.push_back(r);
    broken.push_back(bad);
  }
  const std::vector<uint32_t> order = coherent_ray_order(rays);
  REQUIRE(order.size() == rays.size());
  std::vector<uint32_t> seen(order);
  std::sort(seen.begin(), seen.end());
  for (uint32_t i = 0; i < seen.size(); ++i) REQUIRE(seen[i] == i);  // a permutation
  CHECK(coherent_ray_order(rays) == order);                          // deterministic
  const size_t bad_count = size_t(std::count(broken.begin(), broken.end(), true));
  REQUIRE(bad_count > 20);
  // The broken rays last, in their given order
  for (size_t k = 0; k < order.size(); ++k) CHECK(broken[order[k]] == (k >= order.size() - bad_count));
  for (size_t k = order.size() - bad_count + 1; k < order.size(); ++k) CHECK(order[k - 1] < order[k]);
  // The usable rays by the direction's cube face (the key's highest part): the face of the largest
  // component and its sign, never decreasing along the order
  const auto face = [](glm::vec3 d) {
    const glm::vec3 a = glm::abs(d);
    const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
    return axis * 2 + (d[axis] < 0.0f ? 1 : 0);
  };
  for (size_t k = 1; k < order.size() - bad_count; ++k) CHECK(face(rays[order[k - 1]].dir) <= face(rays[order[k]].dir));
  // Equal rays keep their order: a list of one ray repeated is left as it is
  const std::vector<Ray> same(50, rays[1]);
  const std::vector<uint32_t> same_order = coherent_ray_order(same);
  for (uint32_t k = 0; k < same_order.size(); ++k) CHECK(same_order[k] == k);
  CHECK(coherent_ray_order(std::vector<Ray>{}).empty());
}

TEST_CASE("bench --ray-order sorted: the same rays and hits as in the given order, and only for a fixed list",
          "[cli][bench]") {
  const std::filesystem::path dir = std::filesystem::temp_directory_path();
  const auto run = [&](const std::string& order) {
    const std::filesystem::path json = dir / ("gridrt-bench-order-" + order + ".json");
    const gridrt::test::Run r = gridrt::test::run_tool(
        "bench builtin:atrium --backend cpu --traversal exact --rays glossy-list --ray-order " + order +
        " --width 48 --height 27 --frames 1 --warmup 0 --json " + json.string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    CHECK((r.output.find("sorted by direction, then origin") != std::string::npos) == (order == "sorted"));
    std::ifstream in(json);
    const nlohmann::json j = nlohmann::json::parse(in);
    std::filesystem::remove(json);
    return j;
  };
  const nlohmann::json given = run("given"), sorted = run("sorted");
  CHECK(sorted["ray_order"] == "sorted");
  CHECK(given["ray_order"] == "given");
  // The same rays (every glossy pixel's, the empty ones left out) and, ray by ray, the same hits:
  // the counters' means over them agree exactly (sums of integers)
  REQUIRE(given["rays_per_frame"].get<size_t>() > 100);
  CHECK(sorted["rays_per_frame"] == given["rays_per_frame"]);
  const nlohmann::json& a = given["backends"]["cpu"]["trace_counters"];
  const nlohmann::json& b = sorted["backends"]["cpu"]["trace_counters"];
  CHECK(a["cells_mean"].get<double>() == b["cells_mean"].get<double>());
  CHECK(a["tests_mean"].get<double>() == b["tests_mean"].get<double>());
  CHECK(a["tests_max"].get<double>() == b["tests_max"].get<double>());
  // The frame traces its own rays in its pixel tiles: no order to choose there (exit 2)
  const gridrt::test::Run frame = gridrt::test::run_tool("bench builtin:atrium --backend cpu --ray-order sorted --frames 1");
  INFO(frame.output);
  CHECK(frame.exit_code == 2);
  CHECK(frame.output.find("orders a fixed list") != std::string::npos);
}
