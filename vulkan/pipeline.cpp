// pipeline.cpp: descriptors, specialization constants, pipelines, SPIR-V float controls.
#include "gridrt/vulkan/pipeline.h"

#include <algorithm>
#include <cstring>

namespace gridrt::vulkan {

// ---- SPIR-V ----

namespace {
// Opcodes, capabilities and execution modes of the SPIR-V 1.5 specification.
constexpr uint32_t kOpExtInst = 12;
constexpr uint32_t kOpCapability = 17;
constexpr uint32_t kOpEntryPoint = 15;
constexpr uint32_t kOpExecutionMode = 16;
constexpr uint32_t kOpExecutionModeId = 331;
constexpr uint32_t kOpDecorate = 71;
constexpr uint32_t kDecorationNoContraction = 42;
constexpr uint32_t kGlslFma = 50;  // GLSL.std.450 Fma
constexpr uint32_t kCapDenormPreserve = 4464;
constexpr uint32_t kCapSignedZeroInfNanPreserve = 4466;
constexpr uint32_t kModeDenormPreserve = 4459;
constexpr uint32_t kModeSignedZeroInfNanPreserve = 4461;
constexpr uint32_t kHeaderWords = 5;

uint32_t op(uint32_t w) { return w & 0xFFFFu; }
uint32_t length(uint32_t w) { return w >> 16; }

void check_module(std::span<const uint32_t> words) {
  if (words.size() < kHeaderWords || words[0] != 0x07230203u) throw Error("not a SPIR-V module");
  for (size_t i = kHeaderWords; i < words.size();) {
    const uint32_t n = length(words[i]);
    if (n == 0 || i + n > words.size()) throw Error("malformed SPIR-V module");
    i += n;
  }
}
}  // namespace

FloatControls FloatControls::for_device(const DeviceInfo& info) {
  return {info.denorm_preserve_f32, info.signed_zero_inf_nan_preserve_f32};
}

std::vector<uint32_t> patch_float_controls(std::span<const uint32_t> words, const FloatControls& fc) {
  check_module(words);
  std::vector<uint32_t> caps, modes;
  if (fc.denorm_preserve) caps.push_back(kCapDenormPreserve), modes.push_back(kModeDenormPreserve);
  if (fc.signed_zero_inf_nan_preserve)
    caps.push_back(kCapSignedZeroInfNanPreserve), modes.push_back(kModeSignedZeroInfNanPreserve);
  if (caps.empty()) return {words.begin(), words.end()};

  // Where the capabilities end, the entry points are and the execution modes end (the logical
  // layout of a module fixes that order).
  size_t caps_end = kHeaderWords, modes_end = 0;
  std::vector<uint32_t> entry_ids, present_caps;
  for (size_t i = kHeaderWords; i < words.size(); i += length(words[i])) {
    const uint32_t o = op(words[i]);
    if (o == kOpCapability) caps_end = i + length(words[i]), present_caps.push_back(words[i + 1]);
    if (o == kOpEntryPoint) entry_ids.push_back(words[i + 2]), modes_end = i + length(words[i]);
    if (o == kOpExecutionMode || o == kOpExecutionModeId) modes_end = i + length(words[i]);
  }
  if (entry_ids.empty()) throw Error("SPIR-V module without an entry point");

  std::vector<uint32_t> cap_words, mode_words;
  for (uint32_t c : caps)
    if (std::find(present_caps.begin(), present_caps.end(), c) == present_caps.end())
      cap_words.insert(cap_words.end(), {(2u << 16) | kOpCapability, c});
  for (uint32_t id : entry_ids)
    for (uint32_t m : modes) mode_words.insert(mode_words.end(), {(4u << 16) | kOpExecutionMode, id, m, 32u});

  std::vector<uint32_t> out;
  out.reserve(words.size() + cap_words.size() + mode_words.size());
  out.insert(out.end(), words.begin(), words.begin() + caps_end);
  out.insert(out.end(), cap_words.begin(), cap_words.end());
  out.insert(out.end(), words.begin() + caps_end, words.begin() + modes_end);
  out.insert(out.end(), mode_words.begin(), mode_words.end());
  out.insert(out.end(), words.begin() + modes_end, words.end());
  return out;
}

SpirvFacts inspect_spirv(std::span<const uint32_t> words) {
  check_module(words);
  SpirvFacts f;
  for (size_t i = kHeaderWords; i < words.size(); i += length(words[i])) {
    const uint32_t o = op(words[i]), n = length(words[i]);
    if (o == kOpDecorate && n >= 3 && words[i + 2] == kDecorationNoContraction) ++f.no_contraction;
    if (o == kOpExtInst && n >= 5 && words[i + 4] == kGlslFma) ++f.fma;
    if ((o == kOpExecutionMode || o == kOpExecutionModeId) && n >= 3) f.execution_modes.push_back(words[i + 2]);
  }
  return f;
}

// ---- SpecConstants ----

SpecConstants& SpecConstants::add(uint32_t id, uint32_t value) {
  entries_.push_back({id, uint32_t(data_.size() * 4), 4});
  data_.push_back(value);
  return *this;
}
SpecConstants& SpecConstants::add(uint32_t id, int32_t value) { return add(id, uint32_t(value)); }
SpecConstants& SpecConstants::add(uint32_t id, float value) {
  uint32_t bits;
  std::memcpy(&bits, &value, 4);
  return add(id, bits);
}
SpecConstants& SpecConstants::add(uint32_t id, bool value) { return add(id, uint32_t(value ? VK_TRUE : VK_FALSE)); }

const VkSpecializationInfo* SpecConstants::info() {
  if (entries_.empty()) return nullptr;
  info_.mapEntryCount = uint32_t(entries_.size());
  info_.pMapEntries = entries_.data();
  info_.dataSize = data_.size() * 4;
  info_.pData = data_.data();
  return &info_;
}

// ---- Descriptors ----

Descriptors::Descriptors(Context& ctx, std::vector<VkDescriptorType> bindings, VkShaderStageFlags stages)
    : ctx_(ctx), types_(std::move(bindings)) {
  std::vector<VkDescriptorSetLayoutBinding> b;
  std::vector<VkDescriptorPoolSize> sizes;
  for (uint32_t i = 0; i < types_.size(); ++i) {
    b.push_back({i, types_[i], 1, stages, nullptr});
    auto it = std::find_if(sizes.begin(), sizes.end(), [&](const VkDescriptorPoolSize& s) { return s.type == types_[i]; });
    if (it == sizes.end()) sizes.push_back({types_[i], 1});
    else ++it->descriptorCount;
  }
  VkDescriptorSetLayoutCreateInfo lci{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  lci.bindingCount = uint32_t(b.size());
  lci.pBindings = b.data();
  GRIDRT_VK_CHECK(vkCreateDescriptorSetLayout(ctx.device(), &lci, nullptr, &layout_));
  VkDescriptorPoolCreateInfo pci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pci.maxSets = 1;
  pci.poolSizeCount = uint32_t(sizes.size());
  pci.pPoolSizes = sizes.data();
  GRIDRT_VK_CHECK(vkCreateDescriptorPool(ctx.device(), &pci, nullptr, &pool_));
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = pool_;
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &layout_;
  GRIDRT_VK_CHECK(vkAllocateDescriptorSets(ctx.device(), &ai, &set_));
}

Descriptors::~Descriptors() {
  if (pool_) vkDestroyDescriptorPool(ctx_.device(), pool_, nullptr);
  if (layout_) vkDestroyDescriptorSetLayout(ctx_.device(), layout_, nullptr);
}

void Descriptors::write(uint32_t binding, std::initializer_list<VkDescriptorType> allowed, const char* what,
                        const VkDescriptorBufferInfo* buffer, const VkDescriptorImageInfo* image, const void* next) {
  if (binding >= types_.size() || std::find(allowed.begin(), allowed.end(), types_[binding]) == allowed.end())
    throw Error("descriptor binding " + std::to_string(binding) + " is not " + what);
  VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  w.pNext = next;
  w.dstSet = set_;
  w.dstBinding = binding;
  w.descriptorCount = 1;
  w.descriptorType = types_[binding];
  w.pBufferInfo = buffer;
  w.pImageInfo = image;
  vkUpdateDescriptorSets(ctx_.device(), 1, &w, 0, nullptr);
}

void Descriptors::bind(uint32_t binding, const Buffer& buffer) {
  const VkDescriptorBufferInfo info{buffer.buffer, 0, VK_WHOLE_SIZE};
  write(binding, {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER}, "a buffer", &info, nullptr);
}

void Descriptors::bind(uint32_t binding, const Image3D& image) {
  const VkDescriptorImageInfo info{VK_NULL_HANDLE, image.view, VK_IMAGE_LAYOUT_GENERAL};
  write(binding, {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE}, "a storage image", nullptr, &info);
}

void Descriptors::bind(uint32_t binding, VkImageView view, VkImageLayout layout) {
  const VkDescriptorImageInfo info{VK_NULL_HANDLE, view, layout};
  write(binding, {VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE}, "a sampled or storage image", nullptr,
        &info);
}

void Descriptors::bind(uint32_t binding, VkAccelerationStructureKHR structure) {
  VkWriteDescriptorSetAccelerationStructureKHR as{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET_ACCELERATION_STRUCTURE_KHR};
  as.accelerationStructureCount = 1;
  as.pAccelerationStructures = &structure;
  write(binding, {VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR}, "an acceleration structure", nullptr, nullptr, &as);
}

std::string SpecConstants::summary() const {
  if (entries_.empty()) return "";
  std::string s = " {";
  for (size_t i = 0; i < entries_.size(); ++i)
    s += (i ? ", " : "") + std::to_string(entries_[i].constantID) + "=" + std::to_string(data_[i]);
  return s + "}";
}

// ---- Pipeline ----

VkShaderModule create_shader_module(Context& ctx, std::string_view name) {
  const std::vector<uint32_t> words = patch_float_controls(shader_spirv(name), FloatControls::for_device(ctx.info()));
  VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  ci.codeSize = words.size() * 4;
  ci.pCode = words.data();
  VkShaderModule m = VK_NULL_HANDLE;
  GRIDRT_VK_CHECK(vkCreateShaderModule(ctx.device(), &ci, nullptr, &m));
  return m;
}

VkShaderModule Pipeline::module(std::string_view name) {
  const VkShaderModule m = create_shader_module(ctx_, name);
  modules_.push_back(m);
  return m;
}

void Pipeline::create_layout(VkDescriptorSetLayout set_layout, uint32_t push_bytes) {
  if (push_bytes > ctx_.info().limits.maxPushConstantsSize)
    throw Error("push constants of " + std::to_string(push_bytes) + " bytes exceed maxPushConstantsSize (" +
                std::to_string(ctx_.info().limits.maxPushConstantsSize) + ")");
  const VkPushConstantRange range{push_stages_, 0, push_bytes};
  VkPipelineLayoutCreateInfo ci{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  ci.setLayoutCount = set_layout ? 1 : 0;
  ci.pSetLayouts = &set_layout;
  ci.pushConstantRangeCount = push_bytes ? 1 : 0;
  ci.pPushConstantRanges = &range;
  GRIDRT_VK_CHECK(vkCreatePipelineLayout(ctx_.device(), &ci, nullptr, &layout_));
}

Pipeline::Pipeline(Context& ctx, std::string_view shader, VkDescriptorSetLayout set_layout, uint32_t push_bytes,
                   SpecConstants spec)
    : ctx_(ctx), bind_point_(VK_PIPELINE_BIND_POINT_COMPUTE), push_stages_(VK_SHADER_STAGE_COMPUTE_BIT) {
  try {
    create_layout(set_layout, push_bytes);
    VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    ci.stage.module = module(shader);
    ci.stage.pName = "main";
    ci.stage.pSpecializationInfo = spec.info();
    ci.layout = layout_;
    if (ctx.pipeline_stats()) ci.flags |= VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR;
    GRIDRT_VK_CHECK(vkCreateComputePipelines(ctx.device(), VK_NULL_HANDLE, 1, &ci, nullptr, &pipeline_));
    ctx.report_pipeline_stats(pipeline_, std::string(shader) + spec.summary());
  } catch (...) {
    destroy();
    throw;
  }
}

Pipeline::Pipeline(Context& ctx, std::string_view vertex_shader, std::string_view geometry_shader,
                   VkDescriptorSetLayout set_layout, uint32_t push_bytes, SpecConstants spec)
    : ctx_(ctx),
      bind_point_(VK_PIPELINE_BIND_POINT_GRAPHICS),
      push_stages_(VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_GEOMETRY_BIT) {
  try {
    if (!ctx.info().geometry_shader || !ctx.info().vertex_pipeline_stores_and_atomics)
      throw Error(ctx.info().name +
                  " lacks geometryShader or vertexPipelineStoresAndAtomics: use the compute build (--build compute)");
    create_layout(set_layout, push_bytes);

    // A render pass with one subpass and no attachments, and a 1x1 framebuffer without any.
    VkSubpassDescription sub{};
    sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
    VkRenderPassCreateInfo rci{VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
    rci.subpassCount = 1;
    rci.pSubpasses = &sub;
    GRIDRT_VK_CHECK(vkCreateRenderPass(ctx.device(), &rci, nullptr, &render_pass_));
    VkFramebufferCreateInfo fci{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
    fci.renderPass = render_pass_;
    fci.width = 1;
    fci.height = 1;
    fci.layers = 1;
    GRIDRT_VK_CHECK(vkCreateFramebuffer(ctx.device(), &fci, nullptr, &framebuffer_));

    const VkSpecializationInfo* si = spec.info();
    VkPipelineShaderStageCreateInfo stages[2]{};
    stages[0] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
    stages[0].module = module(vertex_shader);
    stages[0].pName = "main";
    stages[0].pSpecializationInfo = si;
    stages[1] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    stages[1].stage = VK_SHADER_STAGE_GEOMETRY_BIT;
    stages[1].module = module(geometry_shader);
    stages[1].pName = "main";
    stages[1].pSpecializationInfo = si;

    // No vertex buffers: the vertex shader reads the triangles from a storage buffer by
    // gl_VertexIndex. Rasterization is discarded, so viewport, multisample, depth and blend
    // states are not needed.
    VkPipelineVertexInputStateCreateInfo vi{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
    VkPipelineInputAssemblyStateCreateInfo ia{VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
    ia.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
    VkPipelineRasterizationStateCreateInfo rs{VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
    rs.rasterizerDiscardEnable = VK_TRUE;
    rs.polygonMode = VK_POLYGON_MODE_FILL;
    rs.cullMode = VK_CULL_MODE_NONE;
    rs.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
    rs.lineWidth = 1.0f;

    VkGraphicsPipelineCreateInfo ci{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
    ci.stageCount = 2;
    ci.pStages = stages;
    ci.pVertexInputState = &vi;
    ci.pInputAssemblyState = &ia;
    ci.pRasterizationState = &rs;
    ci.layout = layout_;
    ci.renderPass = render_pass_;
    ci.subpass = 0;
    GRIDRT_VK_CHECK(vkCreateGraphicsPipelines(ctx.device(), VK_NULL_HANDLE, 1, &ci, nullptr, &pipeline_));
  } catch (...) {
    destroy();
    throw;
  }
}

Pipeline::~Pipeline() { destroy(); }

void Pipeline::destroy() {
  const VkDevice d = ctx_.device();
  if (pipeline_) vkDestroyPipeline(d, pipeline_, nullptr);
  if (layout_) vkDestroyPipelineLayout(d, layout_, nullptr);
  if (framebuffer_) vkDestroyFramebuffer(d, framebuffer_, nullptr);
  if (render_pass_) vkDestroyRenderPass(d, render_pass_, nullptr);
  for (VkShaderModule m : modules_) vkDestroyShaderModule(d, m, nullptr);
  pipeline_ = VK_NULL_HANDLE, layout_ = VK_NULL_HANDLE, framebuffer_ = VK_NULL_HANDLE, render_pass_ = VK_NULL_HANDLE;
  modules_.clear();
}

void Pipeline::bind(VkCommandBuffer cb, VkDescriptorSet set) const {
  vkCmdBindPipeline(cb, bind_point_, pipeline_);
  if (set) vkCmdBindDescriptorSets(cb, bind_point_, layout_, 0, 1, &set, 0, nullptr);
}

void Pipeline::push(VkCommandBuffer cb, const void* data, uint32_t bytes) const {
  vkCmdPushConstants(cb, layout_, push_stages_, 0, bytes, data);
}

void Pipeline::begin_pass(VkCommandBuffer cb) const {
  VkRenderPassBeginInfo bi{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
  bi.renderPass = render_pass_;
  bi.framebuffer = framebuffer_;
  bi.renderArea = {{0, 0}, {1, 1}};
  vkCmdBeginRenderPass(cb, &bi, VK_SUBPASS_CONTENTS_INLINE);
}

void Pipeline::end_pass(VkCommandBuffer cb) const { vkCmdEndRenderPass(cb); }

}  // namespace gridrt::vulkan
