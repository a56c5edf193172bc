// The scene side of a VirtualTexture, shared by the compose component's public entry point
// (terravt::compose::create_virtual_texture, api/compose/compose_vt.cpp) and terravt's tools
// (api/compose/tool_vt.h): the scene packed for a method and mip strategy, and the store a
// stored or hybrid source reads, checked against the scene it was baked from.
#pragma once
#include <memory>
#include <string>

#include "compose/packed_scene.h"
#include "compose/scene_assets.h"
#include "streaming/page_store.h"
#include "terravt/error.h"
#include "terravt/virtual_texture.h"
#include "vt/vt_config.h"

namespace terravt::detail {

// The scene a VirtualTextureDesc names (scene_file, or the built-in scene) with its method and
// mip strategy; errors name the desc's field or the scene file's.
struct DescScene {
  tvt::SceneAssets assets;
  tvt::Method method = tvt::Method::FbpbDpt;
  tvt::MipStrategy strategy;
};
Status check_scene_fields(const VirtualTextureDesc& desc);  // method and mip_strategy
Result<DescScene> load_desc_scene(const VirtualTextureDesc& desc);

// Opens `path` and checks it against the scene: geometry, page format and scene identity
// (scene + method + mip strategy, for the store's pyramid). Errors name the store and field.
Result<std::shared_ptr<const tvt::PageStoreReader>> open_scene_store(const std::string& path,
                                                                     const tvt::SceneAssets& assets, tvt::Method method,
                                                                     tvt::MipStrategy strategy);

// An internal error as the compose component returns it: a failed Vulkan call keeps its kind,
// and so does running out of memory where `keep_memory` (nothing is made, or nothing half
// done); anything else gets `otherwise`.
inline Error as_error(const Error& e, ErrorKind otherwise, bool keep_memory = true) {
  if (e.vk_result != 0 || e.kind == ErrorKind::vulkan || e.kind == ErrorKind::device_lost) return e;
  if (keep_memory && e.kind == ErrorKind::out_of_memory) return e;
  return Error{otherwise, e.message};
}

}  // namespace terravt::detail
