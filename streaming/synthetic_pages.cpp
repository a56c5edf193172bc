#include "streaming/synthetic_pages.h"

namespace tvt {

namespace {
uint64_t mix(uint64_t x) {  // splitmix64 finaliser
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
uint64_t hash4(uint64_t a, uint64_t b, uint64_t c, uint64_t d) { return mix(a ^ mix(b ^ mix(c ^ mix(d)))); }
}  // namespace

std::vector<uint8_t> synthetic_page(const StoreDesc& desc, const PageId& page, const SyntheticPages& params) {
  const uint32_t slot = desc.vt.slot_texels();
  const int64_t p = desc.vt.page_texels, b = desc.vt.border_texels;
  const uint32_t noise_mask = params.noise_bits >= 8 ? 0xffu : (1u << params.noise_bits) - 1u;
  std::vector<uint8_t> out(size_t(desc.page_bytes()));
  uint8_t* t = out.data();
  for (size_t layer = 0; layer < desc.layers.size(); ++layer) {
    // Four "materials" per layer: a palette of four colours, one chosen per 8x8-texel block.
    const uint64_t salt = params.seed * 8 + layer;
    uint8_t palette[4][3];
    for (int m = 0; m < 4; ++m)
      for (int c = 0; c < 3; ++c) palette[m][c] = uint8_t(hash4(salt, 99, uint64_t(m), uint64_t(c)));
    for (uint32_t y = 0; y < slot; ++y)
      for (uint32_t x = 0; x < slot; ++x, t += 4) {
        // Global texel coordinates at this mip (may be negative in the border of edge pages).
        const int64_t gx = int64_t(page.x) * p + int64_t(x) - b, gy = int64_t(page.y) * p + int64_t(y) - b;
        const uint64_t block = hash4(salt, page.mip, uint64_t(gx >> 3), uint64_t(gy >> 3));
        const uint64_t noise = noise_mask ? hash4(salt + 1, page.mip, uint64_t(gx), uint64_t(gy)) : 0;
        const uint8_t* colour = palette[block & 3];
        for (int c = 0; c < 3; ++c) t[c] = uint8_t(colour[c] + ((noise >> (8 * c)) & noise_mask));
        t[3] = uint8_t(uint64_t(gx + gy) / 8 + (block & 3) * 16 + ((noise >> 24) & noise_mask));
      }
  }
  return out;
}

PageSource synthetic_source(const StoreDesc& desc, const SyntheticPages& params) {
  return [desc, params](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) -> Status {
    for (const PageId& page : pages) out.push_back(synthetic_page(desc, page, params));
    return Ok{};
  };
}

}  // namespace tvt
