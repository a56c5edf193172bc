// What terravt needs of a device (terravt/device.h): the list, enabling it in a client's
// feature chain, and checking a device handed in. Every Vulkan function is looked up through
// the client's vkGetInstanceProcAddr.
#include <cstring>
#include <string>

#include "gpu/context.h"
#include "terravt/device.h"
#include "terravt/error.h"

namespace terravt {

const char* to_string(ErrorKind kind) noexcept {
  switch (kind) {
    case ErrorKind::invalid_argument: return "invalid argument";
    case ErrorKind::unsupported_device: return "unsupported device";
    case ErrorKind::vulkan: return "Vulkan error";
    case ErrorKind::device_lost: return "device lost";
    case ErrorKind::out_of_memory: return "out of memory";
    case ErrorKind::io: return "I/O error";
    case ErrorKind::producer_failed: return "producer failed";
    case ErrorKind::misuse: return "misuse";
  }
  return "error";
}

namespace {

constexpr const char* kCore = "VkPhysicalDeviceFeatures";
constexpr const char* kV12 = "VkPhysicalDeviceVulkan12Features";
constexpr const char* kV13 = "VkPhysicalDeviceVulkan13Features";

// One row per feature: where it lives in the three feature structs.
struct FeatureSlot {
  FeatureRequirement requirement;
  VkBool32 VkPhysicalDeviceFeatures::*core = nullptr;
  VkBool32 VkPhysicalDeviceVulkan12Features::*v12 = nullptr;
  VkBool32 VkPhysicalDeviceVulkan13Features::*v13 = nullptr;
};

const std::vector<FeatureSlot>& feature_slots() {
  static const std::vector<FeatureSlot> slots = {
      {{"shaderInt64", kCore, true, "page composition addresses texels with 64-bit integers (exact at V = 2^24 and beyond)"},
       &VkPhysicalDeviceFeatures::shaderInt64},
      {{"maintenance4", kV13, true, "terravt's shaders size workgroups with specialization constants (LocalSizeId)"},
       nullptr, nullptr, &VkPhysicalDeviceVulkan13Features::maintenance4},
      {{"synchronization2", kV13, false, "barriers as vkCmdPipelineBarrier2 (vkCmdPipelineBarrier otherwise)"},
       nullptr, nullptr, &VkPhysicalDeviceVulkan13Features::synchronization2},
      {{"dynamicRendering", kV13, false, "terravt's own terrain renderer and tools (an engine's render pass does not need it)"},
       nullptr, nullptr, &VkPhysicalDeviceVulkan13Features::dynamicRendering},
      {{"fragmentStoresAndAtomics", kCore, false, "feedback written by fragment-shader stores into a storage buffer"},
       &VkPhysicalDeviceFeatures::fragmentStoresAndAtomics},
      {{"vertexPipelineStoresAndAtomics", kCore, false, "debug and probe passes that store from vertex shaders"},
       &VkPhysicalDeviceFeatures::vertexPipelineStoresAndAtomics},
      {{"samplerAnisotropy", kCore, false, "anisotropic sampling of plain (non-virtual) comparison textures"},
       &VkPhysicalDeviceFeatures::samplerAnisotropy},
      {{"shaderInt8", kV12, false, "enabled when supported; no shader requires it"},
       nullptr, &VkPhysicalDeviceVulkan12Features::shaderInt8},
      {{"storageBuffer8BitAccess", kV12, false, "enabled when supported; no shader requires it"},
       nullptr, &VkPhysicalDeviceVulkan12Features::storageBuffer8BitAccess},
      {{"scalarBlockLayout", kV12, false, "enabled when supported; no shader requires it"},
       nullptr, &VkPhysicalDeviceVulkan12Features::scalarBlockLayout},
  };
  return slots;
}

// The Vulkan 1.2 and 1.3 feature structs in a pNext chain (null when absent).
template <class T>
const T* find_in_chain(const void* next, VkStructureType type) {
  for (auto* s = static_cast<const VkBaseInStructure*>(next); s; s = s->pNext)
    if (s->sType == type) return reinterpret_cast<const T*>(s);
  return nullptr;
}
template <class T>
T* find_in_chain(void* next, VkStructureType type) {
  for (auto* s = static_cast<VkBaseOutStructure*>(next); s; s = s->pNext)
    if (s->sType == type) return reinterpret_cast<T*>(s);
  return nullptr;
}

bool slot_value(const FeatureSlot& f, const VkPhysicalDeviceFeatures& core, const VkPhysicalDeviceVulkan12Features* v12,
                const VkPhysicalDeviceVulkan13Features* v13) {
  if (f.core) return core.*f.core == VK_TRUE;
  if (f.v12) return v12 && v12->*f.v12 == VK_TRUE;
  return v13 && v13->*f.v13 == VK_TRUE;
}

std::string version_text(uint32_t v) {
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v));
}

Error unsupported(std::string message) { return Error{ErrorKind::unsupported_device, std::move(message)}; }
Error invalid(std::string message) { return Error{ErrorKind::invalid_argument, std::move(message)}; }

}  // namespace

DeviceRequirements device_requirements() {
  DeviceRequirements r;
  for (const FeatureSlot& f : feature_slots()) r.features.push_back(f.requirement);
  return r;
}

Status enable_device_features(PFN_vkGetInstanceProcAddr gipa, VkInstance instance, VkPhysicalDevice physical_device,
                              VkPhysicalDeviceFeatures2& chain) {
  if (!gipa || instance == VK_NULL_HANDLE || physical_device == VK_NULL_HANDLE)
    return invalid("terravt::enable_device_features: get_instance_proc_addr, instance and physical_device are required");
  if (chain.sType != VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2)
    return invalid("terravt::enable_device_features: `chain` must be a VkPhysicalDeviceFeatures2 (sType)");
  auto* on12 = find_in_chain<VkPhysicalDeviceVulkan12Features>(chain.pNext, VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES);
  auto* on13 = find_in_chain<VkPhysicalDeviceVulkan13Features>(chain.pNext, VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES);
  if (!on12 || !on13)
    return invalid(std::string("terravt::enable_device_features: the chain has no ") + (on12 ? kV13 : kV12) +
                   "; add one to VkPhysicalDeviceFeatures2::pNext");
  auto get_features2 = reinterpret_cast<PFN_vkGetPhysicalDeviceFeatures2>(gipa(instance, "vkGetPhysicalDeviceFeatures2"));
  if (!get_features2) return unsupported("terravt: vkGetPhysicalDeviceFeatures2 is not available (Vulkan 1.1 or newer needed)");
  VkPhysicalDeviceVulkan13Features have13{};
  have13.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES;
  VkPhysicalDeviceVulkan12Features have12{};
  have12.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES;
  have12.pNext = &have13;
  VkPhysicalDeviceFeatures2 have{};
  have.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
  have.pNext = &have12;
  get_features2(physical_device, &have);
  for (const FeatureSlot& f : feature_slots()) {
    const bool supported = slot_value(f, have.features, &have12, &have13);
    if (!supported) {
      if (f.requirement.required)
        return unsupported(std::string("terravt: the device does not support ") + f.requirement.structure + "::" +
                           f.requirement.name + ", which terravt requires: " + f.requirement.why);
      continue;
    }
    if (f.core) chain.features.*f.core = VK_TRUE;
    if (f.v12) on12->*f.v12 = VK_TRUE;
    if (f.v13) on13->*f.v13 = VK_TRUE;
  }
  return Ok{};
}

Status check_device(const DeviceHandles& d) {
  const char* missing = !d.get_instance_proc_addr              ? "get_instance_proc_addr"
                        : d.instance == VK_NULL_HANDLE          ? "instance"
                        : d.physical_device == VK_NULL_HANDLE   ? "physical_device"
                        : d.device == VK_NULL_HANDLE            ? "device"
                        : d.queue == VK_NULL_HANDLE             ? "queue"
                        : d.enabled_features == nullptr         ? "enabled_features"
                                                                : nullptr;
  if (missing)
    return invalid(std::string("terravt: DeviceHandles::") + missing + " is not set" +
                   (std::strcmp(missing, "enabled_features") == 0
                        ? " (pass the VkPhysicalDeviceFeatures2 chain the device was created with: Vulkan cannot "
                          "report which features a device has on)"
                        : ""));
  if (d.enabled_features->sType != VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2)
    return invalid("terravt: DeviceHandles::enabled_features must point at a VkPhysicalDeviceFeatures2 (sType)");
  if (d.instance_api_version < VK_API_VERSION_1_3)
    return unsupported("terravt: the instance was created for Vulkan " + version_text(d.instance_api_version) +
                       " (DeviceHandles::instance_api_version); terravt needs 1.3");
  const auto gipa = d.get_instance_proc_addr;
  auto get_props = reinterpret_cast<PFN_vkGetPhysicalDeviceProperties>(gipa(d.instance, "vkGetPhysicalDeviceProperties"));
  auto get_families = reinterpret_cast<PFN_vkGetPhysicalDeviceQueueFamilyProperties>(
      gipa(d.instance, "vkGetPhysicalDeviceQueueFamilyProperties"));
  if (!get_props || !get_families)
    return invalid("terravt: DeviceHandles::get_instance_proc_addr returns no physical-device queries for this instance");
  VkPhysicalDeviceProperties props{};
  get_props(d.physical_device, &props);
  if (props.apiVersion < VK_API_VERSION_1_3)
    return unsupported(std::string("terravt: ") + props.deviceName + " supports Vulkan " + version_text(props.apiVersion) +
                       "; terravt needs 1.3");
  uint32_t n = 0;
  get_families(d.physical_device, &n, nullptr);
  std::vector<VkQueueFamilyProperties> families(n);
  get_families(d.physical_device, &n, families.data());
  const VkQueueFlags need = device_requirements().queue_flags;
  if (d.queue_family >= n)
    return invalid("terravt: DeviceHandles::queue_family " + std::to_string(d.queue_family) + " does not exist on " +
                   props.deviceName + " (it has " + std::to_string(n) + " queue families)");
  if ((families[d.queue_family].queueFlags & need) != need)
    return unsupported("terravt: queue family " + std::to_string(d.queue_family) + " of " + props.deviceName +
                       " has no COMPUTE: terravt records page composition and page-table updates into it");
  const auto* on12 = find_in_chain<VkPhysicalDeviceVulkan12Features>(d.enabled_features->pNext,
                                                                     VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES);
  const auto* on13 = find_in_chain<VkPhysicalDeviceVulkan13Features>(d.enabled_features->pNext,
                                                                     VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES);
  for (const FeatureSlot& f : feature_slots()) {
    if (!f.requirement.required || slot_value(f, d.enabled_features->features, on12, on13)) continue;
    return unsupported(std::string("terravt: the device was created without ") + f.requirement.structure +
                       "::" + f.requirement.name + ", which terravt requires (" + f.requirement.why +
                       "); enable it in vkCreateDevice (terravt::enable_device_features() does)");
  }
  return Ok{};
}

}  // namespace terravt

namespace tvt::vk {

DeviceFeatures enabled_features(const VkPhysicalDeviceFeatures2& chain) {
  const auto* on12 = terravt::find_in_chain<VkPhysicalDeviceVulkan12Features>(
      chain.pNext, VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES);
  const auto* on13 = terravt::find_in_chain<VkPhysicalDeviceVulkan13Features>(
      chain.pNext, VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES);
  const VkPhysicalDeviceFeatures& c = chain.features;
  DeviceFeatures f;
  f.shader_int64 = c.shaderInt64;
  f.sampler_anisotropy = c.samplerAnisotropy;
  f.fragment_stores_and_atomics = c.fragmentStoresAndAtomics;
  f.vertex_pipeline_stores_and_atomics = c.vertexPipelineStoresAndAtomics;
  if (on12) {
    f.shader_int8 = on12->shaderInt8;
    f.storage_buffer_8bit_access = on12->storageBuffer8BitAccess;
    f.scalar_block_layout = on12->scalarBlockLayout;
  }
  if (on13) {
    f.maintenance4 = on13->maintenance4;
    f.synchronization2 = on13->synchronization2;
    f.dynamic_rendering = on13->dynamicRendering;
  }
  return f;
}

}  // namespace tvt::vk
