// terravt's own page producers over a scene (render/page_producer.h): the compute composer and
// its hybrid with the stored megatexture, and the factory that picks one by VtSource.
//   composed  every page composed (compose.comp) from the scene's materials; at most
//             page_budget pages a frame
//   stored    every page read from a baked store (render/stored_pages.h, which needs no scene:
//             the runtime core makes it on its own for a scene-less VT)
//   hybrid    stored where the store has a good page, composed elsewhere and instead of a
//             page that failed to load (into the slot it was meant for, the same frame)
#pragma once
#include <memory>
#include <optional>
#include <string_view>

#include "compose/packed_scene.h"
#include "composer/gpu_composer.h"
#include "gpu/context.h"
#include "render/page_producer.h"
#include "render/stored_pages.h"
#include "render/vt_system.h"

namespace tvt {

enum class VtSource { procedural, stored, hybrid };
std::string_view to_string(VtSource source);
std::optional<VtSource> vt_source_from_string(std::string_view text);

struct BuiltinProducerOptions {
  VtSource source = VtSource::procedural;
  uint32_t page_budget = 32;           // pages composed per frame at most
  uint32_t frames_in_flight = 2;
  std::shared_ptr<const PageStoreReader> store;  // required for stored and hybrid
  StoredProducerOptions loader;        // threads, staging ring
  bool sync_loads = false;             // requests_per_frame() as a procedural run's (frame-exact comparisons)
  uint64_t scene_hash = 0;             // checked against the store's (0: unchecked)
};

// `cache`: the VT's cache image (its layers are the slots), owned by the caller and outliving
// the producer.
Result<std::unique_ptr<PageProducer>> make_builtin_producer(vk::Context& context, const PackedScene& scene,
                                                            vk::Image& cache, const BuiltinProducerOptions& options);

// The VT geometry a scene was packed with.
VtConfig scene_vt_config(const PackedScene& scene);

// A VT runtime over a scene: the runtime's options and which built-in producer makes its pages
// (unless `producer` is set: then the scene gives only the geometry).
struct SceneVtOptions : VtSystemOptions {
  VtSource source = VtSource::procedural;
  std::shared_ptr<const PageStoreReader> store;  // required for stored and hybrid
  StoredProducerOptions loader;                  // threads, staging ring
  uint64_t scene_hash = 0;                       // checked against the store's (0: unchecked)
};
// `options` as the runtime takes them: make_producer builds the built-in producer.
VtSystemOptions with_builtin_producer(const PackedScene& scene, const SceneVtOptions& options);
Result<std::unique_ptr<VtSystem>> create_vt_system(vk::Context& context, const PackedScene& scene,
                                                   const SceneVtOptions& options);

}  // namespace tvt
