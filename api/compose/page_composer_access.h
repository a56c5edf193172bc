// What terravt's own tools need of a compose::PageComposer beyond the public API (never
// installed): one made over scene assets the tool already holds (a scene the CLI changed in
// memory, e.g. --hex or --method), and the composer under it for the CLI's timings.
// PageComposer::create() ends in make_page_composer() too.
#pragma once
#include <memory>
#include <string>

#include "compose/packed_scene.h"
#include "compose/scene_assets.h"
#include "composer/gpu_composer.h"
#include "terravt/compose.h"

namespace terravt::detail {

struct ComposeAccess {
  static Result<std::unique_ptr<compose::PageComposer>> make_page_composer(const DeviceHandles& device,
                                                                           const tvt::SceneAssets& assets,
                                                                           tvt::Method method, tvt::MipStrategy strategy,
                                                                           uint32_t batch);
  static tvt::GpuComposer& composer(compose::PageComposer& c);
};

}  // namespace terravt::detail
