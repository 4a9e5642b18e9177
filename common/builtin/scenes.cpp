// scenes.cpp: the built-in scenes (teapot, cornell, atrium), made from code.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

#include <glm/gtc/matrix_transform.hpp>

#include "gridrt/common/builtin/builtin.h"

namespace gridrt {

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// Appends geometry to a mesh; every triangle gets the builder's current material.
struct Builder {
  Mesh mesh;
  uint32_t material = 0;

  explicit Builder(std::string name) { mesh.name = std::move(name); }

  uint32_t vertex(glm::vec3 p, glm::vec2 uv = glm::vec2(0.0f)) {
    mesh.positions.push_back(p);
    mesh.uvs.push_back(uv);
    return uint32_t(mesh.positions.size() - 1);
  }
  void triangle(uint32_t a, uint32_t b, uint32_t c) {
    mesh.triangles.push_back({a, b, c});
    mesh.materials.push_back(material);
  }
  // Quad a b c d (counter-clockwise seen from the front), split along a-c.
  void quad(uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
    triangle(a, b, c);
    triangle(a, c, d);
  }
  // Triangle a b c wound so that its geometric normal has a positive component along `facing`.
  void triangle_facing(uint32_t a, uint32_t b, uint32_t c, glm::vec3 facing) {
    const glm::vec3 n = glm::cross(mesh.positions[b] - mesh.positions[a], mesh.positions[c] - mesh.positions[a]);
    if (glm::dot(n, facing) < 0.0f) std::swap(b, c);
    triangle(a, b, c);
  }
  void quad_facing(uint32_t a, uint32_t b, uint32_t c, uint32_t d, glm::vec3 facing) {
    triangle_facing(a, b, c, facing);
    triangle_facing(a, c, d, facing);
  }
  void quad(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, glm::vec2 uv_scale = glm::vec2(1.0f)) {
    quad(vertex(a, glm::vec2(0.0f)), vertex(b, glm::vec2(uv_scale.x, 0.0f)), vertex(c, uv_scale),
         vertex(d, glm::vec2(0.0f, uv_scale.y)));
  }
};

// An axis-aligned box, outward-facing, with shared corner vertices (closed).
void add_box(Builder& b, glm::vec3 lo, glm::vec3 hi) {
  uint32_t v[8];
  for (int i = 0; i < 8; ++i)
    v[i] = b.vertex({(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z});
  b.quad(v[0], v[4], v[6], v[2]);  // -x
  b.quad(v[1], v[3], v[7], v[5]);  // +x
  b.quad(v[0], v[1], v[5], v[4]);  // -y
  b.quad(v[2], v[6], v[7], v[3]);  // +y
  b.quad(v[0], v[2], v[3], v[1]);  // -z
  b.quad(v[4], v[5], v[7], v[6]);  // +z
}

// ---- teapot -------------------------------------------------------------------------------

Scene make_teapot_scene() {
  Scene s;
  s.name = "teapot";
  s.meshes.push_back(make_teapot_mesh(8));
  s.materials.push_back(Material{.name = "porcelain", .diffuse = {0.85f, 0.82f, 0.75f}});
  s.instances.push_back(Instance{.name = "teapot", .mesh = 0});
  s.camera = Camera{.eye = {0.9f, 0.9f, 1.6f}, .target = {0.1f, 0.35f, 0.0f}, .vfov_degrees = 40.0f};
  s.lights.push_back(Light{.position = {2.0f, 3.0f, 2.0f}, .intensity = 14.0f});
  return s;
}

// ---- cornell ------------------------------------------------------------------------------

// The Cornell box from the measured data of the Cornell Program of Computer Graphics
// (https://www.graphics.cornell.edu/online/box/data.html), millimetres scaled to metres /100
// (so the room is about 5.5 units wide), plus a front wall that closes the room and bottoms that
// close the blocks. Every wall, block and the light panel is a closed or shared-edge mesh; the
// camera stands inside the room, behind the (open in the original) front.
Scene make_cornell() {
  Scene s;
  s.name = "cornell";
  s.materials = {Material{.name = "white", .diffuse = {0.73f, 0.73f, 0.73f}},
                 Material{.name = "red", .diffuse = {0.65f, 0.05f, 0.05f}},
                 Material{.name = "green", .diffuse = {0.12f, 0.45f, 0.15f}},
                 Material{.name = "light", .diffuse = {0.78f, 0.78f, 0.78f}}};
  auto P = [](float x, float y, float z) { return glm::vec3(x, y, z) * 0.01f; };

  // The room: floor, ceiling, back, front, right (green, x = 0), left (red, x ~ 556); corner
  // vertices shared between walls so that the room is closed. Faces point into the room.
  Builder room("cornell_room");
  const uint32_t f0 = room.vertex(P(552.8f, 0, 0)), f1 = room.vertex(P(0, 0, 0)),
                 f2 = room.vertex(P(0, 0, 559.2f)), f3 = room.vertex(P(549.6f, 0, 559.2f));
  const uint32_t c0 = room.vertex(P(556, 548.8f, 0)), c1 = room.vertex(P(556, 548.8f, 559.2f)),
                 c2 = room.vertex(P(0, 548.8f, 559.2f)), c3 = room.vertex(P(0, 548.8f, 0));
  room.material = 0;
  room.quad_facing(f0, f3, f2, f1, {0, 1, 0});   // floor
  room.quad_facing(c0, c3, c2, c1, {0, -1, 0});  // ceiling
  room.quad_facing(f3, c1, c2, f2, {0, 0, -1});  // back wall (z = 559.2)
  room.quad_facing(f1, c3, c0, f0, {0, 0, 1});   // front wall (z = 0)
  room.material = 2;
  room.quad_facing(f2, c2, c3, f1, {1, 0, 0});   // right wall (x = 0)
  room.material = 1;
  room.quad_facing(f0, c0, c1, f3, {-1, 0, 0});  // left wall (x ~ 556)
  s.meshes.push_back(room.mesh);

  // A block from its four top corners (counter-clockwise from above) and its height.
  auto block = [&](std::string name, const glm::vec3 (&top)[4]) {
    Builder b(std::move(name));
    uint32_t t[4], g[4];
    for (int i = 0; i < 4; ++i) {
      t[i] = b.vertex(top[i]);
      g[i] = b.vertex(glm::vec3(top[i].x, 0.0f, top[i].z));
    }
    b.quad(t[0], t[1], t[2], t[3]);  // top
    b.quad(g[0], g[3], g[2], g[1]);  // bottom
    for (int i = 0; i < 4; ++i) {
      const int j = (i + 1) % 4;
      b.quad(g[i], g[j], t[j], t[i]);
    }
    // Make every face point outward: flip all triangles if the top faces down.
    const glm::vec3 n = glm::cross(b.mesh.positions[t[1]] - b.mesh.positions[t[0]],
                                   b.mesh.positions[t[2]] - b.mesh.positions[t[0]]);
    if (n.y < 0.0f)
      for (glm::uvec3& tri : b.mesh.triangles) std::swap(tri[1], tri[2]);
    return b.mesh;
  };
  const glm::vec3 short_top[4] = {P(130, 165, 65), P(82, 165, 225), P(240, 165, 272), P(290, 165, 114)};
  const glm::vec3 tall_top[4] = {P(423, 330, 247), P(265, 330, 296), P(314, 330, 456), P(472, 330, 406)};
  s.meshes.push_back(block("cornell_short_block", short_top));
  s.meshes.push_back(block("cornell_tall_block", tall_top));

  // The light panel, 1 mm below the ceiling, facing down.
  Builder light("cornell_light");
  light.material = 3;
  light.quad(P(343, 547.8f, 227), P(343, 547.8f, 332), P(213, 547.8f, 332), P(213, 547.8f, 227));
  s.meshes.push_back(light.mesh);

  for (uint32_t m = 0; m < s.meshes.size(); ++m) s.instances.push_back(Instance{.name = s.meshes[m].name, .mesh = m});
  s.camera = Camera{.eye = P(278, 273, 5), .target = P(278, 273, 559.2f), .vfov_degrees = 56.0f};
  s.lights.push_back(Light{.position = P(278, 540, 279.5f), .color = {1.0f, 0.9f, 0.75f}, .intensity = 18.0f});
  s.background = glm::vec3(0.0f);
  return s;
}

// ---- atrium -------------------------------------------------------------------------------

// Procedural RGBA leaves: a few overlapping elliptic leaves on transparent ground.
Texture make_leaf_texture(uint32_t size) {
  Texture t;
  t.path = "";
  t.width = t.height = size;
  t.rgba.assign(size_t(size) * size * 4, 0);
  struct Leaf { float cx, cy, angle, len, wid; };
  const Leaf leaves[] = {{0.30f, 0.30f, 0.6f, 0.26f, 0.10f}, {0.70f, 0.28f, -0.5f, 0.24f, 0.09f},
                         {0.50f, 0.55f, 1.5f, 0.30f, 0.11f}, {0.25f, 0.75f, 2.4f, 0.22f, 0.09f},
                         {0.75f, 0.72f, 0.9f, 0.25f, 0.10f}, {0.52f, 0.15f, 0.1f, 0.18f, 0.07f}};
  for (uint32_t y = 0; y < size; ++y)
    for (uint32_t x = 0; x < size; ++x) {
      const float px = (float(x) + 0.5f) / float(size), py = (float(y) + 0.5f) / float(size);
      uint8_t* texel = &t.rgba[(size_t(y) * size + x) * 4];
      for (const Leaf& l : leaves) {
        const float dx = px - l.cx, dy = py - l.cy;
        const float a = std::cos(l.angle) * dx + std::sin(l.angle) * dy;
        const float b = -std::sin(l.angle) * dx + std::cos(l.angle) * dy;
        const float r = (a * a) / (l.len * l.len) + (b * b) / (l.wid * l.wid);
        if (r <= 1.0f) {
          const float vein = std::abs(b) < 0.008f ? 0.7f : 1.0f;
          texel[0] = uint8_t(40.0f * vein + 30.0f * r);
          texel[1] = uint8_t((110.0f + 70.0f * (1.0f - r)) * vein);
          texel[2] = uint8_t(30.0f * vein);
          texel[3] = 255;
        }
      }
    }
  t.has_alpha = true;
  return t;
}

// Floor tiles: a two-tone checker, opaque.
Texture make_tile_texture(uint32_t size) {
  Texture t;
  t.width = t.height = size;
  t.rgba.assign(size_t(size) * size * 4, 255);
  for (uint32_t y = 0; y < size; ++y)
    for (uint32_t x = 0; x < size; ++x) {
      const bool dark = ((x * 2 / size) ^ (y * 2 / size)) & 1u;
      const bool grout = (x % (size / 2)) == 0 || (y % (size / 2)) == 0;
      uint8_t* texel = &t.rgba[(size_t(y) * size + x) * 4];
      const glm::vec3 c = grout ? glm::vec3(90, 85, 80) : dark ? glm::vec3(120, 100, 85) : glm::vec3(225, 215, 195);
      texel[0] = uint8_t(c.x), texel[1] = uint8_t(c.y), texel[2] = uint8_t(c.z);
    }
  return t;
}

// A vertical cylinder (no caps): `segments` long thin quads from y0 to y1.
void add_column(Builder& b, glm::vec3 base, float radius, float height, unsigned segments) {
  std::vector<uint32_t> lo, hi;
  for (unsigned k = 0; k <= segments; ++k) {
    const float a = 2.0f * kPi * float(k % segments) / float(segments);
    const glm::vec3 d(std::cos(a), 0.0f, -std::sin(a));
    lo.push_back(b.vertex(base + radius * d, {float(k) / float(segments), 0.0f}));
    hi.push_back(b.vertex(base + radius * d + glm::vec3(0, height, 0), {float(k) / float(segments), 1.0f}));
  }
  for (unsigned k = 0; k < segments; ++k) b.quad(lo[k], lo[k + 1], hi[k + 1], hi[k]);
  // Base and capital: boxes.
  add_box(b, base + glm::vec3(-1.3f * radius, 0, -1.3f * radius), base + glm::vec3(1.3f * radius, 0.3f, 1.3f * radius));
  add_box(b, base + glm::vec3(-1.4f * radius, height - 0.3f, -1.4f * radius),
          base + glm::vec3(1.4f * radius, height, 1.4f * radius));
}

// An arch between z0 and z1 in the plane x = x_face (facing `side`), springing at y = spring:
// the half-cylinder underside (intrados), `depth` deep in x, and the face wall above it up to
// y = top, triangulated as fans from the upper corners.
void add_arch(Builder& b, float x_face, float side, float depth, float z0, float z1, float spring,
              float top, unsigned segments) {
  const float zc = 0.5f * (z0 + z1), r = 0.5f * (z1 - z0);
  std::vector<glm::vec3> curve;
  for (unsigned k = 0; k <= segments; ++k) {
    const float a = kPi * float(k) / float(segments);
    curve.push_back({x_face, spring + r * std::sin(a), zc - r * std::cos(a)});
  }
  // Intrados: half cylinder along x, facing its axis.
  const glm::vec3 back(-side * depth, 0, 0);
  std::vector<uint32_t> front_ring, back_ring;
  for (const glm::vec3& p : curve) {
    front_ring.push_back(b.vertex(p));
    back_ring.push_back(b.vertex(p + back));
  }
  for (unsigned k = 0; k < segments; ++k) {
    const glm::vec3 mid = 0.5f * (curve[k] + curve[k + 1]);
    b.quad_facing(front_ring[k], back_ring[k], back_ring[k + 1], front_ring[k + 1],
                  glm::vec3(x_face, spring, zc) - mid);
  }
  // Face wall above the curve, fans from the two upper corners.
  const glm::vec3 facing(side, 0, 0);
  const uint32_t tl = b.vertex({x_face, top, z0}), tr = b.vertex({x_face, top, z1});
  const uint32_t* c = front_ring.data();
  const unsigned mid = segments / 2;
  for (unsigned k = 0; k < mid; ++k) b.triangle_facing(tl, c[k + 1], c[k], facing);
  for (unsigned k = mid; k < segments; ++k) b.triangle_facing(tr, c[k + 1], c[k], facing);
  b.triangle_facing(tl, tr, c[mid], facing);
}

Scene make_atrium() {
  Scene s;
  s.name = "atrium";
  s.textures.push_back(make_tile_texture(64));   // 0
  s.textures.push_back(make_leaf_texture(128));  // 1
  s.materials = {
      Material{.name = "floor", .diffuse = {1.0f, 1.0f, 1.0f}, .diffuse_texture = 0, .glossiness = 0.6f},
      Material{.name = "stone", .diffuse = {0.78f, 0.74f, 0.66f}},
      Material{.name = "plaster", .diffuse = {0.85f, 0.80f, 0.70f}},
      Material{.name = "foliage", .diffuse = {1.0f, 1.0f, 1.0f}, .diffuse_texture = 1, .alpha_texture = 1},
      Material{.name = "teapot_gold", .diffuse = {0.85f, 0.62f, 0.25f}, .glossiness = 0.5f},
      Material{.name = "teapot_red", .diffuse = {0.7f, 0.15f, 0.1f}},
  };
  // Court: x in [-10, 10], z in [-15, 15]; arcades of columns and arches along x = +-6;
  // outer walls at x = +-10 and z = +-15; open to the sky.
  Builder floor("atrium_floor");
  floor.material = 0;
  floor.quad({-10, 0, 15}, {10, 0, 15}, {10, 0, -15}, {-10, 0, -15}, {10.0f, 15.0f});
  s.meshes.push_back(floor.mesh);

  Builder walls("atrium_walls");
  walls.material = 2;
  const float h = 9.0f;
  auto wall = [&](glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, glm::vec3 facing) {
    walls.quad_facing(walls.vertex(a), walls.vertex(b), walls.vertex(c), walls.vertex(d), facing);
  };
  wall({-10, 0, -15}, {10, 0, -15}, {10, h, -15}, {-10, h, -15}, {0, 0, 1});  // back
  wall({10, 0, 15}, {-10, 0, 15}, {-10, h, 15}, {10, h, 15}, {0, 0, -1});     // front
  wall({-10, 0, 15}, {-10, 0, -15}, {-10, h, -15}, {-10, h, 15}, {1, 0, 0});  // left
  wall({10, 0, -15}, {10, 0, 15}, {10, h, 15}, {10, h, -15}, {-1, 0, 0});     // right
  // Gallery floors above the arcades (y = 7.5), facing up.
  wall({-10, 7.5f, 15}, {-6, 7.5f, 15}, {-6, 7.5f, -15}, {-10, 7.5f, -15}, {0, 1, 0});
  wall({6, 7.5f, 15}, {10, 7.5f, 15}, {10, 7.5f, -15}, {6, 7.5f, -15}, {0, 1, 0});
  s.meshes.push_back(walls.mesh);

  Builder arcade("atrium_arcades");
  arcade.material = 1;
  const float spacing = 4.0f, column_height = 5.0f;
  for (float side : {-1.0f, 1.0f}) {
    const float x = 6.0f * side;
    for (int k = -3; k <= 3; ++k) add_column(arcade, {x, 0, float(k) * spacing}, 0.35f, column_height, 24);
    for (int k = -3; k < 3; ++k)
      add_arch(arcade, x - 0.45f * side, -side, 0.9f, float(k) * spacing, float(k + 1) * spacing, column_height,
               7.5f, 16);
  }
  s.meshes.push_back(arcade.mesh);

  // Foliage: crossed alpha-masked quads in four planters.
  Builder foliage("atrium_foliage");
  foliage.material = 3;
  const glm::vec2 planters[] = {{-3.0f, -7.0f}, {3.0f, -7.0f}, {-3.0f, 7.0f}, {3.0f, 7.0f}};
  for (const glm::vec2 c : planters) {
    foliage.material = 1;
    add_box(foliage, {c.x - 0.6f, 0.0f, c.y - 0.6f}, {c.x + 0.6f, 0.5f, c.y + 0.6f});
    foliage.material = 3;
    for (int q = 0; q < 3; ++q) {
      const float a = kPi * float(q) / 3.0f;
      const glm::vec3 d(std::cos(a) * 1.1f, 0, std::sin(a) * 1.1f);
      const glm::vec3 b(c.x, 0.4f, c.y);
      foliage.quad(b - d, b + d, b + d + glm::vec3(0, 2.2f, 0), b - d + glm::vec3(0, 2.2f, 0), {1.0f, 1.0f});
    }
  }
  s.meshes.push_back(foliage.mesh);

  // Two teapots (dynamic): one turning on the spot, one travelling round the court.
  Mesh teapot = make_teapot_mesh(6);
  teapot.materials.assign(teapot.triangles.size(), 4u);
  s.meshes.push_back(teapot);
  teapot.name = "teapot_red";
  teapot.materials.assign(teapot.triangles.size(), 5u);
  s.meshes.push_back(teapot);
  const uint32_t gold = uint32_t(s.meshes.size() - 2), red = uint32_t(s.meshes.size() - 1);

  for (uint32_t m = 0; m < gold; ++m) s.instances.push_back(Instance{.name = s.meshes[m].name, .mesh = m});
  Instance spinning{.name = "teapot_spinning", .mesh = gold, .dynamic = true};
  spinning.transform = glm::scale(glm::mat4(1.0f), glm::vec3(2.5f));
  spinning.motion.axis = {0, 1, 0};
  spinning.motion.pivot = {0, 0, 0};
  spinning.motion.angular_speed = 0.8f;
  s.instances.push_back(spinning);
  Instance travelling{.name = "teapot_travelling", .mesh = red, .dynamic = true};
  travelling.transform = glm::scale(glm::mat4(1.0f), glm::vec3(1.6f));
  travelling.motion.path_points = {{-4.2f, 0, -4.2f}, {4.2f, 0, -4.2f}, {4.2f, 0, 4.2f}, {-4.2f, 0, 4.2f}};
  travelling.motion.path_period = 8.0f;
  s.instances.push_back(travelling);

  s.camera = Camera{.eye = {0.0f, 3.2f, 13.5f}, .target = {0.0f, 2.2f, 0.0f}, .vfov_degrees = 60.0f};
  s.lights.push_back(Light{.position = glm::normalize(glm::vec3(0.35f, 1.0f, 0.25f)),
                           .color = {1.0f, 0.95f, 0.85f}, .intensity = 1.0f, .directional = true});
  s.background = {0.55f, 0.70f, 0.95f};
  return s;
}

}  // namespace

std::vector<std::string> builtin_names() { return {"atrium", "cornell", "teapot"}; }

Scene make_builtin(std::string_view name) {
  Scene s;
  if (name == "atrium") s = make_atrium();
  else if (name == "cornell") s = make_cornell();
  else if (name == "teapot") s = make_teapot_scene();
  else {
    std::string known;
    for (const std::string& n : builtin_names()) known += (known.empty() ? "" : ", ") + n;
    throw Error("unknown built-in scene '" + std::string(name) + "' (known: " + known + ")");
  }
  s.finalize();
  return s;
}

}  // namespace gridrt
