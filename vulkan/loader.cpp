// loader.cpp: run-time loading of the Vulkan entry points (see loader.h).
#include "gridrt/vulkan/loader.h"

#include <dlfcn.h>

#include <mutex>

#include "gridrt/common/scene.h"

namespace gridrt::vulkan {

#define GRIDRT_VK_DEFINE(name) PFN_##name name = nullptr;
GRIDRT_VK_GLOBAL_FUNCTIONS(GRIDRT_VK_DEFINE)
GRIDRT_VK_INSTANCE_FUNCTIONS(GRIDRT_VK_DEFINE)
#undef GRIDRT_VK_DEFINE

namespace {
std::mutex g_mutex;
void* g_library = nullptr;
PFN_vkGetInstanceProcAddr g_get_instance_proc_addr = nullptr;
bool g_instance_functions = false;
}  // namespace

void load_global_functions(const std::string& path) {
  std::lock_guard lock(g_mutex);
  if (g_library) return;
  const std::string file = path.empty() ? "libvulkan.so.1" : path;
  void* lib = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!lib) {
    const char* why = dlerror();
    throw Error("no Vulkan device: the Vulkan loader (" + file + ") cannot be opened (" +
                (why ? why : "unknown reason") +
                "); install libvulkan1 and a Vulkan driver, or use --backend cpu");
  }
  auto gipa = reinterpret_cast<PFN_vkGetInstanceProcAddr>(dlsym(lib, "vkGetInstanceProcAddr"));
  if (!gipa) {
    dlclose(lib);
    throw Error("no Vulkan device: " + file + " has no vkGetInstanceProcAddr; use --backend cpu");
  }
#define GRIDRT_VK_LOAD(name) name = reinterpret_cast<PFN_##name>(gipa(nullptr, #name));
  GRIDRT_VK_GLOBAL_FUNCTIONS(GRIDRT_VK_LOAD)
#undef GRIDRT_VK_LOAD
  if (!vkCreateInstance || !vkEnumerateInstanceExtensionProperties || !vkEnumerateInstanceLayerProperties) {
    dlclose(lib);
    throw Error("no Vulkan device: " + file + " lacks core entry points; use --backend cpu");
  }
  g_library = lib;
  g_get_instance_proc_addr = gipa;
}

void load_instance_functions(VkInstance instance) {
  std::lock_guard lock(g_mutex);
  if (g_instance_functions) return;
  std::string missing;
#define GRIDRT_VK_LOAD(name)                                                       \
  name = reinterpret_cast<PFN_##name>(g_get_instance_proc_addr(instance, #name)); \
  if (!name) missing += std::string(missing.empty() ? "" : ", ") + #name;
  GRIDRT_VK_INSTANCE_FUNCTIONS(GRIDRT_VK_LOAD)
#undef GRIDRT_VK_LOAD
  if (!missing.empty())
    throw Error("no Vulkan device: the Vulkan loader lacks " + missing +
                " (Vulkan 1.2 is needed); use --backend cpu");
  g_instance_functions = true;
}

PFN_vkVoidFunction instance_proc_addr(VkInstance instance, const char* name) {
  return g_get_instance_proc_addr ? g_get_instance_proc_addr(instance, name) : nullptr;
}

const char* result_name(VkResult r) {
  switch (r) {
#define GRIDRT_CASE(x) case x: return #x;
    GRIDRT_CASE(VK_SUCCESS)
    GRIDRT_CASE(VK_NOT_READY)
    GRIDRT_CASE(VK_TIMEOUT)
    GRIDRT_CASE(VK_EVENT_SET)
    GRIDRT_CASE(VK_EVENT_RESET)
    GRIDRT_CASE(VK_INCOMPLETE)
    GRIDRT_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
    GRIDRT_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    GRIDRT_CASE(VK_ERROR_INITIALIZATION_FAILED)
    GRIDRT_CASE(VK_ERROR_DEVICE_LOST)
    GRIDRT_CASE(VK_ERROR_MEMORY_MAP_FAILED)
    GRIDRT_CASE(VK_ERROR_LAYER_NOT_PRESENT)
    GRIDRT_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
    GRIDRT_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
    GRIDRT_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
    GRIDRT_CASE(VK_ERROR_TOO_MANY_OBJECTS)
    GRIDRT_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
    GRIDRT_CASE(VK_ERROR_FRAGMENTED_POOL)
    GRIDRT_CASE(VK_ERROR_UNKNOWN)
    GRIDRT_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
    GRIDRT_CASE(VK_ERROR_INVALID_EXTERNAL_HANDLE)
    GRIDRT_CASE(VK_ERROR_FRAGMENTATION)
    GRIDRT_CASE(VK_ERROR_INVALID_OPAQUE_CAPTURE_ADDRESS)
#undef GRIDRT_CASE
    default: return "VkResult(?)";
  }
}

}  // namespace gridrt::vulkan
