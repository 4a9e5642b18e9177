// The portal-div raytracer in the tool: `gridrt portal render`, `gridrt portal explain` and
// `gridrt portal bench`, and `gridrt render --backend portal-cpu|portal-vulkan` (which lands here).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <memory>
#include <iostream>
#include <optional>
#include <sstream>

#include "apps/commands.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/image_io.h"
#include "gridrt/common/parallel.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/common/util.h"
#include "gridrt/reference/portal/build.h"
#include "gridrt/reference/portal/instance.h"
#include "gridrt/reference/portal/trace.h"
#include "gridrt/reference/portal/world.h"
#ifdef GRIDRT_HAVE_VULKAN
#  include "gridrt/vulkan/portal.h"
#endif

namespace gridrt::app {

namespace {

// Pixels the renderer ended at its iteration limit (sh::portal_pixel_iteration_limit): said, never
// silent (their rays cycled between divs, a camera far from the world: docs/PORTAL.md "Limits")
void warn_cut_pixels(const portal::RenderStats& s) {
  if (s.cut_pixels == 0) return;
  std::fprintf(stderr,
               "warning: %llu pixel(s) drawn as background: their rays passed the renderer's iteration limit, "
               "cycling between divs (a camera about 1e6 voxels or more from the world rounds its crossings; "
               "docs/PORTAL.md \"Limits\")\n",
               (unsigned long long)s.cut_pixels);
}

// A camera inside a solid voxel: every primary ray starts in a wall, and the picture is that wall's
// colour (builtin:cornell's eye lies 0.05 from its front wall, inside that wall's voxel at the
// default --voxels: a flat picture with exit 0, an outside sweep). Said, with what to change.
void warn_camera_in_wall(const portal::PortalBuild& build, const Camera& camera, uint32_t width, uint32_t height) {
  const Ray r = camera_ray(camera, width, height, width / 2, height / 2);
  const Hit h = portal::trace_portal(build.packed, r);
  if (is_miss(h) || (h.triangle & ((1u << shared::kPortalFaceBits) - 1u)) != shared::kPortalFaceInside) return;
  std::fprintf(stderr,
               "warning: the camera lies inside a solid voxel (voxels of %g units): the primary rays start in a wall "
               "and the picture shows the wall's colour; give more --voxels (thinner walls) or move the eye\n",
               double(build.packed.voxel_size));
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string portal_backends() {
#ifdef GRIDRT_HAVE_VULKAN
  return "portal-cpu, portal-vulkan";
#else
  return "portal-cpu";
#endif
}

void check_portal_backend(const std::string& backend) {
  if (backend == "portal-cpu") return;
#ifdef GRIDRT_HAVE_VULKAN
  if (backend == "portal-vulkan") return;
#endif
  throw OptionsError("backend '" + backend + "' is not built for portal worlds (this build has: " + portal_backends() + ")");
}

}  // namespace

// Mip-mapped space: the level rule's distance. Given (> 0) or, by default, the distance in voxels
// at which one pixel of a `height`-pixel image spans one voxel: height / (2 tan(vfov / 2)).
float mip_distance_for(float given, const Camera& camera, uint32_t height) {
  if (given > 0.0f) return given;
  return float(height) / (2.0f * camera_frame(camera).tan_half_fov);
}

void add_mip_options(CLI::App* cmd, uint32_t& levels, float& distance) {
  cmd->add_option("--mip-levels", levels,
                  "Mip-mapped space: levels of coarser divs (1 = none; level l has 2^l voxels per coarse voxel)")
      ->check(CLI::Range(1u, shared::kPortalMaxLevels));
  cmd->add_option("--mip-distance", distance,
                  "Mip-mapped space: a ray moves to level l at distance mip-distance * 2^l voxels from its origin "
                  "(default: where one pixel spans one voxel); needs --mip-levels 2 or more")
      // 0 is the "not given" of the default, not a distance: the range is open at 0
      ->check(CLI::Validator(
          [](std::string& v) {
            const double d = std::strtod(v.c_str(), nullptr);
            // as the float it is kept in (1e-50 became 0, the default's "not given")
            return float(d) > 0.0f && d <= 1e9 ? std::string() : std::string("must lie in (0, 1e9], above 1e-38");
          },
          "FLOAT in (0 - 1e+09]"));
}

// --mip-distance without coarse levels has nothing to move to (it was ignored without a word).
void check_mip_distance(uint32_t levels, float distance) {
  if (distance != 0.0f && levels < 2)
    throw CLI::ValidationError("--mip-distance", "needs --mip-levels 2 or more (without coarse levels it does nothing)");
}

// A world from a tile map (.map), the built-in level (empty or builtin:level), a generated level
// (gen:WxDxH[:SEED]), or any scene voxelized at `voxels` per longest axis.
// Instanced worlds (block maps: builtin:blocks, gen-blocks:WxDxH[:SEED], a .map starting with
// `scale`) are flattened here; the portal verbs build them instanced (load_instanced).
std::optional<portal::InstancedWorld> load_instanced(const std::string& spec) {
  if (spec == "builtin:blocks") return portal::builtin_blocks();
  if (spec.rfind("gen-blocks:", 0) == 0) return portal::generated_blocks_spec(spec);
  if (ends_with(spec, ".map")) {
    const std::string text = normalize_text(read_input_file(spec, "tile map"));
    if (portal::is_block_map(text)) return portal::parse_block_map(text, spec);
  }
  return std::nullopt;
}

portal::World load_world(const std::string& spec, uint32_t voxels) {
  if (std::optional<portal::InstancedWorld> iw = load_instanced(spec)) return portal::flatten(*iw);
  if (spec.empty() || spec == "builtin:level") return portal::builtin_level();
  if (spec.rfind("gen:", 0) == 0) return portal::generated_level_spec(spec);
  if (ends_with(spec, ".map")) return portal::load_tile_map(spec);
  try {
    const Scene scene = load_scene_or_default(spec);
    return portal::voxelize(scene, voxels);
  } catch (const Error& e) {
    // The scenes' list of built-in names leaves out the portal verbs' own worlds (an outside sweep)
    if (spec.rfind("builtin:", 0) != 0 || std::string(e.what()).find("unknown built-in scene") == std::string::npos)
      throw;  // as it is
    throw Error(std::string(e.what()) + "; the portal verbs' own worlds: builtin:level, builtin:blocks");
  }
}

// --voxels voxelizes a scene and --flatten flattens a block map: given for another kind of world
// they did nothing, without a word (an outside sweep). OptionsError (exit 2).
void check_world_options(const CLI::App* cmd, const std::string& spec) {
  const bool map = spec.empty() || spec == "builtin:level" || spec == "builtin:blocks" || spec.rfind("gen:", 0) == 0 ||
                   spec.rfind("gen-blocks:", 0) == 0 || ends_with(spec, ".map");
  if (cmd->get_option_no_throw("--voxels") && cmd->count("--voxels") > 0 && map)
    throw OptionsError("--voxels voxelizes a scene or mesh: '" + (spec.empty() ? std::string("builtin:level") : spec) +
                       "' is a tile or block map, voxels already (leave it out)");
  if (cmd->get_option_no_throw("--flatten") && cmd->count("--flatten") > 0 && !load_instanced(spec))
    throw OptionsError("--flatten flattens an instanced world (a block map): '" +
                       (spec.empty() ? std::string("builtin:level") : spec) + "' is not one (leave it out)");
}

// The portal build's options from the verbs' --div-choice and --atlas-width.
portal::PortalOptions portal_options(const std::string& div_choice, uint32_t atlas_width, bool progress) {
  portal::PortalOptions options;
  options.progress = progress;
  options.choice = portal::parse_div_choice(div_choice);
  options.atlas_width = atlas_width;
  return options;
}

// The camera of `spec` (a block map's own, not flattened).
// (Its load's warnings are the build's, said there: this extra load printed them twice or three
// times with --mip-levels, an outside sweep; the world's loaders warn on std::cerr.)
Camera world_camera(const std::string& spec, uint32_t voxels) {
  std::ostringstream quiet;
  std::streambuf* const was = std::cerr.rdbuf(quiet.rdbuf());
  struct Restore {
    std::streambuf* buf;
    ~Restore() { std::cerr.rdbuf(buf); }
  } restore{was};
  if (std::optional<portal::InstancedWorld> iw = load_instanced(spec)) return iw->top.camera;
  return load_world(spec, voxels).camera;
}

// The world of `spec` built: instanced (block maps, unless `flat`), else as load_world.
struct BuiltWorld {
  portal::PortalBuild build;
  Camera camera;
  double seconds = 0;
  std::optional<portal::InstancedWorld> instanced;  // the block map, when built instanced
};
BuiltWorld build_world(const std::string& spec, uint32_t voxels, const portal::PortalOptions& options, bool flat) {
  BuiltWorld b;
  std::optional<portal::InstancedWorld> iw = load_instanced(spec);
  if (iw && !flat) {
    b.camera = iw->top.camera;
    const auto t0 = std::chrono::steady_clock::now();
    b.build = portal::build_instanced(*iw, options);
    b.seconds = seconds_since(t0);
    b.instanced = std::move(iw);
    return b;
  }
  portal::World world = iw ? portal::flatten(*iw) : load_world(spec, voxels);
  b.camera = world.camera;
  const auto t0 = std::chrono::steady_clock::now();
  b.build = portal::build_portal(std::move(world), options);
  b.seconds = seconds_since(t0);
  return b;
}

// The structure's size: divs (top level + blocks) and the textures' bytes.
std::string build_size_text(const portal::PortalBuild& b) {
  char buf[256];
  const portal::PackedPortal& p = b.packed;
  if (p.scale_log2)
    std::snprintf(buf, sizeof buf, "%u divs (%u top level + %zu in %u blocks), %.0f KiB", p.div_count, p.top_divs,
                  b.block_divs, p.blocks, double(p.bytes()) / 1024.0);
  else
    std::snprintf(buf, sizeof buf, "%u divs, %.0f KiB", p.div_count, double(p.bytes()) / 1024.0);
  return buf;
}

void run_portal_render(const PortalRenderOptions& o) {
  check_frame_size(o.width, o.height);
  check_image_output(o.output);
  check_portal_backend(o.backend);
  if (o.flat_compare && o.flatten) throw Error("--flat-compare renders both: leave out --flatten");
  const bool instanced = load_instanced(o.scene).has_value();
  if (o.flat_compare && !instanced) throw OptionsError("--flat-compare needs an instanced world (a block map)");
  portal::PortalOptions options = portal_options(o.div_choice, o.atlas_width, true);
  options.mip_levels = o.mip_levels;
  if (o.mip_levels > 1) {
    // The level rule's default distance needs the camera before the build.
    options.mip_distance = mip_distance_for(o.mip_distance, world_camera(o.scene, o.voxels), o.height);
  }
  if (o.mip_compare && o.mip_levels < 2) throw Error("--mip-compare needs --mip-levels 2 or more");
  BuiltWorld bw = build_world(o.scene, o.voxels, options, o.flatten);
  const Camera camera = bw.camera;
  portal::PortalBuild build = std::move(bw.build);
  const double build_s = bw.seconds;
  warn_camera_in_wall(build, camera, o.width, o.height);
  // --flat-compare: the flattened world, built and rendered on the same backend.
  std::optional<portal::PortalBuild> flat;
  double flat_build_s = 0;
  if (o.flat_compare) {
    BuiltWorld fw = build_world(o.scene, o.voxels, options, true);
    flat = std::move(fw.build);
    flat_build_s = fw.seconds;
  }
  const double flux_s = build.stats.seconds_flux;
  const std::string size_text = build_size_text(build);
  const std::string flat_size_text = flat ? build_size_text(*flat) : "";
  std::vector<glm::vec3> flat_rgb;
  portal::RenderStats flat_stats;
  portal::RenderOptions ro;
  ro.width = o.width;
  ro.height = o.height;
  ro.state_machine = !o.separate_loops;
  portal::RenderStats stats;
  std::vector<glm::vec3> rgb;
  const std::string name = build.world.name;
  const size_t divs = build.packed.div_count;
  std::string device;
  // --mip-compare: the same world without the coarse levels (level 0 only) on the same backend.
  std::vector<glm::vec3> full_rgb;
  portal::RenderStats full_stats;
  std::optional<portal::PortalBuild> full;
  if (o.mip_compare) {
    full = build;
    full->packed.levels = 1;  // the level rule never leaves level 0: the full-resolution tracer
  }
  if (o.backend == "portal-cpu") {
    rgb = portal::render(build, camera, ro, &stats);
    if (full) full_rgb = portal::render(*full, camera, ro, &full_stats);
    if (flat) flat_rgb = portal::render(*flat, camera, ro, &flat_stats);
  } else {
#ifdef GRIDRT_HAVE_VULKAN
    vulkan::PortalVulkanTracer tracer(std::move(build), options);
    rgb = tracer.render(camera, ro, &stats);
    rgb = tracer.render(camera, ro, &stats);  // the second run's time: the first pays for the pipeline
    device = " on " + tracer.context().info().name;
    if (full) {
      vulkan::PortalVulkanTracer full_tracer(std::move(*full), options);
      full_rgb = full_tracer.render(camera, ro, &full_stats);
      full_rgb = full_tracer.render(camera, ro, &full_stats);
    }
    if (flat) {
      vulkan::PortalVulkanTracer flat_tracer(std::move(*flat), options);
      flat_rgb = flat_tracer.render(camera, ro, &flat_stats);
      flat_rgb = flat_tracer.render(camera, ro, &flat_stats);
    }
#endif
  }
  for (const portal::RenderStats* s : {&stats, &full_stats, &flat_stats}) warn_cut_pixels(*s);
  if (o.mip_compare) {
    // Image quality of mip-mapped space against full resolution: RMSE and PSNR over the RGB
    // channels clamped to [0, 1] (as written), pixels that differ at all.
    double se = 0.0;
    size_t differ = 0;
    for (size_t i = 0; i < rgb.size(); ++i) {
      const glm::vec3 a = glm::clamp(rgb[i], 0.0f, 1.0f), b = glm::clamp(full_rgb[i], 0.0f, 1.0f);
      const glm::vec3 d = a - b;
      se += double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z;
      differ += std::memcmp(&rgb[i], &full_rgb[i], sizeof(glm::vec3)) != 0;
    }
    const double rmse = std::sqrt(se / (3.0 * double(rgb.size())));
    std::printf("mip %u levels, distance %.4g voxels, against full resolution: RMSE %.4f, PSNR %.2f dB, %zu of %zu pixels "
                "differ; steps per primary ray %.3f (full %.3f), per shadow ray %.3f (full %.3f); render %.3f s (full %.3f s)\n",
                o.mip_levels, double(options.mip_distance), rmse, rmse > 0 ? 20.0 * std::log10(1.0 / rmse) : INFINITY,
                differ, rgb.size(), double(stats.primary_steps) / double(stats.primary_rays),
                double(full_stats.primary_steps) / double(full_stats.primary_rays),
                stats.shadow_rays ? double(stats.shadow_steps) / double(stats.shadow_rays) : 0.0,
                full_stats.shadow_rays ? double(full_stats.shadow_steps) / double(full_stats.shadow_rays) : 0.0,
                stats.seconds, full_stats.seconds);
  }
  if (o.flat_compare) {
    size_t differ = 0;
    for (size_t i = 0; i < rgb.size(); ++i) differ += std::memcmp(&rgb[i], &flat_rgb[i], sizeof(glm::vec3)) != 0;
    const glm::uvec3 fd = build.packed.fine_dims();
    std::printf("instanced against flattened (%u x %u x %u fine voxels): %zu of %zu pixels differ; instanced %s, built in "
                "%.3f s (%.3f s of it the flux table, once per process); flattened %s, built in %.3f s; steps per primary ray %.3f (flattened %.3f), per shadow ray %.3f "
                "(flattened %.3f); render %.3f s (flattened %.3f s)\n",
                fd.x, fd.y, fd.z, differ, rgb.size(), size_text.c_str(), build_s, flux_s, flat_size_text.c_str(), flat_build_s,
                double(stats.primary_steps) / double(stats.primary_rays),
                double(flat_stats.primary_steps) / double(flat_stats.primary_rays),
                stats.shadow_rays ? double(stats.shadow_steps) / double(stats.shadow_rays) : 0.0,
                flat_stats.shadow_rays ? double(flat_stats.shadow_steps) / double(flat_stats.shadow_rays) : 0.0,
                stats.seconds, flat_stats.seconds);
  }
  write_image(o.output, o.width, o.height, rgb);
  std::fprintf(stderr,
               "%s%s: %s: %zu divs built in %.2f s; %llu primary + %llu shadow rays, %.2f divs per primary ray, "
               "rendered (%s) in %.3f s -> %s\n",
               o.backend.c_str(), device.c_str(), name.c_str(), divs, build_s, (unsigned long long)stats.primary_rays,
               (unsigned long long)stats.shadow_rays,
               stats.primary_rays ? double(stats.primary_steps) / double(stats.primary_rays) : 0.0,
               o.separate_loops ? "three loops" : "state machine", stats.seconds, o.output.c_str());
}

// Rays/s and steps per ray of portal-cpu, voxel-dda and (where built) portal-vulkan on the
// world's camera rays, best of `repeats`; then the renderer (primary + 2 shadow rays) as the
// state machine and as three loops (docs/PORTAL.md, "Measurements").
void run_portal_bench(const std::string& spec, uint32_t voxels, uint32_t width, uint32_t height, uint32_t repeats,
                      bool vulkan_only, const std::string& div_choice, uint32_t atlas_width, bool flat) {
  check_frame_size(width, height);
  const portal::PortalOptions options = portal_options(div_choice, atlas_width, false);
  BuiltWorld bw = build_world(spec, voxels, options, flat);
  const Camera camera = bw.camera;
  portal::PortalBuild build = std::move(bw.build);
  const double build_s = bw.seconds;
  const std::vector<Ray> rays = camera_rays(camera, width, height);
  const double n = double(rays.size());
  const bool instanced = build.packed.scale_log2 != 0;
  const glm::uvec3 vd = instanced ? build.packed.fine_dims() : build.world.dims;
  std::printf("world %s: %u x %u x %u voxels%s, %s (%s choice), built in %.2f s; %u x %u camera rays, best of %u\n",
              build.world.name.c_str(), vd.x, vd.y, vd.z, instanced ? " (instanced)" : "", build_size_text(build).c_str(),
              portal::div_choice_name(options.choice), build_s, width, height, repeats);
  std::printf("| tracer | device | ms | rays/s | steps/ray | hits |\n|---|---|---|---|---|---|\n");
  auto report = [&](const char* tracer, const std::string& device, double ms, const std::vector<Hit>& hits) {
    double steps = 0, hit = 0;
    for (const Hit& h : hits) steps += h.cells, hit += !is_miss(h);
    std::printf("| %s | %s | %.3f | %.3g | %.2f | %.1f%% |\n", tracer, device.c_str(), ms, n / (ms / 1000.0), steps / n,
                100.0 * hit / n);
  };
  std::vector<Hit> hits(rays.size()), cpu_hits;
  std::vector<glm::vec3> cpu_image;
  if (!vulkan_only) {
    portal::PortalTracer cpu(build, options);
    double best = 1e30;
    for (uint32_t r = 0; r < repeats; ++r) {
      const auto s = std::chrono::steady_clock::now();
      cpu.trace(rays, hits);
      best = std::min(best, seconds_since(s) * 1000.0);
    }
    report("portal-cpu", "CPU threads", best, hits);
    cpu_hits = hits;
    if (instanced && !bw.instanced) throw Error("portal bench: instanced build without its world");
    std::optional<portal::World> dda_world;
    if (!instanced) dda_world = build.world;
    else if (glm::all(glm::lessThanEqual(vd, glm::uvec3(portal::kMaxWorldAxis)))) dda_world = portal::flatten(*bw.instanced);
    if (dda_world) {  // the voxel DDA over the (flattened) voxels
      portal::VoxelDdaTracer dda(std::move(*dda_world));
      best = 1e30;
      std::vector<Hit> dda_hits(rays.size());
      for (uint32_t r = 0; r < repeats; ++r) {
        const auto s = std::chrono::steady_clock::now();
        dda.trace(rays, dda_hits);
        best = std::min(best, seconds_since(s) * 1000.0);
      }
      report("voxel-dda", "CPU threads", best, dda_hits);
      size_t same = 0;
      for (size_t i = 0; i < rays.size(); ++i)
        same += dda_hits[i].instance == hits[i].instance && dda_hits[i].triangle == hits[i].triangle &&
                std::memcmp(&dda_hits[i].t, &hits[i].t, 4) == 0;
      std::printf("portal-cpu vs voxel-dda: %zu of %zu hits identical (material, voxel, face, t)\n", same, rays.size());
    } else if (bw.instanced) {  // beyond flatten: the DDA over the instanced world's fine voxels
      std::vector<Hit> dda_hits(rays.size());
      best = 1e30;
      for (uint32_t r = 0; r < repeats; ++r) {
        const auto s = std::chrono::steady_clock::now();
        parallel_for(rays.size(), 0, [&](size_t i) { dda_hits[i] = portal::trace_dda_instanced(*bw.instanced, rays[i]); });
        best = std::min(best, seconds_since(s) * 1000.0);
      }
      report("voxel-dda (instanced voxels)", "CPU threads", best, dda_hits);
      size_t same = 0;
      for (size_t i = 0; i < rays.size(); ++i)
        same += dda_hits[i].instance == hits[i].instance && dda_hits[i].triangle == hits[i].triangle &&
                std::memcmp(&dda_hits[i].t, &hits[i].t, 4) == 0;
      std::printf("portal-cpu vs voxel-dda: %zu of %zu hits identical (material, voxel, face, t)\n", same, rays.size());
    }
    portal::RenderOptions ro;
    ro.width = width, ro.height = height;
    for (bool fsm : {true, false}) {
      ro.state_machine = fsm;
      double rbest = 1e30;
      portal::RenderStats st;
      for (uint32_t r = 0; r < repeats; ++r) {
        cpu_image = portal::render(build, camera, ro, &st);
        rbest = std::min(rbest, st.seconds * 1000.0);
      }
      std::printf("render portal-cpu %s: %.3f ms (%.1f fps), %.2f steps/primary ray, %.2f steps/shadow ray, %llu shadow "
                  "rays\n",
                  fsm ? "state machine" : "three loops", rbest, 1000.0 / rbest,
                  double(st.primary_steps) / double(st.primary_rays),
                  st.shadow_rays ? double(st.shadow_steps) / double(st.shadow_rays) : 0.0,
                  (unsigned long long)st.shadow_rays);
      warn_cut_pixels(st);
    }
  }
#ifdef GRIDRT_HAVE_VULKAN
  vulkan::PortalVulkanTracer gpu(std::move(build), options);
  const std::string dev = gpu.context().info().name;
  // Device time (timestamps) where they bracket dispatches; lavapipe: host time (docs/VULKAN.md).
  const bool host_time = gpu.context().info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE ||
                         !gpu.context().info().timestamp_valid_bits;
  double best = 1e30;
  for (uint32_t r = 0; r < repeats + 1; ++r) {  // one warm-up
    gpu.trace(rays, hits);
    if (r) best = std::min(best, host_time ? gpu.timings().trace_host_ms : gpu.timings().trace_ms);
  }
  report("portal-vulkan", dev + (host_time ? " (host ms)" : " (device ms)"), best, hits);
  if (!cpu_hits.empty()) {
    // The differential check on this device: records identical in bits, and identical but for t, u, v.
    size_t same = 0, discrete = 0;
    for (size_t i = 0; i < hits.size(); ++i) {
      const Hit &a = cpu_hits[i], &b = hits[i];
      same += std::memcmp(&a, &b, sizeof(Hit)) == 0;
      discrete += a.instance == b.instance && a.triangle == b.triangle && a.flags == b.flags && a.cells == b.cells &&
                  a.tests == b.tests;
    }
    std::printf("portal-vulkan vs portal-cpu: %zu of %zu hit records identical in bits, %zu identical in material, "
                "voxel, face, divs and texels\n", same, hits.size(), discrete);
  }
  std::vector<glm::vec3> fsm_image;
  portal::RenderOptions ro;
  ro.width = width, ro.height = height;
  for (bool fsm : {true, false}) {
    ro.state_machine = fsm;
    double rbest = 1e30;
    portal::RenderStats st;
    std::vector<glm::vec3> image;
    for (uint32_t r = 0; r < repeats + 1; ++r) {
      image = gpu.render(camera, ro, &st);
      if (r) rbest = std::min(rbest, host_time ? gpu.timings().render_host_ms : gpu.timings().render_ms);
    }
    std::printf("render portal-vulkan %s on %s: %.3f ms %s (%.1f fps), %.2f steps/primary ray, %.2f steps/shadow ray, "
                "%llu shadow rays\n",
                fsm ? "state machine" : "three loops", dev.c_str(), rbest, host_time ? "host" : "device",
                1000.0 / rbest, double(st.primary_steps) / double(st.primary_rays),
                st.shadow_rays ? double(st.shadow_steps) / double(st.shadow_rays) : 0.0,
                (unsigned long long)st.shadow_rays);
    warn_cut_pixels(st);
    if (fsm) fsm_image = image;
    const std::vector<glm::vec3>& ref = fsm ? cpu_image : fsm_image;
    if (ref.size() == image.size()) {
      size_t differ = 0;
      for (size_t i = 0; i < image.size(); ++i) differ += std::memcmp(&ref[i], &image[i], sizeof(glm::vec3)) != 0;
      std::printf("  %s: %zu of %zu pixels differ in bits\n",
                  fsm ? "vs the portal-cpu render" : "vs the portal-vulkan state machine", differ, image.size());
    }
  }
#else
  if (vulkan_only) throw Error("this build has no Vulkan port");
#endif
}

void add_flatten_option(CLI::App* cmd, bool& flat) {
  cmd->add_flag("--flatten", flat,
                "Instanced worlds (block maps): trace the flattened world (every instance written out as voxels)");
}

void add_world_options(CLI::App* cmd, std::string& spec, uint32_t& voxels, std::string& choice, uint32_t& atlas_width) {
  cmd->add_option("world", spec,
                  "A tile map (.map), builtin:level (default), gen:WxDxH[:SEED] (a generated level), a block map "
                  "(instanced: builtin:blocks, gen-blocks:WxDxH[:SEED], a .map starting with 'scale'), or a scene to "
                  "voxelize");
  cmd->add_option("--voxels", voxels, "Voxels along a voxelized scene's longest axis")->check(CLI::Range(1u, 253u));
  add_choice(cmd, "--div-choice", choice, {"bounded", "exact"}, "How divs are chosen: bounded (near-linear, default) or exact (small worlds)");
  cmd->add_option("--atlas-width", atlas_width, "Atlas texels per row (more for large worlds: the atlas has at most 65536 rows)")
      ->check(CLI::Range(1u, 65536u));
}

#ifdef GRIDRT_HAVE_VULKAN
struct PortalDiffOptions {
  std::string spec, choice = "bounded";
  uint32_t voxels = 64, width = 720, height = 360, ulps = 0, atlas_width = 1024;
  float uv = 0.0f;
  double pixels = 0.0;
  uint32_t mip_levels = 1;
  float mip_distance = 0.0f;
  bool flatten = false;
};

// Both tracers on the same build: every camera ray's record, then the state-machine render.
void run_portal_diff(const PortalDiffOptions& o) {
  check_frame_size(o.width, o.height);
  portal::PortalOptions options = portal_options(o.choice, o.atlas_width, false);
  options.mip_levels = o.mip_levels;
  if (o.mip_levels > 1) options.mip_distance = mip_distance_for(o.mip_distance, world_camera(o.spec, o.voxels), o.height);
  BuiltWorld bw = build_world(o.spec, o.voxels, options, o.flatten);
  const Camera camera = bw.camera;
  portal::PortalBuild build = std::move(bw.build);
  warn_camera_in_wall(build, camera, o.width, o.height);
  const std::string name = build.world.name;
  const std::vector<Ray> rays = camera_rays(camera, o.width, o.height);
  std::vector<Hit> ref(rays.size()), dev(rays.size());
  portal::RenderOptions ro;
  ro.width = o.width, ro.height = o.height;
  portal::RenderStats ref_stats, dev_stats;
  std::vector<glm::vec3> ref_image;
  {
    portal::PortalTracer cpu(build, options);
    cpu.trace(rays, ref);
    ref_image = portal::render(cpu.portal(), camera, ro, &ref_stats);
  }
  vulkan::PortalVulkanTracer gpu(std::move(build), options);
  gpu.trace(rays, dev);
  const std::vector<glm::vec3> dev_image = gpu.render(camera, ro, &dev_stats);
  size_t bits = 0, within = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const Hit &a = ref[i], &b = dev[i];
    if (std::memcmp(&a, &b, sizeof(Hit)) == 0) {
      ++bits, ++within;
      continue;
    }
    const bool discrete = a.instance == b.instance && a.triangle == b.triangle && a.flags == b.flags &&
                          a.cells == b.cells && a.tests == b.tests;
    int32_t ta, tb;
    std::memcpy(&ta, &a.t, 4), std::memcpy(&tb, &b.t, 4);
    const bool t_ok = uint32_t(std::abs(int64_t(ta) - int64_t(tb))) <= o.ulps;
    within += discrete && t_ok && std::abs(a.u - b.u) <= o.uv && std::abs(a.v - b.v) <= o.uv;
  }
  size_t pixels = 0;
  for (size_t i = 0; i < ref_image.size(); ++i) pixels += std::memcmp(&ref_image[i], &dev_image[i], sizeof(glm::vec3)) != 0;
  const bool stats_same = ref_stats.primary_steps == dev_stats.primary_steps &&
                          ref_stats.shadow_steps == dev_stats.shadow_steps && ref_stats.shadow_rays == dev_stats.shadow_rays &&
                          ref_stats.cut_pixels == dev_stats.cut_pixels;
  std::printf("portal diff: %s (%s choice%s), %ux%u, portal-cpu against portal-vulkan on %s\n", name.c_str(),
              o.choice.c_str(),
              o.mip_levels > 1 ? (", " + std::to_string(o.mip_levels) + " mip levels, distance " +
                                  std::to_string(options.mip_distance)).c_str() : "",
              o.width, o.height, gpu.context().info().name.c_str());
  std::printf("  hit records: %zu of %zu identical in bits, %zu within the tolerances\n", bits, rays.size(), within);
  std::printf("  render: %zu of %zu pixels differ in bits; steps and shadow rays %s (primary steps %llu / %llu, shadow "
              "steps %llu / %llu, shadow rays %llu / %llu)\n",
              pixels, ref_image.size(), stats_same ? "identical" : "DIFFER",
              (unsigned long long)ref_stats.primary_steps, (unsigned long long)dev_stats.primary_steps,
              (unsigned long long)ref_stats.shadow_steps, (unsigned long long)dev_stats.shadow_steps,
              (unsigned long long)ref_stats.shadow_rays, (unsigned long long)dev_stats.shadow_rays);
  warn_cut_pixels(ref_stats);
  const bool agree = within == rays.size() && stats_same && double(pixels) <= o.pixels * double(ref_image.size());
  std::printf("  %s\n", agree ? "agree" : "DIFFER");
  if (!agree) throw Differs("portal diff: portal-vulkan differs from portal-cpu (see above)");
}
#endif

void add_portal_command(CLI::App& app) {
  CLI::App* portal_cmd = app.add_subcommand("portal", "The portal-div raytracer (maximal empty cuboids, stackless)");
  portal_cmd->require_subcommand(1);
  {
    auto o = std::make_shared<PortalRenderOptions>();
    CLI::App* cmd = portal_cmd->add_subcommand("render", "Render a world: one primary and two shadow rays per pixel");
    add_world_options(cmd, o->scene, o->voxels, o->div_choice, o->atlas_width);
    add_mip_options(cmd, o->mip_levels, o->mip_distance);
    add_flatten_option(cmd, o->flatten);
    cmd->add_flag("--flat-compare", o->flat_compare,
                  "Instanced worlds: also build and render the flattened world, print the pixels that differ and both "
                  "structures' sizes");
    cmd->add_flag("--mip-compare", o->mip_compare,
                  "Also render without the coarse levels and print the difference (RMSE, PSNR, pixels) and the steps");
    add_image_size(cmd, o->width, o->height, "");
    cmd->add_flag("--separate-loops", o->separate_loops, "Three loops (primary, shadow 1, shadow 2), not the state machine");
    cmd->add_option("--backend,-b", o->backend, "Tracer: " + portal_backends());
    cmd->add_option("-o,--output", o->output, "Image file")->capture_default_str();
    add_choice(cmd, "--view", o->view, {"shaded", "divs", "dda"},
                    "What the picture shows: shaded (the render), or per pixel with a colour bar: divs (divs the "
                    "portal traversal visits per camera ray) or dda (voxels an exact voxel DDA steps through)");
    cmd->callback([o, cmd] {
      check_world_options(cmd, o->scene);
      // The per-pixel work views build the plain world at full resolution: options they would
      // ignore are refused (they were ignored, and the checks below skipped)
      if (o->view != "shaded" && (o->mip_levels > 1 || o->mip_distance != 0.0f || o->mip_compare || o->flatten ||
                                  o->flat_compare || o->separate_loops))
        throw CLI::ValidationError("--view " + o->view,
                                   "shows the plain world's per-pixel work: leave out --mip-levels, --mip-distance, "
                                   "--mip-compare, --flatten, --flat-compare and --separate-loops");
      if (o->flat_compare && o->flatten)
        throw CLI::ValidationError("--flat-compare", "renders both the instanced and the flattened world: leave out --flatten");
      if (o->mip_compare && o->mip_levels < 2)
        throw CLI::ValidationError("--mip-compare", "needs --mip-levels 2 or more");
      check_mip_distance(o->mip_levels, o->mip_distance);
      o->view == "shaded" ? run_portal_render(*o) : run_portal_view(*o);
    });
  }
  {
    auto spec = std::make_shared<std::string>();
    auto voxels = std::make_shared<uint32_t>(64);
    auto width = std::make_shared<uint32_t>(720), height = std::make_shared<uint32_t>(360);
    auto pixel = std::make_shared<std::vector<uint32_t>>();
    auto backend = std::make_shared<std::string>("portal-cpu");
    auto choice = std::make_shared<std::string>("bounded");
    auto atlas = std::make_shared<uint32_t>(1024);
    auto mip_levels = std::make_shared<uint32_t>(1);
    auto mip_distance = std::make_shared<float>(0.0f);
    auto flat = std::make_shared<bool>(false);
    CLI::App* cmd = portal_cmd->add_subcommand("explain", "Every div, face and texel one pixel's primary ray visits");
    add_world_options(cmd, *spec, *voxels, *choice, *atlas);
    add_flatten_option(cmd, *flat);
    add_mip_options(cmd, *mip_levels, *mip_distance);
    add_image_size(cmd, *width, *height, "of the image the pixel lies in");
    cmd->add_option("--pixel,-p", *pixel, "The pixel X,Y")->delimiter(',')->expected(2)->required();
    cmd->add_option("--backend,-b", *backend,
                    "Tracer: " + portal_backends() + " (portal-vulkan: the shader's own record beside the reference's)");
    cmd->callback([=] {
      check_world_options(cmd, *spec);
      check_portal_backend(*backend);
      check_mip_distance(*mip_levels, *mip_distance);
      check_frame_size(*width, *height);
      const uint32_t w = *width, h = *height, x = (*pixel)[0], y = (*pixel)[1];
      if (x >= w || y >= h) throw OptionsError("pixel outside the " + std::to_string(w) + "x" + std::to_string(h) + " image");
      portal::PortalOptions options = portal_options(*choice, *atlas, true);
      options.mip_levels = *mip_levels;
      if (*mip_levels > 1) options.mip_distance = mip_distance_for(*mip_distance, world_camera(*spec, *voxels), h);
      BuiltWorld bw = build_world(*spec, *voxels, options, *flat);
      const Ray ray = camera_ray(bw.camera, w, h, x, y);
#ifdef GRIDRT_HAVE_VULKAN
      if (*backend == "portal-vulkan") {
        vulkan::PortalVulkanTracer tracer(std::move(bw.build), options);
        std::printf("%s", tracer.explain(ray).c_str());
        return;
      }
#endif
      portal::PortalTracer tracer(std::move(bw.build), options);
      std::printf("%s", tracer.explain(ray).c_str());
    });
  }
  {
    auto spec = std::make_shared<std::string>();
    auto voxels = std::make_shared<uint32_t>(64);
    auto width = std::make_shared<uint32_t>(720), height = std::make_shared<uint32_t>(360);
    auto repeats = std::make_shared<uint32_t>(3);
    auto vulkan_only = std::make_shared<bool>(false);
    auto choice = std::make_shared<std::string>("bounded");
    auto atlas = std::make_shared<uint32_t>(1024);
    auto flat = std::make_shared<bool>(false);
    CLI::App* cmd = portal_cmd->add_subcommand(
        "bench", "Rays/s and steps per ray: portal-cpu, voxel-dda, portal-vulkan; the renderer as FSM and three loops");
    add_world_options(cmd, *spec, *voxels, *choice, *atlas);
    cmd->add_option("--width", *width, "Image width (the paper's: 720)")->check(CLI::Range(1u, 16384u));
    cmd->add_option("--height", *height, "Image height (the paper's: 360)")->check(CLI::Range(1u, 16384u));
    cmd->add_option("--repeat", *repeats, "Best of this many runs")->check(CLI::Range(1u, 1000u));
    cmd->add_flag("--vulkan-only", *vulkan_only, "Measure portal-vulkan only");
    add_flatten_option(cmd, *flat);
    cmd->callback([=] {
      check_world_options(cmd, *spec);
      run_portal_bench(*spec, *voxels, *width, *height, *repeats, *vulkan_only, *choice, *atlas, *flat);
    });
  }
  {
    auto spec = std::make_shared<std::string>();
    auto output = std::make_shared<std::string>();
    auto flat = std::make_shared<bool>(false);
    CLI::App* cmd = portal_cmd->add_subcommand(
        "export", "A block map as a triangle scene for the grid: a .json scene beside its .obj meshes (instances of the blocks)");
    cmd->add_option("world", *spec, "A block map: builtin:blocks, gen-blocks:WxDxH[:SEED] or a .map starting with 'scale'")
        ->required();
    cmd->add_option("-o,--output", *output,
                    "The scene file (.json); its meshes (NAME_*.obj) and materials (NAME.mtl) are written beside it, "
                    "replacing files of those names")->required();
    cmd->add_flag("--flatten", *flat, "One mesh of the flattened world instead of the blocks as instances");
    cmd->callback([=] {
      // The output's folder checked first, as every verb's (its message named a temporary file);
      // its extension is the command line's choice: exit 2 (it was 1: an outside sweep), any case
      check_output_path(*output);
      std::string ext = std::filesystem::path(*output).extension().string();
      for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
      if (ext != ".json")
        throw OptionsError("portal export: the output (-o) must be a .json scene file (its meshes are written beside "
                           "it), not '" + *output + "'");
      std::optional<portal::InstancedWorld> iw = load_instanced(*spec);
      if (!iw) throw Error("portal export: '" + *spec + "' is not a block map");
      const size_t triangles = portal::export_scene(*iw, *output, *flat);
      // The files beside it named too (an outside sweep: an existing NAME.mtl was replaced unsaid)
      const std::filesystem::path out(*output);
      const std::string stem = (out.parent_path() / out.stem()).string();
      std::printf("%s: %zu triangles%s -> %s (with %s.mtl and the meshes %s_*.obj beside it)\n", iw->top.name.c_str(),
                  triangles, *flat ? " (flattened, one mesh)" : " (blocks placed by instances)", output->c_str(),
                  stem.c_str(), stem.c_str());
    });
  }
#ifdef GRIDRT_HAVE_VULKAN
  {
    auto o = std::make_shared<PortalDiffOptions>();
    CLI::App* cmd = portal_cmd->add_subcommand(
        "diff", "portal-cpu against portal-vulkan: every camera ray's hit record and the render; exit 3 if they differ");
    add_world_options(cmd, o->spec, o->voxels, o->choice, o->atlas_width);
    add_mip_options(cmd, o->mip_levels, o->mip_distance);
    add_flatten_option(cmd, o->flatten);
    add_image_size(cmd, o->width, o->height, "");
    cmd->add_option("--ulps", o->ulps, "Allow t of otherwise identical hits to differ by this many ulps (default 0)")
        ->check(CLI::Range(0u, 1000000u));
    cmd->add_option("--uv-tolerance", o->uv, "Allow u, v of otherwise identical hits to differ by this much")
        ->check(CLI::Range(0.0f, 1.0f));
    cmd->add_option("--pixels", o->pixels, "Allow this fraction of the render's pixels to differ in bits (default 0)")
        ->check(CLI::Range(0.0, 1.0));
    cmd->callback([o, cmd] {
      check_world_options(cmd, o->spec);
      check_mip_distance(o->mip_levels, o->mip_distance);
      run_portal_diff(*o);
    });
  }
#endif
}

}  // namespace gridrt::app
