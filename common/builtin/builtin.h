// builtin.h: scenes made from code, no files needed.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "common/scene.h"

namespace gridrt {

// Names accepted by make_builtin (and by `builtin:NAME` on the command line):
//   "atrium"   arches, columns, long thin triangles, alpha-masked foliage, two moving teapots
//              (the embedded default scene of the tool)
//   "cornell"  the Cornell box
//   "teapot"   the Utah teapot from Newell's Bezier patches
std::vector<std::string> builtin_names();

// Throws Error for an unknown name. The scene is finalized.
Scene make_builtin(std::string_view name);

// Newell's Utah teapot tessellated from its 32 Bezier patches, `level` segments per patch side
// (level >= 1): one closed-as-far-as-the-model-is mesh with outward normals.
Mesh make_teapot_mesh(unsigned level);

inline constexpr std::string_view kDefaultScene = "atrium";

}  // namespace gridrt
