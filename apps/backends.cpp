#include "apps/backends.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <map>

#include "gridrt/common/scene.h"
#include "gridrt/plan/plan.h"
#ifdef GRIDRT_HAVE_EMBREE
#  include "gridrt/common/embree/embree_tracer.h"
#endif
#ifdef GRIDRT_HAVE_VULKAN
#  include "gridrt/vulkan/grid.h"
#endif

namespace gridrt::app {

namespace {

// An option taking one of a few names, mapped to an enum: the help shows "a|b|c" and the text, not
// CLI11's internals.
template <class E>
CLI::Option* add_enum(CLI::App* cmd, const std::string& name, E& value, const std::vector<std::pair<std::string, E>>& names,
                      const std::string& help) {
  std::map<std::string, E> map(names.begin(), names.end());
  std::string type;
  for (const auto& [n, v] : names) type += (type.empty() ? "" : "|") + n;
  return cmd->add_option(name, value, help)
      ->transform(CLI::CheckedTransformer(map, CLI::ignore_case).description(""))
      ->type_name(type);
}

constexpr const char* kGrid = "Grid";
constexpr const char* kExpert = "Grid (expert)";
using plan::kMaxWorkSamplePixels;

std::string choice_type(const std::vector<std::string>& names) {
  std::string type;
  for (const std::string& n : names) type += (type.empty() ? "" : "|") + n;
  return type;
}

}  // namespace

CLI::Option* add_choice(CLI::App* cmd, const std::string& name, std::string& value, const std::vector<std::string>& names,
                        const std::string& help) {
  return cmd->add_option(name, value, help)->check(CLI::IsMember(names).description(""))->type_name(choice_type(names));
}

CLI::Option* add_json_option(CLI::App* cmd, std::string& path, const std::string& what) {
  return cmd->add_option("--json", path, "Also write " + what + " as JSON to this file")->type_name("FILE");
}

void add_image_size(CLI::App* cmd, uint32_t& width, uint32_t& height, const std::string& whose) {
  const std::string of = whose.empty() ? "" : " " + whose;
  cmd->add_option("--width", width, "Image width" + of)->check(CLI::Range(1u, 16384u));
  cmd->add_option("--height", height, "Image height" + of)->check(CLI::Range(1u, 16384u));
}

std::optional<reference::GridOptions::CapacityPolicy> capacity_policy_named(const std::string& name) {
  using P = reference::GridOptions::CapacityPolicy;
  if (name == "auto" || name == "trace-cost") return P::trace_cost;
  if (name == "no-saturation") return P::no_saturation;
  if (name == "percentile") return P::percentile;
  return std::nullopt;
}

CLI::Option* add_scene_argument(CLI::App* cmd, std::string& scene) {
  return cmd->add_option("scene", scene,
                         "A scene file (.json), a mesh (.obj, .gltf, .glb), a cache (.gridscene) or builtin:NAME "
                         "(atrium, cornell, teapot); default: the embedded atrium");
}

namespace {

// The grid's common options (the "Grid" group of --help).
void add_grid_options(CLI::App* cmd, BackendOptions& o) {
  reference::GridOptions& g = o.grid;
  using GO = reference::GridOptions;
  add_enum(cmd, "--traversal", g.traversal, {{"paper", reference::Traversal::paper}, {"exact", reference::Traversal::exact}},
           "Grid traversal: paper (fixed cell-edge segments) or exact (3D DDA)")
      ->group(kGrid);
  cmd->add_option_function<std::string>(
         "--capacity",
         [&g](const std::string& v) {
           if (const auto policy = capacity_policy_named(v)) {
             g.capacity_policy = *policy;
             g.capacity_policy_given = true;
             g.capacity.reset();
             return;
           }
           size_t used = 0;
           unsigned long n = 0;
           try {
             n = std::stoul(v, &used);
           } catch (const std::exception&) {
             used = 0;
           }
           if (used != v.size() || n < 1 || n > 1024)
             throw CLI::ValidationError("--capacity", "'" + v + "' is neither a number of slots in [1, 1024] nor "
                                                      "auto, trace-cost, no-saturation or percentile");
           g.capacity = uint32_t(n);
         },
         "Slots per cell: a number, or the rule that chooses the resolution and capacity: trace-cost (auto, the "
         "default: the candidate whose estimated trace work on a sample of the frame's rays is lowest), "
         "no-saturation (the resolution near the density target whose largest cell fits) or percentile (the 0.99 "
         "percentile of cell counts, clamped to --max-capacity, default 1024; the original rule clamps it to 64, "
         "as sweep does: give --max-capacity 64)")
      ->type_name("N|auto|trace-cost|no-saturation|percentile")->group(kGrid);
  cmd->add_option("--resolution", o.resolution, "Cells per axis X,Y,Z (default: chosen from the scene)")
      ->delimiter(',')->expected(3)->check(CLI::Range(1u, 16384u))->type_name("X,Y,Z")->group(kGrid);
  add_enum(cmd, "--spill", g.spill, {{"auto", GO::Spill::automatic}, {"on", GO::Spill::on}, {"off", GO::Spill::off}},
           "Spill list: references no slot takes are kept and traced in saturated cells (on), or dropped (off); "
           "auto: on for the exact traversal, off for the paper's (which gap-fills instead)")
      ->group(kGrid);
  add_enum(cmd, "--layout", g.layout,
           {{"auto", GO::Layout::automatic}, {"compact", GO::Layout::compact}, {"image", GO::Layout::image}},
           "Grid layout: compact (static references in one array ordered per cell, dynamic ones in the spill "
           "list; exact traversal), image (the paper's fixed-capacity 3D image) or auto (compact for the exact "
           "traversal, image for the paper's)")
      ->group(kGrid);
  add_enum(cmd, "--gap-fill", g.gap_fill, {{"on", true}, {"off", false}},
           "paper traversal: gap-fill in saturated cells (default on)")
      ->group(kGrid);
  add_enum(cmd, "--skip-empty", g.skip_empty, {{"on", true}, {"off", false}},
           "exact traversal: pass boxes of empty cells at once by a per-cell distance to the nearest reference "
           "(on, the default) or visit every cell (off)")
      ->group(kGrid);
  add_enum(cmd, "--skip-covered", g.skip_covered, {{"on", true}, {"off", false}},
           "exact traversal, compact layout, with --skip-empty on: do not read a cell's references where every one "
           "lies in the cell the walk came from, tested there (on, the default: the hits are the same, fewer "
           "tests) or test every cell's references (off)")
      ->group(kGrid);
  add_enum(cmd, "--mailbox", g.mailbox, {{"on", true}, {"off", false}},
           "exact traversal: do not test again a reference among the last 8 tested on the ray (on: the hits are "
           "the same, fewer tests, but slower on the GPU measured) or test every reference of every cell (off, the "
           "default); the paper traversal and first-empty insertion ignore it")
      ->group(kGrid);
  add_enum(cmd, "--self-hit", g.exclude_launch_ref, {{"exclude", true}, {"keep", false}},
           "The ray's launch triangle: exclude (never accept it, the default) or keep (test it like any other)")
      ->group(kGrid);
  cmd->add_option("--threads", g.threads, "CPU threads (0: all)")->check(CLI::Range(0u, kMaxThreads))->group(kGrid);
}

// The expert knobs ("Grid (expert)").
void add_expert_options(CLI::App* cmd, BackendOptions& o) {
  reference::GridOptions& g = o.grid;
  using GO = reference::GridOptions;
  add_enum(cmd, "--insertion", g.insertion,
           {{"sorted", reference::Insertion::sorted}, {"first-empty", reference::Insertion::first_empty}},
           "Insertion: sorted (atomic-min cascade, timing-independent) or first-empty (the paper's CAS)")
      ->group(kExpert);
  add_enum(cmd, "--triangle-test", g.triangle_test,
           {{"auto", GO::TriangleTest::automatic}, {"moller", GO::TriangleTest::moller},
            {"watertight", GO::TriangleTest::watertight}},
           "Ray/triangle test: auto (watertight for the exact traversal, moller for the paper's), moller "
           "(Moller-Trumbore) or watertight (Woop, Benthin, Wald 2013)")
      ->group(kExpert);
  add_enum(cmd, "--revisit", g.repeats,
           {{"merge", GO::Repeats::merge}, {"skip", GO::Repeats::skip}, {"retest", GO::Repeats::retest}},
           "paper traversal: consecutive samples in one cell: merge (one visit over their segments, the default), "
           "skip (the literal reading of visited-cell tracking) or retest (a second visit)")
      ->group(kExpert);
  cmd->add_option("--cell-size", g.cell_size, "Cell edge in world units (at most 2^26: one cell then holds any scene)")->check(positive_number())->group(kExpert);
  cmd->add_option_function<float>(
         "--density", [&g](float d) { g.density = d, g.density_given = true; },
         "Target cells per triangle for the automatic resolution")
      ->check(CLI::Range(1.0e-3f, 1.0e3f))->group(kExpert);
  cmd->add_option("--max-image-dimension", o.max_image_dimension,
                  "Largest image side the grid may use (default: the Vulkan device's limit when the vulkan "
                  "backend runs, else 4096)")
      ->check(CLI::Range(2u, 65536u))->group(kExpert);
  cmd->add_option_function<double>(
         "--memory-budget",
         [&g](double mib) {
           g.max_texels = uint64_t(mib * 1024.0 * 1024.0 / 4.0);
           g.memory_budget = uint64_t(mib * 1024.0 * 1024.0);
         },
         "The grid's memory in MiB: the image layout's largest image (default 1024), the compact layout's whole "
         "grid (default 320 bytes per scene triangle, at least 4); it bounds each grid the verb builds, the CPU "
         "frame's gather grid (the exact traversal's, for the primary rays) too")
      ->check(CLI::Range(0.001, 1.0e6))->group(kExpert);
  add_enum(cmd, "--offsets", g.offsets,
           {{"auto", GO::Offsets::automatic}, {"dense", GO::Offsets::dense}, {"sparse", GO::Offsets::sparse}},
           "compact layout: one offset per cell (dense), offsets of the occupied cells only under an occupancy "
           "mask per 32 cells (sparse: a quarter of the bytes, one load more per occupied cell), or auto (dense "
           "where it fits the memory budget; sparse for a finer grid only where its estimate is 5 % cheaper)")
      ->group(kExpert);
  cmd->add_option_function<uint32_t>(
         "--max-capacity", [&g](uint32_t c) { g.max_capacity = c, g.max_capacity_given = true; },
         "Largest automatic capacity (at least 4, the automatic capacity's least; --capacity N fixes a "
         "number of slots, up to 1024)")
      ->check(CLI::Range(4u, 65535u))->group(kExpert);
  add_enum(cmd, "--slot-axis", g.slot_axis,
           {{"auto", GO::SlotAxis::automatic}, {"x", GO::SlotAxis::x}, {"y", GO::SlotAxis::y}, {"z", GO::SlotAxis::z}},
           "Scene axis laid along the image's x, the slots' axis (auto: the axis with the fewest cells)")
      ->group(kExpert);
  add_enum(cmd, "--cell-test", g.cell_test,
           {{"auto", GO::CellTest::automatic}, {"sphere", GO::CellTest::sphere}, {"box", GO::CellTest::box}},
           "Build: which cells of a triangle's AABB range take it: sphere (the paper's plane vs enlarged cell "
           "sphere), box (that and the separating-axis triangle/box test: fewer references) or auto (box for the "
           "exact traversal, sphere for the paper's)")
      ->group(kExpert);
  cmd->add_option("--enlargement", g.sphere_enlargement,
                  "Cell bounding-sphere radius multiplier (build; below 1 the plane test drops triangles at cells' "
                  "corners: the paper traversal's knob, refused by the exact traversal)")
      ->check(CLI::Range(0.0f, 16.0f))->group(kExpert);
  cmd->add_option("--aabb-padding", g.aabb_padding,
                  "Cell units added on each side of a triangle's AABB (build; default 0.001, and for the paper "
                  "traversal the trace-cost policy also weighs 0.25)")
      ->check(CLI::Range(0.0f, 16.0f))->group(kExpert);
  cmd->add_option("--elongation", g.elongation, "Segment elongation on each side, in segment lengths (paper trace)")
      ->check(CLI::Range(0.0f, 16.0f))->group(kExpert);
  cmd->add_option("--gap-fill-distance", g.gap_fill_distance, "Cells from the launch surface before gap-fill")
      ->check(CLI::Range(0.0f, 1e6f))->group(kExpert);
  cmd->add_option("--self-hit-offset", g.self_hit_offset, "Hits need t|dir| > this many cells")
      ->check(CLI::Range(0.0f, 1e6f))->group(kExpert);
  cmd->add_option("--spill-capacity", g.spill_capacity,
                  "Entries of the spill list (default: the references the capacity trial drops, plus a quarter "
                  "and 64); an overflow is reported")
      ->check(CLI::Range(0u, 1u << 28))->group(kExpert);
  cmd->add_option("--cell-visit-cost", g.cell_visit_cost,
                  "trace-cost policy: the cost of visiting a cell, in reference tests (default: 1.6 for the exact "
                  "traversal, fitted on the GPU; 1 for the paper's)")
      ->check(CLI::Range(0.0f, 1.0e6f))->group(kExpert);
  cmd->add_option("--saturation-cost", g.saturation_cost,
                  "trace-cost policy: the cost of a ray whose answer the grid changes, in reference tests")
      ->check(CLI::Range(0.0f, 1.0e12f))->group(kExpert);
  cmd->add_option_function<std::vector<uint32_t>>(
         "--work-sample",
         [&g](const std::vector<uint32_t>& wh) {
           // The sample is traced once per candidate resolution: its size bounds the choice's time.
           if (uint64_t(wh[0]) * wh[1] > kMaxWorkSamplePixels)
             throw CLI::ValidationError("--work-sample", std::to_string(wh[0]) + "," + std::to_string(wh[1]) +
                                                             " is more than the limit of " +
                                                             std::to_string(kMaxWorkSamplePixels) + " pixels (e.g. 256,144)");
           g.work_sample_width = wh[0];
           g.work_sample_height = wh[1];
         },
         "trace-cost policy: the gather buffer W,H whose rays sample the trace's work (default 96,54; at most "
         "36864 pixels)")
      ->delimiter(',')->expected(2)->check(CLI::Range(1u, 4096u))->type_name("W,H")->group(kExpert);
  cmd->add_flag("--all-effects", o.all_effects,
                "Simulate every effect (alpha keying, gap-fill) even where the scene does not call for it")
      ->group(kExpert);
  cmd->add_option("--shuffle-seed", g.shuffle_seed, "Run build invocations in a seeded shuffled order")
      ->check(whole_number_u64())->group(kExpert);
}

// The Vulkan backend's own ("Vulkan").
void add_vulkan_options(CLI::App* cmd, BackendOptions& o) {
  add_choice(cmd, "--vk-build", o.vk_build, {"raster", "compute"}, "Vulkan build: raster (geometry shader, the paper's) or compute")
      ->group("Vulkan");
  cmd->add_flag("--fallback-cpu", o.fallback_cpu, "Without a usable Vulkan device, use the CPU reference")
      ->group("Vulkan");
}

}  // namespace

void check_traversal_options(const CLI::App* cmd, const BackendOptions& o, bool trace_grid_only) {
  const auto given = [&](const char* name) { return cmd->get_option_no_throw(name) != nullptr && cmd->count(name) > 0; };
  // Knobs of a part that does not run (outside sweeps: each was accepted and did nothing)
  if (given("--spill-capacity") && !plan::spill_enabled(o.grid))
    throw OptionsError("--spill-capacity sizes the spill list, which is off here (the paper traversal's default, or "
                       "--spill off): it does nothing (leave it out, or give --spill on)");
  // (below 1 the sphere still cuts cells the box test keeps: the paper traversal's knob acts there)
  if (given("--enlargement") && plan::cell_box_enabled(o.grid) && o.grid.sphere_enlargement >= 1.0f)
    throw OptionsError("--enlargement of 1 or more grows the plane test's sphere past the cell, where the "
                       "separating-axis cell test (--cell-test box, the exact traversal's default) decides alone: it "
                       "does nothing (leave it out, or give --cell-test sphere)");
  // The resolution's and the policy's knobs where the command line already fixed what they choose
  // (outside sweeps: accepted, the grid the same)
  if (given("--density") && (given("--resolution") || given("--cell-size")))
    throw OptionsError("--density picks the automatic resolution, which --resolution or --cell-size fixes here: it does "
                       "nothing (leave one out)");
  // One candidate where the cells or the capacity are fixed (choose_by_candidates): nothing to weigh
  const bool fixed = given("--resolution") || given("--cell-size") || o.grid.capacity.has_value();
  for (const char* name : {"--work-sample", "--cell-visit-cost", "--saturation-cost"}) {
    if (!given(name)) continue;
    if (fixed)
      throw OptionsError(std::string(name) + " weighs the trace-cost policy's candidates; --resolution, --cell-size or "
                         "--capacity N leaves one candidate, none to weigh: it does nothing (leave it out)");
    if (o.grid.capacity_policy != reference::GridOptions::CapacityPolicy::trace_cost)
      throw OptionsError(std::string(name) + " weighs the trace-cost policy's candidates (--capacity auto or "
                         "trace-cost); --capacity no-saturation or percentile does not weigh them: it does nothing");
  }
  // The compact layout has no slots: nothing for --max-capacity to bound
  if (given("--max-capacity") && o.grid.layout == reference::GridOptions::Layout::compact)
    throw OptionsError("--max-capacity bounds the image layout's slots per cell; the compact layout (--layout compact) "
                       "has none: it does nothing (leave it out, or give --layout image)");
  // First-empty insertion fills the image layout's slots; the compact layout's build counts and
  // scatters without slots (an outside sweep: accepted, the arrays sorted all the same)
  if (o.grid.insertion == reference::Insertion::first_empty && o.grid.traversal == reference::Traversal::exact &&
      (o.grid.layout == reference::GridOptions::Layout::compact ||
       (o.grid.layout == reference::GridOptions::Layout::automatic && !o.grid.capacity && plan::compact_enabled(o.grid))))
    throw OptionsError("--insertion first-empty fills the image layout's slots; the exact traversal's grid here takes the "
                       "compact layout, which has none: it does nothing (give --layout image, or leave it out)");
  // The image's slot axis on the compact layout, which has no image (an outside sweep: accepted,
  // the grid the same)
  const bool compact_layout =
      o.grid.layout == reference::GridOptions::Layout::compact ||
      (o.grid.layout == reference::GridOptions::Layout::automatic && o.grid.traversal == reference::Traversal::exact &&
       !o.grid.capacity && plan::compact_enabled(o.grid));
  // (The percentile policy sizes its capacity within the image limits whatever the layout: there
  // the limit can refuse a grid, and it is taken.)
  if (given("--max-image-dimension") && compact_layout &&
      o.grid.capacity_policy == reference::GridOptions::CapacityPolicy::trace_cost)
    throw OptionsError("--max-image-dimension bounds the image layout's 3D image; the compact layout that the "
                       "trace-cost policy gives the exact traversal has no image: it does nothing (give --layout "
                       "image, or leave it out)");
  if (given("--slot-axis") && compact_layout)
    throw OptionsError("--slot-axis lays the scene along the image layout's slot axis; the compact layout (the exact "
                       "traversal's default) has no image: it does nothing (give --layout image, or leave it out)");
  // Knobs of a part another option turned off (an outside sweep: accepted, images identical)
  if (given("--gap-fill-distance") && !o.grid.gap_fill)
    throw OptionsError("--gap-fill-distance places the paper traversal's gap-fill, which --gap-fill off turns off: it "
                       "does nothing (leave one out)");
  if (given("--skip-covered") && !o.grid.skip_empty)
    throw OptionsError("--skip-covered reads the skip field's cover bits, which --skip-empty off leaves out: it does "
                       "nothing (leave one out)");
  if (given("--skip-covered") && o.grid.layout == reference::GridOptions::Layout::image)
    throw OptionsError("--skip-covered is the compact layout's (its bits live in the skip field beside the compact "
                       "references); --layout image has none: it does nothing (leave one out)");
  if (given("--skip-covered") && o.grid.traversal == reference::Traversal::exact && !compact_layout &&
      o.grid.layout != reference::GridOptions::Layout::image)
    throw OptionsError("--skip-covered is the compact layout's, and --capacity N lays the exact traversal's grid out "
                       "as the image, which has no cover bits: it does nothing (leave one out)");
  // The mailbox needs sorted insertion (an outside review: accepted with first-empty, tests the same)
  if (given("--mailbox") && o.grid.mailbox && o.grid.traversal == reference::Traversal::exact &&
      o.grid.insertion == reference::Insertion::first_empty)
    throw OptionsError("--mailbox on skips references by their sorted order in a cell, which --insertion first-empty "
                       "does not keep: it does nothing (leave one out)");
  // The exact traversal's knobs with the paper traversal: refused where the verb builds no grid
  // but the trace's (stats, verify: an outside review found them accepted, the output the same);
  // elsewhere the frame's gather and explain's primary rays trace the exact traversal's grid
  // whatever the trace's, and take them.
  if (trace_grid_only && o.grid.traversal != reference::Traversal::exact)
    for (const char* name : {"--mailbox", "--skip-empty", "--skip-covered"})
      if (given(name))
        throw OptionsError(std::string(name) + " is a knob of the exact traversal; with the paper traversal (this "
                           "verb's default, or --traversal paper) it does nothing (leave it out, or give --traversal "
                           "exact)");
  if (o.grid.traversal != reference::Traversal::exact) return;
  for (const char* name : {"--gap-fill", "--revisit", "--elongation", "--gap-fill-distance"})
    if (cmd->get_option_no_throw(name) != nullptr && cmd->count(name) > 0)
      throw OptionsError(std::string(name) + " is a knob of the paper traversal's segments and gap-fill: with "
                         "--traversal exact it does nothing (leave it out)");
}

void add_backend_options(CLI::App* cmd, BackendOptions& o, bool vulkan) {
  add_grid_options(cmd, o);
  add_expert_options(cmd, o);
  if (vulkan) add_vulkan_options(cmd, o);
}

void check_vulkan_options_apply(const CLI::App* cmd, bool vulkan_runs) {
  if (vulkan_runs) return;
  for (const char* name : {"--vk-build", "--fallback-cpu"})
    if (cmd->get_option_no_throw(name) != nullptr && cmd->count(name) > 0)
      throw OptionsError(std::string(name) + " chooses how the Vulkan backend runs: it needs --backend vulkan");
}

std::vector<std::string> backend_names() {
  std::vector<std::string> names{"cpu"};
#ifdef GRIDRT_HAVE_VULKAN
  names.push_back("vulkan");
#endif
#ifdef GRIDRT_HAVE_EMBREE
  names.push_back("embree");
#endif
  return names;
}

std::string backend_list() {
  std::string known;
  for (const std::string& n : backend_names()) known += (known.empty() ? "" : ", ") + n;
  return known;
}

uint32_t vulkan_max_image_dimension() {
#ifdef GRIDRT_HAVE_VULKAN
  try {
    vulkan::Context ctx;
    return ctx.info().limits.maxImageDimension3D;
  } catch (const Error&) {
    return 0;
  }
#else
  return 0;
#endif
}

float frame_time(float start, uint32_t k, float fps) { return float(double(start) + double(k) / double(fps)); }

void require_distinct_frame_times(float start, uint32_t first, uint32_t count, float fps, const std::string& option) {
  for (uint32_t k = first; k + 1 < first + count; ++k) {
    const float a = frame_time(start, k, fps), b = frame_time(start, k + 1, fps);
    if (!(b > a)) {
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "frames %u and %u both fall on t = %.9g s: at --fps %g a frame is %.3g s apart, below a float's step "
                    "there (%.3g s); lower --time or --fps",
                    k, k + 1, double(a), double(fps), 1.0 / double(fps),
                    double(std::nextafter(std::abs(a), INFINITY) - std::abs(a)));
      throw CLI::ValidationError(option, buf);
    }
  }
}

void resolve_image_limit(BackendOptions& o, bool uses_vulkan) {
  if (!uses_vulkan) return;
  const uint32_t limit = vulkan_max_image_dimension();
  if (limit == 0) return;
  // A limit above the device's: the Vulkan side lowered it on its own and planned another grid than
  // the reference's (diff said the images "cannot be compared", explain showed a false divergence)
  if (o.max_image_dimension && *o.max_image_dimension > limit)
    throw OptionsError("--max-image-dimension " + std::to_string(*o.max_image_dimension) +
                       " exceeds the Vulkan device's maxImageDimension3D (" + std::to_string(limit) +
                       "): give at most that, or leave it out");
  if (o.max_image_dimension) return;
  o.max_image_dimension = limit;
  std::fprintf(stderr, "grid image limit: %u texels per side (the Vulkan device's maxImageDimension3D)\n", limit);
}

reference::GridOptions grid_options_for(const BackendOptions& o, const Scene& scene) {
  reference::GridOptions g = o.grid;
  if (o.max_image_dimension) g.max_image_dimension = *o.max_image_dimension;
  if (!o.resolution.empty()) g.resolution = glm::uvec3(o.resolution[0], o.resolution[1], o.resolution[2]);
  if (!o.all_effects) {
    // Simulate only what the scene calls for: no alpha keying without masks.
    const Features f = Features::for_scene(scene);
    g.alpha_keying = g.alpha_keying && f.alpha_keying;
  } else {
    g.gap_fill_if_saturated = false;  // gap-fill compiled in even while no cell is saturated
  }
  return g;
}

#ifdef GRIDRT_HAVE_VULKAN
vulkan::VulkanGridOptions vulkan_grid_options(const BackendOptions& o) {
  vulkan::VulkanGridOptions vk;
  vk.build = o.vk_build == "compute" ? vulkan::BuildMode::compute : vulkan::BuildMode::raster;
  vk.ray_tracing = o.ray_tracing;
  vk.build_pass_timestamps = o.build_pass_timestamps;
  return vk;
}
#endif

std::unique_ptr<Tracer> make_backend(const std::string& name, const BackendOptions& o, const Scene& scene) {
  if (name == "cpu") return std::make_unique<reference::ReferenceGridTracer>(grid_options_for(o, scene));
#ifdef GRIDRT_HAVE_VULKAN
  if (name == "vulkan") {
    const vulkan::VulkanGridOptions vk = vulkan_grid_options(o);
    try {
      return std::make_unique<vulkan::VulkanGridTracer>(grid_options_for(o, scene), vk);
    } catch (const Error& e) {
      if (!o.fallback_cpu) throw;
      // Said once: a render makes a second tracer for its gather (it said it twice: an outside sweep)
      static bool said = false;
      if (!said) std::fprintf(stderr, "gridrt: %s\ngridrt: falling back to the CPU reference (--fallback-cpu)\n", e.what());
      said = true;
      return std::make_unique<reference::ReferenceGridTracer>(grid_options_for(o, scene));
    }
  }
#endif
#ifdef GRIDRT_HAVE_EMBREE
  // --threads bounds Embree's threads too (it was taken and ignored: an outside sweep)
  if (name == "embree") return std::make_unique<EmbreeTracer>(reference::thread_count(o.grid));
#endif
  throw OptionsError("unknown backend '" + name + "' (this build has: " + backend_list() + ")");
}

void add_shadows_option(CLI::App* cmd, ShadowMode& mode) {
  cmd->add_option_function<std::string>(
         "--shadows",
         [&mode](const std::string& v) {
           mode = v == "on" ? ShadowMode::on : v == "off" ? ShadowMode::off : ShadowMode::automatic;
         },
         "Shadow rays from the gather to each light (at most 8 lights): on, off, or auto = on iff the scene has "
         "lights (default: auto)")
      ->check(CLI::IsMember({"on", "off", "auto"}).description(""))
      ->type_name("on|off|auto");
}

void add_traces_option(CLI::App* cmd, std::string& traces) {
  add_choice(cmd, "--traces", traces, {"together", "apart"},
             "Vulkan frame, with bounce and shadow rays in 8x8 pixel tiles: the bounce trace and the first light's "
             "shadow trace in one dispatch (together, the default: the shadow tiles fill the device while the bounce "
             "trace's last workgroups run) or as two passes with a barrier between (apart); the same rays and hits");
}

void add_sort_rays_option(CLI::App* cmd, uint32_t& bits, const std::string& help) {
  cmd->add_option("--sort-rays", bits, help)->type_name("0|16|24|32")->check([](const std::string& v) {
    return v == "0" || v == "16" || v == "24" || v == "32" ? std::string() : "0, 16, 24 or 32";
  });
}

void build_gather_grid(Tracer& tracer, const Scene& scene, float time) {
  try {
    tracer.build(scene, time);
  } catch (const OptionsError&) {
    throw;  // the user's options, as the trace's grid would say
  } catch (const Error& e) {
    // Its own grid, which the user never named: say whose it is
    throw Error(std::string("the gather's grid (the exact traversal's, for the primary rays): ") + e.what());
  }
}

GatherBuffer reference_gather(const Scene& scene, const reference::GridOptions& grid, uint32_t w, uint32_t h,
                              float time, std::optional<size_t> only_pixel) {
  reference::ReferenceGridTracer tracer(plan::gather_options(grid));
  build_gather_grid(tracer, scene, time);
  if (only_pixel) {
    OneRayTracer one(tracer, *only_pixel);
    return make_gather(scene, one, scene.frame_camera(), w, h, time);
  }
  Progress progress("gather buffer", size_t(w) * h);
  ProgressTracer traced(tracer, progress);
  return make_gather(scene, traced, scene.frame_camera(), w, h, time);
}

CLI::Validator whole_number_u64() {
  return CLI::Validator(
      [](std::string& v) {
        errno = 0;
        const bool digits = !v.empty() && v.find_first_not_of("0123456789") == std::string::npos;
        (void)std::strtoull(v.c_str(), nullptr, 10);
        return digits && errno == 0 ? std::string() : std::string("must be a whole number from 0 to 18446744073709551615");
      },
      "0 .. 2^64-1");
}

namespace {
CLI::Validator number_at_least_zero(bool strictly) {
  return CLI::Validator(
      [strictly](std::string& v) {
        char* stop = nullptr;
        const double x = std::strtod(v.c_str(), &stop);
        const bool number = stop && stop != v.c_str() && *stop == '\0';
        if (number && (strictly ? x > 0.0 : x >= 0.0)) return std::string();
        return std::string(strictly ? "must be a number above 0" : "must be a number at or above 0") + ", not " + v;
      },
      strictly ? "> 0" : ">= 0");
}
}  // namespace

CLI::Validator positive_number() { return number_at_least_zero(true); }
CLI::Validator non_negative_number() { return number_at_least_zero(false); }

}  // namespace gridrt::app
