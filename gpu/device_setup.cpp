// terravt's own device for its tools and tests (see device_setup.h).
#include "gpu/device_setup.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <utility>

namespace tvt::vk {

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

const char* device_type_name(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
    default: return "other";
  }
}

// Lower is preferred: discrete, integrated, then the rest (virtual, CPU: lavapipe).
int type_rank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 1;
    default: return 2;
  }
}

struct Candidate {
  VkPhysicalDevice device = VK_NULL_HANDLE;
  VkPhysicalDeviceProperties props{};
  uint32_t queue_family = 0;
  std::string unsuitable;
};

Candidate inspect(VkPhysicalDevice pd) {
  Candidate c;
  c.device = pd;
  vkGetPhysicalDeviceProperties(pd, &c.props);
  if (c.props.apiVersion < VK_API_VERSION_1_3) {
    c.unsuitable = "supports Vulkan " + std::to_string(VK_API_VERSION_MAJOR(c.props.apiVersion)) + "." +
                   std::to_string(VK_API_VERSION_MINOR(c.props.apiVersion)) + ", terravt needs 1.3";
    return c;
  }
  uint32_t n = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, nullptr);
  std::vector<VkQueueFamilyProperties> families(n);
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, families.data());
  // Graphics and compute queues always support transfer (spec: "Queue Family Properties").
  const VkQueueFlags need = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
  bool found = false;
  for (uint32_t i = 0; i < n && !found; ++i) {
    if ((families[i].queueFlags & need) == need && families[i].queueCount > 0) {
      c.queue_family = i;
      found = true;
    }
  }
  if (!found) {
    c.unsuitable = "has no queue family with both GRAPHICS and COMPUTE";
    return c;
  }
  VkPhysicalDeviceFeatures f{};
  vkGetPhysicalDeviceFeatures(pd, &f);
  if (!f.shaderInt64) c.unsuitable = "lacks shaderInt64 (composition uses 64-bit integer texel coordinates)";
  return c;
}

std::string describe(uint32_t index, const VkPhysicalDeviceProperties& p) {
  return std::to_string(index) + ": " + p.deviceName + " (" + device_type_name(p.deviceType) + ")";
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Validation message sink: the debug-utils callback may run on any thread.

struct OwnedDevice::Messages {
  mutable std::mutex mutex;
  std::vector<std::string> list;
  terravt::LogCallback log;
};

namespace {

VKAPI_ATTR VkBool32 VKAPI_CALL debug_callback(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                              VkDebugUtilsMessageTypeFlagsEXT types,
                                              const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  auto* sink = static_cast<OwnedDevice::Messages*>(user);
  const bool error = severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  std::string text = error ? "error" : "warning";
  if (types & VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT) text += " (performance)";
  text += ": ";
  text += data && data->pMessage ? data->pMessage : "(no message)";
  if (sink->log) sink->log(error ? terravt::LogLevel::error : terravt::LogLevel::warning, "vulkan " + text);
  std::lock_guard lock(sink->mutex);
  sink->list.push_back(std::move(text));
  return VK_FALSE;  // never abort the call: the caller sees what the driver does
}

VkDebugUtilsMessengerCreateInfoEXT messenger_info(OwnedDevice::Messages* sink) {
  auto info = init<VkDebugUtilsMessengerCreateInfoEXT>(VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT);
  info.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                     VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  info.pfnUserCallback = debug_callback;
  info.pUserData = sink;
  return info;
}

}  // namespace

OwnedDevice::OwnedDevice() : messages_(std::make_unique<Messages>()) {}

Result<std::unique_ptr<OwnedDevice>> OwnedDevice::create(const ContextOptions& options) {
  std::unique_ptr<OwnedDevice> ctx(new OwnedDevice());  // its destructor cleans up on every error path
  ctx->messages_->log = options.log;
  const bool validation = options.validation;

  uint32_t instance_version = VK_API_VERSION_1_0;
  if (vkEnumerateInstanceVersion(&instance_version) != VK_SUCCESS || instance_version < VK_API_VERSION_1_3) {
    return make_error("Vulkan: the installed Vulkan loader supports only " +
                      std::to_string(VK_API_VERSION_MAJOR(instance_version)) + "." +
                      std::to_string(VK_API_VERSION_MINOR(instance_version)) +
                      "; terravt needs Vulkan 1.3 (install a newer libvulkan1)");
  }

  std::vector<const char*> layers;
  std::vector<const char*> extensions;
  bool sync_validation = false;
  if (validation) {
    uint32_t n = 0;
    vkEnumerateInstanceLayerProperties(&n, nullptr);
    std::vector<VkLayerProperties> available(n);
    vkEnumerateInstanceLayerProperties(&n, available.data());
    const bool present = std::any_of(available.begin(), available.end(),
                                     [](const VkLayerProperties& l) { return std::strcmp(l.layerName, kValidationLayer) == 0; });
    if (!present) {
      return make_error("Vulkan: validation was requested (" + options.validation_source + ") but the layer " +
                        std::string(kValidationLayer) + " is not installed; install the package vulkan-validationlayers " +
                        "(e.g. apt-get install vulkan-validationlayers) or turn validation off");
    }
    layers.push_back(kValidationLayer);
    uint32_t e = 0;
    vkEnumerateInstanceExtensionProperties(kValidationLayer, &e, nullptr);
    std::vector<VkExtensionProperties> layer_exts(e);
    vkEnumerateInstanceExtensionProperties(kValidationLayer, &e, layer_exts.data());
    vkEnumerateInstanceExtensionProperties(nullptr, &e, nullptr);
    std::vector<VkExtensionProperties> exts(e);
    vkEnumerateInstanceExtensionProperties(nullptr, &e, exts.data());
    exts.insert(exts.end(), layer_exts.begin(), layer_exts.end());
    auto has = [&](const char* name) {
      return std::any_of(exts.begin(), exts.end(),
                         [&](const VkExtensionProperties& x) { return std::strcmp(x.extensionName, name) == 0; });
    };
    if (!has(VK_EXT_DEBUG_UTILS_EXTENSION_NAME)) {
      return make_error("Vulkan: validation was requested but VK_EXT_debug_utils is not available; "
                        "reinstall the package vulkan-validationlayers");
    }
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    if (has(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME)) {
      extensions.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
      sync_validation = true;
    }
  }

  auto app = init<VkApplicationInfo>(VK_STRUCTURE_TYPE_APPLICATION_INFO);
  app.pApplicationName = "terravt";
  app.applicationVersion = VK_MAKE_API_VERSION(0, 0, 1, 0);
  app.pEngineName = "terravt";
  app.engineVersion = VK_MAKE_API_VERSION(0, 0, 1, 0);
  app.apiVersion = VK_API_VERSION_1_3;

  // Chained into the instance so messages from vkCreateInstance/vkDestroyInstance are caught.
  VkDebugUtilsMessengerCreateInfoEXT debug_info = messenger_info(ctx->messages_.get());
  // Synchronisation validation catches missing barriers and layout transitions in tests.
  const VkValidationFeatureEnableEXT enables[] = {VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
  auto validation_features = init<VkValidationFeaturesEXT>(VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT);
  validation_features.enabledValidationFeatureCount = 1;
  validation_features.pEnabledValidationFeatures = enables;
  if (sync_validation) debug_info.pNext = &validation_features;

  auto ici = init<VkInstanceCreateInfo>(VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO);
  ici.pApplicationInfo = &app;
  ici.enabledLayerCount = uint32_t(layers.size());
  ici.ppEnabledLayerNames = layers.data();
  ici.enabledExtensionCount = uint32_t(extensions.size());
  ici.ppEnabledExtensionNames = extensions.data();
  if (validation) ici.pNext = &debug_info;
  if (VkResult r = vkCreateInstance(&ici, nullptr, &ctx->instance_); r != VK_SUCCESS) {
    ctx->instance_ = VK_NULL_HANDLE;
    return make_error(std::string("Vulkan: vkCreateInstance failed (") + result_name(r) +
                      "); is a Vulkan driver installed? (GPU-less machines: mesa-vulkan-drivers for lavapipe)");
  }
  if (validation) {
    auto create_messenger = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(ctx->instance_, "vkCreateDebugUtilsMessengerEXT"));
    if (create_messenger == nullptr)
      return make_error("Vulkan: the instance has no vkCreateDebugUtilsMessengerEXT although VK_EXT_debug_utils "
                        "was enabled", ErrorKind::vulkan);
    VkDebugUtilsMessengerCreateInfoEXT mi = messenger_info(ctx->messages_.get());
    if (VkResult r = create_messenger(ctx->instance_, &mi, nullptr, &ctx->messenger_); r != VK_SUCCESS) {
      ctx->messenger_ = VK_NULL_HANDLE;
      return vulkan_error(r, "vkCreateDebugUtilsMessengerEXT");
    }
  }

  // --- physical device
  uint32_t count = 0;
  if (VkResult r = vkEnumeratePhysicalDevices(ctx->instance_, &count, nullptr); r != VK_SUCCESS)
    return vulkan_error(r, "vkEnumeratePhysicalDevices");
  std::vector<VkPhysicalDevice> devices(count);
  if (VkResult r = vkEnumeratePhysicalDevices(ctx->instance_, &count, devices.data()); r != VK_SUCCESS && r != VK_INCOMPLETE)
    return vulkan_error(r, "vkEnumeratePhysicalDevices");
  devices.resize(count);
  if (devices.empty()) {
    return make_error("Vulkan: no Vulkan device found; install a GPU driver, or mesa-vulkan-drivers for the "
                      "lavapipe CPU device");
  }
  std::vector<Candidate> candidates;
  std::string listing;
  for (uint32_t i = 0; i < devices.size(); ++i) {
    candidates.push_back(inspect(devices[i]));
    listing += (i ? ", " : "") + describe(i, candidates.back().props);
  }

  const std::string& wanted = options.device;
  const char* source = options.device_source.c_str();
  const Candidate* chosen = nullptr;
  if (!wanted.empty()) {
    const bool numeric = std::all_of(wanted.begin(), wanted.end(), [](unsigned char c) { return std::isdigit(c); });
    if (numeric) {
      const unsigned long index = std::strtoul(wanted.c_str(), nullptr, 10);
      if (wanted.size() > 9 || index >= candidates.size()) {
        return make_error(std::string("Vulkan: ") + source + "=" + wanted + " is not a device index; available devices: " +
                          listing);
      }
      chosen = &candidates[index];
    } else {
      const std::string needle = lower(wanted);
      for (const Candidate& c : candidates) {
        if (lower(c.props.deviceName).find(needle) != std::string::npos) {
          chosen = &c;
          break;
        }
      }
      if (!chosen) {
        return make_error(std::string("Vulkan: ") + source + "='" + wanted +
                          "' matches no Vulkan device name; available devices: " + listing);
      }
    }
    if (!chosen->unsuitable.empty()) {
      return make_error(std::string("Vulkan: device ") + chosen->props.deviceName + " chosen by " + source + " " +
                        chosen->unsuitable);
    }
  } else {
    for (const Candidate& c : candidates) {
      if (c.unsuitable.empty() && (!chosen || type_rank(c.props.deviceType) < type_rank(chosen->props.deviceType))) {
        chosen = &c;
      }
    }
    if (!chosen) {
      std::string why;
      for (const Candidate& c : candidates) why += std::string(why.empty() ? "" : "; ") + c.props.deviceName + " " + c.unsuitable;
      return make_error("Vulkan: no suitable device: " + why);
    }
  }
  ctx->physical_ = chosen->device;
  ctx->queue_family_ = chosen->queue_family;

  // --- features: terravt's own list (the same call an engine makes), nothing else.
  ctx->v13_.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES;
  ctx->v12_.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES;
  ctx->v12_.pNext = &ctx->v13_;
  ctx->features_.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
  ctx->features_.pNext = &ctx->v12_;
  if (auto s = terravt::enable_device_features(vkGetInstanceProcAddr, ctx->instance_, ctx->physical_, ctx->features_); !s)
    return make_error("Vulkan: " + s.error().message);

  const float priority = 1.0f;
  auto qci = init<VkDeviceQueueCreateInfo>(VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO);
  qci.queueFamilyIndex = ctx->queue_family_;
  qci.queueCount = 1;
  qci.pQueuePriorities = &priority;
  auto dci = init<VkDeviceCreateInfo>(VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO);
  dci.pNext = &ctx->features_;
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &qci;
  if (VkResult r = vkCreateDevice(ctx->physical_, &dci, nullptr, &ctx->device_); r != VK_SUCCESS) {
    ctx->device_ = VK_NULL_HANDLE;
    return make_error(std::string("Vulkan: vkCreateDevice failed on ") + chosen->props.deviceName + " (" +
                      result_name(r) + ")");
  }
  vkGetDeviceQueue(ctx->device_, ctx->queue_family_, 0, &ctx->queue_);

  return ctx;
}

Result<std::unique_ptr<Context>> Context::create(const ContextOptions& options) {
  auto owned = OwnedDevice::create(options);
  if (!owned) return owned.error();
  auto ctx = adopt(owned.value()->handles());
  if (!ctx) return ctx.error();
  ctx.value()->owned_ = std::move(owned.value());
  return ctx;
}

Result<terravt::DeviceHandles> Context::device_handles() const {
  if (!owned_)
    return Error{ErrorKind::invalid_argument, "Context::device_handles(): the device was adopted; its handles are the client's"};
  return owned_->handles();
}

OwnedDevice::~OwnedDevice() {
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

terravt::DeviceHandles OwnedDevice::handles() const {
  terravt::DeviceHandles h;
  h.instance = instance_;
  h.physical_device = physical_;
  h.device = device_;
  h.queue_family = queue_family_;
  h.queue = queue_;
  h.get_instance_proc_addr = vkGetInstanceProcAddr;
  h.instance_api_version = VK_API_VERSION_1_3;
  h.enabled_features = &features_;
  h.log = messages_->log;
  return h;
}

std::vector<std::string> OwnedDevice::messages() const {
  std::lock_guard lock(messages_->mutex);
  return messages_->list;
}

void OwnedDevice::clear_messages() {
  std::lock_guard lock(messages_->mutex);
  messages_->list.clear();
}

}  // namespace tvt::vk
