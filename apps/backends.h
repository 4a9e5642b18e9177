// backends.h: the tracers the tool can run, by name, and the options they share.
#pragma once

#include <algorithm>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "gridrt/common/gather.h"
#include "gridrt/common/progress.h"
#include "gridrt/common/tracer.h"
#include "gridrt/reference/grid.h"

namespace gridrt::vulkan {
struct VulkanGridOptions;
}

namespace gridrt::app {

// --threads: at most this many (a large number made threads until the system refused one)
using plan::kMaxThreads;

struct BackendOptions {
  reference::GridOptions grid;   // the grid's knobs, shared by cpu and vulkan
  std::string vk_build = "raster";  // raster (the paper's geometry-shader pass) or compute
  bool fallback_cpu = false;     // no Vulkan device: use the CPU reference instead of failing
  bool all_effects = false;      // simulate every effect even where the scene does not need it
  bool ray_tracing = false;      // vulkan: a context with the device's ray tracing (bench --rtx)
  bool build_pass_timestamps = false;  // vulkan: time the build's static and skip-field passes (bench)
  std::vector<unsigned> resolution;  // --resolution X,Y,Z
  // --max-image-dimension; unset: the Vulkan device's maxImageDimension3D where a verb runs the
  // vulkan backend (so both tracers of `diff` choose the same grid), else 4096 (lavapipe's)
  std::optional<uint32_t> max_image_dimension;
};

// The Vulkan grid's options from the command line's (where built with Vulkan).
vulkan::VulkanGridOptions vulkan_grid_options(const BackendOptions& options);

// The largest 3D image side of the Vulkan device the tool would use (0 without one).
uint32_t vulkan_max_image_dimension();

// Fills options.max_image_dimension from the Vulkan device when the user did not set it and
// `uses_vulkan`; prints what it chose.
void resolve_image_limit(BackendOptions& options, bool uses_vulkan);

// Frame k's scene time, start + k / fps, in double and rounded once.
float frame_time(float start, uint32_t k, float fps);
// CLI::ValidationError (on `option`) where two consecutive frame times of frames first ..
// first + count - 1 round to one float: far from 0 a float's step grows (1/16 s near 1e6 s) and
// the frames would repeat without a word.
void require_distinct_frame_times(float start, uint32_t first, uint32_t count, float fps, const std::string& option);

// The capacity rule a --capacity value names (auto = trace-cost), or none for a number.
std::optional<reference::GridOptions::CapacityPolicy> capacity_policy_named(const std::string& name);

// Registers the grid's options on a verb: a common set (--traversal, --capacity, --resolution,
// --spill, --gap-fill, --self-hit, --threads) and the expert knobs in their own help group;
// `vulkan`: the Vulkan port's (--vk-build, --fallback-cpu) too, for a verb that can run it.
void add_backend_options(CLI::App* cmd, BackendOptions& options, bool vulkan = true);
// A whole number from 0 to 2^64-1, as written (CLI11 wrapped a negative value and saturated an
// overflowing one without a word: outside sweeps); for seeds.
CLI::Validator whole_number_u64();
// A number above 0, or at or above 0 (CLI11's own checks print the range's end, DBL_MAX, in all
// its 309 digits: an outside sweep).
CLI::Validator positive_number();
CLI::Validator non_negative_number();
// --vk-build and --fallback-cpu choose how the Vulkan backend runs: given where it does not run
// they did nothing, without a word (an outside sweep). OptionsError (exit 2) there.
void check_vulkan_options_apply(const CLI::App* cmd, bool vulkan_runs);
// The paper traversal's knobs (--gap-fill, --revisit, --elongation, --gap-fill-distance) with
// --traversal exact did nothing, without a word (an outside sweep): OptionsError. (The exact
// traversal's own knobs stay with the paper's: they shape the frame's gather grid, except where
// `trace_grid_only`: a verb that builds no grid but the trace's refuses them too.)
void check_traversal_options(const CLI::App* cmd, const BackendOptions& options, bool trace_grid_only = false);
// The grid verbs' positional scene: a scene file, a mesh, a .gridscene or builtin:NAME (empty:
// the embedded atrium).
CLI::Option* add_scene_argument(CLI::App* cmd, std::string& scene);

// The command line's vocabulary, one form for every verb:
// - a choice among names (--kind, --validation, --div-choice...): the help shows "a|b|c", not
//   CLI11's internals; an unknown name is a command-line error (exit 2);
// - --json FILE (and --junit FILE): also write the result to FILE, replaced only by a complete new
//   one; the text report stays on stdout.
CLI::Option* add_choice(CLI::App* cmd, const std::string& name, std::string& value, const std::vector<std::string>& names,
                        const std::string& help);
CLI::Option* add_json_option(CLI::App* cmd, std::string& path, const std::string& what);
// --width W --height H: an image's size in pixels, each in [1, 16384]; `whose` ends the help
// ("of the gather buffer").
void add_image_size(CLI::App* cmd, uint32_t& width, uint32_t& height, const std::string& whose);

// Names this build knows, in the order `--help` lists them (the first is the default).
std::vector<std::string> backend_names();
std::string backend_list();  // "cpu, vulkan, embree"

// A tracer by name; Error for a name this build does not have (naming the ones it has). The grid
// options are narrowed to what `scene` calls for (unless all_effects).
std::unique_ptr<Tracer> make_backend(const std::string& name, const BackendOptions& options, const Scene& scene);

// The grid options of `options` for `scene`: overrides applied, unneeded effects switched off.
reference::GridOptions grid_options_for(const BackendOptions& options, const Scene& scene);

// Wraps a tracer so that every trace() call goes in chunks and advances a progress line.
class ProgressTracer : public Tracer {
 public:
  ProgressTracer(Tracer& inner, Progress& progress) : inner_(inner), progress_(progress) {}
  std::string name() const override { return inner_.name(); }
  bool built() const override { return inner_.built(); }
  void build_scene(const Scene& scene, float time) override { inner_.build(scene, time); }
  void update_to(float time) override { inner_.update(time); }
  void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) override { chunked(&Tracer::trace, rays, hits); }
  void trace_occlusion(std::span<const Ray> rays, std::span<Hit> hits) override {
    chunked(&Tracer::trace_any, rays, hits);
  }
  AccelDump dump() const override { return inner_.dump(); }

 private:
  using TraceFn = void (Tracer::*)(std::span<const Ray>, std::span<Hit>);
  void chunked(TraceFn fn, std::span<const Ray> rays, std::span<Hit> hits) {
    constexpr size_t kChunk = 1 << 16;
    for (size_t i = 0; i < rays.size(); i += kChunk) {
      const size_t n = std::min(kChunk, rays.size() - i);
      (inner_.*fn)(rays.subspan(i, n), hits.subspan(i, n));
      progress_.advance(n);
    }
  }
  Tracer& inner_;
  Progress& progress_;
};

// --shadows on|off|auto (auto: on iff the scene has lights; shadows_for, common/gather.h).
void add_shadows_option(CLI::App* cmd, ShadowMode& mode);

// --sort-rays 0|16|24|32: the Vulkan frame's bounce rays sorted by that many bits of their keys
// before their trace (vulkan::FrameOptions::sort_bits; 0: off); `help` says it for the verb.
void add_sort_rays_option(CLI::App* cmd, uint32_t& bits, const std::string& help);
// --traces together|apart (FrameOptions::traces_together), for bench and diff --gpu-frame
void add_traces_option(CLI::App* cmd, std::string& traces);

// Traces only the ray of one index and answers a miss for every other: a gather buffer whose one
// pixel is real, for explaining that pixel without tracing the whole image.
class OneRayTracer : public Tracer {
 public:
  OneRayTracer(Tracer& inner, size_t index) : inner_(inner), index_(index) {}
  std::string name() const override { return inner_.name(); }
  bool built() const override { return inner_.built(); }
  void build_scene(const Scene& scene, float time) override { inner_.build(scene, time); }
  void update_to(float time) override { inner_.update(time); }
  void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) override { one(&Tracer::trace, rays, hits); }
  void trace_occlusion(std::span<const Ray> rays, std::span<Hit> hits) override { one(&Tracer::trace_any, rays, hits); }

 private:
  using TraceFn = void (Tracer::*)(std::span<const Ray>, std::span<Hit>);
  void one(TraceFn fn, std::span<const Ray> rays, std::span<Hit> hits) {
    for (Hit& h : hits)
      h = Hit{std::numeric_limits<float>::infinity(), shared::kNoInstance, 0, 0.0f, 0.0f, 0, 0, 0};
    if (index_ < rays.size()) (inner_.*fn)(rays.subspan(index_, 1), hits.subspan(index_, 1));
  }
  Tracer& inner_;
  size_t index_;
};

// Builds a frame's gather grid (the tracer of plan::gather_options' grid, which the user never
// named): an error of it says whose grid it is, an OptionsError passes as it is.
void build_gather_grid(Tracer& tracer, const Scene& scene, float time);

// The CPU reference's gather buffer of a frame (plan::gather_options: the exact traversal with the
// GPU gather's triangle test, so the CPU and GPU gathers agree in bits); with `only_pixel`, only that
// pixel's primary ray is traced (explain).
GatherBuffer reference_gather(const Scene& scene, const reference::GridOptions& grid, uint32_t w, uint32_t h,
                              float time, std::optional<size_t> only_pixel = std::nullopt);

}  // namespace gridrt::app
