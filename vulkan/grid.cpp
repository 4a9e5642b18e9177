// grid.cpp: VulkanGridTracer, the host side of the Vulkan grid (see grid.h). The passes are in
// vulkan/shaders/; this file makes the tables they read (as reference/build.cpp does), records
// the passes and reads the results back.
#include "gridrt/vulkan/grid.h"
#include "gridrt/vulkan/shaders/frame_input.h"
#include "gridrt/common/util.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstddef>
#include <cstring>
#include <map>
#include <unordered_map>

#include "gridrt/plan/policy.h"
#include "gridrt/vulkan/ray_pass.h"
#include "gridrt/vulkan/shaders/grid_interface.h"

namespace gridrt::vulkan {

using shared::GridParams;

namespace {

// The descriptor set every grid pipeline uses (vulkan/shaders/grid_common.glsl and trace.comp).
// The bindings, specialization constants and push constants: vulkan/shaders/grid_interface.h.
constexpr uint32_t kStorageBuffersPerStage = shared::kGridBindingCount - 1;
constexpr VkDeviceSize kExplainHeader = sizeof(shared::ExplainHeader);  // count + padding before the events
constexpr uint32_t kBuildPassStamps = 13;  // Gpu::build_pass_timestamps

SpecConstants spec_for(const GridParams& g, bool explain) {
  SpecConstants s;
  // kGridSpecLoopGuard: set by trace_pipeline on llvmpipe only
  s.add(shared::kGridSpecCapacity, g.capacity).add(shared::kGridSpecInsertion, g.insertion).add(shared::kGridSpecTraversal, g.traversal);
  s.add(shared::kGridSpecFlags, g.flags).add(shared::kGridSpecExplain, explain).add(shared::kGridSpecRepeats, g.repeats);
  s.add(shared::kGridSpecTriangleTest, g.triangle_test);
  return s;
}

template <class T>
Buffer make_buffer(Context& ctx, const std::vector<T>& data, VkBufferUsageFlags extra_usage = 0) {
  Buffer b = ctx.create_buffer(std::max<size_t>(data.size() * sizeof(T), 16),
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | extra_usage);
  if (data.empty()) {  // zeros, not whatever the memory held: an empty table reads as counts of 0
    const std::array<uint8_t, 16> zeros{};
    ctx.upload(b, zeros.data(), zeros.size());
  } else {
    ctx.upload(b, data.data(), data.size() * sizeof(T));
  }
  return b;
}

}  // namespace

struct VulkanGridTracer::Gpu {
  Buffer params, instances, triangles, uvs, materials, texels, build_instances, positions, indices;
  Buffer planes;  // the plane buffer: a GridPlane per triangle, written by the build
  Buffer rays, hits, explain, dirty, no_ray_list, no_frame, build_list, spill, spill_heads;
  Buffer skip, skip_table;  // the skip field (kGridSkipEmpty); its table lives for the build only
  // The compact layout (kGridCompact): the offsets and references, and the build's temporaries
  // (per-cell counts, the pairs, the scattered references, the scan's blocks), 16-byte stand-ins
  // after the build and without the compact layout
  Buffer offsets, refs, compact_counts, compact_pairs, compact_scattered, compact_blocks;
  uint32_t compact_pair_capacity = 0;
  std::unique_ptr<Pipeline> compact;
  uint32_t spill_capacity = 0;  // entries the spill list holds (0: spill off)
  uint32_t build_list_capacity = 0;
  VkBuffer ray_list = VK_NULL_HANDLE;  // bound by bind_ray_buffers (not owned)
  // Bytes of the buffers bound as the rays, hits (bind_ray_buffers, or trace()'s own) and the
  // frame's gather and parameters (bind_frame; 0: the stand-ins): the frame traces' checks
  size_t bound_ray_bytes = 0, bound_hit_bytes = 0, bound_gather_bytes = 0, bound_frame_params_bytes = 0;
  size_t ray_capacity = 0;
  Image3D image;
  std::unique_ptr<Descriptors> set, dirty_set, build_list_set;
  std::unique_ptr<Pipeline> init, raster, compute, build_cells, build_list_dispatch, clear, dirty_dispatch, order;
  std::unique_ptr<Pipeline> skip_field;
  std::map<uint64_t, std::unique_ptr<Pipeline>> traces;  // by (ray list, explain, flags): trace_pipeline
  std::unique_ptr<Timestamps> timestamps, update_timestamps, build_timestamps;
  // With VulkanGridOptions::build_pass_timestamps: after the insert pass and the spill order, after
  // each of the compact layout's five passes, after the skip field's fill and each of its five
  std::unique_ptr<Timestamps> build_pass_timestamps;
};

namespace {
// A context for `vk`: the compute build does not need geometry shaders.
ContextOptions context_options(const VulkanGridOptions& vk) {
  ContextOptions o = ContextOptions::from_env();
  o.raster_build = vk.build == BuildMode::raster;
  o.ray_tracing = vk.ray_tracing;
  return o;
}
}  // namespace

VulkanGridTracer::VulkanGridTracer(plan::GridOptions options, VulkanGridOptions vk)
    : owned_(std::make_unique<Context>(context_options(vk))), ctx_(owned_.get()), options_(std::move(options)),
      vk_(vk) {}

VulkanGridTracer::VulkanGridTracer(Context& ctx, plan::GridOptions options, VulkanGridOptions vk)
    : ctx_(&ctx), options_(std::move(options)), vk_(vk) {}

VulkanGridTracer::~VulkanGridTracer() {
  gpu_.reset();  // before an owned context goes
}

std::string VulkanGridTracer::name() const {
  return vk_.build == BuildMode::raster ? "vulkan-grid" : "vulkan-grid (compute build)";
}

// ---- Scene build (paper 2.1) ----

void VulkanGridTracer::build_scene(const Scene& scene, float time) {
  check_device();
  gpu_.reset();
  scene_ = &scene;
  build_time_ = time;
  try {
    const plan::GridPlan plan = make_plan(scene, time);
    std::vector<glm::vec4> positions;
    std::vector<uint32_t> indices;
    make_build_input(scene, time, positions, indices);
    create_resources(plan, positions, indices);
    if ((params_.flags & shared::kGridSkipEmpty) != 0u) {
      const std::vector<uint32_t> boxes = plan::skip_box_words(scene, time, params_);
      ctx_->upload(gpu_->skip, boxes.data(), boxes.size() * sizeof(uint32_t));
    }
    check_build_ranges(scene, time, 0);
    create_pipelines();
    record_build(uint32_t(scene.instances.size()));
    after_insert();
    ++build_generation_;
  } catch (...) {
    // As before any build (Tracer::build): no half-made grid for the frame's or the dump's calls
    gpu_.reset();
    scene_ = nullptr;
    throw;
  }
}

// The device can run the grid: its storage buffers per stage, and for the raster build geometry
// shaders with stores.
void VulkanGridTracer::check_device() const {
  const DeviceInfo& dev = ctx_->info();
  if (dev.limits.maxPerStageDescriptorStorageBuffers < kStorageBuffersPerStage)
    throw Error("the Vulkan grid needs " + std::to_string(kStorageBuffersPerStage) +
                " storage buffers per shader stage, over maxPerStageDescriptorStorageBuffers (" +
                std::to_string(dev.limits.maxPerStageDescriptorStorageBuffers) + ") on " + dev.name +
                "; use --backend cpu");
  if (!dev.subgroup_arithmetic_ballot)
    throw Error(dev.name + " lacks subgroup ballot and arithmetic in compute shaders (the build's atomic counters, "
                           "build.comp and build_cells.comp): use --backend cpu");
  if (vk_.build == BuildMode::raster && (!dev.geometry_shader || !dev.vertex_pipeline_stores_and_atomics))
    throw Error(dev.name + " lacks geometryShader or vertexPipelineStoresAndAtomics for the raster build: use "
                           "the compute build (--build compute)");
}

// The grid the reference would choose (plan/plan.h), within this device's image limit; the
// tables are the plan's.
plan::GridPlan VulkanGridTracer::make_plan(const Scene& scene, float time) {
  const DeviceInfo& dev = ctx_->info();
  plan::GridOptions o = options_;
  o.max_image_dimension = std::min(o.max_image_dimension, dev.limits.maxImageDimension3D);
  plan::GridPlan plan = plan::plan_grid(scene, time, o);
  params_ = plan.params;
  requested_flags_ = params_.flags;

  // Tables: instances, materials and their alpha masks, the geometry buffer (plan/tables.cpp)
  static_instances_ = plan.tables.static_instances;
  instances_ = plan.tables.instances;
  return plan;
}

// Build input: the object-space meshes and every instance's transform at `time`.
void VulkanGridTracer::make_build_input(const Scene& scene, float time, std::vector<glm::vec4>& positions,
                                        std::vector<uint32_t>& indices) {
  std::vector<uint32_t> vertex_offset(scene.meshes.size()), index_offset(scene.meshes.size());
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    vertex_offset[m] = uint32_t(positions.size());
    index_offset[m] = uint32_t(indices.size());
    for (const glm::vec3& p : scene.meshes[m].positions) positions.emplace_back(p, 1.0f);
    for (const glm::uvec3& t : scene.meshes[m].triangles) indices.insert(indices.end(), {t.x, t.y, t.z});
  }
  build_instances_.clear();
  for (uint32_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    build_instances_.push_back({shared::to_affine(inst.transform_at(time)), vertex_offset[inst.mesh],
                                index_offset[inst.mesh], instances_[i].tri_offset, instances_[i].tri_count});
  }
}

// Device resources: the tables' buffers, the build input, the explain, ray, dirty-cell and
// build-list buffers, the image, the spill list.
void VulkanGridTracer::create_resources(const plan::GridPlan& plan, const std::vector<glm::vec4>& positions,
                                        const std::vector<uint32_t>& indices) {
  Context& ctx = *ctx_;
  const DeviceInfo& dev = ctx.info();
  const GridParams& g = params_;
  const uint32_t spill_capacity = plan.spill_capacity;
  const std::vector<shared::GridTriangle>& triangles = plan.tables.triangles;
  const std::vector<shared::GridTriangleUv>& uvs = plan.tables.uvs;
  const std::vector<shared::GridMaterial>& materials = plan.tables.materials;
  const std::vector<uint32_t>& texels = plan.tables.texels;
  gpu_ = std::make_unique<Gpu>();
  Gpu& gpu = *gpu_;
  gpu.params = make_buffer(ctx, std::vector<GridParams>{g}, VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT);
  gpu.instances = make_buffer(ctx, instances_);
  // With ray tracing enabled the geometry buffer is also the vertex input of the acceleration
  // structures (vulkan/rtx.h): the BLASes are built over the very triangles the grid tests
  const VkBufferUsageFlags as_input = ctx.ray_tracing() ? VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT |
                                                              VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR
                                                        : 0u;
  gpu.triangles = make_buffer(ctx, triangles, as_input);
  gpu.planes = make_buffer(ctx, std::vector<shared::GridPlane>(std::max<size_t>(triangles.size(), 1)));
  gpu.uvs = make_buffer(ctx, uvs);
  gpu.materials = make_buffer(ctx, materials);
  gpu.texels = make_buffer(ctx, texels);
  gpu.build_instances = make_buffer(ctx, build_instances_);
  gpu.positions = make_buffer(ctx, positions);
  gpu.indices = make_buffer(ctx, indices);
  gpu.explain = ctx.create_buffer(kExplainHeader + VkDeviceSize(vk_.explain_capacity) * sizeof(shared::ExplainEvent),
                                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  gpu.rays = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  gpu.hits = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  gpu.no_ray_list = ctx.create_buffer(sizeof(shared::WorkListHeader), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  gpu.no_frame = ctx.create_buffer(256, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  gpu.dirty = ctx.create_buffer((g.flags & shared::kGridCompact) != 0u ? VkDeviceSize(shared::kWorkListHeaderWords) * 4
                                                                     : VkDeviceSize(shared::dirty_list_words(g)) * 4,
                                VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT, Memory::Device,
                                "the grid's dirty-cell list, 4 bytes a cell");
  // The runs of long cell ranges, both builds (build.glsl): at most 2^20 items (8 MiB)
  gpu.build_list_capacity = uint32_t(std::min<uint64_t>((dev.limits.maxStorageBufferRange - 32) / 8,
                                                        vk_.build_list_capacity ? vk_.build_list_capacity : 1u << 20));
  gpu.build_list = ctx.create_buffer(sizeof(shared::WorkListHeader) + uint64_t(gpu.build_list_capacity) * 8,
                                     VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT);
  const bool compact = (g.flags & shared::kGridCompact) != 0u;
  gpu.image = ctx.create_image3d(compact ? glm::uvec3(1u) : shared::grid_image_extent(g));
  // The compact layout: the offsets, room for the plan's count of static references, and the
  // build's temporaries (stand-ins of 16 bytes without the compact layout)
  const VkBufferUsageFlags sbu = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  const uint64_t cells = shared::grid_cell_count(g);
  const uint64_t refs = std::max<uint64_t>(plan.static_references, 1);
  const uint64_t max_items = uint64_t(dev.limits.maxComputeWorkGroupCount[0]) * shared::kCompactScanLanes;
  if (compact && (refs > max_items || cells > max_items || refs >= (uint64_t(1) << 31)))
    throw Error("a compact grid of " + std::to_string(cells) + " cells and " + std::to_string(refs) +
                " references needs more workgroups than maxComputeWorkGroupCount on " + dev.name +
                ": use --layout image or fewer cells");
  // The plan's count exactly (the build checks its own against it; 0 where every triangle has zero
  // area), the buffers at least one reference long
  gpu.compact_pair_capacity = compact ? uint32_t(plan.static_references) : 0u;
  const bool sparse = (g.flags & shared::kGridSparseOffsets) != 0u;
  const uint64_t offsets_words =
      sparse ? uint64_t(shared::compact_offsets_words(uint32_t(cells), uint32_t(plan.static_cells))) : cells + 1;
  gpu.offsets = ctx.create_buffer(compact ? offsets_words * 4 : 16, sbu, Memory::Device, "the compact layout's offsets");
  gpu.refs = ctx.create_buffer(compact ? refs * 4 : 16, sbu);
  gpu.compact_counts = ctx.create_buffer(compact ? cells * 4 : 16, sbu, Memory::Device, "the compact build's counts, 4 bytes a cell");
  gpu.compact_pairs = ctx.create_buffer(compact ? 16 + refs * 8 : 16, sbu);
  gpu.compact_scattered = ctx.create_buffer(compact ? refs * 8 : 16, sbu);  // the references, then their cells
  gpu.compact_blocks = ctx.create_buffer(compact ? uint64_t(groups(uint32_t(cells), shared::kCompactScanLanes)) * 8 : 16, sbu);  // (references, occupied cells) per group
  // The spill list: the header (count 0), the entries, four heads per cell (docs/SPEC.md)
  gpu.spill = ctx.create_buffer(sizeof(shared::SpillHeader) + VkDeviceSize(std::max(spill_capacity, 1u)) *
                                                                  sizeof(shared::SpillEntry),
                                VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  spill_header_ = shared::SpillHeader{0u, spill_capacity, 0u, 0u};
  ctx.upload(gpu.spill, &spill_header_, sizeof spill_header_);
  const bool spill_on = (g.flags & shared::kGridSpill) != 0u;
  gpu.spill_capacity = spill_on ? spill_capacity : 0u;
  if (uint64_t(gpu.spill_capacity) > uint64_t(dev.limits.maxComputeWorkGroupCount[0]) * 64u)
    throw Error("a spill list of " + std::to_string(gpu.spill_capacity) + " entries needs more workgroups than "
                "maxComputeWorkGroupCount on " + dev.name + ": use a smaller --spill-capacity");
  if (compact) {
    // The region's header and its cells' heads, every one empty
    const std::vector<uint32_t> heads = plan::compact_heads(plan.region);
    gpu.spill_heads = make_buffer(ctx, heads);
  } else {
    gpu.spill_heads = ctx.create_buffer(spill_on ? 4 * VkDeviceSize(shared::grid_cell_count(g)) * sizeof(uint32_t) : 16,
                                        VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, Memory::Device,
                                        "the spill list's heads, 16 bytes a cell");
  }
  overflow_warned_ = false;
  // The skip field: the dynamic boxes (build and update upload them), the distances (written by
  // the skip_field passes), and the summed-volume table those use during the build
  const bool skip_on = (g.flags & shared::kGridSkipEmpty) != 0u;
  gpu.skip = ctx.create_buffer(skip_on ? VkDeviceSize(shared::skip_words(g)) * 4 : 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                             Memory::Device, "the skip field");
  gpu.skip_table = ctx.create_buffer(skip_on ? VkDeviceSize(shared::skip_scratch_words(g)) * 4 : 16,
                                     VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, Memory::Device,
                                     "the skip field's summed-volume table");
}

// The descriptor set (grid_interface.h's bindings) and the pipelines of the build and update.
void VulkanGridTracer::create_pipelines() {
  Context& ctx = *ctx_;
  const DeviceInfo& dev = ctx.info();
  Gpu& gpu = *gpu_;
  const GridParams& g = params_;
  const VkDescriptorType sb = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  std::vector<VkDescriptorType> types(shared::kGridBindingCount, sb);
  types[shared::kGridBindImage] = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
  types[shared::kGridBindParams] = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  gpu.set = std::make_unique<Descriptors>(ctx, std::move(types));
  Descriptors& set = *gpu.set;
  set.bind(shared::kGridBindParams, gpu.params);
  set.bind(shared::kGridBindImage, gpu.image);
  set.bind(shared::kGridBindInstances, gpu.instances);
  set.bind(shared::kGridBindTriangles, gpu.triangles);
  set.bind(shared::kGridBindPlanes, gpu.planes);
  set.bind(shared::kGridBindUvs, gpu.uvs);
  set.bind(shared::kGridBindMaterials, gpu.materials);
  set.bind(shared::kGridBindTexels, gpu.texels);
  set.bind(shared::kGridBindBuildInstances, gpu.build_instances);
  set.bind(shared::kGridBindPositions, gpu.positions);
  set.bind(shared::kGridBindIndices, gpu.indices);
  set.bind(shared::kGridBindRays, gpu.rays);
  set.bind(shared::kGridBindHits, gpu.hits);
  set.bind(shared::kGridBindExplain, gpu.explain);
  set.bind(shared::kGridBindDirty, gpu.dirty);
  set.bind(shared::kGridBindRayList, gpu.no_ray_list);
  for (uint32_t b : {shared::kGridBindGather, shared::kGridBindFrameParams, shared::kGridBindFrameMaterials})
    set.bind(b, gpu.no_frame);
  set.bind(shared::kGridBindBuildList, gpu.build_list);
  set.bind(shared::kGridBindSpill, gpu.spill);
  set.bind(shared::kGridBindSpillHeads, gpu.spill_heads);
  set.bind(shared::kGridBindSkip, gpu.skip);
  set.bind(shared::kGridBindSkipTable, gpu.skip_table);
  set.bind(shared::kGridBindOffsets, gpu.offsets);
  set.bind(shared::kGridBindRefs, gpu.refs);
  set.bind(shared::kGridBindCompactCounts, gpu.compact_counts);
  set.bind(shared::kGridBindCompactPairs, gpu.compact_pairs);
  set.bind(shared::kGridBindCompactScattered, gpu.compact_scattered);
  set.bind(shared::kGridBindCompactBlocks, gpu.compact_blocks);
  gpu.dirty_set = std::make_unique<Descriptors>(ctx, std::initializer_list<VkDescriptorType>{sb});
  gpu.dirty_set->bind(0, gpu.dirty);

  gpu.init = std::make_unique<Pipeline>(ctx, "grid_init.comp", set.layout(), 0, spec_for(g, false));
  if (vk_.build == BuildMode::raster)
    gpu.raster = std::make_unique<Pipeline>(ctx, "build.vert", "build.geom", set.layout(), 0, spec_for(g, false));
  else
    gpu.compute = std::make_unique<Pipeline>(ctx, "build.comp", set.layout(), uint32_t(sizeof(shared::BuildPush)),
                                             spec_for(g, false));
  gpu.build_cells = std::make_unique<Pipeline>(ctx, "build_cells.comp", set.layout(), 0, spec_for(g, false));
  gpu.build_list_set = std::make_unique<Descriptors>(ctx, std::initializer_list<VkDescriptorType>{sb});
  gpu.build_list_set->bind(0, gpu.build_list);
  gpu.build_list_dispatch = std::make_unique<Pipeline>(ctx, "work_list_dispatch.comp", gpu.build_list_set->layout(),
                                                       uint32_t(sizeof(shared::WorkListDispatchPush)));
  gpu.clear = std::make_unique<Pipeline>(ctx, "clear_dynamic.comp", set.layout(), uint32_t(sizeof(shared::ClearPush)),
                                         spec_for(g, false));
  gpu.dirty_dispatch = std::make_unique<Pipeline>(ctx, "work_list_dispatch.comp", gpu.dirty_set->layout(),
                                                  uint32_t(sizeof(shared::WorkListDispatchPush)));
  if (gpu.spill_capacity) {
    // The order pass's shared copy of the entries: as many as the device's shared memory holds,
    // 8 bytes each (Vulkan guarantees 16 KiB: 2048 entries), or fewer where asked
    const uint32_t device_entries = std::max(dev.limits.maxComputeSharedMemorySize / 8u, 1u);
    SpecConstants order_spec = spec_for(g, false);
    order_spec.add(shared::kGridSpecOrderShared,
                   vk_.order_shared_entries ? std::min(vk_.order_shared_entries, device_entries) : device_entries);
    gpu.order = std::make_unique<Pipeline>(ctx, "spill_order.comp", set.layout(), uint32_t(sizeof(shared::SpillOrderPush)),
                                           std::move(order_spec));
  }
  if ((g.flags & shared::kGridCompact) != 0u)
    gpu.compact = std::make_unique<Pipeline>(ctx, "compact.comp", set.layout(), uint32_t(sizeof(shared::CompactPush)),
                                             spec_for(g, false));
  if ((g.flags & shared::kGridSkipEmpty) != 0u)
    gpu.skip_field = std::make_unique<Pipeline>(ctx, "skip_field.comp", set.layout(), uint32_t(sizeof(shared::SkipFieldPush)),
                                                spec_for(g, false));
  if (dev.timestamp_valid_bits) {
    gpu.timestamps = std::make_unique<Timestamps>(ctx, 2);
    gpu.update_timestamps = std::make_unique<Timestamps>(ctx, 5);  // begin, after the clear, the triangles, the runs, end
    gpu.build_timestamps = std::make_unique<Timestamps>(ctx, 5);  // begin, after init, static, skip, dynamic
    if (vk_.build_pass_timestamps) gpu.build_pass_timestamps = std::make_unique<Timestamps>(ctx, kBuildPassStamps);
  }
}

// The build's passes: the image blank with status texels 0, the static instances (their
// references fill the first slots), then the dynamic ones, each followed by the spill list's order
// pass; timed.
void VulkanGridTracer::record_build(uint32_t instance_count) {
  Context& ctx = *ctx_;
  const DeviceInfo& dev = ctx.info();
  Gpu& gpu = *gpu_;
  Descriptors& set = *gpu.set;
  const glm::uvec3 extent = gpu.image.extent;
  const uint32_t* max_groups = dev.limits.maxComputeWorkGroupCount;
  if (groups(extent.x, 4) > max_groups[0] || groups(extent.y, 4) > max_groups[1] || groups(extent.z, 4) > max_groups[2])
    throw Error("the grid image needs more workgroups than maxComputeWorkGroupCount on " + dev.name +
                ": use fewer cells or a smaller capacity, or --backend cpu");
  const auto t0 = std::chrono::steady_clock::now();
  Timestamps* stamps = gpu.build_timestamps.get();
  Timestamps* passes = stamps ? gpu.build_pass_timestamps.get() : nullptr;
  ctx.submit([&](VkCommandBuffer cb) {
    if (passes) passes->reset(cb);
    if (stamps) stamps->reset(cb), stamps->write(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    vkCmdFillBuffer(cb, gpu.dirty.buffer, 0, VK_WHOLE_SIZE, 0u);  // the dirty-cell list empty
    vkCmdFillBuffer(cb, gpu.build_list.buffer, 0, sizeof(shared::WorkListHeader), 0u);
    // Every slot blank, every status texel 0 (a compute pass: vkCmdClearColorImage and a pass
    // over the status texels took 5-7 times longer on the H200, docs/BENCHMARKS.md)
    gpu.init->bind(cb, set.set());
    vkCmdDispatch(cb, groups(extent.x, 4), groups(extent.y, 4), groups(extent.z, 4));
    if (gpu.compact) {
      // Every dynamic head of the region empty (the header stays), the counts and pairs zero
      if (gpu.spill_heads.size > shared::kCompactHeadsHeader * 4)
        vkCmdFillBuffer(cb, gpu.spill_heads.buffer, shared::kCompactHeadsHeader * 4, VK_WHOLE_SIZE, shared::kSpillEnd);
      vkCmdFillBuffer(cb, gpu.compact_counts.buffer, 0, VK_WHOLE_SIZE, 0u);
      vkCmdFillBuffer(cb, gpu.compact_pairs.buffer, 0, 16, 0u);
    } else {
      vkCmdFillBuffer(cb, gpu.spill_heads.buffer, 0, VK_WHOLE_SIZE, shared::kSpillEnd);  // every spill list empty
    }
    barrier(cb);
    if (stamps) stamps->write(cb, 1);
    insert_instances(cb, 0, static_instances_);
    barrier(cb);
    if (passes) passes->write(cb, 0);
    // The static references' spill count (what the update's clear pass resets the counter to),
    // then their spill lists in order
    const VkBufferCopy count_to_static{offsetof(shared::SpillHeader, count), offsetof(shared::SpillHeader, static_count),
                                       sizeof(uint32_t)};
    vkCmdCopyBuffer(cb, gpu.spill.buffer, gpu.spill.buffer, 1, &count_to_static);
    barrier(cb);
    record_spill_order(cb, false);
    if (passes) passes->write(cb, 1);
    record_compact(cb, passes);
    if (stamps) stamps->write(cb, 2);
    record_skip_field(cb, passes);
    if (stamps) stamps->write(cb, 3);
    insert_instances(cb, static_instances_, instance_count);
    barrier(cb);
    record_spill_order(cb, true);
    if (stamps) stamps->write(cb, 4, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  });
  // The compact build's temporaries are the build's alone: its pair count checked, then 16-byte
  // stand-ins keep the bindings valid
  if (gpu.compact) {
    uint32_t pairs = 0;
    ctx.download(gpu.compact_pairs, &pairs, sizeof pairs);
    if (pairs != gpu.compact_pair_capacity)
      throw Error("vulkan-grid: the compact build counted " + std::to_string(pairs) + " static references, the plan " +
                  std::to_string(gpu.compact_pair_capacity));
    gpu.compact_counts = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    gpu.compact_pairs = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    gpu.compact_scattered = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    gpu.compact_blocks = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    set.bind(shared::kGridBindCompactCounts, gpu.compact_counts);
    set.bind(shared::kGridBindCompactPairs, gpu.compact_pairs);
    set.bind(shared::kGridBindCompactScattered, gpu.compact_scattered);
    set.bind(shared::kGridBindCompactBlocks, gpu.compact_blocks);
  }
  // The table is the build's alone: a 16-byte stand-in keeps the binding valid
  if (gpu.skip_field) {
    gpu.skip_table = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    set.bind(shared::kGridBindSkipTable, gpu.skip_table);
  }
  timings_.build_host_ms = ms_since(t0);
  if (stamps) {
    const std::vector<double> ns = stamps->read_ns();
    timings_.build_ms = (ns[4] - ns[0]) * 1e-6;
    timings_.build_init_ms = (ns[1] - ns[0]) * 1e-6;
    timings_.build_static_ms = (ns[2] - ns[1]) * 1e-6;
    timings_.build_skip_ms = (ns[3] - ns[2]) * 1e-6;
    timings_.build_dynamic_ms = (ns[4] - ns[3]) * 1e-6;
    if (passes) {
      // passes: [0] after the insert pass, [1] after the spill order, [2, 7) the compact layout's,
      // [7] the skip field's fill, [8, 13) its passes
      const std::vector<double> p = passes->read_ns();
      for (uint32_t k = 0; k < 7; ++k) timings_.build_static_passes_ms[k] = (p[k] - (k == 0 ? ns[1] : p[k - 1])) * 1e-6;
      for (uint32_t k = 0; k < 6; ++k) timings_.build_skip_passes_ms[k] = (p[7 + k] - (k == 0 ? ns[2] : p[6 + k])) * 1e-6;
    }
  }
}

// The spill list's order pass over the static entries (after the static pass) or the dynamic ones,
// one invocation per entry the list can hold (those past the stored count return at once), then a
// barrier. Nothing without the spill list.
void VulkanGridTracer::record_spill_order(VkCommandBuffer cb, bool dynamic) {
  Gpu& gpu = *gpu_;
  if (!gpu.order) return;
  gpu.order->bind(cb, gpu.set->set());
  gpu.order->push(cb, shared::SpillOrderPush{uint32_t(dynamic)});
  vkCmdDispatch(cb, groups(gpu.spill_capacity, 64), 1, 1);  // within maxComputeWorkGroupCount: checked at build
  barrier(cb);
}

// The compact layout's passes after the static count (compact.comp): block sums, the blocks' scan,
// offsets and cursors, scatter, order; barriers between. Nothing without the compact layout.
void VulkanGridTracer::record_compact(VkCommandBuffer cb, Timestamps* stamps) {
  Gpu& gpu = *gpu_;
  if (!gpu.compact) {
    if (stamps)
      for (uint32_t k = 2; k < 7; ++k) stamps->write(cb, k);  // every query written (read_ns waits for each)
    return;
  }
  // Workgroups of kCompactScanLanes: a lane per cell (passes 0 and 2), one workgroup (pass 1), a
  // lane per pair (passes 3 and 4); within maxComputeWorkGroupCount (checked by create_resources)
  const uint32_t cells = shared::grid_cell_count(params_);
  const uint32_t items[5] = {cells, shared::kCompactScanLanes, cells, gpu.compact_pair_capacity,
                             gpu.compact_pair_capacity};
  gpu.compact->bind(cb, gpu.set->set());
  for (uint32_t pass = 0; pass < 5; ++pass) {
    gpu.compact->push(cb, shared::CompactPush{pass});
    vkCmdDispatch(cb, groups(items[pass], shared::kCompactScanLanes), 1, 1);
    barrier(cb);
    if (stamps) stamps->write(cb, 2 + pass);
  }
}

// The skip field's passes (skip_field.comp) over the static references: the table zeroed, its
// three line passes (along z, y, x), the bricks' distances, the cells'; barriers between. Nothing without kGridSkipEmpty.
void VulkanGridTracer::record_skip_field(VkCommandBuffer cb, Timestamps* stamps) {
  Gpu& gpu = *gpu_;
  if (!gpu.skip_field) {
    if (stamps)
      for (uint32_t k = 7; k < 13; ++k) stamps->write(cb, k);  // every query written (read_ns waits for each)
    return;
  }
  const GridParams& g = params_;
  const uint32_t max_x = ctx_->info().limits.maxComputeWorkGroupCount[0];
  vkCmdFillBuffer(cb, gpu.skip_table.buffer, 0, VK_WHOLE_SIZE, 0u);
  barrier(cb);
  if (stamps) stamps->write(cb, 7);
  gpu.skip_field->bind(cb, gpu.set->set());
  const glm::uvec3 n = g.cells;
  // The table's passes along z, y, x: a workgroup of 64 lanes per 16 lines along z and y, per line
  // along x (skip_field.comp's skip_lines); then a lane per brick, per cell
  const auto lanes = [](uint32_t lines, uint32_t per_group) { return (lines + per_group - 1u) / per_group * 64u; };
  const uint32_t items[5] = {lanes(n.x * n.y, 16u), lanes(n.x * n.z, 16u), lanes(n.y * n.z, 1u),
                             shared::skip_brick_count(g), shared::grid_cell_count(g)};
  for (uint32_t pass = 0; pass < 5; ++pass) {
    gpu.skip_field->push(cb, shared::SkipFieldPush{pass});
    const glm::uvec3 grid = shared::work_list_groups(items[pass], 64u, max_x);
    vkCmdDispatch(cb, grid.x, grid.y, 1);
    barrier(cb);
    if (stamps) stamps->write(cb, 8 + pass);
  }
}

void VulkanGridTracer::after_insert(bool warn) {
  ctx_->download(gpu_->spill, &spill_header_, sizeof spill_header_);
  // Gap-fill only while some cell is saturated (the trace pipeline follows the flags)
  params_.flags = plan::trace_flags(requested_flags_, options_, spill_header_.count);
  plan::SpillDump d;
  d.on = (params_.flags & shared::kGridSpill) != 0u;
  d.header = spill_header_;
  if (warn) plan::warn_spill_overflow(d, name(), overflow_warned_);
  // llvmpipe's loop limit: a cell listing kLlvmpipeSpillListLimit entries or more (the lists' cells
  // read back only where the whole list is that long)
  if (ctx_->info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE && d.on && d.stored() >= kLlvmpipeSpillListLimit) {
    const std::vector<shared::SpillEntry> entries =
        ctx_->download<shared::SpillEntry>(gpu_->spill, d.stored(), sizeof(shared::SpillHeader));
    std::unordered_map<uint32_t, uint32_t> per_cell;
    uint32_t most = 0;
    for (const shared::SpillEntry& e : entries) most = std::max(most, ++per_cell[e.cell]);
    if (most >= kLlvmpipeSpillListLimit)
      throw Error("vulkan-grid: a cell's spill list holds " + std::to_string(most) +
                  " references; llvmpipe (a CPU Vulkan driver) ends a shader's loops after 65,535 iterations in all, "
                  "which cuts the list's order pass and walk short (refused from " +
                  std::to_string(kLlvmpipeSpillListLimit) + "): run on a GPU, or with --backend cpu");
  }
}

const Pipeline& VulkanGridTracer::trace_pipeline(bool explain, bool list, uint32_t mode, uint32_t rays) {
  Gpu& gpu = *gpu_;
  const uint64_t key = uint64_t(rays) << 40 | uint64_t(mode) << 34 | uint64_t(list) << 33 |
                       uint64_t(explain) << 32 | params_.flags;
  std::unique_ptr<Pipeline>& p = gpu.traces[key];
  if (!p) {
    SpecConstants spec = spec_for(params_, explain);
    if (list) spec.add(shared::kGridSpecTraceList, true);
    spec.add(shared::kGridSpecTraceMode, mode);
    if (rays != shared::kTraceRaysBuffer) spec.add(shared::kGridSpecTraceRays, rays);
    // (not the explain pipeline's: its loops count otherwise, and an explained ray of 20,000 tests
    // ran whole; docs/VULKAN.md)
    if (!explain && ctx_->info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE) spec.add(shared::kGridSpecLoopGuard, true);
    p = std::make_unique<Pipeline>(*ctx_, "trace.comp", gpu.set->layout(), uint32_t(sizeof(shared::TracePush)), std::move(spec));
  }
  return *p;
}

// Insert the triangles of instances [first, last): the raster pass (one draw per instance,
// firstInstance = its id) or the compute build (one invocation per triangle), then, in both, one
// invocation per run of kBuildRun cells of the long AABB ranges those appended to the build list
// (build.glsl: no invocation walks a long range alone, which lavapipe cuts short, docs/VULKAN.md).
void VulkanGridTracer::insert_instances(VkCommandBuffer cb, uint32_t first, uint32_t last, Timestamps* stamps,
                                        uint32_t stamp) {
  if (first >= last) return;
  Gpu& gpu = *gpu_;
  const uint32_t max_groups_x = ctx_->info().limits.maxComputeWorkGroupCount[0];
  if (vk_.build == BuildMode::raster) {
    gpu.raster->begin_pass(cb);
    gpu.raster->bind(cb, gpu.set->set());
    for (uint32_t i = first; i < last; ++i)
      if (instances_[i].tri_count) vkCmdDraw(cb, 3 * instances_[i].tri_count, 1, 0, i);
    gpu.raster->end_pass(cb);
    barrier(cb);
    const shared::WorkListDispatchPush list_push{64u, max_groups_x, gpu.build_list_capacity};
    gpu.build_list_dispatch->bind(cb, gpu.build_list_set->set());
    gpu.build_list_dispatch->push(cb, list_push);
    vkCmdDispatch(cb, 1, 1, 1);
  } else {
    // In chunks of at most maxComputeWorkGroupCount workgroups, at least one workgroup (the last
    // workgroup of all, counted across the chunks, is the build list's dispatch step)
    const uint32_t begin = instances_[first].tri_offset;
    const uint32_t end = instances_[last - 1].tri_offset + instances_[last - 1].tri_count;
    const uint32_t chunk = max_groups_x * 64u;
    const uint32_t total_groups = std::max(groups(end - begin, 64), 1u);
    gpu.compute->bind(cb, gpu.set->set());
    uint32_t t = begin;
    do {
      const uint32_t count = std::min(chunk, end - t);
      const shared::BuildPush push{first, last, t, count, total_groups, max_groups_x, 0u, 0u};
      gpu.compute->push(cb, push);
      vkCmdDispatch(cb, std::max(groups(count, 64), 1u), 1, 1);
      t += count;
    } while (t < end);
  }
  barrier(cb);
  if (stamps) stamps->write(cb, stamp);
  gpu.build_cells->bind(cb, gpu.set->set());
  vkCmdDispatchIndirect(cb, gpu.build_list.buffer, 0);
}

// ---- Scene update (paper 2.2) ----

void VulkanGridTracer::upload_transforms(float time, uint32_t first, uint32_t last) {
  for (uint32_t i = first; i < last; ++i)
    build_instances_[i].transform = shared::to_affine(scene_->instances[i].transform_at(time));
  if (first < last)
    ctx_->upload(gpu_->build_instances, &build_instances_[first], (last - first) * sizeof(shared::BuildInstance),
                 first * sizeof(shared::BuildInstance));
}

void VulkanGridTracer::update_to(float time) {
  if (static_instances_ == uint32_t(scene_->instances.size())) return;
  update_insert(time);
  // The spill list's forecast fell short at this time: grow it and insert again (plan::spill_growth)
  if (const uint32_t grown = plan::spill_growth(spill_header_, options_, requested_flags_)) {
    grow_spill(grown);
    update_insert(time);
  }
  plan::SpillDump d;
  d.on = (params_.flags & shared::kGridSpill) != 0u;
  d.header = spill_header_;
  plan::warn_spill_overflow(d, name(), overflow_warned_);
}

void VulkanGridTracer::grow_spill(uint32_t capacity) {
  Context& ctx = *ctx_;
  Gpu& gpu = *gpu_;
  if (uint64_t(capacity) > uint64_t(ctx.info().limits.maxComputeWorkGroupCount[0]) * 64u)
    throw Error("a spill list of " + std::to_string(capacity) + " entries needs more workgroups than "
                "maxComputeWorkGroupCount on " + ctx.info().name + ": set a smaller --spill-capacity");
  Buffer grown = ctx.create_buffer(sizeof(shared::SpillHeader) + VkDeviceSize(capacity) * sizeof(shared::SpillEntry),
                                   VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  // The header and the static entries (the first static_count: the dynamic ones are inserted again)
  const VkDeviceSize kept = sizeof(shared::SpillHeader) +
                            VkDeviceSize(std::min(spill_header_.static_count, spill_header_.capacity)) *
                                sizeof(shared::SpillEntry);
  ctx.submit([&](VkCommandBuffer cb) {
    const VkBufferCopy copy{0, 0, kept};
    vkCmdCopyBuffer(cb, gpu.spill.buffer, grown.buffer, 1, &copy);
  });
  spill_header_.capacity = capacity;
  ctx.upload(grown, &spill_header_.capacity, sizeof(uint32_t), offsetof(shared::SpillHeader, capacity));
  gpu.spill = std::move(grown);
  gpu.spill_capacity = capacity;
  gpu.set->bind(shared::kGridBindSpill, gpu.spill);
}

void VulkanGridTracer::check_build_ranges(const Scene& scene, float time, uint32_t first) const {
  if (ctx_->info().driver_id != VK_DRIVER_ID_MESA_LLVMPIPE) return;
  uint64_t most = 0, runs = 0;
  for (size_t i = first; i < scene.instances.size(); ++i)
    plan::for_each_placed_triangle(scene, i, time, params_, [&](const plan::PlacedTriangle& p) {
      const glm::uvec3 k = p.hi - p.lo + 1u;
      const uint64_t cells = uint64_t(k.x) * k.y * k.z;
      most = std::max(most, cells);
      if (cells > kBuildRunCells) runs += (cells + kBuildRunCells - 1) / kBuildRunCells;
    });
  // Past a full run list a triangle walks the rest of its range itself, 4 to 7 iterations a cell
  // (a review's find: 33 triangles of 64^3 cells filled the 2^20 runs, the 33rd's walk was cut)
  const bool compact = (params_.flags & shared::kGridCompact) != 0u;
  const uint64_t walk_limit = llvmpipe_walk_cell_limit(params_.capacity, compact);
  if (gpu_ && runs > gpu_->build_list_capacity && most > walk_limit)
    throw Error("vulkan-grid: the triangles' AABB ranges list " + std::to_string(runs) + " runs of " +
                std::to_string(kBuildRunCells) + " cells, more than the build's run list holds (" +
                std::to_string(gpu_->build_list_capacity) + "), and one holds " + std::to_string(most) +
                " cells: llvmpipe (a CPU Vulkan driver) ends a shader's loops after 65,535 iterations in all, which "
                "cuts the walk of a range past the list short (refused above " + std::to_string(walk_limit) +
                " cells" + (compact ? std::string() : " at " + std::to_string(params_.capacity) + " slots a cell") +
                "): its grid cannot be trusted (coarser cells, run on a GPU, or --backend cpu)");
  if (most > kLlvmpipeRangeCellLimit)
    throw Error("vulkan-grid: a triangle's AABB range holds " + std::to_string(most) +
                " cells; llvmpipe (a CPU Vulkan driver) ends a shader's loops after 65,535 iterations in all, which cuts "
                "the build's listing of its runs short (refused above " + std::to_string(kLlvmpipeRangeCellLimit) +
                " cells): its grid cannot be trusted (coarser cells, run on a GPU, or --backend cpu)");
}

void VulkanGridTracer::update_insert(float time) {
  const uint32_t n = uint32_t(scene_->instances.size());
  check_build_ranges(*scene_, time, static_instances_);
  Gpu& gpu = *gpu_;
  upload_transforms(time, static_instances_, n);
  const GridParams& g = params_;
  if (gpu.skip_field) {
    const std::vector<uint32_t> boxes = plan::skip_box_words(*scene_, time, g);
    ctx_->upload(gpu.skip, boxes.data(), boxes.size() * sizeof(uint32_t));
  }
  const auto t0 = std::chrono::steady_clock::now();
  ctx_->submit([&](VkCommandBuffer cb) {
    if (gpu.update_timestamps) gpu.update_timestamps->reset(cb), gpu.update_timestamps->write(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    // The spill counter back to the static references' count: the dynamic entries are dropped
    const VkBufferCopy static_to_count{offsetof(shared::SpillHeader, static_count), offsetof(shared::SpillHeader, count),
                                       sizeof(uint32_t)};
    vkCmdCopyBuffer(cb, gpu.spill.buffer, gpu.spill.buffer, 1, &static_to_count);
    if (gpu.compact) {
      // clear_dynamic_spill: every dynamic head of the region empty (the header stays)
      if (gpu.spill_heads.size > shared::kCompactHeadsHeader * 4) vkCmdFillBuffer(cb, gpu.spill_heads.buffer, shared::kCompactHeadsHeader * 4, VK_WHOLE_SIZE, shared::kSpillEnd);
      barrier(cb);
    } else {
      // Clear the dynamic references of the cells on the dirty-cell list, a workgroup per cell
      const shared::WorkListDispatchPush dispatch_push{1u, ctx_->info().limits.maxComputeWorkGroupCount[0],
                                                       shared::grid_cell_count(g)};
      gpu.dirty_dispatch->bind(cb, gpu.dirty_set->set());
      gpu.dirty_dispatch->push(cb, dispatch_push);
      vkCmdDispatch(cb, 1, 1, 1);
      barrier(cb);
      gpu.clear->bind(cb, gpu.set->set());
      gpu.clear->push(cb, shared::ClearPush{g.comparison_offset});
      vkCmdDispatchIndirect(cb, gpu.dirty.buffer, 0);
      barrier(cb);
    }
    if (gpu.update_timestamps) gpu.update_timestamps->write(cb, 1, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
    // Insert the dynamic instances at their new transforms (the triangles, then the runs of the
    // long ranges), then order their spill lists
    insert_instances(cb, static_instances_, n, gpu.update_timestamps.get(), 2);
    barrier(cb);
    if (gpu.update_timestamps) gpu.update_timestamps->write(cb, 3, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
    record_spill_order(cb, true);
    if (gpu.update_timestamps) gpu.update_timestamps->write(cb, 4, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  });
  timings_.update_host_ms = ms_since(t0);
  after_insert(false);
  if (gpu.update_timestamps) {
    const std::vector<double> ns = gpu.update_timestamps->read_ns();
    timings_.update_ms = (ns[4] - ns[0]) * 1e-6;
    timings_.clear_ms = (ns[1] - ns[0]) * 1e-6;
    timings_.insert_ms = (ns[4] - ns[1]) * 1e-6;
    timings_.insert_triangles_ms = (ns[2] - ns[1]) * 1e-6;
    timings_.insert_runs_ms = (ns[3] - ns[2]) * 1e-6;
    timings_.order_ms = (ns[4] - ns[3]) * 1e-6;
  }
}

// ---- Scene trace (paper 2.3) ----

void check_loop_limit(const Context& ctx, const shared::GridParams& g, std::span<const Hit> hits, const char* what) {
  if (ctx.info().driver_id != VK_DRIVER_ID_MESA_LLVMPIPE) return;
  uint64_t most = 0;
  const Hit* worst = nullptr;
  for (const Hit& h : hits) {
    // The trace's own flag: its estimate with the references the mailbox skipped (kHitLoopSpent)
    const uint64_t e = (h.flags & kHitLoopSpent) != 0u ? kLlvmpipeLoopBudget : llvmpipe_loop_estimate(g, h.tests, h.cells);
    if (e > most || !worst) most = e, worst = &h;
    if ((h.flags & kHitLoopSpent) != 0u) break;
  }
  if (most < kLlvmpipeLoopBudget) return;
  const bool skipped = (worst->flags & kHitLoopSpent) != 0u && (g.flags & shared::kGridMailbox) != 0u;
  // The estimate itself and its weights (the tests and cells alone did not say why 4,679 tests were
  // refused against 49,152 iterations: an outside sweep)
  const bool exact = g.traversal == shared::kTraversalExact;
  const uint32_t per_test = shared::llvmpipe_iterations_per_test((g.flags & shared::kGridCompact) != 0u,
                                                                 (g.flags & shared::kGridMailbox) != 0u);
  const std::string weights = exact ? std::to_string(per_test) + " loop iterations a test and " +
                                          std::to_string(shared::kLlvmpipeIterationsPerCell) + " a cell"
                                    : std::string("1.5 loop iterations a test or a cell");
  throw Error("vulkan-grid: " + std::string(what) + ": a ray made " + std::to_string(worst->tests) +
              " triangle tests over " + std::to_string(worst->cells) + " cells" +
              (skipped ? std::string(" (and skipped references its mailbox held)") : std::string()) +
              ((worst->flags & kHitLoopSpent) != 0u ? ", at least " : ", about ") + std::to_string(most) +
              " loop iterations (" + weights + " in this grid's trace)" +
              "; llvmpipe (a CPU Vulkan driver) ends a shader's loops after 65,535 iterations in all, "
              "which cuts this trace short (refused from an estimated " + std::to_string(kLlvmpipeLoopBudget) +
              " iterations): its hits cannot be trusted (cells holding too many overlapping triangles, or a ray "
              "through thousands of cells: run on a GPU, or with --backend cpu)");
}

void VulkanGridTracer::run_trace(std::span<const Ray> rays, std::span<Hit> hits, uint32_t explain_index,
                                 uint32_t mode) {
  if (hits.size() != rays.size()) throw Error("vulkan-grid: hits.size() != rays.size()");
  if (!scene_ || !gpu_) throw Error("vulkan-grid: trace before build");
  if (rays.empty()) return;
  Context& ctx = *ctx_;
  Gpu& gpu = *gpu_;
  // Ray and hit buffers, grown as needed
  if (grow_ray_buffers(ctx, rays.size(), gpu.rays, gpu.hits, gpu.ray_capacity)) {
    gpu.set->bind(shared::kGridBindRays, gpu.rays);
    gpu.set->bind(shared::kGridBindHits, gpu.hits);
    gpu.set->bind(shared::kGridBindRayList, gpu.no_ray_list);
    gpu.ray_list = VK_NULL_HANDLE;
    gpu.bound_ray_bytes = gpu.rays.size;
    gpu.bound_hit_bytes = gpu.hits.size;
  }
  ctx.upload(gpu.rays, rays.data(), rays.size_bytes());
  const bool explain = explain_index != shared::kNoExplain;
  const Pipeline& pipe = trace_pipeline(explain, false, mode);
  const PassTimes t = submit_ray_chunks<shared::TracePush>(ctx, pipe, gpu.set->set(), uint32_t(rays.size()),
                                                          explain_index, vk_.explain_capacity,
                                                          explain ? &gpu.explain : nullptr, kExplainHeader,
                                                          gpu.timestamps.get());
  timings_.trace_host_ms = t.host_ms;
  timings_.trace_ms = t.device_ms;
  ctx.download(gpu.hits, hits.data(), hits.size_bytes());
  if (!explain) check_loop_limit(ctx, params_, hits, "trace");
}

void VulkanGridTracer::trace_closest(std::span<const Ray> rays, std::span<Hit> hits) {
  run_trace(rays, hits, shared::kNoExplain, shared::kTraceClosestHit);
}

void VulkanGridTracer::trace_occlusion(std::span<const Ray> rays, std::span<Hit> hits) {
  run_trace(rays, hits, shared::kNoExplain, shared::kTraceAnyHit);
}

plan::ExplainRecord VulkanGridTracer::explain_ray(std::span<const Ray> rays, uint32_t index, uint32_t mode) {
  if (!built()) throw Error("vulkan-grid: explain before a build (or after a build that failed)");
  if (index >= rays.size()) throw Error("vulkan-grid: explain index out of range");
  std::vector<Hit> hits(rays.size());
  run_trace(rays, hits, index, mode);
  uint32_t count = 0;
  ctx_->download(gpu_->explain, &count, sizeof count);
  if (count > vk_.explain_capacity)
    throw Error("vulkan-grid: the explained ray left " + std::to_string(count) + " events, over the explain buffer's " +
                std::to_string(vk_.explain_capacity) + " (VulkanGridOptions::explain_capacity)");
  plan::ExplainRecord rec;
  rec.ray = rays[index];
  rec.params = params_;
  rec.mode = mode;
  rec.events = ctx_->download<shared::ExplainEvent>(gpu_->explain, count, kExplainHeader);
  rec.hit = hits[index];
  return rec;
}

// ---- Passes of other pipelines on the grid's device data (vulkan/frame.h) ----

const Buffer& VulkanGridTracer::instance_buffer() const {
  if (!gpu_) throw Error("vulkan-grid: instance_buffer before build");
  return gpu_->instances;
}

const Buffer& VulkanGridTracer::triangle_buffer() const {
  if (!gpu_) throw Error("vulkan-grid: triangle_buffer before build");
  return gpu_->triangles;
}

const Buffer& VulkanGridTracer::plane_buffer() const {
  if (!gpu_) throw Error("vulkan-grid: plane_buffer before build");
  return gpu_->planes;
}

const Buffer& VulkanGridTracer::uv_buffer() const {
  if (!gpu_) throw Error("vulkan-grid: uv_buffer before build");
  return gpu_->uvs;
}

const Buffer& VulkanGridTracer::material_buffer() const {
  if (!gpu_) throw Error("vulkan-grid: material_buffer before build");
  return gpu_->materials;
}

const Buffer& VulkanGridTracer::texel_buffer() const {
  if (!gpu_) throw Error("vulkan-grid: texel_buffer before build");
  return gpu_->texels;
}

void VulkanGridTracer::bind_ray_buffers(const Buffer& rays, const Buffer& hits, const Buffer* ray_list) {
  if (!gpu_) throw Error("vulkan-grid: bind_ray_buffers before build");
  Gpu& gpu = *gpu_;
  gpu.set->bind(shared::kGridBindRays, rays);
  gpu.set->bind(shared::kGridBindHits, hits);
  gpu.set->bind(shared::kGridBindRayList, ray_list ? *ray_list : gpu.no_ray_list);
  gpu.ray_list = ray_list ? ray_list->buffer : VK_NULL_HANDLE;
  gpu.ray_capacity = 0;  // the next trace() makes and binds its own buffers again
  gpu.bound_ray_bytes = rays.size;
  gpu.bound_hit_bytes = hits.size;
}

void VulkanGridTracer::bind_frame(const Buffer& gather, const Buffer& frame_params, const Buffer& frame_materials) {
  if (!gpu_) throw Error("vulkan-grid: bind_frame before build");
  gpu_->set->bind(shared::kGridBindGather, gather);
  gpu_->set->bind(shared::kGridBindFrameParams, frame_params);
  gpu_->set->bind(shared::kGridBindFrameMaterials, frame_materials);
  gpu_->bound_gather_bytes = gather.size;
  gpu_->bound_frame_params_bytes = frame_params.size;
}

void VulkanGridTracer::record_trace_list(VkCommandBuffer cb) {
  if (!gpu_ || !gpu_->ray_list) throw Error("vulkan-grid: record_trace_list without a bound ray list");
  const Pipeline& pipe = trace_pipeline(false, true);
  pipe.bind(cb, gpu_->set->set());
  const shared::TracePush push{0u, 0u, shared::kNoExplain, vk_.explain_capacity, 0u, 0u};
  pipe.push(cb, push);
  vkCmdDispatchIndirect(cb, gpu_->ray_list, 0);
}

void VulkanGridTracer::record_trace(VkCommandBuffer cb, uint32_t count, uint32_t first_ray, uint32_t mode) {
  if (!gpu_) throw Error("vulkan-grid: record_trace before build");
  const uint32_t chunk = ctx_->info().limits.maxComputeWorkGroupCount[0] * 64u;
  const Pipeline& pipe = trace_pipeline(false, false, mode);
  pipe.bind(cb, gpu_->set->set());
  for (uint32_t first = 0; first < count; first += std::min(chunk, count - first)) {
    const shared::TracePush push{first_ray + first, std::min(chunk, count - first), shared::kNoExplain,
                                 vk_.explain_capacity, 0u, 0u};
    pipe.push(cb, push);
    vkCmdDispatch(cb, groups(push.ray_count, 64), 1, 1);
  }
}

void VulkanGridTracer::record_trace_image(VkCommandBuffer cb, uint32_t width, uint32_t height, uint32_t first_ray,
                                          uint32_t mode) {
  if (!gpu_) throw Error("vulkan-grid: record_trace_image before build");
  const Pipeline& pipe = trace_pipeline(false, false, mode);
  pipe.bind(cb, gpu_->set->set());
  const shared::TracePush push{first_ray, width * height, shared::kNoExplain, vk_.explain_capacity, width, height};
  pipe.push(cb, push);
  vkCmdDispatch(cb, groups(width, 8), groups(height, 8), 1);
}

void VulkanGridTracer::record_frame_trace(VkCommandBuffer cb, uint32_t width, uint32_t height, uint32_t first_ray,
                                          uint32_t rays, glm::vec3 light, bool directional) {
  // What the traces read and write must be bound and large enough: a clear error, not an access
  // past a buffer on the device
  const Gpu& gpu = *gpu_;
  const uint64_t pixels = uint64_t(width) * height;
  if (gpu.bound_gather_bytes < pixels * sizeof(shared::GatherTexel) ||
      gpu.bound_frame_params_bytes < sizeof(shared::FrameParams))
    throw Error("vulkan-grid: the frame's trace of a " + std::to_string(width) + "x" + std::to_string(height) +
                " image needs bind_frame with a gather buffer of that many texels and the frame's parameters");
  if (gpu.bound_ray_bytes < (first_ray + pixels) * sizeof(shared::RayRecord) ||
      gpu.bound_hit_bytes < (first_ray + pixels) * sizeof(shared::HitRecord))
    throw Error("vulkan-grid: the frame's trace writes rays and hits " + std::to_string(first_ray) + ".." +
                std::to_string(first_ray + pixels) + ", past the bound ray or hit buffer (bind_ray_buffers)");
  const Pipeline& pipe =
      trace_pipeline(false, false, rays == shared::kTraceRaysShadow ? shared::kTraceAnyHit : shared::kTraceClosestHit, rays);
  pipe.bind(cb, gpu_->set->set());
  const shared::TracePush push{first_ray, width * height, shared::kNoExplain, vk_.explain_capacity, width, height,
                               light.x, light.y, light.z, directional ? 1u : 0u};
  pipe.push(cb, push);
  vkCmdDispatch(cb, groups(width, 8), groups(height, 8), rays == shared::kTraceRaysBoth ? 2u : 1u);
}

void VulkanGridTracer::record_bounce_trace_image(VkCommandBuffer cb, uint32_t width, uint32_t height) {
  if (!gpu_) throw Error("vulkan-grid: record_bounce_trace_image before build");
  record_frame_trace(cb, width, height, 0u, shared::kTraceRaysBounce, glm::vec3(0.0f), false);
}

void VulkanGridTracer::record_bounce_and_shadow_trace_image(VkCommandBuffer cb, uint32_t width, uint32_t height,
                                                           uint32_t first_ray, glm::vec3 light, bool directional) {
  if (!gpu_) throw Error("vulkan-grid: record_bounce_and_shadow_trace_image before build");
  record_frame_trace(cb, width, height, first_ray, shared::kTraceRaysBoth, light, directional);
}

void VulkanGridTracer::record_shadow_trace_image(VkCommandBuffer cb, uint32_t width, uint32_t height,
                                                 uint32_t first_ray, glm::vec3 light, bool directional) {
  if (!gpu_) throw Error("vulkan-grid: record_shadow_trace_image before build");
  record_frame_trace(cb, width, height, first_ray, shared::kTraceRaysShadow, light, directional);
}

AccelDump VulkanGridTracer::dump() const {
  if (!gpu_) return {};
  AccelDump d;
  if ((params_.flags & shared::kGridCompact) != 0u) {
    // The compact layout: the offsets (the index of occupied cells' runs), then the references (as many as the last offset
    // says: the buffer's one-word stand-in of a grid without any is left out), as one row
    d.kind = "grid-compact";
    d.texels = ctx_->download<uint32_t>(gpu_->offsets, gpu_->offsets.size / 4);
    const std::vector<uint32_t> refs = ctx_->download<uint32_t>(gpu_->refs, gpu_->refs.size / 4);
    d.texels.insert(d.texels.end(), refs.begin(), refs.begin() + std::min<size_t>(refs.size(), d.texels.back()));
    d.extent = glm::uvec3(uint32_t(d.texels.size()), 1u, 1u);
    return d;
  }
  d.kind = "grid";
  d.extent = gpu_->image.extent;
  d.texels = ctx_->download(gpu_->image);
  return d;
}

uint32_t VulkanGridTracer::download_build_runs() const {
  if (!gpu_) return 0;
  return ctx_->download<shared::WorkListHeader>(gpu_->build_list, 1)[0].dispatched;
}

std::vector<uint32_t> VulkanGridTracer::download_dirty_cells() const {
  if (!gpu_) return {};
  const shared::WorkListHeader header = ctx_->download<shared::WorkListHeader>(gpu_->dirty, 1)[0];
  return ctx_->download<uint32_t>(gpu_->dirty, header.appended, sizeof(shared::WorkListHeader));
}

std::vector<uint32_t> VulkanGridTracer::download_skip() const {
  if (!gpu_ || (params_.flags & shared::kGridSkipEmpty) == 0u) return {};
  return ctx_->download<uint32_t>(gpu_->skip, shared::skip_words(params_));
}

plan::SpillDump VulkanGridTracer::spill() const {
  if (!gpu_) return {};
  plan::SpillDump d;
  d.on = (params_.flags & shared::kGridSpill) != 0u;
  ctx_->download(gpu_->spill, &d.header, sizeof d.header);
  d.entries = ctx_->download<shared::SpillEntry>(gpu_->spill, d.stored(), sizeof(shared::SpillHeader));
  if (d.on) d.heads = ctx_->download<uint32_t>(gpu_->spill_heads, gpu_->spill_heads.size / sizeof(uint32_t));
  if (d.on && (params_.flags & shared::kGridCompact) != 0u) d.heads = plan::expand_compact_heads(d.heads, params_.cells);
  return d;
}

plan::GridMemory VulkanGridTracer::memory() const {
  plan::GridMemory m;
  if (!gpu_) return m;
  const Gpu& gpu = *gpu_;
  const bool compact = (params_.flags & shared::kGridCompact) != 0u;
  const glm::uvec3 e = gpu.image.extent;
  m.image = uint64_t(e.x) * e.y * e.z * 4;
  if (compact) m.offsets = gpu.offsets.size, m.refs = gpu.refs.size;
  m.spill = gpu.spill.size;
  m.heads = (params_.flags & shared::kGridSpill) != 0u ? gpu.spill_heads.size : 0;
  m.skip = (params_.flags & shared::kGridSkipEmpty) != 0u ? gpu.skip.size : 0;
  m.dirty = gpu.dirty.size;
  return m;
}

std::vector<shared::GridTriangle> VulkanGridTracer::download_triangles() const {
  if (!gpu_) return {};
  const uint32_t n = instances_.empty() ? 0 : instances_.back().tri_offset + instances_.back().tri_count;
  return ctx_->download<shared::GridTriangle>(gpu_->triangles, n);
}

std::vector<shared::GridPlane> VulkanGridTracer::download_planes() const {
  if (!gpu_) return {};
  const uint32_t n = instances_.empty() ? 0 : instances_.back().tri_offset + instances_.back().tri_count;
  return ctx_->download<shared::GridPlane>(gpu_->planes, n);
}

}  // namespace gridrt::vulkan
