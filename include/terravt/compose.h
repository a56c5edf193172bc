// terravt's compose component (libterravt_compose; CMake: find_package(terravt CONFIG
// COMPONENTS compose), target terravt::compose): virtual textures made from a scene — the
// compute composer, stored pages checked against the scene they were baked from, and their
// hybrid. It brings the scene side (JSON scenes, material images through OpenImageIO, feature
// isolation through OpenCV); a client that only streams baked stores or brings its own
// producer links libterravt alone (VirtualTexture::create()).
//
// The composer is a page producer (terravt/page_producer.h) on the public API like a client's:
// the VirtualTexture returned here behaves exactly as one from VirtualTexture::create(), and
// every call of terravt/virtual_texture.h applies to it.
#pragma once
#include <memory>

#include "terravt/device.h"
#include "terravt/error.h"
#include "terravt/export.h"
#include "terravt/virtual_texture.h"

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

}  // namespace terravt::compose
