// Plain CPU images. Texel (x, y) is row-major, y down, origin top-left.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "vt/result.h"

namespace tvt {

// 8-bit RGBA; for materials RGB is albedo (sRGB-encoded, blended as stored, as the papers do)
// and A is the material's height / blend map.
struct ImageRGBA8 {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> texels;  // width * height * 4

  ImageRGBA8() = default;
  ImageRGBA8(int w, int h) : width(w), height(h), texels(size_t(w) * size_t(h) * 4, 0) {}
  uint8_t* at(int x, int y) { return &texels[(size_t(y) * size_t(width) + size_t(x)) * 4]; }
  const uint8_t* at(int x, int y) const { return &texels[(size_t(y) * size_t(width) + size_t(x)) * 4]; }
};

// 8-bit single channel (masks, variation maps).
struct ImageGray8 {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> texels;

  ImageGray8() = default;
  ImageGray8(int w, int h) : width(w), height(h), texels(size_t(w) * size_t(h), 0) {}
  uint8_t& at(int x, int y) { return texels[size_t(y) * size_t(width) + size_t(x)]; }
  uint8_t at(int x, int y) const { return texels[size_t(y) * size_t(width) + size_t(x)]; }
};

// Float image with N channels (heightmaps, weight maps).
struct ImageF {
  int width = 0;
  int height = 0;
  int channels = 1;
  std::vector<float> data;

  ImageF() = default;
  ImageF(int w, int h, int c) : width(w), height(h), channels(c), data(size_t(w) * size_t(h) * size_t(c), 0.f) {}
  float& at(int x, int y, int c = 0) { return data[(size_t(y) * size_t(width) + size_t(x)) * size_t(channels) + size_t(c)]; }
  float at(int x, int y, int c = 0) const {
    return data[(size_t(y) * size_t(width) + size_t(x)) * size_t(channels) + size_t(c)];
  }
};

// Image files through OpenImageIO. Readers name the file in every error and reject
// non-finite float texels; writers write to a temporary file and rename, so a failed
// write never leaves a half file behind.
Result<ImageRGBA8> read_image_rgba8(const std::string& path);
Result<ImageF> read_image_float(const std::string& path);  // all channels, as float
// Size and channel count only (the file's header; no texel is read). The same open checks
// and error text as the readers, so a file that fails here fails them the same way.
struct ImageHeader {
  int width = 0, height = 0, channels = 0;
};
Result<ImageHeader> read_image_header(const std::string& path);
Status write_image(const std::string& path, const ImageRGBA8& image);
Status write_image(const std::string& path, const ImageGray8& image);
Status write_image(const std::string& path, const ImageF& image,
                   const std::vector<std::string>& channel_names = {});

}  // namespace tvt
