// terravt::compose::create_virtual_texture (include/terravt/compose.h): a VirtualTexture from a
// scene. The composer and its hybrid with stored pages (composer/builtin_producers.h) are
// plugged into libterravt's VirtualTexture as a client's producer is (terravt/page_producer.h),
// through the public API alone: libterravt_compose depends on libterravt, never the reverse.
#include "terravt/compose.h"

#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "api/compose/scene_vt.h"
#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "compose/scene_assets.h"
#include "composer/builtin_producers.h"
#include "gpu/context.h"
#include "terravt/page_producer.h"

namespace terravt::compose {

namespace {

Error invalid(std::string message) { return Error{ErrorKind::invalid_argument, std::move(message)}; }

using detail::as_error;

PageTask task_of(const tvt::PageRequest& r) { return PageTask{r.page.mip, r.page.x, r.page.y, r.slot}; }

// terravt's built-in producers over a scene as a public page producer. It records on its own
// adopted context (the client's device, a function table of its own), whose set-up (scene
// buffers, pipelines' first uploads) goes into the first command buffer it records into.
class ScenePages final : public PageProducer {
 public:
  ScenePages(std::unique_ptr<tvt::vk::Context> context, tvt::PackedScene scene, tvt::BuiltinProducerOptions options)
      : context_(std::move(context)), scene_(std::move(scene)), options_(std::move(options)) {}
  ~ScenePages() override {
    inner_.reset();  // before the context its resources belong to
  }

  // As the built-in producer it wraps: the hybrid keeps loads in flight on top of the budget.
  uint32_t requests_per_frame() const override {
    if (options_.source == tvt::VtSource::procedural) return options_.page_budget;
    tvt::StoredPagesOptions so;
    so.page_budget = options_.page_budget;
    so.loader = options_.loader;
    so.sync_loads = options_.sync_loads;
    return tvt::stored_requests_per_frame(so);
  }
  Status attach(const ProducerTarget& t) override {
    if (inner_) return Error{ErrorKind::misuse, "the scene's page producer is attached to one VirtualTexture only"};
    cache_ = tvt::vk::Context::borrow_image(t.cache, t.cache_view, t.format, t.slot_texels, t.slot_texels, t.slots);
    options_.frames_in_flight = t.frames_in_flight;
    frames_in_flight_ = t.frames_in_flight;
    auto made = tvt::make_builtin_producer(*context_, scene_, cache_, options_);
    if (!made) return as_error(made.error(), ErrorKind::invalid_argument);
    inner_ = std::move(made.value());
    return context_->status();
  }
  void begin_frame(uint64_t frame) override {
    ++begun_;
    // The frame that recorded the set-up has completed (frames_in_flight begin_frame() calls
    // later; frame numbers may skip): its staging may go.
    if (setup_begun_ && begun_ >= *setup_begun_ + frames_in_flight_) {
      context_->release_deferred_staging();
      setup_begun_.reset();
    }
    inner_->begin_frame(frame);
  }
  ProducerAccept request(const PageTask& t) override {
    const tvt::PageId page{t.mip, t.x, t.y};
    switch (inner_->request(tvt::PageRequest{page, t.slot})) {
      case tvt::ProducerAccept::accepted: owned_[page.pack()] = t.slot; return ProducerAccept::accepted;
      case tvt::ProducerAccept::unavailable: return ProducerAccept::unavailable;
      case tvt::ProducerAccept::busy: break;
    }
    return ProducerAccept::busy;
  }
  void cancel(const PageTask& t) override {
    const tvt::PageId page{t.mip, t.x, t.y};
    owned_.erase(page.pack());
    inner_->cancel(page);
  }
  void finish() override { inner_->finish(); }
  Status record(VkCommandBuffer cmd, std::vector<PageTask>& written, std::vector<PageTask>& failed) override {
    if (auto st = context_->status(); !st) return st;
    if (context_->has_deferred_setup()) {
      context_->record_deferred_setup(cmd);
      setup_begun_ = begun_;
    }
    outcome_.clear();
    const tvt::Status s = inner_->record(cmd, outcome_);
    inner_->end_frame();
    // Only pages terravt handed over and still wants are reported, each once. The inner
    // producers report a cancelled page as cancelled (the loader turns a load that failed
    // before the cancel into one too), and terravt knows those already.
    const auto report = [&](const std::vector<tvt::PageRequest>& from, std::vector<PageTask>& to) {
      for (const tvt::PageRequest& r : from) {
        const auto it = owned_.find(r.page.pack());
        if (it == owned_.end() || it->second != r.slot) continue;
        owned_.erase(it);
        to.push_back(task_of(r));
      }
    };
    report(outcome_.written, written);
    report(outcome_.failed, failed);
    for (const std::string& m : inner_->take_error_messages()) context_->log(LogLevel::warning, m);
    if (auto st = context_->status(); !st) return st;
    if (!s) return as_error(s.error(), ErrorKind::producer_failed, false);
    return Ok{};
  }

 private:
  std::unique_ptr<tvt::vk::Context> context_;
  tvt::PackedScene scene_;
  tvt::BuiltinProducerOptions options_;
  tvt::vk::Image cache_;  // borrowed: the VirtualTexture's
  std::unique_ptr<tvt::PageProducer> inner_;
  tvt::ProducerOutcome outcome_;
  std::unordered_map<uint64_t, uint32_t> owned_;  // accepted, not yet reported or cancelled: PageId::pack() -> slot
  uint64_t begun_ = 0;                            // begin_frame() calls
  uint32_t frames_in_flight_ = 1;
  std::optional<uint64_t> setup_begun_;           // the call whose frame recorded the set-up
};

}  // namespace

Result<std::unique_ptr<VirtualTexture>> create_virtual_texture(const DeviceHandles& device,
                                                               const VirtualTextureDesc& desc) {
  if (auto st = detail::check_scene_fields(desc); !st) return st.error();
  if (desc.source != PageSource::composed && desc.source != PageSource::stored && desc.source != PageSource::hybrid)
    return invalid("VirtualTextureDesc::source: not a PageSource value");
  if (desc.source != PageSource::composed && desc.store_file.empty() && !desc.producer)
    return invalid("VirtualTextureDesc::store_file: a stored or hybrid source needs a store");
  if (desc.consumer_stages == 0) return invalid("VirtualTextureDesc::consumer_stages: name at least one stage");
  // Then the device, before the scene is read.
  if (auto st = check_device(device); !st) return st.error();

  auto loaded = detail::load_desc_scene(desc);
  if (!loaded) return loaded.error();
  const tvt::SceneAssets* assets = &loaded->assets;
  const tvt::Method* method = &loaded->method;
  const tvt::MipStrategy* strategy = &loaded->strategy;
  const tvt::VtConfig& vt = assets->desc.vt;
  const VirtualTextureLayout& l = desc.layout;
  if (l.log2_size != 0 && (l.log2_size != vt.log2_size || l.page_texels != vt.page_texels ||
                           l.border_texels != vt.border_texels))
    return invalid("VirtualTextureDesc::layout: (log2_size " + std::to_string(l.log2_size) + ", page_texels " +
                   std::to_string(l.page_texels) + ", border_texels " + std::to_string(l.border_texels) +
                   ") differs from the scene's (" + std::to_string(vt.log2_size) + ", " +
                   std::to_string(vt.page_texels) + ", " + std::to_string(vt.border_texels) + ")");

  // What libterravt's VirtualTexture::create() is handed: no scene, the scene's geometry.
  VirtualTextureDesc core = desc;
  core.scene_file.clear();
  core.layout = VirtualTextureLayout{vt.log2_size, vt.page_texels, vt.border_texels};
  if (desc.producer) return VirtualTexture::create(device, core);

  std::shared_ptr<const tvt::PageStoreReader> store;
  if (desc.source != PageSource::composed) {
    auto opened = detail::open_scene_store(desc.store_file, *assets, *method, *strategy);
    if (!opened) return opened.error();
    store = std::move(opened.value());
  }
  if (desc.source == PageSource::stored) return VirtualTexture::create(device, core);  // checked: reads it alone

  auto packed = tvt::pack_scene(*assets, tvt::options_for(*method, *strategy));
  if (!packed) return invalid(packed.error().message);
  auto context = tvt::vk::Context::adopt(device);
  if (!context) return context.error();
  context.value()->defer_setup();  // nothing submitted on the client's queue
  tvt::BuiltinProducerOptions bo;
  bo.source = desc.source == PageSource::hybrid ? tvt::VtSource::hybrid : tvt::VtSource::procedural;
  bo.page_budget = desc.page_budget;
  bo.store = std::move(store);
  core.producer = std::make_shared<ScenePages>(std::move(context.value()), std::move(packed.value()), bo);
  return VirtualTexture::create(device, core);
}

}  // namespace terravt::compose
