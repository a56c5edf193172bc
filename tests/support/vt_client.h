// The engine side of terravt's public-API tests: a device of the client's own (with
// validation; TERRAVT_DEVICE picks it), a command pool, one command buffer and fence per frame
// in flight. Validation messages fail the test when the client goes.
#pragma once
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "gpu/context.h"
#include "gpu/device_setup.h"
#include "terravt/device.h"
#include "terravt/page_producer.h"
#include "terravt/virtual_texture.h"

namespace tvt {

// The engine side: a device with validation, one command buffer and fence per frame in flight.
struct Client {
  std::unique_ptr<vk::OwnedDevice> device;
  terravt::DeviceHandles h;
  VkCommandPool pool = VK_NULL_HANDLE;
  std::vector<VkCommandBuffer> cmds;
  std::vector<VkFence> fences;

  explicit Client(uint32_t frames_in_flight) {
    vk::ContextOptions options;
    options.validation = true;
    if (const char* d = std::getenv("TERRAVT_DEVICE")) options.device = d;
    auto owned = vk::OwnedDevice::create(options);
    if (!owned) {
      ADD_FAILURE() << owned.error().message;
      return;
    }
    device = std::move(owned).value();
    h = device->handles();
    VkCommandPoolCreateInfo pci{};
    pci.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pci.queueFamilyIndex = h.queue_family;
    vkCreateCommandPool(h.device, &pci, nullptr, &pool);
    cmds.resize(frames_in_flight);
    VkCommandBufferAllocateInfo ai{};
    ai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    ai.commandPool = pool;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = frames_in_flight;
    vkAllocateCommandBuffers(h.device, &ai, cmds.data());
    fences.resize(frames_in_flight);
    for (VkFence& f : fences) {
      VkFenceCreateInfo fci{};
      fci.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
      fci.flags = VK_FENCE_CREATE_SIGNALED_BIT;
      vkCreateFence(h.device, &fci, nullptr, &f);
    }
  }
  ~Client() {
    if (!device) return;
    vkDeviceWaitIdle(h.device);
    for (VkFence f : fences) vkDestroyFence(h.device, f, nullptr);
    vkDestroyCommandPool(h.device, pool, nullptr);
    const std::vector<std::string> messages = device->messages();
    std::string all;
    for (const std::string& m : messages) all += "\n  " + m;
    EXPECT_TRUE(messages.empty()) << messages.size() << " Vulkan validation message(s):" << all;
  }
  VkCommandBuffer begin(uint64_t frame) {
    const size_t i = frame % cmds.size();
    vkWaitForFences(h.device, 1, &fences[i], VK_TRUE, UINT64_MAX);
    vkResetFences(h.device, 1, &fences[i]);
    vkResetCommandBuffer(cmds[i], 0);
    VkCommandBufferBeginInfo bi{};
    bi.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    vkBeginCommandBuffer(cmds[i], &bi);
    return cmds[i];
  }
  void submit(uint64_t frame) {
    const size_t i = frame % cmds.size();
    vkEndCommandBuffer(cmds[i]);
    VkSubmitInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmds[i];
    vkQueueSubmit(h.queue, 1, &si, fences[i]);
  }
};

struct Readback {
  std::vector<uint8_t> cache;     // every layer, RGBA8, layer after layer
  std::vector<uint32_t> entries;  // the page table
};

// The cache (every layer, `t` names it as a producer is told) and the page table of `vt`, read
// back through a context of the test's own on the client's device.
inline Readback read_back(const Client& client, const terravt::VirtualTexture& vt, const terravt::ProducerTarget& t) {
  auto ctx = vk::Context::adopt(client.h);
  EXPECT_TRUE(ctx.ok()) << ctx.error().message;
  const terravt::VirtualTextureBindings b = vt.bindings();
  const VkDeviceSize layer = VkDeviceSize(t.slot_texels) * t.slot_texels * 4;
  vk::Buffer cache = (*ctx)->create_buffer(layer * t.slots, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  vk::Buffer table = (*ctx)->create_buffer(b.table_bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  (*ctx)->run_commands([&](VkCommandBuffer cmd) {
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, t.slots};
    region.imageExtent = {t.slot_texels, t.slot_texels, 1};
    // GENERAL -> TRANSFER_SRC_OPTIMAL and back: the copy the validation layer wants.
    VkImageMemoryBarrier to{};
    to.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    to.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    to.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    to.oldLayout = VK_IMAGE_LAYOUT_GENERAL;
    to.newLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    to.srcQueueFamilyIndex = to.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    to.image = t.cache;
    to.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, t.slots};
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0, nullptr,
                         1, &to);
    vkCmdCopyImageToBuffer(cmd, t.cache, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, cache.handle(), 1, &region);
    VkImageMemoryBarrier back = to;
    back.srcAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    back.dstAccessMask = 0;
    std::swap(back.oldLayout, back.newLayout);
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 0, nullptr, 0, nullptr,
                         1, &back);
    const VkBufferCopy all{0, 0, b.table_bytes};
    vkCmdCopyBuffer(cmd, b.table_buffer, table.handle(), 1, &all);
    (*ctx)->memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                                VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
  });
  Readback r;
  const auto* c = static_cast<const uint8_t*>(cache.mapped());
  r.cache.assign(c, c + layer * t.slots);
  const auto* e = static_cast<const uint32_t*>(table.mapped());
  r.entries.assign(e, e + b.table_bytes / 4);
  return r;
}

}  // namespace tvt
