// A brute-force reference model of the VT page table (vt/page_table.h), written from the
// specification (docs/page-table.md) and independent of the implementation: a std::map of
// mapped pages, ancestor search by walking parents, windows recomputed from the centre.
#pragma once
#include <algorithm>
#include <cstdint>
#include <map>
#include <vector>

#include "vt/vt_config.h"

namespace tvt::test {

struct ReferenceTable {
  VtConfig config;
  uint32_t w = 0;
  std::map<PageId, uint32_t> mapped;
  uint32_t centre_x = 0, centre_y = 0;

  uint64_t side(uint32_t m) const { return std::min<uint64_t>(w, config.pages_per_side(m)); }
  uint64_t origin(uint32_t m, uint32_t texel) const {
    const uint64_t pages = config.pages_per_side(m);
    if (pages <= w) return 0;
    const int64_t c = int64_t(texel >> (config.log2_page() + m));
    return uint64_t(std::clamp<int64_t>(c - int64_t(w / 2), 0, int64_t(pages - w)));
  }
  bool covers(const PageId& p) const {
    const uint64_t s = side(p.mip), ox = origin(p.mip, centre_x), oy = origin(p.mip, centre_y);
    return p.x >= ox && p.x < ox + s && p.y >= oy && p.y < oy + s;
  }
  uint32_t expected_entry(PageId p) const {
    for (;;) {
      if (auto it = mapped.find(p); it != mapped.end())
        return 0x80000000u | (p.mip << 20) | it->second;
      if (p.mip + 1 >= config.mip_count()) return 0;
      p = p.parent();
    }
  }
  std::vector<uint32_t> expected_mip(uint32_t m) const {
    const uint64_t s = side(m), ox = origin(m, centre_x), oy = origin(m, centre_y);
    std::vector<uint32_t> out(s * s, 0xdeadbeefu);
    for (uint64_t py = oy; py < oy + s; ++py)
      for (uint64_t px = ox; px < ox + s; ++px)
        out[(py % s) * s + px % s] = expected_entry(PageId{m, uint32_t(px), uint32_t(py)});
    return out;
  }
  uint32_t expected_lookup(uint32_t x, uint32_t y, uint32_t mip) const {
    for (uint32_t m = mip;; ++m) {
      const PageId p{m, x >> (config.log2_page() + m), y >> (config.log2_page() + m)};
      if (covers(p)) return expected_entry(p);
    }
  }
};

}  // namespace tvt::test
