// Buffers and images with dedicated memory (gpu/resources.h), made by the Context.
#include <algorithm>
#include <cstdio>
#include <utility>

#include "gpu/context.h"

namespace tvt::vk {

Buffer Context::create_buffer(VkDeviceSize size, VkBufferUsageFlags usage, bool host_visible) {
  TVT_CHECK(size > 0);
  if (!status()) return {};  // nothing more is made after a failed call
  Buffer b;
  b.device_ = device_;
  b.fn_ = &fn_;
  b.alloc_ = alloc_;
  b.size_ = size;
  auto bci = init<VkBufferCreateInfo>(VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO);
  bci.size = size;
  bci.usage = usage;
  bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  if (!TVT_VK_OK(*this, fn_.vkCreateBuffer(device_, &bci, alloc_, &b.buffer_))) return {};

  VkMemoryRequirements req{};
  fn_.vkGetBufferMemoryRequirements(device_, b.buffer_, &req);
  const VkMemoryPropertyFlags need = host_visible
                                         ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT
                                         : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  const VkMemoryPropertyFlags fallback = host_visible ? need : 0;
  auto dedicated = init<VkMemoryDedicatedAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_DEDICATED_ALLOCATE_INFO);
  dedicated.buffer = b.buffer_;
  auto mai = init<VkMemoryAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO);
  mai.pNext = &dedicated;
  mai.allocationSize = req.size;
  mai.memoryTypeIndex = memory_type(req.memoryTypeBits, need, fallback);
  // A failure anywhere returns an empty Buffer (b frees what was made): a host-visible one is
  // never handed back unmapped.
  if (mai.memoryTypeIndex == UINT32_MAX) {
    ok(VK_ERROR_OUT_OF_DEVICE_MEMORY, "vkAllocateMemory (no memory type with the required properties)");
    return {};
  }
  if (!TVT_VK_OK(*this, fn_.vkAllocateMemory(device_, &mai, alloc_, &b.memory_))) return {};
  if (!TVT_VK_OK(*this, fn_.vkBindBufferMemory(device_, b.buffer_, b.memory_, 0))) return {};
  if (host_visible && !TVT_VK_OK(*this, fn_.vkMapMemory(device_, b.memory_, 0, VK_WHOLE_SIZE, 0, &b.mapped_))) return {};
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
  if (fn_.vkGetPhysicalDeviceImageFormatProperties(physical_, format, VK_IMAGE_TYPE_2D, VK_IMAGE_TILING_OPTIMAL, usage, 0,
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
  if (VkResult r = fn_.vkCreateImage(device_, &ici, alloc_, &probe); r != VK_SUCCESS) {
    if (r == VK_ERROR_OUT_OF_HOST_MEMORY || r == VK_ERROR_OUT_OF_DEVICE_MEMORY) {
      ok(r, "vkCreateImage");  // latched like any failed call
      Error e = vulkan_error(r, "vkCreateImage");
      e.message = what + ": " + e.message;
      return e;
    }
    return make_error(what + ": the device cannot create a " + std::to_string(width) + "x" + std::to_string(height) +
                      " image of " + std::to_string(layers) + " layers");
  }
  VkMemoryRequirements req{};
  fn_.vkGetImageMemoryRequirements(device_, probe, &req);
  fn_.vkDestroyImage(device_, probe, alloc_);
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

Image Context::borrow_image(VkImage image, VkImageView view, VkFormat format, uint32_t width, uint32_t height,
                            uint32_t layers) {
  Image img;  // device_ stays null: reset() destroys nothing
  img.image_ = image;
  img.view_ = view;
  img.format_ = format;
  img.width_ = width;
  img.height_ = height;
  img.layers_ = layers;
  img.mip_levels_ = 1;
  return img;
}

Image Context::create_image(VkFormat format, uint32_t width, uint32_t height, uint32_t layers,
                            VkImageUsageFlags usage, uint32_t mip_levels) {
  TVT_CHECK(width > 0 && height > 0 && layers > 0);
  TVT_CHECK(mip_levels >= 1 && mip_levels <= 32 && (std::max(width, height) >> (mip_levels - 1)) >= 1);
  if (!status()) return {};  // nothing more is made after a failed call
  Image img;
  img.device_ = device_;
  img.fn_ = &fn_;
  img.alloc_ = alloc_;
  img.format_ = format;
  img.width_ = width;
  img.height_ = height;
  img.layers_ = layers;
  img.mip_levels_ = mip_levels;
  const VkImageCreateInfo ici = image_create_info(format, width, height, layers, usage, mip_levels);
  if (!TVT_VK_OK(*this, fn_.vkCreateImage(device_, &ici, alloc_, &img.image_))) return {};

  VkMemoryRequirements req{};
  fn_.vkGetImageMemoryRequirements(device_, img.image_, &req);
  auto dedicated = init<VkMemoryDedicatedAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_DEDICATED_ALLOCATE_INFO);
  dedicated.image = img.image_;
  auto mai = init<VkMemoryAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO);
  mai.pNext = &dedicated;
  mai.allocationSize = req.size;
  mai.memoryTypeIndex =
      memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0);
  if (mai.memoryTypeIndex == UINT32_MAX) {
    ok(VK_ERROR_OUT_OF_DEVICE_MEMORY, "vkAllocateMemory (no memory type with the required properties)");
    return {};
  }
  if (!TVT_VK_OK(*this, fn_.vkAllocateMemory(device_, &mai, alloc_, &img.memory_))) return {};
  if (!TVT_VK_OK(*this, fn_.vkBindImageMemory(device_, img.image_, img.memory_, 0))) return {};

  const VkImageUsageFlags viewable = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_STORAGE_BIT |
                                     VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT |
                                     VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_INPUT_ATTACHMENT_BIT;
  if (usage & viewable) {
    auto vci = init<VkImageViewCreateInfo>(VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO);
    vci.image = img.image_;
    vci.viewType = VK_IMAGE_VIEW_TYPE_2D_ARRAY;
    vci.format = format;
    vci.subresourceRange = {aspect_of(format), 0, mip_levels, 0, layers};
    if (!TVT_VK_OK(*this, fn_.vkCreateImageView(device_, &vci, alloc_, &img.view_))) return {};
  }
  return img;
}

}  // namespace tvt::vk
