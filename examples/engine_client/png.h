// A minimal PNG writer (8-bit RGBA, no filtering, zlib deflate): all the example needs to save
// its frame, with zlib as the only dependency.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace engine {

// Writes `rgba` (width * height * 4 bytes, rows top to bottom) to `path` under a temporary name,
// renamed into place once complete. Returns an empty string, or what failed (naming the file).
std::string write_png(const std::string& path, const std::vector<uint8_t>& rgba, uint32_t width, uint32_t height);

// Writes raw bytes the same way (the page-table dump).
std::string write_file(const std::string& path, const std::vector<uint8_t>& bytes);

}  // namespace engine
