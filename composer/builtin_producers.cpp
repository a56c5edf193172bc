#include "composer/builtin_producers.h"

#include <algorithm>

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

namespace {

void append(std::vector<PageRequest>& to, const std::vector<PageRequest>& from) {
  to.insert(to.end(), from.begin(), from.end());
}

// Every page composed by the GPU composer into the cache, in the frame it was requested.
class ComposedPages final : public PageProducer {
 public:
  ComposedPages(std::unique_ptr<GpuComposer> composer, uint32_t budget)
      : composer_(std::move(composer)), budget_(budget) {}

  uint32_t requests_per_frame() const override { return budget_; }
  void begin_frame(uint64_t) override { accepted_ = 0; }
  ProducerAccept request(const PageRequest& r) override {
    if (accepted_ >= budget_ || !add(r)) return ProducerAccept::busy;
    ++accepted_;
    return ProducerAccept::accepted;
  }
  // A page outside the frame's budget (hybrid: instead of a stored page that failed); false
  // when the composer's batch is full.
  bool add(const PageRequest& r) {
    if (jobs_.size() >= composer_->slots()) return false;
    jobs_.push_back(PageJob{r.page, r.slot});
    return true;
  }
  void cancel(const PageId& page) override {
    const auto it = std::find_if(jobs_.begin(), jobs_.end(), [&](const PageJob& j) { return j.page == page; });
    if (it == jobs_.end()) return;
    cancelled_.push_back(PageRequest{it->page, it->slot});
    jobs_.erase(it);
  }
  Status record(VkCommandBuffer cmd, ProducerOutcome& out) override {
    append(out.cancelled, cancelled_);
    cancelled_.clear();
    // Also with no jobs: the composer's per-record counters restart.
    Status s = composer_->record(cmd, jobs_);
    composed_ = failed_ = 0;
    for (const PageJob& j : jobs_) (s ? out.written : out.failed).push_back(PageRequest{j.page, j.slot});
    (s ? composed_ : failed_) = uint32_t(jobs_.size());
    jobs_.clear();
    return s;
  }
  void add_stats(VtFrameStats& s) const override {
    s.composed += composed_;
    s.compose_failed += failed_;
    s.materials = composer_->upload_stats();
  }

 private:
  std::unique_ptr<GpuComposer> composer_;
  uint32_t budget_ = 0, accepted_ = 0, composed_ = 0, failed_ = 0;
  std::vector<PageJob> jobs_;
  std::vector<PageRequest> cancelled_;
};

// Stored where the store has the page, composed elsewhere and where a stored page failed.
class HybridPages final : public PageProducer {
 public:
  HybridPages(std::unique_ptr<StoredPages> stored, std::unique_ptr<ComposedPages> composed, uint32_t per_frame)
      : stored_(std::move(stored)), composed_(std::move(composed)), per_frame_(per_frame) {}

  uint32_t requests_per_frame() const override { return per_frame_; }
  void begin_frame(uint64_t frame) override {
    stored_->begin_frame(frame);
    composed_->begin_frame(frame);
    fallback_ = 0;
  }
  ProducerAccept request(const PageRequest& r) override {
    return stored_->has(r.page) ? stored_->request(r) : composed_->request(r);
  }
  void cancel(const PageId& page) override {
    stored_->cancel(page);
    composed_->cancel(page);
  }
  void finish() override { stored_->finish(); }
  Status record(VkCommandBuffer cmd, ProducerOutcome& out) override {
    loads_.clear();
    stored_->collect(loads_);
    append(out.written, loads_.written);
    append(out.cancelled, loads_.cancelled);
    // A page that failed to load is composed into the slot it was meant for.
    for (const PageRequest& r : loads_.failed) {
      if (composed_->add(r)) ++fallback_;
      else out.failed.push_back(r);
    }
    Status s = composed_->record(cmd, out);
    stored_->copy(cmd);
    return s;
  }
  void end_frame() override { stored_->end_frame(); }
  void add_stats(VtFrameStats& s) const override {
    stored_->add_stats(s);
    composed_->add_stats(s);
    s.fallback_composed += fallback_;
  }
  std::vector<std::string> take_error_messages() override { return stored_->take_error_messages(); }
  uint64_t gpu_bytes() const override { return stored_->gpu_bytes(); }

 private:
  std::unique_ptr<StoredPages> stored_;
  std::unique_ptr<ComposedPages> composed_;
  uint32_t per_frame_;
  uint32_t fallback_ = 0;
  ProducerOutcome loads_;
};

}  // namespace

Result<std::unique_ptr<PageProducer>> make_builtin_producer(vk::Context& context, const PackedScene& scene,
                                                            vk::Image& cache, const BuiltinProducerOptions& options) {
  const bool streams = options.source != VtSource::procedural;
  const bool composes = options.source != VtSource::stored;
  std::unique_ptr<ComposedPages> composed;
  if (composes) {
    GpuComposerOptions co;
    co.records_in_flight = options.frames_in_flight;
    co.target = &cache;
    auto composer = GpuComposer::create(context, scene, cache.layers(), co);
    if (!composer) return composer.error();
    composed = std::make_unique<ComposedPages>(std::move(composer.value()), options.page_budget);
  }
  if (!streams) return std::unique_ptr<PageProducer>(std::move(composed));

  if (!options.store) return make_error("source: '" + std::string(to_string(options.source)) + "' needs a page store");
  StoredPagesOptions so;
  so.page_budget = options.page_budget;
  so.frames_in_flight = options.frames_in_flight;
  so.loader = options.loader;
  so.sync_loads = options.sync_loads;
  so.scene_hash = options.scene_hash;
  auto stored = StoredPages::create(context, options.store, cache, scene_vt_config(scene), so);
  if (!stored) return stored.error();
  if (!composes) return std::unique_ptr<PageProducer>(std::move(stored.value()));
  const uint32_t per_frame = stored.value()->requests_per_frame();
  return std::unique_ptr<PageProducer>(
      std::make_unique<HybridPages>(std::move(stored.value()), std::move(composed), per_frame));
}

VtConfig scene_vt_config(const PackedScene& scene) {
  return VtConfig{uint32_t(scene.params.log2_vt), uint32_t(scene.params.page_texels), uint32_t(scene.params.border_texels)};
}

VtSystemOptions with_builtin_producer(const PackedScene& scene, const SceneVtOptions& options) {
  VtSystemOptions o = options;
  if (o.producer) return o;
  BuiltinProducerOptions bo;
  bo.source = options.source;
  bo.page_budget = options.page_budget;
  bo.frames_in_flight = options.frames_in_flight;
  bo.store = options.store;
  bo.loader = options.loader;
  bo.sync_loads = options.sync_loads;
  bo.scene_hash = options.scene_hash;
  // A copy: the factory may outlive the caller's scene (PackedScene copies share their caches).
  o.make_producer = [scene = std::make_shared<const PackedScene>(scene), bo](vk::Context& context, vk::Image& cache)
      -> Result<std::shared_ptr<PageProducer>> {
    auto made = make_builtin_producer(context, *scene, cache, bo);
    if (!made) return made.error();
    return std::shared_ptr<PageProducer>(std::move(made.value()));
  };
  return o;
}

Result<std::unique_ptr<VtSystem>> create_vt_system(vk::Context& context, const PackedScene& scene,
                                                   const SceneVtOptions& options) {
  return VtSystem::create(context, scene_vt_config(scene), with_builtin_producer(scene, options));
}

}  // namespace tvt
