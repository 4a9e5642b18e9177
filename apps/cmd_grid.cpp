// gridrt stats / diff: the grid's own verbs (explain: cmd_explain.cpp).
//   stats    the grid's size, memory, occupancy and saturation
//   diff     the CPU reference against the Vulkan port: grid images and every hit, over frames
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>

#include "apps/backends.h"
#include "common/util.h"
#include "apps/commands.h"
#include "apps/slices.h"
#include "common/camera.h"
#include "common/gather.h"
#include "reference/compare.h"
#include "reference/grid.h"
#include "plan/policy.h"
#ifdef GRIDRT_HAVE_VULKAN
#  include "vulkan/frame.h"
#  include "vulkan/grid.h"
#endif
#ifdef GRIDRT_HAVE_EMBREE
#  include "common/embree/embree_tracer.h"
#endif

namespace gridrt::app {
namespace {

namespace sh = gridrt::shared;

struct GridVerbOptions {
  std::string scene;
  std::string backend = "cpu";
  uint32_t width = 960, height = 540;
  float time = 0.0f;
  BackendOptions backend_options;
};

void add_common(CLI::App* cmd, GridVerbOptions& o) {
  cmd->add_option("scene", o.scene, "A scene file, a mesh, a .gridscene or builtin:NAME; default: the embedded atrium");
  cmd->add_option("--width", o.width, "Image width of the gather buffer")->check(CLI::Range(1u, 16384u));
  cmd->add_option("--height", o.height, "Image height of the gather buffer")->check(CLI::Range(1u, 16384u));
  cmd->add_option("--time,-t", o.time, "Scene time in seconds");
  add_backend_options(cmd, o.backend_options);
}

// The gather buffer every grid verb traces its bounce from: primary rays through the exact
// traversal of the reference grid (the paper rasterizes it; the exact DDA finds the same first
// surface as rasterization up to ties).
GatherBuffer reference_gather(const Scene& scene, const reference::GridOptions& grid, uint32_t w, uint32_t h,
                              float time, std::optional<size_t> only_pixel = std::nullopt) {
  reference::GridOptions exact = grid;
  exact.traversal = reference::Traversal::exact;
  reference::ReferenceGridTracer tracer(exact);
  tracer.build(scene, time);
  if (only_pixel) {
    OneRayTracer one(tracer, *only_pixel);
    return make_gather(scene, one, scene.frame_camera(), w, h, time);
  }
  Progress progress("gather buffer", size_t(w) * h);
  ProgressTracer traced(tracer, progress);
  return make_gather(scene, traced, scene.frame_camera(), w, h, time);
}

// ---- stats ------------------------------------------------------------------------------------

struct StatsOptions : GridVerbOptions {
  bool candidates = false;  // print the candidates choose_grid weighed
  bool measure = false;     // ... and trace the frame's rays through each of them
  uint32_t repeat = 3;
  std::string slices;       // a folder for the occupancy contact sheet
  std::string slice_axis = "z";
  std::vector<uint32_t> ray_pixel;  // --slices: the camera ray of this pixel drawn in
};

// The candidates choose_grid weighed, with the trace-cost policy's estimates; with `measure`, each
// candidate built (its cell size and capacity as overrides) and the frame's glossy bounce rays of a
// --width x --height gather buffer (camera rays without glossy materials) traced through it: the
// hit records' cells and tests per ray beside the estimates, and the trace time (median).
void print_candidates(const StatsOptions& o, const Scene& scene, const reference::GridOptions& go) {
  reference::GridChoice choice;
  auto t0 = std::chrono::steady_clock::now();
  const sh::GridParams chosen = reference::choose_grid(scene, o.time, go, &choice);
  const double choose_ms = ms_since(t0);
  if (!choice.sample.rays.empty())
    std::printf("\ntrace-cost sample: %zu %s rays\n", choice.sample.rays.size(),
                choice.sample.bounce ? "glossy bounce" : "camera");
  std::printf("\nchoose_grid: %.0f ms, %zu candidates (image limit %u, policy %s)\n", choose_ms,
              choice.candidates.size(), go.max_image_dimension,
              go.capacity_policy == reference::GridOptions::CapacityPolicy::trace_cost      ? "trace-cost"
              : go.capacity_policy == reference::GridOptions::CapacityPolicy::no_saturation ? "no-saturation"
                                                                                            : "percentile");
  std::vector<Ray> rays;
  std::vector<Hit> want;  // Embree's hits, where this build has it
  if (o.measure) {
    const GatherBuffer gather = reference_gather(scene, go, o.width, o.height, o.time);
    for (const Ray& r : bounce_rays(scene, gather, 0))
      if (!is_unused(r)) rays.push_back(r);
    if (rays.empty())
      for (uint32_t y = 0; y < o.height; ++y)
        for (uint32_t x = 0; x < o.width; ++x) rays.push_back(camera_ray(scene.frame_camera(), o.width, o.height, x, y));
#ifdef GRIDRT_HAVE_EMBREE
    EmbreeTracer embree(reference::thread_count(go));
    embree.build(scene, o.time);
    want.resize(rays.size());
    embree.trace(rays, want);
#endif
    std::printf("measured on %zu rays of a %ux%u gather buffer, %u thread(s), trace median of %u\n", rays.size(),
                o.width, o.height, reference::thread_count(go), o.repeat);
  }
  std::printf("| | cells | cell size | AABB padding | capacity | largest count | saturated cells | dropped refs | MiB | est. cells/ray "
              "| est. tests/ray | est. at risk %% | est. skipped %% | est. lost %% | est. cost |%s\n",
              o.measure ? " cells/ray | tests/ray | gap-fill % | agree % | trace ms |" : "");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|%s\n", o.measure ? "---|---|---|---|---|" : "");
  for (size_t i = 0; i < choice.candidates.size(); ++i) {
    const reference::GridCandidate& c = choice.candidates[i];
    std::printf("| %s | %ux%ux%u | %g | %g | %u | %u | %llu | %llu | %.1f | %.1f | %.1f | %.2f | %.3f | %.3f | %.0f |",
                i == choice.chosen ? "**chosen**" : "", c.cells.x, c.cells.y, c.cells.z, double(c.cell_size),
                double(c.aabb_padding),
                c.capacity, c.max_count, (unsigned long long)c.saturated_cells, (unsigned long long)c.dropped,
                double(c.texels) * 4.0 / 1048576.0, c.work.cells, c.work.tests, 100.0 * c.work.at_risk, 100.0 * c.work.skipped, 100.0 * c.work.lost, c.cost);
    if (o.measure) {
      reference::GridOptions gc = go;
      gc.cell_size = c.cell_size;
      gc.capacity = c.capacity;
      gc.aabb_padding = c.aabb_padding;
      reference::ReferenceGridTracer t(gc);
      t.build(scene, o.time);
      std::vector<Hit> hits(rays.size());
      std::vector<double> ms;
      for (uint32_t k = 0; k < std::max(1u, o.repeat); ++k) {
        t0 = std::chrono::steady_clock::now();
        t.trace(rays, hits);
        ms.push_back(ms_since(t0));
      }
      std::sort(ms.begin(), ms.end());
      const reference::WorkEstimate m = reference::measured_work(rays, hits);
      double agree = 0.0;
      if (!want.empty()) {
        size_t same = 0;
        for (size_t r = 0; r < rays.size(); ++r)
          same += (is_miss(hits[r]) && is_miss(want[r])) ||
                  (!is_miss(hits[r]) && !is_miss(want[r]) && !(hits[r].flags & sh::kHitGapFill) &&
                   hits[r].instance == want[r].instance && hits[r].triangle == want[r].triangle);
        agree = 100.0 * double(same) / double(rays.size());
      }
      std::printf(" %.1f | %.1f | %.3f | %s | %.2f |", m.cells, m.tests, 100.0 * m.lost,
                  want.empty() ? "-" : std::to_string(agree).substr(0, 6).c_str(), ms[ms.size() / 2]);
    }
    std::printf("\n");
    std::fflush(stdout);
  }
  (void)chosen;
}

void run_stats(const StatsOptions& o) {
  const Scene scene = load_scene_or_default(o.scene);
  const reference::GridOptions go = grid_options_for(o.backend_options, scene);
  reference::ReferenceGridTracer ref(go);
  ref.build(scene, o.time);
  std::printf("scene %s: %llu triangles in %zu instances (%u static)\n%s", scene.name.c_str(),
              (unsigned long long)scene.triangle_count(), scene.instances.size(), scene.static_instance_count(),
              reference::to_text(ref.stats()).c_str());
  if (!o.slices.empty()) {
    std::optional<reference::ExplainRecord> ray;
    std::string ray_name;
    if (!o.ray_pixel.empty()) {
      const uint32_t x = o.ray_pixel[0], y = o.ray_pixel[1];
      if (x >= o.width || y >= o.height)
        throw Error("--ray-pixel " + std::to_string(x) + "," + std::to_string(y) + " lies outside the " +
                    std::to_string(o.width) + "x" + std::to_string(o.height) + " image");
      ray = ref.explain_ray(camera_ray(scene.frame_camera(), o.width, o.height, x, y));
      ray_name = "camera ray of pixel " + std::to_string(x) + "," + std::to_string(y) + " of " +
                 std::to_string(o.width) + "x" + std::to_string(o.height);
    }
    write_slices(ref, scene.name, o.slices, o.slice_axis[0], ray ? &*ray : nullptr, ray_name);
  }
  if (o.candidates || o.measure) print_candidates(o, scene, go);
}

// ---- diff -------------------------------------------------------------------------------------

#ifdef GRIDRT_HAVE_VULKAN
struct DiffOptions : GridVerbOptions {
  uint32_t frames = 3;
  float fps = 30.0f;
  uint32_t ulps_t = 0;   // float fields of otherwise equal hits may differ by this many ulps in t
  float abs_uv = 0.0f;   // ... and by this much in u and v (absolute)
  bool gpu_frame = false;  // also the GPU frame's own passes: raster gather, bounce rays, trace
};

// What the GPU frame's passes (vulkan/frame.h) make of one frame, against the reference: the
// gather's launch triangles against the reference's primary rays (reported, not a failure: the
// raster gather differs where the rasterizer's tie rules decide, the compute gather tests the
// triangles themselves where the reference walks its grid); the bounce rays the GPU makes from
// its own gather against bounce_rays() of that same gather (bits); the frame's trace of those rays
// against the reference's trace of the same rays (bits). Returns the records that differ.
struct FrameDiff {
  size_t pixels = 0, same_launch = 0, rays_used = 0, ray_mismatch = 0, hit_mismatch = 0;
};
FrameDiff diff_gpu_frame(const Scene& scene, const reference::GridOptions& grid, reference::ReferenceGridTracer& ref,
                         vulkan::VulkanFrame& frame, uint32_t frame_number, float time) {
  FrameDiff r;
  frame.render(frame_number);
  const uint32_t w = frame.options().width, h = frame.options().height;
  GatherBuffer gpu = frame.download_gather();
  gpu.time = time;
  const GatherBuffer cpu = reference_gather(scene, grid, w, h, time);
  r.pixels = cpu.size();
  for (size_t p = 0; p < cpu.size(); ++p) r.same_launch += cpu.launch_ref[p] == gpu.launch_ref[p];
  const std::vector<Ray> want_rays = bounce_rays(scene, gpu, frame_number);
  if (!frame.bounce()) return r;  // no glossy material: the bounce is specialized away
  const std::vector<Ray> got_rays = frame.download_rays();
  for (size_t p = 0; p < want_rays.size(); ++p) {
    const Ray& a = want_rays[p];
    const Ray& b = got_rays[p];
    r.rays_used += !is_unused(a);
    if (std::memcmp(&a, &b, sizeof a) != 0 && ++r.ray_mismatch == 1)
      std::printf("  first bounce ray that differs: pixel %zu: reference %s\n  vulkan    %s\n", p,
                  reference::hex_ray(a).c_str(), reference::hex_ray(b).c_str());
  }
  std::vector<Hit> want(want_rays.size());
  ref.trace(want_rays, want);
  const std::vector<Hit> got = frame.download_hits();
  const reference::HitDiff d = reference::compare_hits(want, got);
  r.hit_mismatch = d.rays - d.identical;
  if (!d.differing.empty()) {
    const size_t i = d.differing.front();
    std::printf("  first frame hit that differs: pixel %zu: %s\n  reference %s\n  vulkan    %s\n", i,
                reference::hex_ray(want_rays[i]).c_str(), reference::hex_hit(want[i]).c_str(),
                reference::hex_hit(got[i]).c_str());
  }
  return r;
}

// Grid images: sorted texel for texel; first-empty per cell as multisets. Returns false on a
// difference, after printing the first one.
bool diff_images(const reference::ReferenceGridTracer& ref, vulkan::VulkanGridTracer& gpu, uint32_t frame) {
  const AccelDump want = ref.dump(), got = gpu.dump();
  const reference::SpillDump spill = gpu.spill();
  const sh::GridParams& g = ref.params();
  if (ref.options().insertion == reference::Insertion::sorted) {
    const reference::TexelDiff d = reference::compare_texels(want, got);
    std::printf("frame %u: grid image %ux%ux%u: %zu of %zu texels differ\n", frame, want.extent.x, want.extent.y,
                want.extent.z, d.differing.size(), d.texels);
    if (d.differing.empty()) return true;
    const size_t i = d.differing.front();
    const uint32_t tx = uint32_t(i % want.extent.x), ty = uint32_t((i / want.extent.x) % want.extent.y),
                   tz = uint32_t(i / (size_t(want.extent.x) * want.extent.y));
    std::printf("  first: texel (%u, %u, %u) = cell (%u, %u, %u) %s %u: reference 0x%08x, vulkan 0x%08x\n", tx, ty, tz,
                tx / (g.capacity + 1), ty, tz, tx % (g.capacity + 1) == g.capacity ? "status" : "slot",
                tx % (g.capacity + 1), want.texels[i], got.texels[i]);
    return false;
  }
  const reference::CellCheck c = reference::check_cells_as_multisets(
      ref.data(), got, (ref.params().flags & sh::kGridSpill) ? &spill : nullptr);
  std::printf("frame %u: first-empty grid: %zu of %zu cells break the multiset rule (%zu saturated)\n", frame,
              c.bad.size(), c.cells, c.saturated);
  if (c.bad.empty()) return true;
  const size_t i = c.bad.front();
  std::printf("  first: cell (%zu, %zu, %zu)\n", i % g.cells.x, (i / g.cells.x) % g.cells.y,
              i / (size_t(g.cells.x) * g.cells.y));
  return false;
}

// The spill lists: the headers equal (the counter counts every dropped reference, with spill off
// too); with spill on, sorted insertion, the entries equal as multisets of (cell, ref) (the order
// of appends differs by design; first-empty spills another choice, checked per cell above).
bool diff_spill(const reference::ReferenceGridTracer& ref, vulkan::VulkanGridTracer& gpu, uint32_t frame) {
  const reference::SpillDump want = ref.spill(), got = gpu.spill();
  const bool sorted = ref.options().insertion == reference::Insertion::sorted;
  const bool on = (ref.params().flags & sh::kGridSpill) != 0u;
  const reference::SpillDiff d = reference::compare_spill(want, got);
  const bool same_counts = want.header.count == got.header.count && want.header.static_count == got.header.static_count &&
                           want.header.capacity == got.header.capacity;
  const bool ok = same_counts && (!on || !sorted || d.same());
  std::printf("frame %u: spill list %s: %u references found no slot (%u static); reference %u, vulkan %u; %u stored of "
              "%u%s%s\n",
              frame, on ? "on" : "off (counted only)", want.header.count, want.header.static_count, want.header.count,
              got.header.count, want.stored(), want.header.capacity,
              on && sorted ? (d.same() ? ", entries equal as multisets of (cell, ref)"
                                       : (", entries differ: " + std::to_string(d.only_want.size()) + " only in the reference, " +
                                          std::to_string(d.only_got.size()) + " only in vulkan")
                                             .c_str())
                           : "",
              want.overflow() ? " (OVERFLOW: references lost)" : "");
  return ok;
}

void run_diff(const DiffOptions& options) {
  DiffOptions o = options;
  resolve_image_limit(o.backend_options, true);
  const Scene scene = load_scene_or_default(o.scene);
  const reference::GridOptions grid = grid_options_for(o.backend_options, scene);
  vulkan::VulkanGridOptions vk;
  vk.build = o.backend_options.vk_build == "compute" ? vulkan::BuildMode::compute : vulkan::BuildMode::raster;
  vulkan::VulkanGridTracer gpu(grid, vk);
  reference::ReferenceGridTracer ref(grid);
  std::printf("diff: %s, %ux%u, %u frame(s), traversal %s, insertion %s, spill %s, Vulkan device %s (%s build)\n",
              scene.name.c_str(), o.width, o.height, o.frames,
              grid.traversal == reference::Traversal::paper ? "paper" : "exact",
              grid.insertion == reference::Insertion::sorted ? "sorted" : "first-empty",
              reference::spill_enabled(grid) ? "on" : "off",
              gpu.context().info().name.c_str(), o.backend_options.vk_build.c_str());
  bool all_same = true;
  size_t total_rays = 0, total_identical = 0, total_discrete = 0, total_beyond = 0;
  size_t frame_mismatch = 0;
  std::unique_ptr<vulkan::VulkanFrame> gpu_frame;
  bool first_discrete = false;
  struct FloatDiff {
    uint32_t frame = 0;
    size_t index = 0;
    Ray ray{};
    Hit want{}, got{};
  } first_beyond;
  for (uint32_t frame = 0; frame < o.frames; ++frame) {
    const float time = o.time + float(frame) / o.fps;
    if (frame == 0) {
      ref.build(scene, time);
      gpu.build(scene, time);
    } else {
      ref.update(time);
      gpu.update(time);
    }
    all_same = diff_images(ref, gpu, frame) && all_same;
    all_same = diff_spill(ref, gpu, frame) && all_same;

    if (o.gpu_frame) {
      if (!gpu_frame)
        gpu_frame = std::make_unique<vulkan::VulkanFrame>(gpu, scene, vulkan::FrameOptions{.width = o.width, .height = o.height});
      const FrameDiff f = diff_gpu_frame(scene, grid, ref, *gpu_frame, frame, time);
      const bool raster = gpu_frame->gather_mode() == vulkan::GatherMode::raster;
      std::printf("frame %u: GPU frame: %s gather %zu of %zu pixels with the reference's launch triangle%s; %zu bounce "
                  "rays: %zu differ in bits from bounce_rays() of the GPU's gather, %zu frame hits differ in bits from "
                  "the reference's trace\n",
                  frame, raster ? "raster" : "compute", f.same_launch, f.pixels,
                  raster ? " (the rest: the rasterizer's tie rules)" : "", f.rays_used, f.ray_mismatch, f.hit_mismatch);
      frame_mismatch += f.ray_mismatch + f.hit_mismatch;
    }

    // Every hit: the primary rays and the glossy bounce off the reference's gather buffer.
    const GatherBuffer gather = reference_gather(scene, grid, o.width, o.height, time);
    std::vector<Ray> rays = bounce_rays(scene, gather, frame);
    for (uint32_t y = 0; y < o.height; ++y)
      for (uint32_t x = 0; x < o.width; ++x) rays.push_back(camera_ray(scene.frame_camera(), o.width, o.height, x, y));
    std::vector<Hit> want(rays.size()), got(rays.size());
    {
      Progress progress("frame " + std::to_string(frame) + ": reference trace", rays.size());
      ProgressTracer traced(ref, progress);
      traced.trace(rays, want);
    }
    gpu.trace(rays, got);
    const reference::HitDiff d = reference::compare_hits(want, got);
    total_rays += d.rays;
    total_identical += d.identical;
    total_discrete += d.discrete.size();
    // Float-only differences: within the stated bounds or not.
    size_t beyond = 0;
    float max_duv = 0.0f;
    for (size_t i : d.differing) {
      const Hit& a = want[i];
      const Hit& b = got[i];
      if (a.instance != b.instance || a.triangle != b.triangle || a.flags != b.flags || a.cells != b.cells ||
          a.tests != b.tests)
        continue;
      const float duv = std::max(std::abs(a.u - b.u), std::abs(a.v - b.v));
      max_duv = std::max(max_duv, duv);
      if (reference::ulp_distance(a.t, b.t) > o.ulps_t || duv > o.abs_uv) {
        if (beyond == 0) first_beyond = {frame, i, rays[i], a, b};
        ++beyond;
      }
    }
    total_beyond += beyond;
    std::printf("frame %u: %zu rays: %zu identical in bits; %zu differ only in floats (t within %u ulps, u/v within "
                "%.3g), %zu of them beyond the bounds (%u ulps in t, %.3g in u/v); %zu differ in the hit itself "
                "(instance, triangle, flags, cells or tests)\n",
                frame, d.rays, d.identical, d.same_discrete - d.identical, d.max_ulps_t, double(max_duv), beyond,
                o.ulps_t, double(o.abs_uv), d.discrete.size());
    if (!d.discrete.empty() && !first_discrete) {
      const size_t i = d.discrete.front();
      first_discrete = true;
      std::printf("\nfirst ray whose hit differs: ray %zu: %s\n  reference %s\n  vulkan    %s\n\n", i,
                  reference::hex_ray(rays[i]).c_str(), reference::hex_hit(want[i]).c_str(),
                  reference::hex_hit(got[i]).c_str());
      const reference::ExplainRecord a = ref.explain_ray(rays[i]);
      const reference::ExplainRecord b = gpu.explain_ray(rays[i]);
      std::printf("== reference's account ==\n%s\n== shader's account ==\n%s\n", reference::to_text(a).c_str(),
                  reference::to_text(b).c_str());
    }
  }
  if (total_beyond)
    std::printf("first ray beyond the float bounds: frame %u ray %zu: %s\n  reference %s\n  vulkan    %s\n",
                first_beyond.frame, first_beyond.index, reference::hex_ray(first_beyond.ray).c_str(),
                reference::hex_hit(first_beyond.want).c_str(), reference::hex_hit(first_beyond.got).c_str());
  all_same = all_same && total_discrete == 0 && total_beyond == 0 && frame_mismatch == 0;
  std::printf("%s: %zu of %zu hit records identical in bits, %zu with another hit, %zu beyond the float bounds, "
              "over the frames compared\n",
              all_same ? "AGREE" : "DIFFER", total_identical, total_rays, total_discrete, total_beyond);
  if (!all_same) throw Error("the Vulkan port differs from the reference (see above)");
}
#endif

}  // namespace

void add_grid_commands(CLI::App& app) {
  {
    auto o = std::make_shared<StatsOptions>();
    o->width = 192;
    o->height = 108;
    CLI::App* cmd = app.add_subcommand("stats", "The grid's size, memory, occupancy histogram and saturated cells");
    add_common(cmd, *o);
    cmd->add_flag("--candidates", o->candidates,
                  "Also list the candidate grids choose_grid weighed, with the trace-cost policy's estimates");
    cmd->add_flag("--measure", o->measure,
                  "Also build every candidate and trace the frame's bounce rays (--width x --height gather buffer) "
                  "through it: measured cells and tests per ray and trace time beside the estimates");
    cmd->add_option("--repeat", o->repeat, "--measure: trace this many times (median)")->check(CLI::Range(1u, 100u));
    cmd->add_option("--slices", o->slices,
                    "Also draw the grid slice by slice into this folder (occupancy.png: references per cell, "
                    "saturated cells, with a legend)");
    cmd->add_option("--slice-axis", o->slice_axis, "--slices: the axis the slices are cut along")
        ->check(CLI::IsMember({"x", "y", "z"}).description(""))->type_name("x|y|z");
    cmd->add_option("--ray-pixel", o->ray_pixel,
                    "--slices: also draw the camera ray of pixel X,Y (of --width x --height): the cells its traversal "
                    "visits and its samples")
        ->delimiter(',')->expected(2)->type_name("X,Y");
    cmd->callback([o] { run_stats(*o); });
  }
#ifdef GRIDRT_HAVE_VULKAN
  {
    auto o = std::make_shared<DiffOptions>();
    o->width = 160;
    o->height = 90;
    CLI::App* cmd = app.add_subcommand(
        "diff", "Run the CPU reference and the Vulkan port on a scene: grid images and every hit, over frames");
    add_common(cmd, *o);
    cmd->add_option("--frames", o->frames, "Animated frames to compare (the first is a build, then updates)")
        ->check(CLI::Range(1u, 10000u));
    cmd->add_option("--fps", o->fps, "Frames per second")->check(CLI::PositiveNumber);
    cmd->add_option("--ulps", o->ulps_t,
                    "Allow t of otherwise identical hits to differ by this many ulps (drivers whose division is "
                    "not correctly rounded; default 0: bit for bit)");
    cmd->add_option("--uv-tolerance", o->abs_uv, "Allow u and v of otherwise identical hits to differ by this much");
    cmd->add_flag("--gpu-frame", o->gpu_frame,
                  "Also run the GPU frame's own passes (raster gather, bounce, trace) and compare its bounce rays "
                  "and hits, bit for bit, with the reference's from the same gather");
    cmd->callback([o] { run_diff(*o); });
  }
#endif
}

}  // namespace gridrt::app
