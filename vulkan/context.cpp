// context.cpp: instance, device, submission, buffers and 3D images (see context.h).
#include "gridrt/vulkan/context.h"

#include "gridrt/common/progress.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <utility>

namespace gridrt::vulkan {

void check(VkResult r, const char* what) {
  if (r != VK_SUCCESS) throw Error(std::string(what) + " failed: " + result_name(r));
}

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
constexpr const char* kWayOut = "; use --backend cpu";

std::string version_string(uint32_t v) {
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) + "." +
         std::to_string(VK_API_VERSION_PATCH(v));
}

const char* type_name(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete GPU";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated GPU";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual GPU";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "CPU";
    default: return "other";
  }
}

// Preference among suitable devices: discrete first, CPU implementations last.
int type_rank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 4;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 3;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return 1;
    default: return 0;
  }
}

bool env_flag(const char* name) {
  const char* v = std::getenv(name);
  return v && *v && std::strcmp(v, "0") != 0 && std::strcmp(v, "false") != 0 && std::strcmp(v, "off") != 0;
}

VKAPI_ATTR VkBool32 VKAPI_CALL debug_callback(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                              VkDebugUtilsMessageTypeFlagsEXT,
                                              const VkDebugUtilsMessengerCallbackDataEXT* data,
                                              void* user) {
  static_cast<Context*>(user)->on_message(severity, data && data->pMessage ? data->pMessage : "(no text)");
  return VK_FALSE;
}

// The device extensions the ray tracing side by side needs (vulkan/rtx.h).
constexpr const char* kRayTracingExtensions[] = {VK_KHR_ACCELERATION_STRUCTURE_EXTENSION_NAME,
                                                  VK_KHR_RAY_TRACING_PIPELINE_EXTENSION_NAME,
                                                  VK_KHR_DEFERRED_HOST_OPERATIONS_EXTENSION_NAME};

// What `pd` lacks of them (extensions, then features), "" if nothing. Features are queried only
// where the extensions are present, so nothing unknown is chained on other devices.
std::string ray_tracing_missing(VkPhysicalDevice pd, const DeviceInfo& info) {
  if (info.api_version < VK_API_VERSION_1_2) return "Vulkan 1.2";
  uint32_t n = 0;
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &n, nullptr);
  std::vector<VkExtensionProperties> exts(n);
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &n, exts.data());
  exts.resize(n);
  std::string missing;
  for (const char* want : kRayTracingExtensions)
    if (std::none_of(exts.begin(), exts.end(),
                     [&](const VkExtensionProperties& e) { return std::strcmp(e.extensionName, want) == 0; }))
      missing += std::string(missing.empty() ? "" : ", ") + want;
  if (!missing.empty()) return missing;
  VkPhysicalDeviceRayTracingPipelineFeaturesKHR rtp{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR};
  VkPhysicalDeviceAccelerationStructureFeaturesKHR as{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
  as.pNext = &rtp;
  VkPhysicalDeviceVulkan12Features v12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  v12.pNext = &as;
  VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2.pNext = &v12;
  vkGetPhysicalDeviceFeatures2(pd, &f2);
  if (!v12.bufferDeviceAddress) missing += "feature bufferDeviceAddress";
  if (!as.accelerationStructure) missing += std::string(missing.empty() ? "" : ", ") + "feature accelerationStructure";
  if (!rtp.rayTracingPipeline) missing += std::string(missing.empty() ? "" : ", ") + "feature rayTracingPipeline";
  return missing;
}

DeviceInfo query_info(VkPhysicalDevice pd) {
  DeviceInfo info;
  VkPhysicalDeviceVulkan12Properties p12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_PROPERTIES};
  VkPhysicalDeviceVulkan11Properties p11{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_PROPERTIES};
  p11.pNext = &p12;
  VkPhysicalDeviceProperties2 props{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props.pNext = &p11;
  // Properties2 and the 1.1/1.2 structs need a 1.2 device; older ones get the 1.0 query only.
  VkPhysicalDeviceProperties p0{};
  vkGetPhysicalDeviceProperties(pd, &p0);
  info.name = p0.deviceName;
  info.type = p0.deviceType;
  info.api_version = p0.apiVersion;
  info.limits = p0.limits;
  if (p0.apiVersion >= VK_API_VERSION_1_2) {
    vkGetPhysicalDeviceProperties2(pd, &props);
    info.driver = std::string(p12.driverName) + " " + p12.driverInfo;
    info.driver_id = p12.driverID;
    info.denorm_preserve_f32 = p12.shaderDenormPreserveFloat32;
    info.denorm_flush_to_zero_f32 = p12.shaderDenormFlushToZeroFloat32;
    info.signed_zero_inf_nan_preserve_f32 = p12.shaderSignedZeroInfNanPreserveFloat32;
    info.subgroup_size = p11.subgroupSize;
    info.max_memory_allocation = p11.maxMemoryAllocationSize;
    const VkSubgroupFeatureFlags ops = VK_SUBGROUP_FEATURE_BASIC_BIT | VK_SUBGROUP_FEATURE_ARITHMETIC_BIT |
                                       VK_SUBGROUP_FEATURE_BALLOT_BIT;
    info.subgroup_arithmetic_ballot =
        (p11.subgroupSupportedOperations & ops) == ops && (p11.subgroupSupportedStages & VK_SHADER_STAGE_COMPUTE_BIT);
    VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    f2.pNext = &f12;
    vkGetPhysicalDeviceFeatures2(pd, &f2);
    info.buffer_int64_atomics = f2.features.shaderInt64 && f12.shaderBufferInt64Atomics;
  }
  VkPhysicalDeviceFeatures f{};
  vkGetPhysicalDeviceFeatures(pd, &f);
  info.geometry_shader = f.geometryShader;
  info.vertex_pipeline_stores_and_atomics = f.vertexPipelineStoresAndAtomics;
  info.fragment_stores_and_atomics = f.fragmentStoresAndAtomics;
  VkPhysicalDeviceMemoryProperties mem{};
  vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  for (uint32_t h = 0; h < mem.memoryHeapCount; ++h)
    if (mem.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
      info.device_local_heap = std::max(info.device_local_heap, mem.memoryHeaps[h].size);
  info.ray_tracing_missing = ray_tracing_missing(pd, info);
  return info;
}

// The queue family that does graphics and compute, or ~0u.
uint32_t find_queue_family(VkPhysicalDevice pd, uint32_t* timestamp_bits) {
  uint32_t n = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, nullptr);
  std::vector<VkQueueFamilyProperties> families(n);
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, families.data());
  const VkQueueFlags want = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
  for (uint32_t i = 0; i < n; ++i)
    if ((families[i].queueFlags & want) == want && families[i].queueCount > 0) {
      if (timestamp_bits) *timestamp_bits = families[i].timestampValidBits;
      return i;
    }
  return ~0u;
}

// Why `pd` cannot run gridrt ("" if it can).
std::string unsuitable(VkPhysicalDevice pd, const DeviceInfo& info, const ContextOptions& options) {
  std::vector<std::string> why;
  if (info.api_version < VK_API_VERSION_1_2)
    why.push_back("Vulkan " + version_string(info.api_version) + " < 1.2");
  if (find_queue_family(pd, nullptr) == ~0u) why.push_back("no queue family with graphics and compute");
  if (options.raster_build && !info.geometry_shader)
    why.push_back("no geometryShader (the raster build needs it; use the compute build)");
  if (options.raster_build && !info.vertex_pipeline_stores_and_atomics)
    why.push_back("no vertexPipelineStoresAndAtomics (the raster build needs it; use the compute build)");
  VkFormatProperties fp{};
  vkGetPhysicalDeviceFormatProperties(pd, VK_FORMAT_R32_UINT, &fp);
  const VkFormatFeatureFlags img = VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT | VK_FORMAT_FEATURE_STORAGE_IMAGE_ATOMIC_BIT;
  if ((fp.optimalTilingFeatures & img) != img) why.push_back("R32_UINT storage images without atomics");
  std::string s;
  for (const std::string& w : why) s += (s.empty() ? "" : ", ") + w;
  return s;
}

}  // namespace

ContextOptions ContextOptions::from_env() {
  ContextOptions o;
  o.validation = env_flag("GRIDRT_VALIDATION");
  if (const char* v = std::getenv("GRIDRT_VALIDATION"); v && std::strcmp(v, "best-practices") == 0)
    o.validation = o.best_practices = true;
  if (const char* d = std::getenv("GRIDRT_VK_DEVICE"); d && *d) {
    char* end = nullptr;
    errno = 0;
    const long v = std::strtol(d, &end, 10);
    // Past int's range it wrapped to another device or to "any" (an outside sweep)
    if (*end != '\0' || v < 0 || errno == ERANGE || v > 65535 || !std::isdigit(static_cast<unsigned char>(*d)))
      throw Error(std::string("GRIDRT_VK_DEVICE=") + d + " is not a device index (a whole number from 0 to 65535)");
    o.device_index = int(v);
  }
  if (const char* l = std::getenv("GRIDRT_VK_LOADER"); l && *l) o.loader_path = l;
  o.pipeline_stats = env_flag("GRIDRT_VK_PIPELINE_STATS");
  return o;
}

std::string DeviceInfo::summary() const {
  std::ostringstream s;
  s << name << " (" << type_name(type) << ", Vulkan " << version_string(api_version) << ", " << driver
    << "): maxImageDimension3D " << limits.maxImageDimension3D << ", maxStorageBufferRange "
    << limits.maxStorageBufferRange << ", maxMemoryAllocationSize " << max_memory_allocation
    << ", device-local heap " << device_local_heap << ", geometryShader " << geometry_shader
    << ", int64 buffer atomics " << buffer_int64_atomics
    << ", vertexPipelineStoresAndAtomics " << vertex_pipeline_stores_and_atomics
    << ", shaderDenormPreserveFloat32 " << denorm_preserve_f32 << ", shaderDenormFlushToZeroFloat32 "
    << denorm_flush_to_zero_f32 << ", shaderSignedZeroInfNanPreserveFloat32 " << signed_zero_inf_nan_preserve_f32
    << ", subgroup size " << subgroup_size << ", timestamp valid bits " << timestamp_valid_bits
    << ", timestampPeriod " << limits.timestampPeriod << " ns, ray tracing pipeline "
    << (ray_tracing_missing.empty() ? std::string("yes") : "no (" + ray_tracing_missing + ")");
  return s.str();
}

// ---- Buffer, Image3D ----

Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    reset();
    device = std::exchange(o.device, VK_NULL_HANDLE);
    buffer = std::exchange(o.buffer, VK_NULL_HANDLE);
    memory = std::exchange(o.memory, VK_NULL_HANDLE);
    size = std::exchange(o.size, 0);
    mapped = std::exchange(o.mapped, nullptr);
  }
  return *this;
}

void Buffer::reset() {
  if (device) {
    if (buffer) vkDestroyBuffer(device, buffer, nullptr);
    if (memory) vkFreeMemory(device, memory, nullptr);  // unmaps implicitly
  }
  device = VK_NULL_HANDLE, buffer = VK_NULL_HANDLE, memory = VK_NULL_HANDLE, size = 0, mapped = nullptr;
}

Image3D& Image3D::operator=(Image3D&& o) noexcept {
  if (this != &o) {
    reset();
    device = std::exchange(o.device, VK_NULL_HANDLE);
    image = std::exchange(o.image, VK_NULL_HANDLE);
    view = std::exchange(o.view, VK_NULL_HANDLE);
    memory = std::exchange(o.memory, VK_NULL_HANDLE);
    extent = std::exchange(o.extent, glm::uvec3(0));
  }
  return *this;
}

void Image3D::reset() {
  if (device) {
    if (view) vkDestroyImageView(device, view, nullptr);
    if (image) vkDestroyImage(device, image, nullptr);
    if (memory) vkFreeMemory(device, memory, nullptr);
  }
  device = VK_NULL_HANDLE, image = VK_NULL_HANDLE, view = VK_NULL_HANDLE, memory = VK_NULL_HANDLE;
  extent = glm::uvec3(0);
}

// ---- Context ----

namespace {
// A layout transition of the whole image that also orders every earlier access before every
// later one (the images are small in number and the transitions rare: downloads and uploads).
void transition(VkCommandBuffer cb, VkImage image, VkImageLayout from, VkImageLayout to) {
  VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  b.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
  b.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image;
  b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
  vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 0, nullptr, 0,
                       nullptr, 1, &b);
}
}  // namespace

Context::Context(const ContextOptions& options) {
  try {
    load_global_functions(options.loader_path);
    create_instance(options);
    load_instance_functions(instance_);
    choose_physical_device(options);
    create_device(options);
  } catch (...) {
    destroy();
    throw;
  }
}

Context::~Context() { destroy(); }

void Context::destroy() {
  if (device_) {
    vkDeviceWaitIdle(device_);
    if (fence_) vkDestroyFence(device_, fence_, nullptr);
    if (pool_) vkDestroyCommandPool(device_, pool_, nullptr);
    vkDestroyDevice(device_, nullptr);
  }
  if (messenger_ && destroy_messenger_) destroy_messenger_(instance_, messenger_, nullptr);
  if (instance_) vkDestroyInstance(instance_, nullptr);
  device_ = VK_NULL_HANDLE, fence_ = VK_NULL_HANDLE, pool_ = VK_NULL_HANDLE;
  messenger_ = VK_NULL_HANDLE, instance_ = VK_NULL_HANDLE;
}

void Context::create_instance(const ContextOptions& options) {
  uint32_t version = VK_API_VERSION_1_0;
  if (vkEnumerateInstanceVersion) vkEnumerateInstanceVersion(&version);
  if (version < VK_API_VERSION_1_2)
    throw Error("no Vulkan device: the Vulkan loader offers version " + version_string(version) +
                ", gridrt needs 1.2" + kWayOut);

  std::vector<const char*> layers, extensions;
  validation_ = options.validation;
  bool validation_features = false;
  if (validation_) {
    uint32_t n = 0;
    vkEnumerateInstanceLayerProperties(&n, nullptr);
    std::vector<VkLayerProperties> available(n);
    vkEnumerateInstanceLayerProperties(&n, available.data());
    const bool found = std::any_of(available.begin(), available.end(),
                                   [](const VkLayerProperties& l) { return std::strcmp(l.layerName, kValidationLayer) == 0; });
    if (!found)
      throw Error(std::string("validation requested but ") + kValidationLayer +
                  " is not installed (Debian: vulkan-validationlayers); unset GRIDRT_VALIDATION");
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    // The layer's own extension for enabling synchronization validation.
    uint32_t m = 0;
    vkEnumerateInstanceExtensionProperties(kValidationLayer, &m, nullptr);
    std::vector<VkExtensionProperties> exts(m);
    vkEnumerateInstanceExtensionProperties(kValidationLayer, &m, exts.data());
    for (const VkExtensionProperties& e : exts)
      if (std::strcmp(e.extensionName, VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME) == 0) validation_features = true;
    if (validation_features && (options.sync_validation || options.best_practices))
      extensions.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
  }

  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "gridrt";
  app.pEngineName = "gridrt";
  app.apiVersion = VK_API_VERSION_1_2;

  VkDebugUtilsMessengerCreateInfoEXT messenger{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  messenger.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  messenger.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                          VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  messenger.pfnUserCallback = debug_callback;
  messenger.pUserData = this;

  std::vector<VkValidationFeatureEnableEXT> enables;
  if (options.sync_validation) enables.push_back(VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT);
  if (options.best_practices) enables.push_back(VK_VALIDATION_FEATURE_ENABLE_BEST_PRACTICES_EXT);
  VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
  features.enabledValidationFeatureCount = uint32_t(enables.size());
  features.pEnabledValidationFeatures = enables.data();

  VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ci.pApplicationInfo = &app;
  ci.enabledLayerCount = uint32_t(layers.size());
  ci.ppEnabledLayerNames = layers.data();
  ci.enabledExtensionCount = uint32_t(extensions.size());
  ci.ppEnabledExtensionNames = extensions.data();
  if (validation_) {
    // Messages from vkCreateInstance/vkDestroyInstance themselves come through this one.
    ci.pNext = &messenger;
    if (validation_features && !enables.empty()) messenger.pNext = &features;
  }
  const VkResult r = vkCreateInstance(&ci, nullptr, &instance_);
  if (r != VK_SUCCESS) {
    instance_ = VK_NULL_HANDLE;
    throw Error(std::string("no Vulkan device: vkCreateInstance failed (") + result_name(r) +
                "); is a Vulkan driver installed (Debian: mesa-vulkan-drivers)?" + kWayOut);
  }
  if (validation_) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        instance_proc_addr(instance_, "vkCreateDebugUtilsMessengerEXT"));
    destroy_messenger_ = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        instance_proc_addr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (!create || !destroy_messenger_) throw Error("validation requested but VK_EXT_debug_utils is missing");
    messenger.pNext = nullptr;
    GRIDRT_VK_CHECK(create(instance_, &messenger, nullptr, &messenger_));
  }
}

void Context::choose_physical_device(const ContextOptions& options) {
  uint32_t n = 0;
  GRIDRT_VK_CHECK(vkEnumeratePhysicalDevices(instance_, &n, nullptr));
  std::vector<VkPhysicalDevice> devices(n);
  GRIDRT_VK_CHECK(vkEnumeratePhysicalDevices(instance_, &n, devices.data()));
  devices.resize(n);
  if (devices.empty())
    throw Error(std::string("no Vulkan device: the Vulkan loader found no physical device "
                            "(is a driver installed? Debian: mesa-vulkan-drivers)") + kWayOut);

  std::string report;  // every device and why it was not taken
  int best = -1, best_rank = -1;
  for (uint32_t i = 0; i < n; ++i) {
    const DeviceInfo info = query_info(devices[i]);
    const std::string why = unsuitable(devices[i], info, options);
    report += "\n  [" + std::to_string(i) + "] " + info.name + " (" + type_name(info.type) + ")" +
              (why.empty() ? "" : ": " + why);
    if (options.device_index >= 0) continue;
    if (why.empty() && type_rank(info.type) > best_rank) best = int(i), best_rank = type_rank(info.type);
  }
  if (options.device_index >= 0) {
    if (options.device_index >= int(n))
      throw Error("no Vulkan device: GRIDRT_VK_DEVICE=" + std::to_string(options.device_index) +
                  " but there are only " + std::to_string(n) + " devices:" + report + "\n(choose an index above" +
                  kWayOut + ")");
    const DeviceInfo info = query_info(devices[options.device_index]);
    const std::string why = unsuitable(devices[options.device_index], info, options);
    if (!why.empty())
      throw Error("no Vulkan device: device " + std::to_string(options.device_index) + " (" + info.name +
                  ") is not suitable: " + why + kWayOut);
    best = options.device_index;
  }
  if (best < 0) throw Error("no Vulkan device: no suitable device among:" + report + "\n(" + std::string(kWayOut + 2) + ")");
  physical_ = devices[best];
  info_ = query_info(physical_);
  queue_family_ = find_queue_family(physical_, &info_.timestamp_valid_bits);
  vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);
}

void Context::create_device(const ContextOptions& options) {
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo q{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  q.queueFamilyIndex = queue_family_;
  q.queueCount = 1;
  q.pQueuePriorities = &priority;

  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  f12.shaderBufferInt64Atomics = info_.buffer_int64_atomics ? VK_TRUE : VK_FALSE;
  VkPhysicalDeviceFeatures2 features{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  features.pNext = &f12;
  features.features.geometryShader = options.raster_build ? VK_TRUE : VK_FALSE;
  features.features.vertexPipelineStoresAndAtomics = options.raster_build ? VK_TRUE : VK_FALSE;
  features.features.shaderInt64 = info_.buffer_int64_atomics ? VK_TRUE : VK_FALSE;

  VkDeviceCreateInfo ci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  ci.pNext = &features;
  ci.queueCreateInfoCount = 1;
  ci.pQueueCreateInfos = &q;

  // Ray tracing, only when asked and present: the extensions, and their features chained after
  // the Vulkan 1.2 features (buffer device address)
  ray_tracing_ = options.ray_tracing && info_.ray_tracing_missing.empty();
  VkPhysicalDeviceRayTracingPipelineFeaturesKHR rtp{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR};
  VkPhysicalDeviceAccelerationStructureFeaturesKHR as{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
  if (ray_tracing_) {
    rtp.rayTracingPipeline = VK_TRUE;
    as.accelerationStructure = VK_TRUE;
    as.pNext = &rtp;
    f12.bufferDeviceAddress = VK_TRUE;
    f12.pNext = &as;
    ci.enabledExtensionCount = uint32_t(std::size(kRayTracingExtensions));
    ci.ppEnabledExtensionNames = kRayTracingExtensions;
  }
  // Pipeline statistics, only when asked and present
  std::vector<const char*> extensions(ci.ppEnabledExtensionNames, ci.ppEnabledExtensionNames + ci.enabledExtensionCount);
  VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR pe{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
  if (options.pipeline_stats) {
    uint32_t n = 0;
    vkEnumerateDeviceExtensionProperties(physical_, nullptr, &n, nullptr);
    std::vector<VkExtensionProperties> exts(n);
    vkEnumerateDeviceExtensionProperties(physical_, nullptr, &n, exts.data());
    exts.resize(n);
    pipeline_stats_ = std::any_of(exts.begin(), exts.end(), [](const VkExtensionProperties& e) {
      return std::strcmp(e.extensionName, VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME) == 0;
    });
    if (pipeline_stats_) {
      pe.pipelineExecutableInfo = VK_TRUE;
      pe.pNext = features.pNext;
      features.pNext = &pe;
      extensions.push_back(VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME);
      ci.enabledExtensionCount = uint32_t(extensions.size());
      ci.ppEnabledExtensionNames = extensions.data();
    } else {
      std::fprintf(stderr, "pipeline statistics: %s lacks %s; none reported\n", info_.name.c_str(),
                   VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME);
    }
  }
  const VkResult r = vkCreateDevice(physical_, &ci, nullptr, &device_);
  if (r != VK_SUCCESS) {
    device_ = VK_NULL_HANDLE;
    throw Error("no Vulkan device: vkCreateDevice on " + info_.name + " failed (" + result_name(r) + ")" + kWayOut);
  }
  vkGetDeviceQueue(device_, queue_family_, 0, &queue_);

  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
  pci.queueFamilyIndex = queue_family_;
  GRIDRT_VK_CHECK(vkCreateCommandPool(device_, &pci, nullptr, &pool_));
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  GRIDRT_VK_CHECK(vkCreateFence(device_, &fci, nullptr, &fence_));
}

void Context::report_pipeline_stats(VkPipeline pipeline, const std::string& what) const {
  if (!pipeline_stats_) return;
  const auto properties = reinterpret_cast<PFN_vkGetPipelineExecutablePropertiesKHR>(
      vkGetDeviceProcAddr(device_, "vkGetPipelineExecutablePropertiesKHR"));
  const auto statistics = reinterpret_cast<PFN_vkGetPipelineExecutableStatisticsKHR>(
      vkGetDeviceProcAddr(device_, "vkGetPipelineExecutableStatisticsKHR"));
  if (!properties || !statistics) return;
  VkPipelineInfoKHR pi{VK_STRUCTURE_TYPE_PIPELINE_INFO_KHR};
  pi.pipeline = pipeline;
  uint32_t n = 0;
  if (properties(device_, &pi, &n, nullptr) != VK_SUCCESS) return;
  std::vector<VkPipelineExecutablePropertiesKHR> execs(n, {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_PROPERTIES_KHR});
  if (properties(device_, &pi, &n, execs.data()) != VK_SUCCESS) return;
  for (uint32_t e = 0; e < n; ++e) {
    VkPipelineExecutableInfoKHR ei{VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_INFO_KHR};
    ei.pipeline = pipeline;
    ei.executableIndex = e;
    uint32_t m = 0;
    if (statistics(device_, &ei, &m, nullptr) != VK_SUCCESS) continue;
    std::vector<VkPipelineExecutableStatisticKHR> stats(m, {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_STATISTIC_KHR});
    if (statistics(device_, &ei, &m, stats.data()) != VK_SUCCESS) continue;
    std::ostringstream line;
    line << "pipeline statistics: " << what << " [" << execs[e].name << ", subgroup " << execs[e].subgroupSize << "]";
    for (uint32_t k = 0; k < m; ++k) {
      line << (k ? "; " : ": ") << stats[k].name << " ";
      switch (stats[k].format) {
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_BOOL32_KHR: line << (stats[k].value.b32 ? "true" : "false"); break;
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_INT64_KHR: line << stats[k].value.i64; break;
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_UINT64_KHR: line << stats[k].value.u64; break;
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_FLOAT64_KHR: line << stats[k].value.f64; break;
        default: line << "?";
      }
    }
    std::fprintf(stderr, "%s\n", line.str().c_str());
  }
}

void Context::on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity, const char* text) {
  std::lock_guard lock(messages_mutex_);
  messages_.push_back(std::string(severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "error: " : "warning: ") + text);
}

std::vector<std::string> Context::messages() const {
  std::lock_guard lock(messages_mutex_);
  return messages_;
}

size_t Context::message_count() const {
  std::lock_guard lock(messages_mutex_);
  return messages_.size();
}

void Context::clear_messages() {
  std::lock_guard lock(messages_mutex_);
  messages_.clear();
}

void Context::submit(const std::function<void(VkCommandBuffer)>& record) {
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cb = VK_NULL_HANDLE;
  GRIDRT_VK_CHECK(vkAllocateCommandBuffers(device_, &ai, &cb));
  struct Free {
    VkDevice d;
    VkCommandPool p;
    VkCommandBuffer c;
    ~Free() { vkFreeCommandBuffers(d, p, 1, &c); }
  } free_cb{device_, pool_, cb};

  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  GRIDRT_VK_CHECK(vkBeginCommandBuffer(cb, &bi));
  record(cb);
  // Every device write visible to the host once the fence signals.
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &mb, 0, nullptr, 0, nullptr);
  GRIDRT_VK_CHECK(vkEndCommandBuffer(cb));

  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cb;
  GRIDRT_VK_CHECK(vkResetFences(device_, 1, &fence_));
  GRIDRT_VK_CHECK(vkQueueSubmit(queue_, 1, &si, fence_));
  // Waited on a second at a time, with a line on stderr past the first: one submission (a whole
  // frame of a large scene on lavapipe: a minute or more) had no progress line
  Progress progress("vulkan: " + info_.name + " at work on one submission", 0, true);
  for (;;) {
    const VkResult r = vkWaitForFences(device_, 1, &fence_, VK_TRUE, 1000000000ull);
    if (r == VK_SUCCESS) break;
    if (r != VK_TIMEOUT) GRIDRT_VK_CHECK(r);
    progress.advance();
  }
}

uint32_t Context::memory_type(uint32_t type_bits, VkMemoryPropertyFlags required, VkMemoryPropertyFlags avoid) const {
  uint32_t fallback = ~0u;
  for (uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
    if (!(type_bits & (1u << i))) continue;
    const VkMemoryPropertyFlags f = memory_.memoryTypes[i].propertyFlags;
    if ((f & required) != required) continue;
    if (!(f & avoid)) return i;
    if (fallback == ~0u) fallback = i;
  }
  return fallback;
}

VkDeviceMemory Context::allocate(const VkMemoryRequirements& req, Memory where, void** mapped, bool device_address) {
  const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  uint32_t type = where == Memory::Host
                      ? memory_type(req.memoryTypeBits, host, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT)
                      : memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT);
  if (type == ~0u) type = memory_type(req.memoryTypeBits, 0);
  if (type == ~0u) throw Error("no memory type for an allocation of " + std::to_string(req.size) + " bytes");
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = type;
  VkMemoryAllocateFlagsInfo flags{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
  flags.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
  if (device_address) ai.pNext = &flags;
  VkDeviceMemory mem = VK_NULL_HANDLE;
  const VkResult r = vkAllocateMemory(device_, &ai, nullptr, &mem);
  if (r != VK_SUCCESS)
    throw Error("vkAllocateMemory of " + std::to_string(req.size) + " bytes failed (" + result_name(r) +
                "): use a coarser grid or a smaller capacity, or --backend cpu");
  if (mapped) {
    *mapped = nullptr;
    if ((memory_.memoryTypes[type].propertyFlags & host) == host) {
      const VkResult m = vkMapMemory(device_, mem, 0, VK_WHOLE_SIZE, 0, mapped);
      if (m != VK_SUCCESS) {
        vkFreeMemory(device_, mem, nullptr);
        check(m, "vkMapMemory");
      }
    }
  }
  return mem;
}

void Context::require_allocation(VkDeviceSize bytes, const char* what) const {
  auto fail = [&](const char* limit, VkDeviceSize value) {
    throw Error(std::string(what) + " needs " + std::to_string(bytes) + " bytes, over the device's " + limit + " (" +
                std::to_string(value) + ") on " + info_.name +
                ": use a coarser grid or a smaller capacity, or --backend cpu");
  };
  if (info_.max_memory_allocation && bytes > info_.max_memory_allocation) fail("maxMemoryAllocationSize", info_.max_memory_allocation);
  if (info_.device_local_heap && bytes > info_.device_local_heap) fail("device-local heap", info_.device_local_heap);
}

Buffer Context::create_buffer(VkDeviceSize size, VkBufferUsageFlags usage, Memory where, const char* what) {
  size = std::max<VkDeviceSize>(size, 4);
  require_allocation(size, "a buffer");
  if ((usage & VK_BUFFER_USAGE_STORAGE_BUFFER_BIT) && size > info_.limits.maxStorageBufferRange)
    throw Error("a storage buffer of " + std::to_string(size) + " bytes" + (what ? std::string(" (") + what + ")" : "") +
                " exceeds maxStorageBufferRange (" + std::to_string(info_.limits.maxStorageBufferRange) + ") on " +
                info_.name +
                (what ? std::string(": use fewer cells (a coarser --resolution or --cell-size) or the compact layout, "
                                    "or --backend cpu")
                      : std::string(": trace fewer rays at once, use a smaller scene, or --backend cpu")));
  Buffer b;
  b.device = device_;
  b.size = size;
  VkBufferCreateInfo ci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  ci.size = size;
  ci.usage = usage | VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  ci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  GRIDRT_VK_CHECK(vkCreateBuffer(device_, &ci, nullptr, &b.buffer));
  VkMemoryRequirements req{};
  vkGetBufferMemoryRequirements(device_, b.buffer, &req);
  const bool device_address = (usage & VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT) != 0;
  if (device_address && !ray_tracing_)
    throw Error("a buffer with a device address needs bufferDeviceAddress, enabled only with ray tracing");
  b.memory = allocate(req, where, &b.mapped, device_address);
  GRIDRT_VK_CHECK(vkBindBufferMemory(device_, b.buffer, b.memory, 0));
  return b;
}

void Context::upload(const Buffer& dst, const void* data, size_t bytes, VkDeviceSize offset) {
  if (bytes == 0) return;
  if (offset + bytes > dst.size) throw Error("upload past the end of a buffer");
  if (dst.mapped) {
    std::memcpy(static_cast<char*>(dst.mapped) + offset, data, bytes);
    return;
  }
  Buffer staging = create_buffer(bytes, 0, Memory::Host);
  std::memcpy(staging.mapped, data, bytes);
  submit([&](VkCommandBuffer cb) {
    const VkBufferCopy region{0, offset, bytes};
    vkCmdCopyBuffer(cb, staging.buffer, dst.buffer, 1, &region);
  });
}

void Context::download(const Buffer& src, void* data, size_t bytes, VkDeviceSize offset) {
  if (bytes == 0) return;
  if (offset + bytes > src.size) throw Error("download past the end of a buffer");
  if (src.mapped) {
    std::memcpy(data, static_cast<const char*>(src.mapped) + offset, bytes);
    return;
  }
  Buffer staging = create_buffer(bytes, 0, Memory::Host);
  submit([&](VkCommandBuffer cb) {
    const VkBufferCopy region{offset, 0, bytes};
    vkCmdCopyBuffer(cb, src.buffer, staging.buffer, 1, &region);
  });
  std::memcpy(data, staging.mapped, bytes);
}

void Context::require_image3d(glm::uvec3 extent) const {
  const uint32_t max3d = info_.limits.maxImageDimension3D;
  const char* axis[3] = {"x (cells_x * (capacity + 1))", "y (cells_y)", "z (cells_z)"};
  for (int a = 0; a < 3; ++a) {
    if (extent[a] == 0) throw Error("a 3D image with a zero extent");
    if (extent[a] > max3d)
      throw Error("the grid image is " + std::to_string(extent.x) + "x" + std::to_string(extent.y) + "x" +
                  std::to_string(extent.z) + " texels; its " + axis[a] + " exceeds maxImageDimension3D (" +
                  std::to_string(max3d) + ") on " + info_.name +
                  ": use fewer cells or a smaller capacity (--grid-resolution, --capacity), or --backend cpu");
  }
  VkImageFormatProperties p{};
  const VkResult r = vkGetPhysicalDeviceImageFormatProperties(
      physical_, VK_FORMAT_R32_UINT, VK_IMAGE_TYPE_3D, VK_IMAGE_TILING_OPTIMAL,
      VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, 0, &p);
  if (r != VK_SUCCESS) throw Error(std::string("R32_UINT 3D storage images are not supported on ") + info_.name + kWayOut);
  if (extent.x > p.maxExtent.width || extent.y > p.maxExtent.height || extent.z > p.maxExtent.depth)
    throw Error("the grid image exceeds the R32_UINT 3D image limit (" + std::to_string(p.maxExtent.width) + "x" +
                std::to_string(p.maxExtent.height) + "x" + std::to_string(p.maxExtent.depth) + ") on " + info_.name +
                ": use fewer cells or a smaller capacity, or --backend cpu");
  const VkDeviceSize bytes = VkDeviceSize(extent.x) * extent.y * extent.z * 4;
  if (bytes > p.maxResourceSize)
    throw Error("the grid image needs " + std::to_string(bytes) + " bytes, over maxResourceSize (" +
                std::to_string(p.maxResourceSize) + ") on " + info_.name +
                ": use fewer cells or a smaller capacity, or --backend cpu");
  require_allocation(bytes, "the grid image");
}

Image3D Context::create_image(VkImageType type, VkFormat format, glm::uvec3 extent, VkImageUsageFlags usage,
                              VkImageAspectFlags aspect, const char* what) {
  Image3D img;
  img.device = device_;
  img.extent = extent;
  VkImageCreateInfo ci{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  ci.imageType = type;
  ci.format = format;
  ci.extent = {extent.x, extent.y, extent.z};
  ci.mipLevels = 1;
  ci.arrayLayers = 1;
  ci.samples = VK_SAMPLE_COUNT_1_BIT;
  ci.tiling = VK_IMAGE_TILING_OPTIMAL;
  ci.usage = usage;
  ci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ci.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  GRIDRT_VK_CHECK(vkCreateImage(device_, &ci, nullptr, &img.image));
  VkMemoryRequirements req{};
  vkGetImageMemoryRequirements(device_, img.image, &req);
  if (what) require_allocation(req.size, what);
  img.memory = allocate(req, Memory::Device, nullptr);
  GRIDRT_VK_CHECK(vkBindImageMemory(device_, img.image, img.memory, 0));

  VkImageViewCreateInfo vi{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  vi.image = img.image;
  vi.viewType = type == VK_IMAGE_TYPE_3D ? VK_IMAGE_VIEW_TYPE_3D : VK_IMAGE_VIEW_TYPE_2D;
  vi.format = format;
  vi.subresourceRange = {aspect, 0, 1, 0, 1};
  GRIDRT_VK_CHECK(vkCreateImageView(device_, &vi, nullptr, &img.view));
  return img;
}

Image3D Context::create_image3d(glm::uvec3 extent) {
  require_image3d(extent);
  Image3D img = create_image(VK_IMAGE_TYPE_3D, VK_FORMAT_R32_UINT, extent,
                             VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT);

  // The image lives in GENERAL from here on: storage access and transfers alike.
  submit([&](VkCommandBuffer cb) {
    VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
    b.srcAccessMask = 0;
    b.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
    b.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    b.newLayout = VK_IMAGE_LAYOUT_GENERAL;
    b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = img.image;
    b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 0, nullptr, 0,
                         nullptr, 1, &b);
  });
  return img;
}

void Context::clear(const Image3D& image, uint32_t value) {
  submit([&](VkCommandBuffer cb) {
    VkClearColorValue c{};
    c.uint32[0] = c.uint32[1] = c.uint32[2] = c.uint32[3] = value;
    const VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    transition(cb, image.image, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
    vkCmdClearColorImage(cb, image.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &c, 1, &range);
    transition(cb, image.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
  });
}

void Context::upload(const Image3D& image, std::span<const uint32_t> texels) {
  if (texels.size() != image.texel_count()) throw Error("image upload of the wrong size");
  Buffer staging = create_buffer(texels.size_bytes(), 0, Memory::Host);
  std::memcpy(staging.mapped, texels.data(), texels.size_bytes());
  submit([&](VkCommandBuffer cb) {
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {image.extent.x, image.extent.y, image.extent.z};
    transition(cb, image.image, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
    vkCmdCopyBufferToImage(cb, staging.buffer, image.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
    transition(cb, image.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
  });
}

std::vector<uint32_t> Context::download(const Image3D& image) {
  std::vector<uint32_t> out(image.texel_count());
  Buffer staging = create_buffer(out.size() * 4, 0, Memory::Host);
  submit([&](VkCommandBuffer cb) {
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {image.extent.x, image.extent.y, image.extent.z};
    transition(cb, image.image, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    vkCmdCopyImageToBuffer(cb, image.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, staging.buffer, 1, &region);
    transition(cb, image.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
  });
  std::memcpy(out.data(), staging.mapped, out.size() * 4);
  return out;
}

void barrier(VkCommandBuffer cb, VkPipelineStageFlags src, VkPipelineStageFlags dst) {
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
  vkCmdPipelineBarrier(cb, src, dst, 0, 1, &mb, 0, nullptr, 0, nullptr);
}

// ---- Timestamps ----

Timestamps::Timestamps(Context& ctx, uint32_t count) : ctx_(ctx), count_(count) {
  if (ctx.info().timestamp_valid_bits == 0 || ctx.info().limits.timestampPeriod <= 0.0f)
    throw Error("the queue of " + ctx.info().name + " has no timestamps (timestampValidBits 0): time on the host instead");
  VkQueryPoolCreateInfo ci{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  ci.queryType = VK_QUERY_TYPE_TIMESTAMP;
  ci.queryCount = count;
  GRIDRT_VK_CHECK(vkCreateQueryPool(ctx.device(), &ci, nullptr, &pool_));
}

Timestamps::~Timestamps() {
  if (pool_) vkDestroyQueryPool(ctx_.device(), pool_, nullptr);
}

void Timestamps::reset(VkCommandBuffer cb) { vkCmdResetQueryPool(cb, pool_, 0, count_); }

void Timestamps::write(VkCommandBuffer cb, uint32_t index, VkPipelineStageFlagBits stage) {
  vkCmdWriteTimestamp(cb, stage, pool_, index);
}

std::vector<double> Timestamps::read_ns() {
  std::vector<uint64_t> raw(count_);
  GRIDRT_VK_CHECK(vkGetQueryPoolResults(ctx_.device(), pool_, 0, count_, raw.size() * 8, raw.data(), 8,
                                        VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
  const uint32_t bits = ctx_.info().timestamp_valid_bits;
  const uint64_t mask = bits >= 64 ? ~0ull : ((1ull << bits) - 1);
  std::vector<double> ns(count_);
  for (uint32_t i = 0; i < count_; ++i) ns[i] = double(raw[i] & mask) * ctx_.info().limits.timestampPeriod;
  return ns;
}

double Timestamps::elapsed_ms(uint32_t a, uint32_t b) {
  const std::vector<double> ns = read_ns();
  const uint32_t bits = ctx_.info().timestamp_valid_bits;
  double d = ns[b] - ns[a];
  if (d < 0 && bits < 64) d += double(1ull << bits) * ctx_.info().limits.timestampPeriod;  // wrapped
  return d * 1e-6;
}

}  // namespace gridrt::vulkan
