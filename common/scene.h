// scene.h: the scene model every tracer reads: meshes, instances (static or dynamic, with their
// motion), materials, textures, camera, lights and grid overrides.
//
// Conventions
// - Instances are ordered static first, dynamic after (Scene::finalize enforces it). An
//   instance's id is its index in Scene::instances: the paper's dynamic ids "increased by the
//   number of static instances" fall out of that order.
// - The paper's 16-bit limits: a reference packs (instance << 16 | triangle), so a mesh holds at
//   most kMaxTrianglesPerMesh triangles (larger ones are split by finalize) and a scene at most
//   kMaxInstances instances (more is an error).
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace gridrt {

inline constexpr uint32_t kMaxTrianglesPerMesh = 65536;  // triangle index fits in 16 bits
inline constexpr uint32_t kMaxInstances = 65535;         // 0xFFFF is reserved: 0xFFFFFFFF is blank
inline constexpr float kMaxAngularSpeed = 1.0e6f;        // radians per second (finalize checks)
inline constexpr float kMinPathPeriod = 1.0e-3f;         // seconds (finalize checks)

// Every failure the user can cause (bad files, bad values, limits) is reported as this.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A direction of any finite length scaled by a power of two (exact) so that its largest component
// lies in [1, 2) where it lies outside [2^-20, 2^20]: normalizing it then neither overflows nor
// underflows (directional lights, rotation axes). Zero stays zero.
glm::vec3 direction_in_range(glm::vec3 v);

// Options that contradict one another (the compact layout with the paper traversal, ...): an
// Error of the caller's request, not of its input; the tool exits 2 for it, as for any bad
// command line.
class OptionsError : public Error {
 public:
  using Error::Error;
};

struct Mesh {
  std::string name;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;     // per vertex, may be empty (flat shading)
  std::vector<glm::vec2> uvs;         // per vertex, may be empty
  std::vector<glm::uvec3> triangles;  // vertex indices
  std::vector<uint32_t> materials;    // per triangle, index into Scene::materials

  uint32_t triangle_count() const { return uint32_t(triangles.size()); }
};

// RGBA8 texels, row 0 = the first row of the image file. Texture coordinates wrap (repeat);
// v = 0 is the last row (OBJ convention; the glTF loader flips v on load so that one rule holds).
// The uv -> texel mapping used for alpha keying lives in common/shared/alpha.h, shared with the
// shaders.
struct Texture {
  std::string path;  // where it came from ("" for generated textures)
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;  // width * height * 4
  bool has_alpha = false;     // any texel with alpha < 255

  glm::u8vec4 texel(uint32_t x, uint32_t y) const {
    const size_t i = (size_t(y) * width + x) * 4;
    return {rgba[i], rgba[i + 1], rgba[i + 2], rgba[i + 3]};
  }
};

struct Material {
  std::string name;
  glm::vec3 diffuse{0.8f};      // Kd / baseColorFactor
  int32_t diffuse_texture = -1; // index into Scene::textures, -1 none
  int32_t alpha_texture = -1;   // alpha mask (map_d / glTF MASK): texel alpha < 0.5 = no surface
  float glossiness = 0.0f;      // 0 = diffuse only; in (0,1]: glossy reflection, 1 = mirror
  float opacity = 1.0f;         // d / Tr (informational; only the alpha mask cuts geometry)

  bool alpha_keyed() const { return alpha_texture >= 0; }
};

// How an instance moves over time. The transform at time t is
//   path(t) * rotation(t) * base, with rotation about `axis` through `pivot` (in the instance's
//   parent space, i.e. after `base`) and path a piecewise-linear loop through `path_points`.
struct Motion {
  glm::vec3 axis{0.0f, 1.0f, 0.0f};
  glm::vec3 pivot{0.0f};
  float angular_speed = 0.0f;          // radians per second
  std::vector<glm::vec3> path_points;  // offsets added to the position; empty: no path
  float path_period = 1.0f;            // seconds for one loop through path_points

  bool moves() const { return angular_speed != 0.0f || path_points.size() > 1; }
  glm::mat4 at(float time) const;      // the motion's matrix at `time` (identity if none)
};

struct Instance {
  std::string name;
  uint32_t mesh = 0;
  glm::mat4 transform{1.0f};  // base transform, object to world
  bool dynamic = false;       // re-inserted by the update pass every frame
  Motion motion;

  glm::mat4 transform_at(float time) const { return motion.at(time) * transform; }
};

struct Camera {
  glm::vec3 eye{0.0f, 1.0f, 5.0f};
  glm::vec3 target{0.0f, 1.0f, 0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float vfov_degrees = 60.0f;
};

struct Light {
  glm::vec3 position{0.0f, 10.0f, 0.0f};
  glm::vec3 color{1.0f};
  float intensity = 1.0f;  // radiant intensity scale; falloff 1/d^2 unless `directional`
  bool directional = false;  // then `position` is the direction towards the light
};

// Optional overrides of what the grid chooses from the scene (docs/SCENE_FORMAT.md, plan::settle_overrides).
struct GridOverrides {
  std::optional<glm::uvec3> resolution;  // cells per axis
  std::optional<uint32_t> capacity;      // triangle slots per cell
  std::optional<float> cell_size;        // world units; resolution follows from the bounds
};

struct Bounds {
  glm::vec3 lo{std::numeric_limits<float>::infinity()};
  glm::vec3 hi{-std::numeric_limits<float>::infinity()};
  bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
  void grow(const glm::vec3& p) { lo = glm::min(lo, p); hi = glm::max(hi, p); }
  void grow(const Bounds& b) { if (!b.empty()) { grow(b.lo); grow(b.hi); } }
  glm::vec3 extent() const { return hi - lo; }
};

struct Scene {
  std::string name;
  std::vector<Mesh> meshes;
  std::vector<Material> materials;
  std::vector<Texture> textures;
  std::vector<Instance> instances;  // static first, then dynamic (see finalize)
  std::optional<Camera> camera;     // none: frame_camera() chooses one from the bounds
  std::vector<Light> lights;        // none: a headlight at the camera is used for shading
  GridOverrides grid;
  glm::vec3 background{0.55f, 0.65f, 0.8f};  // environment colour on a miss

  // Split meshes over kMaxTrianglesPerMesh into several meshes (and their instances), order
  // instances static-first, check every limit and every number (NaN/inf coordinates, indices
  // out of range, empty scene). Throws Error with a message naming what is wrong.
  void finalize();
  // The checks of finalize, changing nothing: every tracer's build runs them (Tracer::build), so
  // a scene made in code and never finalized, or changed since, is refused naming the rule it
  // breaks (meshes unsplit or instances out of order included) instead of read out of bounds.
  void validate() const;

  uint32_t static_instance_count() const;
  bool has_dynamic() const;          // some instance is dynamic and moves
  bool has_alpha_masks() const;      // some material used by some instance is alpha keyed
  bool has_glossy() const;
  uint64_t triangle_count() const;   // over all instances
  Bounds bounds(float time = 0.0f) const;  // world bounds of all instances at `time`
  // Error where the scene's box at `time` has a largest side above 0 and below the domain's least
  // extent (shared::kDomainMinExtent, docs/SPEC.md "Domain"): `who` names the tracer.
  void require_extent(float time, const std::string& who) const;
  Camera frame_camera() const;       // camera, or one that frames the bounds
};

}  // namespace gridrt
