// Equation-level tests of the CPU reference compositor on hand-made scenes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <vector>

#include "compose/material_source.h"
#include "compose/reference_compositor.h"
#include "compose/scene_identity.h"
#include "shaders/shared/hash.h"
#include "support/synthetic_scene.h"

using namespace tvt;
using test::SyntheticMaterial;

namespace {

constexpr int64_t fp(int64_t texel) { return texel * 256 + 128; }  // level-0 texel centre

glm::dvec4 at(const PackedScene& s, int64_t x, int64_t y, double footprint = 1.0) {
  return compose_sample_reference(s, fp(x), fp(y), footprint);
}

PackedScene pack(const SceneAssets& a, ComposeOptions o = {}) {
  auto p = pack_scene(a, o);
  EXPECT_TRUE(p.ok()) << (p.ok() ? "" : p.error().message);
  return std::move(p).value();
}

double blend_map(double b, double a, double s) {
  const double e0 = 1 - b - s, e1 = 1 - b + s, x = s + a * (1 - 2 * s);
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

const SyntheticMaterial k_base{{200, 0, 0, 100}, 0.f, Mode::BlendMap};

}  // namespace

TEST(Linear, NormalisedAverageWithoutBoost) {
  auto a = test::make_synthetic_assets({k_base, {{0, 200, 0, 50}, 0.75f, Mode::Linear}});
  const PackedScene s = pack(a);
  const glm::dvec4 c = at(s, 100, 100);
  EXPECT_NEAR(c.r, 0.25 * 200 / 255.0, 1e-9);
  EXPECT_NEAR(c.g, 0.75 * 200 / 255.0, 1e-9);
  EXPECT_NEAR(c.a, (0.25 * 100 + 0.75 * 50) / 255.0, 1e-9);
}

TEST(Linear, BoostFollowsBloomThenClamps) {
  auto a = test::make_synthetic_assets({k_base, {{0, 200, 0, 50}, 0.3f, Mode::Linear}});
  a.desc.linear_boost = 1.5;
  PackedScene s = pack(a);
  // b = min(1, 1.5 * 0.3 / (0.7 + 0.3)) = 0.45
  EXPECT_NEAR(at(s, 7, 9).g, 0.45 * 200 / 255.0, 1e-6);
  test::set_weight(a, 1, 0.8f);
  test::set_weight(a, 0, 0.2f);
  s = pack(a);
  EXPECT_NEAR(at(s, 7, 9).g, 200 / 255.0, 1e-9);  // 1.5 * 0.8 > 1: clamped, fully opaque
}

TEST(BlendMap, MatchesFormulaAndIsMonotone) {
  for (double h : {0.0, 0.3, 0.5, 1.0}) {
    double previous = -1;
    for (float p : {0.f, 0.1f, 0.25f, 0.5f, 0.75f, 0.9f, 1.f}) {
      auto a = test::make_synthetic_assets({k_base, {{0, 255, 0, uint8_t(h * 255)}, p, Mode::BlendMap}});
      const PackedScene s = pack(a);
      const double g = at(s, 3, 3).g;
      const double hq = double(uint8_t(h * 255)) / 255.0;  // the material stores A in 8 bits
      EXPECT_NEAR(g, blend_map(p, hq, 0.1), 1e-6) << "p=" << p << " h=" << h;
      EXPECT_GE(g, previous - 1e-12);
      previous = g;
    }
  }
  // 0 at b = 0 and 1 at b = 1 whatever the height.
  auto a0 = test::make_synthetic_assets({k_base, {{0, 255, 0, 255}, 0.f, Mode::BlendMap}});
  EXPECT_EQ(at(pack(a0), 1, 1).g, 0.0);
  auto a1 = test::make_synthetic_assets({k_base, {{0, 255, 0, 0}, 1.f, Mode::BlendMap}});
  EXPECT_NEAR(at(pack(a1), 1, 1).g, 1.0, 1e-12);
}

// FBPB: material 1 has one 5x5 square feature centred on material texel (8, 8) of 16; period
// 64 level-0 texels -> 4 level-0 texels per material texel.
class Fbpb : public ::testing::Test {
 protected:
  SceneAssets make(float p, double cf = 1.0, uint8_t variation = 255) {
    auto a = test::make_synthetic_assets({k_base, {{0, 250, 0, 200}, p, Mode::Fbpb}});
    a.materials->edit(1).meta = test::square_feature_meta(16, 8, 8, 5, variation);
    a.desc.materials[1].has_fbpb = true;
    a.desc.materials[1].fbpb.cf = cf;
    return a;
  }
  // Global material-texel centroid of the feature in tile (tx, ty).
  static uint32_t feature_hash(const PackedScene& s, int64_t tx, int64_t ty) {
    return gpu::tvt_hash_coord(tx * 16 + 8, ty * 16 + 8, s.params.materials[1].fbpb_salt);
  }
};

TEST_F(Fbpb, FullWeightShowsEveryFeatureOpaque) {
  const PackedScene s = pack(make(1.f));
  // Feature texel (material texel 8 = level-0 texels 32..35 of each 64 tile).
  EXPECT_NEAR(at(s, 33, 33).g, 250 / 255.0, 1e-9);         // w = min(Cm*max(p,f),1) = 1
  EXPECT_NEAR(at(s, 64 * 5 + 33, 64 * 7 + 34).g, 250 / 255.0, 1e-9);
  // Non-feature texel: w = (1-d) p Cn = 1.
  EXPECT_NEAR(at(s, 2, 2).g, 250 / 255.0, 1e-9);
}

TEST_F(Fbpb, Equation31PerFeatureDecision) {
  const float p = 0.3f;
  const PackedScene s = pack(make(p));
  int shown = 0;
  for (int64_t ty = 0; ty < 16; ++ty)
    for (int64_t tx = 0; tx < 16; ++tx) {
      const double r = gpu::tvt_rand01(feature_hash(s, tx, ty));
      const bool visible = r <= double(p) * 1.0;
      shown += visible;
      const double f = 200 / 255.0;
      const double w = visible ? std::min(1.5 * std::max(double(p), f), 1.0) : 0.0;  // d = 1: (1-d)pCn = 0
      // Every texel of the feature agrees (all share p and r).
      for (int64_t dy : {-8, 0, 9})
        for (int64_t dx : {-8, 1, 9}) {
          const glm::dvec4 c = at(s, tx * 64 + 34 + dx, ty * 64 + 34 + dy);
          EXPECT_NEAR(c.g, w * 250 / 255.0, 1e-6) << tx << "," << ty;
        }
      // Non-feature texel of that tile: w = p * Cn.
      EXPECT_NEAR(at(s, tx * 64 + 2, ty * 64 + 2).g, double(p) * 250 / 255.0, 1e-6);
    }
  EXPECT_GT(shown, 256 * 0.15);  // about p of the features show
  EXPECT_LT(shown, 256 * 0.45);
}

TEST_F(Fbpb, CfScalesVisibilityAndZeroWeightHidesAll) {
  const PackedScene none = pack(make(0.f));
  for (int64_t t = 0; t < 16; ++t) EXPECT_EQ(at(none, t * 64 + 33, 33).g, 0.0);
  const PackedScene all = pack(make(0.5f, 2.0));  // p*Cf = 1 >= every r
  for (int64_t t = 0; t < 16; ++t) EXPECT_NEAR(at(all, t * 64 + 33, 97).g, 250 / 255.0, 1e-9);
}

TEST_F(Fbpb, VariationChipsVisibleFeatures) {
  // Variation 0 everywhere: every visible feature with p < 1 is chipped: d <- 0, colour * Cc,
  // w = p * Cn, and it no longer counts as visible.
  const PackedScene s = pack(make(0.5f, 2.0, 0));
  EXPECT_NEAR(at(s, 33, 33).g, 0.5 * 0.75 * 250 / 255.0, 1e-6);
  // At p = 1 variations do not apply (Algorithm 1 only for p < 1).
  const PackedScene full = pack(make(1.f, 1.0, 0));
  EXPECT_NEAR(at(full, 33, 33).g, 250 / 255.0, 1e-9);
}

TEST_F(Fbpb, PrecedenceKeepsLowerVisibleFeatures) {
  auto a = make(1.f);
  // A higher non-feature layer at full weight over every texel.
  a.desc.materials.push_back(a.desc.materials[0]);
  a.desc.materials.back().weight.kind = WeightDesc::Kind::Rule;
  a.desc.materials.back().mode = Mode::BlendMap;
  ImageRGBA8 blue(16, 16);
  for (size_t t = 0; t < blue.texels.size(); t += 4) blue.texels[t + 2] = 240, blue.texels[t + 3] = 255;
  MaterialAssets m;
  m.albedo = build_mip_chain(blue);
  a.materials->push_back(std::move(m));
  a.weights.layers = 3;
  a.weights.data.resize(48, 0.f);
  test::set_weight(a, 2, 1.f);
  const PackedScene s = pack(a);
  const glm::dvec4 feature = at(s, 33, 33), mortar = at(s, 2, 2);
  EXPECT_NEAR(feature.g, 250 / 255.0, 1e-9);  // the cobble stays on top
  EXPECT_EQ(feature.b, 0.0);
  EXPECT_NEAR(mortar.b, 240 / 255.0, 1e-9);   // non-feature texels are covered
}

// DPT on a constant weight: the patch mask at corners, bilinear in between.
class Dpt : public ::testing::Test {
 protected:
  SceneAssets make(float p, std::vector<DptLayerDesc> layers) {
    auto a = test::make_synthetic_assets({k_base, {{0, 255, 0, 128}, p, Mode::Dpt}});
    a.desc.materials[1].dpt.layers = std::move(layers);
    a.desc.materials[1].blend_sharpness = 0.1;
    return a;
  }
};

TEST_F(Dpt, FullAndZeroWeight) {
  const PackedScene one = pack(make(1.f, {{32, 1, 1, 1, 0.5}}));
  EXPECT_NEAR(at(one, 5, 70).g, 1.0, 1e-9);
  EXPECT_NEAR(at(one, 5, 70).a, 0.5, 1e-9);  // h = min(w H, 1) goes to the height channel
  const PackedScene zero = pack(make(0.f, {{32, 1, 1, 1, 0.5}}));
  EXPECT_EQ(at(zero, 5, 70).g, 0.0);
}

TEST_F(Dpt, CornersAndBilinearWeights) {
  const float p = 0.5f;
  const PackedScene s = pack(make(p, {{32, 1, 1, 1, 1.0}}));
  const uint32_t salt = s.params.materials[1].dpt[0].salt;
  auto mask = [&](int64_t jx, int64_t jy) { return gpu::tvt_rand01(gpu::tvt_hash_coord(jx, jy, salt)) <= p ? 1.0 : 0.0; };
  int on = 0;
  for (int64_t j = 0; j < 20; ++j)
    for (int64_t i = 0; i < 20; ++i) {
      // Exactly at patch origin (i*32, j*32) in fixed point: f = 0 -> the corner's mask.
      const glm::dvec4 c = compose_sample_reference(s, i * 32 * 256, j * 32 * 256, 1.0);
      const double m = mask(i, j);
      on += int(m);
      EXPECT_NEAR(c.g, blend_map(m, 128 / 255.0, 0.1), 1e-6);
      // Patch middle: f = (0.5, 0.5): average of the four corners.
      const glm::dvec4 mid = compose_sample_reference(s, (i * 32 + 16) * 256, (j * 32 + 16) * 256, 1.0);
      const double avg = (mask(i, j) + mask(i + 1, j) + mask(i, j + 1) + mask(i + 1, j + 1)) / 4;
      EXPECT_NEAR(mid.g, blend_map(avg, 128 / 255.0, 0.1), 1e-6);
      // Height: DPT's h = min(w * H, 1) with H = 1, mixed by b over the base's A (100).
      const double b = blend_map(avg, 128 / 255.0, 0.1);
      EXPECT_NEAR(mid.a, (100 / 255.0) * (1 - b) + avg * b, 1e-6);
    }
  EXPECT_GT(on, 120);
  EXPECT_LT(on, 280);
}

TEST_F(Dpt, ExponentsShapeTheMask) {
  // P: p^P; with P -> large, p = 0.5 gives p_j ~ 0 -> no patches; R -> large makes r^R ~ 0 -> all.
  const PackedScene none = pack(make(0.5f, {{32, 1000, 1, 1, 0}}));
  const PackedScene all = pack(make(0.5f, {{32, 1, 1000, 1, 0}}));
  double sum_none = 0, sum_all = 0;
  for (int64_t i = 0; i < 50; ++i) {
    sum_none += at(none, i * 13, i * 7).g;
    sum_all += at(all, i * 13, i * 7).g;
  }
  EXPECT_LT(sum_none, 1e-6);
  EXPECT_NEAR(sum_all, 50.0, 1e-6);
  // W = 1e3 sharpens: interior bilinear values < 1 go to ~0; W = 1e-3 lifts them to ~1.
  const PackedScene sharp = pack(make(0.5f, {{32, 1, 1, 1000, 0}}));
  const PackedScene soft = pack(make(0.5f, {{32, 1, 1, 0.001, 0}}));
  for (int64_t i = 0; i < 30; ++i) {
    const double g_sharp = compose_sample_reference(sharp, (i * 32 + 16) * 256, 16 * 256, 1.0).g;
    const double g_soft = compose_sample_reference(soft, (i * 32 + 16) * 256, 16 * 256, 1.0).g;
    EXPECT_TRUE(g_sharp < 1e-3 || g_sharp > 1 - 1e-3);
    EXPECT_TRUE(g_soft < 1e-3 || g_soft > 1 - 1e-3);
  }
}

TEST_F(Dpt, MinificationFadesToThePlainBlend) {
  const float p = 0.4f;
  const PackedScene s = pack(make(p, {{8, 1, 1, 1, 0.5}}));  // 8-texel patches, fade 2..8 texels
  const double plain = blend_map(p, 128 / 255.0, 0.1);
  // footprint 8 level-0 texels: a patch spans 1 texel < fade_lo -> plain blend map.
  EXPECT_NEAR(compose_sample_reference(s, fp(100), fp(100), 8.0).g, plain, 1e-9);
  // footprint 2: 4 texels per patch -> fade a = (4-2)/(8-2) = 1/3 on both the layer and the result.
  const uint32_t salt = s.params.materials[1].dpt[0].salt;
  auto mask = [&](int64_t jx, int64_t jy) { return gpu::tvt_rand01(gpu::tvt_hash_coord(jx, jy, salt)) <= p ? 1.0 : 0.0; };
  const double f = (100.5 - 96.0) / 8.0;  // texel 100 in patch 12
  const double w = (mask(12, 12) * (1 - f) + mask(13, 12) * f) * (1 - f) + (mask(12, 13) * (1 - f) + mask(13, 13) * f) * f;
  const double a = 1.0 / 3.0;
  const double expected = a * blend_map(a * w, 128 / 255.0, 0.1) + (1 - a) * plain;
  EXPECT_NEAR(compose_sample_reference(s, fp(100), fp(100), 2.0).g, expected, 1e-6);
  // footprint 1: 8 texels per patch -> fully DPT.
  EXPECT_NEAR(compose_sample_reference(s, fp(100), fp(100), 1.0).g, blend_map(w, 128 / 255.0, 0.1), 1e-6);
}

TEST(Extremes, NoNaNAnywhere) {
  for (double patch : {0.001, 0.5, 1.0, 3.0, 1e9}) {
    for (double e : {1e-3, 1.0, 1e3}) {
      for (float p : {0.f, std::ldexp(1.f, -24), 0.5f, 1.f}) {
        auto a = test::make_synthetic_assets({k_base, {{10, 20, 30, 40}, p, Mode::FbpbDpt}}, 24);
        a.materials->edit(1).meta = test::square_feature_meta(16, 0, 0, 7, 100);
        a.desc.materials[1].has_fbpb = true;
        a.desc.materials[1].period_texels = 1.0;  // tiling period of one texel
        a.desc.materials[1].dpt.layers = {{patch, e, e, e, e}, {patch * 3, e, e, e, 1e6}};
        const PackedScene s = pack(a);
        const int64_t far = (int64_t(1) << 24) - 1;
        for (uint32_t mip : {0u, 3u, 17u})
          for (int64_t x : {int64_t(0), far >> mip}) {
            const glm::dvec4 c = compose_texel_reference(s, mip, x, x);
            for (int i = 0; i < 4; ++i) {
              EXPECT_TRUE(std::isfinite(c[i])) << patch << " " << e << " " << p;
              EXPECT_GE(c[i], 0.0);
              EXPECT_LE(c[i], 1.0);
            }
          }
      }
    }
  }
}

TEST(Extremes, NonFiniteWeightsReadAsZero) {
  auto a = test::make_synthetic_assets({k_base, {{0, 250, 0, 0}, 0.f, Mode::Linear}});
  test::set_weight(a, 1, std::nanf(""));
  test::set_weight(a, 0, std::numeric_limits<float>::infinity());
  const glm::dvec4 c = at(pack(a), 3, 3);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(std::isfinite(c[i]));
  EXPECT_EQ(c.g, 0.0);
}

TEST(Pages, DeterministicAndBordersMatchNeighbours) {
  auto a = test::make_synthetic_assets({k_base, {{0, 250, 0, 200}, 0.5f, Mode::FbpbDpt}});
  a.materials->edit(1).meta = test::square_feature_meta(16, 3, 5, 5, 60);
  a.desc.materials[1].has_fbpb = true;
  a.desc.materials[1].dpt.layers = {{24, 1, 1, 1, 0.5}, {6, 0.5, 1.5, 1, 0.2}};
  // Non-constant weights so neighbouring pages differ.
  for (size_t i = 0; i < 16; ++i) a.weights.data[16 + i] = float(i % 5) / 4.f;
  const PackedScene s = pack(a);
  const PageId p0{1, 3, 4}, p1{1, 4, 4};
  const auto first = compose_page_reference(s, p0).value();
  EXPECT_EQ(first, compose_page_reference(s, p0).value());
  const auto right = compose_page_reference(s, p1).value();
  const int P = 16, B = 2, S = P + 2 * B;
  for (int y = 0; y < S; ++y)
    for (int bx = 0; bx < B; ++bx) {
      // Right border of p0 (x = B + P + bx) equals p1's interior column bx + B.
      for (int c = 0; c < 4; ++c)
        EXPECT_EQ(first[size_t((y * S + B + P + bx) * 4 + c)], right[size_t((y * S + B + bx) * 4 + c)]);
    }
}

TEST(Hash, RandomNumbersCoverTheirBoundsExactly) {
  EXPECT_EQ(gpu::tvt_rand01(0u), std::ldexp(1.f, -24));  // smallest r: never 0, so r <= p*Cf is safe
  EXPECT_EQ(gpu::tvt_rand01(0xffffffffu), 1.f);          // largest r: exactly 1, shown only at p*Cf >= 1
  EXPECT_EQ(gpu::tvt_rand01(0xffu), std::ldexp(1.f, -24));  // the low 8 bits never matter
  // Decorrelated coordinates: swapping x and y, or a neighbouring salt, changes the hash.
  EXPECT_NE(gpu::tvt_hash_coord(3, 5, 1), gpu::tvt_hash_coord(5, 3, 1));
  EXPECT_NE(gpu::tvt_hash_coord(3, 5, 1), gpu::tvt_hash_coord(3, 5, 2));
  EXPECT_NE(gpu::tvt_hash_coord(int64_t(1) << 32, 0, 1), gpu::tvt_hash_coord(0, 0, 1));
  // Roughly uniform: mean of r over 2^16 coordinates.
  double sum = 0;
  for (int64_t i = 0; i < 65536; ++i) sum += gpu::tvt_rand01(gpu::tvt_hash_coord(i & 255, i >> 8, 9));
  EXPECT_NEAR(sum / 65536, 0.5, 0.01);
}

TEST(Extremes, AllFeatureMaskAndFullVisibility) {
  // Every texel is one feature covering the whole tile; at p = 1, r <= p*Cf always holds.
  auto a = test::make_synthetic_assets({k_base, {{0, 250, 0, 200}, 1.f, Mode::Fbpb}});
  a.materials->edit(1).meta = test::square_feature_meta(16, 8, 8, 16);
  a.desc.materials[1].has_fbpb = true;
  const PackedScene s = pack(a);
  for (int64_t x : {0, 17, 63, 64, 1000}) EXPECT_NEAR(at(s, x, x * 3 % 1024).g, 250 / 255.0, 1e-9);
}

// A mip-m texel never takes more than 2^m samples a side (the level-0 texels it covers): mip 0
// is direct under every strategy, and at mip 1 supersample:64 is supersample:2.
TEST(Mips, SupersamplingIsCappedAtTheLevel0TexelsATexelCovers) {
  auto a = test::make_synthetic_assets({k_base, {{0, 250, 0, 200}, 0.5f, Mode::Dpt}});
  a.desc.materials[1].dpt.layers = {{6, 1, 1, 1, 0.5}};
  for (size_t i = 0; i < 16; ++i) a.weights.data[16 + i] = float(i % 3) / 2.f;
  ComposeOptions o64, o2;
  o64.supersample = 64;
  o2.supersample = 2;
  const PackedScene s64 = pack(a, o64), s2 = pack(a, o2), s1 = pack(a);
  for (int64_t y = 0; y < 6; ++y)
    for (int64_t x = 0; x < 6; ++x) {
      EXPECT_EQ(compose_texel_reference(s64, 0, x * 9, y * 5), compose_texel_reference(s1, 0, x * 9, y * 5));
      EXPECT_EQ(compose_texel_reference(s64, 1, x * 9, y * 5), compose_texel_reference(s2, 1, x * 9, y * 5));
    }
}

TEST(Mips, StrategyNamesRoundTripAndEverythingElseIsRefused) {
  for (const char* name : {"direct", "prefiltered", "supersample:2", "supersample:4", "supersample:64"}) {
    auto s = mip_strategy_from_string(name);
    ASSERT_TRUE(s.ok()) << name;
    EXPECT_EQ(to_string(s.value()), name);
  }
  EXPECT_EQ(mip_strategy_from_string("direct")->supersample, 1u);
  EXPECT_EQ(mip_strategy_from_string("supersample:8")->supersample, 8u);
  for (const char* bad : {"", "Direct", "supersample", "supersample:", "supersample:1", "supersample:3", "supersample:128",
                          "supersample:-2", "supersample:+4", "supersample:04x", "supersample: 4", "supersample:0",
                          "supersample:999999999999", "Prefiltered", "prefiltered:2", "prefilter"}) {
    auto s = mip_strategy_from_string(bad);
    ASSERT_FALSE(s.ok()) << "'" << bad << "'";
    EXPECT_NE(s.error().message.find("supersample:S"), std::string::npos) << s.error().message;
  }
}

// A store baked with a non-direct strategy holds other pages at mip >= 1: its identity differs.
// Direct adds nothing, so stores baked before the strategy existed keep their identity.
TEST(Mips, TheStrategyIsPartOfTheSceneIdentityUnlessDirect) {
  const SceneDesc scene = default_scene();
  EXPECT_EQ(scene_identity(scene, Method::Dpt2), scene_identity(scene, Method::Dpt2, MipStrategy{}));
  EXPECT_NE(scene_identity(scene, Method::Dpt2), scene_identity(scene, Method::Dpt2, MipStrategy{4}));
  EXPECT_NE(scene_identity(scene, Method::Dpt2, MipStrategy{2}), scene_identity(scene, Method::Dpt2, MipStrategy{4}));
  const MipStrategy prefiltered{1, true};
  EXPECT_EQ(mip_strategy_from_string("prefiltered").value(), prefiltered);
  EXPECT_NE(scene_identity(scene, Method::Dpt2), scene_identity(scene, Method::Dpt2, prefiltered));
  EXPECT_NE(scene_identity(scene, Method::Dpt2, MipStrategy{2}), scene_identity(scene, Method::Dpt2, prefiltered));
}

namespace {

// A DPT layer of `patch` texels over a base, weight `w` everywhere; materials of constant colour.
SceneAssets dpt_scene(double patch, float w, double p = 1, double r = 1, double wexp = 1) {
  auto a = test::make_synthetic_assets({k_base, {{0, 250, 0, 200}, w, Mode::Dpt}});
  a.desc.materials[1].dpt.layers = {{patch, p, r, wexp, 0.5}};
  return a;
}

ComposeOptions prefiltered_options() {
  ComposeOptions o;
  o.prefiltered = true;
  return o;
}

}  // namespace

// Mip 0 is direct under the prefiltered strategy too; and it refuses supersampling on top.
TEST(Prefiltered, Mip0IsTheDirectComposition) {
  auto a = dpt_scene(6, 0.5f);
  for (size_t i = 0; i < 16; ++i) a.weights.data[16 + i] = float(i % 3) / 2.f;
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  for (int64_t y = 0; y < 8; ++y)
    for (int64_t x = 0; x < 8; ++x) EXPECT_EQ(compose_texel_reference(direct, 0, x * 9, y * 5), compose_texel_reference(pre, 0, x * 9, y * 5));
  ComposeOptions both = prefiltered_options();
  both.supersample = 4;
  EXPECT_FALSE(pack_scene(a, both).ok());
}

// Patches far smaller than a texel, over a material whose blend map A spreads over [0, 1]:
// direct composition shows one patch's decision per texel, or (faded) the plain weight; the
// prefiltered texel is the patches' expected coverage through the blend map's mean over A,
// which is what the box filter of level 0 converges to. (Where A hardly varies: the next test.)
TEST(Prefiltered, ConvergesToTheBoxFilteredTruthWherePatchesAreSmall) {
  // Patches of 2 texels, present at level 0 (fade from 0.5 to 1 texel), 256 to a mip-5 texel;
  // P != R, where the coverage w^(P/R) is not the plain weight direct composition falls back to.
  for (const double pexp : {0.5, 2.0}) {
    SceneAssets a = dpt_scene(2, 0.5f, pexp, 1.0, 1.0);
    a.desc.materials[1].dpt.fade_lo_texels = 0.5;
    a.desc.materials[1].dpt.fade_hi_texels = 1.0;
    ImageRGBA8 spread(16, 16);  // every A value 0..255 once, scattered
    for (int i = 0; i < 256; ++i) {
      uint8_t* t = spread.at(i % 16, i / 16);
      t[0] = 0, t[1] = 250, t[2] = 0, t[3] = uint8_t((i * 97 + 13) % 256);
    }
    a.materials->edit(1).albedo = build_mip_chain(spread);
    const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
    double err_direct = 0, err_pre = 0;
    for (int64_t y = 0; y < 4; ++y)
      for (int64_t x = 0; x < 4; ++x) {
        const double truth = ground_truth_texel(direct, 5, x + 8, y + 8).g;  // 32^2 level-0 texels
        err_direct += std::abs(compose_texel_reference(direct, 5, x + 8, y + 8).g - truth);
        err_pre += std::abs(compose_texel_reference(pre, 5, x + 8, y + 8).g - truth);
      }
    EXPECT_LT(err_pre / 16, 0.06) << "P = " << pexp;  // the truth's own noise: ~256 patch decisions a texel
    EXPECT_LT(err_pre, 0.5 * err_direct) << "P = " << pexp;
  }
}

// The same where A does not vary at all, so the blend map is a sharp threshold of the patch
// ramps: the mean of the thresholded ramps is not the threshold of their mean coverage (here
// the mean coverage, 1/2, is over the threshold everywhere, yet much of each cell is under it).
// The prefiltered texel carries the ramps' spread (mean and variance), and lands near the box
// filter where the mean coverage alone would miss it.
TEST(Prefiltered, FollowsTheSpreadOfThePatchesUnderASharpBlendMap) {
  for (const auto& [alpha, wexp] : {std::pair{200, 1.0}, {150, 1.0}, {200, 2.0}, {90, 0.5}}) {
    SceneAssets a = dpt_scene(2, 0.5f, 1.0, 1.0, wexp);
    a.desc.materials[1].dpt.fade_lo_texels = 0.5;
    a.desc.materials[1].dpt.fade_hi_texels = 1.0;
    ImageRGBA8 flat(16, 16);
    for (int i = 0; i < 256; ++i) {
      uint8_t* t = flat.at(i % 16, i / 16);
      t[0] = 0, t[1] = 250, t[2] = 0, t[3] = uint8_t(alpha);
    }
    a.materials->edit(1).albedo = build_mip_chain(flat);
    const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
    double err_direct = 0, err_pre = 0, truth_mean = 0;
    for (int64_t y = 0; y < 4; ++y)
      for (int64_t x = 0; x < 4; ++x) {
        const double truth = ground_truth_texel(direct, 5, x + 8, y + 8).g;
        truth_mean += truth / 16;
        err_direct += std::abs(compose_texel_reference(direct, 5, x + 8, y + 8).g - truth);
        err_pre += std::abs(compose_texel_reference(pre, 5, x + 8, y + 8).g - truth);
      }
    // With the mean coverage alone the texel was the blend map's value at it: 0.33 off the
    // truth at A = 200 (all patch or none), as far as direct composition.
    const std::string what = "A " + std::to_string(alpha) + ", W " + std::to_string(wexp) + ", truth " +
                             std::to_string(truth_mean) + ", direct error " + std::to_string(err_direct / 16);
    EXPECT_LT(err_pre / 16, 0.16) << what;
    EXPECT_LT(err_pre, 0.5 * err_direct) << what;
  }
}

// Patches about as large as the footprint (16-texel patches under mip-4 and mip-5 texels): a
// texel holds one to four patch cells, so the truth is those cells' own corner decisions, which
// the expectation over random decisions misses by the size of one patch's share. The layer's
// values at points over the footprint follow them.
TEST(Prefiltered, FollowsTheFootprintsOwnPatchesWhereTheyAreFew) {
  SceneAssets a = dpt_scene(16, 0.5f);
  ImageRGBA8 varied(16, 16);  // A varies (every value once, scattered), as a height map does
  for (int i = 0; i < 256; ++i) {
    uint8_t* t = varied.at(i % 16, i / 16);
    t[0] = 0, t[1] = 250, t[2] = 0, t[3] = uint8_t((i * 97 + 13) % 256);
  }
  a.materials->edit(1).albedo = build_mip_chain(varied);
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  for (const uint32_t mip : {4u, 5u}) {
    double err = 0, spread = 0, truth_mean = 0;
    const int n = 12;
    std::vector<double> truths;
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const double truth = ground_truth_texel(direct, mip, x + 3, y + 5).g;
        truths.push_back(truth);
        truth_mean += truth / (n * n);
        err += std::abs(compose_texel_reference(pre, mip, x + 3, y + 5).g - truth) / (n * n);
      }
    for (double t : truths) spread += std::abs(t - truth_mean) / (n * n);
    // The texels differ (0.1 and more from their mean: the decisions show); the expectation
    // alone is off by about that much, the footprint's own patches by far less.
    EXPECT_GT(spread, 0.08) << "mip " << mip;
    EXPECT_LT(err, 0.3 * spread) << "mip " << mip << ": mean error " << err << ", truth's spread " << spread;
  }
}

// Where the footprint is below one patch the prefiltered texel is the exact (direct) one.
TEST(Prefiltered, IsExactWhereAPatchCoversTheFootprint) {
  auto a = dpt_scene(256, 0.5f);
  for (size_t i = 0; i < 16; ++i) a.weights.data[16 + i] = float(i % 3) / 2.f;
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  for (int64_t y = 0; y < 6; ++y)
    for (int64_t x = 0; x < 6; ++x)  // mip 2: 4 texels against patches of 256 (fade 1)
      EXPECT_EQ(compose_texel_reference(direct, 2, x * 7, y * 5), compose_texel_reference(pre, 2, x * 7, y * 5));
}

// p at and near its ends, P and R over six decades, W at both ends, patches below a texel:
// every texel is finite and in [0, 1], and the layer's share grows with p.
TEST(Prefiltered, ExtremesAreDefinedAndMonotoneInP) {
  for (const double patch : {0.004, 1.0, 64.0})
    for (const double pexp : {1e-3, 1.0, 1e3})
      for (const double rexp : {1e-3, 1.0, 1e3})
        for (const double wexp : {1e-3, 1e3}) {
          double last = -1.0;
          for (const float w : {0.f, 0x1p-24f, 0.25f, 0.5f, 1.f}) {
            const PackedScene pre = pack(dpt_scene(patch, w, pexp, rexp, wexp), prefiltered_options());
            const glm::dvec4 t = compose_texel_reference(pre, 4, 3, 5);
            for (int c = 0; c < 4; ++c) ASSERT_TRUE(std::isfinite(t[c]) && t[c] >= 0.0 && t[c] <= 1.0);
            EXPECT_GE(t.g, last - 1e-12) << "patch " << patch << " P " << pexp << " R " << rexp << " W " << wexp << " p " << w;
            last = t.g;
          }
        }
}

// The meta block's feature statistics chain: every level-l texel holds the feature fraction,
// the mean f of its feature texels and D (feature colour mean - colour mean) of the level-0
// texels under it, to the words' rounding.
TEST(Prefiltered, FeatureChainHoldsEachBlocksFractionAndColourMoment) {
  const SceneAssets a = test::big_feature_scene(0.5f);
  const std::shared_ptr<const MaterialAssets> held = a.materials->get(1).value();
  const MaterialAssets& m = *held;
  const MaterialWords w = pack_material(m);
  const uint32_t res = 64;
  ASSERT_EQ(w.meta.size(), 2 * size_t(gpu::tvt_meta_block_texels(res)));
  const ImageRGBA8& albedo = m.albedo.mips.front();
  for (uint32_t level = 1; (res >> level) >= 1; ++level) {
    const uint32_t rl = res >> level, side = 1u << level;
    for (uint32_t by = 0; by < rl; ++by)
      for (uint32_t bx = 0; bx < rl; ++bx) {
        double features = 0, soft = 0;
        glm::dvec4 all(0.0), inside(0.0);
        for (uint32_t y = by * side; y < (by + 1) * side; ++y)
          for (uint32_t x = bx * side; x < (bx + 1) * side; ++x) {
            const uint8_t* t = albedo.at(int(x), int(y));
            const glm::dvec4 c = glm::dvec4(t[0], t[1], t[2], t[3]) / 255.0;
            all += c;
            if (m.meta->at(int(x), int(y)).d) {
              features += 1, soft += m.meta->at(int(x), int(y)).f / 255.0, inside += c;
            }
          }
        const double n = double(side) * double(side);
        const size_t i = gpu::tvt_meta_chain_offset(res, level) + by * rl + bx;
        const uint32_t w0 = w.meta[2 * i], w1 = w.meta[2 * i + 1];
        const std::string where = "level " + std::to_string(level) + " texel " + std::to_string(bx) + "," + std::to_string(by);
        EXPECT_NEAR((w0 & 0xffffu) / 65535.0, features / n, 0.6 / 65535) << where;
        EXPECT_NEAR((w0 >> 16) / 65535.0, features > 0 ? soft / features : 0.0, 0.6 / 65535) << where;
        for (int c = 0; c < 4; ++c) {
          const double moment = (inside[c] - features / n * all[c]) / n;
          EXPECT_NEAR(double(int8_t(uint8_t(w1 >> (8 * c)))) / 127.0 / gpu::TVT_META_MOMENT_SCALE, moment, 0.6 / 508) << where;
        }
      }
  }
}

// A material's words: every level's texels where the layout says, each level >= 1 followed by
// A's spread chain (per texel, A within the level-0 texels under it split at their mean: the
// lower piece's share, the standard deviation of the pieces' means, each piece's half-width
// sqrt(3 var), to the unorm8 rounding), then the statistics block, and nothing after it.
TEST(Prefiltered, SpreadChainHoldsEachBlocksTwoPiecesOfA) {
  // A rough left half (hashed A) and a smooth right half (a gentle ramp): the local spread
  // differs several-fold, which the texture's pooled variance cannot tell apart.
  ImageRGBA8 albedo(64, 64);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {
      uint8_t* t = albedo.at(x, y);
      const uint32_t h = gpu::tvt_hash_coord(x, y, 7u);
      t[0] = uint8_t(h), t[1] = uint8_t(h >> 8), t[2] = uint8_t(x * 4);
      t[3] = x < 32 ? uint8_t(h >> 16) : uint8_t(100 + y);
    }
  MaterialAssets m;
  m.albedo = build_mip_chain(albedo);
  const MaterialWords w = pack_material(m);
  const uint32_t res = 64, levels = 7;
  ASSERT_EQ(w.mip_count, int(levels));
  ASSERT_EQ(w.texels.size(), size_t(gpu::tvt_material_stats_offset(res, levels)) + size_t(gpu::TVT_MATERIAL_STATS_WORDS));
  double largest = 0.0, smallest = 1.0;
  for (uint32_t level = 0; level < levels; ++level) {
    const uint32_t rl = res >> level, side = 1u << level;
    const ImageRGBA8& mip = m.albedo.mips[level];
    const uint32_t first = gpu::tvt_material_level_offset(res, level);
    for (uint32_t i = 0; i < rl * rl; ++i) {
      const uint8_t* t = &mip.texels[4 * size_t(i)];
      ASSERT_EQ(w.texels[first + i], uint32_t(t[0]) | uint32_t(t[1]) << 8 | uint32_t(t[2]) << 16 | uint32_t(t[3]) << 24)
          << "level " << level << " texel " << i;
    }
    if (level == 0) continue;
    ASSERT_EQ(gpu::tvt_material_spread_offset(res, level), first + rl * rl);
    const uint32_t next = level + 1 < levels ? gpu::tvt_material_level_offset(res, level + 1)
                                             : gpu::tvt_material_stats_offset(res, levels);
    ASSERT_EQ(next - gpu::tvt_material_spread_offset(res, level), rl * rl) << "level " << level;
    for (uint32_t by = 0; by < rl; ++by)
      for (uint32_t bx = 0; bx < rl; ++bx) {
        std::vector<double> a;
        double mean = 0;
        for (uint32_t y = by * side; y < (by + 1) * side; ++y)
          for (uint32_t x = bx * side; x < (bx + 1) * side; ++x) a.push_back(albedo.at(int(x), int(y))[3] / 255.0);
        for (double v : a) mean += v / double(a.size());
        double n[2] = {0, 0}, sum[2] = {0, 0}, squares[2] = {0, 0};
        for (double v : a) {
          const int k = v < mean ? 0 : 1;
          n[k] += 1, sum[k] += v, squares[k] += v * v;
        }
        double piece_mean[2], half[2];
        for (int k = 0; k < 2; ++k) {
          piece_mean[k] = n[k] > 0 ? sum[k] / n[k] : 0.0;
          half[k] = n[k] > 0 ? std::sqrt(std::max(0.0, 3.0 * (squares[k] / n[k] - piece_mean[k] * piece_mean[k]))) : 0.0;
        }
        const double p = n[0] / double(a.size());
        const double delta = n[0] > 0 && n[1] > 0 ? std::sqrt(p * (1 - p)) * (piece_mean[1] - piece_mean[0]) : 0.0;
        // The pieces keep A's variance: delta^2 + the pieces' own variances.
        double var = 0;
        for (double v : a) var += (v - mean) * (v - mean) / double(a.size());
        EXPECT_NEAR(delta * delta + p * half[0] * half[0] / 3 + (1 - p) * half[1] * half[1] / 3, var, 1e-9);
        const uint32_t word = w.texels[gpu::tvt_material_spread_offset(res, level) + by * rl + bx];
        const std::string where = "level " + std::to_string(level) + " texel " + std::to_string(bx) + "," + std::to_string(by);
        const double s = gpu::TVT_SPREAD_SCALE, q = 0.501 / 255;  // half a step (ties either way)
        EXPECT_NEAR((word & 0xffu) / 255.0, p, q) << where;
        EXPECT_NEAR(((word >> 8) & 0xffu) / 255.0 / s, delta, q / s) << where;
        EXPECT_NEAR(((word >> 16) & 0xffu) / 255.0 / s, half[0], q / s) << where;
        EXPECT_NEAR((word >> 24) / 255.0 / s, half[1], q / s) << where;
        if (level == 3) largest = std::max(largest, std::sqrt(var)), smallest = std::min(smallest, std::sqrt(var));
      }
  }
  EXPECT_GT(largest, 0.2);  // the rough half
  EXPECT_LT(smallest, 0.05);  // the smooth half: a local spread several-fold smaller
}

// Features larger than the footprint, past the end of the FBPB fade (their expectation): the
// prefiltered texel follows what its footprint holds (this feature's decision, the local
// feature fraction and colour), not the texture's mean feature fraction, so it lands near the
// box filter of level 0 inside features, on the ground between them and across their edges.
TEST(Prefiltered, FeaturesFollowWhatTheFootprintHolds) {
  const SceneAssets a = test::big_feature_scene(0.5f);
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  for (const uint32_t mip : {2u, 3u, 4u}) {
    double err = 0, worst = 0, lowest = 1, highest = 0;
    const int64_t n = 32, step = std::max<int64_t>(1, (int64_t(1) << (10 - mip)) / n);  // texels over the VT
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const glm::dvec4 truth = ground_truth_texel(direct, mip, x * step + 1, y * step + 1);
        const glm::dvec4 got = compose_texel_reference(pre, mip, x * step + 1, y * step + 1);
        for (int c = 0; c < 3; ++c) {
          err += std::abs(got[c] - truth[c]) / (3 * n * n);
          worst = std::max(worst, std::abs(got[c] - truth[c]));
        }
        lowest = std::min(lowest, truth.g), highest = std::max(highest, truth.g);
      }
    EXPECT_LT(err, 0.01) << "mip " << mip;
    EXPECT_LT(worst, 0.2) << "mip " << mip;
    EXPECT_GT(highest - lowest, 0.3) << "mip " << mip;  // the truth is far from uniform: features decide
  }
}

// Algorithm 1's chipped holes in the feature expectation: the statistics block holds the
// variation map's distribution, and a prefiltered texel past the points takes the chipped share
// of each visible feature as ground, darkened, as level 0 does texel by texel.
TEST(Prefiltered, ChippedHolesAreInTheFeatureExpectation) {
  SceneAssets a = test::big_feature_scene(0.5f);
  {
    MetaTexture& meta = a.materials->edit(1).meta.value();
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x)  // fine-grained noise, as a variation map is
        meta.texels[size_t(y) * 64 + size_t(x)].variation = uint8_t(gpu::tvt_hash_coord(x, y, 11u) & 0xffu);
  }
  const std::shared_ptr<const MaterialAssets> held = a.materials->get(1).value();
  const MaterialWords words = pack_material(*held);
  const size_t stats = gpu::tvt_material_stats_offset(64, uint32_t(words.mip_count));
  for (int i = 0; i <= gpu::TVT_STATS_VARIATION_STEPS; ++i) {
    size_t below = 0;
    for (const MetaTexel& t : held->meta->texels) below += double(t.variation) / 255.0 < double(i) / 16.0 ? 1 : 0;
    EXPECT_FLOAT_EQ(std::bit_cast<float>(words.texels[stats + size_t(gpu::TVT_STATS_VARIATION_CDF + i)]),
                    float(double(below) / 4096.0)) << i;
  }
  // A visible feature shows fully (cm = 4) and its chipped texels not at all (cn = 0), and
  // the threshold chips 0.6 of them where p < 1 (everywhere here).
  a.desc.materials[1].fbpb.variation_threshold = 0.6;
  a.desc.materials[1].fbpb.cm = 4.0;
  a.desc.materials[1].fbpb.cn = 0.0;
  // Level 0 before the FBPB fade (fade0 = 1), and half-way through it (fade0 = 0.5: level 0
  // blends half the plain weight, in the chipped texels' darkened colour as well; darker holes
  // there, Cc = 0.25, so that this share matters).
  for (const double fade_lo : {0.0, -0.5}) {
    a.desc.materials[1].fbpb.fade_lod_lo = fade_lo;
    a.desc.materials[1].fbpb.fade_lod_hi = fade_lo + 1.0;
    a.desc.materials[1].fbpb.colour_coeff = fade_lo == 0.0 ? 0.75 : 0.25;
    SceneAssets unchipped = a;
    unchipped.desc.materials[1].fbpb.variation_threshold = 0.0;
    const PackedScene direct = pack(a), pre = pack(a, prefiltered_options()), plain_truth = pack(unchipped);
    for (const uint32_t mip : {3u, 4u}) {  // past the points (fade ends by LOD 1, points to LOD 2)
      double err = 0, chipping = 0;
      const int64_t n = 24, step = (int64_t(1) << (10 - mip)) / n;
      for (int64_t y = 0; y < n; ++y)
        for (int64_t x = 0; x < n; ++x) {
          const glm::dvec4 truth = ground_truth_texel(direct, mip, x * step + 1, y * step + 1);
          const glm::dvec4 got = compose_texel_reference(pre, mip, x * step + 1, y * step + 1);
          const glm::dvec4 whole = ground_truth_texel(plain_truth, mip, x * step + 1, y * step + 1);
          for (int c = 0; c < 3; ++c) {
            err += std::abs(got[c] - truth[c]) / (3 * n * n);
            chipping += std::abs(whole[c] - truth[c]) / (3 * n * n);
          }
        }
      // The holes change the truth (half as much where level 0 blends half the plain weight).
      EXPECT_GT(chipping, fade_lo == 0.0 ? 0.04 : 0.015) << "fade from LOD " << fade_lo << ", mip " << mip;
      // And the expectation follows them: 0.11-0.12 of their effect either way. Half-way through
      // the fade, with the plain share of the chipped texels left undarkened, it was 0.22.
      EXPECT_LT(err, 0.16 * chipping) << "fade from LOD " << fade_lo << ", mip " << mip;
    }
  }
}

namespace {

// A grid of n x n texels of a mip: (x * sx.first + sx.second, y * sy.first + sy.second).
struct TexelGrid {
  int64_t n;
  std::pair<int64_t, int64_t> sx, sy;
};

// The box filter of `direct`'s level 0 and `composed`'s texel at each texel of the grid, in
// order; `visit` returns false to stop.
template <class Visit>
void against_box_filter(const PackedScene& direct, const PackedScene& composed, uint32_t mip, const TexelGrid& g, Visit visit) {
  for (int64_t y = 0; y < g.n; ++y)
    for (int64_t x = 0; x < g.n; ++x) {
      const int64_t tx = x * g.sx.first + g.sx.second, ty = y * g.sy.first + g.sy.second;
      if (!visit(tx, ty, ground_truth_texel(direct, mip, tx, ty), compose_texel_reference(composed, mip, tx, ty))) return;
    }
}

// Asserts that the prefiltered mip-`mip` texels of the grid are the box filter of level 0 (to
// 1e-9), and returns how many of them a point sample gets wrong (their level-0 texels not all
// alike: an edge or a hole inside the footprint); -1 at the first texel that is not.
int box_filter_texels(const PackedScene& direct, const PackedScene& pre, uint32_t mip, int64_t n,
                      std::pair<int64_t, int64_t> sx, std::pair<int64_t, int64_t> sy) {
  int edges = 0;
  against_box_filter(direct, pre, mip, {n, sx, sy}, [&](int64_t tx, int64_t ty, const glm::dvec4& truth, const glm::dvec4& got) {
    for (int c = 0; c < 4; ++c)
      if (!(std::abs(got[c] - truth[c]) <= 1e-9)) {
        ADD_FAILURE() << "mip " << mip << " texel " << tx << " " << ty << " channel " << c << ": " << got[c]
                      << " against the box filter's " << truth[c];
        edges = -1;
        return false;
      }
    const glm::dvec4 centre = compose_texel_reference(direct, mip, tx, ty);
    edges += std::abs(centre.g - truth.g) > 0.05 ? 1 : 0;
    return true;
  });
  return edges;
}

// Mean absolute error over r, g, b of `composed` against the box filter of `direct`'s level 0
// at mip `mip`, over the grid.
double box_filter_error(const PackedScene& direct, const PackedScene& composed, uint32_t mip, int64_t n,
                        std::pair<int64_t, int64_t> sx, std::pair<int64_t, int64_t> sy) {
  double err = 0;
  against_box_filter(direct, composed, mip, {n, sx, sy}, [&](int64_t, int64_t, const glm::dvec4& truth, const glm::dvec4& got) {
    for (int c = 0; c < 3; ++c) err += std::abs(got[c] - truth[c]);
    return true;
  });
  return err / double(3 * n * n);
}

}  // namespace

// Where the features are exact at points (mips up to one LOD past the fade's end), each point
// stands for a quarter of the footprint with the texture one LOD finer. At mip 1 the points
// are the four level-0 texel centres and the texture is level 0's, so over a uniform base and
// a constant weight the prefiltered texel is the box filter of level 0 itself: stone edges,
// chipped holes and each stone's own decision included. At mip 2 it stays close.
TEST(Prefiltered, FeaturesAtPointsAreTheBoxFilterOfLevel0AtMip1) {
  const SceneAssets a = test::big_feature_scene(0.5f);
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  EXPECT_GT(box_filter_texels(direct, pre, 1, 64, {7, 3}, {5, 1}), 20);  // the box filter differs from a point sample on many of them
  EXPECT_LT(box_filter_error(direct, pre, 2, 32, {7, 1}, {3, 2}), 0.01);
}

// The same with level 0 half-way through the FBPB fade (fade0 = 0.5): level 0 blends each
// texel with half its feature weight and half the plain blend map, in the texel's own colour,
// darkened in a chipped hole; the points' plain share takes each point's colour, so the
// prefiltered texel at mip 1 is still the box filter of level 0 (A is uniform here, so the
// plain blend map is the same at every texel).
TEST(Prefiltered, FeaturesAtPointsFollowLevel0HalfWayThroughTheFade) {
  SceneAssets a = test::big_feature_scene(0.5f);
  a.desc.materials[1].fbpb.fade_lod_lo = -0.5;
  a.desc.materials[1].fbpb.fade_lod_hi = 0.5;
  // Chipped holes: fine-grained variation, a third of each visible feature's texels chipped,
  // shown as ground (cn = 0) in half their colour.
  MetaTexture& meta = a.materials->edit(1).meta.value();
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) meta.texels[size_t(y) * 64 + size_t(x)].variation = uint8_t(gpu::tvt_hash_coord(x, y, 5u) & 0xffu);
  a.desc.materials[1].fbpb.variation_threshold = 0.33;
  a.desc.materials[1].fbpb.cn = 0.0;
  a.desc.materials[1].fbpb.colour_coeff = 0.5;
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  EXPECT_GT(box_filter_texels(direct, pre, 1, 64, {7, 3}, {5, 1}), 20);
}

// Features smaller than the footprint under FBPB+DPT (tvt_feature_points: the material LOD
// above the log2 feature size less 1.5, and at least 2), on a footprint under 8 texels wide:
// 4 x 4 points. At mip 2 they are the sixteen level-0 texel centres with level 0's texture, so the prefiltered texel is again the
// box filter of level 0, every small stone's own decision included; with 2 x 2 points it would
// not be. The DPT layer has no patches (p = 0), so the ground's value is 0 at level 0 and in
// the footprint alike.
TEST(Prefiltered, SmallFeaturesTakeFourByFourPointsExactAtMip2) {
  const SceneAssets a = test::small_stone_scene(0.0f, 1.0f);  // points until LOD 2
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  EXPECT_EQ(gpu::tvt_feature_points(2.0f, float(0.5 * std::log2(25.0)), true), 4);
  EXPECT_GT(box_filter_texels(direct, pre, 2, 48, {5, 3}, {3, 1}), 100);  // stone edges and stones of their own decision inside most footprints
}

// The same stones at mip 3, an 8-texel footprint: 3 x 3 points, each reading the texture two
// LODs finer (level 1). They are no longer the box filter (a point stands for 8/3 texels), but
// against it they are far closer than a point sample, and than 2 x 2 points over the same
// stones (the same scene with the statistics block told the stones are large, so that k = 2):
// two points 4 texels apart a side fall both on stones or both between them across an 8-texel
// period, where three see its share. At mip 2 (a 4-texel footprint) three points a side would
// read 3 of its 4 texel columns and miss one: hence 4 x 4 there (the test above).
TEST(Prefiltered, SmallFeaturesTakeThreeByThreePointsAtMip3) {
  const float small = float(0.5 * std::log2(25.0)), large = float(0.5 * std::log2(25.0 * 64));
  EXPECT_EQ(gpu::tvt_feature_points(3.0f, small, true), 3);
  EXPECT_EQ(gpu::tvt_feature_points(2.99f, small, true), 4);  // under 8 texels
  EXPECT_EQ(gpu::tvt_feature_points(1.99f, small, true), 2);  // under 4 texels
  EXPECT_EQ(gpu::tvt_feature_points(3.0f, small, false), 2);  // FBPB alone
  EXPECT_EQ(gpu::tvt_feature_points(3.0f, large, true), 2);   // 3 < log2 40 - 1.5 = 3.82
  EXPECT_EQ(gpu::tvt_feature_point_lods(2), 1);
  EXPECT_EQ(gpu::tvt_feature_point_lods(3), 2);
  EXPECT_EQ(gpu::tvt_feature_point_lods(4), 2);
  // Mean absolute error over r, g, b at mip 3 against the box filter of level 0.
  const auto error = [](const PackedScene& direct, const PackedScene& composed) {
    return box_filter_error(direct, composed, 3, 40, {5, 3}, {3, 1});
  };
  const SceneAssets three = test::small_stone_scene(1.0f, 2.0f), two = test::small_stone_scene(1.0f, 2.0f, 1);  // points until LOD 3
  const PackedScene direct = pack(three);
  const double e_direct = error(direct, direct), e3 = error(direct, pack(three, prefiltered_options()));
  const double e2 = error(direct, pack(two, prefiltered_options()));  // level 0 does not read the statistics
  EXPECT_LT(e3, 0.5 * e_direct) << e3 << " " << e_direct;  // 0.071 against 0.203
  EXPECT_LT(e3, 0.5 * e2) << e3 << " " << e2;              // against 0.210
}

// The points' half spacing is footprint / 2k rounded to the nearest fixed-point unit, worked out
// without a division by a variable (k = 3: a halving, then a division by the constant 3), for
// every k tvt_feature_points() returns, footprints from 1/256 of a texel to 2^40 texels.
TEST(Prefiltered, FeaturePointHalfStepIsTheRoundedQuotient) {
  std::vector<int64_t> footprints;
  for (int64_t f = 1; f < 5000; ++f) footprints.push_back(f);
  for (int e = 12; e < 48; ++e)
    for (int64_t d = -7; d <= 7; ++d) footprints.push_back((int64_t(1) << e) + d);
  for (const int k : {2, 3, 4})
    for (const int64_t f : footprints) {
      const int64_t h = gpu::tvt_feature_point_half_step(f, k);
      ASSERT_EQ(h, (f + k) / (2 * k)) << "footprint " << f << " k " << k;
      ASSERT_LE(std::abs(2 * k * h - f), k) << "footprint " << f << " k " << k;  // nearest
    }
}

TEST(Mips, GroundTruthIsSupersamplingAtTheLevel0Rate) {
  auto a = test::make_synthetic_assets({k_base, {{0, 250, 0, 200}, 0.5f, Mode::Dpt}});
  a.desc.materials[1].dpt.layers = {{6, 1, 1, 1, 0.5}};
  for (size_t i = 0; i < 16; ++i) a.weights.data[16 + i] = float(i % 3) / 2.f;
  ComposeOptions o;
  o.supersample = 4;
  const PackedScene s4 = pack(a, o);
  const PackedScene s1 = pack(a);
  double err_direct = 0;
  for (int64_t y = 0; y < 8; ++y)
    for (int64_t x = 0; x < 8; ++x) {
      const glm::dvec4 gt = ground_truth_texel(s1, 2, x * 5, y * 7);
      const glm::dvec4 ss = compose_texel_reference(s4, 2, x * 5, y * 7);  // 4x4 at mip 2 = level-0 rate
      for (int c = 0; c < 4; ++c) EXPECT_NEAR(gt[c], ss[c], 1e-12);
      err_direct += std::abs(compose_texel_reference(s1, 2, x * 5, y * 7).g - gt.g);
    }
  EXPECT_GT(err_direct, 0.0);  // direct composition at mip 2 is an approximation of it
}

namespace {

// One material, the rock generator at 64 texels tiled every 64 level-0 texels, with hex-tiling
// set as given; the luminance of mip-0 texels over 4 x 4 periods.
struct Luminance {
  std::vector<double> l;
  int side = 256;
  double at(int x, int y) const { return l[size_t(y) * size_t(side) + size_t(x)]; }
};

Luminance rock_luminance(std::optional<HexDesc> hex) {
  SceneDesc d = default_scene();
  d.materials.resize(1);
  d.materials[0].albedo.generator = "rock";
  d.materials[0].albedo.resolution = 64;
  d.materials[0].period_texels = 64;
  d.materials[0].hex = hex.value_or(HexDesc{});  // off unless given (the default scene has it on)
  d.vt.log2_size = 12;
  auto assets = load_scene_assets(d);
  EXPECT_TRUE(assets.ok()) << (assets.ok() ? "" : assets.error().message);
  const PackedScene s = pack(assets.value());
  Luminance r;
  r.l.resize(size_t(r.side) * size_t(r.side));
  for (int y = 0; y < r.side; ++y)
    for (int x = 0; x < r.side; ++x) {
      const glm::dvec4 c = compose_texel_reference(s, 0, 1000 + x, 2000 + y);
      r.l[size_t(y) * size_t(r.side) + size_t(x)] = 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
    }
  return r;
}

// Pearson correlation of the luminance with itself shifted by (dx, dy).
double correlation(const Luminance& a, int dx, int dy) {
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, n = 0;
  for (int y = 0; y + dy < a.side; ++y)
    for (int x = 0; x + dx < a.side; ++x) {
      const double u = a.at(x, y), v = a.at(x + dx, y + dy);
      sx += u, sy += v, sxx += u * u, syy += v * v, sxy += u * v, n += 1;
    }
  const double cov = sxy / n - sx / n * sy / n;
  return cov / std::sqrt((sxx / n - sx * sx / n / n) * (syy / n - sy * sy / n / n));
}

double mean_of(const Luminance& a) {
  double s = 0;
  for (double v : a.l) s += v;
  return s / double(a.l.size());
}

double deviation_of(const Luminance& a) {
  const double m = mean_of(a);
  double s = 0;
  for (double v : a.l) s += (v - m) * (v - m);
  return std::sqrt(s / double(a.l.size()));
}

}  // namespace

// The point of hex-tiling: a texture tiled with period T repeats exactly at lag T (correlation
// 1); with hex-tiling the lag-T correlation drops to what unrelated parts of the texture share.
TEST(HexTiling, RemovesTheRepetitionAtTheTilePeriod) {
  const Luminance tiled = rock_luminance(std::nullopt), hex = rock_luminance(HexDesc{true});
  const double tiled_x = correlation(tiled, 64, 0), tiled_y = correlation(tiled, 0, 64);
  const double hex_x = correlation(hex, 64, 0), hex_y = correlation(hex, 0, 64);
  RecordProperty("lag_T_correlation_tiled", std::to_string(tiled_x));
  RecordProperty("lag_T_correlation_hex", std::to_string(hex_x));
  EXPECT_GT(tiled_x, 0.99);
  EXPECT_GT(tiled_y, 0.99);
  EXPECT_LT(hex_x, 0.5 * tiled_x);
  EXPECT_LT(hex_y, 0.5 * tiled_y);
  // Neighbouring texels still belong to one tile: the texture's own short-range structure stays.
  EXPECT_GT(correlation(hex, 1, 0), 0.5 * correlation(tiled, 1, 0));
}

// Variance preservation about the mean: the blended tiles keep the texture's mean and close to
// its contrast; a linear blend (preserve 0) washes the contrast out where tiles mix.
TEST(HexTiling, KeepsTheMeanAndPreservesContrastUnlessToldNot) {
  const Luminance tiled = rock_luminance(std::nullopt);
  const Luminance kept = rock_luminance(HexDesc{true, 0.0, 7.0, 1.0});
  const Luminance washed = rock_luminance(HexDesc{true, 0.0, 1.0, 0.0});
  EXPECT_NEAR(mean_of(kept), mean_of(tiled), 0.03);
  EXPECT_NEAR(mean_of(washed), mean_of(tiled), 0.03);
  EXPECT_NEAR(deviation_of(kept), deviation_of(tiled), 0.15 * deviation_of(tiled));
  EXPECT_LT(deviation_of(washed), 0.9 * deviation_of(kept));
}

// Hex-tiling is a per-material choice: unset materials keep the tiled texture bit for bit, the
// option forces it on or off, and FBPB layers above the base never get it.
TEST(HexTiling, PerMaterialAndNeverOnFbpbLayers) {
  SceneDesc d = default_scene();
  d.vt.log2_size = 12;
  for (MaterialDesc& m : d.materials) m.hex = HexDesc{};
  d.materials[1].hex = HexDesc{true, 40.0};
  auto assets = load_scene_assets(d);
  ASSERT_TRUE(assets.ok()) << assets.error().message;
  const PackedScene scene = pack(assets.value());
  EXPECT_EQ(scene.params.materials[0].hex_edge, 0);
  EXPECT_EQ(scene.params.materials[1].hex_edge, 40);
  EXPECT_EQ(scene.params.materials[1].hex_row, 35);  // round(40 sqrt(3) / 2)
  ComposeOptions on = options_for(Method::FbpbDpt);
  on.hex = true;
  const PackedScene forced = pack(assets.value(), on);
  EXPECT_EQ(forced.params.materials[0].hex_edge, 128);  // half of the 256-texel base
  for (int n = 1; n < forced.params.material_count; ++n) {
    const int mode = forced.params.materials[n].mode;
    if (mode == gpu::TVT_MODE_FBPB || mode == gpu::TVT_MODE_FBPB_DPT) {
      EXPECT_EQ(forced.params.materials[n].hex_edge, 0) << n;
    } else {
      EXPECT_GT(forced.params.materials[n].hex_edge, 0) << n;
    }
  }
  ComposeOptions off;
  off.hex = false;
  EXPECT_EQ(pack(assets.value(), off).params.materials[1].hex_edge, 0);
  // Off, the scene composes exactly as it did before the mode existed.
  SceneDesc plain = default_scene();
  plain.vt.log2_size = 12;
  for (MaterialDesc& m : plain.materials) m.hex = HexDesc{};
  auto plain_assets = load_scene_assets(plain);
  ASSERT_TRUE(plain_assets.ok());
  EXPECT_EQ(compose_page_reference(pack(plain_assets.value()), {0, 3, 5}).value(),
            compose_page_reference(pack(assets.value(), off), {0, 3, 5}).value());
}
