// portal_bench: steps per ray and rays/s of the portal tracer against the voxel DDA on the same
// worlds, build time and memory (docs/PORTAL.md, "Measurements"). Not a test.
//   portal_bench [--width W] [--height H] [--threads T] [--resolution N] [--choice bounded|exact|both]
//                [--no-render] [--atlas-width N] [--choice-block B] [--choice-range R] [--per-run 2|3]
//                [WORLD...]
// WORLD: "builtin" (the built-in level), a .map file, or any scene spec load_scene accepts
// (builtin:teapot, data/scenes/bunny.json, ...), voxelized at --resolution (default 64).
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "gridrt/common/camera.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/reference/portal/trace.h"

using namespace gridrt;
using namespace gridrt::portal;

namespace {
double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
}  // namespace

int main(int argc, char** argv) try {
  uint32_t width = 720, height = 360, resolution = 64;
  unsigned threads = 0;
  std::vector<DivChoice> choices{DivChoice::bounded};
  bool no_render = false;
  uint32_t atlas_width = 1024, choice_block = 1, choice_range = 0, per_run = 2;
  std::vector<std::string> worlds;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&] { if (i + 1 >= argc) throw Error(a + " needs a value"); return std::string(argv[++i]); };
    if (a == "--width") width = uint32_t(std::stoul(next()));
    else if (a == "--height") height = uint32_t(std::stoul(next()));
    else if (a == "--threads") threads = unsigned(std::stoul(next()));
    else if (a == "--resolution") resolution = uint32_t(std::stoul(next()));
    else if (a == "--choice") {
      const std::string c = next();
      choices = c == "both" ? std::vector<DivChoice>{DivChoice::exact, DivChoice::bounded}
                            : std::vector<DivChoice>{parse_div_choice(c)};
    } else if (a == "--no-render") no_render = true;
    else if (a == "--atlas-width") atlas_width = uint32_t(std::stoul(next()));
    else if (a == "--choice-block") choice_block = uint32_t(std::stoul(next()));
    else if (a == "--choice-range") choice_range = uint32_t(std::stoul(next()));
    else if (a == "--per-run") per_run = uint32_t(std::stoul(next()));
    else worlds.push_back(a);
  }
  if (worlds.empty()) worlds = {"builtin", "builtin:teapot"};
  std::vector<std::string> notes;
  char line[1024];
  std::printf("| world | voxels | maximal divs | stored divs | build s | memory KiB | tracer | rays/s | steps/ray | hits |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& spec : worlds)
  for (const DivChoice choice : choices) {
    World w;
    const double t_load = now();
    if (spec == "builtin") w = builtin_level();
    else if (spec.rfind("gen:", 0) == 0) w = generated_level_spec(spec);
    else if (spec.size() > 4 && spec.substr(spec.size() - 4) == ".map") w = load_tile_map(spec);
    else w = voxelize(load_scene(spec), resolution);
    const double t_vox = now() - t_load;
    const double t0 = now();
    PortalOptions po;
    po.threads = threads;
    po.choice = choice;
    po.atlas_width = atlas_width;
    po.choice_block = choice_block;
    po.choice_range = choice_range;
    po.choice_per_run = per_run;
    PortalTracer pt(build_portal(w, po), po);
    const double t_build = now() - t0;
    const PortalBuild& b = pt.portal();
    const Camera cam = b.world.camera;
    const std::vector<Ray> rays = camera_rays(cam, width, height);
    std::vector<Hit> hp(rays.size()), hd(rays.size());
    VoxelDdaTracer dt(b.world);
    // Best of three for each tracer.
    double best_p = 1e30, best_d = 1e30;
    for (int rep = 0; rep < 3; ++rep) {
      double s = now();
      pt.trace(rays, hp);
      best_p = std::min(best_p, now() - s);
      s = now();
      dt.trace(rays, hd);
      best_d = std::min(best_d, now() - s);
    }
    uint64_t sp = 0, sd = 0, hits = 0, agree = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      sp += hp[i].cells, sd += hd[i].cells, hits += !is_miss(hp[i]);
      agree += hp[i].instance == hd[i].instance && hp[i].triangle == hd[i].triangle;
    }
    const double n = double(rays.size());
    char dims[64];
    std::snprintf(dims, sizeof dims, "%ux%ux%u", b.world.dims.x, b.world.dims.y, b.world.dims.z);
    const std::string label = spec + " (" + div_choice_name(choice) + ")";
    std::printf("| %s | %s | %zu | %zu | %.3f | %.0f | portal-cpu | %.3g | %.2f | %.1f%% |\n", label.c_str(), dims,
                b.stats.maximal, b.stats.divs, t_build, double(b.stats.bytes) / 1024.0, n / best_p, double(sp) / n,
                100.0 * double(hits) / n);
    std::printf("| | | | | | %.0f (occupancy) | voxel-dda | %.3g | %.2f | agree %.4f%% |\n",
                double(b.world.voxel_count() * 2) / 1024.0, n / best_d, double(sd) / n, 100.0 * double(agree) / n);
    std::snprintf(line, sizeof line,
                  "%s: build phases: maximal %.3f s, flux table %.3f s, choice %.3f s (%zu faces chosen, %zu candidate "
                  "evaluations), pack %.3f s; voxelize/load %.3f s",
                  label.c_str(), b.stats.seconds_maximal, b.stats.seconds_flux, b.stats.seconds_choice, b.stats.faces_chosen,
                  b.stats.candidates_evaluated, b.stats.seconds_pack, t_vox);
    notes.push_back(line);
    if (no_render) {
      std::fflush(stdout);
      continue;
    }
    // The renderer: primary + 2 shadow rays per pixel, FSM and separate loops.
    RenderOptions ro;
    ro.width = width, ro.height = height, ro.threads = threads;
    RenderStats fsm, loops;
    ro.state_machine = true;
    render(b, cam, ro, &fsm);
    ro.state_machine = false;
    render(b, cam, ro, &loops);
    std::snprintf(line, sizeof line,
                 "%s: render %ux%u primary + 2 shadow: FSM %.3f s (%.1f fps), loops %.3f s; %.2f steps/primary ray, %.2f "
                 "steps/shadow ray, %llu shadow rays",
                 label.c_str(), width, height, fsm.seconds, 1.0 / fsm.seconds, loops.seconds,
                 double(fsm.primary_steps) / double(fsm.primary_rays),
                 fsm.shadow_rays ? double(fsm.shadow_steps) / double(fsm.shadow_rays) : 0.0,
                 (unsigned long long)fsm.shadow_rays);
    notes.push_back(line);
    std::fflush(stdout);
  }
  std::printf("\n");
  for (const std::string& n : notes) std::printf("- %s\n", n.c_str());
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "portal_bench: %s\n", e.what());
  return 1;
}
