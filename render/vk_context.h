// Headless Vulkan 1.3 context: instance, one physical device with a compute+graphics queue,
// no window or surface. RAII, move-only handles (STYLE #7).
//
// Device choice: ContextOptions::device, else the TERRAVT_DEVICE environment variable (a
// substring of the device name, case-insensitive, or an index), else the first discrete
// GPU, else the first integrated GPU, else anything (lavapipe on GPU-less machines).
// Validation: ContextOptions::validation or TERRAVT_VALIDATION=1 enables
// VK_LAYER_KHRONOS_validation with a debug-utils messenger that counts and records every
// warning and error message; tests fail when validation_messages() is non-empty.
//
// Lifetime: every Buffer, Image, ComputePipeline, GraphicsPipeline and DescriptorSet holds the context's
// VkDevice and must be destroyed (or moved from) before its Context is destroyed.
// Thread-safety: create_* and validation_messages()/clear_validation_messages() may be
// called from any thread; run_commands(), upload() and wait_idle() use the queue and the
// context's command pool, so callers serialise them with each other and with any other use
// of queue() (Vulkan external synchronisation).
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "vt/result.h"

namespace tvt::vk {

// Fatal check for Vulkan calls that must not fail (STYLE #8).
void check_result(VkResult result, const char* file, int line, const char* expr);
#define TVT_VK_CHECK(expr) ::tvt::vk::check_result((expr), __FILE__, __LINE__, #expr)

struct ContextOptions {
  bool validation = false;   // also on when TERRAVT_VALIDATION=1
  std::string device;        // overrides TERRAVT_DEVICE
};

class Context;

// A buffer with its own dedicated memory. Host-visible buffers are persistently mapped.
class Buffer {
 public:
  Buffer() = default;
  Buffer(Buffer&&) noexcept;
  Buffer& operator=(Buffer&&) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  ~Buffer();

  VkBuffer handle() const { return buffer_; }
  VkDeviceSize size() const { return size_; }
  void* mapped() const { return mapped_; }  // nullptr for device-local buffers
  explicit operator bool() const { return buffer_ != VK_NULL_HANDLE; }

 private:
  friend class Context;
  VkDevice device_ = VK_NULL_HANDLE;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize size_ = 0;
  void* mapped_ = nullptr;
  void reset();
};

// A 2D (array) image with its own memory and a default view of all layers and mip levels
// (created when the usage allows a view: sampled, storage or attachment; otherwise view() is
// VK_NULL_HANDLE).
class Image {
 public:
  Image() = default;
  Image(Image&&) noexcept;
  Image& operator=(Image&&) noexcept;
  Image(const Image&) = delete;
  Image& operator=(const Image&) = delete;
  ~Image();

  VkImage handle() const { return image_; }
  VkImageView view() const { return view_; }  // VK_IMAGE_VIEW_TYPE_2D_ARRAY over all layers
  VkFormat format() const { return format_; }
  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  uint32_t layers() const { return layers_; }
  uint32_t mip_levels() const { return mip_levels_; }
  explicit operator bool() const { return image_ != VK_NULL_HANDLE; }

 private:
  friend class Context;
  VkDevice device_ = VK_NULL_HANDLE;
  VkImage image_ = VK_NULL_HANDLE;
  VkImageView view_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkFormat format_ = VK_FORMAT_UNDEFINED;
  uint32_t width_ = 0, height_ = 0, layers_ = 0, mip_levels_ = 0;
  bool synchronization2_ = false;  // the device has synchronization2 on (transition() uses it)
  void reset();
};

// A compute pipeline with its own descriptor-set layout (storage buffers / storage images /
// uniform buffers at the given bindings, set 0) and an optional push-constant range.
struct ComputeBinding {
  uint32_t binding;
  VkDescriptorType type;
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
  void write_storage_image(uint32_t binding, const Image& image);  // layout GENERAL
  // A combined image sampler over the image's default view, read in `layout`.
  void write_sampled_image(uint32_t binding, const Image& image, VkSampler sampler, VkImageLayout layout);

 private:
  friend class Context;
  VkDevice device_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
  void write_image(uint32_t binding, VkDescriptorType type, const VkDescriptorImageInfo& info);
  void reset();
};

// Device features, queried and enabled when supported. Mandatory (create() fails without
// them): shader_int64 (composition uses 64-bit integer texel coordinates, DESIGN §3) and
// maintenance4 (required by Vulkan 1.3; glslang emits LocalSizeId when a workgroup size is a
// constant from shaders/shared/*.h, which needs it).
struct DeviceFeatures {
  bool shader_int64 = false;
  bool maintenance4 = false;                // Vulkan 1.3
  bool shader_int8 = false;                 // Vulkan 1.2
  bool storage_buffer_8bit_access = false;  // Vulkan 1.2
  bool scalar_block_layout = false;         // Vulkan 1.2
  bool synchronization2 = false;            // Vulkan 1.3
  bool dynamic_rendering = false;           // Vulkan 1.3
  bool sampler_anisotropy = false;
  bool fragment_stores_and_atomics = false;
  bool vertex_pipeline_stores_and_atomics = false;
};

class Context {
 public:
  static Result<std::unique_ptr<Context>> create(const ContextOptions& options = {});
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  ~Context();

  VkInstance instance() const { return instance_; }
  VkPhysicalDevice physical_device() const { return physical_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  uint32_t queue_family() const { return queue_family_; }
  const VkPhysicalDeviceProperties& properties() const { return properties_; }
  std::string device_name() const { return properties_.deviceName; }
  bool validation_enabled() const { return validation_; }
  const DeviceFeatures& features() const { return features_; }  // what is enabled on device()

  // Every validation (and other debug-utils warning/error) message since creation or since
  // the last clear_validation_messages().
  std::vector<std::string> validation_messages() const;
  void clear_validation_messages();

  // vkDeviceWaitIdle: everything submitted to the device has finished.
  void wait_idle();

  // host_visible: HOST_VISIBLE|HOST_COHERENT memory, mapped; else DEVICE_LOCAL.
  Buffer create_buffer(VkDeviceSize size, VkBufferUsageFlags usage, bool host_visible);
  // A 2D-array image in VK_IMAGE_LAYOUT_UNDEFINED; usage decides what it may do. mip_levels:
  // 1 ... 1 + log2(max(width, height)).
  Image create_image(VkFormat format, uint32_t width, uint32_t height, uint32_t layers, VkImageUsageFlags usage,
                     uint32_t mip_levels = 1);
  // Whether create_image() with these arguments (one mip) fits what the device allows for one
  // image: its format limits (extent, layers, maxResourceSize), the largest single allocation
  // (maxMemoryAllocationSize) and the device-local heap. The error starts with `what` and
  // gives the image's size and the limit it exceeds, in MB. create_image() itself treats
  // failure as fatal: call this first where a user's numbers set the size.
  Status check_image_fits(VkFormat format, uint32_t width, uint32_t height, uint32_t layers, VkImageUsageFlags usage,
                          const std::string& what) const;
  ComputePipeline create_compute_pipeline(std::span<const uint32_t> spirv, std::span<const ComputeBinding> bindings,
                                          uint32_t push_constant_bytes = 0);
  DescriptorSet allocate_descriptor_set(const ComputePipeline& pipeline);
  // Fatal when the device lacks dynamicRendering (Vulkan 1.3 core, always on for 1.3 devices).
  GraphicsPipeline create_graphics_pipeline(const GraphicsPipelineDesc& desc);
  DescriptorSet allocate_descriptor_set(const GraphicsPipeline& pipeline);

  // Records with `record` into a one-time command buffer, submits, waits for completion.
  // For set-up, uploads and tests; frame loops use their own command buffers and fences.
  void run_commands(const std::function<void(VkCommandBuffer)>& record);
  // Uploads bytes into a (device-local) buffer through a staging buffer.
  void upload(const Buffer& dst, const void* data, VkDeviceSize bytes, VkDeviceSize dst_offset = 0);

  // Layout transition helper (full pipeline barrier on the given image, all layers): all
  // earlier commands' writes are made visible to all later commands. Records
  // vkCmdPipelineBarrier2 when the device has synchronization2 on, else vkCmdPipelineBarrier.
  static void transition(VkCommandBuffer cmd, const Image& image, VkImageLayout from, VkImageLayout to);
  // Global memory barrier: `src_access` writes of `src_stage` become visible to `dst_access`
  // of `dst_stage` (copy chains, compute -> fragment, device -> host readbacks).
  static void memory_barrier(VkCommandBuffer cmd, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                             VkPipelineStageFlags dst_stage, VkAccessFlags dst_access);

  struct Messages;  // validation message sink (implementation detail)

 private:
  Context() = default;
  DescriptorSet allocate_set(VkDescriptorSetLayout layout, std::span<const VkDescriptorType> types);
  VkShaderModule create_shader_module(std::span<const uint32_t> spirv);
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  VkCommandPool command_pool_ = VK_NULL_HANDLE;
  VkPhysicalDeviceProperties properties_{};
  VkPhysicalDeviceMemoryProperties memory_properties_{};
  VkDeviceSize max_allocation_bytes_ = 0;  // VkPhysicalDeviceVulkan11Properties::maxMemoryAllocationSize
  bool validation_ = false;
  DeviceFeatures features_{};
  std::unique_ptr<Messages> messages_;
};

}  // namespace tvt::vk
