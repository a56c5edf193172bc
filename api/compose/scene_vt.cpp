#include "api/compose/scene_vt.h"

#include "compose/scene.h"
#include "compose/scene_identity.h"
#include "render/stored_producer.h"

namespace terravt::detail {

Status check_scene_fields(const VirtualTextureDesc& desc) {
  if (!tvt::method_from_string(desc.method))
    return Error{ErrorKind::invalid_argument, "VirtualTextureDesc::method: unknown method '" + desc.method + "'"};
  if (auto s = tvt::mip_strategy_from_string(desc.mip_strategy); !s)
    return Error{ErrorKind::invalid_argument, "VirtualTextureDesc::mip_strategy: " + s.error().message};
  return Ok{};
}

Result<DescScene> load_desc_scene(const VirtualTextureDesc& desc) {
  if (auto st = check_scene_fields(desc); !st) return st.error();
  DescScene d;
  d.method = *tvt::method_from_string(desc.method);
  d.strategy = tvt::mip_strategy_from_string(desc.mip_strategy).value();
  auto scene = desc.scene_file.empty() ? tvt::Result<tvt::SceneDesc>(tvt::default_scene())
                                       : tvt::load_scene_file(desc.scene_file);
  if (!scene) return Error{ErrorKind::invalid_argument, scene.error().message};
  auto assets = tvt::load_scene_assets(scene.value());
  if (!assets)  // running out of memory stays out_of_memory; anything else is the input's fault
    return assets.error().kind == ErrorKind::out_of_memory ? assets.error()
                                                            : Error{ErrorKind::invalid_argument, assets.error().message};
  d.assets = std::move(assets.value());
  return d;
}

Result<std::shared_ptr<const tvt::PageStoreReader>> open_scene_store(const std::string& path,
                                                                     const tvt::SceneAssets& assets, tvt::Method method,
                                                                     tvt::MipStrategy strategy) {
  auto opened = tvt::PageStoreReader::open(path);
  if (!opened) return Error{ErrorKind::io, opened.error().message};
  std::shared_ptr<const tvt::PageStoreReader> store = std::move(opened.value());
  const uint64_t identity = tvt::store_scene_identity(assets.desc, method, strategy, store->desc().pyramid);
  if (auto m = tvt::StoredProducer::matches(*store, assets.desc.vt, identity); !m)
    return Error{ErrorKind::invalid_argument, m.error().message};
  return store;
}

}  // namespace terravt::detail
