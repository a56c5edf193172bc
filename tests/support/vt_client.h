// The engine side of terravt's public-API tests: a device of the client's own (with
// validation; TERRAVT_DEVICE picks it), a command pool, one command buffer and fence per frame
// in flight. Validation messages fail the test when the client goes.
#pragma once
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "gpu/device_setup.h"
#include "terravt/device.h"

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

}  // namespace tvt
