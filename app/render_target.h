// Off-screen render target for dynamic rendering: N colour attachments (formats chosen by the
// caller, RGBA8 by default) plus an optional D32_SFLOAT depth attachment, all W x H, and
// blocking readback of a colour attachment for tools and tests.
//
// Layout contract: begin() takes every attachment from UNDEFINED (contents discarded: every
// attachment is cleared) to ATTACHMENT_OPTIMAL; end() leaves colour attachments in
// TRANSFER_SRC_OPTIMAL (ready for readback or a copy) and depth in DEPTH_ATTACHMENT_OPTIMAL.
// Not thread-safe. Must be destroyed before its Context.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <vector>

#include "compose/image.h"
#include "gpu/context.h"

namespace tvt::vk {

struct RenderTargetDesc {
  uint32_t width = 0;   // pixels
  uint32_t height = 0;  // pixels
  std::vector<VkFormat> color_formats = {VK_FORMAT_R8G8B8A8_UNORM};  // location order
  bool depth = true;    // D32_SFLOAT
  VkImageUsageFlags extra_color_usage = 0;  // e.g. STORAGE, for a compute pass reading attachments
};

class RenderTarget {
 public:
  static constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

  RenderTarget() = default;
  RenderTarget(Context& context, const RenderTargetDesc& desc);

  uint32_t width() const { return desc_.width; }
  uint32_t height() const { return desc_.height; }
  const std::vector<VkFormat>& color_formats() const { return desc_.color_formats; }
  VkFormat depth_format() const { return desc_.depth ? kDepthFormat : VK_FORMAT_UNDEFINED; }
  const Image& color(uint32_t index) const { return colors_.at(index); }

  // Records the transitions, vkCmdBeginRendering with every attachment cleared
  // (clear_colors[i] for attachment i, missing entries clear to zero; depth clears to
  // clear_depth: 0 for reverse-Z), and a viewport + scissor over the whole target.
  void begin(VkCommandBuffer cmd, const std::vector<VkClearColorValue>& clear_colors, float clear_depth = 0.0f) const;
  // Records vkCmdEndRendering and the transition of colour attachments to TRANSFER_SRC_OPTIMAL.
  void end(VkCommandBuffer cmd) const;

  // Blocking: copies colour attachment `index` (after end() has been submitted and completed or
  // in the same queue order) to host memory, rows tightly packed, texel size of its format.
  std::vector<uint8_t> read_color(uint32_t index) const;
  // read_color() of an RGBA8 attachment as an image.
  ImageRGBA8 read_rgba8(uint32_t index = 0) const;

 private:
  Context* context_ = nullptr;
  RenderTargetDesc desc_;
  std::vector<Image> colors_;
  Image depth_;
};

// Bytes per texel of the colour formats RenderTarget reads back (fatal for others).
uint32_t texel_bytes(VkFormat format);

}  // namespace tvt::vk
