#include "compose/material_culling.h"

#include <algorithm>
#include <cmath>

namespace tvt {

MaterialCuller::MaterialCuller(const PackedScene& s) {
  // The materials' words, for their statistics (not the weights, which the tables below hold).
  scene_ = s.materials_only();
  const gpu::TvtComposeParams& p = s.params;
  width_ = p.weight_width;
  height_ = p.weight_height;
  layers_ = p.weight_layers;
  log2_vt_ = p.log2_vt;
  page_ = p.page_texels;
  border_ = p.border_texels;
  const size_t w1 = size_t(width_) + 1, h1 = size_t(height_) + 1;
  nonzero_sat_.assign(size_t(layers_) * w1 * h1, 0u);
  for (int l = 0; l < layers_; ++l) {
    uint32_t* sat = &nonzero_sat_[size_t(l) * w1 * h1];
    const float* w = &s.weights[size_t(l) * size_t(width_) * size_t(height_)];
    for (int y = 0; y < height_; ++y)
      for (int x = 0; x < width_; ++x) {
        const float v = w[size_t(y) * size_t(width_) + size_t(x)];
        // NaN reads as 0 in the compositors, so only a finite positive weight counts.
        const uint32_t nz = (std::isfinite(v) && v > 0.f) ? 1u : 0u;
        sat[size_t(y + 1) * w1 + size_t(x + 1)] =
            nz + sat[size_t(y) * w1 + size_t(x + 1)] + sat[size_t(y + 1) * w1 + size_t(x)] - sat[size_t(y) * w1 + size_t(x)];
      }
  }
  set_params(p);
}

void MaterialCuller::set_params(const gpu::TvtComposeParams& p) {
  params_ = p;
  reach_texels_.clear();
  layer_of_.clear();
  for (int n = 0; n < p.material_count; ++n) {
    const gpu::TvtMaterial& m = p.materials[n];
    int64_t reach = 0;
    for (int k = 0; k < m.dpt_layer_count; ++k) reach = std::max(reach, 2 * ((m.dpt[k].patch_fp >> 8) + 1));
    // A meta-texture's centroid offsets stay inside one tile (R texels, one period; a lopsided
    // feature's texels can be most of a tile from its centroid), + 2 for the centroid's half
    // texel and the rounding.
    if (m.meta_offset != gpu::TVT_NO_META) reach += (m.period_fp >> 8) + 2;
    reach_texels_.push_back(reach);
    layer_of_.push_back(m.weight_layer);
  }
}

uint32_t MaterialCuller::mask_rect(int64_t x0, int64_t y0, int64_t x1, int64_t y1) const {
  const size_t w1 = size_t(width_) + 1, h1 = size_t(height_) + 1;
  uint32_t mask = 1u;
  for (size_t n = 1; n < reach_texels_.size(); ++n) {
    const int64_t r = reach_texels_[n];
    // Weight texel i covers level-0 [i, i+1) * V / W; bilinear reads one more on each side.
    auto cell = [&](int64_t texel, int size) { return (texel * size) >> log2_vt_; };
    const int64_t i0 = std::clamp<int64_t>(cell(x0 - r, width_) - 1, 0, width_ - 1);
    const int64_t i1 = std::clamp<int64_t>(cell(x1 + r, width_) + 1, 0, width_ - 1);
    const int64_t j0 = std::clamp<int64_t>(cell(y0 - r, height_) - 1, 0, height_ - 1);
    const int64_t j1 = std::clamp<int64_t>(cell(y1 + r, height_) + 1, 0, height_ - 1);
    const uint32_t* sat = &nonzero_sat_[size_t(layer_of_[n]) * w1 * h1];
    const uint32_t count = sat[size_t(j1 + 1) * w1 + size_t(i1 + 1)] - sat[size_t(j0) * w1 + size_t(i1 + 1)] -
                           sat[size_t(j1 + 1) * w1 + size_t(i0)] + sat[size_t(j0) * w1 + size_t(i0)];
    if (count > 0) mask |= 1u << n;
  }
  return mask;
}

uint32_t MaterialCuller::mask(const PageId& page) const {
  const int64_t P = page_, B = border_;
  const int m = int(page.mip);
  const int64_t x0 = (int64_t(page.x) * P - B) << m, y0 = (int64_t(page.y) * P - B) << m;
  const int64_t x1 = (int64_t(page.x + 1) * P + B) << m, y1 = (int64_t(page.y + 1) * P + B) << m;
  return mask_rect(x0, y0, x1, y1);
}

void MaterialNeeds::merge(const MaterialNeeds& other) {
  for (size_t n = 0; n < finest_level.size(); ++n) {
    const uint32_t bit = 1u << n;
    if ((other.mask & bit) && (!(mask & bit) || other.finest_level[n] < finest_level[n]))
      finest_level[n] = other.finest_level[n];
  }
  mask |= other.mask;
  meta_mask |= other.meta_mask;
}

MaterialNeeds MaterialCuller::needs(const PageId& page, uint32_t mask) const {
  constexpr double k_margin = 1e-3;  // levels; fp32 log2 of the same product errs by < 1e-6
  MaterialNeeds out;
  // compose.comp's footprint: min(supersample, 2^mip) samples a side.
  const double footprint =
      std::ldexp(1.0, int(page.mip)) / double(std::clamp(params_.supersample, 1, 1 << std::min<int>(int(page.mip), 30)));
  for (int n = 0; n < params_.material_count; ++n) {
    const uint32_t bit = 1u << n;
    if (!(mask & bit)) continue;
    const gpu::TvtMaterial& m = params_.materials[n];
    // material_lod() in compose_sample.glsl.
    const double lod = std::log2(std::max(footprint, 1.0 / 256.0) * double(m.resolution) * 256.0 / double(m.period_fp));
    out.mask |= bit;
    // Direct, the FBPB branch reads the meta-texture while fade = 1 - ramp(lod, lo, hi) > 0.
    // Prefiltered, it reads it (the features at points, then their statistics chain) at every
    // mip where level 0 has features (fade0 > 0: the level-0 LOD below the fade's end), and the
    // features at points (tvt_feature_points_hold) read the texture tvt_feature_point_lods(k)
    // finer than the footprint, k from tvt_feature_points() (above 2 only under FBPB+DPT). Both
    // take the feature size in the material's statistics block: the material is loaded here
    // (the upload of what this returns loads it anyway); one that fails to load is taken at
    // points with k > 2, and its upload reports the error.
    const bool fbpb_meta = n > 0 && fbpb_mode(m) && m.meta_offset != gpu::TVT_NO_META;
    const bool prefiltered = params_.prefiltered != 0 && page.mip > 0;
    const double level0_lod = std::log2(double(m.resolution) * 256.0 / double(m.period_fp));
    const bool level0_features = prefiltered && level0_lod - k_margin < fbpb_fade_end(m);
    const bool loaded = fbpb_meta && level0_features && scene_.load(bit);
    const float size = loaded ? scene_.stat(size_t(n), gpu::TVT_STATS_FEATURE_LOG2_SIZE) : INFINITY;
    const bool points = fbpb_meta && level0_features && gpu::tvt_feature_points_hold(float(lod - k_margin), size);
    const bool with_dpt = m.mode == gpu::TVT_MODE_FBPB_DPT;
    // At the finest level the reach can take: k from the LOD a margin above (tvt_feature_points
    // grows with the LOD), and the size unknown taken as every size (-inf).
    const int k = gpu::tvt_feature_points(float(lod + k_margin), loaded ? size : -INFINITY, with_dpt);
    const double finer = points ? double(gpu::tvt_feature_point_lods(k)) : 0.0;
    const double level = std::clamp(lod - finer - k_margin, 0.0, double(std::max(m.mip_count - 1, 0)));
    out.finest_level[size_t(n)] = uint8_t(std::floor(level));
    if (fbpb_meta && (prefiltered ? level0_features : lod - k_margin < fbpb_fade_end(m))) out.meta_mask |= bit;
  }
  return out;
}

}  // namespace tvt
