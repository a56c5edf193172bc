// MaterialCuller::needs(): which texture levels and meta-textures a page reads (what the lazy
// material upload copies). The GPU side checks exactness against poisoned buffers
// (tests/gpu_lazy_materials.cpp); here the level arithmetic, the FBPB fade rule and
// the prefiltered features' switch from points to expectation.
#include <gtest/gtest.h>

#include "compose/material_culling.h"
#include "support/synthetic_scene.h"

using namespace tvt;

namespace {

// Material 1: 16x16 texture (5 levels) repeating every `period` level-0 texels, FBPB features.
PackedScene scene(double period, uint32_t supersample = 1, std::optional<Mode> method = std::nullopt,
                  bool prefiltered = false, int feature_side = 5) {
  test::SyntheticMaterial base{{100, 0, 0, 100}, 0.f, Mode::BlendMap};
  test::SyntheticMaterial top{{0, 200, 0, 100}, 0.5f, Mode::Fbpb};
  auto a = test::make_synthetic_assets({base, top}, 12);
  a.desc.materials[1].period_texels = period;
  a.desc.materials[1].has_fbpb = true;
  a.materials->edit(1).meta = test::square_feature_meta(16, 8, 8, feature_side - 1);
  if (method == Mode::FbpbDpt) a.desc.materials[1].dpt.layers = {{8, 1, 1, 1, 0.5}};  // none: plain FBPB
  ComposeOptions o;
  o.supersample = supersample;
  o.method = method;
  o.prefiltered = prefiltered;
  auto packed = pack_scene(a, o);
  TVT_CHECK(packed.ok());
  return std::move(packed.value());
}

}  // namespace

TEST(LazyNeeds, FinestLevelFollowsTheFootprintAndIsConservativeAtIntegerLods) {
  const PackedScene s = scene(48.0);  // R / T = 1/3: lod = mip - 1.585
  const MaterialCuller culler(s);
  const int expected[] = {0, 0, 0, 1, 2, 3, 4, 4};
  for (uint32_t mip = 0; mip < 8; ++mip)
    EXPECT_EQ(int(culler.needs(PageId{mip, 0, 0}, 3u).finest_level[1]), expected[mip]) << mip;
  // R / T = 1/4: lod = mip - 2 exactly; fp32 log2 may land just below, so one level finer.
  const PackedScene q = scene(64.0);
  const MaterialCuller cq(q);
  EXPECT_EQ(int(cq.needs(PageId{3, 0, 0}, 3u).finest_level[1]), 0);
  EXPECT_EQ(int(cq.needs(PageId{5, 0, 0}, 3u).finest_level[1]), 2);
  // Supersampling 4x4 shrinks the footprint by 4: two levels finer.
  const PackedScene ss = scene(48.0, 4);
  EXPECT_EQ(int(MaterialCuller(ss).needs(PageId{5, 0, 0}, 3u).finest_level[1]), 1);
}

TEST(LazyNeeds, MetaTextureOnlyForFbpbWhileFeaturesHaveNotFadedOut) {
  const PackedScene s = scene(64.0);  // lod = mip - 2; FBPB fades out at lod 4
  const MaterialCuller culler(s);
  EXPECT_EQ(culler.needs(PageId{0, 0, 0}, 3u).meta_mask, 2u);
  EXPECT_EQ(culler.needs(PageId{5, 0, 0}, 3u).meta_mask, 2u);  // lod 3
  EXPECT_EQ(culler.needs(PageId{6, 0, 0}, 3u).meta_mask, 2u);  // lod 4: conservative at the edge
  EXPECT_EQ(culler.needs(PageId{7, 0, 0}, 3u).meta_mask, 0u);  // lod 5: faded, never read
  EXPECT_EQ(culler.needs(PageId{0, 0, 0}, 1u).meta_mask, 0u);  // culled: nothing of it
  EXPECT_EQ(culler.needs(PageId{0, 0, 0}, 1u).mask, 1u);
  const PackedScene d = scene(64.0, 1, Mode::Dpt);  // the method override leaves no FBPB
  EXPECT_EQ(MaterialCuller(d).needs(PageId{0, 0, 0}, 3u).meta_mask, 0u);
}

// The prefiltered strategy's FBPB expectation reads the feature statistics chain at any LOD
// of mips >= 1, wherever level 0 has features (its LOD below the fade's end).
TEST(LazyNeeds, PrefilteredFbpbReadsTheMetaBlockAtEveryMipWhereLevel0HasFeatures) {
  const PackedScene s = scene(64.0, 1, std::nullopt, true);  // level-0 lod -2
  const MaterialCuller culler(s);
  for (uint32_t mip = 0; mip < 12; ++mip) EXPECT_EQ(culler.needs(PageId{mip, 0, 0}, 3u).meta_mask, 2u) << mip;
  EXPECT_EQ(culler.needs(PageId{9, 0, 0}, 1u).meta_mask, 0u);  // culled: nothing of it
  // Level-0 lod 5 (R / T = 32): features faded out at every level, the meta block is never read.
  const PackedScene faded = scene(0.5, 1, std::nullopt, true);
  for (uint32_t mip = 1; mip < 12; ++mip) EXPECT_EQ(MaterialCuller(faded).needs(PageId{mip, 0, 0}, 3u).meta_mask, 0u) << mip;
}

// Prefiltered FBPB features at k x k points read the texture tvt_feature_point_lods(k) finer:
// k = 3 (two LODs finer) under FBPB+DPT where the LOD is above the log2 feature size less 1.5
// (tvt_feature_points), from the material's statistics; 2 (one LOD finer) under FBPB alone.
// They are at points while the LOD is below the log2 feature size + TVT_FEATURE_POINTS_REL
// (tvt_feature_points_hold), in expectation past it, at the footprint's own levels.
TEST(LazyNeeds, PrefilteredFeaturePointsReadOneOrTwoLodsFiner) {
  // R / T = 1/3: lod = mip - 1.585; mip 4 is lod 2.415, at points for 5-texel features and
  // larger (log2 5 + 0.25 = 2.57).
  const PackedScene small = scene(48.0, 1, Mode::FbpbDpt, true, 5);  // log2 5 - 1.5 = 0.82: k = 3
  EXPECT_EQ(int(MaterialCuller(small).needs(PageId{4, 0, 0}, 3u).finest_level[1]), 0);
  const PackedScene small_fbpb = scene(48.0, 1, std::nullopt, true, 5);  // FBPB alone: k = 2
  EXPECT_EQ(int(MaterialCuller(small_fbpb).needs(PageId{4, 0, 0}, 3u).finest_level[1]), 1);
  // The whole 16 x 16 tile one feature: log2 16 - 1.5 = 2.5 above the LOD, k = 2.
  const PackedScene big = scene(48.0, 1, Mode::FbpbDpt, true, 17);
  EXPECT_EQ(int(MaterialCuller(big).needs(PageId{4, 0, 0}, 3u).finest_level[1]), 1);
  const PackedScene almost = scene(48.0, 1, Mode::FbpbDpt, true, 15);  // log2 15 - 1.5 = 2.41: k = 3
  EXPECT_EQ(int(MaterialCuller(almost).needs(PageId{4, 0, 0}, 3u).finest_level[1]), 0);
  // Mip 5, lod 3.415: past the 5-texel features' points (the expectation, level 3), within the
  // whole-tile feature's (log2 16 + 0.25 = 4.25; k = 3, level 1).
  EXPECT_EQ(int(MaterialCuller(small).needs(PageId{5, 0, 0}, 3u).finest_level[1]), 3);
  EXPECT_EQ(int(MaterialCuller(small_fbpb).needs(PageId{5, 0, 0}, 3u).finest_level[1]), 3);
  EXPECT_EQ(int(MaterialCuller(big).needs(PageId{5, 0, 0}, 3u).finest_level[1]), 1);
  // Past every size's points (lod 6.4, the expectation alone): the footprint's own levels.
  for (const PackedScene* s : {&small, &small_fbpb, &big})
    EXPECT_EQ(int(MaterialCuller(*s).needs(PageId{8, 0, 0}, 3u).finest_level[1]), 4);
}

TEST(LazyNeeds, MergeKeepsTheFinestLevelAndEveryBit) {
  MaterialNeeds a, b;
  a.mask = 0b011;
  a.finest_level[0] = 3;
  a.finest_level[1] = 1;
  b.mask = 0b110;
  b.meta_mask = 0b100;
  b.finest_level[1] = 2;
  b.finest_level[2] = 0;
  a.merge(b);
  EXPECT_EQ(a.mask, 0b111u);
  EXPECT_EQ(a.meta_mask, 0b100u);
  EXPECT_EQ(a.finest_level[0], 3);
  EXPECT_EQ(a.finest_level[1], 1);
  EXPECT_EQ(a.finest_level[2], 0);
}
