// Page producers shared by `bake` and `compare`: the same compositors `compose` and `render`
// use (GPU compute shader by default, through the public terravt::compose::PageComposer on the
// device the tool made, as an engine would bake; the double-precision CPU reference
// optionally), wrapped as a streaming::PageSource, and the StoreDesc that names them in a
// store header.
#pragma once
#include <memory>
#include <string>

#include "compose/packed_scene.h"
#include "compose/scene_assets.h"
#include "composer/gpu_composer.h"
#include "gpu/context.h"
#include "terravt/compose.h"
#include "streaming/bake.h"
#include "streaming/page_store.h"

namespace tvt::cli {

class PageProducers {
 public:
  // cpu: the CPU reference on every core; else the GPU composer on `context` if given, or on
  // a new context for `gpu_name`'s device.
  static Result<std::unique_ptr<PageProducers>> create(const SceneAssets& assets, Method method, MipStrategy strategy,
                                                       bool cpu, const std::string& gpu_name,
                                                       vk::Context* context = nullptr);
  GpuComposer* composer();  // under the PageComposer (timings); null for the CPU reference
  // A store header for pages made by this producer at zstd `level`.
  StoreDesc store_desc(int level) const;
  // Produces pages in order; raw (P+2B)^2 RGBA8 each.
  PageSource source();
  const std::string& device_name() const { return device_name_; }


 private:
  PageProducers() = default;
  const SceneAssets* assets_ = nullptr;
  Method method_ = Method::FbpbDpt;
  MipStrategy strategy_;
  PackedScene packed_;
  bool cpu_ = false;
  std::string device_name_;
  std::unique_ptr<vk::Context> context_;
  std::unique_ptr<terravt::compose::PageComposer> composer_;
};

}  // namespace tvt::cli
