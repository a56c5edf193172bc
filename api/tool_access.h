// terravt's own tools and tests on the public API (never installed). terravt's renderer, its
// frame loop and its benchmarks are clients of terravt::VirtualTexture like an engine: they run
// the VT through VirtualTexture::create, begin_frame, record and record_feedback, on the device
// they made (vk::Context::device_handles()). What they need beyond an engine comes from here:
//   * create_virtual_texture(): a VirtualTexture over scene assets the tool already holds (a
//     scene the CLI changed, e.g. --hex) with every runtime option (stored-page loader threads,
//     synchronous loads, pinned mips), instead of a scene file and VirtualTextureDesc's subset;
//   * runtime(): the runtime under a VirtualTexture, for the statistics, debug views and
//     read-backs the CLI reports (composed and loaded pages, residency, cache atlas).
// A tool that drives the runtime through runtime() directly (begin_frame/record) bypasses the
// frame protocol: it may only read from it.
#pragma once
#include <memory>

#include "compose/packed_scene.h"
#include "compose/scene_assets.h"
#include "render/vt_system.h"
#include "terravt/virtual_texture.h"

namespace terravt::detail {

struct ToolVirtualTexture {
  const tvt::SceneAssets* assets = nullptr;  // required; must outlive the VirtualTexture
  tvt::Method method = tvt::Method::FbpbDpt;
  tvt::MipStrategy mip_strategy;
  // Every runtime option; its frames_in_flight is the VirtualTexture's. A store without
  // scene_hash gets the scene's identity (checked against the store's).
  tvt::VtSystemOptions runtime;
  uint32_t feedback_texels = 0;  // VirtualTextureDesc::feedback_texels
  VkPipelineStageFlags consumer_stages = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;
};

Result<std::unique_ptr<VirtualTexture>> create_virtual_texture(const DeviceHandles& device,
                                                               const ToolVirtualTexture& desc);

struct Access {
  static tvt::VtSystem& runtime(VirtualTexture& vt);
  static uint32_t feedback_texels(const VirtualTexture& vt);  // VirtualTextureDesc::feedback_texels
  static Result<std::unique_ptr<VirtualTexture>> make_for_tool(const DeviceHandles& device, const ToolVirtualTexture& desc);
  // The shared end of create() and create_virtual_texture() (api/virtual_texture.cpp).
  static Result<std::unique_ptr<VirtualTexture>> make(const DeviceHandles& device, std::unique_ptr<VirtualTexture::Impl> impl,
                                                      tvt::Method method, tvt::MipStrategy strategy, tvt::VtSystemOptions o);
};
inline tvt::VtSystem& runtime(VirtualTexture& vt) { return Access::runtime(vt); }

}  // namespace terravt::detail
