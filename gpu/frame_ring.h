// Frames in flight on the context's queue: a ring of K command buffers, each with its fence
// and two GPU timestamps. The frame loop records frame f while frames f-1 ... f-K+1 may still
// run on the GPU; the CPU blocks only when it is K frames ahead (back-pressure, begin()), never
// for the result of a frame it just submitted.
//
//   VkCommandBuffer cmd = ring.begin(f);  // waits only for frame f-K (its slot)
//   ... record ...
//   ring.submit();
//
// Whatever a frame's commands read from host-visible memory must live in a ring of the same
// depth (VtSystem, GpuComposer, MaterialUploader and StoredProducer take frames_in_flight):
// begin(f) returning means frame f-K has completed, so its part of every ring is free.
//
// Not thread-safe; uses the context's queue (serialise with other users, gpu/context.h). The
// destructor waits for every submitted frame.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "gpu/context.h"

namespace tvt {

struct FrameTiming {
  uint64_t frame = 0;
  double gpu_ms = 0;   // first to last command of the frame's command buffer (GPU timestamps)
  // GPU ms of each stage the frame marked (FrameRing::mark()): stage i runs from mark i-1 (or
  // the start) to mark i; the last entry runs from the last mark to the end.
  std::vector<double> stage_ms;
};

class FrameRing {
 public:
  // frames_in_flight: 1 ... 8 (1: every begin() waits for the previous frame).
  static Result<std::unique_ptr<FrameRing>> create(vk::Context& context, uint32_t frames_in_flight);
  ~FrameRing();
  FrameRing(const FrameRing&) = delete;
  FrameRing& operator=(const FrameRing&) = delete;

  uint32_t frames_in_flight() const { return uint32_t(slots_.size()); }

  // Begins frame `frame` (greater than the previous one) in ring slot frame % K: waits until the
  // frame that last used the slot has completed, then returns its command buffer, recording.
  // VK_NULL_HANDLE when a Vulkan call failed, now or before (context.status() says which).
  VkCommandBuffer begin(uint64_t frame);
  // Ends the current stage of the frame being recorded: a timestamp once every command recorded
  // so far has completed. At most k_max_marks per frame (more are ignored).
  static constexpr uint32_t k_max_marks = 6;
  void mark();
  // Ends and submits the command buffer begin() returned. `also_signal` (optional, unsignalled):
  // a fence of another owner that signals once this frame's commands have completed (an empty
  // submission right behind the frame's), e.g. the feedback compactor's for the compaction
  // recorded into this frame. After a failure (context.status()) nothing is submitted.
  void submit(VkFence also_signal = VK_NULL_HANDLE);
  // Milliseconds the latest begin() blocked for the GPU (0 when the slot was free).
  double last_wait_ms() const { return last_wait_ms_; }
  // GPU times of submitted frames that have completed since the last call (never waits),
  // oldest first. Empty when the queue has no timestamp support.
  std::vector<FrameTiming> take_completed();
  // `frame` was submitted and has completed, as far as the ring has seen (begin() of frame f
  // knows f - K has; take_completed() polls the newer ones). Never waits.
  bool completed(uint64_t frame) const { return completed_through_ && frame <= *completed_through_; }
  // The newest frame known complete that way (std::nullopt before the first).
  std::optional<uint64_t> completed_through() const { return completed_through_; }
  // Waits until submitted frame `frame` has completed (returns at once when it has, or was
  // never submitted); its timing joins take_completed()'s. A failed wait is latched on the
  // context.
  void wait_completed(uint64_t frame);
  // Waits for every submitted frame.
  void wait_idle();

 private:
  struct Slot {
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    VkFence fence = VK_NULL_HANDLE;  // created signalled
    std::optional<uint64_t> frame;   // submitted and not yet reported by take_completed()
    uint32_t marks = 0;              // mark() calls of that frame
  };
  static constexpr uint32_t k_queries_per_slot = k_max_marks + 2;  // start, marks, end
  FrameRing() = default;
  // The slot's frame has completed (its fence signalled): its timing, once.
  std::optional<FrameTiming> collect(Slot& slot, uint32_t index);
  vk::Context* context_ = nullptr;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkQueryPool queries_ = VK_NULL_HANDLE;  // two per slot; VK_NULL_HANDLE without timestamps
  // The slots' timestamps, copied there by their own command buffers: read on the host after
  // the fence, never through vkGetQueryPoolResults (which lavapipe implements by waiting for
  // the whole device, and that would undo frames in flight).
  vk::Buffer timestamps_;
  double ns_per_tick_ = 0;
  uint64_t timestamp_mask_ = 0;
  std::vector<Slot> slots_;
  std::vector<FrameTiming> completed_;
  std::optional<uint32_t> recording_;
  std::optional<uint64_t> last_frame_;
  std::optional<uint64_t> completed_through_;  // every frame up to this one has completed
  double last_wait_ms_ = 0;
};

}  // namespace tvt
