// terravt's private Vulkan function table. Library code never calls the Vulkan loader's
// exported functions (it is compiled with VK_NO_PROTOTYPES, so a direct call does not
// compile): every instance and device function it uses is looked up once per Context through
// the vkGetInstanceProcAddr the client hands in (terravt::DeviceHandles), device functions
// then through vkGetDeviceProcAddr, so they dispatch straight to the client's driver. An engine
// that loads Vulkan its own way (volk, a statically linked loader, a layer of its own) gets
// terravt calling exactly the functions it resolved, and libterravt needs no libvulkan.
//
// Adding a call: add its name (without "vk") to the list of its level below.
#pragma once
#include <vulkan/vulkan.h>

#include "vt/result.h"

namespace tvt::vk {

// Functions of the instance and the physical device.
#define TVT_VK_INSTANCE_FUNCTIONS(X)      \
  X(GetDeviceProcAddr)                    \
  X(GetPhysicalDeviceProperties)          \
  X(GetPhysicalDeviceProperties2)         \
  X(GetPhysicalDeviceMemoryProperties)    \
  X(GetPhysicalDeviceFormatProperties)    \
  X(GetPhysicalDeviceImageFormatProperties) \
  X(GetPhysicalDeviceQueueFamilyProperties)

// Functions of the device and its command buffers (Vulkan 1.3 core; vkCmdPipelineBarrier2 is
// used only where synchronization2 is on).
#define TVT_VK_DEVICE_FUNCTIONS(X) \
  X(AllocateCommandBuffers)        \
  X(AllocateDescriptorSets)        \
  X(AllocateMemory)                \
  X(BeginCommandBuffer)            \
  X(BindBufferMemory)              \
  X(BindImageMemory)               \
  X(CmdBeginRendering)             \
  X(CmdBindDescriptorSets)         \
  X(CmdBindIndexBuffer)            \
  X(CmdBindPipeline)               \
  X(CmdBindVertexBuffers)          \
  X(CmdBlitImage)                  \
  X(CmdCopyBuffer)                 \
  X(CmdCopyBufferToImage)          \
  X(CmdCopyImage)                  \
  X(CmdCopyImageToBuffer)          \
  X(CmdCopyQueryPoolResults)       \
  X(CmdDispatch)                   \
  X(CmdDrawIndexed)                \
  X(CmdEndRendering)               \
  X(CmdFillBuffer)                 \
  X(CmdPipelineBarrier)            \
  X(CmdPipelineBarrier2)           \
  X(CmdPushConstants)              \
  X(CmdResetQueryPool)             \
  X(CmdSetScissor)                 \
  X(CmdSetViewport)                \
  X(CmdUpdateBuffer)               \
  X(CmdWriteTimestamp)             \
  X(CreateBuffer)                  \
  X(CreateCommandPool)             \
  X(CreateComputePipelines)        \
  X(CreateDescriptorPool)          \
  X(CreateDescriptorSetLayout)     \
  X(CreateFence)                   \
  X(CreateGraphicsPipelines)       \
  X(CreateImage)                   \
  X(CreateImageView)               \
  X(CreatePipelineLayout)          \
  X(CreateQueryPool)               \
  X(CreateSampler)                 \
  X(CreateShaderModule)            \
  X(DestroyBuffer)                 \
  X(DestroyCommandPool)            \
  X(DestroyDescriptorPool)         \
  X(DestroyDescriptorSetLayout)    \
  X(DestroyFence)                  \
  X(DestroyImage)                  \
  X(DestroyImageView)              \
  X(DestroyPipeline)               \
  X(DestroyPipelineLayout)         \
  X(DestroyQueryPool)              \
  X(DestroySampler)                \
  X(DestroyShaderModule)           \
  X(DeviceWaitIdle)                \
  X(EndCommandBuffer)              \
  X(FreeCommandBuffers)            \
  X(FreeMemory)                    \
  X(GetBufferMemoryRequirements)   \
  X(GetFenceStatus)                \
  X(GetImageMemoryRequirements)    \
  X(GetQueryPoolResults)           \
  X(MapMemory)                     \
  X(QueueSubmit)                   \
  X(ResetCommandBuffer)            \
  X(ResetFences)                   \
  X(UpdateDescriptorSets)          \
  X(WaitForFences)

// The table: one member per function, named as in Vulkan (fn.vkCmdDispatch(...)).
struct Functions {
#define TVT_VK_DECLARE(name) PFN_vk##name vk##name = nullptr;
  TVT_VK_INSTANCE_FUNCTIONS(TVT_VK_DECLARE)
  TVT_VK_DEVICE_FUNCTIONS(TVT_VK_DECLARE)
#undef TVT_VK_DECLARE

  // Looks every function up: instance functions through `get_instance_proc_addr(instance)`,
  // device functions through vkGetDeviceProcAddr(device). An error (kind unsupported_device)
  // names the first function the driver or loader does not return.
  static Result<Functions> load(PFN_vkGetInstanceProcAddr get_instance_proc_addr, VkInstance instance,
                                VkDevice device);
};

}  // namespace tvt::vk
