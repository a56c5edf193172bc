// Plain pre-composed texture (see plain_texture.h).
#include "app/plain_texture.h"

#include <chrono>
#include <vector>

#include "composer/gpu_composer.h"

namespace tvt {

namespace {

void level_barrier(const vk::Context& context, VkCommandBuffer cmd, const vk::Image& image, uint32_t level, VkImageLayout from, VkImageLayout to,
                   VkAccessFlags src_access, VkAccessFlags dst_access, VkPipelineStageFlags dst_stage) {
  VkImageMemoryBarrier b{};
  b.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
  b.srcAccessMask = src_access;
  b.dstAccessMask = dst_access;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image.handle();
  b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, level, 1, 0, 1};
  context.fn().vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, dst_stage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

}  // namespace

PlainTexture::~PlainTexture() {
  if (sampler_ != VK_NULL_HANDLE) context_->destroy_sampler(sampler_);
}

uint64_t PlainTexture::bytes() const {
  uint64_t sum = 0;
  for (uint32_t l = 0; l <= log2_size_; ++l) sum += (uint64_t(1) << (2 * (log2_size_ - l))) * 4;
  return sum;
}

Result<std::unique_ptr<PlainTexture>> PlainTexture::create(vk::Context& context, const PackedScene& scene,
                                                           const PlainTextureOptions& options) {
  const uint32_t log2_vt = uint32_t(scene.params.log2_vt);
  const uint32_t page = uint32_t(scene.params.page_texels), border = uint32_t(scene.params.border_texels);
  uint32_t log2_page = 0;
  while ((1u << log2_page) < page) ++log2_page;
  const uint32_t max_dim = context.properties().limits.maxImageDimension2D;
  if (options.log2_size < log2_page || options.log2_size > log2_vt || (1u << options.log2_size) > max_dim)
    return make_error("plain texture: log2_size must be between log2 P (" + std::to_string(log2_page) + ") and log2 V (" +
                      std::to_string(log2_vt) + ") and fit maxImageDimension2D (" + std::to_string(max_dim) + ")");
  if (options.batch_pages < 1) return make_error("plain texture: batch_pages must be at least 1");
  VkFormatProperties fp{};
  context.fn().vkGetPhysicalDeviceFormatProperties(context.physical_device(), VK_FORMAT_R8G8B8A8_UNORM, &fp);
  const VkFormatFeatureFlags need = VK_FORMAT_FEATURE_BLIT_SRC_BIT | VK_FORMAT_FEATURE_BLIT_DST_BIT |
                                    VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT;
  if ((fp.optimalTilingFeatures & need) != need)
    return make_error("plain texture: device " + context.device_name() + " cannot blit or linearly filter RGBA8");

  const auto t0 = std::chrono::steady_clock::now();
  std::unique_ptr<PlainTexture> t(new PlainTexture());
  t->context_ = &context;
  t->log2_size_ = options.log2_size;
  t->vt_mip_ = log2_vt - options.log2_size;
  const uint32_t size = 1u << options.log2_size, levels = options.log2_size + 1;
  t->image_ = context.create_image(VK_FORMAT_R8G8B8A8_UNORM, size, size, 1,
                                   VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT |
                                       VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                                   levels);
  auto composer = GpuComposer::create(context, scene, options.batch_pages);
  if (!composer) return composer.error();
  GpuComposer& c = *composer.value();

  // Level 0: every page of VT mip vt_mip_, payload copied to (x P, y P).
  const uint32_t pages_per_side = size / page;
  std::vector<PageJob> jobs;
  context.run_commands([&](VkCommandBuffer cmd) {
    context.transition(cmd, t->image_, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
  });
  const uint32_t total = pages_per_side * pages_per_side;
  for (uint32_t first = 0; first < total; first += options.batch_pages) {
    jobs.clear();
    for (uint32_t i = first; i < total && jobs.size() < options.batch_pages; ++i)
      jobs.push_back(PageJob{PageId{t->vt_mip_, i % pages_per_side, i / pages_per_side}, uint32_t(jobs.size())});
    Status recorded = Ok{};
    context.run_commands([&](VkCommandBuffer cmd) {
      recorded = c.record(cmd, jobs);
      if (!recorded) return;
      context.memory_barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                                  VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
      context.transition(cmd, c.output(), VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
      std::vector<VkImageCopy> regions(jobs.size());
      for (size_t i = 0; i < jobs.size(); ++i) {
        VkImageCopy& r = regions[i];
        r.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, jobs[i].slot, 1};
        r.srcOffset = {int32_t(border), int32_t(border), 0};
        r.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        r.dstOffset = {int32_t(jobs[i].page.x * page), int32_t(jobs[i].page.y * page), 0};
        r.extent = {page, page, 1};
      }
      context.fn().vkCmdCopyImage(cmd, c.output().handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, t->image_.handle(),
                     VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, uint32_t(regions.size()), regions.data());
      context.transition(cmd, c.output(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
    });
    if (!recorded) return recorded.error();
    t->pages_ += uint32_t(jobs.size());
  }

  // Levels 1 ... log2_size: 2:1 linear blits (exactly the 2x2 box filter).
  context.run_commands([&](VkCommandBuffer cmd) {
    for (uint32_t l = 1; l < levels; ++l) {
      level_barrier(context, cmd, t->image_, l - 1, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                    VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
      const int32_t src = int32_t(size >> (l - 1)), dst = int32_t(size >> l);
      VkImageBlit blit{};
      blit.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, l - 1, 0, 1};
      blit.srcOffsets[1] = {src, src, 1};
      blit.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, l, 0, 1};
      blit.dstOffsets[1] = {dst, dst, 1};
      context.fn().vkCmdBlitImage(cmd, t->image_.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, t->image_.handle(),
                     VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &blit, VK_FILTER_LINEAR);
    }
    level_barrier(context, cmd, t->image_, levels - 1, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                  VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT);
    context.transition(cmd, t->image_, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  });

  VkSamplerCreateInfo si{};
  si.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO;
  si.magFilter = VK_FILTER_LINEAR;
  si.minFilter = VK_FILTER_LINEAR;
  si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_LINEAR;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  si.maxLod = VK_LOD_CLAMP_NONE;
  t->sampler_ = context.create_sampler(si);
  t->seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (auto st = context.status(); !st) return st.error();  // a failed Vulkan call (latched)
  return t;
}

}  // namespace tvt
