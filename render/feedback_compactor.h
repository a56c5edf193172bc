// Host side of the GPU feedback compaction (feedback_insert.comp + feedback_gather.comp): turns a
// W x H feedback buffer (two uint32 words per texel, shaders/shared/feedback_types.h) into the
// list of distinct pages with texel counts, read back through a ring of host-visible buffers so
// the CPU never waits for the GPU in the frame loop. See docs/feedback.md.
//
// Planned once from Options, then per frame:
//   VkFence f = compactor.record(cmd, feedback, frame);   // submit cmd with fence f
//   ...later frames...
//   if (auto r = compactor.try_read(frame - ring_size + 1)) residency.update(*r);
// Frame `frame` uses ring slot frame % ring_size. A slot is reused only once its fence has
// signalled; if it has not, record() records nothing and returns VK_NULL_HANDLE (that frame has
// no feedback) rather than waiting.
//
// Thread-safety: none; one thread records, submits and reads. submit(), read_blocking() and
// time_compaction() use the context's queue (serialise them with other users of it, see
// gpu/context.h). The destructor waits for the device when terravt owns it (Context::create());
// on a client's device (Context::adopt()) the client destroys it once the GPU is done.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "gpu/context.h"
#include "vt/feedback_analysis.h"

namespace tvt {

class FeedbackCompactor {
 public:
  struct Options {
    uint32_t feedback_width = 320;    // feedback texels per row (view width / N)
    uint32_t feedback_height = 180;   // feedback rows
    uint32_t table_capacity = 4096;   // hash-table entries = most distinct pages per frame; power of two
    uint32_t max_probes = 128;        // linear-probing limit per texel (1 ... table_capacity); beyond: overflow
    uint32_t ring_size = 3;           // readback buffers; results are ring_size - 1 frames late
  };

  static Result<std::unique_ptr<FeedbackCompactor>> create(vk::Context& context, const Options& options);
  ~FeedbackCompactor();
  FeedbackCompactor(const FeedbackCompactor&) = delete;
  FeedbackCompactor& operator=(const FeedbackCompactor&) = delete;

  const Options& options() const { return options_; }
  uint32_t texel_count() const { return options_.feedback_width * options_.feedback_height; }
  // Bytes a feedback buffer must hold at least: 8 per texel.
  VkDeviceSize feedback_bytes() const { return VkDeviceSize(texel_count()) * 8; }

  // Records the compaction of `feedback` (STORAGE_BUFFER usage, >= feedback_bytes(), row-major
  // texels) for frame `frame` into `cmd`. Starts with a barrier that makes all earlier writes
  // of the queue (any stage) visible, so the feedback may be written earlier in `cmd` or in an
  // earlier submission on the same queue. Returns the fence (unsignalled, owned by the
  // compactor) that the caller must pass to the vkQueueSubmit containing `cmd`, or
  // VK_NULL_HANDLE when the frame's ring slot is still in flight: then nothing is recorded.
  // Frames must increase from call to call.
  VkFence record(VkCommandBuffer cmd, const vk::Buffer& feedback, uint64_t frame);

  // record() for a caller that knows, from its own frame protocol, that the commands of frame
  // `frame - ring_size` (the last user of this frame's ring slot) have completed: no fence is
  // used (the caller's fences cover the slot) and the result is read with
  // try_read(frame, true). `feedback` may be a buffer terravt does not own (STORAGE_BUFFER
  // usage, >= feedback_bytes() from `offset`).
  void record_unfenced(VkCommandBuffer cmd, VkBuffer feedback, VkDeviceSize offset, uint64_t frame);

  // record() into the compactor's own command buffer for the slot, submitted on the context's
  // queue. False when the ring slot is still in flight (nothing submitted) or a Vulkan call
  // failed (latched on the context). Never waits.
  bool submit(const vk::Buffer& feedback, uint64_t frame);

  // The result of `frame` when its slot holds that frame and its fence has signalled
  // (vkGetFenceStatus); std::nullopt otherwise (not submitted yet, still running, skipped, or
  // overwritten by frame + ring_size). Never waits. May be called more than once per frame.
  // known_complete: the caller knows the commands that compacted `frame` have completed (the
  // fence of the command buffer it recorded them into signalled, gpu/frame_ring.h), so the
  // compactor's own fence, which may signal a moment later, is not consulted.
  std::optional<FeedbackResult> try_read(uint64_t frame, bool known_complete = false);

  // Like try_read() but waits for the fence (tools, tests). std::nullopt when the slot does
  // not hold `frame`.
  std::optional<FeedbackResult> read_blocking(uint64_t frame);

  // Benchmark: submits `repeats` compactions of `feedback` one at a time, each waited for, and
  // returns the median seconds per compaction (record + submit until the fence signalled, wall
  // clock; the CPU-side parse and sort of the list is not included). 0 after a failed Vulkan
  // call (latched on the context).
  double time_compaction(const vk::Buffer& feedback, int repeats);

 private:
  struct Slot;
  explicit FeedbackCompactor(vk::Context& context);  // out of line: Slot is incomplete here
  FeedbackResult parse(const Slot& slot) const;
  void record_slot(Slot& slot, VkCommandBuffer cmd, VkBuffer feedback, VkDeviceSize offset, uint64_t frame);

  vk::Context* context_;
  Options options_;
  vk::ComputePipeline insert_pipeline_, gather_pipeline_;
  vk::Buffer table_;
  VkCommandPool command_pool_ = VK_NULL_HANDLE;
  std::vector<Slot> slots_;
  uint64_t next_frame_ = 0;  // frames passed to record() must be >= this
};

}  // namespace tvt
