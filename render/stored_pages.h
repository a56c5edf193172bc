// The stored megatexture as the VT runtime's page producer (render/page_producer.h): pages of a
// baked store, loaded on the loader's threads (render/stored_producer.h) and copied into their
// cache slots when ready. A page the store lacks is unavailable and a page that fails
// verification fails: either way the page's nearest resident ancestor stands in. The hybrid
// source (composer/builtin_producers.h) drives the same object beside the composer.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "gpu/context.h"
#include "render/page_producer.h"
#include "render/stored_producer.h"
#include "vt/vt_config.h"

namespace tvt {

struct StoredPagesOptions {
  uint32_t page_budget = 32;       // pages a frame asks for when loads are synchronous
  uint32_t frames_in_flight = 2;
  StoredProducerOptions loader;    // threads, staging ring
  bool sync_loads = false;         // requests_per_frame() as a procedural run's (frame-exact comparisons)
  uint64_t scene_hash = 0;         // checked against the store's (0: unchecked)
};

// What StoredPages::requests_per_frame() is with these options: loads may be outstanding on top
// of a frame's budget, except in a synchronous run, which asks for exactly what a procedural run
// would so that their frames match one for one.
uint32_t stored_requests_per_frame(const StoredPagesOptions& options);

class StoredPages final : public PageProducer {
 public:
  // `cache`: the VT's cache image, owned by the caller and outliving the producer. `vt`: the
  // geometry the store must have.
  static Result<std::unique_ptr<StoredPages>> create(vk::Context& context, std::shared_ptr<const PageStoreReader> store,
                                                     vk::Image& cache, const VtConfig& vt, const StoredPagesOptions& options);

  uint32_t requests_per_frame() const override { return per_frame_; }
  void begin_frame(uint64_t) override { loader_->begin_frame(); }
  bool has(const PageId& page) const { return loader_->has(page); }
  ProducerAccept request(const PageRequest& r) override;
  void cancel(const PageId& page) override { loader_->cancel(page); }
  void finish() override { loader_->wait_idle(); }
  // The loads finished since the last call; the ready ones are copied by copy().
  void collect(ProducerOutcome& out) { loader_->poll(out.written, out.failed, out.cancelled); }
  void copy(VkCommandBuffer cmd) { loader_->record(cmd, *cache_); }
  Status record(VkCommandBuffer cmd, ProducerOutcome& out) override {
    collect(out);
    copy(cmd);
    return Ok{};
  }
  void end_frame() override { loader_->end_frame(); }
  void add_stats(VtFrameStats& s) const override { s.stored = loader_->stats(); }
  std::vector<std::string> take_error_messages() override { return loader_->take_error_messages(); }
  uint64_t gpu_bytes() const override { return loader_->gpu_bytes(); }

 private:
  StoredPages(std::unique_ptr<StoredProducer> loader, vk::Image& cache, uint32_t per_frame)
      : loader_(std::move(loader)), cache_(&cache), per_frame_(per_frame) {}
  std::unique_ptr<StoredProducer> loader_;
  vk::Image* cache_;
  uint32_t per_frame_;
};

}  // namespace tvt
