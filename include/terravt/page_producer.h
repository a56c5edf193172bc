// A client's page producer: a plug-in that makes the pages terravt's residency asks for, in
// place of terravt's own composer or stored megatexture (VirtualTextureDesc::producer). It
// records its work into the client's command buffer during VirtualTexture::record(); terravt
// then maps what it wrote in the page table and places the barriers around it.
//
// Per frame, on the thread that drives the VirtualTexture:
//   begin_frame(frame)        the frame begun desc.frames_in_flight begin_frame() calls earlier
//                             has completed on the GPU: what it read from host memory may be
//                             reused (frame numbers increase but may skip: count the calls)
//   request(task) ...         the pages wanted, most important first; answer accepted (written
//                             by this or a later record()), busy (none more this frame: asked
//                             again next frame) or unavailable (this page never: its nearest
//                             resident ancestor stands in)
//   cancel(task)              terravt no longer wants an accepted page: do not write its slot
//                             for it any more (the slot goes to another page)
//   finish()                  block until every accepted page can be written or has failed
//                             (called when the coarsest, always-resident pages are requested)
//   record(cmd, written, failed)
//                             record the writes of the accepted pages that are ready, list them
//                             in `written`, and list in `failed` those that will never be made
//                             (their ancestors stand in); the rest stay outstanding
//
// Writing a page: layer `slot` of the cache image, (P + 2B)^2 RGBA8 texels, rgb the albedo and
// a the height; texel (i, j) of the layer is level-`mip` texel (x·P + i − B, y·P + j − B),
// borders included (clamp to the terrain at its edges). The cache stays in
// VK_IMAGE_LAYOUT_GENERAL. Write with compute-shader stores (VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT)
// or transfer commands (VK_PIPELINE_STAGE_TRANSFER_BIT): terravt's barriers before and after
// record() cover exactly these stages, so no barrier of the producer's own is needed for the
// cache. A producer must not write a slot it was not handed in request().
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <vector>

#include "terravt/error.h"
#include "terravt/export.h"

namespace terravt {

// A page and the cache slot it goes to.
struct PageTask {
  uint32_t mip = 0, x = 0, y = 0;  // page column and row at mip `mip`
  uint32_t slot = 0;               // cache layer
  friend bool operator==(const PageTask&, const PageTask&) = default;
};

// What a producer writes into, handed to attach() once, before the first frame.
struct ProducerTarget {
  VkImage cache = VK_NULL_HANDLE;          // RGBA8_UNORM 2D array, one layer per slot; usage
                                           // STORAGE | TRANSFER_DST | SAMPLED | TRANSFER_SRC
  VkImageView cache_view = VK_NULL_HANDLE; // 2D-array view of every layer (a storage image binding)
  VkFormat format = VK_FORMAT_R8G8B8A8_UNORM;
  uint32_t slots = 0;          // layers
  uint32_t slot_texels = 0;    // P + 2B texels per layer side
  uint32_t page_texels = 0;    // P
  uint32_t border_texels = 0;  // B
  uint32_t log2_size = 0;      // level 0 is 2^log2_size texels per side
  uint32_t mip_count = 0;
  uint32_t frames_in_flight = 0;
};

enum class ProducerAccept { accepted, busy, unavailable };

class TERRAVT_API PageProducer {
 public:
  virtual ~PageProducer();
  // Once, from VirtualTexture::create(); an error fails create().
  virtual Status attach(const ProducerTarget& /*target*/) { return Ok{}; }
  virtual void begin_frame(uint64_t /*frame*/) {}
  virtual ProducerAccept request(const PageTask& task) = 0;
  virtual void cancel(const PageTask& /*task*/) {}
  virtual void finish() {}
  // `written` and `failed` arrive empty. An error returned here is handed to the client by
  // VirtualTexture::record() after the frame is completed (list the pages it concerns in
  // `failed`): as ErrorKind::producer_failed, except a failed Vulkan call (vk_result set, or
  // kind vulkan or device_lost), which keeps its kind and stays: every later call returns it.
  virtual Status record(VkCommandBuffer cmd, std::vector<PageTask>& written, std::vector<PageTask>& failed) = 0;
  // New virtual functions go last: a producer built against an earlier 0.x keeps its vtable.
  // The most pages it wants offered in one frame, asked once by VirtualTexture::create()
  // (before attach()); 0: VirtualTextureDesc::page_budget. A loader that keeps reads in flight
  // across frames may want more than it writes in one. At most the cache's slots are offered.
  virtual uint32_t requests_per_frame() const { return 0; }
};

}  // namespace terravt
