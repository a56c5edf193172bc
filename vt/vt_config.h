// Virtual texture geometry: level-0 size V = 2^log2_size, pages of P payload texels plus a
// border of B texels on every side. Mip m has V >> m texels per side; the top mip is one page.
#pragma once
#include <cstdint>
#include <string>

#include "vt/result.h"

namespace tvt {

struct VtConfig {
  uint32_t log2_size = 16;      // log2 of level-0 texels per side; 10 ... 30
  uint32_t page_texels = 128;   // P, payload texels per page side; power of two
  uint32_t border_texels = 4;   // B, border texels on each side

  uint64_t size_texels() const { return uint64_t(1) << log2_size; }
  uint32_t log2_page() const;
  uint32_t slot_texels() const { return page_texels + 2 * border_texels; }
  // Number of mips: 0 (finest) ... top (one page).
  uint32_t mip_count() const { return log2_size - log2_page() + 1; }
  uint64_t pages_per_side(uint32_t mip) const { return (size_texels() >> mip) / page_texels; }
  uint64_t mip_texels(uint32_t mip) const { return size_texels() >> mip; }
};

// Checks ranges; `where` prefixes messages (e.g. "scene.json: /vt").
Status validate(const VtConfig& config, const std::string& where);

// A page: mip level and page coordinates at that mip. Packs into 64 bits for any V <= 2^30.
struct PageId {
  uint32_t mip = 0;
  uint32_t x = 0;
  uint32_t y = 0;

  // Layout: mip in bits 58..63, x in bits 29..57, y in bits 0..28.
  uint64_t pack() const { return (uint64_t(mip) << 58) | (uint64_t(x) << 29) | uint64_t(y); }
  static PageId unpack(uint64_t v) {
    return PageId{uint32_t(v >> 58), uint32_t((v >> 29) & 0x1fffffffu), uint32_t(v & 0x1fffffffu)};
  }
  PageId parent() const { return PageId{mip + 1, x >> 1, y >> 1}; }
  friend bool operator==(const PageId&, const PageId&) = default;
  friend auto operator<=>(const PageId&, const PageId&) = default;
};

bool is_valid(const VtConfig& config, const PageId& id);
std::string to_string(const PageId& id);

}  // namespace tvt
