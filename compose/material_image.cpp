#include "compose/material_image.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <vector>

#include "shared/hash.h"

namespace tvt {

namespace {

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

bool alpha_varies(const ImageRGBA8& image) {
  for (size_t i = 3; i < image.texels.size(); i += 4)
    if (image.texels[i] != 255) return true;
  return false;
}

HeightSource resolve(const MaterialImageOptions& o, int channels) {
  if (o.height != HeightSource::Auto) return o.height;
  if (!o.height_path.empty()) return HeightSource::File;
  // Grey+alpha or RGBA: the alpha is looked at once the texels are read (constant 255 = none).
  return channels == 2 || channels >= 4 ? HeightSource::Alpha : HeightSource::Luminance;
}

// A one-texel row or column has no texture to tile or isolate; far too large ones were refused
// when the header was read (compose/image.h).
Status check_size(const std::string& path, const ImageHeader& h) {
  if (h.width < 2 || h.height < 2)
    return make_error(path + ": image is " + std::to_string(h.width) + " x " + std::to_string(h.height) +
                      " texels; a material image needs at least 2 x 2");
  return Ok{};
}

Status check_height_path(const MaterialImageOptions& o, HeightSource source) {
  if (source == HeightSource::File && o.height_path.empty())
    return make_error("height source 'file' needs a height image");
  return Ok{};
}

}  // namespace

int material_resolution_for(int width, int height) {
  TVT_CHECK(width >= 1 && height >= 1);
  // Nearest power of two in log2 terms; + 0.5 then floor rounds halfway up.
  const double log2_side = 0.5 * (std::log2(double(width)) + std::log2(double(height)));
  const int exponent = int(std::floor(log2_side + 0.5));
  return std::clamp(1 << std::clamp(exponent, 0, 30), k_min_material_resolution, k_max_material_resolution);
}

uint8_t luminance8(const uint8_t* rgb) {
  return uint8_t(std::lround(0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]));
}

ImageRGBA8 resample_tileable(const ImageRGBA8& image, int resolution) {
  TVT_CHECK(image.width > 0 && image.height > 0 && resolution > 0);
  if (image.width == resolution && image.height == resolution) return image;
  // ImageBufAlgo::resize maps the source's full (display) window onto the destination's and
  // lets its separable filter read the source's data window beyond it. So the source is given
  // a data window padded periodically by more than the filter's reach (Lanczos-3: 3 texels,
  // widened by the minification): the filter reads across the edges as on the torus, and the
  // result tiles as the input did. Same texels as ImageBufAlgo::warp with WrapPeriodic (the
  // earlier implementation, within 2/255), 3-4x faster: warp evaluates its 2-D filter per tap.
  const int w = image.width, h = image.height;
  const int pad_x = int(std::ceil(3.0 * std::max(1.0, double(w) / resolution))) + 2;
  const int pad_y = int(std::ceil(3.0 * std::max(1.0, double(h) / resolution))) + 2;
  OIIO::ImageSpec spec(w + 2 * pad_x, h + 2 * pad_y, 4, OIIO::TypeDesc::UINT8);
  spec.x = -pad_x;
  spec.y = -pad_y;
  spec.full_x = 0;
  spec.full_y = 0;
  spec.full_width = w;
  spec.full_height = h;
  std::vector<uint8_t> padded(size_t(spec.width) * size_t(spec.height) * 4);
  for (int y = 0; y < spec.height; ++y) {
    const uint8_t* row = image.at(0, int(gpu::tvt_floor_mod(y - pad_y, h)));
    uint8_t* out = &padded[size_t(y) * size_t(spec.width) * 4];
    for (int x = 0; x < spec.width; ++x)
      std::memcpy(out + size_t(x) * 4, row + size_t(gpu::tvt_floor_mod(x - pad_x, w)) * 4, 4);
  }
  OIIO::ImageBuf src(spec, padded.data());
  OIIO::ImageBuf dst(OIIO::ImageSpec(resolution, resolution, 4, OIIO::TypeDesc::FLOAT));
  const bool ok = OIIO::ImageBufAlgo::resize(dst, src, "lanczos3");
  TVT_CHECK(ok);  // only fails on bad arguments, which the checks above exclude
  std::vector<float> values(size_t(resolution) * size_t(resolution) * 4);
  TVT_CHECK(dst.get_pixels(OIIO::ROI(0, resolution, 0, resolution, 0, 1, 0, 4), OIIO::TypeDesc::FLOAT, values.data()));
  ImageRGBA8 out(resolution, resolution);
  for (size_t i = 0; i < values.size(); ++i) {
    // Lanczos overshoots at edges; the stored range is 0..1 (UINT8 normalised).
    const float v = std::isfinite(values[i]) ? std::clamp(values[i], 0.f, 1.f) : 0.f;
    out.texels[i] = uint8_t(std::lround(v * 255.f));
  }
  return out;
}

namespace {

// Nearest texel of the first channel, for any image type (`first(x, y)`).
template <typename Image, typename First>
ImageGray8 nearest_first_channel(const Image& mask, int resolution, First first) {
  TVT_CHECK(mask.width > 0 && mask.height > 0 && resolution > 0);
  ImageGray8 out(resolution, resolution);
  for (int y = 0; y < resolution; ++y)
    for (int x = 0; x < resolution; ++x)
      out.at(x, y) = first(int(int64_t(x) * mask.width / resolution), int(int64_t(y) * mask.height / resolution));
  return out;
}

}  // namespace

ImageGray8 resample_mask_nearest(const ImageRGBA8& mask, int resolution) {
  return nearest_first_channel(mask, resolution, [&mask](int x, int y) { return mask.at(x, y)[0]; });
}

ImageGray8 resample_mask_nearest(const ImageGray8& mask, int resolution) {
  return nearest_first_channel(mask, resolution, [&mask](int x, int y) { return mask.at(x, y); });
}

bool mask_size_fits(int mask_w, int mask_h, int source_w, int source_h, int resolution) {
  return (mask_w == source_w && mask_h == source_h) || (mask_w == resolution && mask_h == resolution);
}

std::string MaterialImageReport::summary() const {
  std::string s = size_text(source_width, source_height) + " (" + std::to_string(source_channels) + " ch) ";
  s += resampled ? "resampled to " + size_text(resolution, resolution) + " (Lanczos-3, wrap)" : "used as it is";
  s += ", height from " + std::string(to_string(height));
  if (height_inverted) s += " (inverted)";
  return s;
}

Result<int> material_image_resolution(const std::string& path, const MaterialImageOptions& o, bool* height_failed) {
  if (height_failed) *height_failed = false;
  auto h = read_image_header(path);
  if (!h) return h.error();
  if (auto s = check_size(path, *h); !s) return s.error();
  const HeightSource source = resolve(o, h->channels);
  if (auto s = check_height_path(o, source); !s) return make_error(path + ": " + s.error().message);
  if (source == HeightSource::File) {
    auto hh = read_image_header(o.height_path);
    if (!hh || !check_size(o.height_path, *hh)) {
      if (height_failed) *height_failed = true;
      return hh ? check_size(o.height_path, *hh).error() : hh.error();
    }
  }
  return o.resolution > 0 ? o.resolution : material_resolution_for(h->width, h->height);
}

Result<MaterialImage> load_material_image(const std::string& path, const MaterialImageOptions& o, bool* height_failed) {
  if (height_failed) *height_failed = false;
  auto header = read_image_header(path);
  if (!header) return header.error();
  if (auto s = check_size(path, *header); !s) return s.error();
  auto read = read_image_rgba8(path);
  if (!read) return read.error();
  MaterialImage m;
  MaterialImageReport& r = m.report;
  r.source_width = read->width;
  r.source_height = read->height;
  r.source_channels = header->channels;
  r.resolution = o.resolution > 0 ? o.resolution : material_resolution_for(read->width, read->height);
  r.resampled = read->width != r.resolution || read->height != r.resolution;
  HeightSource source = resolve(o, header->channels);
  if (auto s = check_height_path(o, source); !s) return make_error(path + ": " + s.error().message);
  if (source == HeightSource::Alpha && o.height == HeightSource::Auto && !alpha_varies(*read))
    source = HeightSource::Luminance;  // an alpha channel that is 255 everywhere carries no height

  ImageRGBA8 image = std::move(read.value());
  if (source == HeightSource::Luminance || source == HeightSource::None) {
    // Before resampling, so the filter sees the same texels for RGB and A.
    for (size_t i = 0; i < image.texels.size(); i += 4) {
      const uint8_t l = luminance8(&image.texels[i]);
      image.texels[i + 3] = source == HeightSource::None ? uint8_t(255) : o.invert_height ? uint8_t(255 - l) : l;
    }
  }
  m.image = resample_tileable(image, r.resolution);
  if (source == HeightSource::File) {
    auto h = read_image_float(o.height_path);
    if (h && (h->width < 2 || h->height < 2)) h = check_size(o.height_path, {h->width, h->height, h->channels}).error();
    if (!h) {
      if (height_failed) *height_failed = true;
      return h.error();
    }
    ImageRGBA8 height(h->width, h->height);
    for (int y = 0; y < h->height; ++y)
      for (int x = 0; x < h->width; ++x) {
        const float v = std::clamp(h->at(x, y, 0), 0.f, 1.f);
        uint8_t* t = height.at(x, y);
        t[0] = t[1] = t[2] = t[3] = uint8_t(std::lround(v * 255.f));
      }
    const ImageRGBA8 resampled = resample_tileable(height, r.resolution);
    for (size_t i = 3; i < m.image.texels.size(); i += 4) m.image.texels[i] = resampled.texels[i];
  }
  r.height = source;
  r.height_inverted = source == HeightSource::Luminance && o.invert_height;
  return m;
}

}  // namespace tvt
