#include "gpu/frame_ring.h"

#include "gpu/command_slots.h"

#include <algorithm>
#include <chrono>
#include <string>

namespace tvt {

namespace {
constexpr uint64_t k_fence_timeout_ns = 60ull * 1000 * 1000 * 1000;  // 60 s, then an error (latched)
constexpr uint32_t k_max_frames_in_flight = 8;
}  // namespace

Result<std::unique_ptr<FrameRing>> FrameRing::create(vk::Context& context, uint32_t frames_in_flight) {
  if (frames_in_flight < 1 || frames_in_flight > k_max_frames_in_flight)
    return make_error("frames_in_flight: must be between 1 and " + std::to_string(k_max_frames_in_flight) + ", got " +
                      std::to_string(frames_in_flight));
  const VkDevice device = context.device();
  std::unique_ptr<FrameRing> r(new FrameRing());
  r->context_ = &context;

  r->pool_ = vk::create_command_pool(context);

  // Timestamps: only when the queue family counts them.
  if (context.timestamp_mask() != 0) {
    r->timestamp_mask_ = context.timestamp_mask();
    r->ns_per_tick_ = double(context.properties().limits.timestampPeriod);
    VkQueryPoolCreateInfo qci{};
    qci.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
    qci.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qci.queryCount = k_queries_per_slot * frames_in_flight;
    if (!TVT_VK_OK(context, context.fn().vkCreateQueryPool(device, &qci, context.allocation_callbacks(), &r->queries_)))
      r->queries_ = VK_NULL_HANDLE;
    r->timestamps_ = context.create_buffer(sizeof(uint64_t) * k_queries_per_slot * frames_in_flight,
                                           VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  }

  r->slots_.resize(frames_in_flight);
  for (Slot& s : r->slots_) {
    const vk::CommandSlot cs = vk::create_command_slot(context, r->pool_);
    s.fence = cs.fence;
    s.cmd = cs.cmd;
  }
  if (auto st = context.status(); !st) return st.error();  // r's destructor frees what was made
  return r;
}

FrameRing::~FrameRing() {
  if (!context_) return;
  // A slot begun and never submitted keeps an unsignalled fence, so wait for the device rather
  // than for the fences.
  context_->wait_idle();
  const VkDevice device = context_->device();
  for (Slot& s : slots_)
    if (s.fence != VK_NULL_HANDLE) context_->fn().vkDestroyFence(device, s.fence, context_->allocation_callbacks());
  if (queries_ != VK_NULL_HANDLE) context_->fn().vkDestroyQueryPool(device, queries_, context_->allocation_callbacks());
  if (pool_ != VK_NULL_HANDLE) context_->fn().vkDestroyCommandPool(device, pool_, context_->allocation_callbacks());
}

std::optional<FrameTiming> FrameRing::collect(Slot& slot, uint32_t index) {
  if (!slot.frame) return std::nullopt;
  FrameTiming t;
  t.frame = *slot.frame;
  slot.frame.reset();
  // One queue: frames complete in submission order.
  if (!completed_through_ || t.frame > *completed_through_) completed_through_ = t.frame;
  if (queries_ == VK_NULL_HANDLE) return std::nullopt;
  // Start, the marks, end: consecutive differences (modulo the valid bits) are the stages.
  const uint64_t* ticks = static_cast<const uint64_t*>(timestamps_.mapped()) + k_queries_per_slot * index;
  const auto ms = [this](uint64_t from, uint64_t to) { return double((to - from) & timestamp_mask_) * ns_per_tick_ * 1e-6; };
  const uint32_t last = slot.marks + 1;
  t.gpu_ms = ms(ticks[0], ticks[last]);
  if (slot.marks > 0)
    for (uint32_t i = 1; i <= last; ++i) t.stage_ms.push_back(ms(ticks[i - 1], ticks[i]));
  return t;
}

VkCommandBuffer FrameRing::begin(uint64_t frame) {
  TVT_CHECK(!recording_);
  TVT_CHECK(!last_frame_ || frame > *last_frame_);
  const uint32_t index = uint32_t(frame % slots_.size());
  Slot& s = slots_[index];
  const VkDevice device = context_->device();
  const auto t0 = std::chrono::steady_clock::now();
  if (!context_->status()) return VK_NULL_HANDLE;
  // VK_TIMEOUT (a frame not finished within 60 s) is latched like a lost device.
  if (!TVT_VK_OK(*context_, context_->fn().vkWaitForFences(device, 1, &s.fence, VK_TRUE, k_fence_timeout_ns))) return VK_NULL_HANDLE;
  last_wait_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (auto t = collect(s, index)) completed_.push_back(*t);
  VkCommandBufferBeginInfo bi{};
  bi.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  if (!TVT_VK_OK(*context_, context_->fn().vkResetFences(device, 1, &s.fence)) || !TVT_VK_OK(*context_, context_->fn().vkResetCommandBuffer(s.cmd, 0)) ||
      !TVT_VK_OK(*context_, context_->fn().vkBeginCommandBuffer(s.cmd, &bi)))
    return VK_NULL_HANDLE;
  if (queries_ != VK_NULL_HANDLE) {
    context_->fn().vkCmdResetQueryPool(s.cmd, queries_, k_queries_per_slot * index, k_queries_per_slot);
    context_->fn().vkCmdWriteTimestamp(s.cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries_, k_queries_per_slot * index);
  }
  s.frame = frame;
  s.marks = 0;
  recording_ = index;
  last_frame_ = frame;
  return s.cmd;
}

void FrameRing::wait_completed(uint64_t frame) {
  if (completed(frame) || !context_->status()) return;
  const uint32_t index = uint32_t(frame % slots_.size());
  Slot& s = slots_[index];
  if (!s.frame || *s.frame != frame || (recording_ && *recording_ == index)) return;  // not submitted
  if (!TVT_VK_OK(*context_, context_->fn().vkWaitForFences(context_->device(), 1, &s.fence, VK_TRUE, k_fence_timeout_ns)))
    return;
  if (auto t = collect(s, index)) completed_.push_back(*t);
}

void FrameRing::mark() {
  TVT_CHECK(recording_);
  Slot& s = slots_[*recording_];
  if (queries_ == VK_NULL_HANDLE || s.marks == k_max_marks) return;
  ++s.marks;
  context_->fn().vkCmdWriteTimestamp(s.cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries_, k_queries_per_slot * *recording_ + s.marks);
}

void FrameRing::submit(VkFence also_signal) {
  TVT_CHECK(recording_);
  Slot& s = slots_[*recording_];
  if (queries_ != VK_NULL_HANDLE) {
    const uint32_t first = k_queries_per_slot * *recording_, count = s.marks + 2;
    context_->fn().vkCmdWriteTimestamp(s.cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries_, first + count - 1);
    context_->fn().vkCmdCopyQueryPoolResults(s.cmd, queries_, first, count, timestamps_.handle(), sizeof(uint64_t) * first,
                              sizeof(uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
    context_->memory_barrier(s.cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                                VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
  }
  recording_.reset();
  VkSubmitInfo si{};
  si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
  si.commandBufferCount = 1;
  si.pCommandBuffers = &s.cmd;
  // After a failure nothing more is submitted; the slot's fence stays unsignalled (the
  // destructor waits for the device, not for fences).
  if (!context_->status() || !TVT_VK_OK(*context_, context_->fn().vkEndCommandBuffer(s.cmd)) ||
      !TVT_VK_OK(*context_, context_->fn().vkQueueSubmit(context_->queue(), 1, &si, s.fence))) {
    s.frame.reset();
    return;
  }
  // No work: the fence signals when everything submitted before it has completed.
  if (also_signal != VK_NULL_HANDLE) TVT_VK_OK(*context_, context_->fn().vkQueueSubmit(context_->queue(), 0, nullptr, also_signal));
}

std::vector<FrameTiming> FrameRing::take_completed() {
  for (uint32_t i = 0; i < slots_.size(); ++i) {
    Slot& s = slots_[i];
    if (!s.frame || (recording_ && *recording_ == i)) continue;
    if (context_->fn().vkGetFenceStatus(context_->device(), s.fence) != VK_SUCCESS) continue;
    if (auto t = collect(s, i)) completed_.push_back(*t);
  }
  std::vector<FrameTiming> out;
  out.swap(completed_);
  std::sort(out.begin(), out.end(), [](const FrameTiming& a, const FrameTiming& b) { return a.frame < b.frame; });
  return out;
}

void FrameRing::wait_idle() {
  TVT_CHECK(!recording_);
  for (Slot& s : slots_)
    if (s.frame && !TVT_VK_OK(*context_, context_->fn().vkWaitForFences(context_->device(), 1, &s.fence, VK_TRUE, k_fence_timeout_ns)))
      return;
}

}  // namespace tvt
