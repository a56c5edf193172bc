#include "app/vt_debug.h"

#include <algorithm>
#include <cstring>

#include "shaders/shared/feedback_types.h"
#include "shaders/shared/vt_types.h"

namespace tvt {

namespace {
void put_mip_colour(uint8_t* p, int mip, double shade = 1.0) {
  const glm::vec4 c = gpu::tvt_mip_colour(mip);
  for (int i = 0; i < 3; ++i) p[i] = uint8_t(std::clamp(c[i] * shade * 255.0, 0.0, 255.0));
  p[3] = 255;
}
}  // namespace

ImageRGBA8 cache_atlas_image(vk::Context& context, const vk::Image& cache, uint32_t columns, uint32_t shrink) {
  const uint32_t n = cache.layers(), s = cache.width(), cols = std::max(1u, std::min(columns, n));
  const uint32_t rows = (n + cols - 1) / cols, cell = s / std::max(shrink, 1u);
  const VkDeviceSize layer_bytes = VkDeviceSize(s) * s * 4;
  vk::Buffer host = context.create_buffer(layer_bytes * n, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  context.run_commands([&](VkCommandBuffer cmd) {
    context.transition(cmd, cache, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, n};
    region.imageExtent = {s, s, 1};
    context.fn().vkCmdCopyImageToBuffer(cmd, cache.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host.handle(), 1, &region);
    context.transition(cmd, cache, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
  });
  ImageRGBA8 out(int(cols * (cell + 1) + 1), int(rows * (cell + 1) + 1));
  // After a failed Vulkan call (latched on the context; callers check its status) the image is black.
  if (!host || !context.status()) return out;
  const auto* src = static_cast<const uint8_t*>(host.mapped());
  for (uint32_t l = 0; l < n; ++l)
    for (uint32_t y = 0; y < cell; ++y)
      for (uint32_t x = 0; x < cell; ++x) {
        const uint8_t* p = src + layer_bytes * l + (size_t(y * shrink) * s + x * shrink) * 4;
        uint8_t* d = out.at(int((l % cols) * (cell + 1) + 1 + x), int((l / cols) * (cell + 1) + 1 + y));
        std::memcpy(d, p, 3);
        d[3] = 255;
      }
  return out;
}

ImageRGBA8 page_table_image(const PageTable& table) {
  std::vector<uint32_t> scale(table.mip_count());
  int width = 1, height = 1;
  for (uint32_t m = 0; m < table.mip_count(); ++m) {
    const uint32_t side = table.window(m).side;
    scale[m] = std::max(1u, 64u / side);
    width += int(side * scale[m]) + 2;
    height = std::max(height, int(side * scale[m]) + 2);
  }
  ImageRGBA8 out(width, height);
  int ox = 1;
  for (uint32_t m = 0; m < table.mip_count(); ++m) {
    const MipWindow& w = table.window(m);
    const auto entries = table.entries(m);
    for (uint32_t py = 0; py < w.side; ++py)
      for (uint32_t px = 0; px < w.side; ++px) {
        // Draw in page order: page (origin + p) lives at toroidal index (page mod side).
        const uint32_t gx = w.origin_x + px, gy = w.origin_y + py;
        const uint32_t e = entries[(gy % w.side) * w.side + (gx % w.side)];
        for (uint32_t sy = 0; sy < scale[m]; ++sy)
          for (uint32_t sx = 0; sx < scale[m]; ++sx) {
            uint8_t* d = out.at(ox + int(px * scale[m] + sx), 1 + int(py * scale[m] + sy));
            if (entry_valid(e))
              put_mip_colour(d, int(entry_mip(e)), entry_mip(e) == m ? 1.0 : 0.45);  // dim: ancestor data
            else
              d[3] = 255;
          }
      }
    ox += int(w.side * scale[m]) + 2;
  }
  return out;
}

ImageRGBA8 feedback_image(vk::Context& context, const vk::Buffer& feedback, uint32_t width, uint32_t height) {
  const VkDeviceSize bytes = VkDeviceSize(width) * height * 8;
  vk::Buffer host = context.create_buffer(bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  context.run_commands([&](VkCommandBuffer cmd) {
    const VkBufferCopy copy{0, 0, bytes};
    context.fn().vkCmdCopyBuffer(cmd, feedback.handle(), host.handle(), 1, &copy);
  });
  ImageRGBA8 out{int(width), int(height)};
  if (!host || !context.status()) return out;  // a failed Vulkan call (latched): black
  const auto* words = static_cast<const uint32_t*>(host.mapped());
  for (uint32_t i = 0; i < width * height; ++i) {
    uint8_t* d = &out.texels[size_t(i) * 4];
    d[3] = 255;
    if (!gpu::tvt_feedback_is_empty(words[2 * i])) put_mip_colour(d, int(gpu::tvt_feedback_mip(words[2 * i])));
  }
  return out;
}

std::vector<uint8_t> page_table_bytes(vk::Context& context, const vk::Buffer& entries) {
  vk::Buffer host = context.create_buffer(entries.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  context.run_commands([&](VkCommandBuffer cmd) {
    context.memory_barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                                VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                VK_ACCESS_TRANSFER_READ_BIT);
    const VkBufferCopy copy{0, 0, entries.size()};
    context.fn().vkCmdCopyBuffer(cmd, entries.handle(), host.handle(), 1, &copy);
    context.memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                                VK_ACCESS_HOST_READ_BIT);
  });
  if (!host || !context.status()) return std::vector<uint8_t>(entries.size(), 0);  // a failed Vulkan call (latched)
  const auto* p = static_cast<const uint8_t*>(host.mapped());
  return std::vector<uint8_t>(p, p + entries.size());
}

}  // namespace tvt
