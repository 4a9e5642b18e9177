// pipeline.h: descriptor sets, specialization constants, compute pipelines and the raster
// pipeline of the paper's build (vertex + geometry shader, no colour attachments, rasterizer
// discard: the geometry shader does all the work and emits nothing).
//
// Shader modules come from the SPIR-V embedded at build time (shader_spirv("name.comp")), patched
// for the device's float controls before use (patch_float_controls).
#pragma once

#include <cstdint>
#include <initializer_list>
#include <span>
#include <string_view>
#include <vector>

#include "gridrt/vulkan/context.h"

namespace gridrt::vulkan {

// The embedded SPIR-V of vulkan/shaders/<name> (e.g. "trace.comp"). Throws Error if unknown.
std::span<const uint32_t> shader_spirv(std::string_view name);

// What patch_float_controls adds to a module.
struct FloatControls {
  bool denorm_preserve = false;            // DenormPreserve 32: denormals survive as on the CPU
  bool signed_zero_inf_nan_preserve = false;  // SignedZeroInfNanPreserve 32
  static FloatControls for_device(const DeviceInfo& info);  // what the device supports
};

// Adds the float-control capabilities and execution modes (SPIR-V 1.4 core, Vulkan 1.2
// shaderFloatControls) to every entry point of `words`. GLSL cannot spell them, so the embedded
// modules carry none and get what the device supports here.
std::vector<uint32_t> patch_float_controls(std::span<const uint32_t> words, const FloatControls& fc);

// The embedded shader `name`, patched for the device's float controls, as a module; the caller
// destroys it.
VkShaderModule create_shader_module(Context& ctx, std::string_view name);

// Counts of SPIR-V facts the tests check: NoContraction decorations (`precise`), and
// execution modes by number.
struct SpirvFacts {
  uint32_t no_contraction = 0;
  uint32_t fma = 0;  // GLSL.std.450 Fma instructions
  std::vector<uint32_t> execution_modes;
};
SpirvFacts inspect_spirv(std::span<const uint32_t> words);

// Specialization constants: add(id, value) in any order; info() points into this object.
class SpecConstants {
 public:
  SpecConstants& add(uint32_t id, uint32_t value);
  SpecConstants& add(uint32_t id, int32_t value);
  SpecConstants& add(uint32_t id, float value);
  SpecConstants& add(uint32_t id, bool value);  // a VkBool32
  const VkSpecializationInfo* info();          // nullptr when empty
  // " {id=value, ...}" (values as 32-bit words), "" when empty: names a pipeline in reports.
  std::string summary() const;

 private:
  std::vector<VkSpecializationMapEntry> entries_;
  std::vector<uint32_t> data_;
  VkSpecializationInfo info_{};
};

// One descriptor set: a layout of storage buffers / storage images / uniform buffers at bindings
// 0, 1, ..., its own pool and the set. Bind resources, then use layout() and set().
class Descriptors {
 public:
  Descriptors(Context& ctx, std::initializer_list<VkDescriptorType> bindings,
              VkShaderStageFlags stages = VK_SHADER_STAGE_COMPUTE_BIT | VK_SHADER_STAGE_VERTEX_BIT |
                                          VK_SHADER_STAGE_GEOMETRY_BIT)
      : Descriptors(ctx, std::vector<VkDescriptorType>(bindings), stages) {}
  // Binding i of type bindings[i] (the types of an interface header's bindings).
  Descriptors(Context& ctx, std::vector<VkDescriptorType> bindings,
              VkShaderStageFlags stages = VK_SHADER_STAGE_COMPUTE_BIT | VK_SHADER_STAGE_VERTEX_BIT |
                                          VK_SHADER_STAGE_GEOMETRY_BIT);
  ~Descriptors();
  Descriptors(const Descriptors&) = delete;
  Descriptors& operator=(const Descriptors&) = delete;

  void bind(uint32_t binding, const Buffer& buffer);
  void bind(uint32_t binding, const Image3D& image);
  // A sampled or storage image by its view, in `layout` (e.g. the portal's textures, sampled in
  // SHADER_READ_ONLY_OPTIMAL).
  void bind(uint32_t binding, VkImageView view, VkImageLayout layout);
  // An acceleration structure (vulkan/rtx.h; only on a context with ray_tracing()).
  void bind(uint32_t binding, VkAccelerationStructureKHR structure);
  VkDescriptorSetLayout layout() const { return layout_; }
  VkDescriptorSet set() const { return set_; }

 private:
  // Binding `binding` (of one of `allowed` types, else Error naming `what`) to one buffer, image or
  // (through `next`) acceleration structure.
  void write(uint32_t binding, std::initializer_list<VkDescriptorType> allowed, const char* what,
             const VkDescriptorBufferInfo* buffer, const VkDescriptorImageInfo* image, const void* next = nullptr);

  Context& ctx_;
  std::vector<VkDescriptorType> types_;
  VkDescriptorSetLayout layout_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
};

// A compute pipeline or the raster build pipeline, with its layout (one descriptor set, one
// push-constant range of `push_bytes` for every stage).
class Pipeline {
 public:
  // Compute: `shader` names an embedded .comp.
  Pipeline(Context& ctx, std::string_view shader, VkDescriptorSetLayout set_layout, uint32_t push_bytes,
           SpecConstants spec = {});
  // Raster: vertex + geometry shader, rasterizer discard, a render pass without attachments.
  // The specialization constants go to both stages.
  Pipeline(Context& ctx, std::string_view vertex_shader, std::string_view geometry_shader,
           VkDescriptorSetLayout set_layout, uint32_t push_bytes, SpecConstants spec = {});
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  // Binds the pipeline and the set.
  void bind(VkCommandBuffer cb, VkDescriptorSet set) const;
  void push(VkCommandBuffer cb, const void* data, uint32_t bytes) const;
  template <class T>
  void push(VkCommandBuffer cb, const T& value) const { push(cb, &value, sizeof(T)); }
  // Raster only: begin/end the attachment-less render pass around the draws.
  void begin_pass(VkCommandBuffer cb) const;
  void end_pass(VkCommandBuffer cb) const;

  VkPipeline pipeline() const { return pipeline_; }
  VkPipelineLayout layout() const { return layout_; }

 private:
  void destroy();
  VkShaderModule module(std::string_view name);
  void create_layout(VkDescriptorSetLayout set_layout, uint32_t push_bytes);

  Context& ctx_;
  VkPipelineBindPoint bind_point_ = VK_PIPELINE_BIND_POINT_COMPUTE;
  VkShaderStageFlags push_stages_ = 0;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  VkRenderPass render_pass_ = VK_NULL_HANDLE;
  VkFramebuffer framebuffer_ = VK_NULL_HANDLE;
  std::vector<VkShaderModule> modules_;
};

// Number of workgroups of `size` invocations that cover `n`.
inline uint32_t groups(uint64_t n, uint32_t size) { return uint32_t((n + size - 1) / size); }

}  // namespace gridrt::vulkan
