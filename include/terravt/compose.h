// terravt's compose component (libterravt_compose; CMake: find_package(terravt CONFIG
// COMPONENTS compose), target terravt::compose): virtual textures made from a scene — the
// compute composer, stored pages checked against the scene they were baked from, and their
// hybrid. It brings the scene side (JSON scenes, material images through OpenImageIO, feature
// isolation through OpenCV); a client that only streams baked stores or brings its own
// producer links libterravt alone (VirtualTexture::create()).
//
// The composer is a page producer (terravt/page_producer.h) on the public API like a client's:
// the VirtualTexture returned here behaves exactly as one from VirtualTexture::create(), and
// every call of terravt/virtual_texture.h applies to it. PageComposer composes the same pages
// into host memory, for baking.
#pragma once
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "terravt/device.h"
#include "terravt/error.h"
#include "terravt/export.h"
#include "terravt/virtual_texture.h"

namespace terravt::detail {
struct ComposeAccess;  // terravt's own tools (not part of the API)
}

namespace terravt::compose {

// The scene is desc.scene_file (docs/scene-format.md) or, empty, the built-in scene; its
// materials are read lazily, when the first page that needs one is composed (a material that
// cannot be read fails those pages: VirtualTexture::record() returns producer_failed, naming
// the file). By desc.source:
//   composed  every page composed from the scene with desc.method and desc.mip_strategy
//   stored    pages of desc.store_file, which must have been baked from this scene, method and
//             mip strategy (else invalid_argument, naming the store's field)
//   hybrid    stored where the store has a good page, composed elsewhere
// With desc.producer set, the producer makes every page over the scene's geometry.
// desc.layout, when set, must equal the scene's geometry.
TERRAVT_API Result<std::unique_ptr<VirtualTexture>> create_virtual_texture(const DeviceHandles& device,
                                                                          const VirtualTextureDesc& desc);

// Pages composed into host memory on the client's device, for baking stores offline (terravt's
// own `terravt bake` composes through it): the same compute shader and bytes as the pages a
// composed VirtualTexture makes. Unlike VirtualTexture it submits: compose() records its work,
// submits it on DeviceHandles::queue and waits for it, so the client serialises its own use of
// that queue around it (Vulkan external synchronisation). One thread at a time.
class TERRAVT_API PageComposer {
 public:
  // The scene, method and mip strategy of `desc` (as create_virtual_texture() reads them; its
  // source, store, producer and frame options are unused). `batch`: pages composed per
  // submission (1 ... 4096); compose() splits longer lists.
  static Result<std::unique_ptr<PageComposer>> create(const DeviceHandles& device, const VirtualTextureDesc& desc,
                                                      uint32_t batch = 32);
  ~PageComposer();
  PageComposer(const PageComposer&) = delete;
  PageComposer& operator=(const PageComposer&) = delete;

  VirtualTextureInfo info() const;  // cache_slots: 0
  // Bytes of one page: (page_texels + 2 border_texels)^2 RGBA8 texels, rows of texels from
  // the top, rgb the albedo and a the height, as the VT's cache layer holds it.
  uint64_t page_bytes() const;
  // Composes `pages` (their `weight` is unused) into `out`, one page_bytes() vector each, in
  // order. A page outside the VT is invalid_argument naming its index, before anything is
  // composed; a material that cannot be loaded is producer_failed naming the file.
  Status compose(std::span<const PageRequest> pages, std::vector<std::vector<uint8_t>>& out);

 private:
  friend struct terravt::detail::ComposeAccess;
  struct Impl;
  explicit PageComposer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace terravt::compose
