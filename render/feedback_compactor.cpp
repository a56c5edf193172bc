#include "render/feedback_compactor.h"

#include <embedded_shaders.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstring>
#include <string>

#include "gpu/command_slots.h"
#include "shaders/shared/feedback_types.h"

namespace tvt {

namespace {

constexpr uint64_t k_fence_timeout_ns = 60ull * 1000 * 1000 * 1000;  // read_blocking: 60 s, then a latched error

uint32_t group_count(uint32_t invocations) {
  return (invocations + gpu::TVT_FEEDBACK_GROUP - 1) / gpu::TVT_FEEDBACK_GROUP;
}

}  // namespace

// One readback ring slot: the output list (host-visible, header + capacity entries), the
// descriptor sets naming it, the fence of the submission that last wrote it, and which frame
// that was.
struct FeedbackCompactor::Slot {
  vk::Buffer list;
  vk::DescriptorSet insert_set, gather_set;
  VkFence fence = VK_NULL_HANDLE;        // created signalled; reset by record()
  VkCommandBuffer own_cmd = VK_NULL_HANDLE;  // used by submit()
  bool has_frame = false;                // record() ran for `frame`
  uint64_t frame = 0;
};

Result<std::unique_ptr<FeedbackCompactor>> FeedbackCompactor::create(vk::Context& context, const Options& options) {
  const auto fail = [](const std::string& field, const std::string& what) {
    return make_error("feedback compactor options: " + field + ": " + what);
  };
  if (options.feedback_width == 0 || options.feedback_height == 0 ||
      uint64_t(options.feedback_width) * options.feedback_height > (uint64_t(1) << 28))
    return fail("feedback_width x feedback_height", "must be between 1 and 2^28 texels, got " +
                                                        std::to_string(options.feedback_width) + " x " +
                                                        std::to_string(options.feedback_height));
  if (options.table_capacity < gpu::TVT_FEEDBACK_GROUP || !std::has_single_bit(options.table_capacity) ||
      options.table_capacity > (1u << 24))
    return fail("table_capacity", "must be a power of two between 64 and 2^24, got " +
                                      std::to_string(options.table_capacity));
  if (options.max_probes == 0 || options.max_probes > options.table_capacity)
    return fail("max_probes", "must be between 1 and table_capacity, got " + std::to_string(options.max_probes));
  if (options.ring_size < 1 || options.ring_size > 16)
    return fail("ring_size", "must be between 1 and 16, got " + std::to_string(options.ring_size));

  std::unique_ptr<FeedbackCompactor> c(new FeedbackCompactor(context));
  c->options_ = options;

  const vk::ComputeBinding insert_bindings[] = {{TVT_BIND_FEEDBACK_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                                {TVT_BIND_FEEDBACK_TABLE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                                {TVT_BIND_FEEDBACK_LIST, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
  const vk::ComputeBinding gather_bindings[] = {{TVT_BIND_FEEDBACK_TABLE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                                {TVT_BIND_FEEDBACK_LIST, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
  c->insert_pipeline_ =
      context.create_compute_pipeline(shaders::feedback_insert_comp(), insert_bindings, sizeof(gpu::TvtFeedbackPush));
  c->gather_pipeline_ =
      context.create_compute_pipeline(shaders::feedback_gather_comp(), gather_bindings, sizeof(gpu::TvtFeedbackPush));

  // The table starts (and, after every gather pass, ends) with every entry EMPTY.
  const VkDeviceSize table_bytes = VkDeviceSize(options.table_capacity) * sizeof(gpu::TvtFeedbackEntry);
  c->table_ = context.create_buffer(table_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                    false);
  const std::vector<gpu::TvtFeedbackEntry> empty(
      options.table_capacity,
      gpu::TvtFeedbackEntry{gpu::TVT_FEEDBACK_EMPTY_WORD, gpu::TVT_FEEDBACK_EMPTY_WORD, 0u});
  context.upload(c->table_, empty.data(), table_bytes);

  c->command_pool_ = vk::create_command_pool(context);

  const VkDeviceSize list_bytes = sizeof(gpu::TvtFeedbackListHeader) + table_bytes;
  c->slots_.resize(options.ring_size);
  for (Slot& s : c->slots_) {
    s.list = context.create_buffer(list_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                   true);
    s.insert_set = context.allocate_descriptor_set(c->insert_pipeline_);
    s.insert_set.write_buffer(TVT_BIND_FEEDBACK_TABLE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->table_);
    s.insert_set.write_buffer(TVT_BIND_FEEDBACK_LIST, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, s.list);
    s.gather_set = context.allocate_descriptor_set(c->gather_pipeline_);
    s.gather_set.write_buffer(TVT_BIND_FEEDBACK_TABLE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->table_);
    s.gather_set.write_buffer(TVT_BIND_FEEDBACK_LIST, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, s.list);
    const vk::CommandSlot cs = vk::create_command_slot(context, c->command_pool_);
    s.fence = cs.fence;
    s.own_cmd = cs.cmd;
  }
  if (auto st = context.status(); !st) return st.error();  // c's destructor frees what was made
  return c;
}

FeedbackCompactor::FeedbackCompactor(vk::Context& context) : context_(&context) {}

FeedbackCompactor::~FeedbackCompactor() {
  // A fence handed out by record() may never have been submitted, so waiting for the fences
  // could hang: wait for the device instead, then nothing of ours is in use. Never on a
  // client's device: there the client guarantees the GPU is done (record_unfenced()'s contract).
  if (context_->owns_device()) context_->wait_idle();
  const VkDevice device = context_->device();
  for (Slot& s : slots_)
    if (s.fence != VK_NULL_HANDLE) context_->fn().vkDestroyFence(device, s.fence, context_->allocation_callbacks());
  if (command_pool_ != VK_NULL_HANDLE) context_->fn().vkDestroyCommandPool(device, command_pool_, context_->allocation_callbacks());
}

VkFence FeedbackCompactor::record(VkCommandBuffer cmd, const vk::Buffer& feedback, uint64_t frame) {
  TVT_CHECK(frame >= next_frame_);
  TVT_CHECK(feedback.size() >= feedback_bytes());
  Slot& s = slots_[frame % slots_.size()];
  // The slot's last submission must be complete before its sets and list are reused; if it is
  // not, skip this frame's feedback instead of stalling.
  if (!context_->status()) return VK_NULL_HANDLE;
  if (const VkResult r = context_->fn().vkGetFenceStatus(context_->device(), s.fence); r != VK_SUCCESS) {
    if (r != VK_NOT_READY) TVT_VK_OK(*context_, r);  // VK_ERROR_DEVICE_LOST: latched
    return VK_NULL_HANDLE;
  }
  next_frame_ = frame + 1;
  if (!TVT_VK_OK(*context_, context_->fn().vkResetFences(context_->device(), 1, &s.fence))) return VK_NULL_HANDLE;
  record_slot(s, cmd, feedback.handle(), 0, frame);
  return s.fence;
}

void FeedbackCompactor::record_unfenced(VkCommandBuffer cmd, VkBuffer feedback, VkDeviceSize offset, uint64_t frame) {
  TVT_CHECK(frame >= next_frame_);
  next_frame_ = frame + 1;
  record_slot(slots_[frame % slots_.size()], cmd, feedback, offset, frame);
}

void FeedbackCompactor::record_slot(Slot& s, VkCommandBuffer cmd, VkBuffer feedback, VkDeviceSize offset,
                                    uint64_t frame) {
  s.has_frame = true;
  s.frame = frame;
  s.insert_set.write_buffer(TVT_BIND_FEEDBACK_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, feedback, offset);

  const gpu::TvtFeedbackPush push{texel_count(), options_.table_capacity, options_.max_probes, 0u};
  // Earlier writes of the feedback (any pass, this or an earlier submission) and the previous
  // compaction's gather (which reads and resets the table) happen before this one.
  context_->memory_barrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_ACCESS_MEMORY_WRITE_BIT,
                 VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                 VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
  context_->fn().vkCmdFillBuffer(cmd, s.list.handle(), 0, sizeof(gpu::TvtFeedbackListHeader), 0u);
  context_->memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                 VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);

  VkDescriptorSet set = s.insert_set.handle();
  context_->fn().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, insert_pipeline_.handle());
  context_->fn().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, insert_pipeline_.layout(), 0, 1, &set, 0, nullptr);
  context_->fn().vkCmdPushConstants(cmd, insert_pipeline_.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
  const uint32_t invocations = (texel_count() + gpu::TVT_FEEDBACK_TEXELS_PER_INVOCATION - 1) /
                               gpu::TVT_FEEDBACK_TEXELS_PER_INVOCATION;
  context_->fn().vkCmdDispatch(cmd, group_count(invocations), 1, 1);

  context_->memory_barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                 VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);

  set = s.gather_set.handle();
  context_->fn().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, gather_pipeline_.handle());
  context_->fn().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, gather_pipeline_.layout(), 0, 1, &set, 0, nullptr);
  context_->fn().vkCmdPushConstants(cmd, gather_pipeline_.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
  context_->fn().vkCmdDispatch(cmd, group_count(options_.table_capacity), 1, 1);

  context_->memory_barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                 VK_ACCESS_HOST_READ_BIT);
}

bool FeedbackCompactor::submit(const vk::Buffer& feedback, uint64_t frame) {
  Slot& s = slots_[frame % slots_.size()];
  // Checked here too: the command buffer is re-recorded only when its last submission is done.
  if (!context_->status()) return false;
  if (const VkResult r = context_->fn().vkGetFenceStatus(context_->device(), s.fence); r != VK_SUCCESS) {
    if (r != VK_NOT_READY) TVT_VK_OK(*context_, r);  // VK_ERROR_DEVICE_LOST: latched
    return false;
  }
  VkCommandBufferBeginInfo bi{};
  bi.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  if (!TVT_VK_OK(*context_, context_->fn().vkResetCommandBuffer(s.own_cmd, 0)) || !TVT_VK_OK(*context_, context_->fn().vkBeginCommandBuffer(s.own_cmd, &bi)))
    return false;
  const VkFence fence = record(s.own_cmd, feedback, frame);
  if (fence == VK_NULL_HANDLE) return false;  // a failed call (latched); the slot was checked free above
  VkSubmitInfo si{};
  si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
  si.commandBufferCount = 1;
  si.pCommandBuffers = &s.own_cmd;
  return TVT_VK_OK(*context_, context_->fn().vkEndCommandBuffer(s.own_cmd)) && TVT_VK_OK(*context_, context_->fn().vkQueueSubmit(context_->queue(), 1, &si, fence));
}

FeedbackResult FeedbackCompactor::parse(const Slot& slot) const {
  const auto* bytes = static_cast<const uint8_t*>(slot.list.mapped());
  gpu::TvtFeedbackListHeader header{};
  std::memcpy(&header, bytes, sizeof(header));
  header.count = std::min(header.count, options_.table_capacity);  // never more than the GPU table holds
  std::vector<gpu::TvtFeedbackEntry> entries(header.count);
  // An empty list (a frame of sky) has no data(): memcpy from or to null is undefined even for 0 bytes.
  if (!entries.empty()) std::memcpy(entries.data(), bytes + sizeof(header), entries.size() * sizeof(gpu::TvtFeedbackEntry));
  FeedbackResult r;
  r.frame = slot.frame;
  r.overflow = header.overflow_texels != 0;
  r.overflow_texels = header.overflow_texels;
  r.pages.reserve(entries.size());
  for (const gpu::TvtFeedbackEntry& e : entries) r.pages.emplace_back(feedback_texel_page(e.key0, e.key1), e.count);
  std::sort(r.pages.begin(), r.pages.end());
  return r;
}

std::optional<FeedbackResult> FeedbackCompactor::try_read(uint64_t frame, bool known_complete) {
  const Slot& s = slots_[frame % slots_.size()];
  if (!s.has_frame || s.frame != frame) return std::nullopt;
  if (!known_complete && context_->fn().vkGetFenceStatus(context_->device(), s.fence) != VK_SUCCESS) return std::nullopt;
  return parse(s);
}

std::optional<FeedbackResult> FeedbackCompactor::read_blocking(uint64_t frame) {
  const Slot& s = slots_[frame % slots_.size()];
  if (!s.has_frame || s.frame != frame) return std::nullopt;
  // VK_TIMEOUT (not finished within 60 s) is latched like a lost device: no result.
  if (!TVT_VK_OK(*context_, context_->fn().vkWaitForFences(context_->device(), 1, &s.fence, VK_TRUE, k_fence_timeout_ns)))
    return std::nullopt;
  return parse(s);
}

double FeedbackCompactor::time_compaction(const vk::Buffer& feedback, int repeats) {
  std::vector<double> seconds(size_t(std::max(repeats, 1)));
  for (double& t : seconds) {
    const uint64_t frame = next_frame_;
    const auto start = std::chrono::steady_clock::now();
    // The slot of `frame` was waited for by the previous iteration (or never used).
    if (!submit(feedback, frame)) return 0;  // a failed call, latched on the context
    const VkFence fence = slots_[frame % slots_.size()].fence;
    if (!TVT_VK_OK(*context_, context_->fn().vkWaitForFences(context_->device(), 1, &fence, VK_TRUE, k_fence_timeout_ns))) return 0;
    t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  std::nth_element(seconds.begin(), seconds.begin() + seconds.size() / 2, seconds.end());
  return seconds[seconds.size() / 2];
}

}  // namespace tvt
