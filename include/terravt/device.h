// Bring your own device: terravt records into the client's Vulkan device and never creates,
// waits on or destroys it. The client
//   1. asks device_requirements() what terravt needs (API version, features, extensions),
//   2. lets enable_device_features() switch those features on in the VkPhysicalDeviceFeatures2
//      chain it passes to vkCreateDevice (next to whatever else the engine enables),
//   3. hands the handles in as DeviceHandles, naming the chain it enabled: Vulkan cannot report
//      which features a VkDevice was created with, so terravt checks the chain it is told about.
// check_device() says, with the missing item named, why a device cannot carry terravt.
//
// Every Vulkan function terravt calls here is looked up through
// DeviceHandles::get_instance_proc_addr, so a client that loads Vulkan itself (volk, its own
// loader) passes its own entry point.
//
// Threading: these functions are reentrant; they touch no global state.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <functional>
#include <string_view>
#include <vector>

#include "terravt/error.h"
#include "terravt/export.h"

namespace terravt {

enum class LogLevel { debug, info, warning, error };
// Called for diagnostics terravt would otherwise have nowhere to put (it never writes to
// stderr). May be called from any thread terravt runs on; must not call back into terravt.
using LogCallback = std::function<void(LogLevel level, std::string_view message)>;

// The client's device, as terravt uses it. terravt owns none of these handles.
struct DeviceHandles {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical_device = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  // The family of the queue whose command buffers terravt records into: it needs COMPUTE
  // (page composition, page-table scatter, feedback compaction) and transfer (uploads).
  uint32_t queue_family = 0;
  // A queue of that family. terravt::VirtualTexture never submits on it (its set-up is recorded
  // into the client's first frame); terravt's own tools submit one-shot work on it, which the
  // client would serialise with its own use (Vulkan external synchronisation).
  VkQueue queue = VK_NULL_HANDLE;
  // The entry point every terravt Vulkan call is looked up through (required).
  PFN_vkGetInstanceProcAddr get_instance_proc_addr = nullptr;
  // The API version the instance was created with (VkApplicationInfo::apiVersion).
  uint32_t instance_api_version = VK_API_VERSION_1_3;
  // The pNext chain the device was created with (VkDeviceCreateInfo::pNext, a
  // VkPhysicalDeviceFeatures2 at its head). Only read during the call that receives it.
  const VkPhysicalDeviceFeatures2* enabled_features = nullptr;
  // Passed to every vkCreate*/vkAllocate*/vkDestroy*/vkFree* terravt calls; may be null.
  const VkAllocationCallbacks* allocation_callbacks = nullptr;
  LogCallback log;  // may be empty: diagnostics are then dropped
};

// One feature terravt uses, by its Vulkan name ("shaderInt64", "synchronization2"...).
struct FeatureRequirement {
  const char* name;
  const char* structure;  // the struct that holds it: "VkPhysicalDeviceFeatures", "...Vulkan13Features"
  bool required;          // false: used when enabled, a slower or reduced path otherwise
  const char* why;        // what terravt uses it for
};

struct DeviceRequirements {
  uint32_t min_api_version = VK_API_VERSION_1_3;
  VkQueueFlags queue_flags = VK_QUEUE_COMPUTE_BIT;  // the queue family terravt records into
  std::vector<const char*> device_extensions;      // none today: everything is Vulkan 1.3 core
  std::vector<FeatureRequirement> features;
};

TERRAVT_API DeviceRequirements device_requirements();

// Switches on, in `chain` (the VkPhysicalDeviceFeatures2 the client will pass to
// vkCreateDevice), every feature terravt requires and every optional one `physical_device`
// supports. Features the client already enabled stay on. The chain must hold a
// VkPhysicalDeviceVulkan12Features and a VkPhysicalDeviceVulkan13Features. Fails, naming the
// feature, when the device does not support a required one.
TERRAVT_API Status enable_device_features(PFN_vkGetInstanceProcAddr get_instance_proc_addr, VkInstance instance,
                                          VkPhysicalDevice physical_device, VkPhysicalDeviceFeatures2& chain);

// Whether terravt can run on `device`: handles present, Vulkan version, the queue family's
// flags, and every required feature enabled in device.enabled_features. The error names the
// first thing missing and how to provide it.
TERRAVT_API Status check_device(const DeviceHandles& device);

}  // namespace terravt
