// terravt::compose::PageComposer (include/terravt/compose.h): pages into host memory on the
// client's device, through the same GPU composer (composer/gpu_composer.h) a composed
// VirtualTexture uses.
#include <string>
#include <utility>

#include "api/compose/page_composer_access.h"
#include "api/compose/scene_vt.h"
#include "compose/packed_scene.h"
#include "composer/gpu_composer.h"
#include "gpu/context.h"
#include "terravt/compose.h"

namespace terravt::compose {

struct PageComposer::Impl {
  std::unique_ptr<tvt::vk::Context> context;  // declared first: destroyed last
  tvt::PackedScene packed;
  tvt::VtConfig config;
  std::unique_ptr<tvt::GpuComposer> composer;
};

PageComposer::PageComposer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PageComposer::~PageComposer() = default;

Result<std::unique_ptr<PageComposer>> PageComposer::create(const DeviceHandles& device, const VirtualTextureDesc& desc,
                                                           uint32_t batch) {
  if (auto st = detail::check_scene_fields(desc); !st) return st.error();
  if (batch < 1 || batch > 4096)
    return Error{ErrorKind::invalid_argument, "PageComposer::create(): batch must be 1 ... 4096, got " + std::to_string(batch)};
  if (auto st = check_device(device); !st) return st.error();
  auto loaded = detail::load_desc_scene(desc);
  if (!loaded) return loaded.error();
  return detail::ComposeAccess::make_page_composer(device, loaded->assets, loaded->method, loaded->strategy, batch);
}

VirtualTextureInfo PageComposer::info() const {
  const tvt::VtConfig& c = impl_->config;
  return VirtualTextureInfo{c.log2_size, c.page_texels, c.border_texels, c.mip_count(), 0};
}

uint64_t PageComposer::page_bytes() const { return uint64_t(impl_->config.slot_texels()) * impl_->config.slot_texels() * 4; }

Status PageComposer::compose(std::span<const PageRequest> pages, std::vector<std::vector<uint8_t>>& out) {
  Impl& m = *impl_;
  if (auto st = m.context->status(); !st) return st;  // a failed Vulkan call stays
  std::vector<tvt::PageId> ids;
  ids.reserve(pages.size());
  for (size_t i = 0; i < pages.size(); ++i) {
    const tvt::PageId id{pages[i].mip, pages[i].x, pages[i].y};
    if (!tvt::is_valid(m.config, id))
      return Error{ErrorKind::invalid_argument, "PageComposer::compose(): pages[" + std::to_string(i) + "] " +
                                                    tvt::to_string(id) + " is not a page of this VT"};
    ids.push_back(id);
  }
  auto composed = m.composer->compose_pages(ids);  // in batches of the composer's slots
  if (!composed) return detail::as_error(composed.error(), ErrorKind::producer_failed);
  out = std::move(composed.value());
  return Ok{};
}

}  // namespace terravt::compose

namespace terravt::detail {

Result<std::unique_ptr<compose::PageComposer>> ComposeAccess::make_page_composer(const DeviceHandles& device,
                                                                               const tvt::SceneAssets& assets,
                                                                               tvt::Method method,
                                                                               tvt::MipStrategy strategy, uint32_t batch) {
  auto impl = std::make_unique<compose::PageComposer::Impl>();
  auto packed = tvt::pack_scene(assets, tvt::options_for(method, strategy));
  if (!packed) return Error{ErrorKind::invalid_argument, packed.error().message};
  impl->packed = std::move(packed.value());
  impl->config = assets.desc.vt;
  auto context = tvt::vk::Context::adopt(device);
  if (!context) return context.error();
  impl->context = std::move(context.value());
  auto composer = tvt::GpuComposer::create(*impl->context, impl->packed, batch);
  if (!composer) return composer.error();
  impl->composer = std::move(composer.value());
  if (auto st = impl->context->status(); !st) return st.error();
  return std::unique_ptr<compose::PageComposer>(new compose::PageComposer(std::move(impl)));
}

tvt::GpuComposer& ComposeAccess::composer(compose::PageComposer& c) { return *c.impl_->composer; }

}  // namespace terravt::detail
