// Deterministic synthetic pages for tests, fuzz seeds and `terravt bench-loader --synthetic`:
// a pure function of (seed, page id) with terrain-like structure (8x8-texel blocks of one of
// four material colours, a height ramp, per-texel noise of `noise_bits` bits; zstd level 3
// compresses the default about 2.5x, like albedo pages), computed from global texel
// coordinates so that borders equal the neighbours' interiors, as composed pages do.
#pragma once
#include <cstdint>
#include <vector>

#include "streaming/bake.h"

namespace tvt {

struct SyntheticPages {
  uint64_t seed = 1;
  uint32_t noise_bits = 2;  // 0: very compressible (tiny stores); 8: incompressible noise
};

// One raw page of desc.page_bytes() bytes (every layer filled).
std::vector<uint8_t> synthetic_page(const StoreDesc& desc, const PageId& page, const SyntheticPages& params = {});
// A PageSource producing synthetic_page for each requested page.
PageSource synthetic_source(const StoreDesc& desc, const SyntheticPages& params = {});

}  // namespace tvt
