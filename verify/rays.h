// rays.h: adversarial ray families for checking a tracer against the exact referee (referee.h).
// Each family aims at a place where float ray/triangle tests and grid traversals are known to be
// fragile: shared edges and vertices hit exactly, axis-aligned and denormal directions, rays in
// the plane of axis-aligned triangles, origins on cell boundaries, grazing and far rays, and rays
// outside the domain (shared::ray_domain). Generation is deterministic for a seed.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "gridrt/common/scene.h"
#include "gridrt/common/tracer.h"
#include "gridrt/reference/grid.h"

namespace gridrt::verify {

enum class Family {
  camera,      // the frame camera's primary rays
  bounce,      // off the primary hits: mirror and cosine-diffuse directions, launch ref and normal
  random,      // origins uniform in the grid box, directions uniform on the sphere
  surface,     // launched from triangle interiors, vertices and edge midpoints: in front, behind, grazing
  edge,        // through a point exactly on an edge shared by two triangles (checked exactly)
  vertex,      // through a vertex shared by three or more triangles, exactly
  axis,        // axis-aligned directions; zero, signed-zero and denormal components
  plane,       // lying in the plane of an axis-aligned triangle
  lattice,     // origins on cell boundary planes and on lattice corners
  graze,       // grazing the largest triangles
  far,         // origins 1e4 to 1e6 away from the scene, aimed at its surfaces
  degenerate,  // outside the domain or empty: huge, tiny, inf and NaN components, tmin >= tmax, tmin < 0
};
inline constexpr size_t kFamilies = 12;
const char* to_string(Family f);
std::optional<Family> family_from_string(const std::string& name);
std::vector<Family> all_families();
std::string family_list();  // "camera, bounce, ..."

// A ray of a family, and the triangles it was aimed through (refs, for the referee's candidates).
struct FamilyRays {
  Family family = Family::camera;
  std::vector<Ray> rays;
  std::vector<std::vector<uint32_t>> aimed;  // per ray (may be empty): refs it was aimed at exactly
  size_t attempts = 0;                       // edge/vertex: constructions tried (not all exact)
};

// Triangles of the grid's geometry by vertex position, for shared edges and vertices.
struct Topology {
  std::vector<std::array<glm::vec3, 3>> tri;  // world space, per ref index order below
  std::vector<uint32_t> ref;                  // ref of tri[i]
  std::vector<std::vector<uint32_t>> by_vertex_index;  // per distinct position: indices into tri
  std::vector<glm::vec3> positions;            // distinct positions
  std::vector<std::array<uint32_t, 3>> corner;  // per tri: its positions' indices
  std::vector<std::pair<uint32_t, uint32_t>> shared_edges;  // position pairs with >= 2 triangles
  std::vector<uint32_t> shared_vertices;       // positions with >= 3 triangles
  std::vector<uint32_t> neighbours(uint32_t index) const;  // tri indices sharing a position with it
  size_t index_of(uint32_t ref) const;         // tri index of a ref (SIZE_MAX if none)
  std::vector<size_t> ref_to_index;            // dense: instance offset + triangle -> index
  std::vector<uint32_t> instance_offset;
};
Topology make_topology(const reference::GridData& grid);

struct FamilyOptions {
  size_t rays = 4000;   // per family (edge/vertex: at most; the exact constructions that succeed)
  uint64_t seed = 1;
};

// The rays of one family. `oracle` traces the camera rays the bounce family starts from.
FamilyRays make_family(Family f, const Scene& scene, const reference::GridData& grid, const Topology& topo,
                       Tracer& oracle, const FamilyOptions& options);

// The ray kinds of sweep/bench (--rays): glossy (the frame's glossy bounce rays), primary, bounce
// (mirror + diffuse off the primary hits), diffuse, random, or any family name. glossy and
// diffuse start from a gather buffer of width x height pixels (one ray per covered pixel); the
// others make width x height rays (edge and vertex: at most).
std::vector<Ray> rays_of_kind(const std::string& kind, const Scene& scene, const reference::GridData& grid,
                              Tracer& oracle, uint32_t width, uint32_t height, uint64_t seed = 1);
// Whether `kind` names rays_of_kind's rays (or "auto", the verbs' default); the list for messages.
bool is_ray_kind(const std::string& kind);
std::string ray_kind_list();

// A copy of `scene` moved by `offset` (instances frozen at time 0, camera, lights), for the
// translated runs.
Scene translated(const Scene& scene, glm::vec3 offset);

// Why the scene moved by `offset` is not a scene (its camera's eye and target, or its bounds,
// rounded to one point: a model far smaller than a float's step at the offset), or "" when it is
// one: the moved copy through Scene::finalize, the checks every loaded scene passes.
// `grid`: where given, the grid the moved scene would take is chosen too (an explicit cell size
// can be too fine for a float's step out there).
std::string translated_problem(const Scene& scene, glm::vec3 offset, const reference::GridOptions* grid = nullptr);

// A copy of `scene` without alpha masks (the referee judges geometry only).
Scene without_alpha(const Scene& scene);

}  // namespace gridrt::verify
