// instance.cpp: block maps, flatten, the instanced build and renderer (instance.h).
#include "gridrt/reference/portal/instance.h"

#include "gridrt/common/util.h"
#include <algorithm>
#include <iostream>
#include <atomic>
#include <chrono>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include "gridrt/common/camera.h"
#include "gridrt/common/parallel.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/shared/portal.h"

namespace gridrt::portal {

namespace sh = gridrt::shared;

namespace {

// The blocks of builtin:blocks and gen-blocks (8 fine voxels per tile).
constexpr std::string_view kBlockHeader = R"MAP(scale 8
material b brick 0.62 0.30 0.22
material m mortar 0.72 0.70 0.64
material s stone 0.52 0.52 0.56
material w wood 0.55 0.40 0.22
# A brick wall: courses of bricks around a mortar core, the joints recessed by one voxel.
block brick
box 1 0 1 7 8 7 m
box 0 0 0 3 3 8 b
box 4 0 0 8 3 8 b
box 0 4 0 8 7 3 b
box 0 4 4 8 7 8 b
end
# A stone wall along x with a window.
block window
box 0 0 2 8 8 6 s
box 2 3 2 6 6 6 .
box 2 2 1 6 3 7 s
end
# A pillar with a base and a capital.
block pillar
box 2 0 2 6 8 6 s
box 1 0 1 7 1 7 s
box 1 7 1 7 8 7 s
end
# A crate on the floor.
block crate
box 1 0 1 7 5 7 w
box 0 0 0 8 1 8 w
end
tile B brick
tile W window
tile P pillar
tile C crate
)MAP";

constexpr std::string_view kBuiltinBlocksMap = R"MAP(size 28 28 2
map
BBBBBBBBBBBBBBBBBBBBBBBBBBBB
B..........B...............B
B..E.......W...............B
B..........B.....P....P....B
B....L.....B...............B
B..........................B
B..........B.....P....P....B
B..C.......B...............B
B..........B...............B
BBBBB.BBBBBBBBWBBBB.BBBBBBBB
B......B...................B
B......B.......C...........B
B......B...................B
B......W.......P.......L...B
B......B...................B
B..................C.......B
B......B...................B
BBBWBBBBBBBBB.BBBBBBBBWBBBBB
B.............B............B
B..P....P.....B............B
B.............B....CC......B
B.............W............B
B.............B............B
B..P....P.....B.......P....B
B.............B............B
B..........................B
B.............B............B
BBBBBBBBBBBBBBBBBBBBBBBBBBBB
)MAP";

[[noreturn]] void fail(const std::string& name, size_t line, const std::string& what) {
  throw Error("block map " + name + (line ? ":" + std::to_string(line) : std::string()) + ": " + what);
}

// A line's end: nothing but blanks after what it holds (trailing junk was ignored)
void expect_line_end(std::istringstream& ls, const std::string& name, size_t lineno, const std::string& what) {
  std::string extra;
  if (ls >> extra) fail(name, lineno, "unexpected '" + printable(extra) + "' after " + what);
}

bool reserved(char c) { return c == '.' || c == 'E' || c == 'L' || c == ' '; }

}  // namespace

uint32_t InstancedWorld::scale_log2() const {
  uint32_t k = 0;
  while ((1u << k) < scale) ++k;
  return k;
}

void InstancedWorld::validate() const {
  if (scale != 2 && scale != 4 && scale != 8 && scale != 16)
    throw Error("block world '" + top.name + "': scale " + std::to_string(scale) + " (2, 4, 8 or 16 fine voxels per tile)");
  top.validate();
  const glm::uvec3 f = fine_dims();
  const uint64_t fine = uint64_t(f.x) * f.y * f.z;
  if (fine > kMaxInstancedFineVoxels)
    throw Error("block world '" + top.name + "': " + std::to_string(f.x) + " x " + std::to_string(f.y) + " x " +
                std::to_string(f.z) + " fine voxels, more than the 2^29 a hit record's voxel index holds");
  if (blocks.empty()) throw Error("block world '" + top.name + "': no blocks");
  if (blocks.size() > kMaxBlocks)
    throw Error("block world '" + top.name + "': " + std::to_string(blocks.size()) + " blocks, at most " +
                std::to_string(kMaxBlocks));
  if (uint64_t(instance_base) + blocks.size() != top.materials.size())
    throw Error("block world '" + top.name + "': the instance materials must be the last of the material table");
  const size_t n = size_t(scale) * scale * scale;
  for (const Block& b : blocks) {
    if (b.voxels.size() != n) throw Error("block '" + b.name + "': voxel array size does not match the scale");
    for (uint16_t v : b.voxels) {
      if (v == kEmpty) continue;
      if (v >= instance_base)
        throw Error("block '" + b.name + "': holds an instance (blocks inside blocks are not supported)");
      if (top.materials[v].glass) throw Error("block '" + b.name + "': glass is not supported in block maps");
    }
  }
  for (uint16_t v : top.voxels)
    if (v != kEmpty && top.materials[v].glass) throw Error("block world '" + top.name + "': glass is not supported in block maps");
}

bool is_block_map(std::string_view text) {
  std::istringstream in{std::string(text)};
  std::string line;
  while (std::getline(in, line)) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    return key == "scale";
  }
  return false;
}

InstancedWorld parse_block_map(std::string_view text, const std::string& name, bool require_eye) {
  InstancedWorld iw;
  World& w = iw.top;
  w.name = name;
  // The tile maps' default materials ('0'..'9', 'G' glass, floor 11, ceiling 12).
  w.materials = parse_tile_map("size 1 1 1\nmap\n.\n", "defaults", false).materials;
  std::string chars = "0123456789G";
  chars.resize(w.materials.size(), '\0');
  constexpr uint16_t kFloor = 11, kCeiling = 12;
  uint32_t W = 0, D = 0, H = 0;
  bool have_scale = false, have_size = false, in_map = false;
  std::vector<std::string> rows;
  std::vector<size_t> row_lines;
  struct BoxLine {
    size_t line;
    glm::ivec3 lo, hi;
    char c;
  };
  struct BlockDef {
    std::string name;
    size_t line;
    std::vector<BoxLine> boxes;
  };
  std::vector<BlockDef> defs;
  std::map<char, std::pair<std::string, size_t>> tiles;  // character -> block name, line
  bool in_block = false;
  size_t lineno = 0;
  std::string line;
  std::istringstream in{std::string(text)};
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (in_map) {
      if (line.empty() && rows.size() == D) continue;
      rows.push_back(line);
      row_lines.push_back(lineno);
      continue;
    }
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (in_block) {
      if (key == "end") {
        expect_line_end(ls, name, lineno, "'end'");  // trailing text was ignored (an outside sweep)
        in_block = false;
      } else if (key == "box") {
        long long v[6];
        std::string c;
        for (long long& x : v)
          if (!(ls >> x)) fail(name, lineno, "expected 'box X0 Y0 Z0 X1 Y1 Z1 MATERIAL'");
        if (!(ls >> c) || c.size() != 1) fail(name, lineno, "expected 'box X0 Y0 Z0 X1 Y1 Z1 MATERIAL'");
        expect_line_end(ls, name, lineno, "'box X0 Y0 Z0 X1 Y1 Z1 MATERIAL'");
        if (!have_scale) fail(name, lineno, "'box' before 'scale'");
        for (int a = 0; a < 3; ++a)
          if (v[a] < 0 || v[a + 3] > (long long)iw.scale || v[a] >= v[a + 3])
            fail(name, lineno, "box outside the block's " + std::to_string(iw.scale) + " voxels per axis (or empty)");
        defs.back().boxes.push_back({lineno, glm::ivec3(int(v[0]), int(v[1]), int(v[2])),
                                     glm::ivec3(int(v[3]), int(v[4]), int(v[5])), c[0]});
      } else {
        fail(name, lineno, "unknown keyword '" + printable(key) + "' in block '" + printable(defs.back().name) + "' (box or end)");
      }
      continue;
    }
    if (key == "scale") {
      long long s = 0;
      if (!(ls >> s)) fail(name, lineno, "expected 'scale N'");
      expect_line_end(ls, name, lineno, "'scale N'");
      // Once: a block's boxes are checked against the scale in force where they are read
      if (have_scale) fail(name, lineno, "'scale' given twice");
      if (s != 2 && s != 4 && s != 8 && s != 16) fail(name, lineno, "scale must be 2, 4, 8 or 16 fine voxels per tile");
      iw.scale = uint32_t(s);
      have_scale = true;
    } else if (key == "size") {
      long long a = -1, b = -1, c = -1;
      if (!(ls >> a >> b >> c)) fail(name, lineno, "expected 'size WIDTH DEPTH HEIGHT' (tiles)");
      expect_line_end(ls, name, lineno, "'size WIDTH DEPTH HEIGHT'");
      if (a <= 0 || b <= 0 || c <= 0) fail(name, lineno, "size must be positive (empty world)");
      if (a > kMaxWorldAxis || b > kMaxWorldAxis || c + 2 > kMaxWorldAxis)
        fail(name, lineno, "size " + std::to_string(a) + " x " + std::to_string(b) + " x " + std::to_string(c) +
                               " exceeds the top level's 255 tiles per axis (height + 2 for floor and ceiling)");
      W = uint32_t(a), D = uint32_t(b), H = uint32_t(c);
      if (!have_scale) fail(name, lineno, "'size' before 'scale'");
      const uint64_t fine = uint64_t(W) * (H + 2) * D * iw.scale * iw.scale * iw.scale;
      if (fine > kMaxInstancedFineVoxels)
        fail(name, lineno, "size " + std::to_string(W) + " x " + std::to_string(D) + " x " + std::to_string(H) +
                               " at scale " + std::to_string(iw.scale) + " makes " + std::to_string(fine) +
                               " fine voxels, more than the 2^29 a hit record's voxel index holds");
      have_size = true;
    } else if (key == "material") {
      std::string c, mname, opt;
      float r, g, b;
      if (!(ls >> c >> mname >> r >> g >> b) || c.size() != 1) fail(name, lineno, "expected 'material CHAR NAME R G B'");
      // Within [0, 1], a reflectance (as tile maps' colours: world.cpp)
      if (!(r >= 0.0f && r <= 1.0f && g >= 0.0f && g <= 1.0f && b >= 0.0f && b <= 1.0f))
        fail(name, lineno, "material colour must be within [0, 1] (a reflectance)");
      if (ls >> opt) fail(name, lineno, "glass is not supported in block maps");
      if (reserved(c[0])) fail(name, lineno, "'" + c + "' is reserved");
      if (tiles.count(c[0])) fail(name, lineno, "'" + c + "' is a tile's character");
      WallMaterial m{mname, glm::vec3(r, g, b), false, 1.5f, glm::vec3(1.0f)};
      const size_t at = chars.find(c[0]);
      if (at != std::string::npos) w.materials[at] = m;
      else chars.push_back(c[0]), w.materials.push_back(m);
    } else if (key == "block") {
      std::string bname, extra;
      if (!(ls >> bname) || (ls >> extra)) fail(name, lineno, "expected 'block NAME'");
      // Names become file names in `portal export`: letters, digits, '_' and '-' only.
      if (bname.size() > 32 || !std::all_of(bname.begin(), bname.end(), [](char ch) {
            return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-';
          }))
        fail(name, lineno, "block name '" + bname + "': 1 to 32 letters, digits, '_' or '-'");
      for (const BlockDef& d : defs)
        if (d.name == bname) fail(name, lineno, "block '" + bname + "' defined twice");
      if (defs.size() >= kMaxBlocks) fail(name, lineno, "more than " + std::to_string(kMaxBlocks) + " blocks");
      defs.push_back({bname, lineno, {}});
      in_block = true;
    } else if (key == "tile") {
      std::string c, bname;
      if (!(ls >> c >> bname) || c.size() != 1) fail(name, lineno, "expected 'tile CHAR BLOCK'");
      expect_line_end(ls, name, lineno, "'tile CHAR BLOCK'");
      if (reserved(c[0])) fail(name, lineno, "'" + c + "' is reserved");
      if (chars.find(c[0]) != std::string::npos) fail(name, lineno, "'" + c + "' is a material's character");
      if (tiles.count(c[0])) fail(name, lineno, "tile '" + c + "' defined twice");
      tiles[c[0]] = {bname, lineno};
    } else if (key == "map") {
      if (!have_scale) fail(name, lineno, "'map' before 'scale'");
      if (!have_size) fail(name, lineno, "'map' before 'size'");
      expect_line_end(ls, name, lineno, "'map'");
      in_map = true;
    } else {
      fail(name, lineno, "unknown keyword '" + printable(key) + "'");
    }
  }
  if (in_block) fail(name, 0, "block '" + printable(defs.back().name) + "' has no 'end'");
  if (!have_scale) fail(name, 0, "no 'scale' line");
  if (!have_size) fail(name, 0, "no 'size' line (empty world)");
  if (!in_map) fail(name, 0, "no 'map' section");
  if (rows.size() != D) fail(name, 0, "expected " + std::to_string(D) + " map rows, found " + std::to_string(rows.size()));
  // Tiles name blocks; blocks hold materials only.
  std::map<char, uint32_t> tile_block;
  std::vector<std::string> used;  // block names in the order their instance materials take
  for (const auto& [c, ref] : tiles) {
    const std::string& block = ref.first;  // a named copy: clang 14 does not capture structured bindings
    const auto it = std::find_if(defs.begin(), defs.end(), [&](const BlockDef& d) { return d.name == block; });
    if (it == defs.end()) fail(name, ref.second, "tile '" + std::string(1, c) + "' references an unknown block '" + ref.first + "'");
    tile_block[c] = uint32_t(it - defs.begin());
  }
  if (defs.empty()) fail(name, 0, "no blocks (a plain tile map needs no 'scale')");
  iw.instance_base = uint32_t(w.materials.size());
  const uint32_t S = iw.scale;
  for (const BlockDef& d : defs) {
    Block b;
    b.name = d.name;
    b.voxels.assign(size_t(S) * S * S, kEmpty);
    for (const BoxLine& bx : d.boxes) {
      uint16_t m = kEmpty;
      if (bx.c != '.') {
        if (tiles.count(bx.c))
          fail(name, bx.line, "block '" + d.name + "' uses tile '" + std::string(1, bx.c) +
                                  "': blocks inside blocks are not supported");
        const size_t at = chars.find(bx.c);
        if (at == std::string::npos || bx.c == '\0')
          fail(name, bx.line, std::string("unknown material '") + bx.c + "' in block '" + d.name + "'");
        if (w.materials[at].glass) fail(name, bx.line, "glass is not supported in block maps");
        m = uint16_t(at);
      }
      for (int z = bx.lo.z; z < bx.hi.z; ++z)
        for (int y = bx.lo.y; y < bx.hi.y; ++y)
          for (int x = bx.lo.x; x < bx.hi.x; ++x) b.voxels[size_t(x) + S * (size_t(y) + S * size_t(z))] = m;
    }
    iw.blocks.push_back(std::move(b));
    w.materials.push_back({"block " + d.name, glm::vec3(0.5f), false, 1.5f, glm::vec3(1.0f)});
  }
  // The top level, as a tile map: floor, ceiling, walls and instances over the full height.
  w.dims = glm::uvec3(W, H + 2, D);
  const uint64_t fine = uint64_t(W) * (H + 2) * D * S * S * S;
  if (fine > kMaxInstancedFineVoxels)
    fail(name, 0, "size " + std::to_string(W) + " x " + std::to_string(D) + " x " + std::to_string(H) + " at scale " +
                      std::to_string(S) + " makes " + std::to_string(fine) + " fine voxels, more than the 2^29 a hit "
                      "record's voxel index holds");
  w.voxels.assign(w.voxel_count(), kEmpty);
  std::optional<glm::ivec2> eye;
  std::vector<glm::ivec2> lights;
  for (uint32_t z = 0; z < D; ++z) {
    const std::string& r = rows[z];
    if (r.size() != W)
      fail(name, row_lines[z], "row has " + std::to_string(r.size()) + " characters, expected " + std::to_string(W) +
                                   " (ragged map)");
    for (uint32_t x = 0; x < W; ++x) {
      const char c = r[x];
      uint16_t m = kEmpty;
      if (c == '.') {
      } else if (c == 'E') {
        if (eye) fail(name, row_lines[z], "a second eye 'E' at column " + std::to_string(x + 1));
        eye = glm::ivec2(int(x), int(z));
      } else if (c == 'L') {
        lights.push_back({int(x), int(z)});
      } else if (tile_block.count(c)) {
        m = uint16_t(iw.instance_base + tile_block[c]);
      } else {
        const size_t at = c ? chars.find(c) : std::string::npos;
        if (at == std::string::npos)
          fail(name, row_lines[z], std::string("unknown character '") + c + "' at column " + std::to_string(x + 1));
        if (w.materials[at].glass) fail(name, row_lines[z], "glass is not supported in block maps");
        m = uint16_t(at);
      }
      w.voxels[w.index(x, 0, z)] = kFloor;
      w.voxels[w.index(x, H + 1, z)] = kCeiling;
      for (uint32_t y = 1; y <= H; ++y) w.voxels[w.index(x, y, z)] = m;
    }
  }
  if (require_eye && !eye) fail(name, 0, "no eye 'E' in the map");
  if (eye) {
    // As tile maps: at the eye tile, half way up, along the longest free run of tiles.
    w.has_eye = true;
    const glm::ivec2 dirs[4] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    int best = 0, best_len = -1;
    for (int d = 0; d < 4; ++d) {
      int len = 0;
      for (glm::ivec2 p = *eye + dirs[d];
           p.x >= 0 && p.y >= 0 && p.x < int(W) && p.y < int(D) && w.voxels[w.index(p.x, 1, p.y)] == kEmpty; p += dirs[d])
        ++len;
      if (len > best_len) best_len = len, best = d;
    }
    w.camera.eye = glm::vec3(float(eye->x) + 0.5f, 1.0f + 0.5f * float(H), float(eye->y) + 0.5f);
    w.camera.target = w.camera.eye + glm::vec3(float(dirs[best].x), 0.0f, float(dirs[best].y));
    w.camera.up = glm::vec3(0.0f, 1.0f, 0.0f);
    w.camera.vfov_degrees = 60.0f;
  }
  for (const glm::ivec2& l : lights) w.lights.push_back(glm::vec3(float(l.x) + 0.5f, float(H) + 0.5f, float(l.y) + 0.5f));
  warn_unused_lights(w);
  iw.validate();
  return iw;
}

InstancedWorld load_block_map(const std::string& path, bool require_eye) {
  return parse_block_map(normalize_text(read_input_file(path, "block map")), path, require_eye);
}

std::string_view builtin_blocks_text() {
  static const std::string text = "# gridrt portal block map (docs/PORTAL.md, \"Block maps\"): the built-in block level.\n" +
                                  std::string(kBlockHeader) + std::string(kBuiltinBlocksMap);
  return text;
}

InstancedWorld builtin_blocks() { return parse_block_map(builtin_blocks_text(), "builtin:blocks", true); }

std::string generated_blocks_text(uint32_t width, uint32_t depth, uint32_t height, uint32_t seed) {
  // The generated level's rows (its limits checked there), inner walls made of blocks: digit d is
  // brick (d % 4 = 0, 1), window (2) or pillar (3); the outer wall stays brick.
  const std::string level = generated_level_text(width, depth, height, seed);
  const size_t at = level.find("\nmap\n");
  std::string rows = level.substr(at + 5);
  for (char& c : rows)
    if (c >= '0' && c <= '9') c = "BBWP"[(c - '0') % 4];
  return "# generated block level (gridrt portal): seed " + std::to_string(seed) + "\n" + std::string(kBlockHeader) +
         "size " + std::to_string(width) + " " + std::to_string(depth) + " " + std::to_string(height) + "\nmap\n" + rows;
}

InstancedWorld generated_blocks_spec(const std::string& spec) {
  uint32_t w = 0, d = 0, h = 0, seed = 1;
  if (!parse_generated_spec(spec, "gen-blocks:", w, d, h, seed))
    throw Error("generated block level '" + spec + "': expected gen-blocks:WIDTHxDEPTHxHEIGHT[:SEED] (tiles; "
                "each a whole number of at most 4294967295)");
  if (w < 5 || d < 5 || h < 1 || w > kMaxWorldAxis || d > kMaxWorldAxis || h + 2 > kMaxWorldAxis)
    throw Error("generated block level '" + spec + "': width and depth 5 .. 255 tiles, height 1 .. 253 tiles");
  return parse_block_map(generated_blocks_text(w, d, h, seed), spec, true);
}

World flatten(const InstancedWorld& iw) {
  const uint32_t S = iw.scale;
  const glm::uvec3 f = iw.fine_dims();
  for (int a = 0; a < 3; ++a)
    if (f[a] > kMaxWorldAxis)
      throw Error("flatten '" + iw.top.name + "': " + std::to_string(f[a]) + " fine voxels along axis " + "xyz"[a] +
                  ", a plain world allows at most " + std::to_string(kMaxWorldAxis) + " (only the instanced world fits)");
  World w = iw.top;
  w.name = iw.top.name + " (flattened)";
  w.dims = f;
  w.voxel_size = iw.top.voxel_size / float(S);
  w.voxels.assign(w.voxel_count(), kEmpty);
  for (uint32_t z = 0; z < f.z; ++z)
    for (uint32_t y = 0; y < f.y; ++y)
      for (uint32_t x = 0; x < f.x; ++x) {
        const uint16_t t = iw.top.voxels[iw.top.index(x / S, y / S, z / S)];
        uint16_t m = t;
        if (t != kEmpty && t >= iw.instance_base)
          m = iw.blocks[t - iw.instance_base].voxels[(x % S) + S * ((y % S) + S * size_t(z % S))];
        w.voxels[w.index(x, y, z)] = m;
      }
  w.validate();
  return w;
}

namespace {

// Appends build q's divs, atlas rows and (returned) start map to p, div indices offset.
std::vector<uint16_t> append_build(PackedPortal& p, std::vector<uint8_t>& info, const PackedPortal& q, const std::string& what) {
  const uint32_t base = p.div_count, row0 = p.atlas_height;
  if (uint64_t(base) + q.div_count > sh::kPortalMaxDivs)
    throw Error("portal instancing: " + what + " brings the divs to " + std::to_string(base + q.div_count) +
                ", beyond the 32768 of 15-bit indices");
  if (uint64_t(row0) + q.atlas_height > 65536)
    throw Error("portal instancing: " + what + " brings the atlas to " + std::to_string(row0 + q.atlas_height) +
                " rows, beyond the 16-bit atlas coordinates (raise the atlas width)");
  auto remap = [&](uint16_t t) { return t < sh::kPortalWallBit ? uint16_t(t + base) : t; };
  for (uint16_t t : q.atlas) p.atlas.push_back(remap(t));
  p.atlas_height += q.atlas_height;
  for (uint32_t d = 0; d < q.div_count; ++d)
    for (uint32_t k = 0; k < 8; ++k) {
      const size_t idx = size_t(d) * 8 + k;
      const uint8_t* t = &q.info[((idx / q.info_width) * q.info_width + idx % q.info_width) * 4];
      uint8_t tx[4] = {t[0], t[1], t[2], t[3]};
      if (k < 6) {  // face origin: v moves down by the rows before
        const uint32_t v = (uint32_t(tx[1]) | (uint32_t(tx[3]) << 8)) + row0;
        tx[1] = uint8_t(v & 0xFF), tx[3] = uint8_t(v >> 8);
      }
      info.insert(info.end(), tx, tx + 4);
    }
  p.div_count = base + q.div_count;
  std::vector<uint16_t> start;
  for (uint16_t t : q.start) start.push_back(remap(t));
  return start;
}

}  // namespace

PortalBuild build_instanced(const InstancedWorld& iw, const PortalOptions& opt) {
  iw.validate();
  if (opt.mip_levels > 1)
    throw OptionsError("portal instancing: mip levels are not supported with instanced worlds (--flatten builds "
                       "the flat world, which takes them)");
  const auto t0 = std::chrono::steady_clock::now();
  const uint32_t S = iw.scale, k = iw.scale_log2();
  World top = iw.top;
  PortalOptions o = opt;
  o.mip_levels = 1;
  PortalBuild b = build_portal(std::move(top), o);
  PackedPortal& p = b.packed;
  // The top level's divs are traced in tile space: level nibble k.
  for (uint32_t d = 0; d < p.div_count; ++d) {
    const size_t idx = size_t(d) * 8 + 7;
    p.info[((idx / p.info_width) * p.info_width + idx % p.info_width) * 4 + 3] |= uint8_t(k << sh::kPortalLevelShift);
  }
  std::vector<uint8_t> info = p.info;
  info.resize(size_t(p.div_count) * 32);
  p.top_divs = p.div_count;
  std::vector<uint16_t> starts;
  for (size_t i = 0; i < iw.blocks.size(); ++i) {
    World bw;
    bw.name = iw.top.name + " block " + iw.blocks[i].name;
    bw.dims = glm::uvec3(S);
    bw.voxels = iw.blocks[i].voxels;
    bw.materials = iw.top.materials;
    const PortalBuild bb = build_portal(std::move(bw), o);
    const std::vector<uint16_t> st = append_build(p, info, bb.packed, "block '" + iw.blocks[i].name + "'");
    starts.insert(starts.end(), st.begin(), st.end());
    b.block_divs += bb.divs.size();
    b.stats.maximal += bb.stats.maximal, b.stats.candidates_evaluated += bb.stats.candidates_evaluated;
    b.stats.faces_chosen += bb.stats.faces_chosen;
  }
  // The blocks' start maps: atlas rows after the divs' rows.
  p.block_start = p.atlas_height * p.atlas_width;
  const uint64_t rows = (uint64_t(starts.size()) + p.atlas_width - 1) / p.atlas_width;
  if (p.atlas_height + rows > 65536)
    throw Error("portal instancing: the blocks' start maps bring the atlas beyond 65536 rows (raise the atlas width)");
  p.atlas.insert(p.atlas.end(), starts.begin(), starts.end());
  p.atlas_height += uint32_t(rows);
  p.atlas.resize(size_t(p.atlas_width) * p.atlas_height, uint16_t(sh::kPortalOutside));
  p.info_height = uint32_t((uint64_t(p.div_count) * 8 + p.info_width - 1) / p.info_width);
  info.resize(size_t(p.info_width) * p.info_height * 4, 0);
  p.info = std::move(info);
  p.scale_log2 = k;
  p.instance_base = iw.instance_base;
  p.blocks = uint32_t(iw.blocks.size());
  p.voxel_size = iw.top.voxel_size / float(S);  // rays are traced in fine voxel space
  b.stats.divs = p.div_count;
  b.stats.atlas_texels = p.atlas.size();
  b.stats.bytes = p.bytes();
  b.stats.seconds_total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return b;
}

glm::ivec3 instance_fine_voxel(const PackedPortal& p, const VoxelRay& r, uint32_t a, float num, float ad, glm::ivec3 tile) {
  return sh::portal_instance_fine_voxel(a, num, ad, r.org, r.dir, tile, p.scale_log2);
}

uint16_t block_start_texel(const PackedPortal& p, uint32_t m, glm::ivec3 tile, glm::ivec3 fine) {
  return p.atlas[sh::portal_block_start_index(p.block_start, m - p.instance_base, p.scale_log2, tile, fine)];
}

// ---- The renderer -----------------------------------------------------------------------------
// As render.cpp (same shading, same order of operations) with the instanced traversal's state:
// the div and, in a block div, its tile. No glass, no mip levels.

namespace {

enum Mode : uint32_t { kPrimary = 0, kShadowA = 1, kShadowB = 2, kDone = 3 };

struct IPixel {
  uint32_t mode = kPrimary;
  uint32_t div = 0;
  glm::ivec3 tile{0};
  VoxelRay ray;
  glm::vec3 point{0.0f}, normal{0.0f}, albedo{0.0f};
  uint32_t hit_div = 0;
  glm::ivec3 hit_tile{0};
  float light = 0.0f;
  glm::vec3 color{0.0f};
  uint32_t steps_primary = 0, steps_shadow = 0, iterations = 0, shadow_rays = 0;
  bool cut = false;  // past the iteration limit: ended as background (render.cpp end_if_cut)
};

struct IContext {
  const PortalBuild& build;
  const RenderOptions& opt;
  glm::vec3 lights[2];
};

void ifinish(const IContext& c, IPixel& s) {
  // render.cpp's finish with filter 1 and no coarse light (both exact).
  s.color = glm::vec3(1.0f) * s.albedo * (c.opt.ambient + (1.0f - c.opt.ambient) * 0.5f * s.light) + glm::vec3(0.0f);
  s.mode = kDone;
}

void ibegin_shadow(const IContext& c, IPixel& s, uint32_t i) {
  for (; i < 2; ++i) {
    const glm::vec3 to = c.lights[i] - s.point;
    if (glm::dot(to, s.normal) <= 0.0f) continue;
    s.ray.org = s.point;
    s.ray.dir = to;
    s.ray.tmin = 0.0f;
    s.ray.tmax = 1.0f;
    s.div = s.hit_div;
    s.tile = s.hit_tile;
    s.mode = kShadowA + i;
    ++s.shadow_rays;
    return;
  }
  ifinish(c, s);
}

}  // namespace

std::vector<glm::vec3> render_instanced(const PortalBuild& build, const Camera& camera, const RenderOptions& opt,
                                        RenderStats* stats) {
  if (opt.width == 0 || opt.height == 0) throw Error("portal render: image size must be at least 1 x 1");
  const auto t0 = std::chrono::steady_clock::now();
  const PackedPortal& p = build.packed;
  const World& w = build.world;
  IContext c{build, opt, {}};
  for (int i = 0; i < 2; ++i)
    c.lights[i] = (size_t(i) < w.lights.size() ? w.lights[size_t(i)] : camera.eye) - p.origin;
  for (int i = 0; i < 2; ++i) c.lights[i] = c.lights[i] * (1.0f / p.voxel_size);  // World::to_voxel in fine space
  camera_frame(camera);
  const int S = 1 << p.scale_log2;
  std::vector<glm::vec3> image(size_t(opt.width) * opt.height);
  std::vector<RenderStats> row_stats(opt.height);
  const uint32_t limit = shared::portal_pixel_iteration_limit(p.div_count, p.fine_dims(), opt.max_interfaces);
  auto step = [&](IPixel& s) {
    ++s.iterations;
    const glm::ivec3 base = s.div >= p.top_divs ? s.tile * S : glm::ivec3(0);
    const Step st = step_ray(p, s.div, s.ray, base);
    uint32_t texels = 0;
    const uint32_t from = s.div;
    const glm::ivec3 from_tile = s.tile;
    if (s.mode == kPrimary) {
      ++s.steps_primary;
      const InstancedEvent e = instanced_advance(p, s.ray, s.div, s.tile, st, texels, nullptr);
      if (e.kind == InstancedEvent::kContinue) return;
      if (e.kind == InstancedEvent::kWall) {
        const glm::vec3 x = s.ray.org + (e.num / e.ad) * s.ray.dir;
        s.point = x;
        s.normal = glm::vec3(0.0f);
        s.normal[e.axis] = s.ray.dir[e.axis] > 0.0f ? -1.0f : 1.0f;
        s.albedo = w.materials[e.material].color;
        s.hit_div = from, s.hit_tile = from_tile;
        ibegin_shadow(c, s, 0);
        return;
      }
      s.color = glm::vec3(1.0f) * opt.background.value_or(glm::vec3(0.0f)) + glm::vec3(0.0f);
      s.mode = kDone;
      return;
    }
    ++s.steps_shadow;
    const uint32_t i = s.mode - kShadowA;
    if (st.kind == StepKind::kTmax) {
      s.light += glm::dot(s.normal, glm::normalize(s.ray.dir));
      ibegin_shadow(c, s, i + 1);
      return;
    }
    const InstancedEvent e = instanced_advance(p, s.ray, s.div, s.tile, st, texels, nullptr);
    if (e.kind == InstancedEvent::kContinue) return;
    ibegin_shadow(c, s, i + 1);
  };
  std::atomic<uint32_t> next{0};
  auto work = [&] {
    std::vector<IPixel> row(opt.width);
    for (uint32_t y; (y = next.fetch_add(1)) < opt.height;) {
      for (uint32_t x = 0; x < opt.width; ++x) {
        IPixel& s = row[x];
        s = IPixel{};
        s.ray = to_voxel_ray(p.origin, p.voxel_size, camera_ray(camera, opt.width, opt.height, x, y));
        const InstancedStart st = instanced_start(p, s.ray);
        if (st.kind == InstancedStart::kMiss) {
          s.color = opt.background.value_or(glm::vec3(0.0f));
          s.mode = kDone;
        } else if (st.kind == InstancedStart::kInsideSolid) {
          s.albedo = w.materials[st.material].color;
          s.color = s.albedo * opt.ambient;
          s.mode = kDone;
        } else {
          s.div = st.div, s.tile = st.tile;
        }
      }
      // Bounded as render()'s (sh::portal_pixel_iteration_limit): a pixel whose rays cycle ends as background
      const auto end_if_cut = [&](IPixel& s) {
        if (s.mode == kDone || s.iterations < limit) return;
        s.color = opt.background.value_or(glm::vec3(0.0f));
        s.mode = kDone;
        s.cut = true;
      };
      if (opt.state_machine) {
        for (uint32_t x = 0; x < opt.width; ++x) {
          while (row[x].mode != kDone && row[x].iterations < limit) step(row[x]);
          end_if_cut(row[x]);
        }
      } else {
        for (uint32_t mode = kPrimary; mode <= kShadowB; ++mode)
          for (uint32_t x = 0; x < opt.width; ++x) {
            while (row[x].mode == mode && row[x].iterations < limit) step(row[x]);
            end_if_cut(row[x]);
          }
      }
      RenderStats& rs = row_stats[y];
      for (uint32_t x = 0; x < opt.width; ++x) {
        const IPixel& s = row[x];
        image[size_t(y) * opt.width + x] = s.color;
        rs.primary_rays += 1;
        rs.shadow_rays += s.shadow_rays;
        rs.primary_steps += s.steps_primary;
        rs.shadow_steps += s.steps_shadow;
        rs.loop_iterations += s.iterations;
        rs.cut_pixels += s.cut;
      }
    }
  };
  run_on_threads(thread_count_or_hardware(opt.threads), work);
  if (stats) {
    *stats = RenderStats{};
    for (const RenderStats& r : row_stats) {
      stats->primary_rays += r.primary_rays, stats->shadow_rays += r.shadow_rays;
      stats->primary_steps += r.primary_steps, stats->shadow_steps += r.shadow_steps;
      stats->loop_iterations += r.loop_iterations;
      stats->cut_pixels += r.cut_pixels;
    }
    stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  return image;
}

}  // namespace gridrt::portal

// ---- Export as a triangle scene (instance.h) ---------------------------------------------------

namespace gridrt::portal {

namespace {

// The faces of the solid voxels of a grid that face a non-solid neighbour, as quads grouped by
// material: `solid(v)` and `material(v)` over [0, dims); `open_outside`: faces on the grid's
// boundary are emitted too. Vertices at (v + corner) * cell + offset.
template <class Solid, class Mat>
void grid_faces(glm::ivec3 dims, float cell, glm::vec3 offset, bool open_outside, Solid solid, Mat material,
                std::map<uint32_t, std::vector<glm::vec3>>& quads) {
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const glm::ivec3 v(x, y, z);
        if (!solid(v)) continue;
        for (int a = 0; a < 3; ++a)
          for (int sgn : {-1, 1}) {
            glm::ivec3 n = v;
            n[a] += sgn;
            const bool out = n[a] < 0 || n[a] >= dims[a];
            if (out ? !open_outside : solid(n)) continue;
            const int u = (a + 1) % 3, w = (a + 2) % 3;
            glm::vec3 p0(v);
            if (sgn > 0) p0[a] += 1.0f;
            glm::vec3 du(0.0f), dw(0.0f);
            du[u] = 1.0f, dw[w] = 1.0f;
            glm::vec3 c[4] = {p0, p0 + du, p0 + du + dw, p0 + dw};  // counter-clockwise seen from +a
            if (sgn < 0) std::swap(c[1], c[3]);
            std::vector<glm::vec3>& q = quads[material(v)];
            for (const glm::vec3& p : c) q.push_back(p * cell + offset);
          }
      }
}

// Every file of the export is written whole or not at all (write_file_atomically).
void write_obj(const std::string& path, const std::string& mtl, const std::map<uint32_t, std::vector<glm::vec3>>& quads) {
  std::ostringstream f;
  f.precision(9);  // a float's shortest round-trip width
  f << "# gridrt portal export: voxel faces (docs/PORTAL.md, \"Instanced subspaces\")\nmtllib " << mtl << "\n";
  size_t base = 1;
  for (const auto& [m, q] : quads) {
    f << "usemtl m" << m << "\n";
    for (const glm::vec3& p : q) f << "v " << p.x << " " << p.y << " " << p.z << "\n";
    for (size_t i = 0; i < q.size(); i += 4) {
      f << "f " << base + i << " " << base + i + 1 << " " << base + i + 2 << "\n";
      f << "f " << base + i << " " << base + i + 2 << " " << base + i + 3 << "\n";
    }
    base += q.size();
  }
  write_file_atomically(path, "portal export mesh", f.str());
}

// A JSON string literal of `s` (names come from map files: quotes, backslashes and control
// characters escaped).
std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') out += '\\', out += c;
    else if (static_cast<unsigned char>(c) < 0x20) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", unsigned(static_cast<unsigned char>(c)));
      out += b;
    } else out += c;
  }
  return out + "\"";
}

std::string json_vec(glm::vec3 v) {
  char b[128];
  std::snprintf(b, sizeof b, "[%.9g, %.9g, %.9g]", double(v.x), double(v.y), double(v.z));
  return b;
}

}  // namespace

size_t export_scene(const InstancedWorld& iw, const std::string& json_path, bool flat) {
  namespace fs = std::filesystem;
  const fs::path jp(json_path);
  std::string ext = jp.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".json") throw Error("portal export: the output must be a .json scene file");
  const std::string stem = jp.stem().string();
  if (json_path.find_first_of("\"\\") != std::string::npos)
    throw Error("portal export: the output path may not contain '\"' or '\\'");
  // The OBJs name their .mtl by the stem on a mtllib line, which ends at white space, and where
  // '#' starts a comment
  for (const char ch : stem)
    if (std::isspace(static_cast<unsigned char>(ch)) || std::iscntrl(static_cast<unsigned char>(ch)) || ch == '#')
      throw Error("portal export: the output's name may not contain spaces, '#' or control characters (an OBJ's "
                  "mtllib line names the materials by it): '" + stem + "'");
  // The scene names its OBJs by the stem, and a scene file's reader expands a leading ${...} and
  // takes only UTF-8: such a name wrote a scene that did not load again (an outside sweep)
  if (stem.rfind("${", 0) == 0 || !is_utf8(stem))
    throw Error("portal export: the output's name may not start with '${' or hold bytes that are not UTF-8 (the "
                "scene names its models by it, and must load again): '" + to_utf8(stem) + "'");
  for (const Block& bl : iw.blocks)
    if (!is_utf8(bl.name))
      throw Error("portal export: block '" + to_utf8(bl.name) + "' has a name that is not UTF-8 (the scene names its "
                  "model by it)");
  const fs::path dir = jp.parent_path().empty() ? fs::path(".") : jp.parent_path();
  const World& w = iw.top;
  const std::string mtl = stem + ".mtl";
  // Every file it writes is named before any is written: a folder in the way of one of them is
  // refused before the others replace anything (the .mtl was written first: an outside sweep)
  {
    std::vector<std::string> outputs = {mtl, stem + (flat ? "_flat.obj" : "_tiles.obj"), jp.filename().string()};
    if (!flat)
      for (const Block& bl : iw.blocks) outputs.push_back(stem + "_block_" + bl.name + ".obj");
    for (const std::string& o : outputs) {
      std::error_code ec;
      if (fs::is_directory(dir / o, ec))
        throw Error("portal export: cannot write '" + (dir / o).string() + "': it is a folder");
      check_output_allowed((dir / o).string(), "portal export file");
    }
  }

  std::vector<std::string> meshes, instances;  // the scene's entries, joined by ", " below
  size_t triangles = 0;
  auto count = [&](const std::map<uint32_t, std::vector<glm::vec3>>& q) {
    for (const auto& [m, v] : q) triangles += v.size() / 2;
  };
  if (flat) {
    const World fw = flatten(iw);
    std::map<uint32_t, std::vector<glm::vec3>> q;
    grid_faces(glm::ivec3(fw.dims), fw.voxel_size, fw.origin, false, [&](glm::ivec3 v) { return fw.solid(v); },
               [&](glm::ivec3 v) { return uint32_t(fw.at(v)); }, q);
    if (!q.empty()) {
      write_obj((dir / (stem + "_flat.obj")).string(), mtl, q);
      count(q);
      meshes.push_back("\"world\": {\"file\": \"" + stem + "_flat.obj\"}");
      instances.push_back("{\"name\": \"world\", \"mesh\": \"world\"}");
    }
  } else {
    // The plain tiles once; each block once, placed by one instance per instance tile.
    auto plain = [&](glm::ivec3 v) { return w.solid(v) && w.at(v) < iw.instance_base; };
    std::map<uint32_t, std::vector<glm::vec3>> q;
    grid_faces(glm::ivec3(w.dims), w.voxel_size, w.origin, false, plain, [&](glm::ivec3 v) { return uint32_t(w.at(v)); }, q);
    if (!q.empty()) {  // a file without faces is no model (the OBJ loader refuses it)
      write_obj((dir / (stem + "_tiles.obj")).string(), mtl, q);
      count(q);
      meshes.push_back("\"tiles\": {\"file\": \"" + stem + "_tiles.obj\"}");
      instances.push_back("{\"name\": \"tiles\", \"mesh\": \"tiles\"}");
    }
    const int S = int(iw.scale);
    for (size_t b = 0; b < iw.blocks.size(); ++b) {
      const Block& bl = iw.blocks[b];
      auto at = [&](glm::ivec3 v) { return bl.voxels[size_t(v.x) + S * (size_t(v.y) + S * size_t(v.z))]; };
      std::map<uint32_t, std::vector<glm::vec3>> bq;
      grid_faces(glm::ivec3(S), w.voxel_size / float(S), glm::vec3(0.0f), true,
                 [&](glm::ivec3 v) { return at(v) != kEmpty; }, [&](glm::ivec3 v) { return uint32_t(at(v)); }, bq);
      bool placed_somewhere = false;
      for (uint32_t z = 0; z < w.dims.z && !placed_somewhere; ++z)
        for (uint32_t y = 0; y < w.dims.y && !placed_somewhere; ++y)
          for (uint32_t x = 0; x < w.dims.x && !placed_somewhere; ++x)
            placed_somewhere = w.at(glm::ivec3(x, y, z)) == iw.instance_base + b;
      if (bq.empty() || !placed_somewhere) continue;  // an empty or unplaced block draws nothing: no file
      const std::string file = stem + "_block_" + bl.name + ".obj";
      write_obj((dir / file).string(), mtl, bq);
      meshes.push_back(json_string("block " + bl.name) + ": {\"file\": " + json_string(file) + "}");
      size_t placed = 0;
      for (uint32_t z = 0; z < w.dims.z; ++z)
        for (uint32_t y = 0; y < w.dims.y; ++y)
          for (uint32_t x = 0; x < w.dims.x; ++x)
            if (w.at(glm::ivec3(x, y, z)) == iw.instance_base + b) {
              instances.push_back("{\"name\": " +
                                  json_string(bl.name + " " + std::to_string(x) + "," + std::to_string(y) + "," +
                                              std::to_string(z)) +
                                  ", \"mesh\": " + json_string("block " + bl.name) + ", \"translate\": " +
                                  json_vec(w.origin + glm::vec3(x, y, z) * w.voxel_size) + "}");
              ++placed;
            }
      for (const auto& [m, v] : bq) triangles += placed * (v.size() / 2);
    }
  }
  if (instances.empty()) throw Error("portal export: the world has no faces to export (every voxel empty)");
  // The materials last: a world flatten refuses (too large) left the .mtl replaced before
  {
    std::ostringstream f;
    for (size_t m = 0; m < w.materials.size(); ++m)
      f << "newmtl m" << m << "\nKd " << w.materials[m].color.x << " " << w.materials[m].color.y << " "
        << w.materials[m].color.z << "\n";
    write_file_atomically((dir / mtl).string(), "portal export materials", f.str());
  }
  const auto join = [](const std::vector<std::string>& v) {
    std::string out;
    for (size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + v[i];
    return out;
  };
  std::ostringstream f;
  f << "{\n  \"name\": " << json_string(w.name + (flat ? " (flattened)" : "")) << ",\n"
    << "  \"description\": \"gridrt portal export of a block map: the voxel faces as triangles"
    << (flat ? ", one mesh" : ", each block one mesh placed by instances") << "\",\n"
    << "  \"meshes\": {" << join(meshes) << "},\n  \"instances\": [" << join(instances) << "],\n"
    << "  \"camera\": {\"eye\": " << json_vec(w.camera.eye) << ", \"target\": " << json_vec(w.camera.target)
    << ", \"up\": " << json_vec(w.camera.up) << ", \"vfov\": " << w.camera.vfov_degrees << "},\n  \"lights\": [";
  for (size_t i = 0; i < w.lights.size(); ++i)
    f << (i ? ", " : "") << "{\"position\": " << json_vec(w.lights[i]) << ", \"intensity\": 10}";
  f << "]\n}\n";
  write_file_atomically(json_path, "portal export scene", f.str());
  return triangles;
}

}  // namespace gridrt::portal
