// The Vulkan device terravt works on, and the factory of its resources. terravt never owns the
// device a Context runs on:
//   * Context::adopt(handles) runs on a client's device (an engine's); the client keeps
//     creating, waiting on and destroying it.
//   * Context::create(options) is the helper terravt's own tools and tests use: it makes an
//     instance and a device (gpu/device_setup.h), then adopts them like any client's, and
//     destroys them after the Context. One runtime path for both.
// Every create/destroy passes the client's allocation callbacks. Move-only RAII handles
// (gpu/resources.h, gpu/pipelines.h); barriers in gpu/barriers.cpp; one-shot submission
// (run_commands, upload) in gpu/commands.cpp.
//
// Lifetime: every Buffer, Image, pipeline and DescriptorSet holds the context's VkDevice and
// must be destroyed (or moved from) before its Context is destroyed, once the GPU is done with
// it. An adopted Context's destructor destroys only what terravt made and never waits.
// Thread-safety: create_* and validation_messages()/clear_validation_messages() may be
// called from any thread; run_commands(), upload() and wait_idle() use the queue and the
// context's command pool, so callers serialise them with each other and with any other use
// of queue() (Vulkan external synchronisation).
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "gpu/pipelines.h"
#include "gpu/resources.h"
#include "gpu/vk_util.h"
#include "gpu/vk_functions.h"
#include "terravt/device.h"
#include "vt/result.h"

namespace tvt::vk {

// What Context::create() made for terravt's own tools and tests (gpu/device_setup.h): the
// instance and device, destroyed after the Context's own objects. An interface so that the
// library proper (libterravt) never links the code that creates devices, nor the Vulkan loader.
class DeviceOwner {
 public:
  virtual ~DeviceOwner() = default;
  virtual bool validation() const = 0;
  virtual std::vector<std::string> messages() const = 0;
  virtual void clear_messages() = 0;
  // The handles the Context adopted (enabled_features points into the owner).
  virtual terravt::DeviceHandles handles() const = 0;
};

// For Context::create(): which device to make (see gpu/device_setup.h).
struct ContextOptions {
  bool validation = false;  // VK_LAYER_KHRONOS_validation + synchronisation validation, messages recorded
  std::string device;       // a case-insensitive substring of the device name, or its index; empty: the best
  std::string device_source = "the device choice";  // what set `device`, for error messages ("--gpu")
  std::string validation_source = "validation";     // what turned validation on, for error messages
  terravt::LogCallback log;  // validation and driver messages also go here (may be empty)
};

// Device features terravt uses, as enabled on the device (terravt::device_requirements()
// lists them with what each is for). shader_int64 and maintenance4 are always true: a device
// without them is refused.
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

// What `chain` (a VkDeviceCreateInfo::pNext chain headed by VkPhysicalDeviceFeatures2) enables.
DeviceFeatures enabled_features(const VkPhysicalDeviceFeatures2& chain);

class Context {
 public:
  // Runs on the client's device after terravt::check_device(handles) passed.
  static Result<std::unique_ptr<Context>> adopt(const terravt::DeviceHandles& handles);
  // Makes an instance and device for terravt's own tools and tests, and adopts them. Defined
  // in gpu/device_setup.cpp (target terravt_device_setup, which links the Vulkan loader).
  static Result<std::unique_ptr<Context>> create(const ContextOptions& options = {});
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  ~Context();

  VkInstance instance() const { return instance_; }
  VkPhysicalDevice physical_device() const { return physical_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  // terravt's private function table for this device (gpu/vk_functions.h), loaded through the
  // client's vkGetInstanceProcAddr. Valid as long as the Context.
  const Functions& fn() const { return fn_; }
  uint32_t queue_family() const { return queue_family_; }
  const VkAllocationCallbacks* allocation_callbacks() const { return alloc_; }
  const VkPhysicalDeviceProperties& properties() const { return properties_; }
  // Mask of the bits a timestamp of the context's queue counts (timestampValidBits), 0 where
  // the queue family does not count them or the device gives no period: then no timestamps.
  uint64_t timestamp_mask() const { return timestamp_mask_; }
  std::string device_name() const { return properties_.deviceName; }
  const DeviceFeatures& features() const { return features_; }  // what is enabled on device()
  // Sends a diagnostic to the client's log callback (dropped when there is none).
  void log(terravt::LogLevel level, const std::string& message) const;

  // Made by create() (terravt's own device, which it may wait on), not adopt() (a client's,
  // which terravt never waits on).
  bool owns_device() const { return owned_ != nullptr; }
  // The handles of a device made by create(), to hand to terravt's public API
  // (terravt::VirtualTexture::create) exactly as an engine hands in its own: terravt's tools
  // run the VT on their device through that one path. An adopted device's handles are the
  // client's: invalid_argument. Defined in gpu/device_setup.cpp, with create().
  Result<terravt::DeviceHandles> device_handles() const;

  // Validation: only a Context made by create() with validation on records messages.
  bool validation_enabled() const;
  // Every validation (and other debug-utils warning/error) message since creation or since
  // the last clear_validation_messages().
  std::vector<std::string> validation_messages() const;
  void clear_validation_messages();

  // Vulkan failures are errors, never aborts. The first of terravt's Vulkan calls on this
  // context that fails (out of memory, device lost, a GPU that has not finished a wait within
  // 60 s) is latched here and stays: from then on create_* hand back empty handles,
  // run_commands() and upload() do nothing, and every runtime entry point (VtSystem::create and
  // record, terravt::VirtualTexture, the frame loop) returns this error. What was made before
  // stays valid to destroy. Thread-safe.
  Status status() const;
  // Latches `result` of `call` (its source text) when it is a failure; true on VK_SUCCESS.
  // TVT_VK_OK(context, expr) passes the expression's text.
  bool ok(VkResult result, const char* call) const;

  // vkDeviceWaitIdle: everything submitted to the device has finished. For terravt's own
  // tools and tests; library code never calls it on a client's device.
  void wait_idle();

  // host_visible: HOST_VISIBLE|HOST_COHERENT memory, mapped; else DEVICE_LOCAL.
  Buffer create_buffer(VkDeviceSize size, VkBufferUsageFlags usage, bool host_visible);
  // A 2D-array image in VK_IMAGE_LAYOUT_UNDEFINED; usage decides what it may do. mip_levels:
  // 1 ... 1 + log2(max(width, height)).
  Image create_image(VkFormat format, uint32_t width, uint32_t height, uint32_t layers, VkImageUsageFlags usage,
                     uint32_t mip_levels = 1);
  // Someone else's 2D-array image (one mip) and its view, as an Image that never destroys them
  // (e.g. the VT cache a producer plug-in is handed).
  static Image borrow_image(VkImage image, VkImageView view, VkFormat format, uint32_t width, uint32_t height,
                            uint32_t layers);
  // Whether create_image() with these arguments (one mip) fits what the device allows for one
  // image: its format limits (extent, layers, maxResourceSize), the largest single allocation
  // (maxMemoryAllocationSize) and the device-local heap. The error starts with `what` and
  // gives the image's size and the limit it exceeds, in MB. create_image() only latches a
  // failed allocation (status()): call this first where a user's numbers set the size.
  Status check_image_fits(VkFormat format, uint32_t width, uint32_t height, uint32_t layers, VkImageUsageFlags usage,
                          const std::string& what) const;
  // `constants`: specialization constants of the compute stage (constant_id, 32-bit value).
  ComputePipeline create_compute_pipeline(std::span<const uint32_t> spirv, std::span<const ComputeBinding> bindings,
                                          uint32_t push_constant_bytes = 0,
                                          std::span<const SpecConstant> constants = {});
  DescriptorSet allocate_descriptor_set(const ComputePipeline& pipeline);
  // Needs dynamicRendering (Vulkan 1.3 core, always on for 1.3 devices; latched as an error
  // otherwise).
  GraphicsPipeline create_graphics_pipeline(const GraphicsPipelineDesc& desc);
  DescriptorSet allocate_descriptor_set(const GraphicsPipeline& pipeline);
  // A sampler made with the context's allocation callbacks; destroy it with destroy_sampler().
  VkSampler create_sampler(const VkSamplerCreateInfo& info);
  void destroy_sampler(VkSampler sampler);

  // Records with `record` into a one-time command buffer, submits, waits for completion.
  // For set-up, uploads and tests; frame loops use their own command buffers and fences.
  // While set-up is deferred (below), `record` is kept and recorded later instead: it must then
  // capture nothing by reference that dies before record_deferred_setup().
  void run_commands(const std::function<void(VkCommandBuffer)>& record);
  // run_commands() for benchmarks: returns the seconds the device spent between the start and
  // the end of `record`'s commands, from two timestamps when the queue family counts them, else
  // the wall clock of submit + wait. Never deferred; a failed call is in status().
  double run_commands_timed(const std::function<void(VkCommandBuffer)>& record);

  // Set-up in the client's command buffer (a client never has terravt submit on its queue):
  // from defer_setup() on, run_commands() and upload() submit nothing; upload() copies its
  // bytes into a staging buffer at once and both queue their commands, which
  // record_deferred_setup(cmd) records in order into `cmd`, ending with a barrier that makes
  // them visible to every later command. The staging lives until release_deferred_staging()
  // (call it once the GPU has finished `cmd`).
  void defer_setup() { deferring_ = true; }
  bool has_deferred_setup() const { return !deferred_.empty(); }
  void record_deferred_setup(VkCommandBuffer cmd);
  void release_deferred_staging() { deferred_staging_.clear(); }
  // Uploads bytes into a (device-local) buffer through a staging buffer.
  void upload(const Buffer& dst, const void* data, VkDeviceSize bytes, VkDeviceSize dst_offset = 0);

  // Layout transition helper (full pipeline barrier on the given image, all layers): all
  // earlier commands' writes are made visible to all later commands. Records
  // vkCmdPipelineBarrier2 when the device has synchronization2 on, else vkCmdPipelineBarrier.
  void transition(VkCommandBuffer cmd, const Image& image, VkImageLayout from, VkImageLayout to) const;
  // Global memory barrier: `src_access` writes of `src_stage` become visible to `dst_access`
  // of `dst_stage` (copy chains, compute -> fragment, device -> host readbacks).
  void memory_barrier(VkCommandBuffer cmd, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                             VkPipelineStageFlags dst_stage, VkAccessFlags dst_access) const;

 private:
  Context() = default;
  uint32_t memory_type(uint32_t allowed, VkMemoryPropertyFlags need, VkMemoryPropertyFlags fallback) const;
  DescriptorSet allocate_set(VkDescriptorSetLayout layout, std::span<const VkDescriptorType> types);
  VkShaderModule create_shader_module(std::span<const uint32_t> spirv);
  // Destroyed last: the instance and device of a Context made by create() (null when adopted).
  std::unique_ptr<DeviceOwner> owned_;
  VkInstance instance_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  Functions fn_;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  const VkAllocationCallbacks* alloc_ = nullptr;
  terravt::LogCallback log_;
  VkCommandPool command_pool_ = VK_NULL_HANDLE;
  bool deferring_ = false;
  std::vector<std::function<void(VkCommandBuffer)>> deferred_;
  std::vector<Buffer> deferred_staging_;
  VkPhysicalDeviceProperties properties_{};
  uint64_t timestamp_mask_ = 0;
  VkPhysicalDeviceMemoryProperties memory_properties_{};
  VkDeviceSize max_allocation_bytes_ = 0;  // VkPhysicalDeviceVulkan11Properties::maxMemoryAllocationSize
  DeviceFeatures features_{};
  mutable std::mutex fault_mutex_;
  mutable std::optional<Error> fault_;  // the first failed Vulkan call (status())
};

}  // namespace tvt::vk
