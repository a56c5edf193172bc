// Rings of command buffers that terravt records and submits itself (gpu/frame_ring.h, the
// feedback compactor's own submissions): a pool of individually resettable command buffers and,
// per slot, a fence created signalled (the slot is free) and one primary command buffer. Made
// with the context's allocation callbacks; the owner destroys the fences and the pool (which
// frees its command buffers) once the GPU is done with them.
#pragma once
#include <vulkan/vulkan.h>

#include "gpu/context.h"

namespace tvt::vk {

struct CommandSlot {
  VkFence fence = VK_NULL_HANDLE;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
};

// A pool on the context's queue family with VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT.
// A failed call latches its error on the context (Context::status()) and leaves the handle
// empty: the owner checks status() once it has made every slot.
VkCommandPool create_command_pool(const Context& context);
CommandSlot create_command_slot(const Context& context, VkCommandPool pool);

}  // namespace tvt::vk
