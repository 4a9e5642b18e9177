// world.cpp: tile maps, the built-in level and voxelized meshes (world.h).
#include "gridrt/reference/portal/world.h"

#include "gridrt/common/util.h"
#include <algorithm>
#include <iostream>
#include <cctype>
#include <cstdio>
#include <optional>
#include <random>
#include <cmath>
#include <fstream>
#include <sstream>

#include "gridrt/common/safe_io.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/portal.h"
#include "gridrt/common/shared/transform.h"

namespace gridrt::portal {

namespace {

// The built-in level; data/maps/builtin.map holds the same text.
constexpr std::string_view kBuiltinLevel = R"MAP(# gridrt portal tile map (docs/PORTAL.md, "Tile maps"): the built-in level.
size 32 32 4
map
11111111111111111111111111111111
1......1...........2...........1
1..E...1...........2...........1
1......1...........2...........1
1....L.1....3..3...2...........1
1..................G...........1
1......1...........2...........1
1......1....3..3...2...........1
1......1...........2...........1
1111.111111111.11122222.22222221
1.........1........2...........1
1.........1........2...........1
1.........1........2...........1
1....4....1....................1
1.........1........2...........1
1.........1........2.....5.....1
1...........................L..1
1.........1........2...........1
11111.11111111111112...........1
1.........1........2.....5.....1
1.........1........2...........1
1...6.....1........22222.2222222
1.........1........2...........1
1.........1........2...........1
1..............................1
1.........1........2...........1
1.........1.....7..2.....8.....1
1...6.....1........2...........1
1.........1........2...........1
1.........1........2...........1
1.........1........2...........1
11111111111111111111111111111111
)MAP";

[[noreturn]] void fail(const std::string& name, size_t line, const std::string& what) {
  throw Error("tile map " + name + (line ? ":" + std::to_string(line) : std::string()) + ": " + what);
}

glm::vec3 palette(uint32_t i) {
  static const glm::vec3 colors[] = {{0.6f, 0.6f, 0.6f}, {0.55f, 0.5f, 0.45f}, {0.35f, 0.45f, 0.7f},
                                     {0.7f, 0.35f, 0.3f}, {0.4f, 0.65f, 0.35f}, {0.75f, 0.7f, 0.3f},
                                     {0.6f, 0.4f, 0.65f}, {0.3f, 0.65f, 0.65f}, {0.8f, 0.55f, 0.35f},
                                     {0.45f, 0.45f, 0.5f}};
  return colors[i % 10];
}

}  // namespace

bool World::has_glass() const {
  return std::any_of(materials.begin(), materials.end(), [](const WallMaterial& m) { return m.glass; });
}

void World::validate() const {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] == 0) throw Error("portal world '" + name + "': empty world (a dimension is 0)");
    if (dims[a] > kMaxWorldAxis)
      throw Error("portal world '" + name + "': " + std::to_string(dims[a]) + " voxels along axis " + "xyz"[a] +
                  ", the div format (8-bit sizes and origins) allows at most " + std::to_string(kMaxWorldAxis));
  }
  if (voxels.size() != voxel_count()) throw Error("portal world '" + name + "': voxel array size does not match dims");
  if (materials.size() > shared::kPortalMaxMaterial + 1)
    throw Error("portal world '" + name + "': more than 32767 materials");
  for (size_t i = 0; i < voxels.size(); ++i)
    if (voxels[i] != kEmpty && voxels[i] >= materials.size())
      throw Error("portal world '" + name + "': voxel " + std::to_string(i) + " has unknown material " +
                  std::to_string(voxels[i]));
  for (size_t m = 0; m < materials.size(); ++m)
    if (materials[m].glass && m > 255)
      throw Error("portal world '" + name + "': glass material " + std::to_string(m) + " above 255 (8-bit div info)");
  if (!(voxel_size > 0.0f) || !std::isfinite(voxel_size)) throw Error("portal world '" + name + "': bad voxel size");
}

namespace {

// Default materials: '0'..'9' walls 0..9, 'G' glass 10, floor 11, ceiling 12. `chars` holds each
// material's map character ('\0' for those no tile names).
constexpr uint16_t kFloorMaterial = 11, kCeilingMaterial = 12;
void default_materials(World& w, std::string& chars) {
  for (int i = 0; i < 10; ++i) {
    chars.push_back(char('0' + i));
    w.materials.push_back({std::string("wall") + char('0' + i), palette(uint32_t(i)), false, 1.5f, glm::vec3(1.0f)});
  }
  chars.push_back('G');
  w.materials.push_back({"glass", glm::vec3(0.8f, 0.9f, 1.0f), true, 1.5f, glm::vec3(0.75f, 0.85f, 1.0f)});
  chars.push_back('\0');
  w.materials.push_back({"floor", glm::vec3(0.45f, 0.42f, 0.4f), false, 1.5f, glm::vec3(1.0f)});
  chars.push_back('\0');
  w.materials.push_back({"ceiling", glm::vec3(0.75f, 0.75f, 0.78f), false, 1.5f, glm::vec3(1.0f)});
}

// A tile map's text split into its header and its rows.
struct TileMapText {
  uint32_t W = 0, D = 0, H = 0;  // width, depth, height in tiles
  std::vector<std::string> rows;
  std::vector<size_t> row_lines;  // each row's line number
};

// 'size WIDTH DEPTH HEIGHT', within the div format and the volume limit
// A line's end: nothing but blanks after what it holds ('size 3 3 1x' or '... 1 1 1 junk' were read
// up to the junk and the rest ignored)
void expect_line_end(std::istringstream& ls, const std::string& name, size_t lineno, const std::string& what) {
  std::string extra;
  if (ls >> extra) fail(name, lineno, "unexpected '" + printable(extra) + "' after " + what);
}

void parse_size(std::istringstream& ls, const std::string& name, size_t lineno, TileMapText& t) {
  long long a = -1, b = -1, c = -1;
  if (!(ls >> a >> b >> c)) fail(name, lineno, "expected 'size WIDTH DEPTH HEIGHT'");
  expect_line_end(ls, name, lineno, "'size WIDTH DEPTH HEIGHT'");
  if (a <= 0 || b <= 0 || c <= 0) fail(name, lineno, "size must be positive (empty world)");
  if (a > kMaxWorldAxis || b > kMaxWorldAxis || c + 2 > kMaxWorldAxis)
    fail(name, lineno, "size " + std::to_string(a) + " x " + std::to_string(b) + " x " + std::to_string(c) +
                           " exceeds the div format's 255 voxels per axis (height + 2 for floor and ceiling)");
  // The portal build's time grows with the world's volume (a legal 255 x 255 x 253 map takes
  // minutes before the atlas limit stops it): a stated bound, checked before any work.
  const uint64_t volume = uint64_t(a) * uint64_t(b) * uint64_t(c + 2);
  if (volume > kMaxTileMapVoxels)
    fail(name, lineno, "size " + std::to_string(a) + " x " + std::to_string(b) + " x " + std::to_string(c) + " makes " +
                           std::to_string(volume) + " voxels with floor and ceiling, more than the limit of " +
                           std::to_string(kMaxTileMapVoxels));
  t.W = uint32_t(a), t.D = uint32_t(b), t.H = uint32_t(c);
}

// 'material CHAR NAME R G B [glass IOR]': a new material, or one replacing a default
void parse_material(std::istringstream& ls, const std::string& name, size_t lineno, World& w, std::string& chars) {
  std::string c, mname;
  float r, g, b;
  if (!(ls >> c >> mname >> r >> g >> b) || c.size() != 1)
    fail(name, lineno, "expected 'material CHAR NAME R G B [glass IOR]'");
  // A colour is a reflectance, and a glass's its transmittance per voxel: within [0, 1]. Above 1
  // it amplifies light (a glass filter of 3e38 made its pixels +inf, exit 0: an outside sweep)
  if (!(r >= 0.0f && r <= 1.0f && g >= 0.0f && g <= 1.0f && b >= 0.0f && b <= 1.0f))
    fail(name, lineno, "material colour must be within [0, 1] (a reflectance, or glass's transmittance per voxel)");
  if (c[0] == '.' || c[0] == 'E' || c[0] == 'L' || c[0] == ' ') fail(name, lineno, "'" + c + "' is reserved");
  WallMaterial m{mname, glm::vec3(r, g, b), false, 1.5f, glm::vec3(1.0f)};
  std::string opt;
  if (ls >> opt) {
    if (opt != "glass" || !(ls >> m.ior) || !(m.ior > 0.0f) || !std::isfinite(m.ior))
      fail(name, lineno, "expected 'glass IOR' (a positive finite number) after the colour");
    m.glass = true;
    m.filter = m.color;
    expect_line_end(ls, name, lineno, "'glass IOR'");
  }
  const size_t at = chars.find(c[0]);
  if (at != std::string::npos) {
    w.materials[at] = m;
  } else {
    chars.push_back(c[0]);
    w.materials.push_back(m);
  }
}

// The header's lines (comments, size, materials) up to 'map', then the rows
TileMapText read_tile_map(std::string_view text, const std::string& name, World& w, std::string& chars) {
  TileMapText t;
  bool have_size = false, in_map = false;
  size_t lineno = 0;
  std::string line;
  std::istringstream in{std::string(text)};
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (in_map) {
      if (line.empty() && t.rows.size() == t.D) continue;
      t.rows.push_back(line);
      t.row_lines.push_back(lineno);
      continue;
    }
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "size") {
      // A second size replaced the first without a word (the rows then failed on the second's
      // count, a confusing message): refused, as the block maps' 'scale' given twice is
      if (have_size) fail(name, lineno, "'size' given twice");
      parse_size(ls, name, lineno, t);
      have_size = true;
    } else if (key == "material") {
      parse_material(ls, name, lineno, w, chars);
    } else if (key == "map") {
      if (!have_size) fail(name, lineno, "'map' before 'size'");
      expect_line_end(ls, name, lineno, "'map'");  // trailing text was ignored (an outside sweep)
      in_map = true;
    } else {
      fail(name, lineno, "unknown keyword '" + printable(key) + "'");
    }
  }
  if (!have_size) fail(name, 0, "no 'size' line (empty world)");
  if (!in_map) fail(name, 0, "no 'map' section");
  // A wrong number of rows names the line where the map ends (too few) or its first extra row
  if (t.rows.size() != t.D)
    fail(name, t.rows.size() > t.D ? t.row_lines[t.D] : lineno,
         "expected " + std::to_string(t.D) + " map rows, found " + std::to_string(t.rows.size()));
  return t;
}

// The voxels: each tile a column of its material between the floor and the ceiling; the eye and
// the lights' tiles noted
void fill_voxels(const TileMapText& t, const std::string& name, const std::string& chars, World& w,
                 std::optional<glm::ivec2>& eye_tile, std::vector<glm::ivec2>& light_tiles) {
  const uint32_t W = t.W, D = t.D, H = t.H;
  w.dims = glm::uvec3(W, H + 2, D);
  w.voxels.assign(w.voxel_count(), kEmpty);
  for (uint32_t z = 0; z < D; ++z) {
    const std::string& r = t.rows[z];
    if (r.size() != W)
      fail(name, t.row_lines[z], "row has " + std::to_string(r.size()) + " characters, expected " + std::to_string(W) +
                                     " (ragged map)");
    for (uint32_t x = 0; x < W; ++x) {
      const char c = r[x];
      uint16_t m = kEmpty;
      if (c == '.') {
      } else if (c == 'E') {
        if (eye_tile) fail(name, t.row_lines[z], "a second eye 'E' at column " + std::to_string(x + 1));
        eye_tile = glm::ivec2{int(x), int(z)};
      } else if (c == 'L') {
        light_tiles.push_back({int(x), int(z)});
      } else {
        const size_t at = c ? chars.find(c) : std::string::npos;
        if (at == std::string::npos)
        {
          // A byte that does not print (a NUL cut the message, a tab or a UTF-8 byte printed raw)
          // is named by its value
          char shown[16];
          if (std::isprint(static_cast<unsigned char>(c)))
            std::snprintf(shown, sizeof shown, "'%c'", c);
          else
            std::snprintf(shown, sizeof shown, "byte 0x%02X", unsigned(static_cast<unsigned char>(c)));
          fail(name, t.row_lines[z], std::string("unknown character ") + shown + " at column " + std::to_string(x + 1));
        }
        m = uint16_t(at);
      }
      w.voxels[w.index(x, 0, z)] = kFloorMaterial;
      w.voxels[w.index(x, H + 1, z)] = kCeilingMaterial;
      for (uint32_t y = 1; y <= H; ++y) w.voxels[w.index(x, y, z)] = m;
    }
  }
}

// Camera: at the eye tile, half way up, looking along the longest free run of tiles.
void place_camera(World& w, glm::ivec2 eye_tile, const TileMapText& t) {
  const uint32_t W = t.W, D = t.D, H = t.H;
  const float mid = 1.0f + 0.5f * float(H);
  w.has_eye = true;
  const glm::ivec2 dirs[4] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  int best = 0, best_len = -1;
  for (int d = 0; d < 4; ++d) {
    int len = 0;
    glm::ivec2 p = eye_tile + dirs[d];
    while (p.x >= 0 && p.y >= 0 && p.x < int(W) && p.y < int(D) && w.voxels[w.index(p.x, 1, p.y)] == kEmpty) {
      ++len;
      p += dirs[d];
    }
    if (len > best_len) best_len = len, best = d;
  }
  w.camera.eye = glm::vec3(float(eye_tile.x) + 0.5f, mid, float(eye_tile.y) + 0.5f);
  w.camera.target = w.camera.eye + glm::vec3(float(dirs[best].x), 0.0f, float(dirs[best].y));
  w.camera.up = glm::vec3(0.0f, 1.0f, 0.0f);
  w.camera.vfov_degrees = 60.0f;
}

}  // namespace

World parse_tile_map(std::string_view text, const std::string& name, bool require_eye) {
  World w;
  w.name = name;
  std::string chars;
  default_materials(w, chars);
  const TileMapText t = read_tile_map(text, name, w, chars);
  std::optional<glm::ivec2> eye_tile;
  std::vector<glm::ivec2> light_tiles;
  fill_voxels(t, name, chars, w, eye_tile, light_tiles);
  if (require_eye && !eye_tile) fail(name, 0, "no eye 'E' in the map");
  if (eye_tile) place_camera(w, *eye_tile, t);
  for (const glm::ivec2& l : light_tiles)
    w.lights.push_back(glm::vec3(float(l.x) + 0.5f, float(t.H) + 0.5f, float(l.y) + 0.5f));
  warn_unused_lights(w);
  w.validate();
  return w;
}

World load_tile_map(const std::string& path, bool require_eye) {
  // A regular file within the size bound, with safe_io.h's line-break rule and no BOM.
  return parse_tile_map(normalize_text(read_input_file(path, "tile map")), path, require_eye);
}

std::string_view builtin_level_text() { return kBuiltinLevel; }
World builtin_level() { return parse_tile_map(kBuiltinLevel, "builtin", true); }

bool triangle_box_overlap(glm::dvec3 c, glm::dvec3 h, glm::dvec3 a, glm::dvec3 b, glm::dvec3 cc) {
  const glm::dvec3 v0 = a - c, v1 = b - c, v2 = cc - c;
  const glm::dvec3 e[3] = {v1 - v0, v2 - v1, v0 - v2};
  // Box axes.
  for (int i = 0; i < 3; ++i) {
    const double mn = std::min({v0[i], v1[i], v2[i]}), mx = std::max({v0[i], v1[i], v2[i]});
    if (mn > h[i] || mx < -h[i]) return false;
  }
  // Triangle normal: every vertex projected (their spread is the normal's rounding; one vertex
  // alone let a sliver's rounded normal reject boxes it passes through: an outside sweep's find)
  const glm::dvec3 n = glm::cross(e[0], e[1]);
  {
    const double d0 = glm::dot(n, v0), d1 = glm::dot(n, v1), d2 = glm::dot(n, v2);
    const double r = h.x * std::abs(n.x) + h.y * std::abs(n.y) + h.z * std::abs(n.z);
    if (std::min({d0, d1, d2}) > r || std::max({d0, d1, d2}) < -r) return false;
  }
  // Edge x box-axis cross products.
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      glm::dvec3 axis(0.0);
      axis[j] = 1.0;
      const glm::dvec3 l = glm::cross(axis, e[i]);
      const double p0 = glm::dot(l, v0), p1 = glm::dot(l, v1), p2 = glm::dot(l, v2);
      const double r = h.x * std::abs(l.x) + h.y * std::abs(l.y) + h.z * std::abs(l.z);
      if (std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r) return false;
    }
  return true;
}

void warn_unused_lights(const World& w) {
  if (w.lights.size() > 2)
    std::cerr << "warning: world '" << w.name << "': " << w.lights.size()
              << " lights; the portal renderer shades with the first two (two shadow rays a pixel)\n";
}

World voxelize(const Scene& scene, uint32_t resolution) {
  scene.validate();  // a scene made in code: its indices and coordinates checked before they are read
  if (resolution < 1 || resolution > kMaxWorldAxis - 2)
    throw Error("voxelize: resolution " + std::to_string(resolution) + " outside 1 .. 253 (8-bit div format)");
  const Bounds b = scene.bounds(0.0f);
  if (b.empty() || scene.triangle_count() == 0) throw Error("voxelize: scene '" + scene.name + "' has no triangles (empty world)");
  World w;
  w.name = scene.name;
  const glm::vec3 ext = b.extent();
  const float longest = std::max({ext.x, ext.y, ext.z});
  // The grid's least extent (2^-40) for the portal's world too: a model 1e-16 across was drawn as
  // one flat colour with exit 0 (its voxels and the camera's rays at that scale round past each
  // other: an outside sweep)
  if (longest > 0.0f && longest < shared::kDomainMinExtent) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.3g", double(longest));
    throw Error("voxelize: scene '" + scene.name + "' spans only " + buf +
                " (its box's largest side): below 2^-40 = 9.1e-13 its voxels and the camera's rays round past "
                "each other; scale the model up");
  }
  w.voxel_size = longest > 0.0f ? longest / float(resolution) : 1.0f;
  for (int a = 0; a < 3; ++a)
    w.dims[a] = std::clamp(uint32_t(std::ceil(ext[a] / w.voxel_size - 1e-4f)), 1u, resolution) + 2;
  w.origin = b.lo - glm::vec3(w.voxel_size);
  w.voxels.assign(w.voxel_count(), kEmpty);
  for (const Material& m : scene.materials) w.materials.push_back({m.name, m.diffuse, false, 1.5f, glm::vec3(1.0f)});
  if (w.materials.empty()) w.materials.push_back({"default", glm::vec3(0.8f), false, 1.5f, glm::vec3(1.0f)});
  if (w.materials.size() > shared::kPortalMaxMaterial + 1) throw Error("voxelize: more than 32767 materials");
  // The test in voxel units about the world's origin, in double: world-space box centres a
  // million units from the origin rounded by up to half a voxel of a small model, whose surface
  // then fell between the boxes (an outside sweep: a teapot at x = 1e6 lost its handle); at a
  // scale of 1e-15 the float products underflowed and marked boxes the surface misses
  const glm::dvec3 half(0.5 * 1.0001);
  const glm::dvec3 origin(w.origin);
  const double inv_size = 1.0 / double(w.voxel_size);
  const auto local = [&](glm::vec3 p) { return (glm::dvec3(p) - origin) * inv_size; };
  for (size_t ii = 0; ii < scene.instances.size(); ++ii) {
    const Instance& inst = scene.instances[ii];
    const Mesh& mesh = scene.meshes[inst.mesh];
    const shared::Affine xf = shared::to_affine(inst.transform_at(0.0f));
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      const glm::uvec3 tri = mesh.triangles[t];
      const glm::vec3 p0 = shared::transform_point(xf, mesh.positions[tri.x]);
      const glm::vec3 p1 = shared::transform_point(xf, mesh.positions[tri.y]);
      const glm::vec3 p2 = shared::transform_point(xf, mesh.positions[tri.z]);
      const glm::dvec3 q0 = local(p0), q1 = local(p1), q2 = local(p2);
      const glm::dvec3 lo = glm::min(q0, glm::min(q1, q2)), hi = glm::max(q0, glm::max(q1, q2));
      glm::ivec3 vlo, vhi;
      for (int a = 0; a < 3; ++a) {
        vlo[a] = int(std::clamp(std::floor(lo[a]) - 1.0, 0.0, double(w.dims[a]) - 1.0));
        vhi[a] = int(std::clamp(std::floor(hi[a]) + 1.0, 0.0, double(w.dims[a]) - 1.0));
      }
      const uint16_t mat = uint16_t(t < mesh.materials.size() ? std::min<uint32_t>(mesh.materials[t], uint32_t(w.materials.size() - 1)) : 0);
      for (int z = vlo.z; z <= vhi.z; ++z)
        for (int y = vlo.y; y <= vhi.y; ++y)
          for (int x = vlo.x; x <= vhi.x; ++x) {
            uint16_t& v = w.voxels[w.index(x, y, z)];
            if (v != kEmpty) continue;
            const glm::dvec3 center = glm::dvec3(x, y, z) + 0.5;
            if (triangle_box_overlap(center, half, q0, q1, q2)) v = mat;
          }
    }
  }
  const Camera cam = scene.frame_camera();
  w.camera = cam;
  w.open_outside = true;
  w.background = scene.background;
  for (const Light& l : scene.lights)
    w.lights.push_back(l.directional ? cam.eye + l.position * (2.0f * longest) : l.position);
  // What the voxels leave out, said (it was dropped without a word: an outside sweep)
  if (scene.has_dynamic())
    std::cerr << "warning: voxelize: scene '" << scene.name
              << "': its moving instances are voxelized where they stand at t = 0 (the portal worlds are static)\n";
  if (std::any_of(scene.materials.begin(), scene.materials.end(), [](const Material& m) { return m.alpha_keyed(); }))
    std::cerr << "warning: voxelize: scene '" << scene.name
              << "': alpha-masked surfaces are voxelized solid (the voxels carry no mask)\n";
  warn_unused_lights(w);
  w.validate();
  return w;
}

}  // namespace gridrt::portal

namespace gridrt::portal {

namespace {

// Split the tile rectangle [x0, x1) x [z0, z1) (walls on its border already) by one wall line with
// one or two doorways, recursively, until rooms are 6..13 tiles wide; pillars in larger rooms.
void split_rooms(std::vector<std::string>& rows, std::mt19937& rng, int x0, int z0, int x1, int z1) {
  const int w = x1 - x0, d = z1 - z0;
  auto uniform = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  const bool vertical = w > d ? true : w < d ? false : uniform(0, 1) == 1;
  const int span = vertical ? w : d;
  if (span < 14) {
    if (w >= 7 && d >= 7 && uniform(0, 2) == 0) rows[size_t(z0 + d / 2)][size_t(x0 + w / 2)] = char('0' + uniform(0, 9));
    return;
  }
  const int cut = (vertical ? x0 : z0) + uniform(6, span - 7);
  const char m = char('0' + uniform(0, 9));
  const int len = vertical ? d : w;
  for (int k = 0; k < len; ++k) {
    if (vertical) rows[size_t(z0 + k)][size_t(cut)] = m;
    else rows[size_t(cut)][size_t(x0 + k)] = m;
  }
  const int doors = len > 20 ? 2 : 1;
  for (int n = 0; n < doors; ++n) {
    const int at = uniform(0, len - 1), width = uniform(1, 2);
    for (int k = at; k < std::min(len, at + width); ++k) {
      if (vertical) rows[size_t(z0 + k)][size_t(cut)] = '.';
      else rows[size_t(cut)][size_t(x0 + k)] = '.';
    }
  }
  if (vertical) {
    split_rooms(rows, rng, x0, z0, cut, z1);
    split_rooms(rows, rng, cut + 1, z0, x1, z1);
  } else {
    split_rooms(rows, rng, x0, z0, x1, cut);
    split_rooms(rows, rng, x0, cut + 1, x1, z1);
  }
}

}  // namespace

std::string generated_level_text(uint32_t width, uint32_t depth, uint32_t height, uint32_t seed) {
  if (width < 5 || depth < 5 || height < 1)
    throw Error("generated level: " + std::to_string(width) + " x " + std::to_string(depth) + " x " + std::to_string(height) +
                " is too small (at least 5 x 5 tiles, 1 voxel high)");
  if (width > kMaxWorldAxis || depth > kMaxWorldAxis || height + 2 > kMaxWorldAxis)
    throw Error("generated level: " + std::to_string(width) + " x " + std::to_string(depth) + " x " + std::to_string(height) +
                " breaks the div format's " + std::to_string(kMaxWorldAxis) +
                " voxels per axis (width and depth at most 255, height at most 253: floor and ceiling are voxels)");
  std::mt19937 rng(seed);
  std::vector<std::string> rows(depth, std::string(width, '.'));
  for (uint32_t x = 0; x < width; ++x) rows[0][x] = rows[depth - 1][x] = '1';
  for (uint32_t z = 0; z < depth; ++z) rows[z][0] = rows[z][width - 1] = '1';
  split_rooms(rows, rng, 1, 1, int(width) - 1, int(depth) - 1);
  // The eye in the first empty tile from the top-left corner; two lights in empty tiles further on.
  int placed = 0;
  for (uint32_t z = 1; z + 1 < depth && placed < 3; ++z)
    for (uint32_t x = 1; x + 1 < width && placed < 3; ++x) {
      if (rows[z][x] != '.') continue;
      if (placed == 0) rows[z][x] = 'E', ++placed;
      else if ((placed == 1 && x + z >= 4) || (placed == 2 && x + z >= (width + depth) / 3)) rows[z][x] = 'L', ++placed;
    }
  std::string text = "# generated level (gridrt portal): seed " + std::to_string(seed) + "\nsize " + std::to_string(width) +
                     " " + std::to_string(depth) + " " + std::to_string(height) + "\nmap\n";
  for (const std::string& r : rows) text += r + "\n";
  return text;
}

World generated_level(uint32_t width, uint32_t depth, uint32_t height, uint32_t seed) {
  // Named as it is asked for: two seeds' levels are two names (the seed was dropped); seed 1 is
  // the default and unnamed
  return parse_tile_map(generated_level_text(width, depth, height, seed),
                        "gen:" + std::to_string(width) + "x" + std::to_string(depth) + "x" + std::to_string(height) +
                            (seed != 1 ? ":" + std::to_string(seed) : std::string()),
                        true);
}

bool parse_generated_spec(const std::string& spec, const std::string& prefix, uint32_t& w, uint32_t& d, uint32_t& h,
                          uint32_t& seed) {
  if (spec.compare(0, prefix.size(), prefix) != 0) return false;
  size_t at = prefix.size();
  auto number = [&](uint32_t& out) {
    const size_t start = at;
    uint64_t v = 0;
    while (at < spec.size() && spec[at] >= '0' && spec[at] <= '9' && at - start < 10) v = v * 10 + uint64_t(spec[at++] - '0');
    if (at == start || v > 0xffffffffull || (at < spec.size() && spec[at] >= '0' && spec[at] <= '9')) return false;
    out = uint32_t(v);
    return true;
  };
  auto expect = [&](char c) { return at < spec.size() && spec[at] == c ? (++at, true) : false; };
  seed = 1;
  if (!number(w) || !expect('x') || !number(d) || !expect('x') || !number(h)) return false;
  if (at == spec.size()) return true;
  return expect(':') && number(seed) && at == spec.size();
}

World generated_level_spec(const std::string& spec) {
  // gen:WxDxH or gen:WxDxH:SEED
  uint32_t w = 0, d = 0, h = 0, seed = 1;
  if (!parse_generated_spec(spec, "gen:", w, d, h, seed))
    throw Error("generated level '" + spec + "': expected gen:WIDTHxDEPTHxHEIGHT[:SEED] (tiles, tiles, voxels; "
                "each a whole number of at most 4294967295)");
  return generated_level(w, d, h, seed);
}

}  // namespace gridrt::portal
