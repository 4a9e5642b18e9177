// build.h: maximal divs, the flux-density heuristic, the per-face choice and the packed textures
// of the portal tracer (docs/PORTAL.md, "Build" and "Storage").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "gridrt/common/shared/portal.h"
#include "gridrt/reference/portal/world.h"

namespace gridrt::portal {

inline constexpr uint32_t kNone = 0xFFFFFFFFu;

// A div: the voxels [lo, hi) of one medium (kEmpty for air, a glass material).
struct Box {
  glm::ivec3 lo{0}, hi{0};
  uint32_t medium = kEmpty;
  glm::ivec3 size() const { return hi - lo; }
  int64_t volume() const { return int64_t(hi.x - lo.x) * (hi.y - lo.y) * (hi.z - lo.z); }
  bool contains(glm::ivec3 v) const {
    return v.x >= lo.x && v.y >= lo.y && v.z >= lo.z && v.x < hi.x && v.y < hi.y && v.z < hi.z;
  }
  bool operator==(const Box&) const = default;
};

// Every maximal div of every medium: boxes of voxels of one medium that cannot grow by one layer
// in any of the six directions. Exact: for each z range [z0, z1], the columns empty over the whole
// range form a 2D mask whose maximal rectangles (histogram stack, one pass per row) are the
// candidates; a candidate is kept if the layers z0 - 1 and z1 + 1 block it. Each maximal box is
// found once. Sorted by (medium, lo.z, lo.y, lo.x, hi.z, hi.y, hi.x).
// `max_boxes` (0: none) stops the enumeration with an Error once more boxes than that are found.
std::vector<Box> maximal_divs(const World& world, unsigned threads = 0, size_t max_boxes = 0);

// The paper's FluxDensity: rays start uniformly on the unit square z = 0 (voxel (0, 0, 0)'s -z
// face), cosine-distributed over the hemisphere dz > 0; for every voxel face of the octant
// x, y >= 0 (folded: the distribution is symmetric in x and in y), the fraction of rays that cross
// it, and for every voxel the mean length of ray inside it. Offsets up to `range` voxels; beyond,
// 0. Deterministic (fixed seed). Built once per process by get().
struct FluxDensity {
  int range = 0;
  uint32_t rays = 0;
  std::vector<float> plane_x;  // [(p - 1) * R + j) * R + k]: plane x = p (p >= 1), voxel row j, depth k
  std::vector<float> plane_z;  // [(i * R + j) * R + (q - 1)]: plane z = q (q >= 1), column (i, j)
  std::vector<double> length_sat;  // summed-area table of mean length, (R+1)^3
  float x_face(int p, int j, int k) const;  // p >= 1 folded plane, j, k >= 0; 0 beyond range
  float z_face(int i, int j, int q) const;
  double length_sum(int i0, int i1, int j0, int j1, int k0, int k1) const;  // folded box [i0,i1) x ... (i, j signed)
  static FluxDensity compute(int range, uint32_t rays);
  static const FluxDensity& get();  // range 64, 2^18 rays
};

// The paper's heuristic for rays entering voxel `v` through its face `entry_face` (moving inwards)
// into the maximal div `div` (which contains v), integrated over the sub-cuboid they can enter:
//   p_open  = sum of flux over the cuboid's exit voxel faces whose far voxel is of the same medium
//   p_wall  = the same over faces to a wall, another medium or outside the world
//   length  = expected length of ray inside the cuboid (sum of mean lengths of its voxels)
//   cost    = p_open / length  (the paper's "expected length over the probability of reaching an
//             exit face", inverted so that 0 is the best and nothing divides by zero)
struct EntryCost {
  double p_open = 0, p_wall = 0, length = 0, cost = 0;
};
EntryCost integrate_flux_density_over_cuboid(const World& world, const FluxDensity& flux, glm::ivec3 v,
                                             uint32_t entry_face, const Box& div);

// The same integral as the build evaluates it: open voxel faces as runs, the table summed by 1D
// prefix sums (exact up to the order of summation). For tests.
EntryCost integrate_flux_density_fast(const World& world, glm::ivec3 v, uint32_t entry_face, const Box& div);

// How the build chooses the div for each entered voxel face (docs/PORTAL.md, "The choice").
//  bounded: candidates are the greedy maximal divs grown from the voxel's three axis runs (at most
//           six per voxel, each maximal), and only the faces the stored divs' textures reference are
//           evaluated (a closure from the start map): near-linear in the voxel count. The default.
//  exact:   every maximal div of every voxel, every entered face (the paper's choice); refused
//           beyond kExactChoiceMaxVoxels voxels or kExactChoiceMaxEvaluations evaluations.
enum class DivChoice { bounded, exact };
inline constexpr size_t kExactChoiceMaxVoxels = size_t(1) << 20;
inline constexpr size_t kExactChoiceMaxEvaluations = 60'000'000;

struct PortalOptions {
  uint32_t atlas_width = 1024;  // texels per atlas row
  uint32_t info_width = 1024;   // texels per div-info row (a multiple of 8)
  unsigned threads = 0;         // 0: hardware concurrency
  bool progress = true;         // a Progress line on stderr for long builds
  DivChoice choice = DivChoice::bounded;
  // Bounded: faces are evaluated once per world-aligned square of choice_block x choice_block voxel
  // faces with the same candidates (the first such face stands for the others); 1: every face.
  uint32_t choice_block = 1;
  // Bounded: the flux integrals (p_open, p_wall) over faces up to this many voxels from the entry
  // voxel (0: the table's whole range, 64); the expected length always uses the whole table.
  uint32_t choice_range = 0;
  // Bounded: greedy boxes per axis run: 2 (the run, then the other two axes in either order) or 3
  // (also both other axes grown a layer at a time in turn: squarer boxes; up to nine candidates).
  uint32_t choice_per_run = 2;
  // Mip-mapped space (docs/PORTAL.md, "Mip-mapped space"): levels 0 .. mip_levels - 1 (1: none,
  // at most kPortalMaxLevels), each a voxelization at 2^l fine voxels per voxel with its own divs.
  // A ray moves to level l once its Chebyshev distance from its origin reaches mip_distance * 2^l
  // fine voxels (mip_distance > 0 when mip_levels > 1).
  uint32_t mip_levels = 1;
  float mip_distance = 0.0f;
};
DivChoice parse_div_choice(const std::string& name);  // "bounded" | "exact"; Error otherwise
const char* div_choice_name(DivChoice c);

// The textures exactly as a GPU would hold them (docs/PORTAL.md, "Storage").
struct PackedPortal {
  glm::uvec3 dims{0};
  glm::vec3 origin{0.0f};
  float voxel_size = 1.0f;
  uint32_t atlas_width = 0, atlas_height = 0;
  std::vector<uint16_t> atlas;     // R16_UINT, row-major
  uint32_t info_width = 0, info_height = 0;
  std::vector<uint8_t> info;       // RGBA8_UINT, row-major, 8 texels per div
  std::vector<uint16_t> start;     // R16_UINT 3D, one texel per voxel: a div containing it, or a wall texel
  uint32_t div_count = 0;
  // Mip-mapped space: `levels` levels (1: none). Level l's divs follow level l-1's in the div
  // info and the atlas (its atlas rows below); its start map is the block of the start texture at
  // depth start_z(l), level_dims(l) voxels, in the same dims.x x dims.y slices (start_depth slices
  // in all). mip_distance: the level rule's distance (PortalOptions). Per material (the world's
  // table, coarse materials appended): coverage and resolve (WallMaterial).
  uint32_t levels = 1;
  float mip_distance = 0.0f;
  uint32_t start_depth = 0;
  std::vector<float> coverage;
  std::vector<uint8_t> resolve;
  glm::uvec3 level_dims(uint32_t level) const { return shared::portal_level_dims(dims, level); }
  uint32_t start_z(uint32_t level) const {
    uint32_t z = 0;
    for (uint32_t l = 0; l < level; ++l) z += level_dims(l).z;
    return z;
  }
  // The start texel of voxel v of level `level`.
  uint16_t start_at(uint32_t level, glm::ivec3 v) const {
    return start[uint32_t(v.x) + dims.x * (uint32_t(v.y) + dims.y * (start_z(level) + uint32_t(v.z)))];
  }
  // Instanced subspaces (docs/PORTAL.md, "Instanced subspaces"); scale_log2 = 0: none. Then
  // `dims` are the top level's tiles, each 2^scale_log2 fine voxels per axis; origin and voxel_size
  // map world space to fine voxel space (rays are traced there). Divs 0 .. top_divs - 1 are the
  // top level's (level nibble scale_log2: traced in tile space, the ray times 2^-scale_log2, exact);
  // the blocks' divs follow. A top-level wall texel of material instance_base + b (b < blocks) is
  // an instance of block b; block b's start map (one texel per fine voxel of the block, x fastest)
  // is atlas texels block_start + b * 8^scale_log2 ... (row-major in the atlas).
  uint32_t scale_log2 = 0;
  uint32_t instance_base = 0xFFFFu;
  uint32_t blocks = 0;
  uint32_t top_divs = 0;
  uint32_t block_start = 0;
  glm::uvec3 fine_dims() const { return dims * (1u << scale_log2); }
  size_t bytes() const { return atlas.size() * 2 + info.size() + start.size() * 2; }
};

// Decoded div info of div `d` (reads the RGBA8 texels only).
struct DivInfo {
  glm::ivec3 lo{0}, size{0};
  uint32_t type = 0, glass_material = 0;
  uint32_t level = 0;       // mip level (the high nibble of the type byte)
  glm::uvec2 face_uv[6]{};  // atlas origin of each face's rectangle
};
DivInfo read_div_info(const PackedPortal& packed, uint32_t d);

struct BuildStats {
  double seconds_maximal = 0, seconds_flux = 0, seconds_choice = 0, seconds_pack = 0, seconds_total = 0;
  size_t maximal = 0, candidates_evaluated = 0, faces_chosen = 0, divs = 0, atlas_texels = 0, bytes = 0;
  DivChoice choice = DivChoice::bounded;
  // Bounded: faces are evaluated once per world-aligned square of choice_block x choice_block voxel
  // faces with the same candidates (the first such face stands for the others); 1: every face.
  uint32_t choice_block = 1;
  // Bounded: the flux integrals (p_open, p_wall) over faces up to this many voxels from the entry
  // voxel (0: the table's whole range, 64); the expected length always uses the whole table.
  uint32_t choice_range = 0;
  // Bounded: greedy boxes per axis run: 2 (the run, then the other two axes in either order) or 3
  // (also both other axes grown a layer at a time in turn: squarer boxes; up to nine candidates).
  uint32_t choice_per_run = 2;
};

struct PortalBuild {
  World world;
  std::vector<Box> maximal;          // candidate divs, all maximal: every maximal div (exact) or the greedy ones (bounded)
  std::vector<uint32_t> choice;      // [voxel * 6 + entry face]: index into maximal, kNone if no ray enters there
                                     // (bounded: kNone too where no stored texture references the face)
  std::vector<uint32_t> start_box;   // [voxel]: largest candidate containing it, kNone for opaque voxels
  std::vector<Box> divs;             // stored divs; divs[0] is the exterior div (the world box)
  std::vector<uint32_t> div_of_maximal;  // maximal index -> stored div index, kNone if unused
  PackedPortal packed;
  BuildStats stats;
  // Instanced subspaces: the block divs (stored after divs' top-level ones in packed); `world` is
  // then the top level (tiles; block instances are walls of the instance materials).
  size_t block_divs = 0;
};

// Build everything for `world`. Throws Error when the world breaks a format limit (more than
// 32768 divs, an atlas taller than 65536 rows; the bounded choice stops as soon as its stored divs
// pass either), or the exact choice's size limits.
PortalBuild build_portal(World world, const PortalOptions& options = {});

// Mip-mapped space (mip.cpp): the world of level `level` (2^level fine voxels per voxel; a coarse
// voxel is empty when all its fine voxels are, else a coarse material: the mean colour of its
// occupied fine voxels, coverage = occupied / 8^level, resolve = all of them opaque walls).
// Coarse materials are appended to `materials` (shared, deduplicated).
World coarse_world(const World& world, uint32_t level, std::vector<WallMaterial>& materials);
// Adds levels 1 .. options.mip_levels - 1 to a level-0 build: their divs, atlas rows and start
// maps packed after level 0's, the coarse materials appended to build.world.materials.
void add_mip_levels(PortalBuild& build, const PortalOptions& options);

// The greedy maximal div grown from voxel v: along axis `order[0]` (v's run), then `order[1]`,
// then `order[2]`, each as far as the medium of v allows. Maximal: a direction blocked at a
// thinner stage stays blocked. For tests; the bounded build grows the same boxes from runs.
Box greedy_div(const World& world, glm::ivec3 v, glm::ivec3 order);

// Face rectangle size of a box face (tangent axes, lower first).
glm::ivec2 face_extent(const Box& b, uint32_t face);

}  // namespace gridrt::portal
