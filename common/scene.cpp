#include "gridrt/common/scene.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <cstdio>
#include <mutex>
#include <set>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>

#include "gridrt/common/safe_io.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/util.h"

namespace gridrt {

glm::mat4 Motion::at(float time) const {
  glm::mat4 m(1.0f);
  if (path_points.size() > 1 && path_period > 0.0f) {
    // Piecewise-linear closed loop through the path points, one loop per path_period.
    const float n = float(path_points.size());
    // The phase in double: in float, time / period at large times keeps no digit of the loop (a
    // period of 1 ms at 1e6 s: 1e9, whose float step is 64 loops)
    float phase = float(std::fmod(double(time) / double(path_period), 1.0));
    if (phase < 0.0f) phase += 1.0f;
    if (!(phase >= 0.0f && phase < 1.0f)) phase = 0.0f;  // a non-finite time (rejected by the callers)
    const float s = phase * n;
    const size_t i = std::min(size_t(s), path_points.size() - 1);
    const size_t j = (i + 1) % path_points.size();
    const float f = s - float(i);
    m = glm::translate(m, glm::mix(path_points[i], path_points[j], f));
  } else if (path_points.size() == 1) {
    m = glm::translate(m, path_points[0]);
  }
  if (angular_speed != 0.0f) {
    m = glm::translate(m, pivot);
    // The angle reduced modulo a turn in double precision: the float product loses the turn's
    // digits at large times (1e5 rad: a float step of 1/128 rad) and passes float range at larger
    // ones (a NaN rotation: the instance vanished from the frame)
    const float angle = float(std::fmod(double(angular_speed) * double(time), 2.0 * std::numbers::pi));
    m = glm::rotate(m, angle, glm::normalize(axis));
    m = glm::translate(m, -pivot);
  }
  return m;
}

namespace {

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

bool finite(const glm::mat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

// Split one mesh into pieces of at most kMaxTrianglesPerMesh triangles. Vertices are copied into
// each piece that uses them, so every piece is a self-contained mesh.
std::vector<Mesh> split_mesh(const Mesh& mesh) {
  std::vector<Mesh> pieces;
  const uint32_t n = mesh.triangle_count();
  for (uint32_t first = 0; first < n; first += kMaxTrianglesPerMesh) {
    const uint32_t last = std::min(n, first + kMaxTrianglesPerMesh);
    Mesh piece;
    piece.name = mesh.name + "#" + std::to_string(pieces.size());
    std::vector<uint32_t> remap(mesh.positions.size(), UINT32_MAX);
    for (uint32_t t = first; t < last; ++t) {
      glm::uvec3 tri;
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = mesh.triangles[t][k];
        if (remap[v] == UINT32_MAX) {
          remap[v] = uint32_t(piece.positions.size());
          piece.positions.push_back(mesh.positions[v]);
          if (!mesh.normals.empty()) piece.normals.push_back(mesh.normals[v]);
          if (!mesh.uvs.empty()) piece.uvs.push_back(mesh.uvs[v]);
        }
        tri[k] = remap[v];
      }
      piece.triangles.push_back(tri);
      piece.materials.push_back(mesh.materials.empty() ? 0u : mesh.materials[t]);
    }
    pieces.push_back(std::move(piece));
  }
  return pieces;
}

// Every mesh's sizes, indices and numbers, and the vertex limit
void validate_meshes(const Scene& s) {
  for (const Mesh& m : s.meshes) {
    const std::string where = "scene '" + s.name + "', mesh '" + m.name + "'";
    if (!m.normals.empty() && m.normals.size() != m.positions.size())
      throw Error(where + ": " + std::to_string(m.normals.size()) + " normals for " +
                  std::to_string(m.positions.size()) + " vertices");
    if (!m.uvs.empty() && m.uvs.size() != m.positions.size())
      throw Error(where + ": " + std::to_string(m.uvs.size()) + " texture coordinates for " +
                  std::to_string(m.positions.size()) + " vertices");
    if (!m.materials.empty() && m.materials.size() != m.triangles.size())
      throw Error(where + ": " + std::to_string(m.materials.size()) + " material ids for " +
                  std::to_string(m.triangles.size()) + " triangles");
    for (size_t i = 0; i < m.positions.size(); ++i)
      if (!finite(m.positions[i])) {
        std::ostringstream os;
        os << where << ": vertex " << i << " has a non-finite coordinate (" << m.positions[i].x
           << ", " << m.positions[i].y << ", " << m.positions[i].z << ")";
        throw Error(os.str());
      }
    for (size_t i = 0; i < m.normals.size(); ++i)
      if (!finite(m.normals[i])) throw Error(where + ": normal " + std::to_string(i) + " has a non-finite component");
    for (size_t i = 0; i < m.uvs.size(); ++i)
      if (!std::isfinite(m.uvs[i].x) || !std::isfinite(m.uvs[i].y))
        throw Error(where + ": texture coordinate " + std::to_string(i) + " is not finite");
    for (size_t t = 0; t < m.triangles.size(); ++t)
      for (int k = 0; k < 3; ++k)
        if (m.triangles[t][k] >= m.positions.size())
          throw Error(where + ": triangle " + std::to_string(t) + " uses vertex " +
                      std::to_string(m.triangles[t][k]) + " of " + std::to_string(m.positions.size()));
    for (uint32_t mat : m.materials)
      if (mat >= s.materials.size())
        throw Error(where + ": material index " + std::to_string(mat) + " of " +
                    std::to_string(s.materials.size()));
  }
  uint64_t vertices = 0;
  for (const Mesh& m : s.meshes) vertices += m.positions.size();
  if (vertices > input_limits().max_vertices)
    throw Error("scene '" + s.name + "' has " + std::to_string(vertices) + " vertices, more than the limit of " +
                std::to_string(input_limits().max_vertices));
}

// Every texture's size, material's values and instance's mesh, transform and motion
void validate_textures_materials_instances(const Scene& s) {
  for (const Texture& t : s.textures) {
    const std::string where = "scene '" + s.name + "', texture '" + t.path + "'";
    if (t.width == 0 || t.height == 0 || uint64_t(t.width) * t.height > input_limits().max_texture_pixels)
      throw Error(where + ": size " + std::to_string(t.width) + " x " + std::to_string(t.height) +
                  " is zero or above the limit of " + std::to_string(input_limits().max_texture_pixels) +
                  " pixels (--max-texture-pixels)");
    if (t.rgba.size() != uint64_t(t.width) * t.height * 4)
      throw Error(where + ": " + std::to_string(t.rgba.size()) + " bytes for " + std::to_string(t.width) + " x " +
                  std::to_string(t.height) + " RGBA8 texels");
  }
  for (const Material& mat : s.materials) {
    const std::string where = "scene '" + s.name + "', material '" + mat.name + "'";
    if (!finite(mat.diffuse) || mat.diffuse.x < 0.0f || mat.diffuse.y < 0.0f || mat.diffuse.z < 0.0f)
      throw Error(where + ": the diffuse colour must be finite and not negative");
    if (!(mat.opacity >= 0.0f && mat.opacity <= 1.0f))
      throw Error(where + ": opacity must lie in [0, 1]");
    for (int32_t tex : {mat.diffuse_texture, mat.alpha_texture})
      if (tex < -1) throw Error(where + ": texture index " + std::to_string(tex) + " (only -1 means none)");
    for (int32_t tex : {mat.diffuse_texture, mat.alpha_texture})
      if (tex >= int32_t(s.textures.size()))
        throw Error("material '" + mat.name + "' uses texture " + std::to_string(tex) + " of " +
                    std::to_string(s.textures.size()));
    if (!(mat.glossiness >= 0.0f && mat.glossiness <= 1.0f))
      throw Error("material '" + mat.name + "': glossiness must lie in [0, 1]");
  }
  for (const Instance& inst : s.instances) {
    if (inst.mesh >= s.meshes.size())
      throw Error("instance '" + inst.name + "' uses mesh " + std::to_string(inst.mesh) + " of " +
                  std::to_string(s.meshes.size()));
    if (!finite(inst.transform) || !finite(inst.motion.axis) || !finite(inst.motion.pivot) ||
        !std::isfinite(inst.motion.angular_speed) || !std::isfinite(inst.motion.path_period))
      throw Error("instance '" + inst.name + "' has a non-finite transform or motion");
    // Affine, whatever the source (a .gridscene's last row was ignored; glTF refused it)
    if (inst.transform[0][3] != 0.0f || inst.transform[1][3] != 0.0f || inst.transform[2][3] != 0.0f ||
        inst.transform[3][3] != 1.0f)
      throw Error("instance '" + inst.name + "': its transform is not affine (the last row is not 0 0 0 1)");
    for (const glm::vec3& p : inst.motion.path_points)
      if (!finite(p)) throw Error("instance '" + inst.name + "' has a non-finite path point");
    if (inst.motion.angular_speed != 0.0f && glm::length(inst.motion.axis) == 0.0f)
      throw Error("instance '" + inst.name + "' rotates about a zero axis");
    if (std::abs(inst.motion.angular_speed) > kMaxAngularSpeed)
      throw Error("instance '" + inst.name + "': angular speed beyond +-1e6 radians per second");
    if (inst.motion.path_points.size() > 1 && !(inst.motion.path_period >= kMinPathPeriod))
      throw Error("instance '" + inst.name + "': path period must be at least 0.001 seconds");
  }
}

// Meshes split at the 16-bit triangle limit; every instance of a split mesh becomes one instance
// per piece, with the same transform and motion.
void split_large_meshes(Scene& s) {
  std::vector<std::vector<uint32_t>> pieces_of(s.meshes.size());
  std::vector<Mesh> out_meshes;
  for (size_t m = 0; m < s.meshes.size(); ++m) {
    if (s.meshes[m].triangle_count() <= kMaxTrianglesPerMesh) {
      pieces_of[m].push_back(uint32_t(out_meshes.size()));
      out_meshes.push_back(std::move(s.meshes[m]));
    } else {
      for (Mesh& piece : split_mesh(s.meshes[m])) {
        pieces_of[m].push_back(uint32_t(out_meshes.size()));
        out_meshes.push_back(std::move(piece));
      }
    }
  }
  s.meshes = std::move(out_meshes);
  std::vector<Instance> out_instances;
  for (const Instance& inst : s.instances)
    for (size_t p = 0; p < pieces_of[inst.mesh].size(); ++p) {
      Instance piece = inst;
      piece.mesh = pieces_of[inst.mesh][p];
      if (pieces_of[inst.mesh].size() > 1) piece.name += "#" + std::to_string(p);
      out_instances.push_back(std::move(piece));
    }
  // Static first, dynamic after: the order that makes dynamic ids "offset by the static count".
  std::stable_partition(out_instances.begin(), out_instances.end(),
                        [](const Instance& i) { return !i.dynamic; });
  s.instances = std::move(out_instances);
}

// The limits on instances and triangles after the split, and bounds with an extent
void validate_geometry(const Scene& s) {
  if (s.instances.size() > kMaxInstances)
    throw Error("scene '" + s.name + "' has " + std::to_string(s.instances.size()) +
                " instances after splitting meshes at 65,536 triangles; the 16-bit instance "
                "field of a reference holds at most 65,535");
  if (s.triangle_count() == 0) throw Error("scene '" + s.name + "' is empty: it has no triangles");
  if (s.triangle_count() > input_limits().max_triangles)
    throw Error("scene '" + s.name + "' has " + std::to_string(s.triangle_count()) +
                " triangles over its instances, more than the limit of " + std::to_string(input_limits().max_triangles) +
                " (--max-triangles)");
  const Bounds b = s.bounds(0.0f);
  const glm::vec3 e = b.extent();
  if (!finite(b.lo) || !finite(b.hi) || !finite(e) || !std::isfinite(glm::length(e)))
    throw Error("scene '" + s.name + "': the geometry's world bounds overflow single precision (coordinates too large)");
  if (std::max({e.x, e.y, e.z}) <= 0.0f)
    throw Error("scene '" + s.name + "': every vertex lies at one point (the geometry has no extent)");
}

// The scene's camera, or the one frame_camera() makes for a scene without one: either way the
// camera that renders it must be usable.
void validate_camera(const Scene& s) {
  const Camera c = s.frame_camera();
  // A framed camera fails for geometry far past the ray domain (its eye is kept inside): say so
  std::string whose = s.camera ? "camera" : "the camera framed around the geometry";
  if (!s.camera) {
    const Bounds b = s.bounds(0.0f);
    const float reach = std::max({std::abs(b.lo.x), std::abs(b.lo.y), std::abs(b.lo.z), std::abs(b.hi.x),
                                  std::abs(b.hi.y), std::abs(b.hi.z)});
    if (!(reach <= shared::kDomainMaxCoordinate))
      whose = "the geometry reaches " + std::to_string(reach) + " from the origin, beyond the ray domain's 2^24 " +
              "(docs/SPEC.md, \"Domain\"; move it nearer the origin or give the scene a camera), and the camera " +
              "framed around it";
  }
  if (!finite(c.eye) || !finite(c.target) || !finite(c.up) || !std::isfinite(c.vfov_degrees))
    throw Error("scene '" + s.name + "': " + whose + " has non-finite values");
  if (!(c.vfov_degrees > 0.0f && c.vfov_degrees < 180.0f)) {
    // As read, in single precision (179.9999999 is 180 there: it was refused as "outside (0, 180)")
    char v[32];
    std::snprintf(v, sizeof v, "%.9g", double(c.vfov_degrees));
    throw Error("scene '" + s.name + "': " + whose + ": its field of view, " + v +
                " degrees in single precision, lies outside (0, 180)");
  }
  if (c.eye == c.target) throw Error("scene '" + s.name + "': " + whose + ": eye equals its target");
  // Every primary ray starts at the eye: beyond the ray domain's origin limit each one would be
  // rejected (docs/SPEC.md, "Domain"), a picture of nothing. (frame_camera keeps its eye inside.)
  if (!(std::max({std::abs(c.eye.x), std::abs(c.eye.y), std::abs(c.eye.z)}) <= shared::kDomainMaxCoordinate))
    throw Error("scene '" + s.name + "': " + whose + ": the eye lies beyond 2^24 from the origin, outside the ray " +
                "domain (docs/SPEC.md, \"Domain\"): every primary ray would be rejected; move it nearer");
  // The view and up directions as the camera frame takes them (camera_frame: scaled by a power of
  // two into range, so any finite length but zero gives its direction; 1e-30 and 1e20 were refused
  // as underflowing or overflowing, and 1e-22 gave a wrong frame: an outside sweep)
  const glm::vec3 view = direction_in_range(c.target - c.eye), up = direction_in_range(c.up);
  // The camera framed around geometry whose distance overflows: refused with the geometry's reach
  // named (a model 1e38 away: its automatic light overflows too, and its cache would not load back)
  if (!s.camera && !std::isfinite(glm::length(c.target - c.eye)))
    throw Error("scene '" + s.name + "': " + whose + ": eye and target are too far apart (their distance overflows " +
                "single precision)");
  if (!finite(view))
    throw Error("scene '" + s.name + "': " + whose + ": eye and target are too far apart (their difference overflows " +
                "single precision)");
  if (!(glm::length(up) > 0.0f)) throw Error("scene '" + s.name + "': " + whose + ": up is zero");
  const glm::vec3 forward = glm::normalize(view);
  if (!(glm::length(glm::cross(forward, up)) > 1e-6f * glm::length(up)))
    throw Error("scene '" + s.name + "': " + whose + ": up is parallel to the view direction");
}

// Lights, background and the scene's grid overrides
void validate_lights_and_grid(const Scene& s) {
  for (size_t i = 0; i < s.lights.size(); ++i) {
    const Light& l = s.lights[i];
    const std::string where = "scene '" + s.name + "', light " + std::to_string(i);
    if (!finite(l.position) || !finite(l.color) || !std::isfinite(l.intensity))
      throw Error(where + ": non-finite values");
    if (l.intensity < 0.0f || l.color.x < 0.0f || l.color.y < 0.0f || l.color.z < 0.0f)
      throw Error(where + ": negative intensity or colour");
    // The shading takes colour * intensity: past a float's range it was inf, and a colour channel
    // of 0 times inf put NaN pixels in the float images (an outside sweep)
    if (!finite(l.color * l.intensity))
      throw Error(where + ": its colour times its intensity is beyond a float's range (about 3.4e38)");
    if (l.directional && !(glm::length(l.position) > 0.0f))
      throw Error(where + ": zero direction (a directional light needs a direction towards the light)");
  }
  if (!finite(s.background) || s.background.x < 0.0f || s.background.y < 0.0f || s.background.z < 0.0f)
    throw Error("scene '" + s.name + "': the background colour must be finite and not negative");
  if (s.grid.capacity && (*s.grid.capacity == 0 || *s.grid.capacity > 1024))
    throw Error("scene '" + s.name + "': grid capacity must lie in [1, 1024]");
  if (s.grid.resolution && (s.grid.resolution->x == 0 || s.grid.resolution->y == 0 || s.grid.resolution->z == 0))
    throw Error("scene '" + s.name + "': grid resolution must be at least 1 cell per axis");
  if (s.grid.cell_size && !(*s.grid.cell_size > 0.0f && std::isfinite(*s.grid.cell_size)))
    throw Error("scene '" + s.name + "': grid cell size must be a positive finite number");
  // As the scene file's reader says, for every source (a .gridscene with both had its resolution
  // dropped without a word: an outside sweep)
  if (s.grid.resolution && s.grid.cell_size)
    throw Error("scene '" + s.name + "': the grid gives both a resolution and a cell size, which both size it: one of them");
  for (const Instance& inst : s.instances)
    if (!inst.dynamic && inst.motion.moves())
      throw Error("scene '" + s.name + "', instance '" + inst.name +
                  "': a motion on a static instance (it would never move): mark it dynamic or leave the motion out");
}


void directions_in_range(Scene& s) {
  for (Light& l : s.lights)
    if (l.directional) l.position = direction_in_range(l.position);
  for (Instance& inst : s.instances) inst.motion.axis = direction_in_range(inst.motion.axis);
}

}  // namespace

// A direction (a directional light's, a rotation's axis) of any finite length: scaled by a power of
// two (exact: the same direction, in the same bits but for the exponent) so that its largest
// component lies in [1, 2) where it lies outside [2^-20, 2^20]. Normalizing it later then neither
// overflows (a length of 1e20 made dot(v, v) infinite: the light's direction became zero and it
// lit nothing) nor underflows (1e-25 was refused as a zero direction). Zero stays zero.
glm::vec3 direction_in_range(glm::vec3 v) {
  const float m = std::max(std::max(std::abs(v.x), std::abs(v.y)), std::abs(v.z));
  if (!(m > 0.0f) || !std::isfinite(m) || (m >= 0x1p-20f && m <= 0x1p20f)) return v;
  int e = 0;
  std::frexp(m, &e);  // m = f 2^e, f in [0.5, 1)
  return glm::vec3(std::ldexp(v.x, 1 - e), std::ldexp(v.y, 1 - e), std::ldexp(v.z, 1 - e));
}

void Scene::finalize() {
  if (materials.empty()) materials.push_back(Material{.name = "default"});
  directions_in_range(*this);
  validate_meshes(*this);
  validate_textures_materials_instances(*this);
  split_large_meshes(*this);
  validate();
}

void Scene::validate() const {
  if (materials.empty() && !meshes.empty())
    throw Error("scene '" + name + "' has no material (finalize gives it a default one)");
  validate_meshes(*this);
  validate_textures_materials_instances(*this);
  // What finalize makes of a valid scene: meshes within the 16-bit triangle field, static instances first
  for (const Mesh& m : meshes)
    if (m.triangle_count() > kMaxTrianglesPerMesh)
      throw Error("scene '" + name + "', mesh '" + m.name + "' has " + std::to_string(m.triangle_count()) +
                  " triangles, more than a mesh may hold (" + std::to_string(kMaxTrianglesPerMesh) +
                  "): Scene::finalize splits it");
  for (size_t i = 1; i < instances.size(); ++i)
    if (instances[i - 1].dynamic && !instances[i].dynamic)
      throw Error("scene '" + name + "', instance '" + instances[i].name +
                  "' is static after a dynamic one: Scene::finalize orders them static first");
  validate_geometry(*this);
  validate_camera(*this);
  validate_lights_and_grid(*this);
}

uint32_t Scene::static_instance_count() const {
  return uint32_t(std::count_if(instances.begin(), instances.end(),
                                [](const Instance& i) { return !i.dynamic; }));
}

bool Scene::has_dynamic() const {
  return std::any_of(instances.begin(), instances.end(),
                     [](const Instance& i) { return i.dynamic && i.motion.moves(); });
}

bool Scene::has_alpha_masks() const {
  for (const Instance& inst : instances)
    for (uint32_t m : meshes[inst.mesh].materials)
      if (materials[m].alpha_keyed()) return true;
  return false;
}

bool Scene::has_glossy() const {
  for (const Instance& inst : instances)
    for (uint32_t m : meshes[inst.mesh].materials)
      if (materials[m].glossiness > 0.0f) return true;
  return false;
}

uint64_t Scene::triangle_count() const {
  uint64_t n = 0;
  for (const Instance& inst : instances) n += meshes[inst.mesh].triangle_count();
  return n;
}

Bounds Scene::bounds(float time) const {
  Bounds b;
  for (const Instance& inst : instances) {
    const glm::mat4 m = inst.transform_at(time);
    for (const glm::vec3& p : meshes[inst.mesh].positions) b.grow(glm::vec3(m * glm::vec4(p, 1.0f)));
  }
  return b;
}

void Scene::require_extent(float time, const std::string& who) const {
  if (triangle_count() == 0) return;
  // The box over the motions' longest period (16 times, as the spill list's trial samples them):
  // the answer then does not depend on the time asked (a moving tiny model passed at one time and
  // was refused at another)
  double horizon = 0.0;
  for (const Instance& inst : instances) {
    if (!inst.motion.moves()) continue;
    if (inst.motion.path_points.size() > 1) horizon = std::max(horizon, double(inst.motion.path_period));
    if (inst.motion.angular_speed != 0.0f)
      horizon = std::max(horizon, 2.0 * std::numbers::pi / std::abs(double(inst.motion.angular_speed)));
  }
  horizon = std::min(horizon, 60.0);
  Bounds box = bounds(time);
  for (int k = 1; horizon > 0.0 && k < 16; ++k) {
    const float t = float(double(time) + horizon * k / 16.0);
    for (const Instance& inst : instances) {  // the moving ones: the others are where they were
      if (!inst.motion.moves()) continue;
      const glm::mat4 m = inst.transform_at(t);
      for (const glm::vec3& p : meshes[inst.mesh].positions) box.grow(glm::vec3(m * glm::vec4(p, 1.0f)));
    }
  }
  const glm::vec3 e = box.extent();
  const float side = std::max({e.x, e.y, e.z});
  if (side > 0.0f && side < shared::kDomainMinExtent) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", double(side));
    throw Error(who + ": scene '" + name + "' spans only " + buf +
                " (its box's largest side): below 2^-40 = 9.1e-13 the triangle tests' products of three "
                "coordinates leave float's normal range and hits are lost (docs/SPEC.md, \"Domain\"); scale it up");
  }
  // The same floor for each triangle, in a scene of any size: a closed cube 1e-18 across inside a
  // box 2 units across was passed through, and one 1e-15 across hit at a t 4e-4 off (an outside
  // sweep: the tests' products scale with the triangle's size squared, whatever the scene's box).
  // A warning, once a scene: the rest of the scene is traced as the domain promises
  uint64_t tiny = 0;
  float smallest = 0.0f;
  for (const Instance& inst : instances) {
    const glm::mat4 m = inst.transform_at(time);
    const Mesh& mesh = meshes[inst.mesh];
    for (const glm::uvec3& t : mesh.triangles) {
      const glm::vec3 a(m * glm::vec4(mesh.positions[t.x], 1.0f)), b(m * glm::vec4(mesh.positions[t.y], 1.0f)),
          c(m * glm::vec4(mesh.positions[t.z], 1.0f));
      if (shared::triangle_zero_area(a, b, c)) continue;
      const float longest = std::max({glm::length(b - a), glm::length(c - b), glm::length(a - c)});
      if (!(longest < shared::kDomainMinExtent)) continue;
      smallest = tiny == 0 ? longest : std::min(smallest, longest);
      ++tiny;
    }
  }
  if (tiny == 0) return;
  static std::mutex lock;
  static std::set<std::string> warned;
  const std::lock_guard<std::mutex> hold(lock);
  if (!warned.insert(name).second) return;
  std::fprintf(stderr,
               "gridrt: warning: scene '%s': %llu triangle(s) have every side below 2^-40 = 9.1e-13 (the smallest %g "
               "across): the triangle tests' products for them leave float's normal range, so hits on them can be "
               "lost or land at a wrong t (docs/ACCURACY.md, \"Triangles below the domain's floor\"); scale the "
               "model up\n",
               control_escaped(name).c_str(), (unsigned long long)tiny, double(smallest));
}

Camera Scene::frame_camera() const {
  if (camera) return *camera;
  const Bounds b = bounds(0.0f);
  Camera c;
  const glm::vec3 center = 0.5f * (b.lo + b.hi);
  const float radius = 0.5f * glm::length(b.extent());
  c.target = center;
  // Far enough to see the whole bounding sphere; and, for geometry tiny next to its distance from
  // the origin, at least 64 ulps of the centre away (2^-18 of its largest coordinate), so that the
  // eye differs from the target and the view direction is resolved to a few percent (a model of a
  // tenth of a unit at 1e5 then fills a tenth of the picture instead of a pixel); and at least
  // 2^-50, so that the view vector's squared length (normalize) does not underflow for a model at
  // a subnormal scale.
  const float reach = std::max({std::abs(center.x), std::abs(center.y), std::abs(center.z)});
  const float fit = radius / std::tan(glm::radians(c.vfov_degrees) * 0.5f);
  const float dist = std::max({fit, reach * 0x1p-18f, 0x1p-50f});
  c.eye = center + glm::vec3(0.0f, 0.25f, 1.0f) * dist;
  // And within the ray domain (docs/SPEC.md, "Domain"), where every primary ray can start: a model
  // reaching near its edge is seen from nearer than its whole bounding sphere needs (a picture of
  // part of it, not a picture of nothing); a model beyond it is refused by the grid.
  const float lim = shared::kDomainMaxCoordinate;
  c.eye = glm::clamp(c.eye, glm::vec3(-lim), glm::vec3(lim));
  return c;
}

}  // namespace gridrt
