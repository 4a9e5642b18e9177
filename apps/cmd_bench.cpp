// gridrt bench: time the phases of the paper's frame on one backend: the static build once, then
// per frame the update of the dynamic instances and the trace of the glossy bounce rays off a
// gather buffer, after warm-up; medians over the frames, as a table and as JSON.
// The vulkan backend runs the whole frame on the GPU (vulkan/frame.h) and times every phase:
// update (clear + dynamic insert), gather (raster), bounce rays, trace, shade. The CPU backends
// trace the bounce rays of the CPU reference's gather buffer.
// Vulkan phases are timed with timestamp queries where the device's timestamps bracket the
// passes (not lavapipe: there the host time from submit to fence is reported, and says so).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <thread>

#include <nlohmann/json.hpp>

#include "apps/backends.h"
#include "apps/commands.h"
#include "common/gather.h"
#include "reference/grid.h"
#ifdef GRIDRT_HAVE_VULKAN
#  include "vulkan/frame.h"
#  include "vulkan/grid.h"
#endif

namespace gridrt::app {
namespace {

struct BenchOptions {
  std::string scene;
  std::vector<std::string> backends;
  uint32_t width = 1920, height = 1080;
  uint32_t frames = 20, warmup = 3;
  uint32_t back_to_back = 8;  // vulkan: also time frames recorded this many times per submission
  float fps = 30.0f;
  std::string json;
  BackendOptions backend_options;
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// The spill list after the last update, as a line and as JSON (an overflow is never silent).
std::string spill_text(const shared::SpillHeader& h, uint32_t flags) {
  const uint32_t stored = std::min(h.count, h.capacity), lost = h.count > h.capacity ? h.count - h.capacity : 0u;
  char buf[256];
  if (flags & shared::kGridSpill)
    std::snprintf(buf, sizeof buf, "spill list on: %u entries of %u (%u static)%s", stored, h.capacity, h.static_count,
                  lost ? (", OVERFLOW: " + std::to_string(lost) + " references lost").c_str() : ", no overflow");
  else
    std::snprintf(buf, sizeof buf, "spill list off: %u references found no slot (dropped); gap-fill %s", h.count,
                  (flags & shared::kGridGapFill) ? "on" : "off");
  return buf;
}
nlohmann::json spill_json(const shared::SpillHeader& h, uint32_t flags) {
  return {{"on", (flags & shared::kGridSpill) != 0u}, {"appended", h.count}, {"static", h.static_count},
          {"capacity", h.capacity}, {"stored", std::min(h.count, h.capacity)},
          {"overflow", (flags & shared::kGridSpill) && h.count > h.capacity ? h.count - h.capacity : 0u}, {"gap_fill", (flags & shared::kGridGapFill) != 0u}};
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

struct PhaseTimes {
  double build = 0.0;
  std::vector<double> update, trace;
  std::string clock = "host";  // "gpu timestamps" or "host"
};

#ifdef GRIDRT_HAVE_VULKAN
// The whole frame on the GPU: the grid's static build once, then per frame the update (clear,
// dynamic insert) and VulkanFrame::render (gather, bounce, trace, shade), GPU timestamps.
void bench_vulkan_frame(const BenchOptions& o, const Scene& scene, nlohmann::json& out) {
  std::unique_ptr<Tracer> tracer = make_backend("vulkan", o.backend_options, scene);
  auto* vk = dynamic_cast<vulkan::VulkanGridTracer*>(tracer.get());
  if (!vk) throw Error("bench: the vulkan backend is not the Vulkan grid");
  auto t0 = std::chrono::steady_clock::now();
  vk->build(scene, 0.0f);
  const double build_host = ms_since(t0);
  const bool stamps = vk->timings().build_ms > 0.0 && vk->context().info().driver_id != VK_DRIVER_ID_MESA_LLVMPIPE;
  const double build = stamps ? vk->timings().build_ms : build_host;
  vulkan::VulkanFrame frame(*vk, scene, {.width = o.width, .height = o.height});
  std::map<std::string, std::vector<double>> t;
  size_t rays = 0;
  const bool moves = scene.has_dynamic();
  for (uint32_t f = 0; f < o.warmup + o.frames; ++f) {
    const float time = float(f + 1) / o.fps;
    t0 = std::chrono::steady_clock::now();
    if (moves) vk->update(time);
    const double update_host = moves ? ms_since(t0) : 0.0;
    frame.render(f);
    if (f == 0 && frame.bounce()) {
      const std::vector<Ray> r = frame.download_rays();
      rays = size_t(std::count_if(r.begin(), r.end(), [](const Ray& ray) { return !is_unused(ray); }));
    }
    if (f < o.warmup) continue;
    const vulkan::GridTimings& g = vk->timings();
    const vulkan::FrameTimings ft = frame.timings();
    if (o.back_to_back > 1 && stamps) {
      // The same frame again, back to back in one submission (the GPU busy), the last timed
      frame.render(f, o.back_to_back);
      const vulkan::FrameTimings& bb = frame.timings();
      t["b2b_gather"].push_back(bb.gather_ms);
      t["b2b_bounce"].push_back(bb.bounce_ms);
      t["b2b_trace"].push_back(bb.trace_ms);
      t["b2b_shade"].push_back(bb.shade_ms);
      t["b2b_frame"].push_back((moves ? g.update_ms : 0.0) + bb.total_ms);
    }
    const double update = moves ? (stamps ? g.update_ms : update_host) : 0.0;
    t["update"].push_back(update);
    t["clear"].push_back(moves && stamps ? g.clear_ms : 0.0);
    t["insert"].push_back(moves && stamps ? g.insert_ms : 0.0);
    t["gather"].push_back(stamps ? ft.gather_ms : 0.0);
    t["bounce"].push_back(stamps ? ft.bounce_ms : 0.0);
    t["trace"].push_back(stamps ? ft.trace_ms : 0.0);
    t["shade"].push_back(stamps ? ft.shade_ms : 0.0);
    t["frame"].push_back(update + (stamps ? ft.total_ms : ft.host_ms));
  }
  const shared::SpillHeader spill = vk->spill_header();
  const uint32_t spill_flags = vk->params().flags;
  // The static build again, the GPU warm (the first one ran at idle clocks: docs/VULKAN.md), median of 5
  std::vector<double> warm_builds;
  for (int i = 0; i < 5 && stamps; ++i) {
    vk->build(scene, 0.0f);
    warm_builds.push_back(vk->timings().build_ms);
  }
  const double build_warm = median(warm_builds);
  std::map<std::string, double> m;
  for (auto& [k, v] : t) m[k] = median(v);
  const double mrays = m["trace"] > 0.0 ? double(rays) / (m["trace"] * 1e3) : 0.0;
  const shared::GridParams& gp = vk->params();
  const glm::uvec3 ext = shared::grid_image_extent(gp);
  const double grid_mib = double(ext.x) * ext.y * ext.z * 4.0 / (1 << 20);
  const double frame_mib = double(o.width) * o.height * (4 + 4 + sizeof(shared::GatherTexel) + sizeof(Ray) + sizeof(Hit) + 4) /
                           (1 << 20);
  const std::string device = vk->context().info().name;
  const std::string clock = stamps ? "gpu timestamps" : "host (submit to fence; the frame's phases not split)";
  std::printf("\nvulkan, the whole frame on the GPU (%s; %s): %zu bounce rays per frame, grid %ux%ux%u capacity %u\n",
              device.c_str(), clock.c_str(), rays, gp.cells.x, gp.cells.y, gp.cells.z, gp.capacity);
  std::printf("| build ms (first, warm) | update ms (clear + insert) | gather ms | bounce rays ms | trace ms | shade ms | frame ms "
              "(update..shade) | Mrays/s (trace) | grid MiB | frame buffers MiB |\n"
              "|---|---|---|---|---|---|---|---|---|---|\n");
  std::printf("| %.3f, %.3f | %.3f (%.3f + %.3f) | %.3f | %.3f | %.3f | %.3f | %.3f | %.0f | %.1f | %.1f |\n\n", build,
              build_warm,
              m["update"], m["clear"], m["insert"], m["gather"], m["bounce"], m["trace"], m["shade"], m["frame"], mrays,
              grid_mib, frame_mib);
  std::printf("%s (after the last frame's update)\n\n", spill_text(spill, spill_flags).c_str());
  if (t.count("b2b_frame"))
    std::printf("back to back (%u frames per submission, the last timed; update as above): gather %.3f, bounce %.3f, "
                "trace %.3f, shade %.3f, frame (update..shade) %.3f ms, %.0f Mrays/s\n\n",
                o.back_to_back, m["b2b_gather"], m["b2b_bounce"], m["b2b_trace"], m["b2b_shade"], m["b2b_frame"],
                m["b2b_trace"] > 0.0 ? double(rays) / (m["b2b_trace"] * 1e3) : 0.0);
  std::fflush(stdout);
  nlohmann::json j = {{"device", device}, {"clock", clock},       {"build_ms", build}, {"build_warm_ms", build_warm}, {"rays_per_frame", rays},
                      {"mrays_per_s", mrays}, {"grid_mib", grid_mib}, {"frame_mib", frame_mib},
                      {"grid_cells", {gp.cells.x, gp.cells.y, gp.cells.z}}, {"capacity", gp.capacity},
                      {"spill", spill_json(spill, spill_flags)}};
  for (auto& [k, v] : t) {
    j[k + "_ms"] = m[k];
    j[k + "_ms_all"] = v;
  }
  out["backends"]["vulkan"] = j;
}
#endif

void run_bench(const BenchOptions& options) {
  BenchOptions o = options;
  resolve_image_limit(o.backend_options, std::find(o.backends.begin(), o.backends.end(), "vulkan") != o.backends.end());
  const Scene scene = load_scene_or_default(o.scene);
  const std::vector<std::string> backends = o.backends.empty() ? std::vector<std::string>{backend_names().front()} : o.backends;

  // The gather buffer, once, by the exact traversal of the reference grid (CPU), for the
  // backends that trace on the CPU (the vulkan backend makes its own, every frame, on the GPU).
  const bool cpu_rays = std::any_of(backends.begin(), backends.end(), [](const std::string& b) { return b != "vulkan"; });
  reference::GridOptions exact = grid_options_for(o.backend_options, scene);
  exact.traversal = reference::Traversal::exact;
  reference::ReferenceGridTracer gather_tracer(exact);
  GatherBuffer gather;
  size_t bounce_count = 0;
  if (cpu_rays) {
    gather_tracer.build(scene, 0.0f);
    Progress progress("gather buffer (CPU reference, exact)", size_t(o.width) * o.height);
    ProgressTracer traced(gather_tracer, progress);
    gather = make_gather(scene, traced, scene.frame_camera(), o.width, o.height, 0.0f);
    const std::vector<Ray> r = bounce_rays(scene, gather, 0);
    bounce_count = size_t(std::count_if(r.begin(), r.end(), [](const Ray& ray) { return !is_unused(ray); }));
  }
  const Features features = Features::for_scene(scene);
  std::printf("bench: %s, %llu triangles, %zu instances (%zu dynamic), %ux%u, %s glossy bounce rays per frame, "
              "%u frames after %u warm-up\n",
              scene.name.c_str(), (unsigned long long)scene.triangle_count(), scene.instances.size(),
              scene.instances.size() - scene.static_instance_count(), o.width, o.height,
              cpu_rays ? std::to_string(bounce_count).c_str() : "(GPU gather)", o.frames, o.warmup);
  std::printf("machine: %u hardware threads; effects the scene calls for: alpha keying %s, update %s, glossy %s\n",
              std::thread::hardware_concurrency(), features.alpha_keying ? "yes" : "no", features.update ? "yes" : "no",
              features.glossy ? "yes" : "no");

  nlohmann::json out;
  out["scene"] = scene.name;
  out["width"] = o.width;
  out["height"] = o.height;
  out["rays_per_frame"] = bounce_count;
  out["frames"] = o.frames;
  if (cpu_rays)
    std::printf("\n| backend | device | clock | build ms | update ms (median) | trace ms (median) | Mrays/s | grid MiB |\n"
                "|---|---|---|---|---|---|---|---|\n");
  std::vector<std::string> notes;  // printed under the table
  for (const std::string& name : backends) {
#ifdef GRIDRT_HAVE_VULKAN
    if (name == "vulkan") {
      bench_vulkan_frame(o, scene, out);
      continue;
    }
#endif
    std::unique_ptr<Tracer> tracer = make_backend(name, o.backend_options, scene);
    PhaseTimes times;
    std::string device = "CPU, " + std::to_string(std::thread::hardware_concurrency()) + " threads";
    double grid_mib = 0.0;
    auto t0 = std::chrono::steady_clock::now();
    tracer->build(scene, 0.0f);
    times.build = ms_since(t0);
#ifdef GRIDRT_HAVE_VULKAN
    auto* vk = dynamic_cast<vulkan::VulkanGridTracer*>(tracer.get());
    if (vk) {
      device = vk->context().info().name;
      if (vk->timings().build_ms > 0.0) {
        times.clock = "gpu timestamps";
        times.build = vk->timings().build_ms;
      }
    }
#endif
    if (auto* ref = dynamic_cast<reference::ReferenceGridTracer*>(tracer.get()))
      grid_mib = double(ref->stats().image_bytes) / (1 << 20);
    const AccelDump dump = tracer->dump();
    if (!dump.texels.empty()) grid_mib = double(dump.texels.size()) * 4.0 / (1 << 20);

    std::vector<Hit> hits;
    for (uint32_t f = 0; f < o.warmup + o.frames; ++f) {
      const float time = float(f + 1) / o.fps;
      const std::vector<Ray> rays = bounce_rays(scene, gather, f);
      hits.resize(rays.size());
      t0 = std::chrono::steady_clock::now();
      tracer->update(time);
      double update_ms = ms_since(t0);
      t0 = std::chrono::steady_clock::now();
      tracer->trace(rays, hits);
      double trace_ms = ms_since(t0);
#ifdef GRIDRT_HAVE_VULKAN
      if (vk && times.clock == "gpu timestamps") {
        update_ms = vk->timings().update_ms;
        trace_ms = vk->timings().trace_ms;
      } else if (vk) {
        update_ms = vk->timings().update_host_ms;
        trace_ms = vk->timings().trace_host_ms;
      }
#endif
      if (f < o.warmup) continue;
      times.update.push_back(update_ms);
      times.trace.push_back(trace_ms);
    }
    shared::SpillHeader spill{};
    uint32_t spill_flags = 0;
    if (auto* ref = dynamic_cast<reference::ReferenceGridTracer*>(tracer.get())) {
      spill = ref->data().spill_header;
      spill_flags = ref->params().flags;
    }
#ifdef GRIDRT_HAVE_VULKAN
    if (vk) {
      spill = vk->spill_header();
      spill_flags = vk->params().flags;
    }
#endif
    const double update = median(times.update), trace = median(times.trace);
    const double mrays = trace > 0.0 ? double(bounce_count) / (trace * 1e3) : 0.0;
    std::printf("| %s | %s | %s | %.3f | %.3f | %.3f | %.1f | %.2f |\n", name.c_str(), device.c_str(),
                times.clock.c_str(), times.build, update, trace, mrays, grid_mib);
    const bool grid = !dump.texels.empty();
    if (grid) notes.push_back(name + ": " + spill_text(spill, spill_flags));
    std::fflush(stdout);
    out["backends"][name] = {{"device", device},        {"clock", times.clock},   {"build_ms", times.build},
                             {"update_ms", update},     {"trace_ms", trace},      {"mrays_per_s", mrays},
                             {"grid_mib", grid_mib},    {"update_ms_all", times.update},
                             {"trace_ms_all", times.trace}};
    if (grid) out["backends"][name]["spill"] = spill_json(spill, spill_flags);
  }
  if (!notes.empty()) std::printf("\n");
  for (const std::string& n : notes) std::printf("%s (after the last frame's update)\n", n.c_str());
  if (!o.json.empty()) {
    std::ofstream f(o.json);
    if (!f) throw Error("cannot write '" + o.json + "'");
    f << out.dump(2) << "\n";
  }
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  CLI::App* cmd = app.add_subcommand(
      "bench", "Time the static build, then per frame the dynamic update and the glossy-bounce trace (medians)");
  cmd->add_option("scene", o->scene, "A scene file, a mesh, a .gridscene or builtin:NAME; default: the embedded atrium");
  cmd->add_option("--backend,-b", o->backends, "Backends to time, one after the other: " + backend_list())
      ->delimiter(',');
  cmd->add_option("--width", o->width, "Image width")->check(CLI::Range(1u, 16384u));
  cmd->add_option("--height", o->height, "Image height")->check(CLI::Range(1u, 16384u));
  cmd->add_option("--frames", o->frames, "Timed frames")->check(CLI::Range(1u, 100000u));
  cmd->add_option("--warmup", o->warmup, "Untimed frames first")->check(CLI::Range(0u, 1000u));
  cmd->add_option("--back-to-back", o->back_to_back,
                  "Vulkan: also time each frame recorded this many times in one submission, the last timed (GPU kept "
                  "busy); 1: off")
      ->check(CLI::Range(1u, 64u));
  cmd->add_option("--fps", o->fps, "Scene time step per frame is 1/fps")->check(CLI::PositiveNumber);
  cmd->add_option("--json", o->json, "Also write the figures as JSON to this file");
  add_backend_options(cmd, o->backend_options);
  cmd->callback([o] { run_bench(*o); });
}

}  // namespace gridrt::app
