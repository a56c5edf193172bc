#include "render/vt_system.h"

#include <embedded_shaders.h>

#include <algorithm>
#include <cstring>

#include "render/vt_info.h"
#include "shaders/shared/vt_bindings.h"

namespace tvt {

std::string_view to_string(VtSource source) {
  switch (source) {
    case VtSource::procedural: return "procedural";
    case VtSource::stored: return "stored";
    case VtSource::hybrid: return "hybrid";
  }
  return "?";
}

std::optional<VtSource> vt_source_from_string(std::string_view text) {
  for (VtSource s : {VtSource::procedural, VtSource::stored, VtSource::hybrid})
    if (text == to_string(s)) return s;
  return std::nullopt;
}

Result<std::unique_ptr<VtSystem>> VtSystem::create(vk::Context& context, const PackedScene& scene,
                                                   const VtSystemOptions& options) {
  VtConfig vt;
  vt.log2_size = uint32_t(scene.params.log2_vt);
  vt.page_texels = uint32_t(scene.params.page_texels);
  vt.border_texels = uint32_t(scene.params.border_texels);
  ResidencyOptions ro;
  ro.slot_count = options.cache_slots;
  ro.window_pages = options.window_pages;
  ro.max_requests_per_frame = options.page_budget;
  ro.pinned_mips = options.pinned_mips;
  const bool streams = options.source != VtSource::procedural;
  StoredProducerOptions lo = options.loader;
  if (streams) {
    if (!options.store) return make_error("source: '" + std::string(to_string(options.source)) + "' needs a page store");
    // Async loads may be outstanding on top of the pages composed this frame; a synchronous
    // run asks for exactly what a procedural run would, so its frames match one for one.
    // Staging is released frames_in_flight frames after its copy was recorded.
    if (options.sync_loads) lo.staging_slots = std::max(lo.staging_slots, options.page_budget * options.frames_in_flight);
    else ro.max_requests_per_frame = options.page_budget + lo.staging_slots;
  }
  if (options.frames_in_flight < 1 || options.frames_in_flight > 8)
    return make_error("vt: frames_in_flight must be between 1 and 8, got " + std::to_string(options.frames_in_flight));
  lo.frames_in_flight = options.frames_in_flight;
  if (auto s = Residency::validate(vt, ro, "vt"); !s) return s.error();
  if (options.page_budget > options.cache_slots)
    return make_error("vt: page_budget (" + std::to_string(options.page_budget) + ") exceeds cache_slots (" +
                      std::to_string(options.cache_slots) + ")");

  std::unique_ptr<VtSystem> v(new VtSystem(vt, ro));
  v->context_ = &context;
  v->vt_ = vt;
  v->options_ = options;
  GpuComposerOptions co;
  co.records_in_flight = options.frames_in_flight;
  auto composer = GpuComposer::create(context, scene, options.cache_slots, co);
  if (!composer) return composer.error();
  v->composer_ = std::move(composer.value());
  if (streams) {
    auto stored = StoredProducer::create(context, options.store, vt, options.scene_hash, lo);
    if (!stored) return stored.error();
    v->stored_ = std::move(stored.value());
  }

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
  return v;
}

VtSystem::~VtSystem() {
  if (sampler_ != VK_NULL_HANDLE) context_->destroy_sampler(sampler_);
}

void VtSystem::collect_loads() {
  const size_t landed_before = landing_.size();
  load_failed_.clear();
  load_cancelled_.clear();
  stored_->poll(landing_, load_failed_, load_cancelled_);
  for (size_t i = landed_before; i < landing_.size(); ++i) loading_.erase(landing_[i].page.pack());
  for (const PageRequest& r : load_cancelled_) {
    loading_.erase(r.page.pack());
    residency_.cancelled(r.page);
  }
  for (const PageRequest& r : load_failed_) {
    loading_.erase(r.page.pack());
    // Hybrid: compose the page into the slot it was meant for; otherwise its entries keep
    // pointing at the nearest resident ancestor.
    if (options_.source == VtSource::hybrid && jobs_.size() < composer_->slots()) {
      jobs_.push_back(PageJob{r.page, r.slot});
      ++stats_.fallback_composed;
    } else {
      residency_.failed(r.page);
    }
  }
}

void VtSystem::begin_frame(uint64_t frame, uint32_t camera_x, uint32_t camera_y, std::span<const PageFeedback> feedback) {
  // record() consumed the previous frame's jobs and landed pages; skipping it would leave them
  // in flight for ever, their slots lost.
  TVT_CHECK(jobs_.empty() && landing_.empty() && "VtSystem: record() must follow every begin_frame()");
  stats_ = VtFrameStats{};
  if (stored_) {
    stored_->begin_frame();
    collect_loads();
  }
  residency_.set_centre(camera_x, camera_y);
  residency_.begin_frame(frame, feedback);
  if (stored_)
    for (const PageId& p : residency_.stale_in_flight(options_.cancel_after_frames))
      if (loading_.contains(p.pack())) stored_->cancel(p);

  const auto t0 = std::chrono::steady_clock::now();
  uint32_t composed_new = 0;
  bool pinned_loading = false;  // a pinned page was requested from the store this frame
  for (;;) {
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (ms > options_.time_budget_ms) break;
    if (options_.source == VtSource::stored && !stored_->can_accept()) break;
    auto r = residency_.next_request();
    if (!r) break;
    if (stored_ && stored_->has(r->page)) {
      if (!stored_->request(*r)) {
        residency_.cancelled(r->page);  // ring full: asked again next frame
        break;
      }
      loading_.insert(r->page.pack());
      pinned_loading = pinned_loading || residency_.is_pinned(r->page);
      continue;
    }
    if (options_.source == VtSource::stored) {
      residency_.failed(r->page);  // not in the store: the ancestor stands in
      ++stats_.missing;
      continue;
    }
    if (composed_new >= options_.page_budget || jobs_.size() >= composer_->slots()) {
      residency_.cancelled(r->page);
      break;
    }
    jobs_.push_back(PageJob{r->page, r->slot});
    ++composed_new;
  }
  // The pinned (coarsest) pages are what every texel falls back to: a frame that asks for them
  // (the first; later only a retry) waits for their loads, so no frame draws before the store
  // has given them. They are few and small; a failed one is composed here in hybrid.
  if (stored_ && (options_.sync_loads || pinned_loading)) {
    stored_->wait_idle();
    collect_loads();
  }
  stats_.select_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  stats_.composed = uint32_t(jobs_.size());
  info_ = make_vt_info(vt_, residency_.page_table(), float(residency_.mip_bias()));
  info_.debug_view = debug_view_;
}

Status VtSystem::record(VkCommandBuffer cmd) {
  // Earlier frames (possibly still in flight) sample the cache, entries and info that this
  // frame rewrites: their reads finish first (WAR, an execution dependency suffices).
  vkCmdPipelineBarrier(cmd,
                       VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT |
                           VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0, nullptr,
                       0, nullptr);
  vkCmdUpdateBuffer(cmd, info_buffer_.handle(), 0, sizeof(info_), &info_);
  Status composed = composer_->record(cmd, jobs_);
  stats_.materials = composer_->upload_stats();
  if (!composed) {
    // Nothing was recorded for these pages: they must not become resident.
    for (const PageJob& j : jobs_) residency_.failed(j.page);
    stats_.compose_failed = uint32_t(jobs_.size());
    stats_.composed = 0;
    jobs_.clear();
  }
  if (stored_) {
    stored_->record(cmd, composer_->output());
    stats_.stored = stored_->stats();
  }
  // The pages written above are in the cache before this frame's terrain pass reads it (the
  // barrier below), so they are mapped now and sampled this very frame. One scatter carries
  // them with the evictions' unmaps (from next_request()) and the recentred windows; the page
  // table keeps one update per entry, so a frame never sends more than every entry.
  completed_.clear();
  for (const PageJob& j : jobs_) {
    residency_.complete(j.page);
    completed_.push_back(j.page);
  }
  jobs_.clear();
  for (const PageRequest& r : landing_) {
    residency_.complete(r.page);
    completed_.push_back(r.page);
  }
  landing_.clear();
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
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, scatter_.handle());
    const VkDescriptorSet set = scatter_set_.handle();
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, scatter_.layout(), 0, 1, &set, 0, nullptr);
    const gpu::TvtScatterPush push{first, uint32_t(pending_updates_.size())};
    vkCmdPushConstants(cmd, scatter_.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
    vkCmdDispatch(cmd, (push.count + gpu::TVT_SCATTER_GROUP - 1) / gpu::TVT_SCATTER_GROUP, 1, 1);
  }
  pending_updates_.clear();
  // Composed texels, the info and scattered entries become visible to every later read.
  vk::Context::memory_barrier(
      cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
      VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
      VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT);
  return composed;
}

void VtSystem::end_frame() {
  if (stored_) stored_->end_frame();
  stats_.residency = residency_.stats();
}

uint64_t VtSystem::gpu_bytes() const {
  const uint64_t slot = uint64_t(vt_.slot_texels()) * vt_.slot_texels() * 4;
  return entry_buffer_.size() + info_buffer_.size() + slot * options_.cache_slots +
         (stored_ ? stored_->gpu_bytes() : 0);
}

}  // namespace tvt
