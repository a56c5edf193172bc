#include "render/stored_pages.h"

#include <algorithm>

namespace tvt {

Result<std::unique_ptr<StoredPages>> StoredPages::create(vk::Context& context, std::shared_ptr<const PageStoreReader> store,
                                                         vk::Image& cache, const VtConfig& vt,
                                                         const StoredPagesOptions& options) {
  if (!store) return make_error("source: stored pages need a page store");
  StoredProducerOptions lo = options.loader;
  lo.frames_in_flight = options.frames_in_flight;
  // Async loads may be outstanding on top of the pages composed this frame; a synchronous run
  // asks for exactly what a procedural run would, so its frames match one for one. Staging is
  // released frames_in_flight frames after its copy was recorded.
  uint32_t per_frame = options.page_budget + lo.staging_slots;
  if (options.sync_loads) {
    lo.staging_slots = std::max(lo.staging_slots, options.page_budget * options.frames_in_flight);
    per_frame = options.page_budget;
  }
  auto loader = StoredProducer::create(context, std::move(store), vt, options.scene_hash, lo);
  if (!loader) return loader.error();
  return std::unique_ptr<StoredPages>(new StoredPages(std::move(loader.value()), cache, per_frame));
}

ProducerAccept StoredPages::request(const PageRequest& r) {
  if (!loader_->has(r.page)) return ProducerAccept::unavailable;
  return loader_->request(r) ? ProducerAccept::accepted : ProducerAccept::busy;
}

}  // namespace tvt
