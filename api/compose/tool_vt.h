// terravt's own tools and tests on the public API (never installed): a VirtualTexture over scene
// assets the tool already holds (a scene the CLI changed in memory, e.g. --hex or --method),
// with every runtime option (stored-page loader threads, synchronous loads, pinned mips),
// instead of a scene file and VirtualTextureDesc's subset. Its pages come from the built-in
// producers directly (composer/builtin_producers.h), so the runtime's statistics the CLI prints
// (composed, loaded, material uploads) stay whole; api/tool_access.h reads them.
#pragma once
#include <memory>

#include "api/tool_access.h"
#include "compose/packed_scene.h"
#include "compose/scene_assets.h"
#include "composer/builtin_producers.h"
#include "terravt/virtual_texture.h"

namespace terravt::detail {

struct ToolVirtualTexture {
  const tvt::SceneAssets* assets = nullptr;  // required; must outlive the VirtualTexture
  tvt::Method method = tvt::Method::FbpbDpt;
  tvt::MipStrategy mip_strategy;
  // Every runtime option and the built-in source; its frames_in_flight is the VirtualTexture's.
  // A store without scene_hash gets the scene's identity (checked against the store's).
  tvt::SceneVtOptions runtime;
  uint32_t feedback_texels = 0;  // VirtualTextureDesc::feedback_texels
  VkPipelineStageFlags consumer_stages = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;
};

Result<std::unique_ptr<VirtualTexture>> create_virtual_texture(const DeviceHandles& device,
                                                               const ToolVirtualTexture& desc);

}  // namespace terravt::detail
