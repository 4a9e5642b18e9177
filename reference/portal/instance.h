// instance.h: instanced subspaces of the portal tracer ("A Novel Raytracing Algorithm for GPU",
// docs/PORTAL.md, "Instanced subspaces"): block maps (tiles that are instances of small voxel
// models), their flattened equivalent, the build (the top level's divs and each block's divs once),
// and the stackless traversal that enters an instance through a tile face and leaves it back to
// the top level.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "gridrt/reference/portal/build.h"
#include "gridrt/reference/portal/trace.h"
#include "gridrt/reference/portal/world.h"

namespace gridrt::portal {

inline constexpr uint32_t kMaxBlocks = 256;             // blocks per map
inline constexpr uint64_t kMaxInstancedFineVoxels = uint64_t(1) << 29;  // hit records hold (voxel << 3) | face in 32 bits

// One block: scale^3 fine voxels (x fastest, then y, then z) of the map's materials or kEmpty.
struct Block {
  std::string name;
  std::vector<uint16_t> voxels;
};

// A map of tiles, each scale^3 fine voxels: empty, a wall of one material, or an instance of a block.
struct InstancedWorld {
  // The top level: one voxel per tile (voxel_size: the tile's world size). Walls are materials;
  // an instance of block b is material instance_base + b (a material named after the block).
  World top;
  uint32_t scale = 8;  // fine voxels per tile edge: 2, 4, 8 or 16
  uint32_t instance_base = 0;
  std::vector<Block> blocks;
  uint32_t scale_log2() const;
  glm::uvec3 fine_dims() const { return top.dims * scale; }
  // Errors naming what is wrong: scale, sizes, the fine voxel count, instance materials.
  void validate() const;
};

// A block map (format in docs/PORTAL.md, "Block maps"). Throws Error with the line.
InstancedWorld parse_block_map(std::string_view text, const std::string& name = "map", bool require_eye = true);
InstancedWorld load_block_map(const std::string& path, bool require_eye = true);
// Whether a map text is a block map (its first keyword is `scale`).
bool is_block_map(std::string_view text);
// The built-in block level (builtin:blocks) and generated block levels (gen-blocks:WxDxH[:SEED]:
// the generated level of that size, its inner walls made of the built-in blocks).
std::string_view builtin_blocks_text();
InstancedWorld builtin_blocks();
std::string generated_blocks_text(uint32_t width, uint32_t depth, uint32_t height, uint32_t seed = 1);
InstancedWorld generated_blocks_spec(const std::string& spec);

// The equivalent plain world: every tile as its scale^3 fine voxels (voxel_size = tile / scale).
// Throws Error when it breaks the plain world's limits (255 voxels per axis).
World flatten(const InstancedWorld& world);

// The world as a triangle scene for the grid (the voxel faces facing empty space, two triangles
// each): `json_path` (a scene file) beside its .obj meshes and .mtl. Instanced: the plain tiles
// one mesh, each block one mesh placed by one instance per instance tile; `flat`: the flattened
// world as one mesh. Returns the triangles placed in the scene.
size_t export_scene(const InstancedWorld& world, const std::string& json_path, bool flat);

// The top level's divs, each block's divs once, packed into one PackedPortal (build.h).
PortalBuild build_instanced(const InstancedWorld& world, const PortalOptions& options = {});

// The instanced traversal (trace_portal calls it for an instanced build). Hit records are in fine
// voxel space: the flattened world's voxels, so they compare field by field with trace_dda on
// flatten(world) (t, material, voxel, face, u, v; cells and tests count this structure's steps).
Hit trace_instanced(const PackedPortal& packed, const Ray& ray, std::string* log = nullptr);

// The voxel DDA over the fine voxels of an instanced world without writing them out: the same
// records as trace_dda(flatten(world)), also where flatten refuses (beyond 255 voxels per axis).
Hit trace_dda_instanced(const InstancedWorld& world, const Ray& ray);

// Where a ray crossing plane (axis, num, ad: fine space) into tile `tile` meets that tile's fine
// voxels: the fine voxel beyond the plane at the crossing.
glm::ivec3 instance_fine_voxel(const PackedPortal& packed, const VoxelRay& ray, uint32_t axis, float num, float ad,
                               glm::ivec3 tile);
// The start texel of fine voxel `fine` (fine space) in the block of material `m` at tile `tile`.
uint16_t block_start_texel(const PackedPortal& packed, uint32_t m, glm::ivec3 tile, glm::ivec3 fine);
inline bool is_instance_material(const PackedPortal& p, uint32_t m) {
  return shared::portal_is_instance(m, p.scale_log2, p.instance_base, p.blocks);
}

// Where a fine-space ray starts: outside (the top level's exterior div 0), in a top-level div, in
// a block div of an instance tile (`tile`), or inside a solid fine voxel (`voxel`, `material`).
struct InstancedStart {
  enum Kind { kDiv, kInsideSolid, kMiss } kind = kMiss;
  uint32_t div = 0;
  glm::ivec3 tile{0}, voxel{0};
  uint32_t material = 0;
  uint32_t texels = 0;  // start texels read
};
InstancedStart instanced_start(const PackedPortal& packed, const VoxelRay& ray);

// What the ray does after step `st` from div `div` (in a block div: of instance tile `tile`):
// continue in another div (div and tile updated: a top-level div, a block div of the same
// instance, enter_instance into the block of the tile beyond, or leave_instance back to the top
// level's start texel of the tile beyond the block's face), hit a wall (fine space: plane, the
// solid fine voxel and the one before it, material), or miss. `texels` counts the texels read.
struct InstancedEvent {
  enum Kind { kContinue, kWall, kMiss } kind = kMiss;
  uint32_t axis = 0;
  float num = 0, ad = 0;  // fine space: t = num / ad
  glm::ivec3 wall{0}, side{0};
  uint32_t material = 0;
};
InstancedEvent instanced_advance(const PackedPortal& packed, const VoxelRay& ray, uint32_t& div, glm::ivec3& tile,
                                 const Step& st, uint32_t& texels, std::string* log = nullptr);

// The renderer (render() calls it for an instanced build): primary + two shadow rays per pixel, as
// render.cpp without glass or mip levels; the state is the div and, in a block div, its tile.
std::vector<glm::vec3> render_instanced(const PortalBuild& build, const Camera& camera, const RenderOptions& options,
                                        RenderStats* stats);

}  // namespace gridrt::portal
