#include "render/vt_system.h"

#include <embedded_shaders.h>

#include <algorithm>
#include <cstring>

#include "render/vt_info.h"
#include "shaders/shared/vt_bindings.h"

namespace tvt {

Result<std::unique_ptr<VtSystem>> VtSystem::create(vk::Context& context, const VtConfig& vt,
                                                   const VtSystemOptions& options) {
  ResidencyOptions ro;
  ro.slot_count = options.cache_slots;
  ro.window_pages = options.window_pages;
  ro.pinned_mips = options.pinned_mips;
  if (options.frames_in_flight < 1 || options.frames_in_flight > 8)
    return make_error("vt: frames_in_flight must be between 1 and 8, got " + std::to_string(options.frames_in_flight));
  ro.max_requests_per_frame = options.page_budget;
  if (auto s = Residency::validate(vt, ro, "vt"); !s) return s.error();
  if (options.page_budget > options.cache_slots)
    return make_error("vt: page_budget (" + std::to_string(options.page_budget) + ") exceeds cache_slots (" +
                      std::to_string(options.cache_slots) + ")");

  // The cache: one layer per slot, written by the producer (compute or transfer), sampled by
  // the terrain pass, read back by tools; GENERAL throughout.
  const VkImageUsageFlags usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT |
                                  VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  if (auto fits = context.check_image_fits(VK_FORMAT_R8G8B8A8_UNORM, vt.slot_texels(), vt.slot_texels(),
                                           options.cache_slots, usage,
                                           "vt cache (cache_slots pages of vt.page_texels + 2 vt.border_texels texels "
                                           "a side; use fewer slots or smaller pages)");
      !fits)
    return fits.error();
  auto cache = std::make_unique<vk::Image>(
      context.create_image(VK_FORMAT_R8G8B8A8_UNORM, vt.slot_texels(), vt.slot_texels(), options.cache_slots, usage));
  if (!*cache) return context.status().error();  // the producers size themselves on it
  // By value: with deferred set-up (gpu/context.h) this runs after create() returned.
  context.run_commands([ctx = &context, image = cache.get()](VkCommandBuffer cmd) {
    ctx->transition(cmd, *image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL);
  });
  std::shared_ptr<PageProducer> producer = options.producer;
  if (!producer && options.make_producer) {
    auto made = options.make_producer(context, *cache);
    if (!made) return made.error();
    producer = std::move(made.value());
  }
  if (!producer) return make_error("vt: no page producer");
  ro.max_requests_per_frame = std::max(producer->requests_per_frame(), 1u);

  std::unique_ptr<VtSystem> v(new VtSystem(vt, ro));
  v->context_ = &context;
  v->vt_ = vt;
  v->options_ = options;
  v->options_.make_producer = nullptr;  // used once; what it captured is released
  v->cache_ = std::move(cache);
  v->producer_ = std::move(producer);

  const PageTable& table = v->residency_.page_table();
  const auto entries = table.all_entries();
  v->entry_buffer_ = context.create_buffer(
      entries.size_bytes(),
      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, false);
  context.upload(v->entry_buffer_, entries.data(), entries.size_bytes());
  // Device-local, written in the command stream (vkCmdUpdateBuffer), so a frame still in
  // flight keeps reading its own values.
  v->info_buffer_ = context.create_buffer(sizeof(gpu::TvtVtInfo),
                                          VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                              VK_BUFFER_USAGE_TRANSFER_SRC_BIT,  // debug read-backs
                                          false);
  v->info_ = make_vt_info(vt, table, 0.f);
  context.upload(v->info_buffer_, &v->info_, sizeof(v->info_));
  // A recentre can rewrite every entry; nothing else writes more in one frame. One part of the
  // host-visible ring per frame in flight.
  v->update_capacity_ = uint32_t(entries.size());
  v->update_buffer_ = context.create_buffer(VkDeviceSize(v->update_capacity_) * 8 * options.frames_in_flight,
                                            VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);

  const vk::ComputeBinding bindings[] = {{TVT_BIND_SCATTER_ENTRIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                         {TVT_BIND_SCATTER_UPDATES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
  v->scatter_ = context.create_compute_pipeline(shaders::page_table_scatter_comp(), bindings, sizeof(gpu::TvtScatterPush));
  v->scatter_set_ = context.allocate_descriptor_set(v->scatter_);
  v->scatter_set_.write_buffer(TVT_BIND_SCATTER_ENTRIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, v->entry_buffer_);
  v->scatter_set_.write_buffer(TVT_BIND_SCATTER_UPDATES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, v->update_buffer_);

  VkSamplerCreateInfo si{};
  si.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO;
  si.magFilter = VK_FILTER_LINEAR;
  si.minFilter = VK_FILTER_LINEAR;
  si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  si.maxLod = 0.f;
  v->sampler_ = context.create_sampler(si);
  if (auto st = context.status(); !st) return st.error();  // a failed Vulkan call (v frees what was made)
  return v;
}

VtSystem::~VtSystem() {
  if (sampler_ != VK_NULL_HANDLE) context_->destroy_sampler(sampler_);
}

void VtSystem::take_outcome() {
  for (const PageRequest& r : outcome_.written) outstanding_.erase(r.page.pack());
  for (const PageRequest& r : outcome_.failed) {
    outstanding_.erase(r.page.pack());
    residency_.failed(r.page);  // its entries keep pointing at the nearest resident ancestor
  }
  for (const PageRequest& r : outcome_.cancelled) {
    outstanding_.erase(r.page.pack());
    residency_.cancelled(r.page);
  }
  stats_.produce_failed += uint32_t(outcome_.failed.size());
}

void VtSystem::begin_frame(uint64_t frame, uint32_t camera_x, uint32_t camera_y, std::span<const PageFeedback> feedback) {
  stats_ = VtFrameStats{};
  producer_->begin_frame(frame);
  residency_.set_centre(camera_x, camera_y);
  residency_.begin_frame(frame, feedback);
  for (const PageId& p : residency_.stale_in_flight(options_.cancel_after_frames))
    if (outstanding_.contains(p.pack())) producer_->cancel(p);

  const auto t0 = std::chrono::steady_clock::now();
  bool pinned_outstanding = false;  // a pinned page was accepted this frame
  for (;;) {
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (ms > options_.time_budget_ms) break;
    auto r = residency_.next_request();
    if (!r) break;
    const ProducerAccept a = producer_->request(*r);
    if (a == ProducerAccept::busy) {
      residency_.cancelled(r->page);  // asked again next frame
      break;
    }
    if (a == ProducerAccept::unavailable) {
      residency_.failed(r->page);  // the ancestor stands in
      ++stats_.missing;
      continue;
    }
    outstanding_.insert(r->page.pack());
    pinned_outstanding = pinned_outstanding || residency_.is_pinned(r->page);
  }
  // The pinned (coarsest) pages are what every texel falls back to: a frame that asks for them
  // (the first; later only a retry) waits for them, so no frame draws before they exist. They
  // are few and small.
  if (options_.sync_loads || pinned_outstanding) producer_->finish();
  stats_.select_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  info_ = make_vt_info(vt_, residency_.page_table(), float(residency_.mip_bias()));
  info_.debug_view = debug_view_;
}

Status VtSystem::record(VkCommandBuffer cmd) {
  // After a failed Vulkan call (out of memory, device lost) nothing more is recorded.
  if (auto st = context_->status(); !st) return st;
  // Earlier frames (possibly still in flight) sample the cache, entries and info that this
  // frame rewrites: their reads finish first (WAR, an execution dependency suffices).
  context_->fn().vkCmdPipelineBarrier(cmd,
                       VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT |
                           VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0, nullptr,
                       0, nullptr);
  context_->fn().vkCmdUpdateBuffer(cmd, info_buffer_.handle(), 0, sizeof(info_), &info_);
  outcome_.clear();
  const Status produced = producer_->record(cmd, outcome_);
  take_outcome();
  producer_->add_stats(stats_);
  // The pages written above are in the cache before this frame's terrain pass reads it (the
  // barrier below), so they are mapped now and sampled this very frame. One scatter carries
  // them with the evictions' unmaps (from next_request()) and the recentred windows; the page
  // table keeps one update per entry, so a frame never sends more than every entry.
  completed_.clear();
  for (const PageRequest& r : outcome_.written) {
    residency_.complete(r.page);
    completed_.push_back(r.page);
  }
  pending_updates_ = residency_.take_table_updates();
  TVT_CHECK(pending_updates_.size() <= update_capacity_);
  // This frame's part of the ring; the frame that used it last has completed (protocol).
  const uint32_t first = uint32_t(records_++ % options_.frames_in_flight) * update_capacity_;
  auto* dst = static_cast<uint32_t*>(update_buffer_.mapped()) + 2 * size_t(first);
  const PageTable& table = residency_.page_table();
  for (size_t i = 0; i < pending_updates_.size(); ++i) {
    dst[2 * i] = table.window(pending_updates_[i].mip).offset + pending_updates_[i].index;
    dst[2 * i + 1] = pending_updates_[i].value;
  }
  stats_.table_updates = uint32_t(pending_updates_.size());
  if (!pending_updates_.empty()) {
    context_->fn().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, scatter_.handle());
    const VkDescriptorSet set = scatter_set_.handle();
    context_->fn().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, scatter_.layout(), 0, 1, &set, 0, nullptr);
    const gpu::TvtScatterPush push{first, uint32_t(pending_updates_.size())};
    context_->fn().vkCmdPushConstants(cmd, scatter_.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
    context_->fn().vkCmdDispatch(cmd, (push.count + gpu::TVT_SCATTER_GROUP - 1) / gpu::TVT_SCATTER_GROUP, 1, 1);
  }
  pending_updates_.clear();
  // Composed texels, the info and scattered entries become visible to every later read.
  context_->memory_barrier(
      cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
      VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
      VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT);
  if (auto st = context_->status(); !st) return st;  // failed while recording: it outranks a producer's error
  return produced;
}

void VtSystem::end_frame() {
  producer_->end_frame();
  stats_.residency = residency_.stats();
}

uint64_t VtSystem::gpu_bytes() const {
  const uint64_t slot = uint64_t(vt_.slot_texels()) * vt_.slot_texels() * 4;
  return entry_buffer_.size() + info_buffer_.size() + slot * options_.cache_slots + producer_->gpu_bytes();
}

}  // namespace tvt
