// A material texture as the compositor needs it, from an image file of any size and kind:
// a square, power-of-two, tileable RGBA8 image whose RGB is the albedo and whose A is the
// height / blend map. Scene loading (MaterialSource) and `terravt metatex` both make it here,
// so the two give the same texels, hence the same meta-texture, for the same file and options.
//
//   MaterialImageOptions o;                     // resolution 0: the rule below
//   auto m = load_material_image("wall.jpg", o); // 100 x 100 grey JPEG -> 128 x 128 RGBA8
//   // m->image, m->report.summary(): "100x100 (1 ch) resampled to 128x128, height from luminance"
//
// Resolution rule (docs/scene-format.md): the power of two nearest to the geometric mean of the
// sides, sqrt(w·h), in log2 terms (halfway rounds up), clamped to 16 ... 4096; an image whose
// sides are already that power of two is taken as it is, texel for texel. Otherwise it is
// resampled with OpenImageIO's ImageBufAlgo::resize, a Lanczos-3 filter, on the image padded
// periodically beyond its display window: the filter reads across the edges, so the result
// tiles as the input did, and minification widens the filter (no aliasing).
//
// Height (A) sources: the file's alpha, a separate image (first channel), the albedo's
// luminance (Rec. 709 weights on the stored values: "the darkest pixel is deemed to be the
// deeper"; invert flips it), or none (A = 255, flat). Auto: the separate image if one is
// named, else alpha if the file has an alpha channel that is not constant, else luminance.
//
// Thread-safety: pure functions.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "compose/image.h"
#include "vt/result.h"

namespace tvt {

enum class HeightSource { Auto, Alpha, Luminance, File, None };
std::string_view to_string(HeightSource source);                          // "auto", "alpha", ...
std::optional<HeightSource> height_source_from_string(std::string_view);  // inverse of to_string

inline constexpr int k_min_material_resolution = 16;
inline constexpr int k_max_material_resolution = 4096;

// The rule above: texels per side of the material made from a w x h image (w, h >= 1).
int material_resolution_for(int width, int height);

// Rec. 709 luma of stored RGB values, 0..255, rounded.
uint8_t luminance8(const uint8_t* rgb);

// Resamples `image` (any size) to resolution x resolution, tileably (see above). An image of
// that size already comes back unchanged.
ImageRGBA8 resample_tileable(const ImageRGBA8& image, int resolution);

// A feature mask drawn on the source image, brought to the material's resolution by nearest
// texel (a binary mask stays binary): first channel.
ImageGray8 resample_mask_nearest(const ImageRGBA8& mask, int resolution);
ImageGray8 resample_mask_nearest(const ImageGray8& mask, int resolution);
// Whether a mask_w x mask_h feature mask fits a material of `resolution` texels a side made from
// a source_w x source_h image: drawn on the image as given (its size), or at the material's own
// resolution (what `terravt metatex --mask-out` writes for an image smaller than the material,
// whose pixels are too few to keep the features it split apart).
bool mask_size_fits(int mask_w, int mask_h, int source_w, int source_h, int resolution);

struct MaterialImageOptions {
  HeightSource height = HeightSource::Auto;
  std::string height_path;  // the separate height image (HeightSource::File or Auto)
  bool invert_height = false;  // luminance height only: the lightest pixel is the deepest
  int resolution = 0;          // 0: the rule; else a power of two 16 ... 4096
};

struct MaterialImageReport {
  int source_width = 0, source_height = 0, source_channels = 0;
  int resolution = 0;
  bool resampled = false;
  HeightSource height = HeightSource::None;  // the source actually used (never Auto)
  bool height_inverted = false;
  std::string summary() const;  // one line: what was read and what was done to it
};

struct MaterialImage {
  ImageRGBA8 image;  // resolution^2, RGB albedo, A height
  MaterialImageReport report;
};

// Reads `path` (8/16-bit, float, grey, grey+alpha, RGB, RGBA; any format OpenImageIO reads, up
// to 16384 texels per side) and makes the material image. Errors name the file; a height file
// that cannot be read is named too (callers prefix the scene field or CLI flag: on an error,
// *height_failed says whether it is about options.height_path rather than `path`).
Result<MaterialImage> load_material_image(const std::string& path, const MaterialImageOptions& options,
                                          bool* height_failed = nullptr);

// The header-only part of load_material_image: the resolution the image will have.
// Reads headers only (both files when a height file is named); the same errors as the loader.
Result<int> material_image_resolution(const std::string& path, const MaterialImageOptions& options,
                                      bool* height_failed = nullptr);

}  // namespace tvt
