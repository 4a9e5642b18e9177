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
// --rtx puts the device's own ray tracing pipeline beside the grid (vulkan/rtx.h): each frame,
// after the grid's trace, the acceleration structures are updated and the same bounce rays
// traced into a second hit buffer, both timed; after the timed frames both hit buffers are read
// back once and compared ray by ray.
#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <thread>

#include <nlohmann/json.hpp>

#include "apps/backends.h"
#include "gridrt/common/util.h"
#include "apps/commands.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/reference/grid.h"
#ifdef GRIDRT_HAVE_EMBREE
#  include "gridrt/common/embree/embree_tracer.h"
#  include "verify/rays.h"
#endif
#ifdef GRIDRT_HAVE_VULKAN
#  include "gridrt/vulkan/frame.h"
#  include "gridrt/vulkan/grid.h"
#  include "gridrt/vulkan/rtx.h"
#endif

namespace gridrt::app {
namespace {

struct BenchOptions {
  std::string scene;
  std::vector<std::string> backends;
  uint32_t width = 1920, height = 1080;
  uint32_t frames = 20, warmup = 3;
  uint32_t back_to_back = 8;  // vulkan: also time frames recorded this many times per submission
  std::string rays = "auto";       // the traced rays: auto, glossy (the frame's), glossy-list, or a kind (rays_of_kind)
  std::string ray_order = "given";  // a fixed list's order: given, or sorted (coherent_ray_order)
  bool ray_order_set = false;       // --ray-order given on the command line (refused for the frame's rays)
  std::string gather = "compute";  // vulkan: the frame's gather, compute or raster (FrameOptions)
  std::string gather_lists = "buckets";  // vulkan, compute gather: the tile lists' passes
  std::string traces = "together";        // vulkan: the bounce and shadow traces in one dispatch, or apart
  std::vector<std::string> frame_knobs;  // the frame's own options given (refused where --rays auto finds no frame)
  std::optional<uint32_t> gather_bucket;  // vulkan, buckets: a tile's room in pairs
  bool compact_rays = false;       // vulkan: trace only the pixels with a bounce ray
  uint32_t sort_bits = 0;          // vulkan: the bounce rays sorted by this many bits of their keys (0: off)
  ShadowMode shadows = ShadowMode::automatic;  // shadow rays to the lights (auto: iff the scene has some)
  uint32_t counter_frames = 5;     // vulkan: frames whose hit records are read back for the counters
  float fps = 30.0f;
  bool rtx = false;          // vulkan: the device's ray tracing pipeline side by side
  bool rtx_opaque = false;   // !RtxOptions::any_hit_all
  bool rtx_rebuild = false;  // RtxOptions::rebuild_dynamic
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

struct PhaseTimes {
  double build = 0.0;
  std::vector<double> update, trace;
  std::string clock = "host";  // how the times were taken, as printed
  bool device_stamps = false;   // the Vulkan phases come from timestamp queries
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
// The grid's hits against the RT pipeline's, ray by ray, over every ray of a frame (absent rays
// included: both miss) and over the bounce rays alone.
struct Agreement {
  size_t rays = 0, bounce = 0;    // rays of the frame; of them, real bounce rays
  size_t same = 0, same_bounce = 0;  // same (instance, triangle) or both miss
  size_t grid_only = 0;           // the grid hit, the RT pipeline missed
  size_t rtx_only = 0;            // the grid missed, the RT pipeline hit
  size_t different = 0;           // both hit, different triangles
  size_t different_gap_fill = 0;  // ... of which the grid's hit is a gap-fill voxel
  size_t rtx_closer = 0;          // ... of which the RT pipeline's hit is nearer
  size_t rtx_at_origin = 0;       // ... of which at t < 1e-3 of the grid's (next to the ray's origin)
  size_t both_hit = 0;            // same triangle, both hit
  size_t t_identical = 0;         // ... with t identical in bits
  size_t t_within_4_ulps = 0;     // ... with t at most 4 ulps apart
  double t_max_rel = 0.0;         // ... the largest |t_rtx - t_grid| / t_grid
  size_t retraced = 0;            // rays the RT pipeline traced again past the launch triangle
};

Agreement compare_hits(const std::vector<Ray>& rays, const std::vector<Hit>& grid, const std::vector<Hit>& rtx) {
  Agreement a;
  a.rays = rays.size();
  for (size_t i = 0; i < rays.size(); ++i) {
    const Hit& g = grid[i];
    const Hit& r = rtx[i];
    const bool real = !is_unused(rays[i]);
    a.bounce += real;
    a.retraced += r.tests >= 2;
    const bool g_hit = g.instance != shared::kNoInstance, r_hit = r.instance != shared::kNoInstance;
    const bool same = g.instance == r.instance && (!g_hit || g.triangle == r.triangle);
    a.same += same;
    a.same_bounce += same && real;
    if (same && g_hit) {
      ++a.both_hit;
      const uint32_t ulps = ulp_distance(g.t, r.t);
      a.t_identical += std::bit_cast<uint32_t>(g.t) == std::bit_cast<uint32_t>(r.t);
      a.t_within_4_ulps += ulps <= 4u;
      if (g.t > 0.0f) a.t_max_rel = std::max(a.t_max_rel, std::abs(double(r.t) - double(g.t)) / double(g.t));
    }
    if (same) continue;
    if (g_hit && !r_hit) ++a.grid_only;
    else if (!g_hit && r_hit) ++a.rtx_only;
    else {
      ++a.different;
      a.different_gap_fill += (g.flags & shared::kHitGapFill) != 0u;
      a.rtx_closer += r.t < g.t;
      a.rtx_at_origin += r.t < 1e-3f * g.t;
    }
  }
  return a;
}

double percent(size_t part, size_t whole) { return whole ? 100.0 * double(part) / double(whole) : 0.0; }

// What the timed frames gave: per phase its times, the trace's counters (cells visited, references
// tested, read back from the hit records of the first timed frames), the bounce rays of frame 0,
// the last frame's rays and hits (for the CPU tracers) and frame 0's gather tiles.
struct FrameRun {
  std::map<std::string, std::vector<double>> t;
  size_t rays = 0;
  std::map<std::string, std::vector<double>> counters;
  std::vector<Ray> last_rays;
  std::vector<Hit> last_hits;
  float last_time = 0.0f;
  uint32_t counted = 0, gather_tiles = 0;
  vulkan::GatherPairs gather_pairs;  // frame 0's tile lists (compute gather)
};

// The frames, warm-up then timed: per frame the update, the frame's passes and (with `rtx`) the
// RT pipeline's update and trace of the same rays into `rtx_hits`.
FrameRun run_frames(const BenchOptions& o, const Scene& scene, vulkan::VulkanGridTracer* vk, vulkan::VulkanFrame& frame,
                    vulkan::VulkanRtxTracer* rtx, const vulkan::Buffer& rtx_hits, bool stamps) {
  FrameRun run;
  std::map<std::string, std::vector<double>>& t = run.t;
  size_t& rays = run.rays;
  const bool moves = scene.has_dynamic();
  std::map<std::string, std::vector<double>>& counters = run.counters;
  std::vector<Ray>& last_rays = run.last_rays;
  std::vector<Hit>& last_hits = run.last_hits;
  float& last_time = run.last_time;
  uint32_t& counted = run.counted;
  uint32_t& gather_tiles = run.gather_tiles;
  for (uint32_t f = 0; f < o.warmup + o.frames; ++f) {
    const float time = frame_time(0.0f, f + 1, o.fps);
    const auto t0 = std::chrono::steady_clock::now();
    if (moves) vk->update(time);
    const double update_host = moves ? ms_since(t0) : 0.0;
    frame.render(f);
    if (f == 0 && frame.bounce()) {
      const std::vector<Ray> r = frame.download_rays();
      rays = size_t(std::count_if(r.begin(), r.end(), [](const Ray& ray) { return !is_unused(ray); }));
    }
    // The RT pipeline: the acceleration structures after the grid's update, then the same rays
    if (rtx) rtx->update_and_trace(frame.ray_buffer(), rtx_hits, frame.ray_count());
    if (f == 0) gather_tiles = frame.download_gather_tiles();
    if (f == 0) run.gather_pairs = frame.download_gather_pairs();
    if (f < o.warmup) continue;
    if (rtx) {
      const vulkan::RtxTimings& rt = rtx->timings();
      t["rtx_update"].push_back(stamps ? rt.update_ms : rt.host_ms);
      t["rtx_refit"].push_back(stamps ? rt.refit_ms : 0.0);
      t["rtx_tlas"].push_back(stamps ? rt.tlas_ms : 0.0);
      t["rtx_trace"].push_back(stamps ? rt.trace_ms : 0.0);
    }
    const vulkan::GridTimings& g = vk->timings();
    const vulkan::FrameTimings ft = frame.timings();
    // The bounce and shadow traces in one dispatch: the frame's time is this render's; the two
    // traces' own times come from the same frame rendered again as two passes (the same rays and
    // hits), so that the trace column and the RT pipeline's comparison keep the bounce trace alone
    vulkan::FrameTimings apart = ft;
    if (stamps && ft.traces_together && f >= o.warmup) {
      frame.render(f, 1, true);
      apart = frame.timings();
    }
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
      if (!bb.traces_together) t["b2b_shadow"].push_back(bb.shadow_ms);  // else in b2b_trace
      t["b2b_frame"].push_back((moves ? g.update_ms : 0.0) + bb.total_ms);
    }
    const double update = moves ? (stamps ? g.update_ms : update_host) : 0.0;
    t["update"].push_back(update);
    // Without device timestamps (lavapipe: the host clock around the submission) only the update
    // and the whole frame are measured: the phases are left out, not written as zeros
    if (stamps) {
      t["clear"].push_back(moves ? g.clear_ms : 0.0);
      t["insert"].push_back(moves ? g.insert_ms : 0.0);
      t["insert_triangles"].push_back(moves ? g.insert_triangles_ms : 0.0);
      t["insert_runs"].push_back(moves ? g.insert_runs_ms : 0.0);
      t["order"].push_back(moves ? g.order_ms : 0.0);
      t["gather"].push_back(ft.gather_ms);
      t["visibility"].push_back(ft.visibility_ms);
      t["copy"].push_back(ft.copy_ms);
      t["bin"].push_back(ft.bin_ms);
      t["tiles"].push_back(ft.tiles_ms);
      t["gather_dirs"].push_back(ft.dirs_ms);
      t["gather_count"].push_back(ft.count_ms);
      t["gather_scan"].push_back(ft.scan_ms);
      t["gather_scatter"].push_back(ft.scatter_ms);
      t["gather_fine"].push_back(ft.fine_ms);
      t["resolve"].push_back(ft.resolve_ms);
      t["bounce"].push_back(apart.bounce_ms);
      t["trace"].push_back(apart.trace_ms);
      if (ft.traces_together) t["traces_together"].push_back(ft.trace_ms);
      if (o.sort_bits != 0u) {
        t["sort"].push_back(ft.sort_ms);
        t["sort_first_count"].push_back(ft.sort_first_pass_ms[0]);
        t["sort_first_scan"].push_back(ft.sort_first_pass_ms[1]);
        t["sort_first_scatter"].push_back(ft.sort_first_pass_ms[2]);
      }
      t["shade"].push_back(ft.shade_ms);
      t["shadow"].push_back(apart.shadow_ms);
      t["shadow_trace"].push_back(apart.shadow_trace_ms);
    }
    t["frame"].push_back(update + (stamps ? ft.total_ms : ft.host_ms));
  }
  return run;
}

// The RT pipeline beside the grid: printed, and as JSON.
nlohmann::json rtx_report(const BenchOptions& o, std::map<std::string, double>& m, double build, double mrays,
                          double grid_mib, size_t rays, const vulkan::RtxTimings& rtx_first,
                          const vulkan::RtxMemory& rtx_memory, uint32_t rtx_dynamic, const Agreement& agree) {
  const double rtx_mrays = m["rtx_trace"] > 0.0 ? double(rays) / (m["rtx_trace"] * 1e3) : 0.0;
  const double mib = 1.0 / (1 << 20);
  const char* mode =
      o.rtx_opaque ? "opaque where unmasked, re-traced past the launch triangle" : "any-hit on every triangle";
  const char* dynamic = o.rtx_rebuild ? "rebuilt" : "refitted";
  std::printf("rtx: the device's ray tracing pipeline on the same bounce rays (%s; %u dynamic BLASes %s, the TLAS "
              "rebuilt, each frame)\n",
              mode, rtx_dynamic, dynamic);
  // Side by side: each tracer's static build, per-frame update, trace and structure
  std::printf("| tracer | build ms, once | update ms per frame | trace ms | update + trace ms | Mrays/s | structure "
              "MiB |\n|---|---|---|---|---|---|---|\n");
  std::printf("| grid | %.3f | %.3f (clear %.3f + insert %.3f) | %.3f | %.3f | %.0f | %.1f (all the grid keeps) |\n", build,
              m["update"], m["clear"], m["insert"], m["trace"], m["update"] + m["trace"], mrays, grid_mib);
  std::printf("| rtx | %.3f (static BLASes %.3f) | %.3f (dynamic BLASes %.3f + TLAS %.3f) | %.3f | %.3f | %.0f | %.1f "
              "(static %.1f + dynamic %.1f + TLAS %.2f) |\n",
              rtx_first.first_build_ms, rtx_first.static_build_ms, m["rtx_update"], m["rtx_refit"], m["rtx_tlas"], m["rtx_trace"],
              m["rtx_update"] + m["rtx_trace"], rtx_mrays,
              double(rtx_memory.static_blas + rtx_memory.dynamic_blas + rtx_memory.tlas) * mib,
              double(rtx_memory.static_blas) * mib, double(rtx_memory.dynamic_blas) * mib, double(rtx_memory.tlas) * mib);
  std::printf("agree: %.3f %% of all rays, %.3f %% of the bounce rays\n", percent(agree.same, agree.rays),
              percent(agree.same_bounce, agree.bounce));
  std::printf("agreement, the last frame: %zu of %zu rays the same (instance, triangle) or both miss; of the %zu bounce "
              "rays %zu. Differ: grid hit / rtx miss %zu, grid miss / rtx hit %zu, other triangle %zu (the grid's a "
              "gap-fill voxel: %zu; rtx's nearer: %zu, of which at t < 1e-3 of the grid's: %zu). Same triangle: %zu "
              "hits, t identical in bits %zu, within 4 ulps %zu, relative difference at most %.2g. Rays traced again "
              "past their launch triangle: %zu\n\n",
              agree.same, agree.rays, agree.bounce, agree.same_bounce, agree.grid_only, agree.rtx_only, agree.different,
              agree.different_gap_fill, agree.rtx_closer, agree.rtx_at_origin, agree.both_hit, agree.t_identical,
              agree.t_within_4_ulps, agree.t_max_rel, agree.retraced);
  std::fflush(stdout);
  return {{"mode", mode},
          {"dynamic_blas", dynamic},
          {"dynamic_instances", rtx_dynamic},
          {"static_blas_build_ms", rtx_first.static_build_ms},
          {"first_build_ms", rtx_first.first_build_ms},
          {"update_ms", m["rtx_update"]},
          {"refit_ms", m["rtx_refit"]},
          {"tlas_ms", m["rtx_tlas"]},
          {"trace_ms", m["rtx_trace"]},
          {"mrays_per_s", rtx_mrays},
          {"memory_bytes",
               {{"static_blas", rtx_memory.static_blas},
                {"dynamic_blas", rtx_memory.dynamic_blas},
                {"tlas", rtx_memory.tlas},
                {"scratch", rtx_memory.scratch}}},
          {"agreement",
               {{"rays", agree.rays},
                {"same", agree.same},
                {"bounce_rays", agree.bounce},
                {"same_bounce", agree.same_bounce},
                {"grid_hit_rtx_miss", agree.grid_only},
                {"grid_miss_rtx_hit", agree.rtx_only},
                {"other_triangle", agree.different},
                {"other_triangle_grid_gap_fill", agree.different_gap_fill},
                {"other_triangle_rtx_nearer", agree.rtx_closer},
                {"other_triangle_rtx_at_origin", agree.rtx_at_origin},
                {"same_triangle_hits", agree.both_hit},
                {"t_identical", agree.t_identical},
                {"t_within_4_ulps", agree.t_within_4_ulps},
                {"t_max_relative_difference", agree.t_max_rel},
                {"retraced", agree.retraced}}}};
}

// Embree on the CPU, on the last frame's own bounce rays, at that frame's time.
void embree_on_frame_rays(const BenchOptions& o, const Scene& scene, const FrameRun& run, nlohmann::json& out) {
  const std::vector<Ray>& last_rays = run.last_rays;
  const std::vector<Hit>& last_hits = run.last_hits;
  const float last_time = run.last_time;
  if (std::find(o.backends.begin(), o.backends.end(), "embree") == o.backends.end() || last_rays.empty()) return;
  {
    std::unique_ptr<Tracer> embree = make_backend("embree", o.backend_options, scene);
    auto t0 = std::chrono::steady_clock::now();
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
    const double ms = median(times), agree_pct = agreement_percent(last_rays, last_hits, embree_hits);
    size_t gap = 0;
    for (size_t i : index) gap += (last_hits[i].flags & shared::kHitGapFill) != 0;
    const unsigned threads = reference::thread_count(o.backend_options.grid);
    std::printf("embree on the same bounce rays (CPU, %u threads; the last frame, t = %.3f): %zu rays in %.2f ms (median of 3), "
                "%.1f Mrays/s; the GPU grid agrees on %.3f %% (same instance and triangle, or both miss; %zu gap-fill hits); "
                "embree build + update %.0f ms\n\n",
                threads, last_time, real.size(), ms, double(real.size()) / (ms * 1e3), agree_pct, gap, embree_build);
    out["backends"]["embree_on_frame_rays"] = {{"device", "CPU, " + std::to_string(threads) + " threads"},
                                               {"rays", real.size()},       {"trace_ms", ms},
                                               {"trace_ms_all", times},     {"mrays_per_s", double(real.size()) / (ms * 1e3)},
                                               {"agree_percent", agree_pct},    {"gpu_gap_fill_hits", gap},
                                               {"build_ms", embree_build},  {"time", last_time}};
  }
}

// The grid's memory (everything it keeps on the device for the trace, as allocated:
// VulkanGridTracer::memory, and the plane buffer the watertight test reads) and the frame's
// buffers, MiB. (Not counted: the geometry buffer, which the RT pipeline's structures are built
// from too.)
struct VulkanMemory {
  double grid = 0.0, skip = 0.0, spill = 0.0, frame = 0.0;  // grid: the image, or the offsets and references
  double dirty = 0.0, planes = 0.0, total = 0.0;
  bool compact = false;
};
VulkanMemory vulkan_memory(const BenchOptions& o, const Scene& scene, const vulkan::VulkanGridTracer& vk,
                           const vulkan::VulkanFrame& frame) {
  VulkanMemory mem;
  const plan::GridMemory gm = vk.memory();
  const double mib = 1.0 / (1 << 20);
  mem.compact = (vk.params().flags & shared::kGridCompact) != 0u;
  mem.grid = double(mem.compact ? gm.offsets + gm.refs : gm.image) * mib;
  mem.skip = double(gm.skip) * mib;
  mem.spill = (vk.params().flags & shared::kGridSpill) != 0u ? double(gm.spill + gm.heads) * mib : 0.0;
  mem.dirty = double(gm.dirty) * mib;
  mem.planes = double(vk.plane_buffer().size) * mib;
  mem.total = double(gm.total()) * mib + mem.planes;
  const size_t frame_rays = 1 + (frame.shadows() ? scene.lights.size() : 0);  // bounce, then shadow rays
  mem.frame =
      double(o.width) * o.height * (4 + 4 + sizeof(shared::GatherTexel) + frame_rays * (sizeof(Ray) + sizeof(Hit)) + 4) /
      (1 << 20);
  return mem;
}

// The static build again, the GPU warm (the first one ran at idle clocks: docs/VULKAN.md): the
// median of 5, its phases into `t`; 0 without timestamps.
double warm_build_ms(vulkan::VulkanGridTracer& vk, const Scene& scene, bool stamps,
                     std::map<std::string, std::vector<double>>& t) {
  std::vector<double> warm_builds;
  for (int i = 0; i < 5 && stamps; ++i) {
    vk.build(scene, 0.0f);
    warm_builds.push_back(vk.timings().build_ms);
    t["build_init"].push_back(vk.timings().build_init_ms);
    t["build_static"].push_back(vk.timings().build_static_ms);
    t["build_skip"].push_back(vk.timings().build_skip_ms);
    t["build_dynamic"].push_back(vk.timings().build_dynamic_ms);
  }
  return median(warm_builds);
}

// The frame's table (medians `m`), the shadow pass, the spill list, the gather's and the warm
// build's split, the grid's memory.
void print_frame_tables(const BenchOptions& o, const Scene& scene, const vulkan::VulkanFrame& frame,
                        std::map<std::string, double>& m, const std::map<std::string, std::vector<double>>& t,
                        bool stamps, uint32_t gather_tiles, const vulkan::GatherPairs& pairs, double build, double build_warm, double mrays,
                        const VulkanMemory& mem, const std::string& spill_line, size_t shadow_used) {
  const char* gather_name = frame.gather_mode() == vulkan::GatherMode::compute ? "compute"
                            : frame.gather_mode() == vulkan::GatherMode::boxes ? "boxes"
                                                                               : "raster";
  std::printf("| build ms (first, warm) | update ms (clear + insert) | gather ms | bounce rays ms | trace ms | shade ms | frame ms "
              "(update..shade) | Mrays/s (trace) | grid MiB (all it keeps) | frame buffers MiB |\n"
              "|---|---|---|---|---|---|---|---|---|---|\n");
  // A phase the clock did not measure (no device timestamps) is "-", not 0
  auto ms = [&](const char* key, const char* format = "%.3f") {
    if (!t.count(key)) return std::string("-");
    char b[32];
    std::snprintf(b, sizeof b, format, m[key]);
    return std::string(b);
  };
  char warm[32] = "-", rate[32] = "-";
  if (stamps) std::snprintf(warm, sizeof warm, "%.3f", build_warm);
  if (t.count("trace")) std::snprintf(rate, sizeof rate, "%.0f", mrays);
  std::printf("| %.3f, %s | %s (%s + %s) | %s | %s | %s | %s | %s | %s | %.1f | %.1f |\n\n", build, warm,
              ms("update").c_str(), ms("clear").c_str(), ms("insert").c_str(), ms("gather").c_str(), ms("bounce").c_str(),
              ms("trace").c_str(), ms("shade").c_str(), ms("frame").c_str(), rate, mem.total, mem.frame);
  if (o.sort_bits != 0u && t.count("sort"))
    std::printf("sorted rays: the sort's %u passes %.3f ms of the trace's %.3f (its rays made by the bounce pass, "
                "%.3f ms); the first pass: count with the keys made %.3f, scan %.3f, scatter %.3f ms\n\n",
                o.sort_bits / 4u, m["sort"], m["trace"], m["bounce"], m["sort_first_count"], m["sort_first_scan"],
                m["sort_first_scatter"]);
  if (t.count("traces_together"))
    std::printf("traces together: the bounce trace and the first light's shadow trace in one dispatch, %.3f ms in the "
                "frame above; apart (the same frames rendered again as two passes: the trace column and the shadow "
                "pass below) %.3f + %.3f = %.3f ms; together saves %.3f ms (%.1f %%)\n\n",
                m["traces_together"], m["trace"], m["shadow"], m["trace"] + m["shadow"],
                m["trace"] + m["shadow"] - m["traces_together"],
                m["trace"] + m["shadow"] > 0.0 ? 100.0 * (1.0 - m["traces_together"] / (m["trace"] + m["shadow"])) : 0.0);
  if (frame.shadows() && stamps)
    std::printf("shadow pass: %zu shadow rays per frame, of %zu slots (%zu light(s) x %ux%u): rays %.3f + trace %.3f "
                "= %.3f ms (%s)%s\n\n",
                shadow_used, scene.lights.size() * o.width * o.height, scene.lights.size(), o.width, o.height,
                m["shadow"] - m["shadow_trace"], m["shadow_trace"], m["shadow"],
                t.count("traces_together") ? "rendered apart; in the frame above traced with the bounce rays"
                                           : "in the frame above, between trace and shade",
                t.count("b2b_shadow") ? (", back to back " + std::to_string(m["b2b_shadow"]) + " ms").c_str() : "");
  else if (frame.shadows())
    std::printf("shadow pass: %zu shadow rays per frame, of %zu slots (%zu light(s) x %ux%u), in the frame above (host "
                "clock: not split; --shadows off gives the frame without it)\n\n",
                shadow_used, scene.lights.size() * o.width * o.height, scene.lights.size(), o.width, o.height);
  else
    std::printf("shadow pass: none (%s)\n\n", scene.lights.empty() ? "the scene has no lights" : "--shadows off");
  std::printf("%s (after the last frame's update)\n\n", spill_line.c_str());
  const std::string pair_text =
      frame.gather_mode() != vulkan::GatherMode::compute ? ""
      : pairs.buckets ? ", " + std::to_string(pairs.pairs) + " tile pairs in buckets of " +
                            std::to_string(pairs.bucket) + ", " +
                            std::to_string(pairs.past) + " past them (" + std::to_string(pairs.past_in_place) +
                            " rasterized by the pairs pass, the rest by the past pass), fine pass"
      : pairs.overflow ? ", " + std::to_string(pairs.pairs) + " tile pairs over the capacity " +
                             std::to_string(pairs.capacity) + ": the item pass ran"
                       : ", " + std::to_string(pairs.pairs) + " tile pairs, fine pass";
  if (!stamps)
    std::printf("gather split and warm build split: not measured (the host clock times the whole frame)\n");
  else
    std::printf("gather split: visibility (%s; %u work items in frame 0%s) %.3f (bin %.3f + tiles %.3f), copy %.3f, "
              "resolve %.3f ms; warm build split (%s build): blank image %.3f, static instances %.3f, skip field %.3f, "
              "dynamic instances %.3f ms\n",
              gather_name, gather_tiles, pair_text.c_str(), m["visibility"], m["bin"], m["tiles"], m["copy"], m["resolve"],
              o.backend_options.vk_build.c_str(), m["build_init"], m["build_static"], m["build_skip"], m["build_dynamic"]);
  if (stamps && !o.backend_options.build_pass_timestamps)
    std::printf("first build split: blank image %.3f, static instances %.3f, skip field %.3f, dynamic instances %.3f ms\n",
                m["first_build_init"], m["first_build_static"], m["first_build_skip"], m["first_build_dynamic"]);
  if (stamps && o.backend_options.build_pass_timestamps)
    std::printf("first build split: blank image %.3f, static instances %.3f (insert %.3f, spill order %.3f, compact: "
                "sums %.3f, scan %.3f, offsets %.3f, scatter %.3f, order %.3f), skip field %.3f (fill %.3f, table z %.3f, "
                "y %.3f, x %.3f, bricks %.3f, cells %.3f), dynamic instances %.3f ms (--build-passes)\n",
                m["first_build_init"], m["first_build_static"], m["first_static_insert"], m["first_static_spill_order"],
                m["first_static_sums"], m["first_static_scan"], m["first_static_offsets"], m["first_static_scatter"],
                m["first_static_order"], m["first_build_skip"], m["first_skip_fill"],
                m["first_skip_table_z"], m["first_skip_table_y"], m["first_skip_table_x"], m["first_skip_bricks"],
                m["first_skip_cells"], m["first_build_dynamic"]);
  if (frame.gather_mode() == vulkan::GatherMode::compute && stamps && pairs.buckets)
    std::printf("gather passes: starting pass (keys, depth bounds, list counts, pixel rays) %.3f, bin %.3f, pairs "
                "(buckets) %.3f, past %.3f, fine (with its resolve) %.3f ms\n",
                m["gather_dirs"], m["bin"] - m["gather_dirs"], m["gather_count"], m["gather_scan"], m["gather_fine"]);
  else if (frame.gather_mode() == vulkan::GatherMode::compute && stamps)
    std::printf("gather passes: starting pass (keys, depth bounds, list counts, pixel rays) %.3f, bin %.3f, count %.3f, "
                "scan %.3f, scatter %.3f, fine (with its resolve) %.3f ms\n",
                m["gather_dirs"], m["bin"] - m["gather_dirs"], m["gather_count"], m["gather_scan"], m["gather_scatter"],
                m["gather_fine"]);
  if (stamps && m["update"] > 0.0)
    std::printf("update passes: clear %.3f, triangles (with the runs' dispatch) %.3f, runs of long ranges %.3f, spill "
                "lists' order %.3f ms\n",
                m["clear"], m["insert_triangles"], m["insert_runs"], m["order"]);
  std::printf("grid memory (%s layout): %s %.1f MiB, spill list and heads %.1f MiB, skip field %.1f MiB, dirty-cell "
              "list %.1f MiB, plane buffer %.1f MiB, total %.1f MiB\n",
              mem.compact ? "compact" : "image", mem.compact ? "offsets and references" : "image", mem.grid, mem.spill,
              mem.skip, mem.dirty, mem.planes, mem.total);
}

// The trace's counters (medians over the counted frames): printed, and as JSON (empty without).
nlohmann::json trace_counter_report(const std::map<std::string, std::vector<double>>& counters, size_t rays,
                                    double trace_ms, uint32_t counted) {
  // The trace's counters; bytes the trace requests per ray, estimated from them: the ray (48) and
  // its hit record (32), per visited cell one blank or status texel (4), per test the slot's
  // texel (4), the instance (16) and the triangle (48). Requested, not DRAM traffic (the caches
  // serve most of it); ignores the few uv, material and alpha reads of accepted hits.
  std::map<std::string, double> cm;
  for (auto& [k, v] : counters) cm[k] = median(v);
  const double bytes_per_ray = 80.0 + 4.0 * cm["cells_mean"] + 68.0 * cm["tests_mean"];
  // trace_ms 0: the trace was not timed on its own (the host clock): no rate, "-" and null
  const double rays_per_s = trace_ms > 0.0 ? double(rays) / (trace_ms * 1e-3) : 0.0;
  char rate[32] = "-", traffic[32] = "-";
  if (trace_ms > 0.0) {
    std::snprintf(rate, sizeof rate, "%.3g", rays_per_s);
    std::snprintf(traffic, sizeof traffic, "%.0f", rays_per_s * bytes_per_ray * 1e-9);
  }
  if (!counters.empty())
    std::printf("| trace: rays | rays/s | cells visited mean / p99 / max | refs tested mean / p99 / max | bytes read per ray "
                "(estimate) | GB/s requested |\n|---|---|---|---|---|---|\n"
                "| %zu | %s | %.2f / %.0f / %.0f | %.2f / %.0f / %.0f | %.0f | %s |\n"
                "(counters: medians over the first %u timed frames of each frame's mean / p99 / max over its real rays)\n\n",
                rays, rate, cm["cells_mean"], cm["cells_p99"], cm["cells_max"], cm["tests_mean"], cm["tests_p99"],
                cm["tests_max"], bytes_per_ray, traffic, counted);
  if (counters.empty()) return nlohmann::json();
  nlohmann::json c = {{"frames", counted},
                      {"rays_per_s", trace_ms > 0.0 ? nlohmann::json(rays_per_s) : nlohmann::json()},
                      {"bytes_per_ray_estimate", bytes_per_ray}};
  for (auto& [k, v] : cm) c[k] = v;
  return c;
}

vulkan::FrameOptions frame_options(const BenchOptions& o, const Scene& scene) {
  vulkan::FrameOptions fo{.width = o.width, .height = o.height};
  fo.gather = o.gather == "raster"  ? vulkan::GatherMode::raster
              : o.gather == "boxes" ? vulkan::GatherMode::boxes
                                    : vulkan::GatherMode::compute;
  fo.gather_lists = o.gather_lists == "scan" ? vulkan::GatherLists::scan : vulkan::GatherLists::buckets;
  fo.gather_bucket_capacity = o.gather_bucket;
  fo.compact_rays = o.compact_rays;
  fo.sort_bits = o.sort_bits;
  fo.shadows = shadows_for(o.shadows, scene);
  fo.traces_together = o.traces == "together";
  return fo;
}

// With GRIDRT_VALIDATION=1: what the validation layer said (the tool's only way to show it)
void report_validation(vulkan::Context& ctx, nlohmann::json& j) {
  if (!ctx.validation()) return;
  const std::vector<std::string> msgs = ctx.messages();
  std::fprintf(stderr, "validation layer: %zu messages\n", msgs.size());
  for (size_t i = 0; i < msgs.size() && i < 20; ++i) std::fprintf(stderr, "  %s\n", msgs[i].c_str());
  j["validation_messages"] = msgs.size();
}

// The whole frame on the GPU: the grid's static build once, then per frame the update (clear,
// dynamic insert) and VulkanFrame::render (gather, bounce, trace, shade), GPU timestamps.
void bench_vulkan_frame(const BenchOptions& o, const Scene& scene, nlohmann::json& out) {
  std::unique_ptr<Tracer> tracer = make_backend("vulkan", o.backend_options, scene);
  auto* vk = dynamic_cast<vulkan::VulkanGridTracer*>(tracer.get());
  if (!vk) throw Error("bench: the vulkan backend is not the Vulkan grid");
  if (o.rtx)
    if (const std::string why = vulkan::rtx_unsupported(vk->context()); !why.empty()) throw Error("--rtx: " + why);
  auto t0 = std::chrono::steady_clock::now();
  vk->build(scene, 0.0f);
  const double build_host = ms_since(t0);
  const bool stamps = vk->timings().build_ms > 0.0 && vk->context().info().driver_id != VK_DRIVER_ID_MESA_LLVMPIPE;
  const double build = stamps ? vk->timings().build_ms : build_host;
  const vulkan::GridTimings first_build = vk->timings();
  vulkan::VulkanFrame frame(*vk, scene, frame_options(o, scene));
  if (std::find(o.frame_knobs.begin(), o.frame_knobs.end(), "--traces") != o.frame_knobs.end() && !frame.shadows())
    throw OptionsError("--traces chooses whether the bounce trace shares its dispatch with the shadow trace; the frame "
                       "has no shadow pass (" + (scene.lights.empty() ? scene.name + " has no lights" : std::string("--shadows off")) +
                       "): it does nothing (leave it out)");
  // The RT pipeline side by side: its acceleration structures over the geometry the build wrote
  std::unique_ptr<vulkan::VulkanRtxTracer> rtx;
  vulkan::Buffer rtx_hits;
  if (o.rtx) {
    if (!frame.bounce())
      throw Error("--rtx: " + scene.name + " has no glossy material, so the frame has no bounce rays to trace");
    rtx = std::make_unique<vulkan::VulkanRtxTracer>(
        *vk, vulkan::RtxOptions{.any_hit_all = !o.rtx_opaque, .rebuild_dynamic = o.rtx_rebuild});
    rtx_hits = vk->context().create_buffer(VkDeviceSize(frame.ray_count()) * sizeof(Hit), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  }
  FrameRun run = run_frames(o, scene, vk, frame, rtx.get(), rtx_hits, stamps);
  std::map<std::string, std::vector<double>>& t = run.t;
  const size_t rays = run.rays;
  const std::map<std::string, std::vector<double>>& counters = run.counters;
  const uint32_t counted = run.counted, gather_tiles = run.gather_tiles;
  const shared::SpillHeader spill = vk->spill_header();
  const uint32_t spill_flags = vk->params().flags;
  // The RT pipeline's hits against the grid's, the last frame's rays; then the RT tracer goes
  // (the grid's builds below make new buffers)
  Agreement agree;
  vulkan::RtxTimings rtx_first;
  vulkan::RtxMemory rtx_memory;
  uint32_t rtx_dynamic = 0;
  if (rtx) {
    agree = compare_hits(frame.download_rays(), frame.download_hits(),
                         vk->context().download<Hit>(rtx_hits, frame.ray_count()));
    rtx_first = rtx->timings();
    rtx_memory = rtx->memory();
    rtx_dynamic = rtx->dynamic_instance_count();
    rtx.reset();
    rtx_hits.reset();
  }
  const double build_warm = warm_build_ms(*vk, scene, stamps, t);
  std::map<std::string, double> m;
  for (auto& [k, v] : t) m[k] = median(v);
  m["first_build_init"] = first_build.build_init_ms;
  m["first_build_static"] = first_build.build_static_ms;
  m["first_build_skip"] = first_build.build_skip_ms;
  m["first_build_dynamic"] = first_build.build_dynamic_ms;
  const char* skip_parts[6] = {"fill", "table_z", "table_y", "table_x", "bricks", "cells"};
  for (uint32_t k = 0; k < 6; ++k) m[std::string("first_skip_") + skip_parts[k]] = first_build.build_skip_passes_ms[k];
  const char* static_parts[7] = {"insert", "spill_order", "sums", "scan", "offsets", "scatter", "order"};
  for (uint32_t k = 0; k < 7; ++k) m[std::string("first_static_") + static_parts[k]] = first_build.build_static_passes_ms[k];
  const double mrays = m["trace"] > 0.0 ? double(rays) / (m["trace"] * 1e3) : 0.0;
  const shared::GridParams& gp = vk->params();
  const VulkanMemory mem = vulkan_memory(o, scene, *vk, frame);
  const std::string device = vk->context().info().name;
  const std::string clock = !stamps ? "host (submit to fence; the frame's phases not split)"
                            : vk->context().info().type == VK_PHYSICAL_DEVICE_TYPE_CPU
                                ? "device timestamps of a CPU implementation"
                                : "gpu timestamps";
  const char* gather_name = frame.gather_mode() == vulkan::GatherMode::compute ? "compute"
                            : frame.gather_mode() == vulkan::GatherMode::boxes ? "boxes"
                                                                               : "raster";
  std::printf("\nvulkan, the whole frame on the GPU (%s; %s): %zu bounce rays per frame, grid %ux%ux%u %s %u, "
              "%s gather, %s trace\n",
              device.c_str(), clock.c_str(), rays, gp.cells.x, gp.cells.y, gp.cells.z,
              (gp.flags & shared::kGridCompact) != 0u ? "compact, largest cell" : "capacity", gp.capacity, gather_name,
              o.compact_rays ? "compacted"
              : o.sort_bits != 0u ? ("sorted-ray (" + std::to_string(o.sort_bits) + " key bits)").c_str()
              : frame.traces_together() ? "every-pixel (with the first light's shadow rays in one dispatch)"
                                        : "every-pixel");
  // The shadow rays the last frame made: a slot per pixel and light, a ray where the pixel has a
  // surface facing its light (the slots were reported as rays, where the CPU counts rays: an
  // outside sweep)
  size_t shadow_used = 0;
  if (frame.shadows())
    for (const Ray& r : frame.download_shadow_rays()) shadow_used += !is_unused(r);
  print_frame_tables(o, scene, frame, m, t, stamps, gather_tiles, run.gather_pairs, build, build_warm, mrays, mem,
                     spill_text(spill, spill_flags), shadow_used);
  const nlohmann::json trace_counters = trace_counter_report(counters, rays, m["trace"], counted);
  if (t.count("b2b_frame") && t.count("traces_together"))
    std::printf("back to back (%u frames per submission, the last timed; update as above): gather %.3f, bounce %.3f, "
                "bounce and shadow traces (one dispatch) %.3f, shade %.3f, frame (update..shade) %.3f ms\n\n",
                o.back_to_back, m["b2b_gather"], m["b2b_bounce"], m["b2b_trace"], m["b2b_shade"], m["b2b_frame"]);
  else if (t.count("b2b_frame"))
    std::printf("back to back (%u frames per submission, the last timed; update as above): gather %.3f, bounce %.3f, "
                "trace %.3f, shade %.3f, frame (update..shade) %.3f ms, %.0f Mrays/s\n\n",
                o.back_to_back, m["b2b_gather"], m["b2b_bounce"], m["b2b_trace"], m["b2b_shade"], m["b2b_frame"],
                m["b2b_trace"] > 0.0 ? double(rays) / (m["b2b_trace"] * 1e3) : 0.0);
  std::fflush(stdout);
  // grid_mib: everything the grid keeps, as the CPU backends' (its storage, the image or the
  // offsets and references, is storage_mib); a figure the clock did not measure is null
  nlohmann::json j = {{"device", device}, {"clock", clock},       {"build_ms", build},
                      {"build_warm_ms", stamps ? nlohmann::json(build_warm) : nlohmann::json()}, {"rays_per_frame", rays},
                      {"mrays_per_s", t.count("trace") ? nlohmann::json(mrays) : nlohmann::json()},
                      {"grid_mib", mem.total}, {"storage_mib", mem.grid}, {"skip_mib", mem.skip}, {"planes_mib", mem.planes}, {"spill_mib", mem.spill}, {"frame_mib", mem.frame},
                      {"layout", mem.compact ? "compact" : "image"},
                      {"grid_cells", {gp.cells.x, gp.cells.y, gp.cells.z}}, {"capacity", gp.capacity},
                      {"spill", spill_json(spill, spill_flags)}};
  if (stamps) {
    j["first_build_split_ms"] = {{"blank_image", m["first_build_init"]},
                                 {"static_instances", m["first_build_static"]},
                                 {"skip_field", m["first_build_skip"]},
                                 {"dynamic_instances", m["first_build_dynamic"]}};
    if (o.backend_options.build_pass_timestamps) {
      j["first_build_split_ms"]["static_passes"] = {
          {"insert", m["first_static_insert"]},          {"spill_order", m["first_static_spill_order"]},
          {"compact_sums", m["first_static_sums"]},      {"compact_scan", m["first_static_scan"]},
          {"compact_offsets", m["first_static_offsets"]}, {"compact_scatter", m["first_static_scatter"]},
          {"compact_order", m["first_static_order"]}};
      j["first_build_split_ms"]["skip_field_passes"] = {
          {"fill", m["first_skip_fill"]},       {"table_z", m["first_skip_table_z"]}, {"table_y", m["first_skip_table_y"]},
          {"table_x", m["first_skip_table_x"]}, {"bricks", m["first_skip_bricks"]},   {"cells", m["first_skip_cells"]}};
    }
  }
  j["gather_mode"] = gather_name;
  j["gather_tiles_frame0"] = gather_tiles;
  j["gather_pairs_frame0"] = run.gather_pairs.pairs;
  j["gather_pairs_overflow"] = run.gather_pairs.overflow;
  j["gather_lists"] = run.gather_pairs.buckets ? "buckets" : "scan";
  j["gather_pairs_past_buckets"] = run.gather_pairs.past;
  j["compact_rays"] = o.compact_rays;
  j["sort_bits"] = o.sort_bits;
  j["traces_together"] = frame.traces_together();
  j["shadows"] = frame.shadows();
  j["shadow_rays_per_frame"] = shadow_used;
  j["shadow_ray_slots_per_frame"] = frame.shadows() ? scene.lights.size() * o.width * o.height : 0;
  for (auto& [k, v] : t) {
    j[k + "_ms"] = m[k];
    j[k + "_ms_all"] = v;
  }
  if (o.rtx) j["rtx"] = rtx_report(o, m, build, mrays, mem.total, rays, rtx_first, rtx_memory, rtx_dynamic, agree);
  report_validation(vk->context(), j);
  if (!trace_counters.empty()) j["trace_counters"] = trace_counters;
  out["backends"]["vulkan"] = j;

  embree_on_frame_rays(o, scene, run, out);
}
#endif

// The CPU's gather buffer of each timed frame, by the exact traversal of the reference grid, as
// the GPU frame makes its own: at the frame's time (frame_time(0, f + 1, fps)) where instances
// move, so that the frame's bounce and shadow rays leave the surfaces where they are when the grid
// is traced (made once at time 0, the CPU's rows traced frame 0's rays against every later frame's
// grid, off surfaces that had moved: an outside sweep); one gather for a scene that does not move.
// The last one made is kept (each backend walks the frames in order).
class FrameGathers {
 public:
  FrameGathers(const BenchOptions& o, const Scene& scene, reference::ReferenceGridTracer& tracer)
      : o_(o), scene_(scene), tracer_(tracer), moves_(scene.has_dynamic()) {}

  const GatherBuffer& at(uint32_t f) {
    if (!moves_) f = 0;
    if (made_ && f == frame_) return gather_;
    const float time = frame_time(0.0f, f + 1, o_.fps);
    if (!built_) tracer_.build(scene_, time);
    else tracer_.update(time);
    built_ = true;
    Progress progress("gather buffer (CPU reference, exact)", size_t(o_.width) * o_.height);
    ProgressTracer traced(tracer_, progress);
    gather_ = make_gather(scene_, traced, scene_.frame_camera(), o_.width, o_.height, time);
    made_ = true;
    frame_ = f;
    return gather_;
  }

 private:
  const BenchOptions& o_;
  const Scene& scene_;
  reference::ReferenceGridTracer& tracer_;
  bool moves_;
  bool built_ = false, made_ = false;
  uint32_t frame_ = 0;
  GatherBuffer gather_;
};

// One backend that traces on the CPU's rays: its build, then per frame the update and the trace
// of the frame's bounce rays (and its shadow rays, with `shadows`) off its gather: a table row,
// notes, JSON.
void bench_cpu_backend(const BenchOptions& o, const Scene& scene, const std::string& name, FrameGathers& gathers,
                       bool frame_rays, const std::vector<Ray>& given, size_t bounce_count, bool shadows,
                       nlohmann::json& out,
                       std::vector<std::string>& notes, std::vector<std::string>& shadow_notes) {
  std::unique_ptr<Tracer> tracer = make_backend(name, o.backend_options, scene);
  PhaseTimes times;
  // The threads it runs with (--threads; the machine's were printed whatever was asked: an outside sweep)
  std::string device = "CPU, " + std::to_string(reference::thread_count(o.backend_options.grid)) + " threads";
  double grid_mib = 0.0;
  auto t0 = std::chrono::steady_clock::now();
  tracer->build(scene, 0.0f);
  times.build = ms_since(t0);
#ifdef GRIDRT_HAVE_VULKAN
  auto* vk = dynamic_cast<vulkan::VulkanGridTracer*>(tracer.get());
  if (vk) {
    device = vk->context().info().name;
    // lavapipe's timestamps do not bracket compute dispatches (docs/VULKAN.md): its traces timed
    // 0.007 ms where the host clock says 1.5 ms (an outside sweep's find); the host's times there
    if (vk->timings().build_ms > 0.0 && vk->context().info().driver_id != VK_DRIVER_ID_MESA_LLVMPIPE) {
      times.device_stamps = true;
      times.clock = vk->context().info().type == VK_PHYSICAL_DEVICE_TYPE_CPU ? "device timestamps (CPU implementation)"
                                                                             : "gpu timestamps";
      times.build = vk->timings().build_ms;
    }
  }
#endif
  // Everything the grid keeps (the image or the compact arrays, spill list, heads, skip field, the
  // plane buffer)
  if (auto* ref = dynamic_cast<reference::ReferenceGridTracer*>(tracer.get()))
    grid_mib = double(ref->stats().memory.total() + ref->data().planes.size() * sizeof(shared::GridPlane)) / (1 << 20);
#ifdef GRIDRT_HAVE_VULKAN
  if (vk) grid_mib = double(vk->memory().total() + vk->plane_buffer().size) / (1 << 20);
#endif
  const AccelDump dump = tracer->dump();
  if (grid_mib == 0.0 && !dump.texels.empty()) grid_mib = double(dump.texels.size()) * 4.0 / (1 << 20);

  std::vector<Hit> hits, shadow_hits;
  std::vector<double> shadow_ms;
  std::vector<Ray> rays, shadow;  // the frame's; after the loop, the last frame's
  for (uint32_t f = 0; f < o.warmup + o.frames; ++f) {
    const float time = frame_time(0.0f, f + 1, o.fps);
    rays = frame_rays ? bounce_rays(scene, gathers.at(f), f) : given;
    if (frame_rays && shadows) shadow = shadow_rays(scene, gathers.at(f));
    shadow_hits.resize(shadow.size());
    hits.resize(rays.size());
    t0 = std::chrono::steady_clock::now();
    tracer->update(time);
    double update_ms = ms_since(t0);
    t0 = std::chrono::steady_clock::now();
    tracer->trace(rays, hits);
    double trace_ms = ms_since(t0);
#ifdef GRIDRT_HAVE_VULKAN
    if (vk && times.device_stamps) {
      update_ms = vk->timings().update_ms;
      trace_ms = vk->timings().trace_ms;
    } else if (vk) {
      update_ms = vk->timings().update_host_ms;
      trace_ms = vk->timings().trace_host_ms;
    }
#endif
    double shadow_trace_ms = 0.0;
    if (!shadow.empty()) {
      t0 = std::chrono::steady_clock::now();
      tracer->trace_any(shadow, shadow_hits);
      shadow_trace_ms = ms_since(t0);
#ifdef GRIDRT_HAVE_VULKAN
      if (vk) shadow_trace_ms = times.device_stamps ? vk->timings().trace_ms : vk->timings().trace_host_ms;
#endif
    }
    if (f < o.warmup) continue;
    times.update.push_back(update_ms);
    times.trace.push_back(trace_ms);
    shadow_ms.push_back(shadow_trace_ms);
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
  // more decimals for a slow device: its rate read "0.0" at one decimal (an outside sweep)
  std::printf("| %s | %s | %s | %.3f | %.3f | %.3f | %.*f | %.2f |\n", name.c_str(), device.c_str(),
              times.clock.c_str(), times.build, update, trace, mrays >= 10.0 ? 1 : 3, mrays, grid_mib);
  const bool grid = !dump.texels.empty();
  if (grid) notes.push_back(name + ": " + spill_text(spill, spill_flags));
  // The grid's per-ray counters (the hit records' cells and tests) over the last frame's rays
  nlohmann::json counters_json;
  if (grid) {
    std::vector<uint32_t> cells, tests;
    for (size_t i = 0; i < rays.size() && i < hits.size(); ++i)
      if (!is_unused(rays[i])) {
        cells.push_back(hits[i].cells);
        tests.push_back(hits[i].tests);
      }
    const CounterStats c = counter_stats(cells), tt = counter_stats(tests);
    char line[256];
    std::snprintf(line, sizeof line, "%s: per traced ray of the last frame: cells mean %.2f (p99 %.0f, max %.0f), "
                  "references tested mean %.2f (p99 %.0f, max %.0f)%s", name.c_str(), c.mean, c.p99, c.max, tt.mean,
                  tt.p99, tt.max, (spill_flags & shared::kGridMailbox) != 0u ? ", mailbox on" : "");
    notes.push_back(line);
    counters_json = {{"cells_mean", c.mean}, {"cells_p99", c.p99}, {"cells_max", c.max},
                     {"tests_mean", tt.mean}, {"tests_p99", tt.p99}, {"tests_max", tt.max}};
  }
  // The shadow rays that exist (a pixel with a surface facing the light): the light-major vector
  // holds a slot for every pixel and light, the empty ones unused (they were counted too)
  const size_t shadow_used =
      size_t(std::count_if(shadow.begin(), shadow.end(), [](const Ray& r) { return !is_unused(r); }));
  nlohmann::json shadow_counters;
  if (!shadow.empty()) {
    char line[512];
    std::snprintf(line, sizeof line, "%s: shadow pass: %zu shadow rays per frame (%zu light(s); %zu slots, the others "
                  "empty), their trace %.3f ms (median; not in the table's trace)", name.c_str(), shadow_used,
                  scene.lights.size(), shadow.size(), median(shadow_ms));
    std::string text = line;
    // The shadow rays' own counters (any hit: a ray stops at its first accepted candidate), and
    // how many reach their light
    if (grid && shadow_hits.size() == shadow.size()) {
      std::vector<uint32_t> cells, tests;
      size_t lit = 0;
      for (size_t i = 0; i < shadow.size(); ++i)
        if (!is_unused(shadow[i])) {
          cells.push_back(shadow_hits[i].cells);
          tests.push_back(shadow_hits[i].tests);
          lit += is_miss(shadow_hits[i]);
        }
      const CounterStats c = counter_stats(cells), tt = counter_stats(tests);
      std::snprintf(line, sizeof line, "; per shadow ray: cells mean %.2f (p99 %.0f, max %.0f), references tested "
                    "mean %.2f (p99 %.0f, max %.0f); %zu reach their light", c.mean, c.p99, c.max, tt.mean, tt.p99,
                    tt.max, lit);
      text += line;
      shadow_counters = {{"cells_mean", c.mean}, {"cells_p99", c.p99}, {"cells_max", c.max}, {"tests_mean", tt.mean},
                         {"tests_p99", tt.p99}, {"tests_max", tt.max}, {"reach_light", lit}};
    }
    shadow_notes.push_back(text);
  }
  std::fflush(stdout);
  out["backends"][name] = {{"device", device},        {"clock", times.clock},   {"build_ms", times.build},
                           {"update_ms", update},     {"trace_ms", trace},      {"mrays_per_s", mrays},
                           {"grid_mib", grid_mib},    {"update_ms_all", times.update},
                           {"trace_ms_all", times.trace}, {"shadow_rays", shadow_used}, {"shadow_slots", shadow.size()},
                           {"shadow_trace_ms", median(shadow_ms)}, {"shadow_trace_ms_all", shadow_ms}};
  if (grid) out["backends"][name]["spill"] = spill_json(spill, spill_flags);
  if (!counters_json.empty()) out["backends"][name]["trace_counters"] = counters_json;
  if (!shadow_counters.empty()) out["backends"][name]["shadow_counters"] = shadow_counters;
}

// A fixed list in the order --ray-order asks: as made, or sorted (coherent_ray_order: neighbours by
// direction and origin); every backend gets the one list, so the hits compare ray by ray.
std::vector<Ray> in_order(std::vector<Ray> rays, const std::string& order) {
  if (order != "sorted") return rays;
  const std::vector<uint32_t> perm = coherent_ray_order(rays);
  std::vector<Ray> sorted(rays.size());
  for (size_t k = 0; k < perm.size(); ++k) sorted[k] = rays[perm[k]];
  return sorted;
}

void run_bench(const BenchOptions& options) {
  // The command line is checked before any work (exit 2): the backends and the rays' kind
  for (const std::string& b : options.backends)
    if (const std::vector<std::string> known = backend_names(); std::find(known.begin(), known.end(), b) == known.end())
      throw OptionsError("--backend: unknown backend '" + b + "' (this build has: " + backend_list() + ")");
#ifdef GRIDRT_HAVE_EMBREE
  if (!verify::is_ray_kind(options.rays) && options.rays != "glossy-list")
    throw OptionsError("--rays: unknown kind '" + options.rays + "' (" + verify::ray_kind_list() + ", glossy-list)");
#else
  if (options.rays != "auto" && options.rays != "glossy" && options.rays != "glossy-list" && options.rays != "primary" &&
      options.rays != "camera")
    throw OptionsError("--rays: '" + options.rays + "' needs the Embree backend (this build has none): auto, glossy, "
                       "glossy-list or primary");
#endif
  check_frame_size(options.width, options.height);
  if (!options.json.empty()) check_output_path(options.json);  // before the benchmark, not after it
  BenchOptions o = options;
  // Frame f's scene time is (f + 1) / fps: the last one within the scene time's limit (1e6 s)
  if (!(double(o.frames) + double(o.warmup) <= 1.0e6 * double(o.fps)))
    throw CLI::ValidationError("--frames", std::to_string(o.frames + o.warmup) + " frames at --fps " +
                                               std::to_string(o.fps) + " pass 1e6 s, the scene time's limit");
  require_distinct_frame_times(0.0f, 1, o.warmup + o.frames, o.fps, "--fps");
  if (o.rtx) {
#ifndef GRIDRT_HAVE_VULKAN
    throw Error("--rtx: this build has no Vulkan backend");
#endif
    if (std::find(o.backends.begin(), o.backends.end(), "vulkan") == o.backends.end())
      throw OptionsError("--rtx runs beside the vulkan backend: add --backend vulkan");
    o.backend_options.ray_tracing = true;
  }
  resolve_image_limit(o.backend_options, std::find(o.backends.begin(), o.backends.end(), "vulkan") != o.backends.end());
  const Scene scene = load_scene_or_default(o.scene);
  if (!o.json.empty()) check_output_allowed(o.json, "JSON report");  // not over an input: refused now, not after
  // A backend named twice is timed once (the report keeps one entry a backend)
  std::vector<std::string> backends;
  for (const std::string& b : o.backends)
    if (std::find(backends.begin(), backends.end(), b) == backends.end()) backends.push_back(b);
  if (backends.empty()) backends.push_back(backend_names().front());

  // The gather buffer of each frame (FrameGathers: one for a scene that does not move), by the
  // exact traversal of the reference grid (CPU), for the
  // backends that trace on the CPU (the vulkan backend makes its own, every frame, on the GPU).
  // (with the vulkan backend, embree traces the GPU frame's own bounce rays instead)
  // --rays: the frame's glossy bounce rays (glossy; auto on a scene with a glossy material), or one
  // fixed set of rays of a kind (primary, diffuse, a verify family; auto: diffuse) that every
  // backend, vulkan included, is handed and traces each frame
  const Features features = Features::for_scene(scene);
  const bool frame_rays = o.rays == "glossy" || (o.rays == "auto" && features.glossy);
  if (o.rays == "glossy" && !features.glossy)
    throw Error("bench: " + scene.name + " has no glossy material, so its frame has no glossy bounce rays: "
                "choose --rays primary, diffuse or a verify family");
  const std::string kind = frame_rays ? "glossy bounce" : (o.rays == "auto" ? "diffuse" : o.rays);
  // --ray-order orders a fixed list; the frame's own rays are traced in its pixel tiles
  if (frame_rays && o.ray_order_set)
    throw OptionsError("--ray-order " + o.ray_order + " orders a fixed list of rays; the frame traces its glossy bounce "
                       "rays in its own pixel tiles (--sort-rays sorts them on the GPU): give --rays glossy-list "
                       "(the same rays of one frame as a list) or another kind");
  if (o.rtx && !frame_rays)
    throw Error("--rtx traces the frame's glossy bounce rays: it needs --rays glossy (or auto) on a scene with a glossy material");
  // --rays auto on a scene without a glossy material traces diffuse rays as a list, without the
  // frame: the frame's options do nothing there (an outside sweep: accepted, as --rays diffuse is not)
  if (!frame_rays && !o.frame_knobs.empty())
    throw OptionsError(o.frame_knobs.front() + " is a knob of the frame, which traces its glossy bounce rays; " + scene.name +
                       " has no glossy material, so --rays auto traces a fixed list of diffuse rays without it: it "
                       "does nothing (leave it out)");
  const bool with_vulkan = frame_rays && std::find(backends.begin(), backends.end(), "vulkan") != backends.end();
  auto on_cpu_rays = [&](const std::string& b) { return b != "vulkan" ? !(with_vulkan && b == "embree") : !frame_rays; };
  const bool cpu_rays = std::any_of(backends.begin(), backends.end(), on_cpu_rays);
  reference::ReferenceGridTracer gather_tracer(plan::gather_options(grid_options_for(o.backend_options, scene)));
  size_t bounce_count = 0;
  std::vector<Ray> given;  // the fixed rays of a kind (not frame_rays)
  FrameGathers gathers(o, scene, gather_tracer);
  if (o.rays == "glossy-list") {
    // The glossy bounce rays of frame 0's gather, the CPU reference's (as the CPU backends trace
    // them in the frame), the real ones as a list: no Embree needed
    for (const Ray& r : bounce_rays(scene, gathers.at(0), 0))
      if (!is_unused(r)) given.push_back(r);
    if (given.empty()) throw Error("bench: " + scene.name + " has no glossy bounce ray (no glossy material in view?)");
  } else if (!frame_rays) {
#ifdef GRIDRT_HAVE_EMBREE
    reference::GridOptions aim = grid_options_for(o.backend_options, scene);
    aim.traversal = reference::Traversal::exact;
    reference::ReferenceGridTracer aimer(aim);
    aimer.build(scene, 0.0f);
    EmbreeTracer embree(0);
    embree.build(scene, 0.0f);
    given = verify::rays_of_kind(kind, scene, aimer.data(), embree, o.width, o.height);
    if (given.empty()) throw Error("bench: " + scene.name + " gives no " + kind + " rays");
#else
    // Without the oracle only the camera rays can be made: verify's camera family (a 16:9 grid of
    // about WIDTH x HEIGHT camera rays, verify/rays.cpp), which needs no Embree
    if (kind != "primary" && kind != "camera")
      throw Error("bench: --rays " + kind + " needs the Embree backend (this build has none): use --rays glossy or primary");
    given = camera_grid_rays(scene.frame_camera(), size_t(o.width) * o.height);
#endif
  }
  if (!frame_rays) {
    given = in_order(std::move(given), o.ray_order);
    bounce_count = given.size();
  }
  if (cpu_rays && frame_rays) {
    const std::vector<Ray> r = bounce_rays(scene, gathers.at(0), 0);
    bounce_count = size_t(std::count_if(r.begin(), r.end(), [](const Ray& ray) { return !is_unused(ray); }));
  }
  // The gather's shadow rays (each frame's), traced after the bounce as their own phase
  const bool shadows = shadows_for(o.shadows, scene);
  // The shadow rays come from the frame's gather: rays of another kind have none (--shadows on
  // with them did nothing, the header said "shadows yes": an outside sweep)
  if (o.shadows == ShadowMode::on && !frame_rays)
    throw OptionsError("--shadows on traces the frame's shadow rays, from its gather: --rays " + o.rays +
                       " has no gather (give --rays glossy, on a scene with glossy materials, or leave --shadows out)");
  if (shadows && !(cpu_rays && frame_rays)) check_shadow_lights(scene);
  std::printf("bench: %s, %llu triangles, %zu instances (%zu dynamic), %ux%u, %s %s rays per frame, "
              "%u frames after %u warm-up\n",
              scene.name.c_str(), (unsigned long long)scene.triangle_count(), scene.instances.size(),
              scene.instances.size() - scene.static_instance_count(), o.width, o.height,
              cpu_rays ? std::to_string(bounce_count).c_str() : "(GPU gather)",
              (kind + (o.ray_order == "sorted" ? " (sorted by direction, then origin)" : "")).c_str(), o.frames, o.warmup);
  std::printf("machine: %u hardware threads; effects the scene calls for: alpha keying %s, update %s, glossy %s, shadows %s\n",
              std::thread::hardware_concurrency(), features.alpha_keying ? "yes" : "no", features.update ? "yes" : "no",
              features.glossy ? "yes" : "no", features.shadows ? "yes" : "no");

  nlohmann::json out;
  out["scene"] = scene.name;
  out["width"] = o.width;
  out["height"] = o.height;
  out["rays_per_frame"] = bounce_count;
  out["rays"] = kind;
  out["ray_order"] = frame_rays ? "tiles" : o.ray_order;
  out["frames"] = o.frames;
  if (cpu_rays)
    std::printf("\n| backend | device | clock | build ms | update ms (median) | trace ms (median) | Mrays/s | grid MiB |\n"
                "|---|---|---|---|---|---|---|---|\n");
  std::vector<std::string> notes;  // printed under the table
  std::vector<std::string> shadow_notes;
  for (const std::string& name : backends) {
#ifdef GRIDRT_HAVE_VULKAN
    if (name == "vulkan" && frame_rays) {
      bench_vulkan_frame(o, scene, out);
      continue;
    }
#endif
    if (on_cpu_rays(name))
      bench_cpu_backend(o, scene, name, gathers, frame_rays, given, bounce_count, cpu_rays && frame_rays && shadows, out,
                        notes, shadow_notes);
  }
  if (!notes.empty()) std::printf("\n");
  for (const std::string& n : notes) std::printf("%s (after the last frame's update)\n", n.c_str());
  for (const std::string& n : shadow_notes) std::printf("%s\n", n.c_str());
  if (!o.json.empty()) write_file_atomically(o.json, "JSON report", out.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  CLI::App* cmd = app.add_subcommand(
      "bench", "Time the static build, then per frame the dynamic update and the glossy-bounce trace (medians)");
  add_scene_argument(cmd, o->scene);
  cmd->add_option("--backend,-b", o->backends, "Backends to time, one after the other: " + backend_list())
      ->delimiter(',');
  add_image_size(cmd, o->width, o->height, "");
  cmd->add_option("--frames", o->frames, "Timed frames")->check(CLI::Range(1u, 100000u));
  cmd->add_option("--warmup", o->warmup, "Untimed frames first")->check(CLI::Range(0u, 1000u));
  cmd->add_option("--back-to-back", o->back_to_back,
                  "Vulkan: also time each frame recorded this many times in one submission, the last timed (GPU kept "
                  "busy); 1: off")
      ->check(CLI::Range(1u, 64u));
  cmd->add_option("--fps", o->fps, "Scene time step per frame is 1/fps")->check(CLI::Range(1.0e-3f, 1.0e6f));
  cmd->add_option("--rays", o->rays,
                  "The traced rays: auto (the frame's glossy bounce rays, else diffuse bounces), glossy, primary, "
                  "diffuse, or a verify family (random, surface, edge, ...); a kind other than glossy is one fixed set "
                  "of about WIDTH x HEIGHT rays, handed to every backend (vulkan included) each frame; glossy-list: the "
                  "glossy bounce rays of frame 0's gather (the CPU reference's) as such a list");
  add_choice(cmd, "--ray-order", o->ray_order, {"given", "sorted"},
                  "A fixed list's order (--rays other than the frame's): given (as made: pixel rows for glossy-list, "
                  "diffuse and primary) or sorted (by direction, then origin: neighbouring rays walk alike; "
                  "the hits are the same, per ray)");
  CLI::Option* rtx =
      cmd->add_flag("--rtx", o->rtx,
                    "Vulkan: the device's ray tracing pipeline (VK_KHR_ray_tracing_pipeline) side by side: each frame, "
                    "after the grid's trace, refit the dynamic instances' BLASes, rebuild the TLAS and trace the same "
                    "bounce rays; report its times and how many of its hits agree with the grid's");
  cmd->add_flag("--rtx-opaque", o->rtx_opaque,
                "With --rtx: opaque geometry where there is no alpha mask, a ray whose closest hit is its launch "
                "triangle traced again past it (default: every triangle through the any-hit shader, which ignores the "
                "launch triangle as the grid does)")
      ->needs(rtx);
  cmd->add_flag("--rtx-rebuild", o->rtx_rebuild, "With --rtx: rebuild the dynamic BLASes each frame instead of refitting")
      ->needs(rtx);
  add_choice(cmd, "--gather", o->gather, {"compute", "boxes", "raster"},
                  "Vulkan: the frame's gather: compute (the CPU gather's ray test through a rasterizer's bins, tiles "
                  "and depth culling; needs 64-bit buffer atomics), boxes (the same test on every pixel of each "
                  "triangle's box) or raster (the paper's raster pass)");
  add_choice(cmd, "--gather-lists", o->gather_lists, {"buckets", "scan"},
             "Vulkan, compute gather: the rasterizer's tile lists written in one pass to a bucket per 8x8-pixel "
             "tile (a pair past its bucket rasterized there), or counted, scanned and scattered");
  cmd->add_option("--gather-bucket", o->gather_bucket,
                  "Vulkan, compute gather with --gather-lists buckets: the pairs a tile's bucket holds (default " +
                      std::to_string(vulkan::kGatherBucketDefault) + "; the pairs past it are rasterized by the past pass)")
      ->check(CLI::Range(0u, 1u << 20));
  add_sort_rays_option(cmd, o->sort_bits,
                       "Vulkan: the frame's bounce rays made by a pass of their own, sorted by the top BITS bits of "
                       "a key (the direction's cell, then the origin's) by a radix sort on the GPU, and traced in that "
                       "order (the same rays and hits; 0, the default: the trace takes every pixel in 8x8 tiles and "
                       "makes its ray itself)");
  add_traces_option(cmd, o->traces);
  cmd->add_flag("--compact-rays", o->compact_rays,
                "Vulkan: trace only the pixels with a bounce ray, through a work list (default: every pixel; the "
                "empty rays return at once)");
  cmd->add_flag("--build-passes", o->backend_options.build_pass_timestamps,
                "Vulkan: time every pass of the static build and of the skip field (printed with the first build's "
                "split; the extra timestamps add about 0.01 ms to the build)");
  cmd->add_option("--counter-frames", o->counter_frames,
                  "Vulkan: timed frames whose hit records are read back for the trace's counters")
      ->check(CLI::Range(0u, 1000u));
  add_shadows_option(cmd, o->shadows);
  add_json_option(cmd, o->json, "the figures");
  add_backend_options(cmd, o->backend_options);
  cmd->callback([o, cmd] {
    check_vulkan_options_apply(cmd, std::find(o->backends.begin(), o->backends.end(), "vulkan") != o->backends.end());
    check_traversal_options(cmd, o->backend_options);
    if (cmd->count("--back-to-back") > 0 &&
        std::find(o->backends.begin(), o->backends.end(), "vulkan") == o->backends.end())
      throw OptionsError("--back-to-back times the Vulkan frame recorded several times a submission: it needs "
                         "--backend vulkan");
    // The Vulkan frame's own knobs did nothing on the other backends (an outside sweep)
    for (const char* name : {"--gather", "--gather-lists", "--gather-bucket", "--compact-rays", "--sort-rays", "--traces", "--build-passes", "--counter-frames"})
      if (cmd->count(name) > 0 && std::find(o->backends.begin(), o->backends.end(), "vulkan") == o->backends.end())
        throw OptionsError(std::string(name) + " is a knob of the Vulkan frame: it needs --backend vulkan");
    if (cmd->count("--gather-bucket") > 0 && (o->gather_lists == "scan" || o->gather != "compute"))
      throw OptionsError("--gather-bucket sizes the compute gather's buckets: it needs --gather compute and "
                         "--gather-lists buckets (the defaults)");
    // The tile lists are the compute gather's (an outside sweep: accepted with the others, nothing changed)
    if (cmd->count("--gather-lists") > 0 && o->gather != "compute")
      throw OptionsError("--gather-lists chooses the compute gather's tile lists; --gather " + o->gather +
                         " has none: it does nothing (leave one out)");
    o->ray_order_set = cmd->count("--ray-order") > 0;
    if (o->sort_bits != 0u && o->compact_rays)
      throw OptionsError("--sort-rays traces the pixels with a bounce ray in their keys' order; --compact-rays traces "
                         "them in the order their rays were made: give one of them");
    if (cmd->count("--traces") > 0 && (o->sort_bits != 0u || o->compact_rays))
      throw OptionsError(std::string("--traces chooses whether the tiles' bounce trace shares its dispatch with the "
                                     "shadow trace; ") + (o->sort_bits != 0u ? "--sort-rays" : "--compact-rays") +
                         " traces the bounce rays through a list, always apart: it does nothing (leave one out)");
    o->frame_knobs.clear();
    for (const char* name : {"--gather", "--gather-lists", "--gather-bucket", "--compact-rays", "--sort-rays", "--traces", "--counter-frames", "--back-to-back"})
      if (cmd->get_option_no_throw(name) != nullptr && cmd->count(name) > 0) o->frame_knobs.push_back(name);
    // ... nor with rays of a fixed kind, which every backend, vulkan included, traces as a list
    // without the frame (an outside sweep: accepted, nothing changed)
    if (o->rays != "glossy" && o->rays != "auto") {
      for (const char* name : {"--gather", "--gather-lists", "--gather-bucket", "--compact-rays", "--sort-rays", "--traces", "--counter-frames", "--back-to-back", "--rtx"})
        if (cmd->get_option_no_throw(name) != nullptr && cmd->count(name) > 0)
          throw OptionsError(std::string(name) + " is a knob of the frame, which traces its glossy bounce rays; --rays " +
                             o->rays + " traces a fixed list of rays without it: it does nothing (leave it out, or "
                             "give --rays glossy)");
    }
    // Embree alone traces its own BVH: the grid's options did nothing there (render refuses them;
    // bench ran without a word: an outside sweep)
    const auto has = [&](const char* b) { return std::find(o->backends.begin(), o->backends.end(), b) != o->backends.end(); };
    if (!o->backends.empty() && !has("cpu") && !has("vulkan")) {
      std::string grid_given;
      for (const CLI::Option* opt : cmd->get_options()) {
        const std::string& g = opt->get_group();
        if (opt->count() > 0 && (g == "Grid" || g == "Grid (expert)") && opt->get_name() != "--threads")
          grid_given += (grid_given.empty() ? "" : ", ") + opt->get_name();
      }
      if (!grid_given.empty())
        throw OptionsError("bench --backend embree times Embree's own structure: " + grid_given +
                           " do(es) not apply (leave them out, or add --backend cpu or vulkan)");
    }
    // A fallback filed the CPU's times under "vulkan", in the table and the JSON (an outside sweep)
    if (cmd->get_option_no_throw("--fallback-cpu") != nullptr && cmd->count("--fallback-cpu") > 0)
      throw OptionsError("--fallback-cpu does not apply to bench: its figures are filed by backend; time the CPU "
                         "reference with --backend cpu");
    run_bench(*o);
  });
}

}  // namespace gridrt::app
