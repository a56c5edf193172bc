// Which materials a page can possibly show ("model only what the scene requires"): a material
// whose weight is zero on every weight-grid texel within reach of the page contributes b = 0
// to every texel of it, whatever its mode, so composition may skip it. Exact, not a heuristic:
// culled pages are byte-identical to unculled ones (tests/gpu_compose.cpp).
//
// Reach of material n around the page footprint: one weight texel (bilinear), plus for DPT
// twice the largest patch (corner centres lie up to 1.5 patches away), plus for FBPB a tiling
// period (a meta-texture keeps a feature's centroid within one tile of its texels; a lopsided
// feature's can be most of a tile away, not half).
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "compose/packed_scene.h"
#include "vt/vt_config.h"

namespace tvt {

// Whether material m composes with FBPB features (fbpb or fbpb+dpt).
inline bool fbpb_mode(const gpu::TvtMaterial& m) {
  return m.mode == gpu::TVT_MODE_FBPB || m.mode == gpu::TVT_MODE_FBPB_DPT;
}
// The material LOD at which FBPB features have faded out of direct composition (the end of
// fade_lod): the composers and the culler agree.
inline double fbpb_fade_end(const gpu::TvtMaterial& m) {
  return m.fbpb_fade_hi > m.fbpb_fade_lo ? double(m.fbpb_fade_hi) : double(m.fbpb_fade_lo);
}
// What composing a page reads of each material (composer/material_uploader.h uploads just this).
struct MaterialNeeds {
  uint32_t mask = 0;       // bit n: material n and its weight layer (the culling mask)
  uint32_t meta_mask = 0;  // bit n: material n's FBPB meta-texture
  // Finest mip level of material n's texture that is read (meaningful where `mask` has n).
  std::array<uint8_t, gpu::TVT_MAX_MATERIALS> finest_level{};
  // The union: everything either reads.
  void merge(const MaterialNeeds& other);
};

class MaterialCuller {
 public:
  explicit MaterialCuller(const PackedScene& scene);
  // Recomputes the per-material reach for new parameters (same weights).
  void set_params(const gpu::TvtComposeParams& params);
  // Bit n set: material n may contribute to `page`. The base (bit 0) is always set.
  uint32_t mask(const PageId& page) const;
  // The same for an arbitrary level-0 texel rectangle [x0, x1) x [y0, y1).
  uint32_t mask_rect(int64_t x0, int64_t y0, int64_t x1, int64_t y1) const;
  // What composing `page` reads, for the materials in `mask` (mask(page), or every bit when
  // culling is off). compose_sample.glsl reads material n's texture at the trilinear levels
  // floor(l) and floor(l) + 1 of l = clamp(log2(footprint * R / T), 0, mips - 1), footprint =
  // 2^mip / min(supersample, 2^mip), and its meta-texture only in FBPB modes while the FBPB fade is
  // above 0 (l < fade_lod_hi). Conservative by 1e-3 levels against fp32 rounding.
  MaterialNeeds needs(const PageId& page, uint32_t mask) const;

 private:
  int width_ = 0, height_ = 0, layers_ = 0, log2_vt_ = 0, page_ = 0, border_ = 0;
  gpu::TvtComposeParams params_{};
  std::vector<int64_t> reach_texels_;  // per material
  std::vector<int> layer_of_;          // weight layer per material
  std::vector<uint32_t> nonzero_sat_;  // per layer summed-area table of (weight > 0), (W+1)*(H+1)
  PackedScene scene_;                  // the scene's materials (shared cache), without its weights
};

}  // namespace tvt
