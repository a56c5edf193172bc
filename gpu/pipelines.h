// Compute and graphics pipelines with their own set-0 descriptor-set layouts, and descriptor
// sets with their own pools: move-only RAII handles made by Context (gpu/context.h).
// Lifetime as in gpu/resources.h.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <span>
#include <vector>

#include "gpu/resources.h"

namespace tvt::vk {

// A compute pipeline with its own descriptor-set layout (storage buffers / storage images /
// uniform buffers at the given bindings, set 0) and an optional push-constant range.
struct ComputeBinding {
  uint32_t binding;
  VkDescriptorType type;
};

// One specialization constant: layout(constant_id = id) takes these 32 bits (int, uint, bool
// or float). Variants of one shader without its dead branches.
struct SpecConstant {
  uint32_t id;
  uint32_t value;
};

// What every pipeline owns: the pipeline, its layout and its set-0 descriptor-set layout.
// Move-only; destroys them with the device it was created on.
class PipelineHandles {
 public:
  PipelineHandles() = default;
  PipelineHandles(PipelineHandles&&) noexcept;
  PipelineHandles& operator=(PipelineHandles&&) noexcept;
  PipelineHandles(const PipelineHandles&) = delete;
  PipelineHandles& operator=(const PipelineHandles&) = delete;
  ~PipelineHandles();

  VkPipeline handle() const { return pipeline_; }
  VkPipelineLayout layout() const { return layout_; }
  VkDescriptorSetLayout set_layout() const { return set_layout_; }

 protected:
  VkDevice device_ = VK_NULL_HANDLE;
  const Functions* fn_ = nullptr;  // the Context's table (gpu/vk_functions.h)
  const VkAllocationCallbacks* alloc_ = nullptr;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;

 private:
  void reset();
};

class ComputePipeline : public PipelineHandles {
 private:
  friend class Context;
  std::vector<ComputeBinding> bindings_;  // sizes the pool of each DescriptorSet
};

// A graphics pipeline for dynamic rendering (Vulkan 1.3 core): vertex + fragment stages, its
// own descriptor-set layout (set 0) and an optional push-constant range. Viewport and scissor
// are dynamic state (RenderTarget::begin sets them to the whole target).
struct GraphicsBinding {
  uint32_t binding;
  VkDescriptorType type;
  VkShaderStageFlags stages;
};

struct GraphicsPipelineDesc {
  std::span<const uint32_t> vertex_spirv;
  std::span<const uint32_t> fragment_spirv;
  // Specialization constants of the fragment stage: constant_id i takes fragment_constants[i]
  // (32-bit int/uint/bool/float bits). Lets one shader compile to variants without dead branches.
  std::vector<uint32_t> fragment_constants;
  std::vector<VkVertexInputBindingDescription> vertex_bindings;
  std::vector<VkVertexInputAttributeDescription> vertex_attributes;
  std::vector<GraphicsBinding> bindings;            // descriptor set 0
  uint32_t push_constant_bytes = 0;                 // multiple of 4; 0: none
  VkShaderStageFlags push_constant_stages = VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;
  std::vector<VkFormat> color_formats;              // one per colour attachment, in location order
  VkFormat depth_format = VK_FORMAT_UNDEFINED;      // UNDEFINED: no depth attachment
  VkCompareOp depth_compare = VK_COMPARE_OP_GREATER_OR_EQUAL;  // reverse-Z by default
  bool depth_write = true;
  VkPrimitiveTopology topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
  VkCullModeFlags cull_mode = VK_CULL_MODE_BACK_BIT;
  VkFrontFace front_face = VK_FRONT_FACE_COUNTER_CLOCKWISE;  // in framebuffer coordinates (y down)
};

class GraphicsPipeline : public PipelineHandles {
 public:
  VkShaderStageFlags push_constant_stages() const { return push_stages_; }

 private:
  friend class Context;
  VkShaderStageFlags push_stages_ = 0;
  std::vector<VkDescriptorType> types_;  // sizes the pool of each DescriptorSet
};

// One descriptor set from a pool owned by the set itself; write_*() binds resources. Writes
// must not happen while a submitted command buffer that uses the set is still pending.
class DescriptorSet {
 public:
  DescriptorSet() = default;
  DescriptorSet(DescriptorSet&&) noexcept;
  DescriptorSet& operator=(DescriptorSet&&) noexcept;
  DescriptorSet(const DescriptorSet&) = delete;
  DescriptorSet& operator=(const DescriptorSet&) = delete;
  ~DescriptorSet();

  VkDescriptorSet handle() const { return set_; }
  // type: VK_DESCRIPTOR_TYPE_STORAGE_BUFFER or VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER; whole buffer.
  void write_buffer(uint32_t binding, VkDescriptorType type, const Buffer& buffer);
  // A buffer terravt does not own (a client's), from `offset` to its end.
  void write_buffer(uint32_t binding, VkDescriptorType type, VkBuffer buffer, VkDeviceSize offset);
  void write_storage_image(uint32_t binding, const Image& image);  // layout GENERAL
  // A combined image sampler over the image's default view, read in `layout`.
  void write_sampled_image(uint32_t binding, const Image& image, VkSampler sampler, VkImageLayout layout);

 private:
  friend class Context;
  VkDevice device_ = VK_NULL_HANDLE;
  const Functions* fn_ = nullptr;  // the Context's table (gpu/vk_functions.h)
  const VkAllocationCallbacks* alloc_ = nullptr;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
  void write_image(uint32_t binding, VkDescriptorType type, const VkDescriptorImageInfo& info);
  void reset();
};

}  // namespace tvt::vk
