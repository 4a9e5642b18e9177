// grid.h: the Vulkan port of the fixed-capacity grid, behind the same interface as the reference
// (reference/grid.h) and held to it bit for bit (docs/VULKAN.md):
//   scene_build  (2.1)  grid_init.comp, then the raster pass (build.vert + build.geom, one draw
//                       per instance) or the compute build (build.comp), static then dynamic;
//                       references no slot takes go to the spill list (kGridSpill), whose
//                       lists spill_order.comp orders after each pass
//   scene_update (2.2)  clear_dynamic.comp over the dirty-cell list (dispatched indirectly; the
//                       spill counter back to the static count first), then the dynamic instances
//                       again (which append the cells they reach)
//   scene_trace  (2.3)  trace.comp, one invocation per ray; the explain ray records its events
// The grid (placement, resolution, capacity) is chosen by plan::choose_grid, so both
// tracers build the same grid from the same GridOptions.
#pragma once

#include <algorithm>
#include <array>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "gridrt/common/tracer.h"
#include "gridrt/plan/plan.h"
#include "gridrt/plan/records.h"
#include "gridrt/vulkan/shaders/grid_interface.h"
#include "gridrt/vulkan/context.h"
#include "gridrt/vulkan/pipeline.h"
#include "gridrt/vulkan/shaders/grid_interface.h"
#include "gridrt/vulkan/shaders/build_input.h"

namespace gridrt::vulkan {

enum class BuildMode {
  raster,   // the paper's: a raster pass whose geometry shader does the work
  compute,  // one compute invocation per triangle
};

struct VulkanGridOptions {
  BuildMode build = BuildMode::raster;
  uint32_t explain_capacity = 1u << 16;  // events the explain buffer holds
  bool ray_tracing = false;  // an owned context enables ray tracing where present (vulkan/rtx.h)
  // The build's run list (build.glsl) in runs; 0: 2^20, within maxStorageBufferRange (tests set a
  // small one to fill it exactly or to overflow it)
  uint32_t build_list_capacity = 0;
  // The spill order pass's shared copy of the entries (spill_order.comp), in entries; 0: as many
  // as maxComputeSharedMemorySize holds (tests set a smaller one: a pass with more entries than
  // the copy holds walks the buffer instead)
  uint32_t order_shared_entries = 0;
  // Timestamps between the build's static passes and the skip field's (GridTimings'
  // build_static_passes_ms, build_skip_passes_ms; gridrt bench): 13 more queries in the build,
  // about 0.01 ms on the H100 (docs/BENCHMARKS.md), so off unless asked for
  bool build_pass_timestamps = false;
};

// Time of the last build, update and trace, milliseconds: on the device (timestamp queries
// around the pass's commands; 0 without timestamps) and on the host (submit to fence, the pass's
// commands only: no uploads or downloads). lavapipe's timestamps do not bracket compute
// dispatches (docs/VULKAN.md): there, the host times are the ones to read.
struct GridTimings {
  double build_ms = 0.0, update_ms = 0.0, trace_ms = 0.0;
  double build_host_ms = 0.0, update_host_ms = 0.0, trace_host_ms = 0.0;
  double clear_ms = 0.0, insert_ms = 0.0;  // the update's two parts (device), update_ms = their sum
  // The insert's parts: the triangles (with the runs' dispatch), the runs of long ranges, the
  // spill lists' order pass
  double insert_triangles_ms = 0.0, insert_runs_ms = 0.0, order_ms = 0.0;
  // The build's passes (device): the blank image, the static instances, the dynamic ones
  double build_init_ms = 0.0, build_static_ms = 0.0, build_skip_ms = 0.0, build_dynamic_ms = 0.0;
  // The skip field's part (device, with build_pass_timestamps): its table's fill, the table along
  // z, y, x, the bricks, the cells
  std::array<double, 6> build_skip_passes_ms{};
  // The static instances' part (device, with build_pass_timestamps): the insert pass, the spill
  // order, the compact layout's group sums, group scan, offsets, scatter, order (0 without the
  // compact layout)
  std::array<double, 7> build_static_passes_ms{};
};

// llvmpipe, Mesa's CPU driver, ends every loop of a shader invocation once its loops have run
// 65,535 iterations in all (gallivm's LP_MAX_TGSI_LOOP_ITERATIONS), and says nothing. The exact
// traversal's trace was cut (measured on Mesa 22.3, each alone): the compact layout's one-loop
// trace (trace.comp trace_exact_flat) near 4,680 reference tests (N copies of one triangle) and
// near 5,041 cells walked with one test (a ray down a tube of 12,000 empty cells, --skip-empty
// off, or beside a wall that keeps the skip boxes small); with the mailbox near 2,980 tests and
// 4,680 cells; the image layout near 64,500 tests, 7,240 with the mailbox. So a ray's loop
// iterations are about (kLlvmpipeIterationsPerTest of its layout) x tests + 14 x cells, and
// check_loop_limit refuses, on llvmpipe and for every traversal, a trace where a ray's estimate
// reaches kLlvmpipeLoopBudget (3/4 of the limit: the per-cell cost was measured on one shape of
// walk) (`what`: the rays, for the message); elsewhere it does nothing (docs/VULKAN.md). The
// paper traversal's segments and slots: tests + cells from 32,768 (an outside sweep: shadow rays
// through 400 cells of 170 references each came back as misses). References the mailbox skips
// cost iterations too but are no tests (an outside sweep: 8 skips a cell over 520 cells cut a ray
// with 8 tests): the trace itself counts them on llvmpipe and flags the ray (kHitLoopSpent,
// llvmpipe_loop_estimate in vulkan/shaders/grid_interface.h, the one estimate of both sides).
using shared::kLlvmpipeLoopBudget;
using shared::kHitLoopSpent;
inline uint64_t llvmpipe_loop_estimate(const shared::GridParams& g, uint32_t tests, uint32_t cells) {
  return shared::llvmpipe_loop_estimate(g.traversal == shared::kTraversalExact, (g.flags & shared::kGridCompact) != 0u,
                                        (g.flags & shared::kGridMailbox) != 0u, tests, 0u, cells);
}
// The frame's gather with the scan's lists: a screen tile's list of triangles, walked by its fine
// pass's workgroup (a tile of about 64,000 was cut short); VulkanFrame::render refuses from this
// many on llvmpipe. (In buckets the fine pass walks at most a bucket's room.)
inline constexpr uint32_t kLlvmpipeTilePairLimit = 16384;
// The spill list's order pass and walk: a cell listing 65,535 entries or more is cut (70,000
// triangles in one cell of capacity 1); after_insert refuses, on llvmpipe, a cell listing this many.
inline constexpr uint32_t kLlvmpipeSpillListLimit = 32768;
// The build's run list: a triangle's invocation lists its AABB range's runs of 8 cells one by one
// (build.glsl), a loop of 110,592 iterations for a triangle over 96^3 cells, cut on llvmpipe (the
// list's tail left stale: junk references, cells left out). build and update refuse, on llvmpipe,
// a triangle whose range holds more cells than this (32,768 runs).
inline constexpr uint64_t kLlvmpipeRangeCellLimit = 262144;
// And where the ranges' runs overflow the list, a triangle walks the rest of its range itself: 4
// to 7 iterations a cell, and in each cell it keeps the insertion's (the slot search's gallop and
// halving, about 2 log2(capacity) + 2, and the sorted insert's cascade, up to the capacity). Refused
// there, on llvmpipe, above this many cells, and above llvmpipe_walk_cell_limit(capacity): 8,192
// walked cells of capacity 256 passed the 65,535 iterations and lost 21,008 references (an outside
// sweep).
inline constexpr uint64_t kLlvmpipeWalkCellLimit = 8192;
// `compact`: the compact layout's build counts a cell's pair and appends it (no slots, no
// cascade: a few iterations a cell); its `capacity` is the largest cell's count, not slots.
inline uint64_t llvmpipe_walk_cell_limit(uint32_t capacity, bool compact = false) {
  if (compact) return kLlvmpipeWalkCellLimit;
  uint64_t log2 = 0;
  while ((uint64_t(1) << log2) < uint64_t(capacity) + 1u) ++log2;
  const uint64_t per_cell = 7u + 2u * log2 + 2u + uint64_t(capacity);
  return std::min<uint64_t>(kLlvmpipeWalkCellLimit, 60000u / per_cell);
}
inline constexpr uint64_t kBuildRunCells = 8;  // build.glsl's kBuildRun
void check_loop_limit(const Context& ctx, const shared::GridParams& g, std::span<const Hit> hits, const char* what);

class VulkanGridTracer : public Tracer {
 public:
  // On its own context (ContextOptions::from_env(); geometry shaders required only for the
  // raster build).
  explicit VulkanGridTracer(plan::GridOptions options = {}, VulkanGridOptions vk = {});
  // On a context the caller keeps alive.
  VulkanGridTracer(Context& ctx, plan::GridOptions options = {}, VulkanGridOptions vk = {});
  ~VulkanGridTracer() override;

  std::string name() const override;
  void build_scene(const Scene& scene, float time) override;
  void update_to(float time) override;
  void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) override;
  void trace_occlusion(std::span<const Ray> rays, std::span<Hit> hits) override;
  AccelDump dump() const override;

  // Traces `rays` and records the events of rays[index], as the reference's explain_ray does
  // (`mode`: which hit, shared::kTraceClosestHit or kTraceAnyHit).
  plan::ExplainRecord explain_ray(std::span<const Ray> rays, uint32_t index, uint32_t mode = shared::kTraceClosestHit);
  plan::ExplainRecord explain_ray(const Ray& ray, uint32_t mode = shared::kTraceClosestHit) {
    return explain_ray(std::span<const Ray>(&ray, 1), 0, mode);
  }

  // Runs of kBuildRun cells (build.glsl) the compute build and its updates handed out so far
  // (0 for the raster build).
  uint32_t download_build_runs() const;
  // The dirty-cell list's cells (as plan::dirty_cells: the cells appended since the last
  // clear pass, in the order the device appended them).
  std::vector<uint32_t> download_dirty_cells() const;
  // The skip field (kGridSkipEmpty: shared::skip_words words; empty without it).
  std::vector<uint32_t> download_skip() const;
  // The geometry buffer as the build wrote it (for tests against GridData::triangles).
  std::vector<shared::GridTriangle> download_triangles() const;
  // The plane buffer as the build wrote it (for tests against GridData::planes).
  std::vector<shared::GridPlane> download_planes() const;
  // The spill list as the device holds it: the header and the stored entries (append order).
  plan::SpillDump spill() const;
  // Everything the grid keeps on the device, as allocated (plan::grid_memory's parts).
  plan::GridMemory memory() const;
  // The spill list's header as read back after the last build or update.
  const shared::SpillHeader& spill_header() const { return spill_header_; }

  const shared::GridParams& params() const { return params_; }
  const plan::GridOptions& options() const { return options_; }
  float build_time() const { return build_time_; }  // the scene time of the last build
  // Counts the builds that succeeded: each makes new buffers, which a VulkanFrame made before it
  // no longer holds (it refuses to render then)
  uint64_t build_generation() const { return build_generation_; }
  const GridTimings& timings() const { return timings_; }

  // For passes of other pipelines on the grid's device data (vulkan/frame.h), valid after
  // build(): the instances (GridInstance), the geometry buffer (GridTriangle, world space as the
  // build and update wrote it; on a context with ray_tracing() also an acceleration-structure
  // build input with a device address), the plane buffer (GridPlane), the triangles' uvs (GridTriangleUv), the materials
  // (GridMaterial) and the alpha masks' texels. A later build() makes new buffers.
  const Buffer& instance_buffer() const;
  const Buffer& triangle_buffer() const;
  const Buffer& plane_buffer() const;
  const Buffer& uv_buffer() const;
  const Buffer& material_buffer() const;
  const Buffer& texel_buffer() const;
  // Binds device buffers the caller keeps alive as the rays and hits of record_trace (a later
  // trace() binds its own again), and optionally a work list of ray indices
  // (common/shared/worklist.h, usage INDIRECT_BUFFER too) for record_trace_list.
  void bind_ray_buffers(const Buffer& rays, const Buffer& hits, const Buffer* ray_list = nullptr);
  // Records the trace of rays [first, first + count) of the bound buffers into `cb` (no barriers);
  // `mode`: which hit (shared::kTraceAnyHit for the frame's shadow rays).
  void record_trace(VkCommandBuffer cb, uint32_t count, uint32_t first = 0, uint32_t mode = shared::kTraceClosestHit);
  // The same for the rays of a width x height image stored row by row from ray `first`, a
  // workgroup per 8x8 pixel tile (neighbouring pixels' rays in one subgroup; no barriers).
  void record_trace_image(VkCommandBuffer cb, uint32_t width, uint32_t height, uint32_t first,
                          uint32_t mode = shared::kTraceClosestHit);
  // Binds device buffers the caller keeps alive as the frame's gather buffer (shared::GatherTexel
  // per pixel, row by row), its parameters (shared::FrameParams) and materials
  // (shared::FrameMaterial), which the frame's traces below make their rays from.
  void bind_frame(const Buffer& gather, const Buffer& frame_params, const Buffer& frame_materials);
  // The frame's bounce trace: for every pixel of the width x height image the trace makes the
  // pixel's glossy bounce ray from the bound gather (as bounce.comp, common/shared/bounce.h; the
  // empty ray where there is none), writes it as ray `pixel` of the bound ray buffer and traces
  // it, a workgroup per 8x8 pixel tile (no barriers).
  void record_bounce_trace_image(VkCommandBuffer cb, uint32_t width, uint32_t height);
  // The frame's shadow trace towards one light: the same with the pixel's shadow ray
  // (shared::shadow_ray towards `light`, a position, or with `directional` the direction towards
  // it), written as ray `first` + pixel and traced for any hit.
  void record_shadow_trace_image(VkCommandBuffer cb, uint32_t width, uint32_t height, uint32_t first,
                                 glm::vec3 light, bool directional);
  // Both in one dispatch: the bounce trace's workgroups first, then the shadow trace's towards
  // `light` (rays `first` + pixel), so that the shadow rays fill the device while the bounce
  // trace's last workgroups run (no barrier between two passes)
  void record_bounce_and_shadow_trace_image(VkCommandBuffer cb, uint32_t width, uint32_t height, uint32_t first,
                                            glm::vec3 light, bool directional);
  // Records the trace of the rays the bound ray list names, dispatched indirectly on the list
  // (its dispatch step must have run; no barriers). The other rays' hits are not written.
  void record_trace_list(VkCommandBuffer cb);
  uint32_t static_instance_count() const { return static_instances_; }
  const std::vector<shared::GridInstance>& instances() const { return instances_; }
  Context& context() const { return *ctx_; }

 private:
  struct Gpu;  // buffers, image, descriptors, pipelines
  // build()'s steps
  void check_device() const;
  // llvmpipe: refuses a triangle of instances [first, end) whose AABB range at `time` holds more
  // than kLlvmpipeRangeCellLimit cells; elsewhere nothing.
  void check_build_ranges(const Scene& scene, float time, uint32_t first) const;
  plan::GridPlan make_plan(const Scene& scene, float time);
  void make_build_input(const Scene& scene, float time, std::vector<glm::vec4>& positions,
                        std::vector<uint32_t>& indices);
  void create_resources(const plan::GridPlan& plan, const std::vector<glm::vec4>& positions,
                        const std::vector<uint32_t>& indices);
  void create_pipelines();
  void record_build(uint32_t instance_count);
  // `stamps`: timestamp `stamp` written between the triangles and the runs
  void insert_instances(VkCommandBuffer cb, uint32_t first, uint32_t last, Timestamps* stamps = nullptr,
                        uint32_t stamp = 0);
  // Reads the spill header back, sets the trace's flags from it (plan::trace_flags) and
  // warns once on an overflow.
  void after_insert(bool warn = true);
  // update's work after its early return: the dynamic references cleared and inserted at `time`.
  void update_insert(float time);
  // The spill list grown to `capacity` entries, its header and static entries copied over and the
  // set bound to it (plan::spill_growth: the update then inserts again).
  void grow_spill(uint32_t capacity);
  void record_spill_order(VkCommandBuffer cb, bool dynamic);
  // The trace pipeline for the current flags, with explain or on a ray list (made on first use:
  // gap-fill comes and goes with saturation).
  const Pipeline& trace_pipeline(bool explain, bool list = false, uint32_t mode = shared::kTraceClosestHit,
                                 uint32_t rays = shared::kTraceRaysBuffer);
  void record_frame_trace(VkCommandBuffer cb, uint32_t width, uint32_t height, uint32_t first, uint32_t rays,
                          glm::vec3 light, bool directional);
  void upload_transforms(float time, uint32_t first, uint32_t last);
  void record_skip_field(VkCommandBuffer cb, Timestamps* stamps = nullptr);
  void record_compact(VkCommandBuffer cb, Timestamps* stamps = nullptr);
  void run_trace(std::span<const Ray> rays, std::span<Hit> hits, uint32_t explain_index, uint32_t mode);

  std::unique_ptr<Context> owned_;
  Context* ctx_ = nullptr;
  plan::GridOptions options_;
  VulkanGridOptions vk_;
  float build_time_ = 0.0f;
  uint64_t build_generation_ = 0;
  const Scene* scene_ = nullptr;
  shared::GridParams params_{};
  uint32_t requested_flags_ = 0;  // params_.flags as choose_grid chose them
  shared::SpillHeader spill_header_{};
  bool overflow_warned_ = false;
  uint32_t static_instances_ = 0;
  std::vector<shared::GridInstance> instances_;
  std::vector<shared::BuildInstance> build_instances_;
  std::unique_ptr<Gpu> gpu_;
  GridTimings timings_;
};

}  // namespace gridrt::vulkan
