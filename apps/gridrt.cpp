// gridrt: the command-line tool. Verbs: render, convert (and, with the grid, explain, stats, diff).
//
// Exit codes: 0 success, 1 a user error (bad input, limits, no device), 2 bad command line,
// 3 an internal error (a bug: please report it).
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include <CLI/CLI.hpp>

#include "apps/backends.h"
#include "apps/commands.h"
#include "common/builtin/builtin.h"
#include "common/scene.h"
#include "common/scene_io.h"

using namespace gridrt;

namespace gridrt::app {

Scene load_scene_or_default(const std::string& spec) {
  const std::string s = spec.empty() ? "builtin:" + std::string(kDefaultScene) : spec;
  const auto t0 = std::chrono::steady_clock::now();
  Scene scene = load_scene(s);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (secs > 1.0) std::fprintf(stderr, "loaded %s in %.1f s\n", s.c_str(), secs);
  return scene;
}

void check_output_path(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  if (!fs::is_directory(dir)) throw Error("cannot write '" + path + "': folder '" + dir.string() + "' does not exist");
}

}  // namespace gridrt::app

int main(int argc, char** argv) {
  CLI::App app{
      "gridrt: ray tracing without ray-tracing hardware. The fixed-capacity grid of\n"
      "\"Hybrid ray/voxel tracing with fixed-capacity grids\" as a CPU reference (the spec) and a\n"
      "Vulkan port, with Embree as the ground truth."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "gridrt 0.1.0");
  app::add_render_command(app);
  app::add_convert_command(app);
  app::add_explain_command(app);
  app::add_grid_commands(app);
  app::add_bench_command(app);
  app::add_portal_command(app);
  app::add_sweep_command(app);
  try {
    app.parse(argc, argv);
    return 0;
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints help, version or the parse error
    return code == 0 ? 0 : 2;
  } catch (const app::Differs& e) {
    std::fprintf(stderr, "gridrt: %s\n", e.what());
    return 3;
  } catch (const Error& e) {
    std::fprintf(stderr, "gridrt: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gridrt: internal error: %s\n", e.what());
    return 3;
  }
}
