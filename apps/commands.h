// commands.h: the tool's verbs, each registered on the CLI11 app by one function.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "apps/backends.h"
#include "gridrt/common/scene.h"

namespace gridrt::app {

void add_render_command(CLI::App& app);   // cmd_render.cpp
void add_convert_command(CLI::App& app);  // cmd_convert.cpp
void add_grid_commands(CLI::App& app);    // cmd_grid.cpp: stats
void add_explain_command(CLI::App& app);  // cmd_explain.cpp
void add_diff_command(CLI::App& app);     // cmd_diff.cpp: the reference against the Vulkan port

// Thrown by a verb to end the tool with this exit status after it has reported (diff: 3 differ,
// 4 validation messages).
struct ExitStatus {
  int code;
};

// The tool's command line as given (gridrt.cpp sets it before parsing; diff repeats its grid flags
// in the explain command it prints).
extern std::vector<std::string> command_line;
void add_bench_command(CLI::App& app);    // cmd_bench.cpp
void add_portal_command(CLI::App& app);   // cmd_portal.cpp: portal render, portal explain

struct PortalRenderOptions {
  std::string scene;             // a .map, builtin:level, or a scene to voxelize
  std::string backend = "portal-cpu";
  std::string output = "render.png";
  uint32_t width = 720, height = 360;  // the paper's resolution
  uint32_t voxels = 64;
  bool separate_loops = false;
  std::string view = "shaded";   // shaded, or divs / dda: per-pixel work (portal_views.cpp)
  std::string div_choice = "bounded";  // bounded | exact (reference/portal/build.h)
  uint32_t atlas_width = 1024;
  uint32_t mip_levels = 1;       // mip-mapped space (docs/PORTAL.md): levels, 1 = none
  float mip_distance = 0.0f;     // the level rule's distance in voxels; 0: one voxel per pixel
  bool mip_compare = false;      // also render at full resolution and print the difference
  bool flatten = false;          // instanced worlds: trace the flattened world instead
  bool flat_compare = false;     // instanced worlds: also render the flattened world and compare
};

// Thrown by a diff whose two sides disagree: the tool exits with 3 (1 is bad input, 2 the command line).
struct Differs : std::runtime_error {
  using std::runtime_error::runtime_error;
};
void run_portal_render(const PortalRenderOptions& options);  // cmd_portal.cpp
void run_portal_view(const PortalRenderOptions& options);    // portal_views.cpp
void add_sweep_command(CLI::App& app);    // cmd_sweep.cpp: accuracy against Embree vs time
void add_verify_command(CLI::App& app);   // cmd_verify.cpp: adversarial rays, the exact referee

// render --view (views.cpp): a per-pixel picture of the grid's work with a colour bar or legend.
struct ViewOptions {
  std::string view = "shaded";   // one of view_names()
  std::string scene, backend, output;
  uint32_t width = 0, height = 0;
  float time = 0.0f;
  bool primary = false;          // camera rays instead of the glossy bounce
  int scale = 1;                 // pixels per image pixel in the figure
  BackendOptions backend_options;
};
const std::vector<std::string>& view_names();  // shaded (the plain render) first
void run_view(const ViewOptions& options);

// The scene named by SCENE (a scene file, a bare mesh, builtin:NAME), or the embedded default
// when `spec` is empty. Prints how long loading took when it took over a second.
Scene load_scene_or_default(const std::string& spec);

// Error unless the folder of `path` exists and `path` is not a folder (checked before hours of
// work, not after).
void check_output_path(const std::string& path);
// check_output_path for an image, and its extension one of a format the tool writes: a name of no
// such format is the command line's error (OptionsError, exit 2) on every verb (render said 2 and
// portal render 1: an outside sweep).
void check_image_output(const std::string& path);

// The frame-buffer limit (--max-pixels): width x height of any image a verb renders or gathers.
struct FrameLimits {
  uint64_t max_pixels = uint64_t(1) << 25;  // 33.5 Mpixel, e.g. 8192 x 4096: about 3 GiB of frame buffers
};
FrameLimits& frame_limits();
// Error naming --max-pixels when width x height exceeds it.
void check_frame_size(uint32_t width, uint32_t height);

}  // namespace gridrt::app
