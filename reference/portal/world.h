// world.h: the voxel worlds the portal tracer runs in (docs/PORTAL.md, "Worlds"): an occupancy
// grid of wall materials, from a Wolf3D-style tile map, the built-in level, or a voxelized mesh.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "gridrt/common/scene.h"

namespace gridrt::portal {

inline constexpr uint16_t kEmpty = 0xFFFF;      // a voxel of empty space
inline constexpr uint32_t kMaxWorldAxis = 255;  // div sizes and origins are 8-bit (the paper's format)
// The largest tile map, in voxels with floor and ceiling: the whole range of the div format
// (255 x 255 x 253 and its floor and ceiling). The bounded div choice builds the largest such world
// in about half a minute on two cores with 1.76 GB (docs/PORTAL.md), and fails in seconds, naming
// the limit, where the divs or the atlas would not fit.
inline constexpr uint64_t kMaxTileMapVoxels = uint64_t(kMaxWorldAxis) * kMaxWorldAxis * kMaxWorldAxis;

struct WallMaterial {
  std::string name;
  glm::vec3 color{0.7f};
  bool glass = false;        // a transparent medium the renderer refracts through (never forks)
  float ior = 1.5f;          // index of refraction of the glass
  glm::vec3 filter{1.0f};    // colour filter per unit length inside the glass
  // Materials of coarse mip levels (docs/PORTAL.md, "Mip-mapped space"): the fraction of the
  // coarse voxel's fine voxels that are walls or glass (its opacity), and whether every one of them
  // is an opaque wall (then a ray meeting it returns to full resolution for the exact hit).
  float coverage = 1.0f;
  bool resolve = false;
};

struct World {
  std::string name;
  glm::uvec3 dims{0};                  // voxels per axis, each 1 .. 255
  std::vector<uint16_t> voxels;        // x fastest, then y, then z: kEmpty or a material index
  std::vector<WallMaterial> materials; // indexed by voxel values
  glm::vec3 origin{0.0f};              // world position of voxel corner (0, 0, 0)
  float voxel_size = 1.0f;             // world units per voxel
  // Tile maps: the eye and the lights (world positions); scenes: from the scene.
  bool has_eye = false;
  Camera camera;
  std::vector<glm::vec3> lights;
  // Voxelized scenes: the world is the model's box and one voxel, and space goes on beyond it, so
  // a shadow ray that leaves it reaches its light (lights outside the box, a directional light, a
  // missing light put at an eye outside: all blocked before, every such picture unlit, an outside
  // sweep). Tile and block maps: the outside lies beyond the walls, and blocks.
  bool open_outside = false;
  // The colour beyond the world: a voxelized scene's `background` (it rendered black, where every
  // grid backend shows the scene's: an outside sweep); black for tile and block maps.
  glm::vec3 background{0.0f};

  size_t index(uint32_t x, uint32_t y, uint32_t z) const { return x + size_t(dims.x) * (y + size_t(dims.y) * z); }
  size_t index(glm::uvec3 v) const { return index(v.x, v.y, v.z); }
  size_t voxel_count() const { return size_t(dims.x) * dims.y * dims.z; }
  bool inside(glm::ivec3 v) const {
    return v.x >= 0 && v.y >= 0 && v.z >= 0 && uint32_t(v.x) < dims.x && uint32_t(v.y) < dims.y && uint32_t(v.z) < dims.z;
  }
  uint16_t at(glm::ivec3 v) const { return voxels[index(glm::uvec3(v))]; }
  bool solid(glm::ivec3 v) const { return at(v) != kEmpty; }  // wall or glass
  // Medium key of a voxel for div building: kEmpty for air, the material for glass, and
  // kOpaque for an opaque wall (no div).
  static constexpr uint32_t kOpaque = 0x10000;
  uint32_t medium(glm::ivec3 v) const {
    const uint16_t m = at(v);
    if (m == kEmpty) return kEmpty;
    return materials[m].glass ? m : kOpaque;
  }
  bool has_glass() const;

  // Check dims (1 .. 255 each), sizes, material indices (< materials.size(), <= 0x7FFE), glass
  // materials < 256. Throws Error naming what is wrong.
  void validate() const;
  // Voxel-space <-> world-space.
  glm::vec3 to_voxel(glm::vec3 p) const { return (p - origin) * (1.0f / voxel_size); }
  glm::vec3 to_world(glm::vec3 v) const { return origin + v * voxel_size; }
};

// A tile map (format in docs/PORTAL.md, "Tile maps"). `name` names the source in errors.
// `require_eye`: a map without 'E' is an error. Throws Error with the line and column.
World parse_tile_map(std::string_view text, const std::string& name = "map", bool require_eye = true);
World load_tile_map(const std::string& path, bool require_eye = true);

// The built-in level: 32 x 32 tiles, 4 voxels high, rooms, corridors, pillars, a glass wall,
// two lights. Its text is builtin_level_text().
World builtin_level();
std::string_view builtin_level_text();

// A generated level: `width` x `depth` tiles, `height` voxels high (width, depth 5..255, height
// 1..253), walls around the edge, rooms split recursively by walls of random materials with one or
// two doorways, a pillar in some rooms, the eye near the top-left corner, two lights. Deterministic
// for a seed. generated_level_spec parses "gen:WxDxH[:SEED]" (the tool's world spec).
std::string generated_level_text(uint32_t width, uint32_t depth, uint32_t height, uint32_t seed = 1);
World generated_level(uint32_t width, uint32_t depth, uint32_t height, uint32_t seed = 1);
World generated_level_spec(const std::string& spec);
// The numbers of a generated world spec "PREFIXWxDxH[:SEED]" (PREFIX "gen:" or "gen-blocks:"):
// decimal digits only, each at most 2^32 - 1 (seed 1 when absent). False on anything else,
// trailing characters included.
bool parse_generated_spec(const std::string& spec, const std::string& prefix, uint32_t& w, uint32_t& d, uint32_t& h,
                          uint32_t& seed);

// Voxelize every instance of `scene` at time 0: a voxel is solid when a triangle overlaps it
// (triangle/box separating-axis test, Akenine-Moeller), its material the scene material of the
// lowest (instance, triangle) that overlaps it. `resolution` voxels along the longest axis of the
// bounds (1 .. 253); one empty voxel of margin on every side. Camera and lights from the scene.
// Says on stderr what the voxels leave out: a moving instance's motion (voxelized at t = 0), alpha
// masks (solid), lights past the renderer's two (warn_unused_lights).
World voxelize(const Scene& scene, uint32_t resolution = 64);

// A warning on stderr when the world has more lights than the portal renderer shades with (two).
void warn_unused_lights(const World& w);

// Triangle/axis-aligned box overlap (separating axis theorem: 3 box axes, the triangle normal,
// 9 edge cross products), in double; voxelize gives it voxel units. Exposed for tests.
bool triangle_box_overlap(glm::dvec3 box_center, glm::dvec3 box_half, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c);

}  // namespace gridrt::portal
