#include "api/compose/tool_vt.h"

#include "compose/scene_identity.h"

namespace terravt::detail {

Result<std::unique_ptr<VirtualTexture>> create_virtual_texture(const DeviceHandles& device,
                                                               const ToolVirtualTexture& td) {
  const auto invalid = [](std::string m) { return Error{ErrorKind::invalid_argument, std::move(m)}; };
  if (!td.assets) return invalid("create_virtual_texture(): no scene assets");
  VirtualTextureDesc d;  // the public subset, as the runtime options set it
  d.cache_slots = td.runtime.cache_slots;
  d.page_budget = td.runtime.page_budget;
  d.window_pages = td.runtime.window_pages;
  d.frames_in_flight = td.runtime.frames_in_flight;
  d.feedback_texels = td.feedback_texels;
  d.consumer_stages = td.consumer_stages;
  if (td.consumer_stages == 0) return invalid("create_virtual_texture(): consumer_stages: name at least one stage");
  auto packed = tvt::pack_scene(*td.assets, tvt::options_for(td.method, td.mip_strategy));
  if (!packed) return invalid(packed.error().message);
  tvt::SceneVtOptions o = td.runtime;
  if (o.store && o.scene_hash == 0)
    o.scene_hash = tvt::store_scene_identity(td.assets->desc, td.method, td.mip_strategy, o.store->desc().pyramid);
  return Access::make(device, d, tvt::scene_vt_config(packed.value()), tvt::with_builtin_producer(packed.value(), o));
}

}  // namespace terravt::detail
