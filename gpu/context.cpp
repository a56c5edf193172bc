// The Context: a client's device adopted, or terravt's own made and adopted (see context.h).
#include "gpu/context.h"

#include <algorithm>
#include <utility>
#include <vector>

namespace tvt::vk {

Result<std::unique_ptr<Context>> Context::adopt(const terravt::DeviceHandles& handles) {
  if (auto s = terravt::check_device(handles); !s) return s.error();
  std::unique_ptr<Context> ctx(new Context());
  ctx->instance_ = handles.instance;
  ctx->physical_ = handles.physical_device;
  ctx->device_ = handles.device;
  ctx->queue_ = handles.queue;
  ctx->queue_family_ = handles.queue_family;
  ctx->alloc_ = handles.allocation_callbacks;
  ctx->log_ = handles.log;
  ctx->features_ = enabled_features(*handles.enabled_features);
  auto fn = Functions::load(handles.get_instance_proc_addr, handles.instance, handles.device);
  if (!fn) return fn.error();
  ctx->fn_ = fn.value();
  ctx->fn_.vkGetPhysicalDeviceProperties(ctx->physical_, &ctx->properties_);
  ctx->fn_.vkGetPhysicalDeviceMemoryProperties(ctx->physical_, &ctx->memory_properties_);
  auto p11 = init<VkPhysicalDeviceVulkan11Properties>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_PROPERTIES);
  auto p2 = init<VkPhysicalDeviceProperties2>(VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2);
  p2.pNext = &p11;
  ctx->fn_.vkGetPhysicalDeviceProperties2(ctx->physical_, &p2);
  ctx->max_allocation_bytes_ = p11.maxMemoryAllocationSize;
  uint32_t families = 0;
  ctx->fn_.vkGetPhysicalDeviceQueueFamilyProperties(ctx->physical_, &families, nullptr);
  std::vector<VkQueueFamilyProperties> family_props(families);
  ctx->fn_.vkGetPhysicalDeviceQueueFamilyProperties(ctx->physical_, &families, family_props.data());
  const uint32_t valid_bits = ctx->queue_family_ < families ? family_props[ctx->queue_family_].timestampValidBits : 0;
  if (valid_bits > 0 && ctx->properties_.limits.timestampPeriod > 0.f)
    ctx->timestamp_mask_ = valid_bits >= 64 ? ~0ull : (1ull << valid_bits) - 1;

  auto pci = init<VkCommandPoolCreateInfo>(VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO);
  pci.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
  pci.queueFamilyIndex = ctx->queue_family_;
  if (VkResult r = ctx->fn_.vkCreateCommandPool(ctx->device_, &pci, ctx->alloc_, &ctx->command_pool_); r != VK_SUCCESS) {
    ctx->command_pool_ = VK_NULL_HANDLE;
    return vulkan_error(r, "vkCreateCommandPool");
  }
  return ctx;
}

Context::~Context() {
  // terravt's own device: let the GPU finish before anything is destroyed. A client's device
  // is never waited on: the client guarantees the GPU is done with terravt's objects.
  if (owned_ && device_) fn_.vkDeviceWaitIdle(device_);
  if (command_pool_) fn_.vkDestroyCommandPool(device_, command_pool_, alloc_);
  owned_.reset();
}

void Context::log(terravt::LogLevel level, const std::string& message) const {
  if (log_) log_(level, message);
}

bool Context::validation_enabled() const { return owned_ && owned_->validation(); }

std::vector<std::string> Context::validation_messages() const {
  return owned_ ? owned_->messages() : std::vector<std::string>{};
}

void Context::clear_validation_messages() {
  if (owned_) owned_->clear_messages();
}

Status Context::status() const {
  std::lock_guard lock(fault_mutex_);
  if (fault_) return *fault_;
  return Ok{};
}

bool Context::ok(VkResult result, const char* call) const {
  if (result == VK_SUCCESS) return true;
  std::string first;
  {
    std::lock_guard lock(fault_mutex_);
    if (!fault_) {
      fault_ = vulkan_error(result, call);
      first = fault_->message;
    }
  }
  if (!first.empty()) log(terravt::LogLevel::error, first);
  return false;
}

void Context::wait_idle() { TVT_VK_OK(*this, fn_.vkDeviceWaitIdle(device_)); }

uint32_t Context::memory_type(uint32_t allowed, VkMemoryPropertyFlags need, VkMemoryPropertyFlags fallback) const {
  for (VkMemoryPropertyFlags flags : {need, fallback}) {
    for (uint32_t i = 0; i < memory_properties_.memoryTypeCount; ++i) {
      if ((allowed & (1u << i)) && (memory_properties_.memoryTypes[i].propertyFlags & flags) == flags) return i;
    }
  }
  return UINT32_MAX;  // none: the allocation that asks for it fails (create_buffer/create_image)
}

VkSampler Context::create_sampler(const VkSamplerCreateInfo& info) {
  VkSampler sampler = VK_NULL_HANDLE;
  if (!status()) return VK_NULL_HANDLE;  // nothing more is made after a failed call
  if (!TVT_VK_OK(*this, fn_.vkCreateSampler(device_, &info, alloc_, &sampler))) return VK_NULL_HANDLE;
  return sampler;
}

void Context::destroy_sampler(VkSampler sampler) {
  if (sampler != VK_NULL_HANDLE) fn_.vkDestroySampler(device_, sampler, alloc_);
}

}  // namespace tvt::vk
