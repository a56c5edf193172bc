// The engine's terrain pass: a classic VkRenderPass + VkFramebuffer (colour RGBA8 + reverse-Z
// depth), its own flat chunked grid culled on the CPU and drawn in one instanced draw, its own
// descriptor set layout with terravt's three descriptors at bindings 5/6/7, and a feedback
// storage buffer per frame in flight that the fragment shader fills with page requests (compacted
// on the GPU by terravt's record_feedback(), or read back here on the CPU).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "device.h"

namespace engine {

// World: metres, z up, the terrain is [0, extent_m]^2 at z = 0. yaw 0 looks along +x, pi/2
// along +y; pitch > 0 looks up. View space x right, y up, looking down -z.
struct Camera {
  glm::dvec3 position_m{0.0};
  double yaw_rad = 0, pitch_rad = 0;
  double vertical_fov_rad = 1.0471975511965976;  // 60 degrees
  double near_m = 0.5, far_m = 100000.0;
  // Camera-relative world offsets -> Vulkan clip space, reverse-Z (depth 1 at near, 0 at far).
  glm::dmat4 clip_from_relative(double aspect) const;
};

struct TerrainPassDesc {
  uint32_t width = 640, height = 360;
  uint32_t log2_size = 16;          // the VT: 2^log2_size level-0 texels per side
  double extent_m = 8192;           // the terrain's side in metres (the engine's own knowledge)
  uint32_t chunks_per_side = 16;    // power of two
  uint32_t quads_per_chunk = 32;    // power of two
  uint32_t feedback_divisor = 8;    // one request per N x N pixel block, a rotating pixel per frame
  uint32_t frames_in_flight = 2;
  // true: the feedback buffers are host-visible and read_requests() reads them (the CPU route);
  // false: device-local, read only on the GPU by terravt's record_feedback().
  bool feedback_on_host = false;
  terravt::VirtualTextureBindings vt;
};

// The feedback texels of a width x height image with one request per divisor x divisor block
// (what VirtualTextureDesc::feedback_texels must be for the GPU route).
inline uint32_t feedback_texel_count(uint32_t width, uint32_t height, uint32_t divisor) {
  return ((width + divisor - 1) / divisor) * ((height + divisor - 1) / divisor);
}

class TerrainPass {
 public:
  static std::unique_ptr<TerrainPass> create(Device& device, const TerrainPassDesc& desc, std::string& error);
  ~TerrainPass();

  // The level-0 texel under the camera (what terravt's begin_frame() centres its windows on).
  glm::dvec2 camera_texel(const Camera& camera) const;
  // Records the pass for `camera` with the resources of frame-in-flight `slot` (whose previous
  // frame the caller has waited for): feedback cleared (after earlier fragment writes and
  // compute reads of it), chunks culled and drawn, and with feedback_on_host the feedback made
  // visible to the host. `frame` picks the rotating feedback pixel.
  void record(VkCommandBuffer cmd, uint32_t slot, uint64_t frame, const Camera& camera);
  // The feedback buffer of `slot`: feedback_texel_count() texels of two uint32 words.
  VkBuffer feedback_buffer(uint32_t slot) const { return slots_[slot].feedback.buffer; }
  // Copies the colour image and terravt's page table into host buffers (the last frame).
  void record_readback(VkCommandBuffer cmd, VkBuffer table, VkDeviceSize table_bytes);
  // The page requests of the frame last recorded in `slot` (its fence has signalled): one per
  // distinct page, weight = the feedback pixels that asked for it, sorted by (mip, y, x).
  // Only with feedback_on_host (empty otherwise).
  std::vector<terravt::PageRequest> read_requests(uint32_t slot) const;
  // After record_readback()'s frame completed: RGBA8 rows top to bottom, and the table bytes.
  std::vector<uint8_t> colour_rgba() const;
  std::vector<uint8_t> table_bytes() const;
  uint32_t drawn_chunks() const { return drawn_; }

 private:
  explicit TerrainPass(Device& device) : dev_(device) {}
  Device& dev_;
  TerrainPassDesc desc_;
  double metres_per_texel_ = 1;
  uint32_t quad_texels_ = 1;
  uint32_t fb_width_ = 0, fb_height_ = 0;  // feedback texels
  uint32_t index_count_ = 0, drawn_ = 0;
  Image colour_, depth_;
  VkRenderPass render_pass_ = VK_NULL_HANDLE;
  VkFramebuffer framebuffer_ = VK_NULL_HANDLE;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout pipeline_layout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  Buffer vertices_, indices_;
  struct Slot {
    Buffer frame, instances;  // host-visible: written by the CPU
    Buffer feedback;          // host-visible only with feedback_on_host
    VkDescriptorSet set = VK_NULL_HANDLE;
  };
  std::vector<Slot> slots_;
  Buffer colour_readback_, table_readback_;
};

}  // namespace engine
