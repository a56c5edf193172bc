// Everything a scene needs at composition time, loaded from a SceneDesc: the heightfield,
// the low-resolution weight grid (one layer per material) and each material's mip chain and
// FBPB meta-texture, the last two on first use (MaterialSource).
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "compose/image.h"
#include "compose/material_source.h"
#include "compose/metatex.h"
#include "compose/scene.h"
#include "vt/result.h"

namespace tvt {

// Weight grid covering the whole terrain: texel (i, j) sits at terrain position
// ((i + 0.5) / width, (j + 0.5) / height) of the extent. Layer n is material n's weight in [0,1].
struct WeightGrid {
  int width = 0;
  int height = 0;
  int layers = 0;
  std::vector<float> data;  // layer-major: data[(layer * height + y) * width + x]
  float at(int layer, int x, int y) const {
    return data[(size_t(layer) * size_t(height) + size_t(y)) * size_t(width) + size_t(x)];
  }
};

struct SceneAssets {
  SceneDesc desc;
  ImageF heightfield;              // normalised heights in [0,1], 1 channel
  WeightGrid weights;
  // Material textures and meta-textures, read on first use (compose/material_source.h).
  // Shared: copies of the assets and every PackedScene made from them use one cache.
  std::shared_ptr<MaterialSource> materials = MaterialSource::in_memory();
};

// Loads or generates the heightfield and the weights, and opens the materials: their headers
// are checked here, their texels read on first use. Errors name the scene file, the field and
// the file.
Result<SceneAssets> load_scene_assets(const SceneDesc& desc);

// Weight rule evaluation (exposed for tests): smoothstep window, 1 inside [lo, hi], falling
// to 0 over `fade` outside; fade 0 is a hard step.
double window_weight(double v, double lo, double hi, double fade);

}  // namespace tvt
