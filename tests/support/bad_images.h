// Bad image files for error tests: each one with the text its reader's error must contain.
// None allocates its claimed size (the huge one is a PNG header only).
#pragma once
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "compose/image.h"
#include "vt/result.h"

namespace tvt::test {

// PNG with only a signature, an IHDR chunk (valid CRC) claiming w x h texels of 8-bit RGBA and
// an empty IDAT and IEND: no image data.
inline void write_png_header_only(const std::string& file, uint32_t w, uint32_t h) {
  auto be32 = [](std::vector<uint8_t>& v, uint32_t x) {
    for (int s = 24; s >= 0; s -= 8) v.push_back(uint8_t(x >> s));
  };
  std::vector<uint8_t> chunk = {'I', 'H', 'D', 'R'};
  be32(chunk, w);
  be32(chunk, h);
  for (uint8_t b : {uint8_t(8), uint8_t(6), uint8_t(0), uint8_t(0), uint8_t(0)}) chunk.push_back(b);  // 8-bit RGBA, deflate, no filter, no interlace
  uint32_t crc = 0xffffffffu;  // CRC-32 (ISO 3309) over type and data, as PNG requires
  for (uint8_t b : chunk) {
    crc ^= b;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  std::vector<uint8_t> bytes = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  be32(bytes, 13);
  bytes.insert(bytes.end(), chunk.begin(), chunk.end());
  be32(bytes, crc ^ 0xffffffffu);
  // An empty IDAT (readers stop at the first IDAT to report the header), then IEND.
  for (uint8_t b : std::initializer_list<uint8_t>{0, 0, 0, 0, 'I', 'D', 'A', 'T', 0x35, 0xaf, 0x06, 0x1e, 0, 0, 0, 0,
                                                  'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82})
    bytes.push_back(b);
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

// Writes the bad files into `dir`; returns (file name, text the error must contain).
inline std::vector<std::pair<std::string, std::string>> write_bad_images(const std::filesystem::path& dir) {
  std::ofstream(dir / "empty.png");
  std::ofstream(dir / "text.png") << "this is not an image\n";
  std::filesystem::create_directories(dir / "folder.png");
  TVT_CHECK(write_image((dir / "one.png").string(), ImageRGBA8(1, 1)).ok());
  write_png_header_only((dir / "huge.png").string(), 20000, 20000);
  ImageF nan(4, 4, 3);
  nan.at(2, 1, 1) = std::nanf("");
  TVT_CHECK(write_image((dir / "nan.exr").string(), nan).ok());
  return {{"empty.png", "not an image"},
          {"text.png", "not an image"},
          {"folder.png", "is a directory"},
          {"one.png", "is 1 x 1 texels; a material image needs at least 2 x 2"},
          {"huge.png", "image too large (20000 x 20000 texels; at most 16384 per side)"},
          {"nan.exr", "non-finite value (NaN) at texel (2, 1) channel 1"}};
}

}  // namespace tvt::test
