// Buffers and images, each with its own dedicated memory: move-only RAII handles made by
// Context::create_buffer()/create_image() (gpu/context.h). A moved-from handle owns nothing.
// Lifetime: a handle holds the VkDevice (and allocation callbacks) it was made with and must be
// destroyed, or moved from, before that device is; the GPU must be done with it by then.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>

#include "gpu/vk_functions.h"

namespace tvt::vk {

class Context;

// A buffer with its own dedicated memory. Host-visible buffers are persistently mapped.
class Buffer {
 public:
  Buffer() = default;
  Buffer(Buffer&&) noexcept;
  Buffer& operator=(Buffer&&) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  ~Buffer();

  VkBuffer handle() const { return buffer_; }
  VkDeviceSize size() const { return size_; }
  void* mapped() const { return mapped_; }  // nullptr for device-local buffers
  explicit operator bool() const { return buffer_ != VK_NULL_HANDLE; }

 private:
  friend class Context;
  VkDevice device_ = VK_NULL_HANDLE;
  const Functions* fn_ = nullptr;  // the Context's table (gpu/vk_functions.h)
  const VkAllocationCallbacks* alloc_ = nullptr;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize size_ = 0;
  void* mapped_ = nullptr;
  void reset();
};

// A 2D (array) image with its own memory and a default view of all layers and mip levels
// (created when the usage allows a view: sampled, storage or attachment; otherwise view() is
// VK_NULL_HANDLE).
class Image {
 public:
  Image() = default;
  Image(Image&&) noexcept;
  Image& operator=(Image&&) noexcept;
  Image(const Image&) = delete;
  Image& operator=(const Image&) = delete;
  ~Image();

  VkImage handle() const { return image_; }
  VkImageView view() const { return view_; }  // VK_IMAGE_VIEW_TYPE_2D_ARRAY over all layers
  VkFormat format() const { return format_; }
  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  uint32_t layers() const { return layers_; }
  uint32_t mip_levels() const { return mip_levels_; }
  explicit operator bool() const { return image_ != VK_NULL_HANDLE; }

 private:
  friend class Context;
  VkDevice device_ = VK_NULL_HANDLE;
  const Functions* fn_ = nullptr;  // the Context's table (gpu/vk_functions.h)
  const VkAllocationCallbacks* alloc_ = nullptr;
  VkImage image_ = VK_NULL_HANDLE;
  VkImageView view_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkFormat format_ = VK_FORMAT_UNDEFINED;
  uint32_t width_ = 0, height_ = 0, layers_ = 0, mip_levels_ = 0;
  void reset();
};

}  // namespace tvt::vk
