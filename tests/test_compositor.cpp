// Equation-level tests of the CPU reference compositor on hand-made scenes.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "compose/material_source.h"
#include "compose/reference_compositor.h"
#include "compose/scene_identity.h"
#include "shaders/shared/hash.h"
#include "support/synthetic_scene.h"

using namespace tvt;
using test::k_base;
using test::pack;
using test::SyntheticMaterial;

namespace {

constexpr int64_t fp(int64_t texel) { return texel * 256 + 128; }  // level-0 texel centre

glm::dvec4 at(const PackedScene& s, int64_t x, int64_t y, double footprint = 1.0) {
  return compose_sample_reference(s, fp(x), fp(y), footprint);
}

double blend_map(double b, double a, double s) {
  const double e0 = 1 - b - s, e1 = 1 - b + s, x = s + a * (1 - 2 * s);
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

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
