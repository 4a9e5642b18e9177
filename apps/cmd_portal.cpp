// The portal-div raytracer in the tool: `gridrt portal render` and `gridrt portal explain`, and
// `gridrt render --backend portal-cpu` (which lands here).
#include <chrono>
#include <cstdio>

#include "apps/commands.h"
#include "common/camera.h"
#include "common/image_io.h"
#include "common/scene_io.h"
#include "reference/portal/build.h"
#include "reference/portal/trace.h"
#include "reference/portal/world.h"

namespace gridrt::app {

namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

// A world from a tile map (.map), the built-in level (empty or builtin:level), or any scene
// voxelized at `voxels` per longest axis.
portal::World load_world(const std::string& spec, uint32_t voxels) {
  if (spec.empty() || spec == "builtin:level") return portal::builtin_level();
  if (ends_with(spec, ".map")) return portal::load_tile_map(spec);
  const Scene scene = load_scene_or_default(spec);
  return portal::voxelize(scene, voxels);
}

void run_portal_render(const PortalRenderOptions& o) {
  check_output_path(o.output);
  check_image_extension(o.output);
  if (o.backend != "portal-cpu")
    throw Error("backend '" + o.backend + "' is not built for portal worlds (this build has: portal-cpu)");
  portal::World world = load_world(o.scene, o.voxels);
  const Camera camera = world.camera;
  auto t0 = std::chrono::steady_clock::now();
  portal::PortalOptions options;
  const portal::PortalBuild build = portal::build_portal(std::move(world), options);
  const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  portal::RenderOptions ro;
  ro.width = o.width;
  ro.height = o.height;
  ro.state_machine = !o.separate_loops;
  portal::RenderStats stats;
  const std::vector<glm::vec3> rgb = portal::render(build, camera, ro, &stats);
  write_image(o.output, o.width, o.height, rgb);
  std::fprintf(stderr,
               "portal-cpu: %s: %zu divs built in %.2f s; %llu primary + %llu shadow rays, %.2f divs per primary ray, "
               "rendered in %.3f s -> %s\n",
               build.world.name.c_str(), build.divs.size(), build_s, (unsigned long long)stats.primary_rays,
               (unsigned long long)stats.shadow_rays,
               stats.primary_rays ? double(stats.primary_steps) / double(stats.primary_rays) : 0.0, stats.seconds,
               o.output.c_str());
}

void add_portal_command(CLI::App& app) {
  CLI::App* portal_cmd = app.add_subcommand("portal", "The portal-div raytracer (maximal empty cuboids, stackless)");
  portal_cmd->require_subcommand(1);
  {
    auto o = std::make_shared<PortalRenderOptions>();
    CLI::App* cmd = portal_cmd->add_subcommand("render", "Render a world: one primary and two shadow rays per pixel");
    cmd->add_option("world", o->scene, "A tile map (.map), builtin:level (default), or a scene to voxelize");
    cmd->add_option("--voxels", o->voxels, "Voxels along a voxelized scene's longest axis")->check(CLI::Range(1u, 255u));
    cmd->add_option("--width", o->width, "Image width")->check(CLI::Range(1u, 16384u));
    cmd->add_option("--height", o->height, "Image height")->check(CLI::Range(1u, 16384u));
    cmd->add_flag("--separate-loops", o->separate_loops, "Three loops (primary, shadow 1, shadow 2), not the state machine");
    cmd->add_option("-o,--output", o->output, "Image file");
    cmd->callback([o] { run_portal_render(*o); });
  }
  {
    auto spec = std::make_shared<std::string>();
    auto voxels = std::make_shared<uint32_t>(64);
    auto size = std::make_shared<std::vector<uint32_t>>(std::vector<uint32_t>{720, 360});
    auto pixel = std::make_shared<std::vector<uint32_t>>();
    CLI::App* cmd = portal_cmd->add_subcommand("explain", "Every div, face and texel one pixel's primary ray visits");
    cmd->add_option("world", *spec, "A tile map (.map), builtin:level (default), or a scene to voxelize");
    cmd->add_option("--voxels", *voxels, "Voxels along a voxelized scene's longest axis")->check(CLI::Range(1u, 255u));
    cmd->add_option("--size", *size, "Image size W,H the pixel lies in")->delimiter(',')->expected(2)
        ->check(CLI::Range(1u, 16384u));
    cmd->add_option("--pixel,-p", *pixel, "The pixel X,Y")->delimiter(',')->expected(2)->required();
    cmd->callback([=] {
      const uint32_t w = (*size)[0], h = (*size)[1], x = (*pixel)[0], y = (*pixel)[1];
      if (x >= w || y >= h) throw Error("pixel outside the " + std::to_string(w) + "x" + std::to_string(h) + " image");
      portal::World world = load_world(*spec, *voxels);
      const Camera camera = world.camera;
      portal::PortalTracer tracer(std::move(world));
      const Ray ray = camera_ray(camera, w, h, x, y);
      std::printf("%s", tracer.explain(ray).c_str());
    });
  }
}

}  // namespace gridrt::app
