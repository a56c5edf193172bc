// The virtual texture on a client's device: residency, page production into the physical
// cache and the page table, recorded into the client's command buffers.
//
// One frame (the client's render loop, one thread):
//   vt->begin_frame(frame, completed, camera_texel_x, camera_texel_y, requests);  // CPU only
//   vt->record(cmd);           // production + page-table update + barriers, into `cmd`
//   ... the client's passes that sample through terravt/vt.glsl, bound from bindings() ...
//   submit `cmd` on the queue family given at create(), with the client's own fences
// `requests` are the pages the client's view wants (from its feedback pass, read back as the
// client likes, or computed on the CPU); every ancestor of a requested page is requested too.
//
// Frames in flight: `frame` increases from call to call; `completed` is the newest frame whose
// commands the client knows have finished on the GPU (std::nullopt before the first does). At
// most frames_in_flight frames may be begun and not completed: terravt reuses what older frames
// read only then. Misuse — frames out of order, `completed` going backwards or not yet begun,
// too many frames in flight, record() twice or without begin_frame() — is an error
// (ErrorKind::misuse) and changes nothing.
//
// Synchronisation (desc.record_barriers; or placed by the client from dependencies()): record() first waits (execution dependency) for reads of the cache, table
// and description by earlier frames' `consumer_stages`, then writes them with compute and
// transfer commands, then makes the writes visible to `consumer_stages` of the commands
// recorded after it in the same queue. The cache stays in VK_IMAGE_LAYOUT_GENERAL.
// Set-up: create() submits nothing and waits for nothing; its uploads (the initial page table,
// the description) and layout transitions are recorded at the start of the first record() (or
// record_feedback()), so the bindings hold defined data from that frame's commands on.
//
// Threading: one thread calls a VirtualTexture at a time. Destroy it only once the GPU has
// finished every command buffer it recorded into.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>
#include <span>
#include <string>

#include "terravt/device.h"
#include "terravt/error.h"
#include "terravt/export.h"
#include "terravt/page_producer.h"

namespace terravt {

namespace detail {
struct Access;  // terravt's own tools (not part of the API)
}

enum class PageSource {
  composed,  // every page composed by terravt's compute shader from the scene's materials (compose component)
  stored,    // every page read from a baked store (store_file); a missing or bad page falls back to its ancestor
  hybrid,    // stored where the store has a good page, composed elsewhere (compose component)
};

// The VT's geometry: level 0 is 2^log2_size texels a side (10 ... 30), pages hold page_texels
// (a power of two, 16 ... 1024) plus border_texels (at most page_texels / 2) on every side.
struct VirtualTextureLayout {
  uint32_t log2_size = 0;  // 0: from the scene (compose component) or the store
  uint32_t page_texels = 128;
  uint32_t border_texels = 4;
};

// What a VirtualTexture is made from. Two entry points take it:
//   * VirtualTexture::create() (libterravt, terravt::terravt): pages from a baked store
//     (source stored, geometry from the store) or from a client's producer (geometry from
//     `layout`). It reads no scene and links no image or scene library: a scene_file and the
//     composed and hybrid sources are refused there (invalid_argument, naming the compose
//     component); method and mip_strategy, which only say how a scene is composed, are unused.
//   * terravt::compose::create_virtual_texture() (terravt/compose.h, libterravt_compose,
//     terravt::compose): everything, from a scene: composed, stored (the store checked against
//     the scene) and hybrid pages, or a client's producer over the scene's geometry.
struct VirtualTextureDesc {
  // The scene and how it is composed: compose component only.
  std::string scene_file;            // JSON scene (docs/scene-format.md); empty: the built-in scene
  std::string method = "fbpb+dpt2";  // transition method: linear, blendmap, fbpb, dpt1, dpt2, fbpb+dpt2
  // How composed pages of mip >= 1 are made: "direct" (one sample per texel), "prefiltered" (one
  // sample per texel, with the expected coverage of the DPT patches, FBPB features and blend-map
  // heights smaller than the texel) or "supersample:S" (up to S x S samples per texel, S a power
  // of two 2 ... 64, never more than the level-0 texels a texel covers); mip 0 is the same under
  // each. prefiltered (the default) costs about what direct costs and is closer to the
  // box-filtered level-0 composition at coarse mips; supersample:S is closer still at mips up to
  // about log2(S) + 1, at S^2 times the cost.
  std::string mip_strategy = "prefiltered";
  PageSource source = PageSource::composed;
  std::string store_file;            // the baked store, for stored and hybrid
  // Set: this producer makes every page instead of `source` (terravt/page_producer.h). Shared:
  // the client may keep it to drive or inspect.
  std::shared_ptr<PageProducer> producer;
  // The geometry. Required by VirtualTexture::create() with a producer; otherwise left at
  // log2_size 0 it comes from the scene or the store, and set it must equal theirs.
  VirtualTextureLayout layout;
  uint32_t cache_slots = 256;        // pages the physical cache holds
  uint32_t page_budget = 32;         // pages composed per frame at most
  uint32_t window_pages = 64;        // page-table window per mip, entries per side
  uint32_t frames_in_flight = 2;     // 1 ... 8
  // > 0: record_feedback() compacts, on the GPU, a client buffer of this many feedback texels
  // (two uint32 words each, written with terravt_feedback() by the client's pass); 0: page
  // requests come only as the CPU list given to begin_frame().
  uint32_t feedback_texels = 0;
  // Stages of the client's passes that read the VT (fragment by default; vertex or compute too).
  VkPipelineStageFlags consumer_stages = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;
  // true: record() records the barriers between the client's consumer stages and its own work.
  // false: it records none of them; the client (a render graph) places dependencies() itself,
  // `before` ahead of record()'s commands and `after` between them and the first consumer.
  bool record_barriers = true;
};

// The two dependencies between the client's consumer stages and terravt's work, as a render
// graph places them (vkCmdPipelineBarrier2; synchronization2). The pointers inside stay valid
// as long as the VirtualTexture.
struct VirtualTextureDependencies {
  VkDependencyInfo before{};  // earlier frames' consumer reads -> this frame's compute/transfer writes
  VkDependencyInfo after{};   // this frame's compute/transfer writes -> consumer shader reads
};

struct VirtualTextureInfo {
  uint32_t log2_size = 0;      // V = 2^log2_size level-0 texels per side
  uint32_t page_texels = 0;    // P, payload texels per page side
  uint32_t border_texels = 0;  // B, border texels on every side of a page
  uint32_t mip_count = 0;
  uint32_t cache_slots = 0;
};

// What terravt/vt.glsl binds (TERRAVT_VT_BINDING_INFO, _TABLE, _CACHE).
struct VirtualTextureBindings {
  VkBuffer info_buffer = VK_NULL_HANDLE;   // storage buffer, whole range
  VkDeviceSize info_bytes = 0;
  VkBuffer table_buffer = VK_NULL_HANDLE;  // storage buffer, whole range
  VkDeviceSize table_bytes = 0;
  VkImageView cache_view = VK_NULL_HANDLE; // 2D array view of the cache
  VkSampler cache_sampler = VK_NULL_HANDLE;
  VkImageLayout cache_layout = VK_IMAGE_LAYOUT_GENERAL;
};

// One page a view wants: mip, page column and row at that mip; `weight` ranks requests (e.g.
// the pixels that asked for it).
struct PageRequest {
  uint32_t mip = 0, x = 0, y = 0;
  uint32_t weight = 1;
};

struct FrameStats {
  uint32_t produced = 0;       // pages that became resident this frame
  uint32_t failed = 0;         // pages that could not be produced (their ancestors stand in)
  uint32_t table_updates = 0;  // page-table entries rewritten
  uint32_t resident = 0;       // pages in the cache after this frame
  // GPU feedback (record_feedback()) that joined this frame's requests: the compaction of the
  // newest completed frame that recorded one. A frame whose `completed` brings no newer
  // compaction reuses the newest one read, so requests keep flowing while the GPU catches up.
  bool gpu_feedback = false;    // some did (false until the first compaction was read)
  uint32_t feedback_pages = 0;  // its distinct pages
  uint64_t feedback_frame = 0;  // the frame that recorded it (valid when gpu_feedback)
};

class TERRAVT_API VirtualTexture {
 public:
  static Result<std::unique_ptr<VirtualTexture>> create(const DeviceHandles& device, const VirtualTextureDesc& desc);
  ~VirtualTexture();
  VirtualTexture(const VirtualTexture&) = delete;
  VirtualTexture& operator=(const VirtualTexture&) = delete;

  VirtualTextureInfo info() const;
  VirtualTextureBindings bindings() const;
  // The barriers record() places itself when desc.record_barriers is true.
  const VirtualTextureDependencies& dependencies() const;

  // CPU only. camera_texel_*: the level-0 texel under the camera (the page-table windows
  // centre there; clamped to the terrain).
  Status begin_frame(uint64_t frame, std::optional<uint64_t> completed_frame, int64_t camera_texel_x,
                     int64_t camera_texel_y, std::span<const PageRequest> requests);
  // Records this frame's GPU work into `cmd` (a primary command buffer in the recording state,
  // of the queue family given at create()). A page the producer cannot make fails
  // (ErrorKind::producer_failed: e.g. the compose component's material that cannot be loaded,
  // naming the file); the frame is still complete and usable. A failed Vulkan call, terravt's
  // or the producer's, keeps its kind and is returned by every later call.
  Status record(VkCommandBuffer cmd);
  // Records into `cmd` the GPU compaction of the client's feedback buffer (STORAGE_BUFFER usage,
  // desc.feedback_texels texels of 8 bytes from `offset`, cleared to 0xffffffff and written by
  // the client's pass earlier in `cmd` or in an earlier submission on the same queue; terravt
  // places the barrier after those writes). At most once per frame, after begin_frame() (before
  // or after record()). Its distinct pages, each weighted by the texels that asked for it, join
  // the requests of every begin_frame() from the first whose `completed` frame is this one or
  // newer, until a newer completed frame's feedback replaces it (FrameStats::gpu_feedback).
  // `offset` must be a multiple of the device's minStorageBufferOffsetAlignment (else
  // invalid_argument, nothing recorded).
  Status record_feedback(VkCommandBuffer cmd, VkBuffer feedback, VkDeviceSize offset = 0);
  const FrameStats& stats() const;

 private:
  friend struct detail::Access;
  struct Impl;
  explicit VirtualTexture(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace terravt
