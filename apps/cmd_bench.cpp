// gridrt bench: time the phases of the paper's frame on one backend: the static build once, then
// per frame the update of the dynamic instances and the trace of the glossy bounce rays off a
// gather buffer, after warm-up; medians over the frames, as a table and as JSON.
// The vulkan backend runs the whole frame on the GPU (vulkan/frame.h) and times every phase:
// update (clear + dynamic insert), gather (visibility, copy, resolve), bounce rays, trace, shade,
// reads the trace's per-ray counters back from the hit records, and with `embree` among the
// backends traces the last frame's own bounce rays with Embree (agreement, time). The CPU
// backends trace the bounce rays of the CPU reference's gather buffer.
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
  std::string gather = "compute";  // vulkan: the frame's gather, compute or raster (FrameOptions)
  bool compact_rays = false;       // vulkan: trace only the pixels with a bounce ray
  uint32_t counter_frames = 5;     // vulkan: frames whose hit records are read back for the counters
  float fps = 30.0f;
  std::string json;
  BackendOptions backend_options;
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

struct PhaseTimes {
  double build = 0.0;
  std::vector<double> update, trace;
  std::string clock = "host";  // "gpu timestamps" or "host"
};

// Distribution of one per-ray counter over the real rays of a frame.
struct CounterStats {
  double mean = 0.0, p99 = 0.0, max = 0.0;
};
CounterStats counter_stats(std::vector<uint32_t> v) {
  CounterStats c;
  if (v.empty()) return c;
  double sum = 0.0;
  for (uint32_t x : v) sum += x;
  c.mean = sum / double(v.size());
  std::sort(v.begin(), v.end());
  c.p99 = v[std::min(v.size() - 1, size_t(0.99 * double(v.size())))];
  c.max = v.back();
  return c;
}

// Agreement of two tracers' hits on the real rays: same (instance, triangle), or both miss.
double agreement_percent(const std::vector<Ray>& rays, const std::vector<Hit>& a, const std::vector<Hit>& b) {
  size_t n = 0, same = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (is_unused(rays[i])) continue;
    ++n;
    const bool miss_a = is_miss(a[i]), miss_b = is_miss(b[i]);
    if ((miss_a && miss_b) || (!miss_a && !miss_b && a[i].instance == b[i].instance && a[i].triangle == b[i].triangle))
      ++same;
  }
  return n ? 100.0 * double(same) / double(n) : 100.0;
}

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
  vulkan::FrameOptions fo{.width = o.width, .height = o.height};
  fo.gather = o.gather == "raster" ? vulkan::GatherMode::raster : vulkan::GatherMode::compute;
  fo.compact_rays = o.compact_rays;
  vulkan::VulkanFrame frame(*vk, scene, fo);
  std::map<std::string, std::vector<double>> t;
  size_t rays = 0;
  const bool moves = scene.has_dynamic();
  // Per-ray counters of the trace (cells visited, references tested), read back from the hit
  // records of the first timed frames; the last frame's rays and hits for the CPU tracers
  std::map<std::string, std::vector<double>> counters;
  std::vector<Ray> last_rays;
  std::vector<Hit> last_hits;
  float last_time = 0.0f;
  uint32_t counted = 0, gather_tiles = 0;
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
    if (f == 0) gather_tiles = frame.download_gather_tiles();
    if (f < o.warmup) continue;
    const vulkan::GridTimings& g = vk->timings();
    const vulkan::FrameTimings ft = frame.timings();
    if (frame.bounce() && (counted < o.counter_frames || f + 1 == o.warmup + o.frames)) {
      last_rays = frame.download_rays();
      last_hits = frame.download_hits();
      last_time = time;
      if (counted < o.counter_frames) {
        ++counted;
        std::vector<uint32_t> cells, tests;
        for (size_t i = 0; i < last_rays.size(); ++i)
          if (!is_unused(last_rays[i])) {
            cells.push_back(last_hits[i].cells);
            tests.push_back(last_hits[i].tests);
          }
        const CounterStats c = counter_stats(cells), tt = counter_stats(tests);
        counters["cells_mean"].push_back(c.mean);
        counters["cells_p99"].push_back(c.p99);
        counters["cells_max"].push_back(c.max);
        counters["tests_mean"].push_back(tt.mean);
        counters["tests_p99"].push_back(tt.p99);
        counters["tests_max"].push_back(tt.max);
      }
    }
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
    t["visibility"].push_back(stamps ? ft.visibility_ms : 0.0);
    t["copy"].push_back(stamps ? ft.copy_ms : 0.0);
    t["bin"].push_back(stamps ? ft.bin_ms : 0.0);
    t["tiles"].push_back(stamps ? ft.tiles_ms : 0.0);
    t["resolve"].push_back(stamps ? ft.resolve_ms : 0.0);
    t["bounce"].push_back(stamps ? ft.bounce_ms : 0.0);
    t["trace"].push_back(stamps ? ft.trace_ms : 0.0);
    t["shade"].push_back(stamps ? ft.shade_ms : 0.0);
    t["frame"].push_back(update + (stamps ? ft.total_ms : ft.host_ms));
  }
  // The static build again, the GPU warm (the first one ran at idle clocks: docs/VULKAN.md), median of 5
  std::vector<double> warm_builds;
  for (int i = 0; i < 5 && stamps; ++i) {
    vk->build(scene, 0.0f);
    warm_builds.push_back(vk->timings().build_ms);
    t["build_init"].push_back(vk->timings().build_init_ms);
    t["build_static"].push_back(vk->timings().build_static_ms);
    t["build_dynamic"].push_back(vk->timings().build_dynamic_ms);
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
  const char* gather_name = frame.gather_mode() == vulkan::GatherMode::compute ? "compute" : "raster";
  std::printf("\nvulkan, the whole frame on the GPU (%s; %s): %zu bounce rays per frame, grid %ux%ux%u capacity %u, "
              "%s gather, %s trace\n",
              device.c_str(), clock.c_str(), rays, gp.cells.x, gp.cells.y, gp.cells.z, gp.capacity, gather_name,
              o.compact_rays ? "compacted" : "every-pixel");
  std::printf("| build ms (first, warm) | update ms (clear + insert) | gather ms | bounce rays ms | trace ms | shade ms | frame ms "
              "(update..shade) | Mrays/s (trace) | grid MiB | frame buffers MiB |\n"
              "|---|---|---|---|---|---|---|---|---|---|\n");
  std::printf("| %.3f, %.3f | %.3f (%.3f + %.3f) | %.3f | %.3f | %.3f | %.3f | %.3f | %.0f | %.1f | %.1f |\n\n", build,
              build_warm,
              m["update"], m["clear"], m["insert"], m["gather"], m["bounce"], m["trace"], m["shade"], m["frame"], mrays,
              grid_mib, frame_mib);
  std::printf("gather split: visibility (%s; %u tiles of 8x8 pixels in frame 0) %.3f (bin %.3f + tiles %.3f), copy %.3f, "
              "resolve %.3f ms; warm build split (%s build): blank image %.3f, static instances %.3f, dynamic instances "
              "%.3f ms\n",
              gather_name, gather_tiles, m["visibility"], m["bin"], m["tiles"], m["copy"], m["resolve"],
              o.backend_options.vk_build.c_str(), m["build_init"], m["build_static"], m["build_dynamic"]);
  // The trace's counters; bytes the trace requests per ray, estimated from them: the ray (48) and
  // its hit record (32), per visited cell one blank or status texel (4), per test the slot's
  // texel (4), the instance (16) and the triangle (48). Requested, not DRAM traffic (the caches
  // serve most of it); ignores the few uv, material and alpha reads of accepted hits.
  std::map<std::string, double> cm;
  for (auto& [k, v] : counters) cm[k] = median(v);
  const double bytes_per_ray = 80.0 + 4.0 * cm["cells_mean"] + 68.0 * cm["tests_mean"];
  const double rays_per_s = m["trace"] > 0.0 ? double(rays) / (m["trace"] * 1e-3) : 0.0;
  if (!counters.empty())
    std::printf("| trace: rays | rays/s | cells visited mean / p99 / max | refs tested mean / p99 / max | bytes read per ray "
                "(estimate) | GB/s requested |\n|---|---|---|---|---|---|\n"
                "| %zu | %.3g | %.2f / %.0f / %.0f | %.2f / %.0f / %.0f | %.0f | %.0f |\n"
                "(counters: medians over the first %u timed frames of each frame's mean / p99 / max over its real rays)\n\n",
                rays, rays_per_s, cm["cells_mean"], cm["cells_p99"], cm["cells_max"], cm["tests_mean"], cm["tests_p99"],
                cm["tests_max"], bytes_per_ray, rays_per_s * bytes_per_ray * 1e-9, counted);
  if (t.count("b2b_frame"))
    std::printf("back to back (%u frames per submission, the last timed; update as above): gather %.3f, bounce %.3f, "
                "trace %.3f, shade %.3f, frame (update..shade) %.3f ms, %.0f Mrays/s\n\n",
                o.back_to_back, m["b2b_gather"], m["b2b_bounce"], m["b2b_trace"], m["b2b_shade"], m["b2b_frame"],
                m["b2b_trace"] > 0.0 ? double(rays) / (m["b2b_trace"] * 1e3) : 0.0);
  std::fflush(stdout);
  nlohmann::json j = {{"device", device}, {"clock", clock},       {"build_ms", build}, {"build_warm_ms", build_warm}, {"rays_per_frame", rays},
                      {"mrays_per_s", mrays}, {"grid_mib", grid_mib}, {"frame_mib", frame_mib},
                      {"grid_cells", {gp.cells.x, gp.cells.y, gp.cells.z}}, {"capacity", gp.capacity}};
  j["gather_mode"] = gather_name;
  j["gather_tiles_frame0"] = gather_tiles;
  j["compact_rays"] = o.compact_rays;
  for (auto& [k, v] : t) {
    j[k + "_ms"] = m[k];
    j[k + "_ms_all"] = v;
  }
  if (!counters.empty()) {
    nlohmann::json c = {{"frames", counted}, {"rays_per_s", rays_per_s}, {"bytes_per_ray_estimate", bytes_per_ray}};
    for (auto& [k, v] : cm) c[k] = v;
    j["trace_counters"] = c;
  }
  out["backends"]["vulkan"] = j;

  // Embree on the CPU, on the last frame's own bounce rays, at that frame's time
  if (std::find(o.backends.begin(), o.backends.end(), "embree") != o.backends.end() && !last_rays.empty()) {
    std::unique_ptr<Tracer> embree = make_backend("embree", o.backend_options, scene);
    t0 = std::chrono::steady_clock::now();
    embree->build(scene, 0.0f);
    embree->update(last_time);
    const double embree_build = ms_since(t0);
    std::vector<Ray> real;
    std::vector<size_t> index;
    for (size_t i = 0; i < last_rays.size(); ++i)
      if (!is_unused(last_rays[i])) real.push_back(last_rays[i]), index.push_back(i);
    std::vector<Hit> hits(real.size());
    std::vector<double> times;
    for (int r = 0; r < 3; ++r) {
      t0 = std::chrono::steady_clock::now();
      embree->trace(real, hits);
      times.push_back(ms_since(t0));
    }
    std::vector<Hit> embree_hits(last_rays.size(), Hit{});
    for (size_t k = 0; k < index.size(); ++k) embree_hits[index[k]] = hits[k];
    const double ms = median(times), agree = agreement_percent(last_rays, last_hits, embree_hits);
    size_t gap = 0;
    for (size_t i : index) gap += (last_hits[i].flags & shared::kHitGapFill) != 0;
    const unsigned threads = std::thread::hardware_concurrency();
    std::printf("embree on the same bounce rays (CPU, %u threads; the last frame, t = %.3f): %zu rays in %.2f ms (median of 3), "
                "%.1f Mrays/s; the GPU grid agrees on %.3f %% (same instance and triangle, or both miss; %zu gap-fill hits); "
                "embree build + update %.0f ms\n\n",
                threads, last_time, real.size(), ms, double(real.size()) / (ms * 1e3), agree, gap, embree_build);
    out["backends"]["embree_on_frame_rays"] = {{"device", "CPU, " + std::to_string(threads) + " threads"},
                                               {"rays", real.size()},       {"trace_ms", ms},
                                               {"trace_ms_all", times},     {"mrays_per_s", double(real.size()) / (ms * 1e3)},
                                               {"agree_percent", agree},    {"gpu_gap_fill_hits", gap},
                                               {"build_ms", embree_build},  {"time", last_time}};
  }
}
#endif

void run_bench(const BenchOptions& options) {
  BenchOptions o = options;
  resolve_image_limit(o.backend_options, std::find(o.backends.begin(), o.backends.end(), "vulkan") != o.backends.end());
  const Scene scene = load_scene_or_default(o.scene);
  const std::vector<std::string> backends = o.backends.empty() ? std::vector<std::string>{backend_names().front()} : o.backends;

  // The gather buffer, once, by the exact traversal of the reference grid (CPU), for the
  // backends that trace on the CPU (the vulkan backend makes its own, every frame, on the GPU).
  // (with the vulkan backend, embree traces the GPU frame's own bounce rays instead)
  const bool with_vulkan = std::find(backends.begin(), backends.end(), "vulkan") != backends.end();
  auto on_cpu_rays = [&](const std::string& b) { return b != "vulkan" && !(with_vulkan && b == "embree"); };
  const bool cpu_rays = std::any_of(backends.begin(), backends.end(), on_cpu_rays);
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
  for (const std::string& name : backends) {
#ifdef GRIDRT_HAVE_VULKAN
    if (name == "vulkan") {
      bench_vulkan_frame(o, scene, out);
      continue;
    }
#endif
    if (!on_cpu_rays(name)) continue;
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
    const double update = median(times.update), trace = median(times.trace);
    const double mrays = trace > 0.0 ? double(bounce_count) / (trace * 1e3) : 0.0;
    std::printf("| %s | %s | %s | %.3f | %.3f | %.3f | %.1f | %.2f |\n", name.c_str(), device.c_str(),
                times.clock.c_str(), times.build, update, trace, mrays, grid_mib);
    std::fflush(stdout);
    out["backends"][name] = {{"device", device},        {"clock", times.clock},   {"build_ms", times.build},
                             {"update_ms", update},     {"trace_ms", trace},      {"mrays_per_s", mrays},
                             {"grid_mib", grid_mib},    {"update_ms_all", times.update},
                             {"trace_ms_all", times.trace}};
  }
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
  cmd->add_option("--gather", o->gather,
                  "Vulkan: the frame's gather: compute (the CPU gather's ray test, needs 64-bit buffer atomics) or raster "
                  "(the paper's raster pass)")
      ->check(CLI::IsMember({"compute", "raster"}));
  cmd->add_flag("--compact-rays", o->compact_rays,
                "Vulkan: trace only the pixels with a bounce ray, through a work list (default: every pixel; the "
                "empty rays return at once)");
  cmd->add_option("--counter-frames", o->counter_frames,
                  "Vulkan: timed frames whose hit records are read back for the trace's counters")
      ->check(CLI::Range(0u, 1000u));
  cmd->add_option("--json", o->json, "Also write the figures as JSON to this file");
  add_backend_options(cmd, o->backend_options);
  cmd->callback([o] { run_bench(*o); });
}

}  // namespace gridrt::app
