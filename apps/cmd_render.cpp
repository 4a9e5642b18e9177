// gridrt render: a frame (or an animation) of a scene through one backend: primary rays into a
// gather buffer, one glossy bounce off it, simple shading, an image file.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#include "apps/backends.h"
#include "apps/commands.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/image_io.h"
#include "gridrt/common/progress.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/shade.h"
#include "gridrt/common/util.h"
#include "gridrt/reference/grid.h"
#ifdef GRIDRT_HAVE_VULKAN
#  include "gridrt/vulkan/frame.h"
#endif

namespace gridrt::app {
namespace {

struct RenderOptions {
  std::string scene;
  std::string backend;
  std::string output = "render.png";
  uint32_t width = 960, height = 540;
  float time = 0.0f;
  uint32_t frames = 1;
  float fps = 30.0f;
  ShadowMode shadows = ShadowMode::automatic;  // auto: on iff the scene has lights
  bool no_bounce = false;
  std::string view = "shaded";
  std::string rays = "bounce";
  int scale = 1;
  BackendOptions backend_options;
};

// out.png -> out_0007.png for frame 7 of an animation.
std::string frame_path(const std::string& output, uint32_t frame, uint32_t frames) {
  if (frames <= 1) return output;
  const std::filesystem::path p(output);
  char suffix[16];
  std::snprintf(suffix, sizeof suffix, "_%04u", frame);
  return (p.parent_path() / (p.stem().string() + suffix + p.extension().string())).string();
}

// One frame on a CPU tracer: the gather (through `gather_tracer` where given), the bounce and
// shadow rays, shading, the image written.
void render_cpu_frame(const RenderOptions& o, const Scene& scene, Tracer& tracer, Tracer* gather_tracer,
                      const Camera& camera, uint32_t frame, float time, bool shadows) {
  const size_t pixels = size_t(o.width) * o.height;
  const auto t0 = std::chrono::steady_clock::now();
  Progress progress("frame " + std::to_string(frame) + ": tracing",
                    pixels * ((o.no_bounce ? 1 : 2) + (shadows ? scene.lights.size() : 0)));
  ProgressTracer traced(tracer, progress);
  ProgressTracer gather_traced(gather_tracer ? *gather_tracer : tracer, progress);
  const GatherBuffer gather = make_gather(scene, gather_traced, camera, o.width, o.height, time);
  std::vector<Ray> rays;
  std::vector<Hit> hits;
  if (!o.no_bounce) {
    rays = bounce_rays(scene, gather, frame);
    hits.resize(rays.size());
    traced.trace(rays, hits);
  }
  // Shadow rays from the gather to every light, through the bounce's tracer (as the GPU frame)
  std::vector<Ray> shadow;
  std::vector<Hit> shadow_hits;
  if (shadows) {
    shadow = shadow_rays(scene, gather);
    shadow_hits.resize(shadow.size());
    traced.trace_any(shadow, shadow_hits);  // occlusion: any hit (docs/SPEC.md "Any hit")
  }
  progress.finish();
  // Rays outside the domain (shared::ray_domain) are not traced: say how many
  size_t rejected = 0;
  for (const Hit& h : gather.hit) rejected += (h.flags & shared::kHitRejected) != 0;
  for (const Hit& h : hits) rejected += (h.flags & shared::kHitRejected) != 0;
  if (rejected)
    std::fprintf(stderr, "%s: frame %u: %zu rays outside the domain (docs/SPEC.md, \"Domain\") were rejected, not traced\n",
                 tracer.name().c_str(), frame, rejected);
  ShadeOptions shade_options;
  shade_options.shadow_rays = shadow;
  shade_options.shadow_hits = shadow_hits;
  const std::vector<glm::vec3> rgb = shade(scene, gather, rays, hits, shade_options);
  const std::string path = frame_path(o.output, frame, o.frames);
  write_image(path, o.width, o.height, rgb);
  std::fprintf(stderr, "%s: frame %u (t = %.3f s) traced and shaded in %.2f s -> %s\n", tracer.name().c_str(),
               frame, time, seconds_since(t0), path.c_str());
}

void run_render(const RenderOptions& options, bool scale_given, bool rays_given, const std::vector<std::string>& given) {
  RenderOptions o = options;
  check_frame_size(o.width, o.height);
  if (!(std::abs(o.time) <= 1.0e6f))
    throw CLI::ValidationError("--time", "must be a finite number of seconds within +-1e6");
  if (!(o.fps >= 1.0e-3f && o.fps <= 1.0e6f)) throw CLI::ValidationError("--fps", "must lie in [0.001, 1e6]");
  // The last frame's time too (frame k at --time + k / --fps)
  if (o.frames > 1 && !(std::abs(double(o.time) + double(o.frames - 1) / double(o.fps)) <= 1.0e6))
    throw CLI::ValidationError("--frames", std::to_string(o.frames) + " frames at --fps " + std::to_string(o.fps) +
                                               " from --time " + std::to_string(o.time) +
                                               " pass 1e6 s, the scene time's limit");
  require_distinct_frame_times(o.time, 0, o.frames, o.fps, "--fps");
  // Options that did nothing in the combination given, without a word (an outside sweep)
  const auto has = [&](const char* name) { return std::find(given.begin(), given.end(), name) != given.end(); };
  if (has("--fps") && o.frames <= 1)
    throw OptionsError("--fps spaces the frames of --frames: give --frames 2 or more, or leave --fps out");
  if (o.view == "shaded" && scale_given)
    throw CLI::ValidationError("--scale", "sizes a --view figure: add --view, or leave --scale out");
  if (o.view == "shaded" && rays_given)
    throw CLI::ValidationError("--rays", "picks a --view figure's rays: add --view, or leave --rays out");
  if (o.view != "shaded") {
    if (o.frames > 1) throw CLI::ValidationError("--view", o.view + " makes one picture: leave out --frames");
    // A figure of one kind of ray: the frame's other switches change nothing in it (an outside sweep)
    if (std::find(given.begin(), given.end(), "--shadows") != given.end())
      throw CLI::ValidationError("--shadows", "switches the frame's shadow rays; a --view figure shows the primary or "
                                              "bounce rays' records: leave it out");
    if (o.no_bounce)
      throw CLI::ValidationError("--no-bounce", "a --view figure picks its rays with --rays (bounce or primary): "
                                                "give --rays primary, and leave --no-bounce out");
    // The figure is --scale times the image along each side, with its title above and its colour bar
    // and legend beside (at most 500 pixels wider and 60 higher than the image, and at least 1200 by
    // 600 for the title and the bar, plot.cpp
    // draw_image_figure): its pixels count against --max-pixels too (about 40 bytes each; the image
    // alone was counted, and a figure 2.1 times the limit was written: an outside sweep)
    const uint64_t figure = std::max<uint64_t>(uint64_t(o.width) * uint64_t(o.scale) + 500, 1200) *
                            std::max<uint64_t>(uint64_t(o.height) * uint64_t(o.scale) + 60, 600);
    if (figure > frame_limits().max_pixels)
      throw Error("--view with --scale " + std::to_string(o.scale) + ": a figure of " + std::to_string(figure) +
                  " pixels exceeds the limit of " + std::to_string(frame_limits().max_pixels) +
                  " pixels (--max-pixels): lower --scale, --width or --height");
    ViewOptions v;
    v.view = o.view;
    v.scene = o.scene;
    v.backend = o.backend;
    v.output = o.output;
    v.width = o.width;
    v.height = o.height;
    v.time = o.time;
    v.primary = o.rays == "primary";
    v.scale = o.scale;
    v.backend_options = o.backend_options;
    run_view(v);
    return;
  }
  resolve_image_limit(o.backend_options, o.backend == "vulkan");
  if (o.backend.rfind("portal", 0) == 0) {
    // The portal-div raytracer renders worlds of voxels with its own shading (cmd_portal.cpp): it
    // takes the scene, the size and the output; the grid's and the frame's options do not apply
    // and are refused (they were dropped without a word: an outside sweep's find)
    std::string ignored;
    for (const std::string& name : given)
      if (name != "--backend" && name != "--width" && name != "--height" && name != "--output" && name != "scene" &&
          name != "--help")
        ignored += (ignored.empty() ? "" : ", ") + name;
    if (!ignored.empty())
      throw OptionsError("render --backend " + o.backend + " takes the scene, --width, --height and --output only; " +
                         ignored + " do(es) not apply to the portal raytracer (gridrt portal render --help lists its own)");
    PortalRenderOptions p;
    p.scene = o.scene.empty() ? "builtin:level" : o.scene;
    p.backend = o.backend;
    p.output = o.output;
    p.width = o.width;
    p.height = o.height;
    run_portal_render(p);
    return;
  }
  check_image_output(o.output);
  const Scene scene = load_scene_or_default(o.scene);
  // Every frame's file checked before the first is written, once the inputs are known (a later
  // frame over a texture this run read was refused after the earlier frames had replaced theirs:
  // an outside sweep)
  // No two frames in one file either (a frame's name a link to another's: the first frame was
  // written there, then replaced, an outside sweep)
  {
    std::map<std::string, std::string> resolved;
    for (uint32_t frame = 0; frame < o.frames; ++frame) {
      const std::string path = frame_path(o.output, frame, o.frames);
      check_output_allowed(path, "image");
      // Links followed, a dangling one too (it names the file it will create)
      std::error_code ec;
      std::filesystem::path at = path;
      for (int hop = 0; hop < 40 && std::filesystem::is_symlink(at, ec); ++hop) {
        const std::filesystem::path to = std::filesystem::read_symlink(at, ec);
        if (ec) break;
        at = to.is_absolute() ? to : at.parent_path() / to;
      }
      const std::string key = std::filesystem::weakly_canonical(at, ec).string();
      if (ec || is_stream_output(path)) continue;
      if (const auto [it, fresh] = resolved.emplace(key, path); !fresh)
        throw Error("render: frames '" + it->second + "' and '" + path + "' name one file (" + key +
                    "): each frame needs its own");
    }
  }
  const std::string backend = o.backend.empty() ? backend_names().front() : o.backend;
  const bool shadows = shadows_for(o.shadows, scene);
  if (shadows) check_shadow_lights(scene);
  // No bounce and no shadow rays: only the primary rays, which the gather traces on its own grid
  // (plan::gather_options: the exact traversal, the watertight test, every reference kept). The
  // trace's own knobs were accepted and the image the same in bits (an outside sweep).
  if (o.no_bounce && !shadows && backend != "embree") {
    std::string idle;
    for (const char* name : {"--traversal", "--triangle-test", "--enlargement", "--spill", "--spill-capacity",
                             "--self-hit-offset", "--max-capacity", "--elongation", "--revisit", "--gap-fill",
                             "--gap-fill-distance"})
      if (std::find(given.begin(), given.end(), name) != given.end()) idle += (idle.empty() ? "" : ", ") + std::string(name);
    if (!idle.empty())
      throw OptionsError("with --no-bounce and no shadow rays only the primary rays are traced, on the gather's grid "
                         "(the exact traversal, the watertight test, every reference kept): " + idle +
                         " shape(s) only the trace's and do(es) nothing here (leave them out)");
  }
  std::unique_ptr<Tracer> tracer = make_backend(backend, o.backend_options, scene);
  // The paper rasterizes its gather buffer: primary visibility is exact, only the bounce goes
  // through the paper's segments (and may meet gap-fill voxels). A grid backend in paper mode
  // therefore makes the gather buffer with a second tracer on the exact traversal.
  // The gather's test is the watertight one (plan::gather_options; the exact traversal's default),
  // so a CPU grid tracing with Moller-Trumbore gathers with a second tracer too, and so does one
  // that may leave triangles out of its cells or its hits (the spill list off or bounded, a
  // self-hit offset): the gather keeps every reference (plan::gather_options)
  const reference::GridOptions& gg = o.backend_options.grid;
  const bool moller = plan::resolved_triangle_test(gg) == reference::GridOptions::TriangleTest::moller;
  const bool drops = gg.spill == reference::GridOptions::Spill::off || gg.spill_capacity.has_value() ||
                     gg.self_hit_offset != 0.0f;
  // The Vulkan frame gathers on the GPU: it built a second grid it never read (about 3 s and 160
  // MB on the atrium: an outside sweep). A --fallback-cpu tracer is the CPU's, and gathers as one (cpu_tracer below).
  bool frame_on_gpu = false;
#ifdef GRIDRT_HAVE_VULKAN
  frame_on_gpu = dynamic_cast<vulkan::VulkanGridTracer*>(tracer.get()) != nullptr;
#endif
  // The CPU reference's tracer: --backend cpu, or a --fallback-cpu tracer (its name is still vulkan)
  const bool cpu_tracer = dynamic_cast<reference::ReferenceGridTracer*>(tracer.get()) != nullptr;
  std::unique_ptr<Tracer> gather_tracer;
  if (!frame_on_gpu && ((backend != "embree" && gg.traversal == reference::Traversal::paper) ||
                     (cpu_tracer && (moller || drops)))) {
    BackendOptions exact = o.backend_options;
    exact.grid = plan::gather_options(exact.grid);
    gather_tracer = make_backend(backend, exact, scene);
    build_gather_grid(*gather_tracer, scene, o.time);
  }

  auto t0 = std::chrono::steady_clock::now();
  tracer->build(scene, o.time);
  std::fprintf(stderr, "%s: built %s (%llu triangles, %zu instances) in %.2f s\n", tracer->name().c_str(),
               scene.name.c_str(), (unsigned long long)scene.triangle_count(), scene.instances.size(),
               seconds_since(t0));
#ifdef GRIDRT_HAVE_VULKAN
  // The Vulkan grid renders the whole frame on the GPU (vulkan/frame.h): raster gather, bounce,
  // trace, shadow rays and shade, read back once as RGBA8.
  if (auto* vk = dynamic_cast<vulkan::VulkanGridTracer*>(tracer.get())) {
    vulkan::VulkanFrame gpu_frame(*vk, scene, {.width = o.width, .height = o.height, .bounce = !o.no_bounce, .shadows = shadows});
    for (uint32_t frame = 0; frame < o.frames; ++frame) {
      const float time = frame_time(o.time, frame, o.fps);
      if (frame > 0) vk->update(time);
      t0 = std::chrono::steady_clock::now();
      gpu_frame.render(frame);
      const std::string path = frame_path(o.output, frame, o.frames);
      write_image_rgba8(path, o.width, o.height, gpu_frame.download_rgba(), false);  // RGB, as the CPU's
      // A CPU implementation's (llvmpipe's) timestamps do not bracket its compute work (docs/VULKAN.md,
      // "Timings on lavapipe"): there only the host's time is printed (an outside sweep read 4 ms of
      // "trace" off a frame of seconds)
      if (vk->context().info().type == VK_PHYSICAL_DEVICE_TYPE_CPU)
        std::fprintf(stderr, "%s: frame %u (t = %.3f s) rendered in %.2f s (host clock: a CPU implementation's "
                     "timestamps do not time its passes) -> %s\n", tracer->name().c_str(), frame, time,
                     seconds_since(t0), path.c_str());
      else
        std::fprintf(stderr, "%s: frame %u (t = %.3f s) rendered on the GPU in %.2f s (device: gather %.3f, bounce %.3f, "
                     "trace %.3f, shadow %.3f, shade %.3f ms) -> %s\n", tracer->name().c_str(), frame, time, seconds_since(t0),
                     gpu_frame.timings().gather_ms, gpu_frame.timings().bounce_ms, gpu_frame.timings().trace_ms,
                     gpu_frame.timings().shadow_ms, gpu_frame.timings().shade_ms, path.c_str());
    }
    return;
  }
#endif
  const Camera camera = scene.frame_camera();
  for (uint32_t frame = 0; frame < o.frames; ++frame) {
    const float time = frame_time(o.time, frame, o.fps);
    if (frame > 0) {
      tracer->update(time);
      if (gather_tracer) gather_tracer->update(time);
    }
    render_cpu_frame(o, scene, *tracer, gather_tracer.get(), camera, frame, time, shadows);
  }
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  CLI::App* cmd = app.add_subcommand("render", "Render a scene to an image: primary rays, one glossy bounce, simple shading");
  add_scene_argument(cmd, o->scene);
  cmd->add_option("--backend,-b", o->backend,
                  "Tracer: " + backend_list() + ", or portal-cpu, portal-vulkan (voxel worlds: a .map, builtin:level, a scene voxelized) "
                  "(default: the first)");
  add_image_size(cmd, o->width, o->height, "in pixels");
  cmd->add_option("--time,-t", o->time, "Scene time in seconds (animation)")->check(CLI::Range(-1.0e6f, 1.0e6f));
  cmd->add_option("--frames", o->frames, "Frames to render, --fps apart, written as NAME_0000.EXT ...")
      ->check(CLI::Range(1u, 100000u));
  cmd->add_option("--fps", o->fps, "Frames per second of --frames")->check(CLI::Range(1.0e-3f, 1.0e6f));
  add_shadows_option(cmd, o->shadows);
  cmd->add_flag("--no-bounce", o->no_bounce, "Primary rays only, no glossy bounce");
  cmd->add_option("-o,--output", o->output, "Image file: .png, .jpg, .exr, .hdr, .tif (OpenImageIO), .ppm, .pfm")
      ->capture_default_str();
  add_choice(cmd, "--view", o->view, view_names(),
                  "What the picture shows: shaded (the render), or per pixel with a colour bar or legend: cells "
                  "(visited), tests (references tested), saturation (saturated cells visited), gap-fill (a gap-fill "
                  "voxel answered), spill (a spilled reference answered), diff (CPU reference vs Vulkan shader; "
                  "needs --backend vulkan)")->group("Views");
  auto* rays_opt = add_choice(cmd, "--rays", o->rays, {"bounce", "primary"},
                  "--view: which ray of each pixel: bounce (its glossy bounce, as the frame traces it; the camera "
                  "rays where the scene has no glossy material) or primary (the camera ray, through the grid)")->group("Views");
  auto* scale_opt =
      cmd->add_option("--scale", o->scale, "--view: figure pixels per image pixel")->check(CLI::Range(1, 16))->group("Views");
  add_backend_options(cmd, o->backend_options);
  cmd->callback([o, cmd, scale_opt, rays_opt] {
    // The options given (for the portal backends, which take only a few of them)
    std::vector<std::string> given;
    std::string grid_given;  // the grid's and the Vulkan port's options given
    for (const CLI::Option* opt : cmd->get_options()) {
      if (opt->count() == 0) continue;
      given.push_back(opt->get_name());
      const std::string& g = opt->get_group();
      if ((g == "Grid" || g == "Grid (expert)" || g == "Vulkan") && opt->get_name() != "--threads")
        grid_given += (grid_given.empty() ? "" : ", ") + opt->get_name();
    }
    // Embree traces its own BVH: the grid's options did nothing there, without a word (an outside sweep)
    if (o->backend == "embree" && !grid_given.empty())
      throw OptionsError("render --backend embree traces Embree's own structure: " + grid_given +
                         " do(es) not apply (leave them out, or render with --backend cpu)");
    check_vulkan_options_apply(cmd, o->backend == "vulkan");
    check_traversal_options(cmd, o->backend_options);
    // The CPU reference's build order: the Vulkan frame builds and renders on the device alone (it
    // was accepted and did nothing: an outside sweep); a --view or --fallback-cpu build is the CPU's
    if (o->backend == "vulkan" && cmd->count("--shuffle-seed") > 0 && cmd->count("--view") == 0 &&
        !o->backend_options.fallback_cpu)
      throw OptionsError("--shuffle-seed orders the CPU reference's build invocations; render --backend vulkan builds "
                         "on the device: it does nothing (leave it out, or render with --backend cpu)");
    run_render(*o, scale_opt->count() > 0, rays_opt->count() > 0, given);
  });
}

}  // namespace gridrt::app
