// rtx.cpp: VulkanRtxTracer, the device's ray tracing pipeline side by side with the grid (see
// rtx.h): the acceleration structures over the grid's geometry buffer, the pipeline and its
// shader binding table, the per-frame update and trace.
#include "gridrt/vulkan/rtx.h"
#include "gridrt/common/util.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <type_traits>

#include "gridrt/vulkan/pipeline.h"
#include "gridrt/vulkan/shaders/rtx_input.h"

namespace gridrt::vulkan {

using shared::RtxPush;

namespace {

// The descriptor set's bindings: rtx_input.h.

// The shader groups, in the order of the pipeline and the shader binding table.
enum RtxGroup : uint32_t { kGroupRaygen = 0, kGroupMiss = 1, kGroupHit = 2, kGroupCount = 3 };

constexpr VkShaderStageFlags kRtStages = VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_MISS_BIT_KHR |
                                         VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR | VK_SHADER_STAGE_ANY_HIT_BIT_KHR;
constexpr VkDeviceSize kAccelAlignment = 256;  // VkAccelerationStructureCreateInfoKHR::offset

// The extension's entry points, fetched from the device (the loader's table has core ones only).
struct Functions {
  PFN_vkGetBufferDeviceAddress get_buffer_address = nullptr;
  PFN_vkCreateAccelerationStructureKHR create_as = nullptr;
  PFN_vkDestroyAccelerationStructureKHR destroy_as = nullptr;
  PFN_vkGetAccelerationStructureBuildSizesKHR build_sizes = nullptr;
  PFN_vkCmdBuildAccelerationStructuresKHR cmd_build = nullptr;
  PFN_vkGetAccelerationStructureDeviceAddressKHR as_address = nullptr;
  PFN_vkCreateRayTracingPipelinesKHR create_pipelines = nullptr;
  PFN_vkGetRayTracingShaderGroupHandlesKHR group_handles = nullptr;
  PFN_vkCmdTraceRaysKHR trace_rays = nullptr;

  void load(VkDevice device) {
    std::string missing;
    auto get = [&](auto& fn, const char* name) {
      fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(vkGetDeviceProcAddr(device, name));
      if (!fn) missing += std::string(missing.empty() ? "" : ", ") + name;
    };
    get(get_buffer_address, "vkGetBufferDeviceAddress");
    get(create_as, "vkCreateAccelerationStructureKHR");
    get(destroy_as, "vkDestroyAccelerationStructureKHR");
    get(build_sizes, "vkGetAccelerationStructureBuildSizesKHR");
    get(cmd_build, "vkCmdBuildAccelerationStructuresKHR");
    get(as_address, "vkGetAccelerationStructureDeviceAddressKHR");
    get(create_pipelines, "vkCreateRayTracingPipelinesKHR");
    get(group_handles, "vkGetRayTracingShaderGroupHandlesKHR");
    get(trace_rays, "vkCmdTraceRaysKHR");
    if (!missing.empty()) throw Error("the ray tracing side by side: the device lacks " + missing);
  }
};

VkDeviceSize align_up(VkDeviceSize x, VkDeviceSize a) { return (x + a - 1) / a * a; }

// One acceleration structure: where it lives in its storage buffer and what building it needs.
struct Accel {
  VkAccelerationStructureKHR handle = VK_NULL_HANDLE;
  uint32_t instance = 0;           // the scene instance (BLAS)
  uint32_t primitives = 0;         // triangles (BLAS) or instances (TLAS)
  bool dynamic = false;            // refitted or rebuilt each frame
  VkAccelerationStructureGeometryKHR geometry{};
  VkAccelerationStructureBuildSizesInfoKHR sizes{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
  VkBuildAccelerationStructureFlagsKHR flags = 0;
  VkDeviceSize offset = 0;          // in its storage buffer
  VkDeviceSize scratch_offset = 0;  // in its scratch buffer
  VkDeviceAddress address = 0;      // vkGetAccelerationStructureDeviceAddressKHR
};

}  // namespace

struct VulkanRtxTracer::Gpu {
  Context* ctx = nullptr;
  Functions fn;
  VkPhysicalDeviceRayTracingPipelinePropertiesKHR rt{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR};
  VkPhysicalDeviceAccelerationStructurePropertiesKHR as{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR};
  std::vector<Accel> blas;  // one per scene instance with triangles: static ones first
  Accel tlas;
  Buffer static_storage, dynamic_storage, tlas_storage, instances, scratch, sbt;
  Buffer rays, hits;  // the host path's
  size_t ray_capacity = 0;
  VkBuffer bound_rays = VK_NULL_HANDLE, bound_hits = VK_NULL_HANDLE;
  std::unique_ptr<Descriptors> set;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkPipeline pipeline = VK_NULL_HANDLE;
  std::vector<VkShaderModule> modules;
  VkStridedDeviceAddressRegionKHR raygen{}, miss{}, hit{}, callable{};
  std::unique_ptr<Timestamps> timestamps;  // begin, after the BLASes, after the TLAS, after the trace
  RtxPush push{};

  ~Gpu() {
    const VkDevice d = ctx->device();
    if (pipeline) vkDestroyPipeline(d, pipeline, nullptr);
    if (layout) vkDestroyPipelineLayout(d, layout, nullptr);
    for (VkShaderModule m : modules) vkDestroyShaderModule(d, m, nullptr);
    for (Accel& a : blas)
      if (a.handle) fn.destroy_as(d, a.handle, nullptr);
    if (tlas.handle) fn.destroy_as(d, tlas.handle, nullptr);
  }

  VkDeviceAddress address(const Buffer& b) const {
    VkBufferDeviceAddressInfo info{VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
    info.buffer = b.buffer;
    return fn.get_buffer_address(ctx->device(), &info);
  }

  VkShaderModule module(std::string_view name) {
    const VkShaderModule m = create_shader_module(*ctx, name);
    modules.push_back(m);
    return m;
  }

  // The build info of `a` in `mode` (UPDATE: from itself), its scratch at `scratch_base`.
  VkAccelerationStructureBuildGeometryInfoKHR build_info(Accel& a, VkAccelerationStructureTypeKHR type,
                                                         VkBuildAccelerationStructureModeKHR mode,
                                                         VkDeviceAddress scratch_base) const {
    VkAccelerationStructureBuildGeometryInfoKHR bi{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
    bi.type = type;
    bi.flags = a.flags;
    bi.mode = mode;
    bi.srcAccelerationStructure = mode == VK_BUILD_ACCELERATION_STRUCTURE_MODE_UPDATE_KHR ? a.handle : VK_NULL_HANDLE;
    bi.dstAccelerationStructure = a.handle;
    bi.geometryCount = 1;
    bi.pGeometries = &a.geometry;
    bi.scratchData.deviceAddress = scratch_base + a.scratch_offset;
    return bi;
  }

  // Records the builds (or updates) of `list` in one command.
  void record_builds(VkCommandBuffer cb, std::vector<Accel*> list, VkAccelerationStructureTypeKHR type,
                     VkBuildAccelerationStructureModeKHR mode, VkDeviceAddress scratch_base) {
    if (list.empty()) return;
    std::vector<VkAccelerationStructureBuildGeometryInfoKHR> infos;
    std::vector<VkAccelerationStructureBuildRangeInfoKHR> ranges;
    std::vector<const VkAccelerationStructureBuildRangeInfoKHR*> range_ptrs;
    infos.reserve(list.size());
    ranges.reserve(list.size());
    for (Accel* a : list) {
      infos.push_back(build_info(*a, type, mode, scratch_base));
      ranges.push_back({a->primitives, 0, 0, 0});
    }
    for (const auto& r : ranges) range_ptrs.push_back(&r);
    fn.cmd_build(cb, uint32_t(infos.size()), infos.data(), range_ptrs.data());
  }
};

std::string rtx_unsupported(const Context& ctx) {
  const DeviceInfo& info = ctx.info();
  if (!info.ray_tracing_missing.empty())
    return "the ray tracing side by side needs VK_KHR_ray_tracing_pipeline and VK_KHR_acceleration_structure: " +
           info.name + ", driver " + info.driver + ", lacks " + info.ray_tracing_missing +
           "; run without it (no --rtx), or on a device with ray tracing";
  if (!ctx.ray_tracing())
    return info.name + " has ray tracing, but this Vulkan context was made without it (ContextOptions::ray_tracing)";
  return "";
}

VulkanRtxTracer::VulkanRtxTracer(VulkanGridTracer& grid, RtxOptions options)
    : grid_(grid), ctx_(grid.context()), options_(options) {
  if (const std::string why = rtx_unsupported(ctx_); !why.empty()) throw Error(why);
  Context& ctx = ctx_;
  const VkDevice d = ctx.device();
  gpu_ = std::make_unique<Gpu>();
  Gpu& gpu = *gpu_;
  gpu.ctx = &ctx;
  gpu.fn.load(d);
  gpu.as.pNext = nullptr;
  gpu.rt.pNext = &gpu.as;
  VkPhysicalDeviceProperties2 props{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props.pNext = &gpu.rt;
  vkGetPhysicalDeviceProperties2(ctx.physical_device(), &props);
  const shared::GridParams& params = grid.params();
  const std::vector<shared::GridInstance>& instances = grid.instances();
  if (instances.size() > (1u << 24))
    throw Error("the ray tracing side by side: more scene instances than instanceCustomIndex holds (2^24)");
  const bool alpha = (params.flags & shared::kGridAlphaKeying) != 0u;

  describe_blases(alpha);
  const VkDeviceSize scratch_align = std::max<VkDeviceSize>(gpu.as.minAccelerationStructureScratchOffsetAlignment, 16);
  const Buffer first_scratch = create_structures(scratch_align);
  first_build(first_scratch, scratch_align);
  create_pipeline();

  // What the shaders honour of the grid's options
  gpu.push.mode = ((params.flags & shared::kGridExcludeLaunchRef) ? shared::kRtxExcludeLaunchRef : 0u) |
                  (alpha ? shared::kRtxAlphaKeying : 0u) | (options_.any_hit_all ? shared::kRtxAnyHitAll : 0u);
  gpu.push.cell_size = params.cell_size;
  gpu.push.self_hit_offset = params.self_hit_offset;
}

// The BLASes' geometry: each instance's triangles of the geometry buffer, 3 vertices of 16 bytes
// per GridTriangle (v0, material; v1, pad; v2, pad), opaque unless alpha-keyed (with `alpha`).
void VulkanRtxTracer::describe_blases(bool alpha) {
  Gpu& gpu = *gpu_;
  const std::vector<shared::GridInstance>& instances = grid_.instances();
  const VkDeviceAddress triangles = gpu.address(grid_.triangle_buffer());
  for (uint32_t i = 0; i < instances.size(); ++i) {
    const shared::GridInstance& inst = instances[i];
    if (inst.tri_count == 0) continue;
    Accel a;
    a.instance = i;
    a.primitives = inst.tri_count;
    a.dynamic = i >= grid_.static_instance_count();
    a.geometry = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
    a.geometry.geometryType = VK_GEOMETRY_TYPE_TRIANGLES_KHR;
    a.geometry.flags = alpha && (inst.flags & shared::kInstanceAlphaKeyed) ? VkGeometryFlagsKHR(0)
                                                                           : VkGeometryFlagsKHR(VK_GEOMETRY_OPAQUE_BIT_KHR);
    VkAccelerationStructureGeometryTrianglesDataKHR& t = a.geometry.geometry.triangles;
    t = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR};
    t.vertexFormat = VK_FORMAT_R32G32B32_SFLOAT;
    t.vertexData.deviceAddress = triangles + VkDeviceAddress(inst.tri_offset) * sizeof(shared::GridTriangle);
    t.vertexStride = sizeof(shared::GridTriangle) / 3;
    t.maxVertex = 3 * inst.tri_count - 1;
    t.indexType = VK_INDEX_TYPE_NONE_KHR;
    a.flags = !a.dynamic                 ? VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR
              : options_.rebuild_dynamic ? VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_BUILD_BIT_KHR
                                         : VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR |
                                               VK_BUILD_ACCELERATION_STRUCTURE_ALLOW_UPDATE_BIT_KHR;
    gpu.blas.push_back(a);
  }
}

// Sizes, storage and scratch: static BLASes in one buffer (their scratch only for the first
// build, returned), dynamic BLASes in another, the TLAS in a third; the per-frame scratch holds
// the dynamic BLASes' and the TLAS's side by side. Then the structures, and the TLAS's instances.
Buffer VulkanRtxTracer::create_structures(VkDeviceSize scratch_align) {
  Context& ctx = ctx_;
  const VkDevice d = ctx.device();
  Gpu& gpu = *gpu_;
  VkDeviceSize static_bytes = 0, dynamic_bytes = 0, static_scratch = 0, frame_scratch = 0;
  for (Accel& a : gpu.blas) {
    VkAccelerationStructureBuildGeometryInfoKHR bi =
        gpu.build_info(a, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR, VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR, 0);
    gpu.fn.build_sizes(d, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &bi, &a.primitives, &a.sizes);
    VkDeviceSize& bytes = a.dynamic ? dynamic_bytes : static_bytes;
    VkDeviceSize& scratch = a.dynamic ? frame_scratch : static_scratch;
    a.offset = bytes;
    bytes = align_up(bytes + a.sizes.accelerationStructureSize, kAccelAlignment);
    a.scratch_offset = scratch;
    scratch = align_up(scratch + std::max(a.sizes.buildScratchSize, a.sizes.updateScratchSize), scratch_align);
  }
  Accel& tl = gpu.tlas;
  tl.primitives = uint32_t(gpu.blas.size());
  tl.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
  tl.geometry = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  tl.geometry.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;
  tl.geometry.geometry.instances = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR};
  {
    VkAccelerationStructureBuildGeometryInfoKHR bi =
        gpu.build_info(tl, VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR, VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR, 0);
    gpu.fn.build_sizes(d, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &bi, &tl.primitives, &tl.sizes);
    tl.scratch_offset = frame_scratch;
    frame_scratch = align_up(frame_scratch + tl.sizes.buildScratchSize, scratch_align);
  }
  const VkBufferUsageFlags storage_usage =
      VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_STORAGE_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;
  const VkBufferUsageFlags scratch_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;
  gpu.static_storage = ctx.create_buffer(std::max<VkDeviceSize>(static_bytes, 256), storage_usage);
  gpu.dynamic_storage = ctx.create_buffer(std::max<VkDeviceSize>(dynamic_bytes, 256), storage_usage);
  gpu.tlas_storage = ctx.create_buffer(tl.sizes.accelerationStructureSize, storage_usage);
  gpu.scratch = ctx.create_buffer(frame_scratch + scratch_align, scratch_usage);
  Buffer first_scratch = ctx.create_buffer(static_scratch + scratch_align, scratch_usage);
  memory_.static_blas = static_bytes;
  memory_.dynamic_blas = dynamic_bytes;
  memory_.tlas = tl.sizes.accelerationStructureSize;
  memory_.scratch = gpu.scratch.size;

  auto create = [&](Accel& a, const Buffer& storage, VkAccelerationStructureTypeKHR type) {
    VkAccelerationStructureCreateInfoKHR ci{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_CREATE_INFO_KHR};
    ci.buffer = storage.buffer;
    ci.offset = a.offset;
    ci.size = a.sizes.accelerationStructureSize;
    ci.type = type;
    GRIDRT_VK_CHECK(gpu.fn.create_as(d, &ci, nullptr, &a.handle));
    VkAccelerationStructureDeviceAddressInfoKHR ai{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_DEVICE_ADDRESS_INFO_KHR};
    ai.accelerationStructure = a.handle;
    a.address = gpu.fn.as_address(d, &ai);
  };
  for (Accel& a : gpu.blas)
    create(a, a.dynamic ? gpu.dynamic_storage : gpu.static_storage, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR);
  create(tl, gpu.tlas_storage, VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR);

  // The TLAS's instances: identity transforms, the scene instance as the custom index
  std::vector<VkAccelerationStructureInstanceKHR> tlas_instances;
  for (const Accel& a : gpu.blas) {
    VkAccelerationStructureInstanceKHR in{};
    in.transform.matrix[0][0] = in.transform.matrix[1][1] = in.transform.matrix[2][2] = 1.0f;
    in.instanceCustomIndex = a.instance;
    in.mask = 0xFF;
    in.instanceShaderBindingTableRecordOffset = 0;
    in.flags = VK_GEOMETRY_INSTANCE_TRIANGLE_FACING_CULL_DISABLE_BIT_KHR;
    in.accelerationStructureReference = a.address;
    tlas_instances.push_back(in);
  }
  gpu.instances = ctx.create_buffer(
      std::max<size_t>(tlas_instances.size() * sizeof(VkAccelerationStructureInstanceKHR), 64),
      VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT);
  ctx.upload(gpu.instances, tlas_instances.data(), tlas_instances.size() * sizeof(VkAccelerationStructureInstanceKHR));
  tl.geometry.geometry.instances.data.deviceAddress = gpu.address(gpu.instances);
  return first_scratch;
}

// The first build, timed: the static BLASes, then the dynamic ones and the TLAS.
void VulkanRtxTracer::first_build(const Buffer& first_scratch, VkDeviceSize scratch_align) {
  Context& ctx = ctx_;
  Gpu& gpu = *gpu_;
  Accel& tl = gpu.tlas;
  if (ctx.info().timestamp_valid_bits) gpu.timestamps = std::make_unique<Timestamps>(ctx, 4);
  const VkDeviceAddress first_base = align_up(gpu.address(first_scratch), scratch_align);
  const VkDeviceAddress frame_base = align_up(gpu.address(gpu.scratch), scratch_align);
  std::vector<Accel*> statics, dynamics;
  for (Accel& a : gpu.blas) (a.dynamic ? dynamics : statics).push_back(&a);
  ctx.submit([&](VkCommandBuffer cb) {
    barrier(cb);  // the grid's build wrote the geometry buffer
    if (gpu.timestamps) gpu.timestamps->reset(cb), gpu.timestamps->write(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    gpu.record_builds(cb, statics, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR,
                      VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR, first_base);
    if (gpu.timestamps) gpu.timestamps->write(cb, 1);
    gpu.record_builds(cb, dynamics, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR,
                      VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR, frame_base);
    barrier(cb);
    if (gpu.timestamps) gpu.timestamps->write(cb, 2);
    gpu.record_builds(cb, {&tl}, VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR,
                      VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR, frame_base);
    if (gpu.timestamps) gpu.timestamps->write(cb, 3);
  });
  if (gpu.timestamps) {
    const std::vector<double> ns = gpu.timestamps->read_ns();
    timings_.static_build_ms = (ns[1] - ns[0]) * 1e-6;
    timings_.first_build_ms = (ns[3] - ns[0]) * 1e-6;
  }
}

// The descriptor set, the ray tracing pipeline and its shader binding table.
void VulkanRtxTracer::create_pipeline() {
  Context& ctx = ctx_;
  const VkDevice d = ctx.device();
  Gpu& gpu = *gpu_;
  Accel& tl = gpu.tlas;
  // The descriptor set: the TLAS and the grid's tables (rays and hits bound per trace)
  const VkDescriptorType sb = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  gpu.set = std::make_unique<Descriptors>(
      ctx, std::initializer_list<VkDescriptorType>{VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR, sb, sb, sb, sb, sb, sb, sb},
      kRtStages);
  Descriptors& set = *gpu.set;
  set.bind(shared::kRtxBindTlas, tl.handle);
  set.bind(shared::kRtxBindInstances, grid_.instance_buffer());
  set.bind(shared::kRtxBindTriangles, grid_.triangle_buffer());
  set.bind(shared::kRtxBindUvs, grid_.uv_buffer());
  set.bind(shared::kRtxBindMaterials, grid_.material_buffer());
  set.bind(shared::kRtxBindTexels, grid_.texel_buffer());

  // The pipeline: ray generation, miss, and one hit group (closest hit + any hit)
  const VkDescriptorSetLayout set_layout = set.layout();
  const VkPushConstantRange range{kRtStages, 0, uint32_t(sizeof(RtxPush))};
  VkPipelineLayoutCreateInfo li{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  li.setLayoutCount = 1;
  li.pSetLayouts = &set_layout;
  li.pushConstantRangeCount = 1;
  li.pPushConstantRanges = &range;
  GRIDRT_VK_CHECK(vkCreatePipelineLayout(d, &li, nullptr, &gpu.layout));
  const std::pair<VkShaderStageFlagBits, const char*> stage_list[] = {{VK_SHADER_STAGE_RAYGEN_BIT_KHR, "rtx.rgen"},
                                                                      {VK_SHADER_STAGE_MISS_BIT_KHR, "rtx.rmiss"},
                                                                      {VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR, "rtx.rchit"},
                                                                      {VK_SHADER_STAGE_ANY_HIT_BIT_KHR, "rtx.rahit"}};
  std::vector<VkPipelineShaderStageCreateInfo> stages;
  for (const auto& [stage, name] : stage_list) {
    VkPipelineShaderStageCreateInfo s{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    s.stage = stage;
    s.module = gpu.module(name);
    s.pName = "main";
    stages.push_back(s);
  }
  VkRayTracingShaderGroupCreateInfoKHR groups[kGroupCount]{};
  for (auto& g : groups) {
    g = {VK_STRUCTURE_TYPE_RAY_TRACING_SHADER_GROUP_CREATE_INFO_KHR};
    g.generalShader = g.closestHitShader = g.anyHitShader = g.intersectionShader = VK_SHADER_UNUSED_KHR;
  }
  groups[kGroupRaygen].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR;
  groups[kGroupRaygen].generalShader = 0;
  groups[kGroupMiss].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR;
  groups[kGroupMiss].generalShader = 1;
  groups[kGroupHit].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_TRIANGLES_HIT_GROUP_KHR;
  groups[kGroupHit].closestHitShader = 2;
  groups[kGroupHit].anyHitShader = 3;
  VkRayTracingPipelineCreateInfoKHR pci{VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_CREATE_INFO_KHR};
  pci.stageCount = uint32_t(stages.size());
  pci.pStages = stages.data();
  pci.groupCount = kGroupCount;
  pci.pGroups = groups;
  pci.maxPipelineRayRecursionDepth = 1;
  pci.layout = gpu.layout;
  GRIDRT_VK_CHECK(gpu.fn.create_pipelines(d, VK_NULL_HANDLE, VK_NULL_HANDLE, 1, &pci, nullptr, &gpu.pipeline));

  // The shader binding table: one record per group, each region at the base alignment
  const VkDeviceSize handle = gpu.rt.shaderGroupHandleSize;
  const VkDeviceSize stride = align_up(handle, gpu.rt.shaderGroupHandleAlignment);
  const VkDeviceSize base_align = gpu.rt.shaderGroupBaseAlignment;
  const VkDeviceSize region = align_up(stride, base_align);
  std::vector<uint8_t> handles(handle * kGroupCount);
  GRIDRT_VK_CHECK(gpu.fn.group_handles(d, gpu.pipeline, 0, kGroupCount, handles.size(), handles.data()));
  std::vector<uint8_t> table(region * kGroupCount + base_align, 0);
  gpu.sbt = ctx.create_buffer(table.size(),
                              VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT);
  const VkDeviceAddress sbt_address = gpu.address(gpu.sbt);
  const VkDeviceAddress sbt_base = align_up(sbt_address, base_align);
  for (uint32_t g = 0; g < kGroupCount; ++g)
    std::memcpy(table.data() + (sbt_base - sbt_address) + g * region, handles.data() + g * handle, handle);
  ctx.upload(gpu.sbt, table.data(), table.size());
  gpu.raygen = {sbt_base + kGroupRaygen * region, region, region};
  gpu.miss = {sbt_base + kGroupMiss * region, stride, stride};
  gpu.hit = {sbt_base + kGroupHit * region, stride, stride};
}

VulkanRtxTracer::~VulkanRtxTracer() {
  if (gpu_) vkDeviceWaitIdle(ctx_.device());
  gpu_.reset();
}

uint32_t VulkanRtxTracer::dynamic_instance_count() const {
  return uint32_t(std::count_if(gpu_->blas.begin(), gpu_->blas.end(), [](const Accel& a) { return a.dynamic; }));
}

// The dynamic BLASes refitted (or rebuilt) to the geometry buffer's new triangles, then the TLAS
// rebuilt over every BLAS.
void VulkanRtxTracer::record_update(VkCommandBuffer cb) {
  Gpu& gpu = *gpu_;
  const VkDeviceSize scratch_align = std::max<VkDeviceSize>(gpu.as.minAccelerationStructureScratchOffsetAlignment, 16);
  const VkDeviceAddress frame_base = align_up(gpu.address(gpu.scratch), scratch_align);
  std::vector<Accel*> dynamics;
  for (Accel& a : gpu.blas)
    if (a.dynamic) dynamics.push_back(&a);
  if (dynamics.empty()) {  // nothing moves: the acceleration structures stand
    if (gpu.timestamps) gpu.timestamps->write(cb, 1);
    return;
  }
  gpu.record_builds(cb, dynamics, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR,
                    options_.rebuild_dynamic ? VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR
                                             : VK_BUILD_ACCELERATION_STRUCTURE_MODE_UPDATE_KHR,
                    frame_base);
  barrier(cb);
  if (gpu.timestamps) gpu.timestamps->write(cb, 1);
  gpu.record_builds(cb, {&gpu.tlas}, VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR,
                    VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR, frame_base);
  barrier(cb);
}

void VulkanRtxTracer::record_trace(VkCommandBuffer cb, uint32_t count) {
  Gpu& gpu = *gpu_;
  const VkPhysicalDeviceLimits& lim = ctx_.info().limits;
  const uint64_t width_limit = uint64_t(lim.maxComputeWorkGroupCount[0]) * lim.maxComputeWorkGroupSize[0];
  const uint32_t chunk = uint32_t(std::min<uint64_t>({width_limit, gpu.rt.maxRayDispatchInvocationCount, 1u << 30}));
  vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, gpu.pipeline);
  const VkDescriptorSet s = gpu.set->set();
  vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, gpu.layout, 0, 1, &s, 0, nullptr);
  for (uint32_t first = 0; first < count; first += std::min(chunk, count - first)) {
    RtxPush push = gpu.push;
    push.ray_offset = first;
    push.ray_count = std::min(chunk, count - first);
    vkCmdPushConstants(cb, gpu.layout, kRtStages, 0, sizeof push, &push);
    gpu.fn.trace_rays(cb, &gpu.raygen, &gpu.miss, &gpu.hit, &gpu.callable, push.ray_count, 1, 1);
  }
}

void VulkanRtxTracer::update_and_trace(const Buffer& rays, const Buffer& hits, uint32_t count) {
  Gpu& gpu = *gpu_;
  if (rays.size < VkDeviceSize(count) * sizeof(Ray) || hits.size < VkDeviceSize(count) * sizeof(Hit))
    throw Error("the ray tracing side by side: the ray or hit buffer holds fewer than " + std::to_string(count) +
                " records");
  if (rays.buffer != gpu.bound_rays) gpu.set->bind(shared::kRtxBindRays, rays), gpu.bound_rays = rays.buffer;
  if (hits.buffer != gpu.bound_hits) gpu.set->bind(shared::kRtxBindHits, hits), gpu.bound_hits = hits.buffer;
  const auto t0 = std::chrono::steady_clock::now();
  ctx_.submit([&](VkCommandBuffer cb) {
    barrier(cb);  // the grid's update rewrote the geometry buffer; the frame wrote the rays
    if (gpu.timestamps) gpu.timestamps->reset(cb), gpu.timestamps->write(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    record_update(cb);
    if (gpu.timestamps) gpu.timestamps->write(cb, 2);
    if (count) record_trace(cb, count);
    if (gpu.timestamps) gpu.timestamps->write(cb, 3);
  });
  timings_.host_ms = ms_since(t0);
  if (gpu.timestamps) {
    const std::vector<double> ns = gpu.timestamps->read_ns();
    timings_.refit_ms = (ns[1] - ns[0]) * 1e-6;
    timings_.tlas_ms = (ns[2] - ns[1]) * 1e-6;
    timings_.update_ms = (ns[2] - ns[0]) * 1e-6;
    timings_.trace_ms = (ns[3] - ns[2]) * 1e-6;
  }
}

void VulkanRtxTracer::update_and_trace(std::span<const Ray> rays, std::span<Hit> hits) {
  if (hits.size() != rays.size()) throw Error("the ray tracing side by side: hits.size() != rays.size()");
  Gpu& gpu = *gpu_;
  if (rays.size() > gpu.ray_capacity || !gpu.rays.buffer) {
    const size_t n = std::max<size_t>(rays.size(), 1);
    gpu.rays = ctx_.create_buffer(n * sizeof(Ray), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    gpu.hits = ctx_.create_buffer(n * sizeof(Hit), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    gpu.ray_capacity = n;
  }
  ctx_.upload(gpu.rays, rays.data(), rays.size_bytes());
  update_and_trace(gpu.rays, gpu.hits, uint32_t(rays.size()));
  ctx_.download(gpu.hits, hits.data(), hits.size_bytes());
}

}  // namespace gridrt::vulkan
