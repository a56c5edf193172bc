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
#include "gpu/context.h"
#include "render/feedback_compactor.h"
#include "render/stored_pages.h"
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

// What the compose component (terravt/compose.h) makes, asked of libterravt alone.
Error needs_compose(const std::string& field, const std::string& what) {
  return invalid("VirtualTextureDesc::" + field + ": " + what +
                 " need terravt's compose component: call terravt::compose::create_virtual_texture() "
                 "(terravt/compose.h; CMake target terravt::compose)");
}

}  // namespace

struct VirtualTexture::Impl {
  std::unique_ptr<tvt::vk::Context> context;  // declared first: destroyed last
  VirtualTextureDesc desc;                    // holds the client's producer (shared)
  tvt::VtConfig config;                       // the geometry
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
  // A failed Vulkan call on the device, by terravt's context or reported by the producer (which
  // may record on a context of its own): every later call returns it.
  std::optional<Error> device_error;
  Status device_status() const {
    if (device_error) return *device_error;
    return context->status();
  }
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

// The one path from a device to a VirtualTexture: create() (a store or a client's producer),
// the compose component (terravt/compose.h: its producers are client producers too) and
// terravt's tools (api/compose/tool_vt.h) all end here. `o` holds the runtime's options and the
// producer (or its factory).
Result<std::unique_ptr<VirtualTexture>> Access::make(const DeviceHandles& device, const VirtualTextureDesc& desc,
                                                     const tvt::VtConfig& config, tvt::VtSystemOptions o) {
  if (auto valid = tvt::validate(config, "VirtualTextureDesc::layout"); !valid) return invalid(valid.error().message);
  auto impl = std::make_unique<VirtualTexture::Impl>();
  impl->desc = desc;
  impl->config = config;
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

  o.cache_slots = desc.cache_slots;
  o.page_budget = desc.page_budget;
  o.window_pages = desc.window_pages;
  o.frames_in_flight = desc.frames_in_flight;
  if (desc.producer) o.producer = std::make_shared<detail::ClientProducer>(desc.producer, desc.page_budget, desc.cache_slots);
  auto vt = tvt::VtSystem::create(*impl->context, config, o);
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
    const tvt::VtConfig& c = config;
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
      return Error{attached.error().kind, "VirtualTextureDesc::producer: attach(): " + attached.error().message,
                   attached.error().vk_result};
  }
  return std::unique_ptr<VirtualTexture>(new VirtualTexture(std::move(impl)));
}

}  // namespace detail

Status detail::Access::check_desc(const DeviceHandles& device, const VirtualTextureDesc& desc) {
  if (desc.source != PageSource::composed && desc.source != PageSource::stored && desc.source != PageSource::hybrid)
    return invalid("VirtualTextureDesc::source: not a PageSource value");
  if (desc.source != PageSource::composed && desc.store_file.empty() && !desc.producer)
    return invalid("VirtualTextureDesc::store_file: a stored or hybrid source needs a store");
  if (desc.consumer_stages == 0) return invalid("VirtualTextureDesc::consumer_stages: name at least one stage");
  // Then the device, before any file is read or anything made on it.
  return check_device(device);
}

Result<std::unique_ptr<VirtualTexture>> VirtualTexture::create(const DeviceHandles& device,
                                                               const VirtualTextureDesc& desc) {
  if (auto st = detail::Access::check_desc(device, desc); !st) return st.error();
  if (!desc.scene_file.empty()) return needs_compose("scene_file", "scenes");
  tvt::VtSystemOptions o;
  const VirtualTextureLayout& l = desc.layout;
  if (desc.producer) {
    if (l.log2_size == 0)
      return invalid("VirtualTextureDesc::layout: log2_size is 0; a producer without a scene needs the VT's geometry");
    return detail::Access::make(device, desc, tvt::VtConfig{l.log2_size, l.page_texels, l.border_texels}, std::move(o));
  }
  if (desc.source != PageSource::stored) return needs_compose("source", "composed and hybrid pages");
  auto opened = tvt::PageStoreReader::open(desc.store_file);
  if (!opened) return Error{ErrorKind::io, opened.error().message};
  std::shared_ptr<const tvt::PageStoreReader> store = std::move(opened.value());
  const tvt::VtConfig config = store->desc().vt;
  // Its page format, before anything is made on the device.
  if (auto m = tvt::StoredProducer::matches(*store, config, 0); !m) return invalid(m.error().message);
  if (l.log2_size != 0 && (l.log2_size != config.log2_size || l.page_texels != config.page_texels ||
                           l.border_texels != config.border_texels))
    return invalid("VirtualTextureDesc::layout: (log2_size " + std::to_string(l.log2_size) + ", page_texels " +
                   std::to_string(l.page_texels) + ", border_texels " + std::to_string(l.border_texels) +
                   ") differs from the store's " + desc.store_file + " (" + std::to_string(config.log2_size) + ", " +
                   std::to_string(config.page_texels) + ", " + std::to_string(config.border_texels) + ")");
  tvt::StoredPagesOptions so;
  so.page_budget = desc.page_budget;
  so.frames_in_flight = desc.frames_in_flight;
  o.make_producer = [store, config, so](tvt::vk::Context& context,
                                        tvt::vk::Image& cache) -> tvt::Result<std::shared_ptr<tvt::PageProducer>> {
    auto made = tvt::StoredPages::create(context, store, cache, config, so);
    if (!made) return made.error();
    return std::shared_ptr<tvt::PageProducer>(std::move(made.value()));
  };
  return detail::Access::make(device, desc, config, std::move(o));
}

VirtualTextureInfo VirtualTexture::info() const {
  const tvt::VtConfig& c = impl_->config;
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
  if (auto st = m.device_status(); !st) return st;
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

  const tvt::VtConfig& c = m.config;
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
  if (auto st = m.device_status(); !st) return st;
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
  if (!s) {
    const Error& e = s.error();
    if (e.vk_result != 0 || e.kind == ErrorKind::vulkan || e.kind == ErrorKind::device_lost) {
      if (!m.device_error && m.context->status()) m.device_error = e;  // the producer's device failure stays
      return m.device_status();
    }
    return e.kind == ErrorKind::invalid_argument ? Error{ErrorKind::producer_failed, e.message} : e;
  }
  return Ok{};
}

Status VirtualTexture::record_feedback(VkCommandBuffer cmd, VkBuffer feedback, VkDeviceSize offset) {
  Impl& m = *impl_;
  const BusyGuard guard(m.busy);
  if (guard.reentered()) return reentered("record_feedback()");
  if (auto st = m.device_status(); !st) return st;
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
  return m.device_status();
}

const FrameStats& VirtualTexture::stats() const { return impl_->stats; }

const VirtualTextureDependencies& VirtualTexture::dependencies() const { return impl_->dependencies; }

}  // namespace terravt
