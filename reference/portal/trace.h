// trace.h: the portal tracer ("A Novel Raytracing Algorithm for GPU": stackless traversal of divs, only the current div index as
// state), the exact voxel DDA over the same occupancy (the ground truth), explain, the Tracer
// implementations "portal-cpu" and "voxel-dda", and the renderer (primary + two shadow rays,
// non-forking refraction) as separate loops and as the single-loop state machine.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "gridrt/common/tracer.h"
#include "gridrt/reference/portal/build.h"

namespace gridrt::portal {

// A ray in voxel space (org and dir mapped by the world's origin and voxel size; t unchanged).
struct VoxelRay {
  glm::vec3 org{0.0f}, dir{0.0f, 0.0f, 1.0f};
  float tmin = 0.0f, tmax = 0.0f;
};
VoxelRay to_voxel_ray(glm::vec3 origin, float voxel_size, const Ray& ray);

// One step of the portal traversal from div `div` (seed steps 1-3): the exit face by three slab
// tests, the texel of that face at the crossing voxel, and what it says.
enum class StepKind : uint32_t { kNext, kWall, kOutside, kTmax, kNoDirection };
struct Step {
  StepKind kind = StepKind::kNoDirection;
  uint32_t axis = 3;          // axis of the plane crossed
  float num = 0, ad = 0;      // that plane's distance ahead and |dir[axis]|: t = num / ad
  uint32_t face = 0;          // the div face left (exterior div: the world face entered)
  glm::ivec3 voxel{0};        // exterior: the boundary voxel entered; else the voxel on this side of the face
  glm::uvec2 texel_uv{0};     // atlas coordinates read
  uint32_t texel = 0;         // the atlas texel value
};
// `base`: instanced subspaces (docs/PORTAL.md, "Instanced subspaces"): a block div's box is
// offset by `base` fine voxels (its instance tile's corner); 0 for every other div.
Step step_ray(const PackedPortal& packed, uint32_t div, const VoxelRay& ray, glm::ivec3 base = glm::ivec3(0));

// Where a ray starts: the div holding the voxel at org + tmin dir (start map), the exterior div
// (div 0) when that point lies outside the world, or a hit (the point is inside a solid voxel:
// t = tmin, face kPortalFaceInside) / a miss (outside and never entering).
struct Start {
  enum Kind { kDiv, kInsideSolid, kMiss } kind = kMiss;
  uint32_t div = 0;
  glm::ivec3 voxel{0};
  uint32_t texel = 0;
};
Start start_ray(const PackedPortal& packed, const VoxelRay& ray);

// ---- Mip-mapped space (docs/PORTAL.md, "Mip-mapped space") ----
// The level-`level` ray: org and dir times 2^-level (exact; t unchanged).
VoxelRay level_ray(const VoxelRay& ray, uint32_t level);
// After a step from a level-`level` air div into the div beyond (kNext): whether the ray moves to
// a coarser level at that plane (the level rule, at a plane of the coarser level), and where: the
// coarse voxel beyond the plane and its start texel (a div of that level, or a coarse wall).
struct MipEnter {
  bool moved = false;
  uint32_t level = 0;
  glm::ivec3 voxel{0};
  uint32_t texel = 0;
};
MipEnter mip_enter(const PackedPortal& packed, const VoxelRay& ray, uint32_t level, const Step& step);
// A coarse wall voxel `voxel` of level `level` met on the plane (axis, num, ad: level space):
// the fine voxel beyond the plane at the crossing (`wall`) and the fine voxel before it (`side`).
void mip_fine_voxels(const PackedPortal& packed, const VoxelRay& ray, uint32_t level, uint32_t axis, float num, float ad,
                     glm::ivec3 voxel, glm::ivec3& wall, glm::ivec3& side);

// Closest wall of a world-space ray from the packed textures only. Glass counts as a wall here
// (the first surface). `log`, if given, receives the explanation (one line per step).
Hit trace_portal(const PackedPortal& packed, const Ray& ray, std::string* log = nullptr);
// The same by an exact voxel DDA over the world's occupancy (same hit convention, same plane
// predicate). `log` as above.
Hit trace_dda(const World& world, const Ray& ray, std::string* log = nullptr);

// Names for explain texts (shared by the CPU and Vulkan accounts): a face id ("-X" ... "+Z",
// "inside") and an atlas texel ("0x8001 (wall, material 1)").
const char* face_name(uint32_t face);
std::string texel_text(uint32_t texel);

// Readable account of one ray: divs visited, exit faces, texels read, decisions.
std::string explain_portal(const PackedPortal& packed, const World& world, const Ray& ray);

// Helpers for hit records (common/shared/portal.h gives the convention).
inline uint32_t hit_face(const Hit& h) { return h.triangle & 7u; }
inline uint32_t hit_voxel_index(const Hit& h) { return h.triangle >> 3; }
glm::ivec3 hit_voxel(const World& world, const Hit& h);

// Tracer interface. build(scene) voxelizes the scene at `resolution`; the World constructor
// builds from a world directly (then build(scene) is not needed; update does nothing).
class PortalTracer final : public Tracer {
 public:
  explicit PortalTracer(uint32_t resolution = 64, PortalOptions options = {});
  explicit PortalTracer(World world, PortalOptions options = {});
  explicit PortalTracer(PortalBuild build, PortalOptions options = {});  // an existing build
  std::string name() const override { return "portal-cpu"; }
  void build_scene(const Scene& scene, float time) override;
  void update_to(float) override {}
  void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) override;
  AccelDump dump() const override;  // kind "portal": the atlas texels (extent atlas w x h x 1)
  const PortalBuild& portal() const;
  std::string explain(const Ray& ray) const;

 private:
  uint32_t resolution_;
  PortalOptions options_;
  std::unique_ptr<PortalBuild> build_;
};

class VoxelDdaTracer final : public Tracer {
 public:
  explicit VoxelDdaTracer(uint32_t resolution = 64) : resolution_(resolution) {}
  explicit VoxelDdaTracer(World world) : resolution_(0), world_(std::move(world)) {
    world_->validate();
    set_built();
  }
  std::string name() const override { return "voxel-dda"; }
  void build_scene(const Scene& scene, float time) override;
  void update_to(float) override {}
  void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) override;
  const World& world() const;

 private:
  uint32_t resolution_;
  std::optional<World> world_;
};

// ---- Rendering -------------------------------------------------------------------------------

struct RenderOptions {
  uint32_t width = 720, height = 360;  // the paper's resolution
  bool state_machine = true;   // one loop with state transitions (the paper's FSM); false: three loops
  bool refraction = true;      // glass refracts (never forks; total internal reflection reflects)
  unsigned threads = 0;        // 0: hardware concurrency
  float ambient = 0.15f;
  // A ray leaving the world (or a primary ray that misses it); unset: the world's own
  // (World::background: a voxelized scene's, black for a map)
  std::optional<glm::vec3> background;
  uint32_t max_interfaces = 32; // glass interfaces per primary ray before it is given up (black)
};

// The colour a ray leaving `world` gets under `o`.
inline glm::vec3 background_of(const RenderOptions& o, const World& world) { return o.background.value_or(world.background); }

struct RenderStats {
  uint64_t primary_rays = 0, shadow_rays = 0;
  uint64_t primary_steps = 0, shadow_steps = 0;  // divs visited
  uint64_t loop_iterations = 0;                  // of the FSM loop or the three loops together
  uint64_t refractions = 0, reflections = 0;     // total internal reflections
  uint64_t cut_pixels = 0;  // pixels whose rays ran past sh::portal_pixel_iteration_limit (drawn as background)
  double seconds = 0;
};

// Linear RGB, row 0 at the top (index y * width + x). The two shadow rays go to the world's first
// two lights (a missing light is placed at the eye). Shading: material colour * filter *
// (ambient + (1 - ambient) * sum over the two lights of visible * max(0, N.L) / 2).
std::vector<glm::vec3> render(const PortalBuild& build, const Camera& camera, const RenderOptions& options = {},
                              RenderStats* stats = nullptr);

// Refraction of unit direction `d` at a surface with unit normal `n` facing the incoming ray,
// eta = n_from / n_to. Returns false (and the reflected direction) on total internal reflection.
bool refract_or_reflect(glm::vec3 d, glm::vec3 n, float eta, glm::vec3& out);

}  // namespace gridrt::portal
