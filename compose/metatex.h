// FBPB meta-texture (thesis §3.4.4, docs/composition.md): per material texel, the integer offset to
// its feature's centroid, the binary feature mask d and the soft feature map f. Offsets are
// computed on the torus, so a feature split across the tile edge is one feature and every
// piece points at the same centroid.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "compose/feature_isolation.h"
#include "compose/image.h"
#include "vt/result.h"

namespace tvt {

struct MetaTexel {
  int16_t dx = 0;         // offset to the feature centroid, material texels (0 if d == 0)
  int16_t dy = 0;
  uint8_t d = 0;          // 1 inside a feature
  uint8_t f = 0;          // soft feature map, blurred d, 0..255
  uint8_t variation = 0;  // variation map value, 0..255 (Algorithm 1)
  uint8_t reserved = 0;
};

struct MetaTexture {
  int resolution = 0;
  std::vector<MetaTexel> texels;  // resolution^2, row-major
  uint32_t feature_count = 0;
  const MetaTexel& at(int x, int y) const { return texels[size_t(y) * size_t(resolution) + size_t(x)]; }
};

// Centroids: the mean position of a feature's texels, unwrapped on the torus, rounded to the
// nearest texel. f: d blurred with a wrap-around box/Gaussian of radius blur_texels.
// variation may be empty (all 255: never chips).
MetaTexture build_meta_texture(const FeatureLabels& labels, const ImageGray8& variation, double blur_texels);

// File format: OpenEXR via OpenImageIO with channels dx, dy, d, f, v (float). Errors name the
// file and what is wrong (missing channel, non-square, offsets out of range, non-integers).
Status write_meta_texture(const std::string& path, const MetaTexture& meta);
Result<MetaTexture> read_meta_texture(const std::string& path);

// Colour-coded debug image: albedo darkened, each feature tinted with a colour from its id,
// centroids marked with a white cross. `marks` (IsolationReport::marks, empty: none) adds what
// automatic isolation did: filled pin-holes blue, dropped specks red, split lines yellow.
ImageRGBA8 meta_debug_image(const MetaTexture& meta, const ImageRGBA8& albedo, const std::vector<uint8_t>& marks = {});

}  // namespace tvt
