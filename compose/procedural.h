// Built-in procedural inputs: tileable material textures (with the exact feature labels of
// salient-feature materials) and fBm heightmaps. Pure functions of their parameters.
#pragma once
#include <cstdint>
#include <string_view>
#include <vector>

#include "compose/image.h"
#include "vt/result.h"

namespace tvt {

struct GeneratedMaterial {
  ImageRGBA8 albedo;               // RGB albedo, A = height / blend map; tiles seamlessly
  // Exact feature labels for materials with salient features (cobbles, bricks): one int per
  // texel, -1 = no feature, 0..feature_count-1 = feature id. Features may cross the tile
  // edges and the corner; a feature's texels form one connected component on the torus.
  // Empty for materials without features.
  std::vector<int32_t> feature_labels;
  uint32_t feature_count = 0;
  ImageGray8 variation;            // tileable noise for FBPB variations (Algorithm 1)
};

// Generators: "sand", "grass", "rock", "mud" (no features), "cobbles", "bricks" (features).
// resolution: power of two 16 ... 4096. Unknown names or bad sizes give an Error.
Result<GeneratedMaterial> generate_material(std::string_view generator, uint32_t resolution, uint32_t seed);
bool is_known_generator(std::string_view generator);

// Tileable value-noise fBm in [0,1] on a size x size grid; deterministic in all parameters.
std::vector<float> fbm_grid(uint32_t size, uint32_t seed, uint32_t octaves, double frequency, double gain,
                            double lacunarity);

// FBPB variation map (Algorithm 1) for a material that brings none: tileable fBm as 0..255.
// Image materials use k_image_variation_seed in scenes and in `terravt metatex` alike, so the
// two write the same meta-texture for the same image (the map is read at per-feature hashed
// offsets at run time, so one fixed map serves every image).
ImageGray8 variation_noise(uint32_t resolution, uint32_t seed);
inline constexpr uint32_t k_image_variation_seed = 0x76617269u;  // "vari"

}  // namespace tvt
