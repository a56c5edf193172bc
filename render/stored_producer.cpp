#include "render/stored_producer.h"

#include <algorithm>

namespace tvt {

Result<std::unique_ptr<StoredProducer>> StoredProducer::create(vk::Context& context,
                                                               std::shared_ptr<const PageStoreReader> store,
                                                               const VtConfig& vt, uint64_t scene_hash,
                                                               const StoredProducerOptions& options) {
  TVT_CHECK(store != nullptr);
  if (auto s = matches(*store, vt, scene_hash); !s) return s.error();
  if (options.staging_slots < 1) return make_error("staging_slots: must be at least 1");
  if (options.threads < 1) return make_error("loader threads: must be at least 1");
  if (options.frames_in_flight < 1) return make_error("frames_in_flight: must be at least 1");

  std::unique_ptr<StoredProducer> p(new StoredProducer());
  p->context_ = &context;
  p->store_ = std::move(store);
  p->staging_slots_ = options.staging_slots;
  p->slot_texels_ = vt.slot_texels();
  p->to_release_.resize(options.frames_in_flight);
  // Only layer 0 goes to the cache; a store with more layers is staged whole (page_bytes).
  const uint64_t page_bytes = p->store_->desc().page_bytes();
  p->staging_ = context.create_buffer(VkDeviceSize(page_bytes) * options.staging_slots,
                                      VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
  if (!p->staging_) return context.status().error();
  std::span<uint8_t> staging(static_cast<uint8_t*>(p->staging_.mapped()), size_t(page_bytes) * options.staging_slots);
  PageLoaderOptions lo;
  lo.threads = options.threads;
  lo.staging_slots = options.staging_slots;
  p->loader_ = std::make_unique<PageLoader>(p->store_, lo, staging);
  return p;
}

Status StoredProducer::matches(const PageStoreReader& store, const VtConfig& vt, uint64_t scene_hash) {
  const std::string& path = store.path();
  const StoreDesc& d = store.desc();
  auto mismatch = [&](const std::string& field, uint64_t have, uint64_t want) {
    return make_error(path + ": " + field + " is " + std::to_string(have) + " but the scene needs " +
                      std::to_string(want) + " (bake the store from this scene)");
  };
  if (d.vt.log2_size != vt.log2_size) return mismatch("vt.log2_size", d.vt.log2_size, vt.log2_size);
  if (d.vt.page_texels != vt.page_texels) return mismatch("vt.page_texels", d.vt.page_texels, vt.page_texels);
  if (d.vt.border_texels != vt.border_texels) return mismatch("vt.border_texels", d.vt.border_texels, vt.border_texels);
  if (d.layers.empty() || d.layers[0] != PageLayerFormat::rgba8_albedo_height)
    return make_error(path + ": layers[0]: not RGBA8 albedo+height, which the cache holds");
  if (scene_hash != 0 && d.scene_hash != 0 && d.scene_hash != scene_hash)
    return make_error(path + ": scene_hash: the store was baked from another scene, method or mip strategy (producer '" +
                      d.producer + "'); its pages would not match this scene");
  return Ok{};
}

StoredProducer::~StoredProducer() {
  // The loader joins its threads before the staging buffer it writes into goes away.
  loader_.reset();
}

bool StoredProducer::has(const PageId& page) const {
  return store_->contains(page) && !bad_.contains(page.pack());
}

bool StoredProducer::can_accept() const {
  const PageLoaderStats s = loader_->stats();
  return s.outstanding + s.staging_in_use < staging_slots_;
}

bool StoredProducer::request(const PageRequest& r) {
  if (!loader_->request(r.page, r.slot)) return false;
  ++stats_.requested;
  return true;
}

void StoredProducer::cancel(const PageId& page) { loader_->cancel(page); }

void StoredProducer::poll(std::vector<PageRequest>& ready, std::vector<PageRequest>& failed,
                          std::vector<PageRequest>& cancelled) {
  polled_.clear();
  loader_->poll(polled_);
  for (const LoadedPage& l : polled_) {
    const PageRequest r{l.page, uint32_t(l.tag)};
    switch (l.status) {
      case LoadStatus::ok:
        to_copy_.push_back(Copy{r, l.staging});
        ready.push_back(r);
        stats_.read_ms += l.read_ms;
        stats_.decode_ms += l.decode_ms;
        break;
      case LoadStatus::failed:
        bad_.insert(l.page.pack());
        failed.push_back(r);
        ++stats_.failed;
        break;
      case LoadStatus::cancelled:
        cancelled.push_back(r);
        ++stats_.cancelled;
        break;
    }
  }
}

void StoredProducer::record(VkCommandBuffer cmd, const vk::Image& cache) {
  if (!to_copy_.empty()) {
    std::vector<VkBufferImageCopy> regions;
    regions.reserve(to_copy_.size());
    for (const Copy& c : to_copy_) {
      VkBufferImageCopy region{};
      region.bufferOffset = loader_->staging_offset(c.staging);
      region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, c.request.slot, 1};
      region.imageExtent = {slot_texels_, slot_texels_, 1};
      regions.push_back(region);
      to_release_[frames_ % to_release_.size()].push_back(c.staging);
    }
    // The cache lives in GENERAL (the composer writes it as a storage image); the copy gets the
    // transfer layout, and the barriers order it after this frame's compute writes and before
    // every later read.
    context_->transition(cmd, cache, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
    context_->fn().vkCmdCopyBufferToImage(cmd, staging_.handle(), cache.handle(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                           uint32_t(regions.size()), regions.data());
    context_->transition(cmd, cache, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
    stats_.landed += uint32_t(to_copy_.size());
    to_copy_.clear();
  }
  const PageLoaderStats s = loader_->stats();
  stats_.outstanding = s.outstanding;
  stats_.staging_in_use = s.staging_in_use;
}

void StoredProducer::begin_frame() {
  stats_ = StoredFrameStats{};
  // The frame that used this part of the ring, frames_in_flight frames ago, has completed: its
  // copies have read their staging.
  std::vector<uint32_t>& done = to_release_[frames_ % to_release_.size()];
  for (uint32_t s : done) loader_->release(s);
  done.clear();
}

void StoredProducer::end_frame() { ++frames_; }

}  // namespace tvt
