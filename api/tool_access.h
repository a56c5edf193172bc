// What terravt's own code needs of a VirtualTexture beyond the public API (never installed).
// terravt's renderer, its frame loop and its benchmarks are clients of terravt::VirtualTexture
// like an engine: they run the VT through begin_frame, record and record_feedback on the
// device they made (vk::Context::device_handles()). From here they get:
//   * make(): the one constructor every VirtualTexture goes through, with every runtime option
//     (stored-page loader threads, synchronous loads, pinned mips) and the producer or its
//     factory; the tools' scene VTs (api/compose/tool_vt.h) are made with it;
//   * runtime(): the runtime under a VirtualTexture, for the statistics, debug views and
//     read-backs the CLI reports (composed and loaded pages, residency, cache atlas).
// A tool that drives the runtime through runtime() directly (begin_frame/record) bypasses the
// frame protocol: it may only read from it.
#pragma once
#include <memory>

#include "render/vt_system.h"
#include "terravt/virtual_texture.h"
#include "vt/vt_config.h"

namespace terravt::detail {

struct Access {
  static tvt::VtSystem& runtime(VirtualTexture& vt);
  static uint32_t feedback_texels(const VirtualTexture& vt);  // VirtualTextureDesc::feedback_texels
  // The checks every entry point makes first: the desc's enums and stages, then the device.
  static Status check_desc(const DeviceHandles& device, const VirtualTextureDesc& desc);
  // A VirtualTexture with geometry `config` whose pages come from desc.producer (a client's,
  // adapted), else o.producer, else o.make_producer. desc's public options (cache_slots,
  // page_budget, window_pages, frames_in_flight) replace o's; o adds the others.
  static Result<std::unique_ptr<VirtualTexture>> make(const DeviceHandles& device, const VirtualTextureDesc& desc,
                                                      const tvt::VtConfig& config, tvt::VtSystemOptions o);
};
inline tvt::VtSystem& runtime(VirtualTexture& vt) { return Access::runtime(vt); }

}  // namespace terravt::detail
