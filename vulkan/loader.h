// loader.h: the Vulkan entry points gridrt uses, loaded at run time from the system's Vulkan
// loader (libvulkan.so.1, opened with dlopen) instead of being linked: a machine without Vulkan
// still runs the CPU backend, and asking for the Vulkan one there is a clear Error, not a failure
// to start the program.
//
// Each function is a pointer of the same name in namespace gridrt::vulkan (the headers are
// compiled with VK_NO_PROTOTYPES), so code in that namespace calls vkCmdDispatch(...) as usual.
// Device-level functions are fetched with vkGetInstanceProcAddr: the loader's trampolines, valid
// for every device of every instance (several contexts may live at once).
#pragma once

#include <string>

#include <vulkan/vulkan.h>

// Functions that need no instance.
#define GRIDRT_VK_GLOBAL_FUNCTIONS(X)     \
  X(vkEnumerateInstanceVersion)           \
  X(vkEnumerateInstanceLayerProperties)   \
  X(vkEnumerateInstanceExtensionProperties) \
  X(vkCreateInstance)

// Instance- and device-level core functions (Vulkan 1.0-1.2).
#define GRIDRT_VK_INSTANCE_FUNCTIONS(X)          \
  X(vkDestroyInstance)                           \
  X(vkEnumeratePhysicalDevices)                  \
  X(vkGetPhysicalDeviceProperties)               \
  X(vkGetPhysicalDeviceProperties2)              \
  X(vkGetPhysicalDeviceFeatures)                 \
  X(vkGetPhysicalDeviceFeatures2)                \
  X(vkGetPhysicalDeviceMemoryProperties)         \
  X(vkGetPhysicalDeviceQueueFamilyProperties)    \
  X(vkGetPhysicalDeviceFormatProperties)         \
  X(vkGetPhysicalDeviceImageFormatProperties)    \
  X(vkEnumerateDeviceExtensionProperties)        \
  X(vkCreateDevice)                              \
  X(vkGetDeviceProcAddr)                         \
  X(vkDestroyDevice)                             \
  X(vkGetDeviceQueue)                            \
  X(vkDeviceWaitIdle)                            \
  X(vkQueueSubmit)                               \
  X(vkQueueWaitIdle)                             \
  X(vkCreateCommandPool)                         \
  X(vkDestroyCommandPool)                        \
  X(vkResetCommandPool)                          \
  X(vkAllocateCommandBuffers)                    \
  X(vkFreeCommandBuffers)                        \
  X(vkBeginCommandBuffer)                        \
  X(vkEndCommandBuffer)                          \
  X(vkCreateFence)                               \
  X(vkDestroyFence)                              \
  X(vkWaitForFences)                             \
  X(vkResetFences)                               \
  X(vkCreateBuffer)                              \
  X(vkDestroyBuffer)                             \
  X(vkGetBufferMemoryRequirements)               \
  X(vkBindBufferMemory)                          \
  X(vkCreateImage)                               \
  X(vkDestroyImage)                              \
  X(vkGetImageMemoryRequirements)                \
  X(vkBindImageMemory)                           \
  X(vkCreateImageView)                           \
  X(vkDestroyImageView)                          \
  X(vkAllocateMemory)                            \
  X(vkFreeMemory)                                \
  X(vkMapMemory)                                 \
  X(vkUnmapMemory)                               \
  X(vkCreateShaderModule)                        \
  X(vkDestroyShaderModule)                       \
  X(vkCreateDescriptorSetLayout)                 \
  X(vkDestroyDescriptorSetLayout)                \
  X(vkCreateDescriptorPool)                      \
  X(vkDestroyDescriptorPool)                     \
  X(vkAllocateDescriptorSets)                    \
  X(vkUpdateDescriptorSets)                      \
  X(vkCreatePipelineLayout)                      \
  X(vkDestroyPipelineLayout)                     \
  X(vkCreateComputePipelines)                    \
  X(vkCreateGraphicsPipelines)                   \
  X(vkDestroyPipeline)                           \
  X(vkCreateRenderPass)                          \
  X(vkDestroyRenderPass)                         \
  X(vkCreateFramebuffer)                         \
  X(vkDestroyFramebuffer)                        \
  X(vkCreateQueryPool)                           \
  X(vkDestroyQueryPool)                          \
  X(vkGetQueryPoolResults)                       \
  X(vkCmdResetQueryPool)                         \
  X(vkCmdWriteTimestamp)                         \
  X(vkCmdBindPipeline)                           \
  X(vkCmdBindDescriptorSets)                     \
  X(vkCmdPushConstants)                          \
  X(vkCmdDispatch)                               \
  X(vkCmdDispatchIndirect)                       \
  X(vkCmdDraw)                                   \
  X(vkCmdBeginRenderPass)                        \
  X(vkCmdEndRenderPass)                          \
  X(vkCmdPipelineBarrier)                        \
  X(vkCmdCopyBuffer)                             \
  X(vkCmdCopyBufferToImage)                      \
  X(vkCmdCopyImageToBuffer)                      \
  X(vkCmdFillBuffer)                             \
  X(vkCmdClearColorImage)

namespace gridrt::vulkan {

#define GRIDRT_VK_DECLARE(name) extern PFN_##name name;
GRIDRT_VK_GLOBAL_FUNCTIONS(GRIDRT_VK_DECLARE)
GRIDRT_VK_INSTANCE_FUNCTIONS(GRIDRT_VK_DECLARE)
#undef GRIDRT_VK_DECLARE

// Opens the loader once (path: "" for libvulkan.so.1, else that file) and fetches the global
// functions. Throws Error("no Vulkan loader: ...") when it cannot be opened. Thread-safe; the
// first successful path wins.
void load_global_functions(const std::string& path = "");

// Fetches the instance- and device-level functions through `instance` (once per process).
void load_instance_functions(VkInstance instance);

// vkGetInstanceProcAddr of the loaded loader (for extension functions such as debug utils).
PFN_vkVoidFunction instance_proc_addr(VkInstance instance, const char* name);

// The name of a VkResult, e.g. "VK_ERROR_OUT_OF_DEVICE_MEMORY".
const char* result_name(VkResult r);

}  // namespace gridrt::vulkan
