// Off-screen render target (see render_target.h for the layout contract).
#include "app/render_target.h"

#include <cstring>

namespace tvt::vk {

uint32_t texel_bytes(VkFormat format) {
  switch (format) {
    case VK_FORMAT_R8G8B8A8_UNORM:
    case VK_FORMAT_R8G8B8A8_SRGB:
    case VK_FORMAT_B8G8R8A8_UNORM:
    case VK_FORMAT_R32_UINT:
    case VK_FORMAT_R32_SFLOAT: return 4;
    case VK_FORMAT_R32G32_UINT:
    case VK_FORMAT_R32G32_SFLOAT:
    case VK_FORMAT_R16G16B16A16_SFLOAT: return 8;
    case VK_FORMAT_R32G32B32A32_UINT:
    case VK_FORMAT_R32G32B32A32_SFLOAT: return 16;
    default: fatal(__FILE__, __LINE__, "texel_bytes", "render target format without a known texel size");
  }
}

RenderTarget::RenderTarget(Context& context, const RenderTargetDesc& desc) : context_(&context), desc_(desc) {
  TVT_CHECK(desc.width > 0 && desc.height > 0);
  TVT_CHECK(!desc.color_formats.empty() || desc.depth);
  for (const VkFormat f : desc.color_formats) {
    (void)texel_bytes(f);  // readable back
    colors_.push_back(context.create_image(f, desc.width, desc.height, 1,
                                           VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT |
                                               desc.extra_color_usage));
  }
  if (desc.depth) {
    depth_ = context.create_image(kDepthFormat, desc.width, desc.height, 1, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT);
  }
}

void RenderTarget::begin(VkCommandBuffer cmd, const std::vector<VkClearColorValue>& clear_colors,
                         float clear_depth) const {
  TVT_CHECK(context_ != nullptr);
  std::vector<VkRenderingAttachmentInfo> color_infos;
  for (size_t i = 0; i < colors_.size(); ++i) {
    context_->transition(cmd, colors_[i], VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL);
    VkRenderingAttachmentInfo a{};
    a.sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO;
    a.imageView = colors_[i].view();
    a.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    a.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    a.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    if (i < clear_colors.size()) a.clearValue.color = clear_colors[i];
    color_infos.push_back(a);
  }
  VkRenderingAttachmentInfo depth_info{};
  if (desc_.depth) {
    context_->transition(cmd, depth_, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL);
    depth_info.sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO;
    depth_info.imageView = depth_.view();
    depth_info.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth_info.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    depth_info.storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
    depth_info.clearValue.depthStencil = {clear_depth, 0};
  }
  VkRenderingInfo ri{};
  ri.sType = VK_STRUCTURE_TYPE_RENDERING_INFO;
  ri.renderArea = {{0, 0}, {desc_.width, desc_.height}};
  ri.layerCount = 1;
  ri.colorAttachmentCount = uint32_t(color_infos.size());
  ri.pColorAttachments = color_infos.data();
  ri.pDepthAttachment = desc_.depth ? &depth_info : nullptr;
  context_->fn().vkCmdBeginRendering(cmd, &ri);

  const VkViewport viewport{0.0f, 0.0f, float(desc_.width), float(desc_.height), 0.0f, 1.0f};
  const VkRect2D scissor{{0, 0}, {desc_.width, desc_.height}};
  context_->fn().vkCmdSetViewport(cmd, 0, 1, &viewport);
  context_->fn().vkCmdSetScissor(cmd, 0, 1, &scissor);
}

void RenderTarget::end(VkCommandBuffer cmd) const {
  context_->fn().vkCmdEndRendering(cmd);
  for (const Image& c : colors_) {
    context_->transition(cmd, c, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
  }
}

std::vector<uint8_t> RenderTarget::read_color(uint32_t index) const {
  TVT_CHECK(context_ != nullptr && index < colors_.size());
  const Image& img = colors_[index];
  const VkDeviceSize bytes = VkDeviceSize(desc_.width) * desc_.height * texel_bytes(img.format());
  Buffer staging = context_->create_buffer(bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  std::vector<uint8_t> out(static_cast<size_t>(bytes), 0);
  // After a failed Vulkan call (latched: context.status()) the read-back is zeros; callers
  // check the context's status before they use a frame.
  if (!staging) return out;
  context_->run_commands([&](VkCommandBuffer cmd) {
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {desc_.width, desc_.height, 1};
    context_->fn().vkCmdCopyImageToBuffer(cmd, img.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, staging.handle(), 1, &region);
    context_->memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                                VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
  });
  if (context_->status()) std::memcpy(out.data(), staging.mapped(), out.size());
  return out;
}

ImageRGBA8 RenderTarget::read_rgba8(uint32_t index) const {
  TVT_CHECK(index < colors_.size() && (colors_[index].format() == VK_FORMAT_R8G8B8A8_UNORM ||
                                       colors_[index].format() == VK_FORMAT_R8G8B8A8_SRGB));
  ImageRGBA8 image(int(desc_.width), int(desc_.height));
  image.texels = read_color(index);
  return image;
}

}  // namespace tvt::vk
