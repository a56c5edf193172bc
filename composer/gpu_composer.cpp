#include "composer/gpu_composer.h"

#include <embedded_shaders.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>

#include "shaders/shared/compose_bindings.h"
#include "shaders/shared/compose_coord.h"

namespace tvt {

GpuComposer::~GpuComposer() = default;

Result<std::unique_ptr<GpuComposer>> GpuComposer::create(vk::Context& context, const PackedScene& scene,
                                                         uint32_t slots, const GpuComposerOptions& options) {
  if (slots == 0 || slots > context.properties().limits.maxImageArrayLayers)
    return make_error("compose slots: must be between 1 and " +
                      std::to_string(context.properties().limits.maxImageArrayLayers) + ", got " +
                      std::to_string(slots));
  std::unique_ptr<GpuComposer> c(new GpuComposer());
  c->context_ = &context;
  c->slots_ = slots;
  c->slot_texels_ = uint32_t(scene.params.page_texels + 2 * scene.params.border_texels);
  c->params_ = scene.params;
  c->culler_ = std::make_unique<MaterialCuller>(scene);

  c->params_buffer_ = context.create_buffer(sizeof(gpu::TvtComposeParams), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  if (!c->params_buffer_) return context.status().error();
  std::memcpy(c->params_buffer_.mapped(), &c->params_, sizeof(c->params_));
  c->records_in_flight_ = std::max(options.records_in_flight, 1u);
  c->materials_ = std::make_unique<MaterialUploader>(context, scene, c->records_in_flight_);
  if (options.poison_materials)
    context.run_commands([m = c->materials_.get()](VkCommandBuffer cmd) { m->fill(cmd, 0xffffffffu); });  // by value: may be deferred
  if (!options.lazy_materials)
    if (auto s = c->materials_->upload_all(); !s) return s.error();
  c->job_buffer_ = context.create_buffer(sizeof(gpu::TvtPageJob) * slots * c->records_in_flight_,
                                         VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  // The read-back buffer of compose_pages() is made on its first use: a VT cache never needs it.
  if (options.target) {
    const vk::Image& t = *options.target;
    if (t.format() != VK_FORMAT_R8G8B8A8_UNORM || t.width() != c->slot_texels_ || t.height() != c->slot_texels_ ||
        t.layers() < slots)
      return make_error("compose target: must be RGBA8 " + std::to_string(c->slot_texels_) + "^2 with at least " +
                        std::to_string(slots) + " layers");
    c->target_ = options.target;
  } else {
    const VkImageUsageFlags usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT |
                                    VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
    if (auto fits = context.check_image_fits(VK_FORMAT_R8G8B8A8_UNORM, c->slot_texels_, c->slot_texels_, slots, usage,
                                             "compose slots (one per cached page, vt.page_texels + 2 vt.border_texels "
                                             "texels a side; use fewer slots or smaller pages)");
        !fits)
      return fits.error();
    c->own_output_ = context.create_image(VK_FORMAT_R8G8B8A8_UNORM, c->slot_texels_, c->slot_texels_, slots, usage);
    c->target_ = &c->own_output_;
    // By value: with deferred set-up (gpu/context.h) this runs after create() returned.
    context.run_commands([ctx = &context, image = &c->own_output_](VkCommandBuffer cmd) {
      ctx->transition(cmd, *image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL);
    });
  }

  const vk::ComputeBinding bindings[] = {
      {TVT_BIND_COMPOSE_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}, {TVT_BIND_MATERIAL_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
      {TVT_BIND_META_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},    {TVT_BIND_WEIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
      {TVT_BIND_PAGE_JOBS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},      {TVT_BIND_PAGE_OUTPUT, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
  };
  c->pipeline_ = context.create_compute_pipeline(shaders::compose_comp(), bindings, sizeof(gpu::TvtComposePush));
  c->descriptors_ = context.allocate_descriptor_set(c->pipeline_);
  c->descriptors_.write_buffer(TVT_BIND_COMPOSE_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->params_buffer_);
  c->descriptors_.write_buffer(TVT_BIND_MATERIAL_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->materials_->texels());
  c->descriptors_.write_buffer(TVT_BIND_META_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->materials_->meta());
  c->descriptors_.write_buffer(TVT_BIND_WEIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->materials_->weights());
  c->descriptors_.write_buffer(TVT_BIND_PAGE_JOBS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->job_buffer_);
  c->descriptors_.write_storage_image(TVT_BIND_PAGE_OUTPUT, *c->target_);
  if (auto st = context.status(); !st) return st.error();  // a failed Vulkan call (c frees what was made)
  return c;
}

void GpuComposer::set_params(const gpu::TvtComposeParams& params) {
  TVT_CHECK(materials_->same_layout(params));
  params_ = params;
  culler_->set_params(params);
  std::memcpy(params_buffer_.mapped(), &params_, sizeof(params_));
}

Status GpuComposer::record(VkCommandBuffer cmd, std::span<const PageJob> jobs) {
  TVT_CHECK(jobs.size() <= slots_);
  if (auto st = context_->status(); !st) return st;  // nothing is recorded after a failed Vulkan call
  // This call's part of the job ring; the call that last used it has completed (contract).
  const uint32_t job_offset = uint32_t(records_++ % records_in_flight_) * slots_;
  auto* dst = static_cast<gpu::TvtPageJob*>(job_buffer_.mapped()) + job_offset;
  MaterialNeeds needed;  // what any of the pages reads
  for (size_t i = 0; i < jobs.size(); ++i) {
    TVT_CHECK(jobs[i].slot < slots_);
    const uint32_t mask = culling_ ? culler_->mask(jobs[i].page) : 0xffffffffu;
    dst[i] = gpu::TvtPageJob{jobs[i].page.mip, jobs[i].page.x, jobs[i].page.y, jobs[i].slot, mask, 0u, 0u, 0u};
    if (params_.pattern == gpu::TVT_COMPOSE_PATTERN_NONE) needed.merge(culler_->needs(jobs[i].page, mask));
  }
  // Also with no jobs: the per-record counters restart.
  if (auto s = materials_->record(cmd, needed); !s) return s;
  if (jobs.empty()) return Ok{};
  context_->fn().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.handle());
  const VkDescriptorSet set = descriptors_.handle();
  context_->fn().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.layout(), 0, 1, &set, 0, nullptr);
  const gpu::TvtComposePush push{job_offset, uint32_t(jobs.size())};
  context_->fn().vkCmdPushConstants(cmd, pipeline_.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
  const uint32_t groups = (slot_texels_ + gpu::TVT_COMPOSE_GROUP - 1) / gpu::TVT_COMPOSE_GROUP;
  context_->fn().vkCmdDispatch(cmd, groups, groups, uint32_t(jobs.size()));
  return Ok{};
}

Result<std::vector<std::vector<uint8_t>>> GpuComposer::compose_pages(std::span<const PageId> pages) {
  std::vector<std::vector<uint8_t>> out;
  out.reserve(pages.size());
  const size_t page_bytes = size_t(slot_texels_) * slot_texels_ * 4;
  if (!readback_buffer_ && !pages.empty())
    readback_buffer_ = context_->create_buffer(VkDeviceSize(page_bytes) * slots_, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  if (!pages.empty() && !readback_buffer_) return context_->status().error();
  for (size_t first = 0; first < pages.size(); first += slots_) {
    const size_t count = std::min<size_t>(slots_, pages.size() - first);
    std::vector<PageJob> jobs(count);
    for (size_t i = 0; i < count; ++i) jobs[i] = PageJob{pages[first + i], uint32_t(i)};
    Status recorded = Ok{};
    context_->run_commands([&](VkCommandBuffer cmd) {
      recorded = record(cmd, jobs);
      if (!recorded) return;
      context_->transition(cmd, *target_, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
      VkBufferImageCopy region{};
      region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, uint32_t(count)};
      region.imageExtent = {slot_texels_, slot_texels_, 1};
      context_->fn().vkCmdCopyImageToBuffer(cmd, target_->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, readback_buffer_.handle(), 1,
                             &region);
      context_->transition(cmd, *target_, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
    });
    if (!recorded) return recorded.error();
    if (auto st = context_->status(); !st) return st.error();  // nothing ran
    const auto* src = static_cast<const uint8_t*>(readback_buffer_.mapped());
    for (size_t i = 0; i < count; ++i) out.emplace_back(src + i * page_bytes, src + (i + 1) * page_bytes);
  }
  return out;
}

Result<double> GpuComposer::time_batch(std::span<const PageId> pages, int repeats) {
  TVT_CHECK(pages.size() <= slots_);
  std::vector<PageJob> jobs(pages.size());
  for (size_t i = 0; i < pages.size(); ++i) jobs[i] = PageJob{pages[i], uint32_t(i)};
  // A hardware GPU is timed by timestamps around the batch (submit and fence latency would
  // swamp a batch that takes a fraction of a millisecond); a CPU device by the wall clock.
  const bool cpu_device = context_->properties().deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
  const auto start = std::chrono::steady_clock::now();
  double device_seconds = 0;
  Status recorded = Ok{};
  for (int r = 0; r < repeats && recorded; ++r) {
    const auto rec = [&](VkCommandBuffer cmd) { recorded = record(cmd, jobs); };
    if (cpu_device)
      context_->run_commands(rec);
    else
      device_seconds += context_->run_commands_timed(rec);
  }
  if (!recorded) return recorded.error();
  if (auto st = context_->status(); !st) return st.error();
  const double seconds =
      cpu_device ? std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() : device_seconds;
  return seconds / std::max(repeats, 1);
}

}  // namespace tvt
