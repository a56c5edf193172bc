#include "support/synthetic_scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <utility>

namespace tvt::test {

SceneAssets make_synthetic_assets(const std::vector<SyntheticMaterial>& materials, uint32_t log2_vt) {
  SceneAssets a;
  a.desc.source_path = "<synthetic>";
  a.desc.seed = 42;
  a.desc.vt.log2_size = log2_vt;
  a.desc.vt.page_texels = 16;
  a.desc.vt.border_texels = 2;
  a.desc.linear_boost = 1.0;
  a.weights.width = 4;
  a.weights.height = 4;
  a.weights.layers = int(materials.size());
  a.weights.data.assign(16 * materials.size(), 0.f);
  float others = 0.f;
  for (size_t n = 0; n < materials.size(); ++n) {
    const SyntheticMaterial& s = materials[n];
    MaterialDesc md;
    md.name = "m" + std::to_string(n);
    md.mode = s.mode;
    md.period_texels = 64.0;
    md.weight.kind = n == 0 ? WeightDesc::Kind::Remainder : WeightDesc::Kind::Rule;
    a.desc.materials.push_back(md);
    ImageRGBA8 img(s.resolution, s.resolution);
    for (size_t t = 0; t < img.texels.size(); t += 4) std::copy(s.rgba.begin(), s.rgba.end(), img.texels.begin() + long(t));
    MaterialAssets ma;
    ma.albedo = build_mip_chain(img);
    a.materials->push_back(std::move(ma));
    if (n > 0) {
      set_weight(a, int(n), s.weight);
      others += s.weight;
    }
  }
  set_weight(a, 0, 1.f - std::clamp(others, 0.f, 1.f));
  return a;
}

namespace {

// Material 1 takes `meta` as its FBPB features, with an albedo that shows them: feature texels
// (0, 200, 0), ground (0, 40, 200), A = 128; its features fade out between lo and hi.
void set_features(SceneAssets& a, MetaTexture meta, float fade_lod_lo, float fade_lod_hi) {
  const int r = meta.resolution;
  ImageRGBA8 albedo(r, r);
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      uint8_t* t = albedo.at(x, y);
      const bool feature = meta.at(x, y).d != 0;
      t[0] = 0, t[1] = feature ? 200 : 40, t[2] = feature ? 0 : 200, t[3] = 128;
    }
  a.materials->edit(1).albedo = build_mip_chain(albedo);
  a.materials->edit(1).meta = std::move(meta);
  a.desc.materials[1].has_fbpb = true;
  a.desc.materials[1].fbpb.fade_lod_lo = fade_lod_lo;
  a.desc.materials[1].fbpb.fade_lod_hi = fade_lod_hi;
}

}  // namespace

SceneAssets big_feature_scene(float p, uint32_t feature_count) {
  SceneAssets a = make_synthetic_assets({k_base, {{0, 40, 200, 128}, p, Mode::Fbpb, 64}});
  MetaTexture meta = square_feature_meta(64, 32, 32, 32);
  meta.feature_count = feature_count;
  set_features(a, std::move(meta), 0.0f, 1.0f);
  return a;
}

SceneAssets small_stone_scene(float fade_lod_lo, float fade_lod_hi, uint32_t feature_count) {
  SceneAssets a = make_synthetic_assets({k_base, {{0, 40, 200, 128}, 0.5f, Mode::FbpbDpt, 64}});
  a.desc.materials[1].dpt.layers = {{16, 0, 1, 1, 0.5}};  // FBPB+DPT needs a layer
  MetaTexture meta;
  meta.resolution = 64;
  meta.texels.resize(64 * 64);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {
      const int dx = 4 - x % 8, dy = 4 - y % 8;
      MetaTexel& t = meta.texels[size_t(y) * 64 + size_t(x)];
      t.variation = 255;
      if (std::abs(dx) <= 2 && std::abs(dy) <= 2) t.d = 1, t.f = 200, t.dx = int16_t(dx), t.dy = int16_t(dy);
    }
  meta.feature_count = feature_count;
  set_features(a, std::move(meta), fade_lod_lo, fade_lod_hi);
  return a;
}

PackedScene pack(const SceneAssets& assets, ComposeOptions options) {
  auto p = pack_scene(assets, options);
  EXPECT_TRUE(p.ok()) << (p.ok() ? "" : p.error().message);
  return std::move(p).value();
}

void set_weight(SceneAssets& a, int layer, float value) {
  std::fill_n(a.weights.data.begin() + long(layer) * 16, 16, value);
}

MetaTexture square_feature_meta(int resolution, int cx, int cy, int side, uint8_t variation) {
  MetaTexture m;
  m.resolution = resolution;
  m.feature_count = 1;
  m.texels.resize(size_t(resolution) * size_t(resolution));
  auto wrap_delta = [&](int d) {
    d %= resolution;
    if (d > resolution / 2) d -= resolution;
    if (d < -resolution / 2) d += resolution;
    return d;
  };
  for (int y = 0; y < resolution; ++y)
    for (int x = 0; x < resolution; ++x) {
      MetaTexel& t = m.texels[size_t(y) * size_t(resolution) + size_t(x)];
      const int dx = wrap_delta(cx - x), dy = wrap_delta(cy - y);
      t.variation = variation;
      if (std::abs(dx) <= side / 2 && std::abs(dy) <= side / 2) {
        t.d = 1;
        t.f = 200;
        t.dx = int16_t(dx);
        t.dy = int16_t(dy);
      }
    }
  return m;
}

}  // namespace tvt::test
