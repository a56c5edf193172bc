// Assembling regions of a mip from pages, and picking a region worth looking at.
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include "compose/image.h"
#include "compose/scene_assets.h"
#include "vt/vt_config.h"

namespace tvt {

// A rectangle of texels at one mip.
struct Region {
  uint32_t mip = 0;
  int64_t x = 0, y = 0;  // first texel
  int width = 512, height = 512;
};

// The pages whose payload covers `region`, row-major.
std::vector<PageId> pages_covering(const VtConfig& vt, const Region& region);

// Copies the payload texels of composed pages (border dropped) into the region image.
// `page_texels(i)` returns page i of pages_covering(), (P+2B)^2 RGBA8.
ImageRGBA8 assemble_region(const VtConfig& vt, const Region& region, const std::vector<PageId>& pages,
                           const std::function<const std::vector<uint8_t>&(size_t)>& page_texels);

// The region of the given size, at mip `mip`, centred where the most materials are in
// transition (sum over materials of p(1-p) in a window of the weight grid; feature
// materials count double). Deterministic.
Region interesting_region(const SceneAssets& assets, uint32_t mip, int width, int height);

}  // namespace tvt
