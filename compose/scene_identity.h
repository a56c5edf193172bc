// A stable 64-bit identity of "what a page of this scene looks like": the scene description
// (as canonical JSON), the transition method and the page-format version. A baked store records
// it, so pages baked from another scene or method are refused instead of shown.
// Limit: image files named by the scene are identified by path, size and modification time,
// not by their bytes (hashing every texture at startup would cost more than it protects).
#pragma once
#include <cstdint>

#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "streaming/page_store.h"

namespace tvt {

// The mip strategy changes pages of mip >= 1: a store baked with one is not another's. Direct
// adds nothing, so identities of stores baked before the knob existed still match.
uint64_t scene_identity(const SceneDesc& scene, Method method, MipStrategy strategy = {});
// The identity a store of `pyramid` must carry to serve a run of `method` and `strategy`: a
// filtered store composed level 0 alone, where every strategy is direct.
uint64_t store_scene_identity(const SceneDesc& scene, Method method, MipStrategy strategy, StorePyramid pyramid);

}  // namespace tvt
