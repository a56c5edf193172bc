// Small hand-made scenes for equation tests: constant-colour materials, constant or
// hand-set weights, hand-made meta-textures. Independent of the loaders and generators.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "compose/packed_scene.h"
#include "compose/scene_assets.h"

namespace tvt::test {

struct SyntheticMaterial {
  std::array<uint8_t, 4> rgba{128, 128, 128, 128};  // constant texel value (A = height)
  float weight = 0.f;                                // constant weight (ignored for the base: remainder)
  Mode mode = Mode::BlendMap;
  int resolution = 16;
};

// The base of the equation tests' scenes: a blend map of colour (200, 0, 0) and height 100,
// remainder weight.
inline const SyntheticMaterial k_base{{200, 0, 0, 100}, 0.f, Mode::BlendMap};

// V = 2^log2_vt, P = 16, B = 2, a 4x4 weight grid; material 0 is the base with remainder weight.
SceneAssets make_synthetic_assets(const std::vector<SyntheticMaterial>& materials, uint32_t log2_vt = 10);

// A meta-texture with one square feature per tile of `side` texels centred at (cx, cy),
// wrapping on the torus; f = 200 inside, 0 outside; variation = `variation` everywhere.
MetaTexture square_feature_meta(int resolution, int cx, int cy, int side, uint8_t variation = 255);

// A blend-map base (200, 0, 0, 100) under an FBPB material of weight p, 64 texels a tile
// (period 64 level-0 texels: material LOD = mip), with one 33 x 33 square feature a tile
// (square_feature_meta), feature texels (0, 200, 0) and ground (0, 40, 200), A = 128
// everywhere. feature_count is what the meta-texture reports: 1, the truth (the statistics
// block's log2 feature size log2 33: exact at points up to material LOD 5); more tell it the
// typical feature is smaller, as in a material whose features vary in size, where a large one
// takes the expectation past the typical feature's switch (40: log2 feature size 2.38, the
// expectation from LOD 2.63).
SceneAssets big_feature_scene(float p, uint32_t feature_count = 1);

// The same base under an FBPB+DPT material of weight 0.5, 64 texels a tile (material LOD =
// mip), with a 5 x 5 stone (feature texels (0, 200, 0), ground (0, 40, 200)) in every 8 x 8
// cell, each its own feature; its DPT layer has no patches (p = 0: the ground's value is 0 at
// level 0 and in any footprint). The features fade out of direct composition between
// fade_lod_lo and _hi. feature_count is what the meta-texture reports (64 stones: the statistics
// block's log2 feature size is log2 5, at points up to material LOD 2.57; fewer tell it the
// stones are larger: 16, log2 10, at points up to LOD 3.57).
SceneAssets small_stone_scene(float fade_lod_lo, float fade_lod_hi, uint32_t feature_count = 64);

// pack_scene(), failing the test where it returns an error.
PackedScene pack(const SceneAssets& assets, ComposeOptions options = {});

// Sets every weight-grid texel of `layer` to `value`.
void set_weight(SceneAssets& assets, int layer, float value);

}  // namespace tvt::test
