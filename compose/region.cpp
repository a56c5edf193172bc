#include "compose/region.h"

#include <algorithm>
#include <cstring>

namespace tvt {

std::vector<PageId> pages_covering(const VtConfig& vt, const Region& r) {
  std::vector<PageId> pages;
  const int64_t P = vt.page_texels;
  const int64_t n = int64_t(vt.pages_per_side(r.mip));
  const int64_t px0 = std::clamp<int64_t>(r.x / P, 0, n - 1), py0 = std::clamp<int64_t>(r.y / P, 0, n - 1);
  const int64_t px1 = std::clamp<int64_t>((r.x + r.width - 1) / P, 0, n - 1);
  const int64_t py1 = std::clamp<int64_t>((r.y + r.height - 1) / P, 0, n - 1);
  for (int64_t py = py0; py <= py1; ++py)
    for (int64_t px = px0; px <= px1; ++px) pages.push_back(PageId{r.mip, uint32_t(px), uint32_t(py)});
  return pages;
}

ImageRGBA8 assemble_region(const VtConfig& vt, const Region& r, const std::vector<PageId>& pages,
                           const std::function<const std::vector<uint8_t>&(size_t)>& page_texels) {
  ImageRGBA8 out(r.width, r.height);
  const int64_t P = vt.page_texels, B = vt.border_texels, S = P + 2 * B;
  for (size_t i = 0; i < pages.size(); ++i) {
    const std::vector<uint8_t>& texels = page_texels(i);
    const int64_t ox = int64_t(pages[i].x) * P, oy = int64_t(pages[i].y) * P;
    for (int64_t ty = 0; ty < P; ++ty) {
      const int64_t y = oy + ty - r.y;
      if (y < 0 || y >= r.height) continue;
      for (int64_t tx = 0; tx < P; ++tx) {
        const int64_t x = ox + tx - r.x;
        if (x < 0 || x >= r.width) continue;
        std::memcpy(out.at(int(x), int(y)), &texels[size_t(((ty + B) * S + tx + B) * 4)], 4);
      }
    }
  }
  return out;
}

Region interesting_region(const SceneAssets& assets, uint32_t mip, int width, int height) {
  const WeightGrid& g = assets.weights;
  const VtConfig& vt = assets.desc.vt;
  const int64_t mip_size = int64_t(vt.mip_texels(mip));
  width = int(std::min<int64_t>(width, mip_size));
  height = int(std::min<int64_t>(height, mip_size));
  // Score every weight texel, then sum over a window the size of the region.
  std::vector<double> score(size_t(g.width) * size_t(g.height), 0.0);
  for (int l = 1; l < g.layers; ++l) {
    // Without reading texels: an FBPB meta-texture not loaded yet counts as having features.
    const MaterialInfo info = assets.materials->info(size_t(l));
    const bool features = info.meta && (!info.features_known || info.feature_count > 0);
    for (int y = 0; y < g.height; ++y)
      for (int x = 0; x < g.width; ++x) {
        const double p = g.at(l, x, y);
        score[size_t(y) * size_t(g.width) + size_t(x)] += (features ? 2.0 : 1.0) * p * (1.0 - p);
      }
  }
  const double texels_per_cell_x = double(mip_size) / g.width, texels_per_cell_y = double(mip_size) / g.height;
  const int wx = std::max(1, int(width / texels_per_cell_x)), wy = std::max(1, int(height / texels_per_cell_y));
  // Summed-area table, so every window costs four lookups.
  const size_t W1 = size_t(g.width) + 1;
  std::vector<double> sat(W1 * (size_t(g.height) + 1), 0.0);
  for (int y = 0; y < g.height; ++y)
    for (int x = 0; x < g.width; ++x)
      sat[size_t(y + 1) * W1 + size_t(x + 1)] = score[size_t(y) * size_t(g.width) + size_t(x)] +
                                                sat[size_t(y) * W1 + size_t(x + 1)] +
                                                sat[size_t(y + 1) * W1 + size_t(x)] - sat[size_t(y) * W1 + size_t(x)];
  auto window = [&](int x, int y) {
    return sat[size_t(y + wy) * W1 + size_t(x + wx)] - sat[size_t(y) * W1 + size_t(x + wx)] -
           sat[size_t(y + wy) * W1 + size_t(x)] + sat[size_t(y) * W1 + size_t(x)];
  };
  double best = -1;
  int bx = 0, by = 0;
  for (int y = 0; y + wy <= g.height; ++y)
    for (int x = 0; x + wx <= g.width; ++x) {
      const double s = window(x, y);
      if (s > best) best = s, bx = x, by = y;
    }
  Region r;
  r.mip = mip;
  r.width = width;
  r.height = height;
  r.x = std::clamp<int64_t>(int64_t(bx * texels_per_cell_x), 0, mip_size - width);
  r.y = std::clamp<int64_t>(int64_t(by * texels_per_cell_y), 0, mip_size - height);
  return r;
}

}  // namespace tvt
