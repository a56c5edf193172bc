#include "render/stored_pages.h"

#include <algorithm>

namespace tvt {

Result<std::unique_ptr<StoredPages>> StoredPages::create(vk::Context& context, std::shared_ptr<const PageStoreReader> store,
                                                         vk::Image& cache, const VtConfig& vt,
                                                         const StoredPagesOptions& options) {
  if (!store) return make_error("source: stored pages need a page store");
  StoredProducerOptions lo = options.loader;
  lo.frames_in_flight = options.frames_in_flight;
  // Staging is released frames_in_flight frames after its copy was recorded.
  if (options.sync_loads) lo.staging_slots = std::max(lo.staging_slots, options.page_budget * options.frames_in_flight);
  const uint32_t per_frame = stored_requests_per_frame(options);
  auto loader = StoredProducer::create(context, std::move(store), vt, options.scene_hash, lo);
  if (!loader) return loader.error();
  return std::unique_ptr<StoredPages>(new StoredPages(std::move(loader.value()), cache, per_frame));
}

uint32_t stored_requests_per_frame(const StoredPagesOptions& options) {
  return options.sync_loads ? options.page_budget : options.page_budget + options.loader.staging_slots;
}

ProducerAccept StoredPages::request(const PageRequest& r) {
  if (!loader_->has(r.page)) return ProducerAccept::unavailable;
  return loader_->request(r) ? ProducerAccept::accepted : ProducerAccept::busy;
}

}  // namespace tvt
