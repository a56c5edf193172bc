// terravt::VirtualTexture: the public face of the VT runtime (render/vt_system.h) on an adopted
// device, with the frame protocol checked (see include/terravt/virtual_texture.h).
#include "terravt/virtual_texture.h"

#include <algorithm>
#include <deque>
#include <string>
#include <utility>
#include <vector>

#include "api/client_producer.h"
#include "api/tool_access.h"
#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "compose/scene_assets.h"
#include "compose/scene_identity.h"
#include "gpu/context.h"
#include "render/feedback_compactor.h"
#include "render/vt_system.h"
#include "streaming/page_store.h"

namespace terravt {

namespace {

Error misuse(std::string message) { return Error{ErrorKind::misuse, std::move(message)}; }
Error invalid(std::string message) { return Error{ErrorKind::invalid_argument, std::move(message)}; }
// An internal error under the public API: a failed Vulkan call keeps its kind and VkResult;
// anything else is the caller's input (invalid_argument).
// Marks the VirtualTexture busy for one call; a call made from inside it (a page producer's
// callback calling back into the VirtualTexture) is misuse.
class BusyGuard {
 public:
  explicit BusyGuard(bool& busy) : busy_(busy), entered_(!busy) { busy_ = true; }
  ~BusyGuard() {
    if (entered_) busy_ = false;
  }
  BusyGuard(const BusyGuard&) = delete;
  BusyGuard& operator=(const BusyGuard&) = delete;
  bool reentered() const { return !entered_; }

 private:
  bool& busy_;
  bool entered_;
};

Error reentered(const char* call) {
  return misuse(std::string(call) + ": called from inside another VirtualTexture call (a page producer's callback "
                                    "may not call back into the VirtualTexture)");
}

Error as_input_error(const Error& e, const std::string& prefix = "") {
  if (e.vk_result != 0) return Error{e.kind, prefix + e.message, e.vk_result};
  return invalid(prefix + e.message);
}

std::optional<tvt::VtSource> internal_source(PageSource s) {
  switch (s) {
    case PageSource::composed: return tvt::VtSource::procedural;
    case PageSource::stored: return tvt::VtSource::stored;
    case PageSource::hybrid: return tvt::VtSource::hybrid;
  }
  return std::nullopt;
}

}  // namespace

struct VirtualTexture::Impl {
  VirtualTextureDesc desc;
  std::unique_ptr<tvt::vk::Context> context;  // declared first: destroyed last
  tvt::SceneAssets owned_assets;              // create(): the scene it loaded
  const tvt::SceneAssets* assets = nullptr;   // &owned_assets, or a tool's (api/tool_access.h)
  std::unique_ptr<tvt::VtSystem> vt;
  std::vector<tvt::PageFeedback> feedback;
  std::optional<uint64_t> last_begun, last_completed;
  std::deque<uint64_t> in_flight;  // frames begun and not known complete, oldest first
  bool recorded = true;  // record() followed the last begin_frame()
  FrameStats stats;
  VkMemoryBarrier2 before{}, after{};  // what dependencies() points at
  std::unique_ptr<tvt::FeedbackCompactor> compactor;  // desc.feedback_texels > 0
  // (frame, compaction number) of compactions not yet read. The compactor's ring is indexed by
  // compaction number, consecutive even when frame numbers skip.
  std::deque<std::pair<uint64_t, uint64_t>> compacted;
  uint64_t compactions = 0;
  std::vector<tvt::PageFeedback> gpu_feedback;  // the newest compaction read, and its frame
  std::optional<uint64_t> gpu_feedback_frame;
  bool feedback_recorded = false;      // record_feedback() ran for the last frame begun
  bool busy = false;  // inside a call: a producer's callback calling back in is refused
  std::optional<uint64_t> setup_frame;  // the frame that recorded the set-up; its staging lives until it completed
  // The set-up create() deferred goes first into whichever command buffer comes first.
  void record_setup(VkCommandBuffer cmd) {
    if (!context->has_deferred_setup()) return;
    context->record_deferred_setup(cmd);
    setup_frame = last_begun;
  }
  VirtualTextureDependencies dependencies;
};

VirtualTexture::VirtualTexture(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
VirtualTexture::~VirtualTexture() = default;

namespace detail {

tvt::VtSystem& Access::runtime(VirtualTexture& vt) { return *vt.impl_->vt; }
uint32_t Access::feedback_texels(const VirtualTexture& vt) { return vt.impl_->desc.feedback_texels; }

// The one path from a device and a scene to a VirtualTexture: create() (a scene file and
// VirtualTextureDesc) and create_virtual_texture() (terravt's tools) both end here.
// impl->desc and impl->assets are set; `o` holds the runtime's options.
Result<std::unique_ptr<VirtualTexture>> Access::make(const DeviceHandles& device, std::unique_ptr<VirtualTexture::Impl> impl,
                                                     tvt::Method method, tvt::MipStrategy strategy, tvt::VtSystemOptions o) {
  const VirtualTextureDesc& desc = impl->desc;
  // The legacy stage bits have the same values as their VK_PIPELINE_STAGE_2_* counterparts.
  const VkPipelineStageFlags2 consumers = desc.consumer_stages;
  const VkPipelineStageFlags2 producers = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_TRANSFER_BIT;
  impl->before.sType = impl->after.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER_2;
  impl->before.srcStageMask = consumers;  // write-after-read: an execution dependency
  impl->before.dstStageMask = producers;
  impl->after.srcStageMask = producers;
  impl->after.srcAccessMask = VK_ACCESS_2_SHADER_WRITE_BIT | VK_ACCESS_2_TRANSFER_WRITE_BIT;
  impl->after.dstStageMask = consumers;
  impl->after.dstAccessMask = VK_ACCESS_2_SHADER_READ_BIT;
  for (auto [info, barrier] : {std::pair{&impl->dependencies.before, &impl->before},
                               std::pair{&impl->dependencies.after, &impl->after}}) {
    info->sType = VK_STRUCTURE_TYPE_DEPENDENCY_INFO;
    info->memoryBarrierCount = 1;
    info->pMemoryBarriers = barrier;
  }
  auto context = tvt::vk::Context::adopt(device);
  if (!context) return context.error();  // check_device()'s kind: invalid_argument or unsupported_device
  impl->context = std::move(context.value());
  // Nothing is submitted on the client's queue: set-up is recorded by the first record().
  impl->context->defer_setup();

  auto packed = tvt::pack_scene(*impl->assets, tvt::options_for(method, strategy));
  if (!packed) return invalid(packed.error().message);
  if (o.store && o.scene_hash == 0)
    o.scene_hash = tvt::store_scene_identity(impl->assets->desc, method, strategy, o.store->desc().pyramid);
  o.frames_in_flight = desc.frames_in_flight;
  auto vt = tvt::VtSystem::create(*impl->context, packed.value(), o);
  if (!vt) return as_input_error(vt.error());
  impl->vt = std::move(vt.value());
  if (desc.feedback_texels > 0) {
    tvt::FeedbackCompactor::Options fo;
    fo.feedback_width = desc.feedback_texels;
    fo.feedback_height = 1;
    // Compaction c's slot is next written by compaction c + ring_size: the frame that records
    // it was begun with at most frames_in_flight - 1 others open, so c's frame had completed
    // and its begin_frame() read c.
    fo.ring_size = desc.frames_in_flight + 1;
    auto compactor = tvt::FeedbackCompactor::create(*impl->context, fo);
    if (!compactor) return as_input_error(compactor.error(), "VirtualTextureDesc::feedback_texels: ");
    impl->compactor = std::move(compactor.value());
  }
  if (desc.producer) {
    const tvt::VtConfig& c = impl->assets->desc.vt;
    const tvt::vk::Image& cache = impl->vt->cache();
    ProducerTarget t;
    t.cache = cache.handle();
    t.cache_view = cache.view();
    t.format = cache.format();
    t.slots = cache.layers();
    t.slot_texels = c.slot_texels();
    t.page_texels = c.page_texels;
    t.border_texels = c.border_texels;
    t.log2_size = c.log2_size;
    t.mip_count = c.mip_count();
    t.frames_in_flight = desc.frames_in_flight;
    if (auto attached = desc.producer->attach(t); !attached)
      return Error{attached.error().kind, "VirtualTextureDesc::producer: attach(): " + attached.error().message};
  }
  return std::unique_ptr<VirtualTexture>(new VirtualTexture(std::move(impl)));
}

Result<std::unique_ptr<VirtualTexture>> create_virtual_texture(const DeviceHandles& device, const ToolVirtualTexture& td) {
  return Access::make_for_tool(device, td);
}

Result<std::unique_ptr<VirtualTexture>> Access::make_for_tool(const DeviceHandles& device, const ToolVirtualTexture& td) {
  if (!td.assets) return invalid("create_virtual_texture(): no scene assets");
  if (td.consumer_stages == 0) return invalid("create_virtual_texture(): consumer_stages: name at least one stage");
  auto impl = std::make_unique<VirtualTexture::Impl>();
  VirtualTextureDesc& d = impl->desc;  // the public subset, as the runtime options set it
  d.cache_slots = td.runtime.cache_slots;
  d.page_budget = td.runtime.page_budget;
  d.window_pages = td.runtime.window_pages;
  d.frames_in_flight = td.runtime.frames_in_flight;
  d.feedback_texels = td.feedback_texels;
  d.consumer_stages = td.consumer_stages;
  impl->assets = td.assets;
  return make(device, std::move(impl), td.method, td.mip_strategy, td.runtime);
}

}  // namespace detail

Result<std::unique_ptr<VirtualTexture>> VirtualTexture::create(const DeviceHandles& device,
                                                               const VirtualTextureDesc& desc) {
  const auto source = internal_source(desc.source);
  if (!source) return invalid("VirtualTextureDesc::source: not a PageSource value");
  const auto method = tvt::method_from_string(desc.method);
  if (!method) return invalid("VirtualTextureDesc::method: unknown method '" + desc.method + "'");
  const auto strategy = tvt::mip_strategy_from_string(desc.mip_strategy);
  if (!strategy) return invalid("VirtualTextureDesc::mip_strategy: " + strategy.error().message);
  if (desc.source != PageSource::composed && desc.store_file.empty() && !desc.producer)
    return invalid("VirtualTextureDesc::store_file: a stored or hybrid source needs a store");
  if (desc.consumer_stages == 0) return invalid("VirtualTextureDesc::consumer_stages: name at least one stage");
  // The device first: a device terravt cannot run on is the first thing to hear about.
  if (auto st = check_device(device); !st) return st.error();

  auto impl = std::make_unique<Impl>();
  impl->desc = desc;
  auto scene = desc.scene_file.empty() ? tvt::Result<tvt::SceneDesc>(tvt::default_scene())
                                       : tvt::load_scene_file(desc.scene_file);
  if (!scene) return invalid(scene.error().message);
  auto assets = tvt::load_scene_assets(scene.value());
  if (!assets)  // running out of memory stays out_of_memory; anything else is the input's fault
    return assets.error().kind == ErrorKind::out_of_memory ? assets.error() : invalid(assets.error().message);
  impl->owned_assets = std::move(assets.value());
  impl->assets = &impl->owned_assets;

  tvt::VtSystemOptions o;
  o.cache_slots = desc.cache_slots;
  o.page_budget = desc.page_budget;
  o.window_pages = desc.window_pages;
  o.source = *source;
  if (desc.producer) {
    o.producer = std::make_shared<detail::ClientProducer>(desc.producer, desc.page_budget);
  } else if (desc.source != PageSource::composed) {
    auto store = tvt::PageStoreReader::open(desc.store_file);
    if (!store) return Error{ErrorKind::io, store.error().message};
    o.store = std::move(store.value());
  }
  return detail::Access::make(device, std::move(impl), *method, strategy.value(), std::move(o));
}

VirtualTextureInfo VirtualTexture::info() const {
  const tvt::VtConfig& c = impl_->assets->desc.vt;
  return VirtualTextureInfo{c.log2_size, c.page_texels, c.border_texels, c.mip_count(), impl_->desc.cache_slots};
}

VirtualTextureBindings VirtualTexture::bindings() const {
  const tvt::VtSystem& v = *impl_->vt;
  VirtualTextureBindings b;
  b.info_buffer = v.info_buffer().handle();
  b.info_bytes = v.info_buffer().size();
  b.table_buffer = v.entry_buffer().handle();
  b.table_bytes = v.entry_buffer().size();
  b.cache_view = v.cache().view();
  b.cache_sampler = v.sampler();
  b.cache_layout = VK_IMAGE_LAYOUT_GENERAL;
  return b;
}

Status VirtualTexture::begin_frame(uint64_t frame, std::optional<uint64_t> completed, int64_t camera_texel_x,
                                   int64_t camera_texel_y, std::span<const PageRequest> requests) {
  Impl& m = *impl_;
  const BusyGuard guard(m.busy);
  if (guard.reentered()) return reentered("begin_frame()");
  // A failed Vulkan call (out of memory, device lost) stays: every call returns it.
  if (auto st = m.context->status(); !st) return st;
  const std::string f = std::to_string(frame);
  if (!m.recorded)
    return misuse("begin_frame(" + f + "): record() did not follow begin_frame(" + std::to_string(*m.last_begun) + ")");
  if (m.last_begun && frame <= *m.last_begun)
    return misuse("begin_frame(" + f + "): frames must increase; frame " + std::to_string(*m.last_begun) +
                  " was begun already");
  if (completed) {
    if (m.last_completed && *completed < *m.last_completed)
      return misuse("begin_frame(" + f + "): the completed frame went backwards (" + std::to_string(*completed) +
                    " after " + std::to_string(*m.last_completed) + ")");
    if (!m.last_begun || *completed > *m.last_begun)
      return misuse("begin_frame(" + f + "): completed frame " + std::to_string(*completed) + " was never begun");
  }
  const std::optional<uint64_t> done = completed ? completed : m.last_completed;
  // Frames begun and not known complete when this one begins.
  size_t open = m.in_flight.size();
  if (done) open = size_t(std::count_if(m.in_flight.begin(), m.in_flight.end(), [&](uint64_t b) { return b > *done; }));
  if (open + 1 > m.desc.frames_in_flight)
    return misuse("begin_frame(" + f + "): " + std::to_string(open) + " earlier frame(s) not completed, and at most " +
                  std::to_string(m.desc.frames_in_flight) + " may be in flight (VirtualTextureDesc::frames_in_flight)");

  const tvt::VtConfig& c = m.assets->desc.vt;
  m.feedback.clear();
  for (size_t i = 0; i < requests.size(); ++i) {
    const PageRequest& r = requests[i];
    if (r.mip >= c.mip_count() || r.x >= c.pages_per_side(r.mip) || r.y >= c.pages_per_side(r.mip))
      return invalid("begin_frame(" + f + "): requests[" + std::to_string(i) + "] (mip " + std::to_string(r.mip) +
                     ", page " + std::to_string(r.x) + ", " + std::to_string(r.y) + ") is not a page of this VT (" +
                     std::to_string(c.mip_count()) + " mips; mip 0 has " + std::to_string(c.pages_per_side(0)) +
                     " pages per side)");
    m.feedback.push_back(tvt::PageFeedback{tvt::PageId{r.mip, r.x, r.y}, std::max(r.weight, 1u)});
  }
  const auto clamp_texel = [&](int64_t v) {
    return uint32_t(std::clamp<int64_t>(v, 0, int64_t(c.size_texels() - 1)));
  };
  // The newest completed frame's GPU feedback joins the requests; older ones are stale. With
  // no newer one completed, the newest read stands (the view has not told us otherwise).
  while (done && !m.compacted.empty() && m.compacted.front().first <= *done) {
    if (auto gpu = m.compactor->try_read(m.compacted.front().second, true)) {
      m.gpu_feedback.clear();
      for (const auto& [page, count] : gpu->pages) m.gpu_feedback.push_back(tvt::PageFeedback{page, count});
      m.gpu_feedback_frame = m.compacted.front().first;
    }
    m.compacted.pop_front();
  }
  m.stats.gpu_feedback = m.gpu_feedback_frame.has_value();
  m.stats.feedback_pages = uint32_t(m.gpu_feedback.size());
  m.stats.feedback_frame = m.gpu_feedback_frame.value_or(0);
  m.feedback.insert(m.feedback.end(), m.gpu_feedback.begin(), m.gpu_feedback.end());
  if (m.setup_frame && done && *done >= *m.setup_frame) {
    m.context->release_deferred_staging();
    m.setup_frame.reset();
  }
  m.vt->begin_frame(frame, clamp_texel(camera_texel_x), clamp_texel(camera_texel_y), m.feedback);
  m.feedback_recorded = false;
  if (done) while (!m.in_flight.empty() && m.in_flight.front() <= *done) m.in_flight.pop_front();
  m.in_flight.push_back(frame);
  m.last_begun = frame;
  m.last_completed = done;
  m.recorded = false;
  return Ok{};
}

Status VirtualTexture::record(VkCommandBuffer cmd) {
  Impl& m = *impl_;
  const BusyGuard guard(m.busy);
  if (guard.reentered()) return reentered("record()");
  // A failed Vulkan call (out of memory, device lost) stays: nothing is recorded any more.
  if (auto st = m.context->status(); !st) return st;
  if (m.recorded)
    return misuse(m.last_begun ? "record(): frame " + std::to_string(*m.last_begun) + " was recorded already"
                               : std::string("record(): no frame begun (call begin_frame() first)"));
  if (cmd == VK_NULL_HANDLE) return invalid("record(): cmd is VK_NULL_HANDLE");
  m.record_setup(cmd);
  // Earlier frames' reads by the client's stages end before this frame rewrites what they read.
  if (m.desc.record_barriers)
    m.context->fn().vkCmdPipelineBarrier(cmd, m.desc.consumer_stages, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                         0, 0, nullptr, 0, nullptr, 0, nullptr);
  const tvt::Status s = m.vt->record(cmd);
  m.vt->end_frame();
  m.recorded = true;
  // This frame's writes become visible to the client's stages recorded next.
  if (m.desc.record_barriers)
    m.context->memory_barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                                     VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT, m.desc.consumer_stages,
                                     VK_ACCESS_SHADER_READ_BIT);
  const tvt::VtFrameStats& vs = m.vt->stats();
  m.stats.produced = uint32_t(m.vt->last_completed().size());
  m.stats.failed = vs.produce_failed + vs.missing;
  m.stats.table_updates = vs.table_updates;
  m.stats.resident = vs.residency.resident;
  if (!s) return s.error().kind == ErrorKind::invalid_argument ? Error{ErrorKind::producer_failed, s.error().message}
                                                                : s.error();
  return Ok{};
}

Status VirtualTexture::record_feedback(VkCommandBuffer cmd, VkBuffer feedback, VkDeviceSize offset) {
  Impl& m = *impl_;
  const BusyGuard guard(m.busy);
  if (guard.reentered()) return reentered("record_feedback()");
  if (auto st = m.context->status(); !st) return st;
  if (!m.compactor) return misuse("record_feedback(): VirtualTextureDesc::feedback_texels was 0 at create()");
  if (!m.last_begun) return misuse("record_feedback(): no frame begun (call begin_frame() first)");
  if (m.feedback_recorded)
    return misuse("record_feedback(): frame " + std::to_string(*m.last_begun) + "'s feedback was recorded already");
  if (cmd == VK_NULL_HANDLE || feedback == VK_NULL_HANDLE)
    return invalid(std::string("record_feedback(): ") + (cmd == VK_NULL_HANDLE ? "cmd" : "feedback") +
                   " is VK_NULL_HANDLE");
  // The buffer is bound as a storage buffer from `offset`: Vulkan requires the device's alignment.
  if (const VkDeviceSize align = m.context->properties().limits.minStorageBufferOffsetAlignment;
      align > 0 && offset % align != 0)
    return invalid("record_feedback(): offset " + std::to_string(offset) +
                   " is not a multiple of the device's minStorageBufferOffsetAlignment (" + std::to_string(align) + ")");
  m.record_setup(cmd);
  m.compactor->record_unfenced(cmd, feedback, offset, m.compactions);
  m.compacted.emplace_back(*m.last_begun, m.compactions++);
  m.feedback_recorded = true;
  return m.context->status();
}

const FrameStats& VirtualTexture::stats() const { return impl_->stats; }

const VirtualTextureDependencies& VirtualTexture::dependencies() const { return impl_->dependencies; }

}  // namespace terravt
