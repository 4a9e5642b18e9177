// builtin.h: scenes made from code, no files needed.
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "gridrt/common/scene.h"

namespace gridrt {

// Names accepted by make_builtin (and by `builtin:NAME` on the command line):
//   "atrium"   arches, columns, long thin triangles, alpha-masked foliage, a glossy floor, two
//              moving teapots (the embedded default scene of the tool)
//   "cornell"  the Cornell box (classic dimensions, closed by a front wall, camera inside)
//   "teapot"   the Utah teapot from Newell's Bezier patches
std::vector<std::string> builtin_names();

// Throws Error for an unknown name. The scene is finalized.
Scene make_builtin(std::string_view name);

// Newell's Utah teapot tessellated from its 28 Bezier patches (rim, body, handle, spout, lid; the
// original model has no bottom), `level` segments per patch side (1 <= level <= 128): one mesh,
// vertices welded along patch seams, no zero-area triangles, outward normals. Y up, the body's
// axis on the y axis, the open bottom at y = 0; about 1.63 wide (spout to handle), 0.75 high.
// Boundary edges are exactly those of the model's open rims: the bottom, the inner edge of the
// pot's rim, the edge of the lid, both ends of the handle, the base and the tip of the spout.
Mesh make_teapot_mesh(unsigned level);

// The 28 x 16 control points as stored (Geomview's teapot.bez: z up), row-major per patch.
std::span<const glm::vec3> teapot_control_points();
// The map from the stored frame to the scene's (y up) used by make_teapot_mesh.
glm::vec3 teapot_to_scene(const glm::vec3& p);

inline constexpr std::string_view kDefaultScene = "atrium";

}  // namespace gridrt
