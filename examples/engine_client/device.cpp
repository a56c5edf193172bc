// The engine's device (see device.h).
#include "device.h"

#include <algorithm>
#include <cstring>
#include <utility>

namespace engine {

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

VKAPI_ATTR VkBool32 VKAPI_CALL on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                          VkDebugUtilsMessageTypeFlagsEXT, const VkDebugUtilsMessengerCallbackDataEXT* data,
                                          void* user) {
  if (severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT)
    static_cast<Messages*>(user)->add(std::string("vulkan: ") + (data && data->pMessage ? data->pMessage : "(no text)"));
  return VK_FALSE;
}

// discrete > integrated > virtual > CPU (lavapipe), the order terravt's own tools rank in, so
// the example and `terravt render` pick the same device on one machine.
int rank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 4;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 3;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
    default: return 1;
  }
}

}  // namespace

void Messages::add(std::string line) {
  std::lock_guard<std::mutex> lock(mutex);
  lines.push_back(std::move(line));
}

std::vector<std::string> Messages::take() {
  std::lock_guard<std::mutex> lock(mutex);
  return std::exchange(lines, {});
}

std::unique_ptr<Device> Device::create(bool validation, std::string& error) {
  std::unique_ptr<Device> d(new Device());
  std::vector<const char*> layers, extensions;
  if (validation) {
    uint32_t n = 0;
    vkEnumerateInstanceLayerProperties(&n, nullptr);
    std::vector<VkLayerProperties> props(n);
    vkEnumerateInstanceLayerProperties(&n, props.data());
    if (std::none_of(props.begin(), props.end(), [](const VkLayerProperties& p) { return std::strcmp(p.layerName, kValidationLayer) == 0; })) {
      error = std::string("--validation: ") + kValidationLayer + " is not installed (Debian: vulkan-validationlayers)";
      return nullptr;
    }
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    extensions.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
  }
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "terravt engine_client";
  app.apiVersion = VK_API_VERSION_1_3;
  // Synchronisation validation on top of the core checks: hazards between terravt's work and
  // the engine's passes, across frames in flight, are errors too.
  const VkValidationFeatureEnableEXT enables[] = {VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
  VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
  features.enabledValidationFeatureCount = 1;
  features.pEnabledValidationFeatures = enables;
  VkDebugUtilsMessengerCreateInfoEXT mci{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  mci.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  mci.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                    VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  mci.pfnUserCallback = on_message;
  mci.pUserData = &d->messages_;
  features.pNext = &mci;  // messages during vkCreateInstance too
  VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ici.pNext = validation ? &features : nullptr;
  ici.pApplicationInfo = &app;
  ici.enabledLayerCount = uint32_t(layers.size());
  ici.ppEnabledLayerNames = layers.data();
  ici.enabledExtensionCount = uint32_t(extensions.size());
  ici.ppEnabledExtensionNames = extensions.data();
  if (VkResult r = vkCreateInstance(&ici, nullptr, &d->instance_); r != VK_SUCCESS) {
    error = "vkCreateInstance failed (VkResult " + std::to_string(int(r)) + ")";
    return nullptr;
  }
  if (validation) {
    auto create_messenger = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(d->instance_, "vkCreateDebugUtilsMessengerEXT"));
    if (!create_messenger || create_messenger(d->instance_, &mci, nullptr, &d->messenger_) != VK_SUCCESS) {
      error = "--validation: cannot create the debug-utils messenger";
      return nullptr;
    }
  }

  uint32_t n = 0;
  vkEnumeratePhysicalDevices(d->instance_, &n, nullptr);
  std::vector<VkPhysicalDevice> devices(n);
  vkEnumeratePhysicalDevices(d->instance_, &n, devices.data());
  int best = 0;
  std::string why = "no Vulkan device";
  for (VkPhysicalDevice p : devices) {
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(p, &props);
    if (props.apiVersion < VK_API_VERSION_1_3) {
      why = std::string(props.deviceName) + " is older than Vulkan 1.3";
      continue;
    }
    uint32_t qn = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(p, &qn, nullptr);
    std::vector<VkQueueFamilyProperties> qs(qn);
    vkGetPhysicalDeviceQueueFamilyProperties(p, &qn, qs.data());
    const VkQueueFlags want = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
    for (uint32_t i = 0; i < qn; ++i)
      if ((qs[i].queueFlags & want) == want && rank(props.deviceType) > best) {
        best = rank(props.deviceType);
        d->physical_ = p;
        d->family_ = i;
        break;
      }
  }
  if (!d->physical_) {
    error = why;
    return nullptr;
  }
  vkGetPhysicalDeviceMemoryProperties(d->physical_, &d->memory_);

  // The engine's own feature choices would go here; terravt adds what it needs.
  d->f2_.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
  d->f12_.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES;
  d->f13_.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES;
  d->f2_.pNext = &d->f12_;
  d->f12_.pNext = &d->f13_;
  const terravt::Status enabled = terravt::enable_device_features(vkGetInstanceProcAddr, d->instance_, d->physical_, d->f2_);
  if (!enabled.ok()) {
    error = "terravt::enable_device_features: " + enabled.error().message;
    return nullptr;
  }
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qci.queueFamilyIndex = d->family_;
  qci.queueCount = 1;
  qci.pQueuePriorities = &priority;
  VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  dci.pNext = &d->f2_;
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &qci;
  if (VkResult r = vkCreateDevice(d->physical_, &dci, nullptr, &d->device_); r != VK_SUCCESS) {
    error = "vkCreateDevice failed (VkResult " + std::to_string(int(r)) + ")";
    return nullptr;
  }
  vkGetDeviceQueue(d->device_, d->family_, 0, &d->queue_);
  return d;
}

Device::~Device() {
  if (device_) {
    vkDeviceWaitIdle(device_);
    vkDestroyDevice(device_, nullptr);
  }
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
  }
  if (instance_) vkDestroyInstance(instance_, nullptr);
}

terravt::DeviceHandles Device::handles() {
  terravt::DeviceHandles h;
  h.instance = instance_;
  h.physical_device = physical_;
  h.device = device_;
  h.queue_family = family_;
  h.queue = queue_;
  h.get_instance_proc_addr = vkGetInstanceProcAddr;
  h.instance_api_version = VK_API_VERSION_1_3;
  h.enabled_features = &f2_;
  h.log = [this](terravt::LogLevel level, std::string_view text) {
    if (level >= terravt::LogLevel::warning) messages_.add("terravt: " + std::string(text));
  };
  return h;
}

std::string Device::name() const {
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(physical_, &props);
  return props.deviceName;
}

uint32_t Device::memory_type(uint32_t bits, VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer) const {
  uint32_t fallback = UINT32_MAX;
  for (uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
    const VkMemoryPropertyFlags f = memory_.memoryTypes[i].propertyFlags;
    if (!(bits & (1u << i)) || (f & want) != want) continue;
    if ((f & prefer) == prefer) return i;
    if (fallback == UINT32_MAX) fallback = i;
  }
  return fallback;
}

Buffer Device::create_buffer(VkDeviceSize size, VkBufferUsageFlags usage, bool host) {
  Buffer b;
  b.size = size;
  VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bci.size = size;
  bci.usage = usage;
  vkCreateBuffer(device_, &bci, nullptr, &b.buffer);
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(device_, b.buffer, &req);
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = host ? memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
                                          VK_MEMORY_PROPERTY_HOST_CACHED_BIT)
                            : memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0);
  vkAllocateMemory(device_, &ai, nullptr, &b.memory);
  vkBindBufferMemory(device_, b.buffer, b.memory, 0);
  if (host) vkMapMemory(device_, b.memory, 0, VK_WHOLE_SIZE, 0, &b.mapped);
  return b;
}

void Device::destroy(Buffer& b) {
  if (b.buffer) vkDestroyBuffer(device_, b.buffer, nullptr);
  if (b.memory) vkFreeMemory(device_, b.memory, nullptr);
  b = Buffer{};
}

Image Device::create_image(VkFormat format, uint32_t width, uint32_t height, VkImageUsageFlags usage,
                           VkImageAspectFlags aspect) {
  Image i;
  VkImageCreateInfo ici{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  ici.imageType = VK_IMAGE_TYPE_2D;
  ici.format = format;
  ici.extent = {width, height, 1};
  ici.mipLevels = 1;
  ici.arrayLayers = 1;
  ici.samples = VK_SAMPLE_COUNT_1_BIT;
  ici.tiling = VK_IMAGE_TILING_OPTIMAL;
  ici.usage = usage;
  ici.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  vkCreateImage(device_, &ici, nullptr, &i.image);
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(device_, i.image, &req);
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0);
  vkAllocateMemory(device_, &ai, nullptr, &i.memory);
  vkBindImageMemory(device_, i.image, i.memory, 0);
  VkImageViewCreateInfo vci{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  vci.image = i.image;
  vci.viewType = VK_IMAGE_VIEW_TYPE_2D;
  vci.format = format;
  vci.subresourceRange = {aspect, 0, 1, 0, 1};
  vkCreateImageView(device_, &vci, nullptr, &i.view);
  return i;
}

void Device::destroy(Image& i) {
  if (i.view) vkDestroyImageView(device_, i.view, nullptr);
  if (i.image) vkDestroyImage(device_, i.image, nullptr);
  if (i.memory) vkFreeMemory(device_, i.memory, nullptr);
  i = Image{};
}

}  // namespace engine
