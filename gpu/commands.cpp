// One-shot submission for set-up, uploads and tests: run_commands() and upload().
#include <algorithm>
#include <chrono>
#include <cstring>
#include <utility>

#include "gpu/context.h"

namespace tvt::vk {

namespace {
constexpr uint64_t kFenceTimeoutNs = 60ull * 1000 * 1000 * 1000;  // 60 s, then an error
constexpr VkDeviceSize kStagingChunkBytes = VkDeviceSize(16) << 20;  // upload() staging size
}  // namespace

void Context::run_commands(const std::function<void(VkCommandBuffer)>& record) {
  if (!status()) return;  // a failed call before: nothing more is submitted
  if (deferring_) {
    deferred_.push_back(record);
    return;
  }
  auto ai = init<VkCommandBufferAllocateInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO);
  ai.commandPool = command_pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  if (!TVT_VK_OK(*this, fn_.vkAllocateCommandBuffers(device_, &ai, &cmd))) return;
  VkFence fence = VK_NULL_HANDLE;
  auto bi = init<VkCommandBufferBeginInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO);
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  auto fci = init<VkFenceCreateInfo>(VK_STRUCTURE_TYPE_FENCE_CREATE_INFO);
  auto si = init<VkSubmitInfo>(VK_STRUCTURE_TYPE_SUBMIT_INFO);
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  bool submitted = false;
  if (TVT_VK_OK(*this, fn_.vkBeginCommandBuffer(cmd, &bi))) {
    record(cmd);
    submitted = TVT_VK_OK(*this, fn_.vkEndCommandBuffer(cmd)) &&
                TVT_VK_OK(*this, fn_.vkCreateFence(device_, &fci, alloc_, &fence)) &&
                TVT_VK_OK(*this, fn_.vkQueueSubmit(queue_, 1, &si, fence));
  }
  if (submitted) {
    // VK_TIMEOUT after 60 s: a hung GPU is latched like a lost device.
    if (!TVT_VK_OK(*this, fn_.vkWaitForFences(device_, 1, &fence, VK_TRUE, kFenceTimeoutNs))) {
      // The command buffer may still be pending: leave it to the pool rather than free it.
      fn_.vkDestroyFence(device_, fence, alloc_);
      return;
    }
  }
  if (fence != VK_NULL_HANDLE) fn_.vkDestroyFence(device_, fence, alloc_);
  fn_.vkFreeCommandBuffers(device_, command_pool_, 1, &cmd);
}

double Context::run_commands_timed(const std::function<void(VkCommandBuffer)>& record) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto wall = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  VkQueryPool pool = VK_NULL_HANDLE;
  auto qci = init<VkQueryPoolCreateInfo>(VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO);
  qci.queryType = VK_QUERY_TYPE_TIMESTAMP;
  qci.queryCount = 2;
  if (deferring_ || timestamp_mask_ == 0 ||
      fn_.vkCreateQueryPool(device_, &qci, alloc_, &pool) != VK_SUCCESS) {
    run_commands(record);
    return wall();
  }
  run_commands([&](VkCommandBuffer cmd) {
    fn_.vkCmdResetQueryPool(cmd, pool, 0, 2);
    fn_.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, pool, 0);
    record(cmd);
    fn_.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool, 1);
  });
  double seconds = wall();
  uint64_t ticks[2] = {};
  if (status() && fn_.vkGetQueryPoolResults(device_, pool, 0, 2, sizeof(ticks), ticks, sizeof(uint64_t),
                                            VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT) == VK_SUCCESS) {
    seconds = double((ticks[1] - ticks[0]) & timestamp_mask_) * double(properties_.limits.timestampPeriod) * 1e-9;
  }
  fn_.vkDestroyQueryPool(device_, pool, alloc_);
  return seconds;
}

void Context::record_deferred_setup(VkCommandBuffer cmd) {
  if (deferred_.empty() || !status()) return;
  for (const auto& record : deferred_) record(cmd);
  deferred_.clear();
  memory_barrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_ACCESS_MEMORY_WRITE_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                 VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT);
}

void Context::upload(const Buffer& dst, const void* data, VkDeviceSize bytes, VkDeviceSize dst_offset) {
  // An empty dst: its creation failed (latched); nothing is uploaded after a failure.
  if (bytes == 0 || !dst || !status()) return;
  TVT_CHECK(data != nullptr);
  TVT_CHECK(dst_offset <= dst.size() && bytes <= dst.size() - dst_offset);
  if (deferring_) {
    // One staging buffer for the whole upload, kept until the client's command buffer ran.
    Buffer staging = create_buffer(bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
    if (!staging) return;
    deferred_staging_.push_back(std::move(staging));
    std::memcpy(deferred_staging_.back().mapped(), data, size_t(bytes));
    const VkBuffer src = deferred_staging_.back().handle(), to = dst.handle();
    deferred_.push_back([this, src, to, bytes, dst_offset](VkCommandBuffer cmd) {
      const VkBufferCopy region{0, dst_offset, bytes};
      fn_.vkCmdCopyBuffer(cmd, src, to, 1, &region);
    });
    return;
  }
  const VkDeviceSize chunk = std::min(bytes, kStagingChunkBytes);
  Buffer staging = create_buffer(chunk, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
  if (!staging) return;
  const auto* src = static_cast<const unsigned char*>(data);
  for (VkDeviceSize done = 0; done < bytes; done += chunk) {
    const VkDeviceSize n = std::min(chunk, bytes - done);
    if (!status()) return;
    std::memcpy(staging.mapped(), src + done, size_t(n));  // host writes: visible at submit
    run_commands([&](VkCommandBuffer cmd) {
      const VkBufferCopy region{0, dst_offset + done, n};
      fn_.vkCmdCopyBuffer(cmd, staging.handle(), dst.handle(), 1, &region);
      // Make the copy visible to whatever the caller records next (any stage, any access).
      auto mb = init<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
      mb.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      mb.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
      fn_.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 1, &mb, 0,
                           nullptr, 0, nullptr);
    });
  }
}

}  // namespace tvt::vk
