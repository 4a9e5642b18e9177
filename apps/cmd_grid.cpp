// gridrt stats: the grid's own verbs (explain: cmd_explain.cpp; diff: cmd_diff.cpp).
//   stats    the grid's size, memory, occupancy and saturation
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>

#include "apps/backends.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/util.h"
#include "apps/commands.h"
#include "apps/slices.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/reference/compare.h"
#include "gridrt/reference/grid.h"
#include "gridrt/plan/policy.h"
#ifdef GRIDRT_HAVE_VULKAN
#  include "gridrt/vulkan/frame.h"
#  include "gridrt/vulkan/grid.h"
#endif
#ifdef GRIDRT_HAVE_EMBREE
#  include "gridrt/common/embree/embree_tracer.h"
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
  add_scene_argument(cmd, o.scene);
  add_image_size(cmd, o.width, o.height, "of the gather buffer that --measure and --pixel trace (only with one of them)");
  cmd->add_option("--time,-t", o.time, "Scene time in seconds")->check(CLI::Range(-1.0e6f, 1.0e6f));
  add_backend_options(cmd, o.backend_options, /*vulkan=*/false);  // the CPU reference's grid only
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
  std::printf("\nchoose_grid: %.0f ms, %zu candidates (image limit %u, work bound %llu AABB range cells: %u finer "
              "grids over it left out, policy %s)\n",
              choose_ms, choice.candidates.size(), go.max_image_dimension,
              (unsigned long long)plan::range_cells_budget(scene.triangle_count()), choice.over_bound,
              go.capacity_policy == reference::GridOptions::CapacityPolicy::trace_cost      ? "trace-cost"
              : go.capacity_policy == reference::GridOptions::CapacityPolicy::no_saturation ? "no-saturation"
                                                                                            : "percentile");
  std::vector<Ray> rays;
  std::vector<Hit> want;  // Embree's hits, where this build has it
  bool bounce = false;    // the rays are glossy bounce rays (else camera rays)
  if (o.measure) {
    const GatherBuffer gather = reference_gather(scene, go, o.width, o.height, o.time);
    for (const Ray& r : bounce_rays(scene, gather, 0))
      if (!is_unused(r)) rays.push_back(r);
    bounce = !rays.empty();
    if (rays.empty()) rays = camera_rays(scene.frame_camera(), o.width, o.height);
#ifdef GRIDRT_HAVE_EMBREE
    EmbreeTracer embree(reference::thread_count(go));
    embree.build(scene, o.time);
    want.resize(rays.size());
    embree.trace(rays, want);
#endif
    std::printf("measured on %zu %s of a %ux%u gather buffer, %u thread(s), trace median of %u\n", rays.size(),
                bounce ? "glossy bounce rays" : "camera rays (the scene has no glossy material: the kind the "
                                                "trace-cost policy samples)",
                o.width, o.height, reference::thread_count(go), o.repeat);
  }
  // The candidates' figures are choose_grid's, not the built grid's above: the counts the worst
  // over the animation's samples, the memory the layout's storage
  std::printf("candidates' columns: largest count, saturated cells and dropped refs are the worst over the scene's "
              "animation samples (the grid above is counted at --time alone); MiB is the compact layout's whole grid, "
              "the image layout's image\n");
  std::printf("| | cells | cell size | AABB padding | capacity | largest count | saturated cells (worst sample) | dropped refs (worst sample) | MiB | range cells/tri | est. cells/ray "
              "| est. tests/ray | est. at risk %% | est. skipped %% | est. lost %% | est. cost |%s\n",
              o.measure ? " cells/ray | tests/ray | gap-fill % | agree % | trace ms |" : "");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|%s\n", o.measure ? "---|---|---|---|---|" : "");
  for (size_t i = 0; i < choice.candidates.size(); ++i) {
    const reference::GridCandidate& c = choice.candidates[i];
    std::printf("| %s | %ux%ux%u | %g | %g | %u | %u | %llu | %llu | %.1f | %.1f | %.1f | %.1f | %.2f | %.3f | %.3f | %.0f |",
                i == choice.chosen ? "**chosen**" : "", c.cells.x, c.cells.y, c.cells.z, double(c.cell_size),
                double(c.aabb_padding),
                c.capacity, c.max_count, (unsigned long long)c.saturated_cells, (unsigned long long)c.dropped,
                double(c.memory ? c.memory : c.texels * 4) / 1048576.0,
                double(c.range_cells) / double(std::max<uint64_t>(scene.triangle_count(), 1)), c.work.cells, c.work.tests, 100.0 * c.work.at_risk, 100.0 * c.work.skipped, 100.0 * c.work.lost, c.cost);
    if (o.measure) {
      // The candidate as choose_grid would build it: the compact layout (its offsets, no fixed
      // capacity: a capacity asked for means the image layout), or the image with its capacity
      reference::GridOptions gc = go;
      gc.cell_size = c.cell_size;
      gc.resolution.reset();  // the candidate's size, whatever sized the grid
      gc.aabb_padding = c.aabb_padding;
      if ((chosen.flags & sh::kGridCompact) != 0u) {
        gc.layout = reference::GridOptions::Layout::compact;
        gc.offsets = c.sparse_offsets ? reference::GridOptions::Offsets::sparse : reference::GridOptions::Offsets::dense;
      } else {
        gc.capacity = c.capacity;
      }
      reference::ReferenceGridTracer t(gc);
      try {
        t.build(scene, o.time);
      } catch (const Error& e) {
        // A candidate that cannot be built (over the budget, the limits) is said so in its row
        std::printf(" not built: %s | | | | |\n", e.what());
        continue;
      }
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
  // --pixel draws a ray into --slices' pictures: alone it did nothing, without a word
  if (!o.ray_pixel.empty() && o.slices.empty())
    throw OptionsError("--pixel draws its camera ray into --slices' pictures: give --slices FOLDER too");
  // The folder checked before the build and the report, as every output (it was checked after)
  if (!o.slices.empty()) check_slices_folder(o.slices);
  // Only where a gather buffer is made (--measure, --pixel): plain stats made none, yet a low
  // --max-pixels refused them, and the options that size it are refused without those (an
  // outside sweep)
  if (o.measure || !o.ray_pixel.empty()) check_frame_size(o.width, o.height);
  // The pixel checked before the build (it was, after the whole report: an outside sweep)
  if (!o.ray_pixel.empty() && (o.ray_pixel[0] >= o.width || o.ray_pixel[1] >= o.height))
    throw OptionsError("--pixel " + std::to_string(o.ray_pixel[0]) + "," + std::to_string(o.ray_pixel[1]) +
                       " lies outside the " + std::to_string(o.width) + "x" + std::to_string(o.height) + " image");
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
      ray = ref.explain_ray(camera_ray(scene.frame_camera(), o.width, o.height, x, y));
      ray_name = "camera ray of pixel " + std::to_string(x) + "," + std::to_string(y) + " of " +
                 std::to_string(o.width) + "x" + std::to_string(o.height);
    }
    write_slices(ref, scene.name, o.slices, o.slice_axis[0], ray ? &*ray : nullptr, ray_name);
  }
  if (o.candidates || o.measure) print_candidates(o, scene, go);
}

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
                  "Also build every candidate and trace the frame's glossy bounce rays (--width x --height gather "
                  "buffer; camera rays on a scene without glossy materials, as the trace-cost policy samples) "
                  "through it: measured cells and tests per ray and trace time beside the estimates");
    auto* repeat_opt =
        cmd->add_option("--repeat", o->repeat, "--measure: trace this many times (median)")->check(CLI::Range(1u, 100u));
    cmd->add_option("--slices", o->slices,
                    "Also draw the grid slice by slice into this folder (occupancy.png: references per cell, "
                    "saturated cells, with a legend)");
    auto* axis_opt =
        add_choice(cmd, "--slice-axis", o->slice_axis, {"x", "y", "z"}, "--slices: the axis the slices are cut along");
    cmd->add_option("--pixel,-p,--ray-pixel", o->ray_pixel,
                    "--slices: also draw the camera ray of pixel X,Y (of --width x --height): the cells its traversal "
                    "visits and its samples")
        ->delimiter(',')->expected(2)->type_name("X,Y");
    cmd->callback([o, cmd, repeat_opt, axis_opt] {
      check_traversal_options(cmd, o->backend_options, /*trace_grid_only=*/true);
      // Each did nothing without its verb's option, without a word (an outside sweep)
      if (repeat_opt->count() > 0 && !o->measure)
        throw OptionsError("--repeat times --measure's traces: give --measure, or leave --repeat out");
      if (axis_opt->count() > 0 && o->slices.empty())
        throw OptionsError("--slice-axis cuts --slices' pictures: give --slices FOLDER too");
      // The gather buffer's size is read by --measure and --pixel alone (the trace-cost policy's
      // sample is --work-sample's)
      for (const char* name : {"--width", "--height"})
        if (cmd->count(name) > 0 && !o->measure && o->ray_pixel.empty())
          throw OptionsError(std::string(name) + " sizes the gather buffer of --measure and --pixel: give one of "
                             "them, or leave it out (the policy's sample is --work-sample's)");
      run_stats(*o);
    });
  }
}

}  // namespace gridrt::app
