// Command pools and slots for terravt's own submission rings (see command_slots.h).
#include "gpu/command_slots.h"

namespace tvt::vk {

VkCommandPool create_command_pool(const Context& context) {
  auto pci = init<VkCommandPoolCreateInfo>(VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO);
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = context.queue_family();
  VkCommandPool pool = VK_NULL_HANDLE;
  if (!TVT_VK_OK(context, context.fn().vkCreateCommandPool(context.device(), &pci, context.allocation_callbacks(), &pool)))
    return VK_NULL_HANDLE;
  return pool;
}

CommandSlot create_command_slot(const Context& context, VkCommandPool pool) {
  CommandSlot slot;
  auto fci = init<VkFenceCreateInfo>(VK_STRUCTURE_TYPE_FENCE_CREATE_INFO);
  fci.flags = VK_FENCE_CREATE_SIGNALED_BIT;
  if (pool == VK_NULL_HANDLE ||
      !TVT_VK_OK(context, context.fn().vkCreateFence(context.device(), &fci, context.allocation_callbacks(), &slot.fence)))
    return {};
  auto cai = init<VkCommandBufferAllocateInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO);
  cai.commandPool = pool;
  cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  cai.commandBufferCount = 1;
  if (!TVT_VK_OK(context, context.fn().vkAllocateCommandBuffers(context.device(), &cai, &slot.cmd))) slot.cmd = VK_NULL_HANDLE;
  return slot;  // the owner destroys the fence, also when cmd is empty (the failure is latched)
}

}  // namespace tvt::vk
