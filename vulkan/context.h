// context.h: a small Vulkan context in the plain C API: instance (with the validation layer and
// a debug-utils messenger when asked), the physical device, one queue that does graphics and
// compute, one-shot command submission, buffers, R32_UINT 3D storage images and the limits they
// are checked against.
//
// Every failure is a gridrt::Error that says what is missing and the way out ("...; use
// --backend cpu"), never a crash: no loader, no device, no suitable device, a limit exceeded.
// Limits and features are queried, never assumed (lavapipe here, NVIDIA on the GPU machine).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "gridrt/common/scene.h"
#include "gridrt/vulkan/loader.h"

namespace gridrt::vulkan {

// Throws Error("<what> failed: VK_ERROR_...") unless r is VK_SUCCESS.
void check(VkResult r, const char* what);
#define GRIDRT_VK_CHECK(call) ::gridrt::vulkan::check((call), #call)

struct ContextOptions {
  bool validation = false;       // Khronos validation layer + messenger (env GRIDRT_VALIDATION=1)
  bool sync_validation = true;   // with validation: synchronization validation as well
  bool best_practices = false;   // with validation: the layer's best-practices checks as well
                                 // (env GRIDRT_VALIDATION=best-practices)
  int device_index = -1;         // physical device by index (env GRIDRT_VK_DEVICE); -1: best
  std::string loader_path;       // "" = libvulkan.so.1 (env GRIDRT_VK_LOADER)
  bool raster_build = true;      // need geometryShader + vertexPipelineStoresAndAtomics
  // Enable the device's ray tracing (VK_KHR_acceleration_structure, VK_KHR_ray_tracing_pipeline,
  // VK_KHR_deferred_host_operations, bufferDeviceAddress) for vulkan/rtx.h, where the device has
  // all of it; never required (the device choice does not change), never enabled unless asked.
  bool ray_tracing = false;
  // Report every compute pipeline's statistics as the driver gives them (registers, local
  // memory, ...: VK_KHR_pipeline_executable_properties) on stderr as it is made, where the device
  // has the extension (env GRIDRT_VK_PIPELINE_STATS=1); a note says so where it has not.
  bool pipeline_stats = false;

  // Defaults overridden by GRIDRT_VALIDATION, GRIDRT_VK_DEVICE, GRIDRT_VK_LOADER and
  // GRIDRT_VK_PIPELINE_STATS.
  static ContextOptions from_env();
};

// What the chosen device offers, as queried.
struct DeviceInfo {
  std::string name;
  std::string driver;                  // driverName + driverInfo
  VkDriverId driver_id = VkDriverId(0);
  VkPhysicalDeviceType type = VK_PHYSICAL_DEVICE_TYPE_OTHER;
  uint32_t api_version = 0;
  VkPhysicalDeviceLimits limits{};
  bool geometry_shader = false;
  bool vertex_pipeline_stores_and_atomics = false;
  bool fragment_stores_and_atomics = false;
  // shaderInt64 + shaderBufferInt64Atomics (enabled when present: the compute gather's key)
  bool buffer_int64_atomics = false;
  // Subgroup arithmetic and ballot in compute shaders (the compute gather's appends, the build's
  // counters: build.glsl)
  bool subgroup_arithmetic_ballot = false;
  // Float controls (VkPhysicalDeviceFloatControlsProperties), 32-bit floats.
  bool denorm_preserve_f32 = false;
  bool denorm_flush_to_zero_f32 = false;
  bool signed_zero_inf_nan_preserve_f32 = false;
  uint32_t subgroup_size = 0;
  uint32_t timestamp_valid_bits = 0;   // of the queue family, 0: no timestamps
  VkDeviceSize max_memory_allocation = 0;
  VkDeviceSize device_local_heap = 0;  // the largest device-local heap, bytes
  // What the device lacks for the ray tracing side by side (vulkan/rtx.h): the missing
  // extensions and features by name, "" when it has everything.
  std::string ray_tracing_missing;

  std::string summary() const;         // one paragraph for logs and docs
};

enum class Memory {
  Device,  // device-local; mapped when the device-local memory is host-visible (lavapipe, ReBAR)
  Host,    // host-visible and coherent, always mapped: readbacks, small per-frame data
};

class Context;

// A buffer and its memory. Move-only; destroyed with its context's device.
struct Buffer {
  Buffer() = default;
  Buffer(Buffer&& o) noexcept { *this = std::move(o); }
  Buffer& operator=(Buffer&& o) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  ~Buffer() { reset(); }
  void reset();

  VkDevice device = VK_NULL_HANDLE;
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkDeviceSize size = 0;
  void* mapped = nullptr;  // non-null when host-visible and coherent
};

// An image with its memory and view: the grid's 3D storage image of R32_UINT texels (in
// VK_IMAGE_LAYOUT_GENERAL), and as well the portal's textures and the gather's attachments.
struct Image3D {
  Image3D() = default;
  Image3D(Image3D&& o) noexcept { *this = std::move(o); }
  Image3D& operator=(Image3D&& o) noexcept;
  Image3D(const Image3D&) = delete;
  Image3D& operator=(const Image3D&) = delete;
  ~Image3D() { reset(); }
  void reset();

  VkDevice device = VK_NULL_HANDLE;
  VkImage image = VK_NULL_HANDLE;
  VkImageView view = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  glm::uvec3 extent{0};
  size_t texel_count() const { return size_t(extent.x) * extent.y * extent.z; }
};

class Context {
 public:
  explicit Context(const ContextOptions& options = ContextOptions::from_env());
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  VkInstance instance() const { return instance_; }
  VkPhysicalDevice physical_device() const { return physical_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  uint32_t queue_family() const { return queue_family_; }
  const DeviceInfo& info() const { return info_; }
  bool validation() const { return validation_; }
  // Whether the ray tracing extensions and features are enabled (asked for and present).
  bool ray_tracing() const { return ray_tracing_; }
  // Whether pipelines are made with their statistics captured (ContextOptions::pipeline_stats on
  // a device with VK_KHR_pipeline_executable_properties).
  bool pipeline_stats() const { return pipeline_stats_; }
  // Writes `pipeline`'s statistics, as the driver reports them, to stderr as one line per
  // executable, headed by `what` (with pipeline_stats() only).
  void report_pipeline_stats(VkPipeline pipeline, const std::string& what) const;

  // Validation messages (warnings and errors) received since the last clear_messages().
  std::vector<std::string> messages() const;
  size_t message_count() const;
  void clear_messages();

  // Records commands into a fresh primary command buffer, submits it and waits on a fence. A
  // final barrier makes every device write visible to the host.
  void submit(const std::function<void(VkCommandBuffer)>& record);

  // Buffers. Usage gets TRANSFER_SRC|TRANSFER_DST added; SHADER_DEVICE_ADDRESS usage (only with
  // ray_tracing()) allocates with the device-address flag. Throws Error on a limit.
  // `what`: the buffer, for the message where a storage buffer passes maxStorageBufferRange (the
  // advice follows from it: the grid's tables shrink with fewer cells, the ray buffers with fewer rays)
  Buffer create_buffer(VkDeviceSize size, VkBufferUsageFlags usage, Memory where = Memory::Device,
                       const char* what = nullptr);
  void upload(const Buffer& dst, const void* data, size_t bytes, VkDeviceSize offset = 0);
  void download(const Buffer& src, void* data, size_t bytes, VkDeviceSize offset = 0);
  template <class T>
  void upload(const Buffer& dst, std::span<const T> data, VkDeviceSize offset = 0) {
    upload(dst, data.data(), data.size_bytes(), offset);
  }
  template <class T>
  std::vector<T> download(const Buffer& src, size_t count, VkDeviceSize offset = 0) {
    std::vector<T> out(count);
    download(src, out.data(), count * sizeof(T), offset);
    return out;
  }

  // 3D storage images of R32_UINT. The extent is checked against maxImageDimension3D and the
  // format's image limits first.
  Image3D create_image3d(glm::uvec3 extent);
  // Any image (Image3D holds a 2D one as well): `type` and `format`, one mip level and layer,
  // optimal tiling, `usage`, in device memory, with a view of `aspect`; left UNDEFINED. With `what`,
  // the allocation is checked first (require_allocation).
  Image3D create_image(VkImageType type, VkFormat format, glm::uvec3 extent, VkImageUsageFlags usage,
                       VkImageAspectFlags aspect = VK_IMAGE_ASPECT_COLOR_BIT, const char* what = nullptr);
  void clear(const Image3D& image, uint32_t value);
  void upload(const Image3D& image, std::span<const uint32_t> texels);
  std::vector<uint32_t> download(const Image3D& image);

  // Throws Error naming the limit when a 3D image of `extent` texels cannot be made.
  void require_image3d(glm::uvec3 extent) const;
  // Throws Error when one allocation of `bytes` for `what` exceeds the device's limits.
  void require_allocation(VkDeviceSize bytes, const char* what) const;

  // A memory type index with all of `required` (and preferably none of `avoid`), or ~0u.
  uint32_t memory_type(uint32_t type_bits, VkMemoryPropertyFlags required,
                       VkMemoryPropertyFlags avoid = 0) const;

  // For the messenger callback.
  void on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity, const char* text);

 private:
  void destroy();
  void create_instance(const ContextOptions& options);
  void choose_physical_device(const ContextOptions& options);
  void create_device(const ContextOptions& options);
  VkDeviceMemory allocate(const VkMemoryRequirements& req, Memory where, void** mapped, bool device_address = false);

  bool validation_ = false;
  bool ray_tracing_ = false;
  bool pipeline_stats_ = false;
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  PFN_vkDestroyDebugUtilsMessengerEXT destroy_messenger_ = nullptr;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkPhysicalDeviceMemoryProperties memory_{};
  DeviceInfo info_;
  VkDevice device_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  VkQueue queue_ = VK_NULL_HANDLE;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;

  mutable std::mutex messages_mutex_;
  std::vector<std::string> messages_;
};

// A global memory barrier between two commands: every write of `src` stages visible to every
// access of `dst` stages (the tracer's passes are few and large; finer barriers buy nothing).
void barrier(VkCommandBuffer cb, VkPipelineStageFlags src = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
             VkPipelineStageFlags dst = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT);

// Timestamp queries: write(i) at points of a command buffer, read() after the submit.
class Timestamps {
 public:
  Timestamps(Context& ctx, uint32_t count);  // throws Error when the queue has no timestamps
  ~Timestamps();
  Timestamps(const Timestamps&) = delete;
  Timestamps& operator=(const Timestamps&) = delete;

  void reset(VkCommandBuffer cb);  // before the first write in a command buffer
  void write(VkCommandBuffer cb, uint32_t index,
             VkPipelineStageFlagBits stage = VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  // Nanoseconds of every query (valid bits masked, timestampPeriod applied); waits for them.
  std::vector<double> read_ns();
  // Milliseconds from query a to query b.
  double elapsed_ms(uint32_t a, uint32_t b);

 private:
  Context& ctx_;
  VkQueryPool pool_ = VK_NULL_HANDLE;
  uint32_t count_ = 0;
};

}  // namespace gridrt::vulkan
