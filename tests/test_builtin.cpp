// test_builtin.cpp: the built-in scenes and the Bezier teapot, against properties derived from
// the patch data and from geometry, not from the tessellator's own bookkeeping.
#include <catch2/catch.hpp>

#include <cmath>
#include <map>
#include <set>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/tracer.h"

using namespace gridrt;

namespace {

using Edge = std::pair<uint32_t, uint32_t>;

// Undirected edge -> the directions in which triangles traverse it (+1: low -> high).
std::map<Edge, std::vector<int>> edge_uses(const Mesh& m) {
  std::map<Edge, std::vector<int>> e;
  for (const glm::uvec3& t : m.triangles)
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = t[k], b = t[(k + 1) % 3];
      e[{std::min(a, b), std::max(a, b)}].push_back(a < b ? 1 : -1);
    }
  return e;
}

// Closed and consistently oriented: every edge used twice, in opposite directions.
bool closed(const Mesh& m) {
  for (const auto& [e, uses] : edge_uses(m))
    if (uses.size() != 2 || uses[0] + uses[1] != 0) return false;
  return true;
}

double signed_volume(const Mesh& m) {
  double v = 0.0;
  for (const glm::uvec3& t : m.triangles)
    v += glm::dot(glm::dvec3(m.positions[t[0]]),
                  glm::cross(glm::dvec3(m.positions[t[1]]), glm::dvec3(m.positions[t[2]]))) / 6.0;
  return v;
}

glm::vec3 face_normal(const Mesh& m, const glm::uvec3& t) {
  return glm::cross(m.positions[t[1]] - m.positions[t[0]], m.positions[t[2]] - m.positions[t[0]]);
}

}  // namespace

TEST_CASE("Teapot: seams welded, boundary only at the model's open rims", "[unit][scenes]") {
  for (unsigned level : {2u, 3u, 5u, 8u}) {
    CAPTURE(level);
    const Mesh m = make_teapot_mesh(level);
    const auto uses = edge_uses(m);
    std::vector<Edge> boundary;
    for (const auto& [e, u] : uses) {
      // Interior seam edges: exactly two triangles, opposite directions (consistent orientation).
      REQUIRE(u.size() <= 2);
      if (u.size() == 2) CHECK(u[0] + u[1] == 0);
      if (u.size() == 1) boundary.push_back(e);
    }
    // The open rims of the 28-patch model: seven loops of level segments per patch side, 4 patch
    // sides each for the bottom (r 0.375, y 0), the pot's inner rim edge (r 0.35) and the lid's
    // edge (r 0.325) at the rim height; 2 each for both handle ends, the spout's base and tip.
    CHECK(boundary.size() == size_t(20 * level));
    const float rim_y = 0.863037f - 0.300049f;
    // Newell's Bezier arcs approximate circles to within 1% of the radius.
    auto on = [](float r, float radius) { return std::abs(r - radius) < 0.01f * radius; };
    size_t bottom = 0, rim = 0, lid = 0, handle = 0, spout_base = 0, spout_tip = 0;
    for (const Edge& e : boundary) {
      const glm::vec3 p = m.positions[e.first], q = m.positions[e.second];
      const float rp = std::hypot(p.x, p.z), rq = std::hypot(q.x, q.z);
      if (p.y == 0.0f && q.y == 0.0f && on(rp, 0.375f) && on(rq, 0.375f)) ++bottom;
      else if (std::abs(p.y - rim_y) < 1e-6f && std::abs(q.y - rim_y) < 1e-6f && on(rp, 0.35f) && on(rq, 0.35f)) ++rim;
      else if (std::abs(p.y - rim_y) < 1e-6f && std::abs(q.y - rim_y) < 1e-6f && on(rp, 0.325f) && on(rq, 0.325f)) ++lid;
      else if (p.x < -0.37f && q.x < -0.37f) ++handle;
      else if (std::abs(p.x - 0.425f) < 1e-6f && std::abs(q.x - 0.425f) < 1e-6f) ++spout_base;
      else if (p.x >= 0.675f && q.x >= 0.675f && p.y > 0.55f && q.y > 0.55f) ++spout_tip;
    }
    CHECK(bottom == 4 * level);
    CHECK(rim == 4 * level);
    CHECK(lid == 4 * level);
    CHECK(handle == 4 * level);
    CHECK(spout_base == 2 * level);
    CHECK(spout_tip == 2 * level);
    CHECK(bottom + rim + lid + handle + spout_base + spout_tip == boundary.size());
  }
}

TEST_CASE("Teapot: vertex count grows as 28 L^2 + 8 L, no zero-area triangles", "[unit][scenes]") {
  for (unsigned level = 1; level <= 6; ++level) {
    CAPTURE(level);
    const Mesh m = make_teapot_mesh(level);
    // 28 patches of (L+1)^2 points, seams and poles welded: second difference 2 * 28 = 56.
    CHECK(m.positions.size() == size_t(28 * level * level + 8 * level));
    // 56 L^2 triangles less the 4 L that collapse at the lid's pole (at L = 1 more collapse).
    if (level >= 2) CHECK(m.triangles.size() == size_t(56 * level * level - 4 * level));
    for (const glm::uvec3& t : m.triangles) CHECK(glm::length(face_normal(m, t)) > 0.0f);
    std::set<std::array<float, 3>> unique;
    for (const glm::vec3& p : m.positions) unique.insert({p.x, p.y, p.z});
    CHECK(unique.size() == m.positions.size());
    CHECK(m.normals.size() == m.positions.size());
    CHECK(m.materials.size() == m.triangles.size());
  }
}

TEST_CASE("Teapot: patch corners are the control-point corners exactly", "[unit][scenes]") {
  const auto cp = teapot_control_points();
  REQUIRE(cp.size() == 28 * 16);
  for (unsigned level : {1u, 4u, 7u}) {
    const Mesh m = make_teapot_mesh(level);
    std::set<std::array<float, 3>> have;
    for (const glm::vec3& p : m.positions) have.insert({p.x, p.y, p.z});
    for (size_t k = 0; k < 28; ++k)
      for (size_t c : {0u, 3u, 12u, 15u}) {
        const glm::vec3 p = teapot_to_scene(cp[k * 16 + c]);
        CAPTURE(level, k, c);
        CHECK(have.count({p.x, p.y, p.z}) == 1);
      }
  }
  // The stored frame is z up: the scene's y spans the stored z range, bottom at 0.
  CHECK(teapot_to_scene({0.5f, 0.0f, 0.300049f}) == glm::vec3(0.0f));
}

TEST_CASE("Teapot: normals point outward", "[unit][scenes]") {
  const Mesh m = make_teapot_mesh(8);
  size_t body = 0;
  for (const glm::uvec3& t : m.triangles) {
    const glm::vec3 n = face_normal(m, t);
    // Vertex normals agree with the winding.
    CHECK(glm::dot(n, m.normals[t[0]] + m.normals[t[1]] + m.normals[t[2]]) > 0.0f);
    // On the body, away from the handle and the spout (both near z = 0), away from the axis.
    const glm::vec3 c = (m.positions[t[0]] + m.positions[t[1]] + m.positions[t[2]]) / 3.0f;
    const float r = std::hypot(c.x, c.z);
    if (c.y > 0.02f && c.y < 0.55f && r > 0.36f && r < 0.51f && std::abs(c.z) > 0.2f) {
      ++body;
      CHECK(glm::dot(n, glm::vec3(c.x, 0.0f, c.z)) > 0.0f);
    }
    // The lid's dome (below the knob) faces up.
    if (c.y > 0.57f && c.y < 0.635f && r > 0.06f && r < 0.3f) CHECK(n.y > 0.0f);
  }
  CHECK(body > 200);
  for (const glm::vec3& n : m.normals) CHECK(std::abs(glm::length(n) - 1.0f) < 1e-5f);
  // The pole of the lid: a single vertex with the axis as its normal.
  size_t top = 0;
  for (size_t v = 0; v < m.positions.size(); ++v)
    if (m.positions[v].y == 1.050049f - 0.300049f) {
      ++top;
      CHECK(m.normals[v].y > 0.999f);
    }
  CHECK(top == 1);
}

TEST_CASE("Teapot level out of range is an error", "[unit][scenes][badinput]") {
  CHECK_THROWS_AS(make_teapot_mesh(0), Error);
  CHECK_THROWS_AS(make_teapot_mesh(1000), Error);
}

TEST_CASE("Built-in scenes finalize and have their traits", "[unit][scenes]") {
  CHECK(builtin_names() == std::vector<std::string>{"atrium", "cornell", "teapot"});
  CHECK_THROWS_AS(make_builtin("nonesuch"), Error);
  for (const std::string& name : builtin_names()) {
    CAPTURE(name);
    const Scene s = make_builtin(name);
    CHECK(s.name == name);
    CHECK(s.camera.has_value());
    CHECK(s.triangle_count() > 0);
    CHECK(s.triangle_count() < 30000);
    // The camera looks into the scene: its central ray points towards the bounds' centre.
    const Bounds b = s.bounds(0.0f);
    const Ray r = camera_ray(*s.camera, 64, 64, 32, 32);
    CHECK(glm::dot(r.dir, 0.5f * (b.lo + b.hi) - r.org) > 0.0f);
  }
}

TEST_CASE("Atrium: alpha masks, two moving teapots, glossy floor", "[unit][scenes]") {
  const Scene s = make_builtin("atrium");
  CHECK(s.has_alpha_masks());
  CHECK(s.has_glossy());
  CHECK(s.has_dynamic());
  CHECK(s.triangle_count() > 3000);
  // Exactly two dynamic instances, last in order, and both move between t = 0 and t = 1.
  size_t dynamic = 0;
  for (size_t i = 0; i < s.instances.size(); ++i)
    if (s.instances[i].dynamic) {
      ++dynamic;
      CHECK(i >= s.static_instance_count());
      const Instance& inst = s.instances[i];
      CHECK(inst.motion.moves());
      const glm::vec3 p(0.3f, 0.2f, 0.1f);
      const glm::vec3 a(inst.transform_at(0.0f) * glm::vec4(p, 1.0f)), b(inst.transform_at(1.0f) * glm::vec4(p, 1.0f));
      CHECK(glm::length(a - b) > 0.1f);
    }
  CHECK(dynamic == 2);
  // The floor is glossy (~0.6) and the foliage is alpha keyed by a generated RGBA texture.
  bool glossy_floor = false, foliage = false;
  for (const Material& m : s.materials) {
    if (m.name == "floor") glossy_floor = std::abs(m.glossiness - 0.6f) < 0.05f;
    if (m.alpha_keyed()) {
      const Texture& t = s.textures[m.alpha_texture];
      CHECK(t.path.empty());
      CHECK(t.has_alpha);
      size_t cut = 0, kept = 0;
      for (size_t i = 3; i < t.rgba.size(); i += 4) (t.rgba[i] < 128 ? cut : kept)++;
      CHECK(cut > 0);
      CHECK(kept > 0);
      foliage = true;
    }
  }
  CHECK(glossy_floor);
  CHECK(foliage);
  const Features f = Features::for_scene(s);
  CHECK(f.alpha_keying);
  CHECK(f.update);
  CHECK(f.glossy);
  CHECK(f.shadows);
}

TEST_CASE("Cornell: a closed room with two closed blocks", "[unit][scenes]") {
  const Scene s = make_builtin("cornell");
  size_t closed_meshes = 0;
  for (const Mesh& m : s.meshes) {
    CAPTURE(m.name);
    if (m.name == "cornell_room") {
      CHECK(closed(m));
      CHECK(signed_volume(m) < 0.0);  // faces point into the room
      ++closed_meshes;
    } else if (m.name.find("block") != std::string::npos) {
      CHECK(closed(m));
      CHECK(signed_volume(m) > 0.0);  // faces point out of the block
      ++closed_meshes;
    }
  }
  CHECK(closed_meshes == 3);
  // The camera stands inside the room.
  const Bounds b = s.bounds();
  const glm::vec3 eye = s.camera->eye;
  CHECK((eye.x > b.lo.x && eye.x < b.hi.x && eye.y > b.lo.y && eye.y < b.hi.y && eye.z > b.lo.z && eye.z < b.hi.z));
  const Features f = Features::for_scene(s);
  CHECK_FALSE(f.alpha_keying);
  CHECK_FALSE(f.update);
  CHECK_FALSE(f.glossy);
  CHECK(f.shadows);
}

TEST_CASE("Camera rays go through pixel centres, normalized", "[unit]") {
  Camera c{.eye = {0, 0, 0}, .target = {0, 0, -1}, .up = {0, 1, 0}, .vfov_degrees = 90.0f};
  // 2 x 2 image, 90 degrees: pixel centres at (+-0.5, +-0.5) on the plane z = -1.
  const Ray r = camera_ray(c, 2, 2, 0, 0);
  CHECK(r.dir.x == Approx(-0.5f / std::sqrt(1.5f)));
  CHECK(r.dir.y == Approx(0.5f / std::sqrt(1.5f)));
  CHECK(r.dir.z == Approx(-1.0f / std::sqrt(1.5f)));
  CHECK(r.tmin == 0.0f);
  CHECK(std::isinf(r.tmax));
  CHECK(r.launch_ref == shared::kNoRef);
  CHECK(r.launch_normal == glm::vec3(0.0f));
  // Odd size: the centre pixel looks straight at the target.
  const Ray m = camera_ray(c, 3, 3, 1, 1);
  CHECK(m.dir == glm::vec3(0, 0, -1));
  for (uint32_t y = 0; y < 5; ++y)
    for (uint32_t x = 0; x < 7; ++x) CHECK(std::abs(glm::length(camera_ray(c, 7, 5, x, y).dir) - 1.0f) < 1e-6f);
  CHECK_THROWS_AS(camera_ray(c, 2, 2, 2, 0), Error);
  CHECK_THROWS_AS(camera_ray(Camera{.eye = {0, 0, 0}, .target = {0, 1, 0}, .up = {0, 1, 0}}, 2, 2, 0, 0), Error);
}
