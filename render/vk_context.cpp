// Headless Vulkan 1.3 context (see vk_context.h for the contract).
#include "render/vk_context.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <utility>

namespace tvt::vk {

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
constexpr uint64_t kFenceTimeoutNs = 60ull * 1000 * 1000 * 1000;  // 60 s, then fatal
constexpr VkDeviceSize kStagingChunkBytes = VkDeviceSize(16) << 20;  // upload() staging size

// A zeroed Vulkan info struct with its sType set.
template <class T>
T init(VkStructureType type) {
  T v{};
  v.sType = type;
  return v;
}

const char* result_name(VkResult r) {
  switch (r) {
    case VK_SUCCESS: return "VK_SUCCESS";
    case VK_NOT_READY: return "VK_NOT_READY";
    case VK_TIMEOUT: return "VK_TIMEOUT";
    case VK_INCOMPLETE: return "VK_INCOMPLETE";
    case VK_ERROR_OUT_OF_HOST_MEMORY: return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY: return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED: return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST: return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_MEMORY_MAP_FAILED: return "VK_ERROR_MEMORY_MAP_FAILED";
    case VK_ERROR_LAYER_NOT_PRESENT: return "VK_ERROR_LAYER_NOT_PRESENT";
    case VK_ERROR_EXTENSION_NOT_PRESENT: return "VK_ERROR_EXTENSION_NOT_PRESENT";
    case VK_ERROR_FEATURE_NOT_PRESENT: return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_INCOMPATIBLE_DRIVER: return "VK_ERROR_INCOMPATIBLE_DRIVER";
    case VK_ERROR_TOO_MANY_OBJECTS: return "VK_ERROR_TOO_MANY_OBJECTS";
    case VK_ERROR_FORMAT_NOT_SUPPORTED: return "VK_ERROR_FORMAT_NOT_SUPPORTED";
    case VK_ERROR_OUT_OF_POOL_MEMORY: return "VK_ERROR_OUT_OF_POOL_MEMORY";
    case VK_ERROR_VALIDATION_FAILED_EXT: return "VK_ERROR_VALIDATION_FAILED_EXT";
    default: return "VkResult (unnamed)";
  }
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

bool env_flag(const char* name) {
  const char* v = std::getenv(name);
  return v && *v && std::strcmp(v, "0") != 0;
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

bool has_depth(VkFormat f) {
  return f == VK_FORMAT_D16_UNORM || f == VK_FORMAT_X8_D24_UNORM_PACK32 || f == VK_FORMAT_D32_SFLOAT ||
         f == VK_FORMAT_D16_UNORM_S8_UINT || f == VK_FORMAT_D24_UNORM_S8_UINT || f == VK_FORMAT_D32_SFLOAT_S8_UINT;
}
bool has_stencil(VkFormat f) {
  return f == VK_FORMAT_S8_UINT || f == VK_FORMAT_D16_UNORM_S8_UINT || f == VK_FORMAT_D24_UNORM_S8_UINT ||
         f == VK_FORMAT_D32_SFLOAT_S8_UINT;
}
VkImageAspectFlags aspect_of(VkFormat f) {
  VkImageAspectFlags a = 0;
  if (has_depth(f)) a |= VK_IMAGE_ASPECT_DEPTH_BIT;
  if (has_stencil(f)) a |= VK_IMAGE_ASPECT_STENCIL_BIT;
  return a ? a : VkImageAspectFlags(VK_IMAGE_ASPECT_COLOR_BIT);
}

// What a physical device offers; `unsuitable` names the first missing requirement.
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

uint32_t find_memory_type(const VkPhysicalDeviceMemoryProperties& mp, uint32_t allowed, VkMemoryPropertyFlags need,
                          VkMemoryPropertyFlags fallback) {
  for (VkMemoryPropertyFlags flags : {need, fallback}) {
    for (uint32_t i = 0; i < mp.memoryTypeCount; ++i) {
      if ((allowed & (1u << i)) && (mp.memoryTypes[i].propertyFlags & flags) == flags) return i;
    }
  }
  fatal(__FILE__, __LINE__, "find_memory_type", "no Vulkan memory type has the required properties");
}

}  // namespace

void check_result(VkResult result, const char* file, int line, const char* expr) {
  if (result == VK_SUCCESS) return;
  fatal(file, line, expr, result_name(result));
}

// ---------------------------------------------------------------------------------------
// Validation message sink: the debug-utils callback may run on any thread.

struct Context::Messages {
  mutable std::mutex mutex;
  std::vector<std::string> list;
};

namespace {

VKAPI_ATTR VkBool32 VKAPI_CALL debug_callback(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                              VkDebugUtilsMessageTypeFlagsEXT types,
                                              const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  auto* sink = static_cast<Context::Messages*>(user);
  std::string text = (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) ? "error" : "warning";
  if (types & VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT) text += " (performance)";
  text += ": ";
  text += data && data->pMessage ? data->pMessage : "(no message)";
  std::fprintf(stderr, "terravt: vulkan %s\n", text.c_str());
  std::lock_guard lock(sink->mutex);
  sink->list.push_back(std::move(text));
  return VK_FALSE;  // never abort the call: the caller sees what the driver does
}

VkDebugUtilsMessengerCreateInfoEXT messenger_info(Context::Messages* sink) {
  auto info = init<VkDebugUtilsMessengerCreateInfoEXT>(VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT);
  info.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                     VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  info.pfnUserCallback = debug_callback;
  info.pUserData = sink;
  return info;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Context creation

Result<std::unique_ptr<Context>> Context::create(const ContextOptions& options) {
  std::unique_ptr<Context> ctx(new Context());  // its destructor cleans up on every error path
  ctx->messages_ = std::make_unique<Messages>();
  ctx->validation_ = options.validation || env_flag("TERRAVT_VALIDATION");

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
  if (ctx->validation_) {
    uint32_t n = 0;
    vkEnumerateInstanceLayerProperties(&n, nullptr);
    std::vector<VkLayerProperties> available(n);
    vkEnumerateInstanceLayerProperties(&n, available.data());
    const bool present = std::any_of(available.begin(), available.end(),
                                     [](const VkLayerProperties& l) { return std::strcmp(l.layerName, kValidationLayer) == 0; });
    if (!present) {
      return make_error(std::string("Vulkan: validation was requested (ContextOptions::validation or TERRAVT_VALIDATION=1) "
                                    "but the layer ") +
                        kValidationLayer + " is not installed; install the package vulkan-validationlayers " +
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
  if (ctx->validation_) ici.pNext = &debug_info;
  if (VkResult r = vkCreateInstance(&ici, nullptr, &ctx->instance_); r != VK_SUCCESS) {
    ctx->instance_ = VK_NULL_HANDLE;
    return make_error(std::string("Vulkan: vkCreateInstance failed (") + result_name(r) +
                      "); is a Vulkan driver installed? (GPU-less machines: mesa-vulkan-drivers for lavapipe)");
  }
  if (ctx->validation_) {
    auto create_messenger = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(ctx->instance_, "vkCreateDebugUtilsMessengerEXT"));
    TVT_CHECK(create_messenger != nullptr);
    VkDebugUtilsMessengerCreateInfoEXT mi = messenger_info(ctx->messages_.get());
    TVT_VK_CHECK(create_messenger(ctx->instance_, &mi, nullptr, &ctx->messenger_));
  }

  // --- physical device
  uint32_t count = 0;
  TVT_VK_CHECK(vkEnumeratePhysicalDevices(ctx->instance_, &count, nullptr));
  std::vector<VkPhysicalDevice> devices(count);
  TVT_VK_CHECK(vkEnumeratePhysicalDevices(ctx->instance_, &count, devices.data()));
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

  const char* env_device = std::getenv("TERRAVT_DEVICE");
  const std::string wanted = !options.device.empty() ? options.device : (env_device ? env_device : "");
  const char* source = !options.device.empty() ? "ContextOptions::device" : "TERRAVT_DEVICE";
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
  ctx->properties_ = chosen->props;
  ctx->queue_family_ = chosen->queue_family;
  vkGetPhysicalDeviceMemoryProperties(ctx->physical_, &ctx->memory_properties_);
  {
    auto p11 = init<VkPhysicalDeviceVulkan11Properties>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_PROPERTIES);
    auto p2 = init<VkPhysicalDeviceProperties2>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2);
    p2.pNext = &p11;
    vkGetPhysicalDeviceProperties2(ctx->physical_, &p2);
    ctx->max_allocation_bytes_ = p11.maxMemoryAllocationSize;
  }

  // --- features: query everything, enable what later passes use when supported.
  auto have13 = init<VkPhysicalDeviceVulkan13Features>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES);
  auto have12 = init<VkPhysicalDeviceVulkan12Features>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES);
  have12.pNext = &have13;
  auto have = init<VkPhysicalDeviceFeatures2>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2);
  have.pNext = &have12;
  vkGetPhysicalDeviceFeatures2(ctx->physical_, &have);

  auto on13 = init<VkPhysicalDeviceVulkan13Features>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES);
  auto on12 = init<VkPhysicalDeviceVulkan12Features>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES);
  on12.pNext = &on13;
  auto on = init<VkPhysicalDeviceFeatures2>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2);
  on.pNext = &on12;
  on.features.shaderInt64 = have.features.shaderInt64;
  on.features.samplerAnisotropy = have.features.samplerAnisotropy;
  on.features.fragmentStoresAndAtomics = have.features.fragmentStoresAndAtomics;
  on.features.vertexPipelineStoresAndAtomics = have.features.vertexPipelineStoresAndAtomics;
  on12.shaderInt8 = have12.shaderInt8;
  on12.storageBuffer8BitAccess = have12.storageBuffer8BitAccess;
  on12.scalarBlockLayout = have12.scalarBlockLayout;
  on13.synchronization2 = have13.synchronization2;
  on13.dynamicRendering = have13.dynamicRendering;
  on13.maintenance4 = have13.maintenance4;
  if (!on.features.shaderInt64) {  // inspect() already refused such devices; keep the check local
    return make_error(std::string("Vulkan: device ") + ctx->properties_.deviceName +
                      " lacks shaderInt64 (composition uses 64-bit integer texel coordinates)");
  }
  if (!on13.maintenance4) {
    return make_error(std::string("Vulkan: device ") + ctx->properties_.deviceName +
                      " lacks maintenance4 (required by Vulkan 1.3; shaders size workgroups with LocalSizeId)");
  }
  DeviceFeatures& f = ctx->features_;
  f.shader_int64 = true;
  f.maintenance4 = true;
  f.shader_int8 = on12.shaderInt8;
  f.storage_buffer_8bit_access = on12.storageBuffer8BitAccess;
  f.scalar_block_layout = on12.scalarBlockLayout;
  f.synchronization2 = on13.synchronization2;
  f.dynamic_rendering = on13.dynamicRendering;
  f.sampler_anisotropy = on.features.samplerAnisotropy;
  f.fragment_stores_and_atomics = on.features.fragmentStoresAndAtomics;
  f.vertex_pipeline_stores_and_atomics = on.features.vertexPipelineStoresAndAtomics;

  const float priority = 1.0f;
  auto qci = init<VkDeviceQueueCreateInfo>(VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO);
  qci.queueFamilyIndex = ctx->queue_family_;
  qci.queueCount = 1;
  qci.pQueuePriorities = &priority;
  auto dci = init<VkDeviceCreateInfo>(VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO);
  dci.pNext = &on;
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &qci;
  if (VkResult r = vkCreateDevice(ctx->physical_, &dci, nullptr, &ctx->device_); r != VK_SUCCESS) {
    ctx->device_ = VK_NULL_HANDLE;
    return make_error(std::string("Vulkan: vkCreateDevice failed on ") + ctx->properties_.deviceName + " (" +
                      result_name(r) + ")");
  }
  vkGetDeviceQueue(ctx->device_, ctx->queue_family_, 0, &ctx->queue_);

  auto pci = init<VkCommandPoolCreateInfo>(VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO);
  pci.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
  pci.queueFamilyIndex = ctx->queue_family_;
  TVT_VK_CHECK(vkCreateCommandPool(ctx->device_, &pci, nullptr, &ctx->command_pool_));
  return ctx;
}

Context::~Context() {
  if (device_) {
    vkDeviceWaitIdle(device_);
    if (command_pool_) vkDestroyCommandPool(device_, command_pool_, nullptr);
    vkDestroyDevice(device_, nullptr);
  }
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
  }
  if (instance_) vkDestroyInstance(instance_, nullptr);
}

std::vector<std::string> Context::validation_messages() const {
  std::lock_guard lock(messages_->mutex);
  return messages_->list;
}

void Context::clear_validation_messages() {
  std::lock_guard lock(messages_->mutex);
  messages_->list.clear();
}

void Context::wait_idle() { TVT_VK_CHECK(vkDeviceWaitIdle(device_)); }

// ---------------------------------------------------------------------------------------
// Resources

Buffer Context::create_buffer(VkDeviceSize size, VkBufferUsageFlags usage, bool host_visible) {
  TVT_CHECK(size > 0);
  Buffer b;
  b.device_ = device_;
  b.size_ = size;
  auto bci = init<VkBufferCreateInfo>(VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO);
  bci.size = size;
  bci.usage = usage;
  bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  TVT_VK_CHECK(vkCreateBuffer(device_, &bci, nullptr, &b.buffer_));

  VkMemoryRequirements req{};
  vkGetBufferMemoryRequirements(device_, b.buffer_, &req);
  const VkMemoryPropertyFlags need = host_visible
                                         ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT
                                         : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  const VkMemoryPropertyFlags fallback = host_visible ? need : 0;
  auto dedicated = init<VkMemoryDedicatedAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_DEDICATED_ALLOCATE_INFO);
  dedicated.buffer = b.buffer_;
  auto mai = init<VkMemoryAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO);
  mai.pNext = &dedicated;
  mai.allocationSize = req.size;
  mai.memoryTypeIndex = find_memory_type(memory_properties_, req.memoryTypeBits, need, fallback);
  TVT_VK_CHECK(vkAllocateMemory(device_, &mai, nullptr, &b.memory_));
  TVT_VK_CHECK(vkBindBufferMemory(device_, b.buffer_, b.memory_, 0));
  if (host_visible) TVT_VK_CHECK(vkMapMemory(device_, b.memory_, 0, VK_WHOLE_SIZE, 0, &b.mapped_));
  return b;
}

namespace {
// A 2D (array) image, optimal tiling, one sample, exclusive, undefined initial layout: every
// image this project makes.
VkImageCreateInfo image_create_info(VkFormat format, uint32_t width, uint32_t height, uint32_t layers,
                                    VkImageUsageFlags usage, uint32_t mip_levels) {
  auto ici = init<VkImageCreateInfo>(VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO);
  ici.imageType = VK_IMAGE_TYPE_2D;
  ici.format = format;
  ici.extent = {width, height, 1};
  ici.mipLevels = mip_levels;
  ici.arrayLayers = layers;
  ici.samples = VK_SAMPLE_COUNT_1_BIT;
  ici.tiling = VK_IMAGE_TILING_OPTIMAL;
  ici.usage = usage;
  ici.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ici.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  return ici;
}
}  // namespace

Status Context::check_image_fits(VkFormat format, uint32_t width, uint32_t height, uint32_t layers,
                                 VkImageUsageFlags usage, const std::string& what) const {
  const double mb = 1.0 / 1048576.0;
  char text[320];
  VkImageFormatProperties fp{};
  if (vkGetPhysicalDeviceImageFormatProperties(physical_, format, VK_IMAGE_TYPE_2D, VK_IMAGE_TILING_OPTIMAL, usage, 0,
                                               &fp) != VK_SUCCESS) {
    return make_error(what + ": the device cannot make this image (format " + std::to_string(int(format)) + ")");
  }
  if (width > fp.maxExtent.width || height > fp.maxExtent.height || layers > fp.maxArrayLayers) {
    std::snprintf(text, sizeof(text), "%s: %ux%u texels x %u layers exceed the device's limits (%ux%u x %u layers)",
                  what.c_str(), width, height, layers, fp.maxExtent.width, fp.maxExtent.height, fp.maxArrayLayers);
    return make_error(text);
  }
  // The memory it needs, as the device computes it (creating an image allocates nothing).
  const VkImageCreateInfo ici = image_create_info(format, width, height, layers, usage, 1);
  VkImage probe = VK_NULL_HANDLE;
  if (vkCreateImage(device_, &ici, nullptr, &probe) != VK_SUCCESS)
    return make_error(what + ": the device cannot create a " + std::to_string(width) + "x" + std::to_string(height) +
                      " image of " + std::to_string(layers) + " layers");
  VkMemoryRequirements req{};
  vkGetImageMemoryRequirements(device_, probe, &req);
  vkDestroyImage(device_, probe, nullptr);
  const VkDeviceSize bytes = req.size;
  VkDeviceSize heap = 0;
  for (uint32_t i = 0; i < memory_properties_.memoryHeapCount; ++i)
    if (memory_properties_.memoryHeaps[i].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
      heap = std::max(heap, memory_properties_.memoryHeaps[i].size);
  const std::pair<VkDeviceSize, const char*> limits[] = {
      {fp.maxResourceSize, "the largest image of this format"},
      {max_allocation_bytes_, "the largest single allocation"},
      {heap, "the device-local memory heap"}};
  for (const auto& [limit, name] : limits) {
    if (limit == 0 || bytes <= limit) continue;  // 0: not reported
    std::snprintf(text, sizeof(text), "%s: %ux%u texels x %u layers is %.1f MB, more than %s on %s (%.1f MB)",
                  what.c_str(), width, height, layers, double(bytes) * mb, name, properties_.deviceName,
                  double(limit) * mb);
    return make_error(text);
  }
  return Ok{};
}

Image Context::create_image(VkFormat format, uint32_t width, uint32_t height, uint32_t layers,
                            VkImageUsageFlags usage, uint32_t mip_levels) {
  TVT_CHECK(width > 0 && height > 0 && layers > 0);
  TVT_CHECK(mip_levels >= 1 && mip_levels <= 32 && (std::max(width, height) >> (mip_levels - 1)) >= 1);
  Image img;
  img.device_ = device_;
  img.format_ = format;
  img.width_ = width;
  img.height_ = height;
  img.layers_ = layers;
  img.mip_levels_ = mip_levels;
  img.synchronization2_ = features_.synchronization2;
  const VkImageCreateInfo ici = image_create_info(format, width, height, layers, usage, mip_levels);
  TVT_VK_CHECK(vkCreateImage(device_, &ici, nullptr, &img.image_));

  VkMemoryRequirements req{};
  vkGetImageMemoryRequirements(device_, img.image_, &req);
  auto dedicated = init<VkMemoryDedicatedAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_DEDICATED_ALLOCATE_INFO);
  dedicated.image = img.image_;
  auto mai = init<VkMemoryAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO);
  mai.pNext = &dedicated;
  mai.allocationSize = req.size;
  mai.memoryTypeIndex =
      find_memory_type(memory_properties_, req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0);
  TVT_VK_CHECK(vkAllocateMemory(device_, &mai, nullptr, &img.memory_));
  TVT_VK_CHECK(vkBindImageMemory(device_, img.image_, img.memory_, 0));

  const VkImageUsageFlags viewable = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_STORAGE_BIT |
                                     VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT |
                                     VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_INPUT_ATTACHMENT_BIT;
  if (usage & viewable) {
    auto vci = init<VkImageViewCreateInfo>(VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO);
    vci.image = img.image_;
    vci.viewType = VK_IMAGE_VIEW_TYPE_2D_ARRAY;
    vci.format = format;
    vci.subresourceRange = {aspect_of(format), 0, mip_levels, 0, layers};
    TVT_VK_CHECK(vkCreateImageView(device_, &vci, nullptr, &img.view_));
  }
  return img;
}

ComputePipeline Context::create_compute_pipeline(std::span<const uint32_t> spirv,
                                                 std::span<const ComputeBinding> bindings,
                                                 uint32_t push_constant_bytes) {
  TVT_CHECK(!spirv.empty());
  TVT_CHECK(push_constant_bytes % 4 == 0);
  ComputePipeline p;
  p.device_ = device_;
  p.bindings_.assign(bindings.begin(), bindings.end());

  std::vector<VkDescriptorSetLayoutBinding> lb;
  for (const ComputeBinding& b : bindings) {
    lb.push_back({b.binding, b.type, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  }
  auto dci = init<VkDescriptorSetLayoutCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO);
  dci.bindingCount = uint32_t(lb.size());
  dci.pBindings = lb.data();
  TVT_VK_CHECK(vkCreateDescriptorSetLayout(device_, &dci, nullptr, &p.set_layout_));

  const VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_constant_bytes};
  auto plci = init<VkPipelineLayoutCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO);
  plci.setLayoutCount = 1;
  plci.pSetLayouts = &p.set_layout_;
  plci.pushConstantRangeCount = push_constant_bytes ? 1u : 0u;
  plci.pPushConstantRanges = &range;
  TVT_VK_CHECK(vkCreatePipelineLayout(device_, &plci, nullptr, &p.layout_));

  const VkShaderModule module = create_shader_module(spirv);

  auto cpci = init<VkComputePipelineCreateInfo>(VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO);
  cpci.stage = init<VkPipelineShaderStageCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO);
  cpci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  cpci.stage.module = module;
  cpci.stage.pName = "main";
  cpci.layout = p.layout_;
  const VkResult r = vkCreateComputePipelines(device_, VK_NULL_HANDLE, 1, &cpci, nullptr, &p.pipeline_);
  vkDestroyShaderModule(device_, module, nullptr);
  TVT_VK_CHECK(r);
  return p;
}

DescriptorSet Context::allocate_descriptor_set(const ComputePipeline& pipeline) {
  TVT_CHECK(pipeline.set_layout_ != VK_NULL_HANDLE);
  std::vector<VkDescriptorType> types;
  for (const ComputeBinding& b : pipeline.bindings_) types.push_back(b.type);
  return allocate_set(pipeline.set_layout_, types);
}

DescriptorSet Context::allocate_descriptor_set(const GraphicsPipeline& pipeline) {
  TVT_CHECK(pipeline.set_layout_ != VK_NULL_HANDLE);
  return allocate_set(pipeline.set_layout_, pipeline.types_);
}

DescriptorSet Context::allocate_set(VkDescriptorSetLayout layout, std::span<const VkDescriptorType> types) {
  DescriptorSet s;
  s.device_ = device_;
  std::vector<VkDescriptorPoolSize> sizes;
  for (const VkDescriptorType type : types) {
    auto it = std::find_if(sizes.begin(), sizes.end(), [&](const VkDescriptorPoolSize& ps) { return ps.type == type; });
    if (it == sizes.end()) {
      sizes.push_back({type, 1});
    } else {
      ++it->descriptorCount;
    }
  }
  if (sizes.empty()) sizes.push_back({VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1});  // keep the pool create valid
  auto pci = init<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
  pci.maxSets = 1;
  pci.poolSizeCount = uint32_t(sizes.size());
  pci.pPoolSizes = sizes.data();
  TVT_VK_CHECK(vkCreateDescriptorPool(device_, &pci, nullptr, &s.pool_));
  auto ai = init<VkDescriptorSetAllocateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO);
  ai.descriptorPool = s.pool_;
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &layout;
  TVT_VK_CHECK(vkAllocateDescriptorSets(device_, &ai, &s.set_));
  return s;
}

VkShaderModule Context::create_shader_module(std::span<const uint32_t> spirv) {
  TVT_CHECK(!spirv.empty());
  auto smci = init<VkShaderModuleCreateInfo>(VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO);
  smci.codeSize = spirv.size_bytes();
  smci.pCode = spirv.data();
  VkShaderModule module = VK_NULL_HANDLE;
  TVT_VK_CHECK(vkCreateShaderModule(device_, &smci, nullptr, &module));
  return module;
}

GraphicsPipeline Context::create_graphics_pipeline(const GraphicsPipelineDesc& desc) {
  TVT_CHECK(features_.dynamic_rendering);
  TVT_CHECK(!desc.vertex_spirv.empty() && !desc.fragment_spirv.empty());
  TVT_CHECK(desc.push_constant_bytes % 4 == 0);
  TVT_CHECK(!desc.color_formats.empty() || desc.depth_format != VK_FORMAT_UNDEFINED);
  GraphicsPipeline p;
  p.device_ = device_;
  p.push_stages_ = desc.push_constant_bytes ? desc.push_constant_stages : 0;

  std::vector<VkDescriptorSetLayoutBinding> lb;
  for (const GraphicsBinding& b : desc.bindings) {
    lb.push_back({b.binding, b.type, 1, b.stages, nullptr});
    p.types_.push_back(b.type);
  }
  auto dci = init<VkDescriptorSetLayoutCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO);
  dci.bindingCount = uint32_t(lb.size());
  dci.pBindings = lb.data();
  TVT_VK_CHECK(vkCreateDescriptorSetLayout(device_, &dci, nullptr, &p.set_layout_));

  const VkPushConstantRange range{desc.push_constant_stages, 0, desc.push_constant_bytes};
  auto plci = init<VkPipelineLayoutCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO);
  plci.setLayoutCount = 1;
  plci.pSetLayouts = &p.set_layout_;
  plci.pushConstantRangeCount = desc.push_constant_bytes ? 1u : 0u;
  plci.pPushConstantRanges = &range;
  TVT_VK_CHECK(vkCreatePipelineLayout(device_, &plci, nullptr, &p.layout_));

  const VkShaderModule vs = create_shader_module(desc.vertex_spirv);
  const VkShaderModule fs = create_shader_module(desc.fragment_spirv);
  // Fragment specialization constants: constant_id i = desc.fragment_constants[i] (32 bits each).
  std::vector<VkSpecializationMapEntry> spec_entries;
  for (uint32_t i = 0; i < desc.fragment_constants.size(); ++i)
    spec_entries.push_back({i, i * uint32_t(sizeof(uint32_t)), sizeof(uint32_t)});
  VkSpecializationInfo spec{};
  spec.mapEntryCount = uint32_t(spec_entries.size());
  spec.pMapEntries = spec_entries.data();
  spec.dataSize = desc.fragment_constants.size() * sizeof(uint32_t);
  spec.pData = desc.fragment_constants.data();
  VkPipelineShaderStageCreateInfo stages[2];
  for (int i = 0; i < 2; ++i) {
    stages[i] = init<VkPipelineShaderStageCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO);
    stages[i].stage = i == 0 ? VK_SHADER_STAGE_VERTEX_BIT : VK_SHADER_STAGE_FRAGMENT_BIT;
    stages[i].module = i == 0 ? vs : fs;
    stages[i].pName = "main";
    if (i == 1 && !spec_entries.empty()) stages[i].pSpecializationInfo = &spec;
  }

  auto vi = init<VkPipelineVertexInputStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO);
  vi.vertexBindingDescriptionCount = uint32_t(desc.vertex_bindings.size());
  vi.pVertexBindingDescriptions = desc.vertex_bindings.data();
  vi.vertexAttributeDescriptionCount = uint32_t(desc.vertex_attributes.size());
  vi.pVertexAttributeDescriptions = desc.vertex_attributes.data();
  auto ia = init<VkPipelineInputAssemblyStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO);
  ia.topology = desc.topology;
  auto vp = init<VkPipelineViewportStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO);
  vp.viewportCount = 1;
  vp.scissorCount = 1;
  auto rs = init<VkPipelineRasterizationStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO);
  rs.polygonMode = VK_POLYGON_MODE_FILL;
  rs.cullMode = desc.cull_mode;
  rs.frontFace = desc.front_face;
  rs.lineWidth = 1.0f;
  auto ms = init<VkPipelineMultisampleStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO);
  ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
  auto ds = init<VkPipelineDepthStencilStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO);
  const bool depth = desc.depth_format != VK_FORMAT_UNDEFINED;
  ds.depthTestEnable = depth ? VK_TRUE : VK_FALSE;
  ds.depthWriteEnable = depth && desc.depth_write ? VK_TRUE : VK_FALSE;
  ds.depthCompareOp = desc.depth_compare;
  std::vector<VkPipelineColorBlendAttachmentState> blend(desc.color_formats.size());
  for (auto& b : blend) {
    b.blendEnable = VK_FALSE;
    b.colorWriteMask =
        VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
  }
  auto cb = init<VkPipelineColorBlendStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO);
  cb.attachmentCount = uint32_t(blend.size());
  cb.pAttachments = blend.data();
  const VkDynamicState dynamic[] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  auto dyn = init<VkPipelineDynamicStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO);
  dyn.dynamicStateCount = 2;
  dyn.pDynamicStates = dynamic;
  auto rendering = init<VkPipelineRenderingCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO);
  rendering.colorAttachmentCount = uint32_t(desc.color_formats.size());
  rendering.pColorAttachmentFormats = desc.color_formats.data();
  rendering.depthAttachmentFormat = desc.depth_format;

  auto gpci = init<VkGraphicsPipelineCreateInfo>(VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO);
  gpci.pNext = &rendering;
  gpci.stageCount = 2;
  gpci.pStages = stages;
  gpci.pVertexInputState = &vi;
  gpci.pInputAssemblyState = &ia;
  gpci.pViewportState = &vp;
  gpci.pRasterizationState = &rs;
  gpci.pMultisampleState = &ms;
  gpci.pDepthStencilState = &ds;
  gpci.pColorBlendState = &cb;
  gpci.pDynamicState = &dyn;
  gpci.layout = p.layout_;
  const VkResult r = vkCreateGraphicsPipelines(device_, VK_NULL_HANDLE, 1, &gpci, nullptr, &p.pipeline_);
  vkDestroyShaderModule(device_, vs, nullptr);
  vkDestroyShaderModule(device_, fs, nullptr);
  TVT_VK_CHECK(r);
  return p;
}

void DescriptorSet::write_buffer(uint32_t binding, VkDescriptorType type, const Buffer& buffer) {
  TVT_CHECK(set_ != VK_NULL_HANDLE && buffer.handle() != VK_NULL_HANDLE);
  TVT_CHECK(type == VK_DESCRIPTOR_TYPE_STORAGE_BUFFER || type == VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER);
  const VkDescriptorBufferInfo info{buffer.handle(), 0, VK_WHOLE_SIZE};
  auto w = init<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
  w.dstSet = set_;
  w.dstBinding = binding;
  w.descriptorCount = 1;
  w.descriptorType = type;
  w.pBufferInfo = &info;
  vkUpdateDescriptorSets(device_, 1, &w, 0, nullptr);
}

void DescriptorSet::write_image(uint32_t binding, VkDescriptorType type, const VkDescriptorImageInfo& info) {
  TVT_CHECK(set_ != VK_NULL_HANDLE && info.imageView != VK_NULL_HANDLE);
  auto w = init<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
  w.dstSet = set_;
  w.dstBinding = binding;
  w.descriptorCount = 1;
  w.descriptorType = type;
  w.pImageInfo = &info;
  vkUpdateDescriptorSets(device_, 1, &w, 0, nullptr);
}

void DescriptorSet::write_storage_image(uint32_t binding, const Image& image) {
  write_image(binding, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, {VK_NULL_HANDLE, image.view(), VK_IMAGE_LAYOUT_GENERAL});
}

void DescriptorSet::write_sampled_image(uint32_t binding, const Image& image, VkSampler sampler, VkImageLayout layout) {
  TVT_CHECK(sampler != VK_NULL_HANDLE);
  write_image(binding, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, {sampler, image.view(), layout});
}

// ---------------------------------------------------------------------------------------
// Commands

void Context::run_commands(const std::function<void(VkCommandBuffer)>& record) {
  auto ai = init<VkCommandBufferAllocateInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO);
  ai.commandPool = command_pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  TVT_VK_CHECK(vkAllocateCommandBuffers(device_, &ai, &cmd));
  auto bi = init<VkCommandBufferBeginInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO);
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  TVT_VK_CHECK(vkBeginCommandBuffer(cmd, &bi));
  record(cmd);
  TVT_VK_CHECK(vkEndCommandBuffer(cmd));

  auto fci = init<VkFenceCreateInfo>(VK_STRUCTURE_TYPE_FENCE_CREATE_INFO);
  VkFence fence = VK_NULL_HANDLE;
  TVT_VK_CHECK(vkCreateFence(device_, &fci, nullptr, &fence));
  auto si = init<VkSubmitInfo>(VK_STRUCTURE_TYPE_SUBMIT_INFO);
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  TVT_VK_CHECK(vkQueueSubmit(queue_, 1, &si, fence));
  const VkResult r = vkWaitForFences(device_, 1, &fence, VK_TRUE, kFenceTimeoutNs);
  if (r == VK_TIMEOUT) {
    fatal(__FILE__, __LINE__, "vkWaitForFences", "run_commands: the GPU did not finish within 60 s (hang or device lost)");
  }
  TVT_VK_CHECK(r);
  vkDestroyFence(device_, fence, nullptr);
  vkFreeCommandBuffers(device_, command_pool_, 1, &cmd);
}

void Context::upload(const Buffer& dst, const void* data, VkDeviceSize bytes, VkDeviceSize dst_offset) {
  if (bytes == 0) return;
  TVT_CHECK(dst.handle() != VK_NULL_HANDLE && data != nullptr);
  TVT_CHECK(dst_offset <= dst.size() && bytes <= dst.size() - dst_offset);
  const VkDeviceSize chunk = std::min(bytes, kStagingChunkBytes);
  Buffer staging = create_buffer(chunk, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
  const auto* src = static_cast<const unsigned char*>(data);
  for (VkDeviceSize done = 0; done < bytes; done += chunk) {
    const VkDeviceSize n = std::min(chunk, bytes - done);
    std::memcpy(staging.mapped(), src + done, size_t(n));  // host writes: visible at submit
    run_commands([&](VkCommandBuffer cmd) {
      const VkBufferCopy region{0, dst_offset + done, n};
      vkCmdCopyBuffer(cmd, staging.handle(), dst.handle(), 1, &region);
      // Make the copy visible to whatever the caller records next (any stage, any access).
      auto mb = init<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
      mb.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      mb.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
      vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 1, &mb, 0,
                           nullptr, 0, nullptr);
    });
  }
}

void Context::transition(VkCommandBuffer cmd, const Image& image, VkImageLayout from, VkImageLayout to) {
  TVT_CHECK(image.handle() != VK_NULL_HANDLE);
  const VkImageSubresourceRange range{aspect_of(image.format()), 0, VK_REMAINING_MIP_LEVELS, 0,
                                      VK_REMAINING_ARRAY_LAYERS};
  if (image.synchronization2_) {
    auto b = init<VkImageMemoryBarrier2>(VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER_2);
    b.srcStageMask = VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT;
    b.srcAccessMask = VK_ACCESS_2_MEMORY_WRITE_BIT;
    b.dstStageMask = VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT;
    b.dstAccessMask = VK_ACCESS_2_MEMORY_READ_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT;
    b.oldLayout = from;
    b.newLayout = to;
    b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image.handle();
    b.subresourceRange = range;
    auto dep = init<VkDependencyInfo>(VK_STRUCTURE_TYPE_DEPENDENCY_INFO);
    dep.imageMemoryBarrierCount = 1;
    dep.pImageMemoryBarriers = &b;
    vkCmdPipelineBarrier2(cmd, &dep);
  } else {
    auto b = init<VkImageMemoryBarrier>(VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER);
    b.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
    b.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
    b.oldLayout = from;
    b.newLayout = to;
    b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image.handle();
    b.subresourceRange = range;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 0, nullptr, 0,
                         nullptr, 1, &b);
  }
}

void Context::memory_barrier(VkCommandBuffer cmd, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                             VkPipelineStageFlags dst_stage, VkAccessFlags dst_access) {
  auto mb = init<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
  mb.srcAccessMask = src_access;
  mb.dstAccessMask = dst_access;
  vkCmdPipelineBarrier(cmd, src_stage, dst_stage, 0, 1, &mb, 0, nullptr, 0, nullptr);
}

}  // namespace tvt::vk
