#include "api/compose/scene_vt.h"

#include "compose/scene_identity.h"
#include "render/stored_producer.h"

namespace terravt::detail {

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
