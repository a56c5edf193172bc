// GPU compute composition against the CPU reference (validation layers on).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <bit>
#include <filesystem>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "compose/packed_scene.h"
#include "compose/reference_compositor.h"
#include "compose/region.h"
#include "compose/scene.h"
#include "composer/gpu_composer.h"
#include "shaders/shared/hash.h"
#include "support/file_scene.h"
#include "support/gpu_test.h"
#include "support/synthetic_scene.h"
#include "support/temp_dir.h"

using namespace tvt;

namespace {

const SceneAssets& default_assets(uint32_t log2_vt) {
  static std::map<uint32_t, SceneAssets> cache;
  auto it = cache.find(log2_vt);
  if (it == cache.end()) {
    SceneDesc d = default_scene();
    d.vt.log2_size = log2_vt;
    auto a = load_scene_assets(d);
    EXPECT_TRUE(a.ok()) << (a.ok() ? "" : a.error().message);
    it = cache.emplace(log2_vt, std::move(a.value())).first;
  }
  return it->second;
}

// Three level-0 pages where most materials are in transition, and one mip-3 page.
std::vector<PageId> transition_pages(const SceneAssets& assets) {
  std::vector<PageId> pages = pages_covering(assets.desc.vt, interesting_region(assets, 0, 256, 256));
  pages.resize(std::min<size_t>(pages.size(), 3));
  pages.push_back(PageId{3, 5, 9});
  return pages;
}

struct Agreement {
  size_t channels = 0, within_one = 0;
  int max_diff = 0;
};

Agreement compare(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
  Agreement r;
  r.channels = a.size();
  for (size_t i = 0; i < a.size(); ++i) {
    const int d = std::abs(int(a[i]) - int(b[i]));
    r.within_one += d <= 1;
    r.max_diff = std::max(r.max_diff, d);
  }
  return r;
}

class GpuCompose : public GpuTest {
 protected:
  // Composes `pages` on the GPU and the CPU; asserts >= 99.9% of channels within 1/255.
  void expect_agreement(const SceneAssets& assets, const ComposeOptions& options, const std::vector<PageId>& pages,
                        const std::string& what) {
    auto packed = pack_scene(assets, options);
    ASSERT_TRUE(packed.ok()) << packed.error().message;
    auto composer = GpuComposer::create(ctx(), packed.value(), 8);
    ASSERT_TRUE(composer.ok()) << composer.error().message;
    const auto gpu_pages = composer.value()->compose_pages(pages).value();
    ASSERT_EQ(gpu_pages.size(), pages.size());
    Agreement total;
    for (size_t i = 0; i < pages.size(); ++i) {
      const auto cpu = compose_page_reference(packed.value(), pages[i]).value();
      const Agreement a = compare(cpu, gpu_pages[i]);
      total.channels += a.channels;
      total.within_one += a.within_one;
      total.max_diff = std::max(total.max_diff, a.max_diff);
    }
    const double fraction = double(total.within_one) / double(total.channels);
    EXPECT_GE(fraction, 0.999) << what << ": max difference " << total.max_diff << "/255";
    RecordProperty(what, std::to_string(fraction));
  }

  // Composes `pages` through the variants specialised to the scene and each mip, and through
  // one pipeline that keeps every path; asserts every byte is the same.
  void expect_specialised_unchanged(const PackedScene& packed, const std::vector<PageId>& pages,
                                    const std::string& what) {
    GpuComposerOptions plain;
    plain.specialise = false;
    auto specialised = GpuComposer::create(ctx(), packed, uint32_t(pages.size()));
    auto general = GpuComposer::create(ctx(), packed, uint32_t(pages.size()), plain);
    ASSERT_TRUE(specialised.ok() && general.ok());
    const auto a = specialised.value()->compose_pages(pages).value();
    const auto b = general.value()->compose_pages(pages).value();
    for (size_t i = 0; i < pages.size(); ++i) EXPECT_TRUE(a[i] == b[i]) << what << ": mip " << pages[i].mip;
  }
};

}  // namespace

TEST_F(GpuCompose, MatchesReferenceForEveryMethodOnTheDefaultScene) {
  const SceneAssets& assets = default_assets(16);
  std::vector<PageId> pages = transition_pages(assets);
  for (Method m : k_all_methods) expect_agreement(assets, options_for(m), pages, std::string(to_string(m)));
}

TEST_F(GpuCompose, MatchesReferenceAtTheFarCornerOf2To24) {
  const SceneAssets& assets = default_assets(24);
  const uint32_t last = uint32_t(assets.desc.vt.pages_per_side(0) - 1);
  const std::vector<PageId> pages = {{0, 0, 0}, {0, last, last}, {0, last - 1, last}, {4, 4095, 4095}};
  expect_agreement(assets, options_for(Method::FbpbDpt), pages, "fbpb+dpt2 far corner");
  expect_agreement(assets, options_for(Method::Dpt2), pages, "dpt2 far corner");
}

// A material from a 100 x 100 greyscale image without alpha (resampled to 128, height and FBPB
// features from luminance) composes the same pages on both sides, for every method.
TEST_F(GpuCompose, MatchesReferenceWithAHundredTexelGreyscaleImageMaterial) {
  const std::filesystem::path dir = test::fresh_test_dir("tvt_gpu_compose_image");
  ImageGray8 grey(100, 100);  // dark 20 x 8 bricks, light mortar, a little noise
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < 100; ++x) {
      const int row = y / 10, bx = (x + (row % 2) * 12) % 25, by = y % 10;
      grey.at(x, y) = uint8_t(bx < 22 && by < 8 ? 50 + (x * 7 + y * 3) % 20 : 200 + (x + y) % 9);
    }
  ASSERT_TRUE(write_image((dir / "wall.png").string(), grey).ok());
  const std::string scene = test::write_scene_json(dir, "scene.json", R"(
    {"name": "ground", "albedo": {"generator": "sand", "resolution": 64}, "weight": "remainder"},
    {"name": "wall", "albedo": {"image": "wall.png"}, "period_texels": 96, "mode": "fbpb+dpt",
     "fbpb": {}, "dpt": {"layers": [{"patch_texels": 64}]},
     "weight": {"rule": {"height": [0.3, 1.0], "height_fade": 0.2}}})");
  auto desc = load_scene_file(scene);
  ASSERT_TRUE(desc.ok()) << desc.error().message;
  auto assets = load_scene_assets(desc.value());
  ASSERT_TRUE(assets.ok()) << assets.error().message;
  ASSERT_EQ(assets->materials->info(1).resolution, 128);
  const std::vector<PageId> pages = {{0, 0, 0}, {0, 7, 9}, {0, 15, 15}, {2, 1, 2}};
  for (Method m : k_all_methods) expect_agreement(assets.value(), options_for(m), pages, std::string(to_string(m)) + " image");
  std::filesystem::remove_all(dir);
}

// Hex-tiling on every material it applies to (FBPB layers above the base keep their texture).
TEST_F(GpuCompose, HexTilingMatchesReferenceForEveryMethodAndAtTheFarCornerOf2To24) {
  const SceneAssets& assets = default_assets(16);
  std::vector<PageId> pages = transition_pages(assets);
  pages.push_back(PageId{7, 1, 0});  // hex tiles far smaller than a texel's footprint
  for (Method m : k_all_methods) {
    ComposeOptions o = options_for(m);
    o.hex = true;
    auto packed = pack_scene(assets, o);
    ASSERT_TRUE(packed.ok());
    EXPECT_GT(packed->params.materials[0].hex_edge, 0) << to_string(m);  // the base always has it
    expect_agreement(assets, o, pages, std::string(to_string(m)) + " hex");
  }
  const SceneAssets& far = default_assets(24);
  const uint32_t last = uint32_t(far.desc.vt.pages_per_side(0) - 1);
  ComposeOptions o = options_for(Method::Dpt2);
  o.hex = true;
  expect_agreement(far, o, {{0, 0, 0}, {0, last, last}, {0, last - 1, last}, {4, 4095, 4095}}, "dpt2 hex far corner");
}

// The parameters at their limits: the smallest lattice (edge 2 texels), linear weights
// (gamma 1) and a near step (gamma 64), no variance preservation and full.
TEST_F(GpuCompose, HexTilingAtExtremeParametersMatchesReference) {
  SceneDesc d = default_scene();
  d.vt.log2_size = 16;
  const double settings[][3] = {{2, 1, 0}, {2, 64, 1}, {65536, 7, 1}, {6, 7, 0.5}};
  for (const auto& [edge, sharpness, preserve] : settings) {
    for (MaterialDesc& m : d.materials) m.hex = HexDesc{true, edge, sharpness, preserve};
    auto assets = load_scene_assets(d);
    ASSERT_TRUE(assets.ok()) << assets.error().message;
    const std::string what = "hex edge " + std::to_string(edge) + " gamma " + std::to_string(sharpness) +
                             " preserve " + std::to_string(preserve);
    expect_agreement(assets.value(), options_for(Method::BlendMap), {{0, 30, 41}, {2, 3, 4}}, what);
  }
  // Material texel indices beyond 2^29 (one texture repeat per level-0 texel at V = 2^24):
  // the lattice in 64-bit arithmetic rather than the 32-bit fast path.
  SceneDesc far = default_scene();
  far.vt.log2_size = 24;
  for (MaterialDesc& m : far.materials) {
    m.hex = HexDesc{true};
    m.period_texels = 1.0;
  }
  auto assets = load_scene_assets(far);
  ASSERT_TRUE(assets.ok()) << assets.error().message;
  const uint32_t last = uint32_t(far.vt.pages_per_side(0) - 1);
  expect_agreement(assets.value(), options_for(Method::Dpt2), {{0, last, last}, {0, last / 2, 3}}, "hex, 2^32 material texels");
}

TEST_F(GpuCompose, SupersampledMipsMatchReference) {
  const SceneAssets& assets = default_assets(16);
  ComposeOptions o = options_for(Method::FbpbDpt);
  o.supersample = 4;
  expect_agreement(assets, o, {{2, 20, 30}, {5, 1, 1}}, "supersample 4");
  // Capped at 2^mip samples a side, on both sides: supersample:64 at mips 0, 1 and 3.
  o.supersample = 64;
  expect_agreement(assets, o, {{0, 40, 60}, {1, 20, 30}, {3, 5, 7}}, "supersample 64 (capped)");
}

// The prefiltered strategy: every method, mip 0 (direct), mip 4 (the cobbles' 3 x 3 feature
// points) and coarse mips where patches and features are far smaller than a texel, and the far
// corner of V = 2^24 (64-bit paths).
TEST_F(GpuCompose, PrefilteredMipsMatchReferenceForEveryMethod) {
  const SceneAssets& assets = default_assets(16);
  for (Method m : k_all_methods)
    expect_agreement(assets, options_for(m, MipStrategy{1, true}),
                     {{0, 40, 60}, {2, 20, 30}, {4, 10, 15}, {5, 1, 1}, {7, 0, 0}}, "prefiltered " + std::string(to_string(m)));
  // A's spread read through hex tiles on every material that can have them.
  for (Method m : {Method::BlendMap, Method::Dpt2}) {
    ComposeOptions o = options_for(m, MipStrategy{1, true});
    o.hex = true;
    expect_agreement(assets, o, {{2, 20, 30}, {4, 3, 2}}, "prefiltered hex " + std::string(to_string(m)));
  }
  const SceneAssets& far = default_assets(24);
  const uint32_t last = uint32_t(far.desc.vt.pages_per_side(0) - 1);
  for (Method m : {Method::FbpbDpt, Method::BlendMap})
    expect_agreement(far, options_for(m, MipStrategy{1, true}), {{0, last, last}, {4, 4095, 4095}, {12, 15, 15}},
                     "prefiltered far corner " + std::string(to_string(m)));
}

// DPT's samples (1 to 8 patches a side of a footprint): the shader decides the points' corner
// masks once on a lattice and finds their cells from the footprint centre's; patch sizes that
// are no power of two, W != 1 (pow) and positions past 2^32 fixed-point units (the 64-bit cells)
// give the reference's values.
TEST_F(GpuCompose, PrefilteredPatchSamplesMatchReferenceAtOddPatchSizes) {
  for (const uint32_t log2_vt : {16u, 24u}) {
    SceneDesc d = default_scene();
    d.vt.log2_size = log2_vt;
    const double scale = log2_vt == 16 ? 1.0 : 777.0;  // patches of 4.6k and 29k texels at 2^24
    for (MaterialDesc& m : d.materials)
      m.dpt.layers = {DptLayerDesc{37.3 * scale, 0.8, 1.3, 1.7, 0.5}, DptLayerDesc{5.9 * scale, 1.0, 1.0, 1.0, 0.3}};
    auto assets = load_scene_assets(d);
    ASSERT_TRUE(assets.ok()) << assets.error().message;
    std::vector<PageId> pages;
    const uint32_t shift = log2_vt == 16 ? 0 : 9;  // 777 ~ 2^9.6: the same patches a footprint
    for (uint32_t mip = 3; mip <= 8; ++mip) {
      const uint32_t last = uint32_t(d.vt.pages_per_side(mip + shift) - 1);
      pages.push_back(PageId{mip + shift, last / 2, last / 3});
      if (log2_vt == 24) pages.push_back(PageId{mip + shift, last, last});
    }
    expect_agreement(assets.value(), options_for(Method::Dpt2, MipStrategy{1, true}), pages,
                     "patch samples, V = 2^" + std::to_string(log2_vt));
  }
}

// The pipelines specialised to the scene's modes, hex-tiling and each mip's parts of the
// prefiltered maths (TVT_COMPOSE_SPEC_*) leave out only what cannot run: every byte as the one
// pipeline that keeps every path, for every method, strategy and mip, in one mixed batch.
TEST_F(GpuCompose, SpecialisedPipelinesChangeNoByte) {
  std::vector<PageId> pages;
  for (uint32_t mip = 0; mip <= 9; ++mip) pages.push_back(PageId{mip, 20u >> (mip / 2), 30u >> (mip / 2)});
  // V = 2^16: a weight texel every 128 level-0 texels, narrower than most DPT patches, so the
  // direct pages take the corners' general path. V = 2^20 (the built-in scene's): every patch
  // is narrower than a weight texel, so they take the narrow one; the DPT methods there, and
  // supersampled (footprints below a texel at mip 0).
  for (const uint32_t log2_vt : {16u, 20u}) {
    const SceneAssets& assets = default_assets(log2_vt);
    for (const bool hex : {false, true})
      for (const MipStrategy strategy : {MipStrategy{}, MipStrategy{1, true}, MipStrategy{2}})
        for (Method m : k_all_methods) {
          if (strategy.supersample > 1 && (hex || m != Method::FbpbDpt)) continue;  // supersampling: one case
          if (hex && m != Method::BlendMap && m != Method::FbpbDpt) continue;     // hex: two methods
          const bool with_dpt = m == Method::Dpt1 || m == Method::Dpt2 || m == Method::FbpbDpt;
          if (log2_vt == 20u && (!with_dpt || hex)) continue;
          ComposeOptions o = options_for(m, strategy);
          o.hex = hex;
          auto packed = pack_scene(assets, o);
          ASSERT_TRUE(packed.ok()) << packed.error().message;
          if (with_dpt) {
            EXPECT_EQ(direct_parts(packed.value().params) & gpu::TVT_PART_DPT_CORNERS_WIDE,
                      log2_vt == 20u ? 0u : gpu::TVT_PART_DPT_CORNERS_WIDE);
            // Some prefiltered mip samples its layers before the material loop (not dpt1 at
            // V = 2^16: its one layer's lattices may all span three weight texels there).
            bool pairs = false;
            for (const PageId& page : pages) pairs = pairs || sample_pairs(packed.value().params, page.mip) != 0;
            EXPECT_EQ(pairs, log2_vt == 20u || m != Method::Dpt1) << to_string(m) << " V = 2^" << log2_vt;
          }
          expect_specialised_unchanged(packed.value(), pages,
                                       std::string(to_string(m)) + " " + to_string(strategy) + (hex ? " hex" : "") +
                                           " V = 2^" + std::to_string(log2_vt));
        }
  }
}

// Grass and mud with two sampled DPT layers each: at some mips more (material, layer) pairs
// reach their samples than sample_pairs() takes, or their lattices may be wide, and they stay in
// the material loop; at others two are sampled before it. Either way every byte as the pipeline
// that keeps every path.
TEST_F(GpuCompose, SampledLayersBeforeOrInTheMaterialLoopChangeNoByte) {
  SceneDesc d = default_scene();
  d.vt.log2_size = 16;  // a weight texel every 128 level-0 texels
  for (MaterialDesc& m : d.materials) m.dpt.layers.clear();
  for (const size_t n : {1u, 2u})
    d.materials[n].dpt.layers = {DptLayerDesc{37.3, 0.8, 1.3, 1.7, 0.5}, DptLayerDesc{5.9, 1.0, 1.0, 1.0, 0.3}};
  auto assets = load_scene_assets(d);
  ASSERT_TRUE(assets.ok()) << assets.error().message;
  auto packed = pack_scene(assets.value(), options_for(Method::Dpt2, MipStrategy{1, true}));
  ASSERT_TRUE(packed.ok()) << packed.error().message;
  const gpu::TvtComposeParams& params = packed.value().params;
  for (const uint32_t mip : {3u, 4u})  // the small layer of both materials
    EXPECT_EQ(gpu::tvt_sample_pairs_count(sample_pairs(params, mip)), 2u) << mip;
  EXPECT_EQ(sample_pairs(params, 5), 0u);  // both layers of both: four pairs
  EXPECT_NE(prefiltered_parts(params, 5, loaded_feature_sizes(packed.value())) & gpu::TVT_PART_DPT_SAMPLES, 0u);
  EXPECT_EQ(sample_pairs(params, 6), 0u);  // the large layers, whose lattices may span 3 weight texels
  EXPECT_NE(prefiltered_parts(params, 6, loaded_feature_sizes(packed.value())) & gpu::TVT_PART_DPT_SAMPLES_WIDE, 0u);
  std::vector<PageId> pages;
  for (uint32_t mip = 2; mip <= 8; ++mip) pages.push_back(PageId{mip, 5u >> (mip / 2), 7u >> (mip / 2)});
  expect_specialised_unchanged(packed.value(), pages, "grass and mud sampled");
}

// Level 0 half-way through the FBPB fade (fade0 = 0.5) with chipped holes: the prefiltered
// points' plain share in each point's own colour and the expectation's darkened plain share,
// on the GPU as in the reference, at the points' mips (1-2) and the expectation's (3-4; the
// statistics block says the typical feature is small).
TEST_F(GpuCompose, PrefilteredFeaturesHalfWayThroughLevel0sFadeMatchReference) {
  SceneAssets a = test::big_feature_scene(0.5f, 40);
  MetaTexture& meta = a.materials->edit(1).meta.value();
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) meta.texels[size_t(y) * 64 + size_t(x)].variation = uint8_t(gpu::tvt_hash_coord(x, y, 5u) & 0xffu);
  MaterialDesc& m = a.desc.materials[1];
  m.fbpb.fade_lod_lo = -0.5;
  m.fbpb.fade_lod_hi = 0.5;
  m.fbpb.variation_threshold = 0.33;
  m.fbpb.cn = 0.0;
  m.fbpb.colour_coeff = 0.25;
  std::vector<PageId> pages;
  for (uint32_t mip = 0; mip <= 4; ++mip) pages.push_back(PageId{mip, 1u >> (mip / 2), 2u >> (mip / 2)});
  expect_agreement(a, options_for(Method::Fbpb, MipStrategy{1, true}), pages, "FBPB half-way through level 0's fade");
}

// Stones smaller than the footprint under FBPB+DPT: 4 x 4 feature points at mip 2 (a 4-texel
// footprint), 3 x 3 at mip 3 (a third of a footprint apart, rounded in fixed point), and the
// expectation past them, on the GPU as in the reference.
TEST_F(GpuCompose, PrefilteredSmallFeaturesAtFourAndThreePointsMatchReference) {
  const SceneAssets a = test::small_stone_scene(1.0f, 2.0f, 16);  // told 10 texels: at points up to LOD 3.57
  std::vector<PageId> pages;
  for (uint32_t mip = 2; mip <= 4; ++mip) pages.push_back(PageId{mip, 3u >> (mip / 2), 2u >> (mip / 2)});
  expect_agreement(a, options_for(Method::FbpbDpt, MipStrategy{1, true}), pages, "small stones at points");
}

// A driver compiles at pipeline creation: no frame may be the first to need a variant.
TEST_F(GpuCompose, EveryVariantOfTheVtsMipsIsMadeBeforeTheFirstPage) {
  const SceneAssets& assets = default_assets(16);
  auto packed = pack_scene(assets, options_for(Method::FbpbDpt, MipStrategy{1, true}));
  ASSERT_TRUE(packed.ok()) << packed.error().message;
  const gpu::TvtComposeParams& params = packed.value().params;
  const uint32_t top = uint32_t(params.log2_vt) - uint32_t(std::countr_zero(uint32_t(params.page_texels)));
  // The composer loads the FBPB materials (the cobbles) on the host for their feature size,
  // which picks each mip's variant; the rest come with the pages that read them.
  ASSERT_EQ(packed.value().loaded_mask(), 0u);
  auto c = GpuComposer::create(ctx(), packed.value(), 4);
  ASSERT_TRUE(c.ok()) << c.error().message;
  uint32_t fbpb = 0;
  for (int n = 1; n < params.material_count; ++n) fbpb |= params.materials[n].mode == gpu::TVT_MODE_FBPB_DPT ? 1u << n : 0u;
  ASSERT_NE(fbpb, 0u);
  EXPECT_EQ(packed.value().loaded_mask(), fbpb);
  const FeatureSizes sizes = loaded_feature_sizes(packed.value());
  std::set<std::pair<uint32_t, uint32_t>> parts;  // what a mip's variant is specialised to
  for (uint32_t mip = 1; mip <= top; ++mip) {
    const uint32_t pairs = sample_pairs(params, mip);
    parts.emplace(prefiltered_parts(params, mip, sizes) & (pairs ? ~gpu::TVT_PART_DPT_SAMPLES : ~0u), pairs);
  }
  ASSERT_GE(parts.size(), 2u);  // else this scene would not tell
  EXPECT_EQ(c.value()->pipeline_count(), 1 + parts.size());  // direct, and one per distinct set of parts and pairs
  std::vector<PageId> pages;
  for (uint32_t mip = 0; mip <= top; ++mip) pages.push_back(PageId{mip, 0, 0});
  ASSERT_TRUE(c.value()->compose_pages(pages).ok());
  EXPECT_EQ(c.value()->pipeline_count(), 1 + parts.size());
  // Another strategy through set_params(): its variants are made there, not by the next page.
  gpu::TvtComposeParams direct = params;
  direct.prefiltered = 0;
  c.value()->set_params(direct);
  EXPECT_EQ(c.value()->pipeline_count(), 1 + parts.size());  // direct pages: the one made at creation
  gpu::TvtComposeParams plain_modes = params;
  for (int n = 1; n < plain_modes.material_count; ++n) plain_modes.materials[n].mode = gpu::TVT_MODE_BLENDMAP;
  c.value()->set_params(plain_modes);
  const size_t made = c.value()->pipeline_count();
  EXPECT_GT(made, 1 + parts.size());
  ASSERT_TRUE(c.value()->compose_pages(pages).ok());
  EXPECT_EQ(c.value()->pipeline_count(), made);
}

// Parameters not from pack_scene, with a mode no build knows: every mode's path is kept (no
// undefined shift), and the page composes.
TEST_F(GpuCompose, AnUnknownModeKeepsEveryPath) {
  const SceneAssets& assets = default_assets(16);
  auto packed = pack_scene(assets, options_for(Method::BlendMap, MipStrategy{1, true}));
  ASSERT_TRUE(packed.ok()) << packed.error().message;
  auto c = GpuComposer::create(ctx(), packed.value(), 2);
  ASSERT_TRUE(c.ok()) << c.error().message;
  gpu::TvtComposeParams odd = packed.value().params;
  odd.materials[1].mode = 40;
  c.value()->set_params(odd);
  const std::vector<PageId> pages{PageId{0, 1, 1}, PageId{3, 0, 0}};
  EXPECT_TRUE(c.value()->compose_pages(pages).ok());
}

namespace {
// Prefiltered parameters of three materials (the two above the base for the caller to set), V =
// 2^20 with a weight texel every 2048 level-0 texels.
gpu::TvtComposeParams prefiltered_params() {
  gpu::TvtComposeParams p{};
  p.material_count = 3;
  p.supersample = 1;
  p.prefiltered = 1;
  p.prefilter_patch_lo = 0.5f;
  p.prefilter_patch_hi = 2.0f;
  p.log2_vt = 20;
  p.weight_width = 512;
  p.weight_height = 512;
  return p;
}
}  // namespace

TEST(PrefilteredParts, FollowEachLayersPatchesAndTheFeatureSizeWithTheFootprint) {
  gpu::TvtComposeParams p = prefiltered_params();  // every sample lattice below is narrower than a weight texel
  gpu::TvtMaterial& dpt = p.materials[1];
  dpt.mode = gpu::TVT_MODE_DPT;
  dpt.resolution = 256;
  dpt.period_fp = 256 * 256;
  dpt.dpt_layer_count = 1;
  dpt.dpt_fade_lo = 1.0f;
  dpt.dpt_fade_hi = 2.0f;
  dpt.dpt[0].patch_texels = 64.0f;
  gpu::TvtMaterial& fbpb = p.materials[2];  // one material texel a level-0 texel: its LOD is the mip
  fbpb.mode = gpu::TVT_MODE_FBPB;
  fbpb.resolution = 256;
  fbpb.period_fp = 256 * 256;
  fbpb.fbpb_fade_lo = 1.0f;
  fbpb.fbpb_fade_hi = 2.0f;
  using namespace gpu;
  // Material 2's features 2^2.9 = 7.5 texels a side: exact at points while the LOD is below
  // 2.9 + TVT_FEATURE_POINTS_REL = 3.15, in expectation from there; a switch, never both.
  FeatureSizes sizes = unknown_feature_sizes();
  sizes[2] = 2.9f;
  EXPECT_EQ(TVT_FEATURE_POINTS_REL, 0.25f);
  // Footprint 2: 32 texels a patch, exact; features exact at points (LOD 1).
  EXPECT_EQ(prefiltered_parts(p, 1, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURES);
  EXPECT_EQ(prefiltered_parts(p, 2, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURES);
  EXPECT_EQ(prefiltered_parts(p, 3, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURES);
  EXPECT_EQ(prefiltered_parts(p, 4, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURE_EXPECT);
  // The LOD at a power-of-two footprint is exactly mip + lod_bias, and the host decides the
  // switch in the shader's float arithmetic: a size whose edge is LOD 3 exactly puts LOD 3 in
  // expectation, one a float step larger keeps it at points.
  sizes[2] = 2.75f;
  EXPECT_EQ(prefiltered_parts(p, 3, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURE_EXPECT);
  sizes[2] = std::nextafter(2.75f, 3.0f);
  EXPECT_EQ(prefiltered_parts(p, 3, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURES);
  // The size is the feature's, not the fade's: the fade's end (LOD 2) moves nothing.
  fbpb.fbpb_fade_lo = 0.0f;
  fbpb.fbpb_fade_hi = 0.5f;
  EXPECT_EQ(prefiltered_parts(p, 3, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURES);
  fbpb.fbpb_fade_lo = 1.0f;
  fbpb.fbpb_fade_hi = 2.0f;
  // Not loaded (NaN): no page reads it until it is, and then its parts are worked out again.
  EXPECT_EQ(prefiltered_parts(p, 3, unknown_feature_sizes()), TVT_PART_DPT_POINT);
  EXPECT_EQ(prefiltered_parts(p, 8, unknown_feature_sizes()), TVT_PART_DPT_EXPECT | TVT_PART_DPT_SAMPLES);
  sizes[2] = 2.9f;
  // Two material texels a level-0 texel: the LOD is the mip + 1 (as pack_scene() sets it).
  fbpb.lod_bias = 1.0f;
  EXPECT_EQ(prefiltered_parts(p, 2, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURES);
  EXPECT_EQ(prefiltered_parts(p, 3, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURE_EXPECT);
  // Level 0 past the feature fade (its LOD 2 at the fade's end): the truth has no features, so
  // no prefiltered mip keeps either part.
  fbpb.lod_bias = 2.0f;
  EXPECT_EQ(prefiltered_parts(p, 1, sizes), TVT_PART_DPT_POINT);
  EXPECT_EQ(prefiltered_parts(p, 4, sizes), TVT_PART_DPT_POINT);
  fbpb.lod_bias = 0.0f;
  // Footprint 32 is on the patch ramp's upper end (2 texels of patch a texel) and 128 on its
  // lower end: the shader's ratio is exact at power-of-two footprints and its ramp is exactly 1
  // and 0 there, so the expectation (and its samples) and the point value are left out.
  EXPECT_EQ(prefiltered_parts(p, 5, sizes), TVT_PART_DPT_POINT | TVT_PART_FEATURE_EXPECT);
  EXPECT_EQ(prefiltered_parts(p, 6, sizes),
            TVT_PART_ALL & ~TVT_PART_FEATURES & ~TVT_PART_DPT_SAMPLES_WIDE & ~TVT_PART_DPT_CORNERS_WIDE &
                ~TVT_PART_FEATURE_WEIGHTS_WIDE);
  EXPECT_EQ(prefiltered_parts(p, 7, sizes), TVT_PART_DPT_EXPECT | TVT_PART_DPT_SAMPLES | TVT_PART_FEATURE_EXPECT);
  // Footprint 256: four patches a side, in expectation from samples; 1024: 16, expectation alone.
  EXPECT_EQ(prefiltered_parts(p, 8, sizes), TVT_PART_DPT_EXPECT | TVT_PART_DPT_SAMPLES | TVT_PART_FEATURE_EXPECT);
  EXPECT_EQ(prefiltered_parts(p, 10, sizes), TVT_PART_DPT_EXPECT | TVT_PART_FEATURE_EXPECT);
  // The samples' corner lattice spans the footprint and a patch either side: 256 + 128 level-0
  // texels at footprint 256. A weight texel every 256 texels (4096 a side) is not enough
  // margin, every 512 is; no weights (parameters not from pack_scene) keep the wide path.
  for (const int size : {4096, 2048, 0}) {
    p.weight_width = size;
    EXPECT_EQ(prefiltered_parts(p, 8, sizes) & TVT_PART_DPT_SAMPLES_WIDE, size == 2048 ? 0u : TVT_PART_DPT_SAMPLES_WIDE) << size;
    EXPECT_EQ(prefiltered_parts(p, 5, sizes) & TVT_PART_DPT_SAMPLES_WIDE, 0u) << size;  // no samples at footprint 32
  }
  // A patch cell's corners lie one patch (64 texels, + 1 for rounding) apart: narrow at any
  // weight grid up to 16384 a side (a texel every 64 texels, less the margin, is not enough),
  // where the point value is composed (mips 1-6) and in direct pages; no weights keep the
  // general path.
  for (const int size : {16384, 8192, 0}) {
    p.weight_width = size;
    const uint32_t wide = size == 8192 ? 0u : TVT_PART_DPT_CORNERS_WIDE;
    EXPECT_EQ(prefiltered_parts(p, 1, sizes) & TVT_PART_DPT_CORNERS_WIDE, wide) << size;
    EXPECT_EQ(prefiltered_parts(p, 6, sizes) & TVT_PART_DPT_CORNERS_WIDE, wide) << size;
    EXPECT_EQ(prefiltered_parts(p, 8, sizes) & TVT_PART_DPT_CORNERS_WIDE, 0u) << size;  // no point value at footprint 256
    EXPECT_EQ(direct_parts(p), TVT_PART_ALL & ~(TVT_PART_DPT_CORNERS_WIDE & ~wide)) << size;
  }
  // The FBPB points' feature centroids lie within half the footprint and a tile's reach of the
  // texel's centre (256 level-0 texels, + 2 for the centroid's half texel and the rounding):
  // 2 + 2 * 258 = 518 texels at footprint 2, more than a weight texel every 512 less the margin
  // (504), well within one every 1024; no weights, and direct pages, keep a fetch a point.
  for (const int size : {2048, 1024, 0}) {
    p.weight_width = size;
    const uint32_t wide = size == 1024 ? 0u : TVT_PART_FEATURE_WEIGHTS_WIDE;
    EXPECT_EQ(prefiltered_parts(p, 1, sizes) & TVT_PART_FEATURE_WEIGHTS_WIDE, wide) << size;
    EXPECT_EQ(prefiltered_parts(p, 3, sizes) & TVT_PART_FEATURE_WEIGHTS_WIDE, wide) << size;
    EXPECT_EQ(prefiltered_parts(p, 4, sizes) & TVT_PART_FEATURE_WEIGHTS_WIDE, 0u) << size;  // no points at LOD 4
    EXPECT_NE(direct_parts(p) & TVT_PART_FEATURE_WEIGHTS_WIDE, 0u) << size;
  }
  p.weight_width = 512;
  // FBPB features that have faded out before the finest texture level: never in expectation.
  fbpb.fbpb_fade_lo = -2.0f;
  fbpb.fbpb_fade_hi = -1.0f;
  EXPECT_EQ(prefiltered_parts(p, 10, sizes), TVT_PART_DPT_EXPECT);
  // A DPT layer below the minification fade is absent at every prefiltered footprint; a
  // direct page supersampled 4 x 4 (footprint 1/4) shows it, so direct pages keep the general
  // path where it would be wide (a weight texel every 0.5 level-0 texels).
  dpt.dpt[0].patch_texels = 0.5f;
  EXPECT_EQ(prefiltered_parts(p, 1, sizes), 0u);
  p.log2_vt = 10;
  p.weight_width = 2048;
  EXPECT_EQ(direct_parts(p), TVT_PART_ALL);
  p.log2_vt = 20;
  p.weight_width = 512;
  EXPECT_EQ(direct_parts(p), TVT_PART_ALL & ~TVT_PART_DPT_CORNERS_WIDE);
  // Numbers no validated scene has keep every part.
  dpt.dpt[0].patch_texels = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(prefiltered_parts(p, 4, sizes), TVT_PART_ALL);
  EXPECT_EQ(direct_parts(p), TVT_PART_ALL);
  dpt.dpt[0].patch_texels = 64.0f;
  fbpb.period_fp = 0;
  EXPECT_EQ(prefiltered_parts(p, 4, sizes), TVT_PART_ALL);
}

// The (material, layer) pairs whose samples a mip reaches, sampled before the material loop:
// in material and layer order, none where no layer samples, and none (the samples stay in the
// loop) where there are more than the pre-pass takes, a lattice may be wide, or the numbers are
// not a validated scene's.
TEST(SamplePairs, NameTheSampledLayersInOrderUpToTheMost) {
  gpu::TvtComposeParams p = prefiltered_params();  // the lattices below are narrow
  const FeatureSizes sizes = unknown_feature_sizes();      // the pairs are DPT's alone
  for (int n = 1; n < 4; ++n) {
    gpu::TvtMaterial& m = p.materials[n];
    m.mode = n == 2 ? gpu::TVT_MODE_FBPB_DPT : gpu::TVT_MODE_DPT;
    m.resolution = 256;
    m.period_fp = 256 * 256;
    m.fbpb_fade_lo = 1.0f;
    m.fbpb_fade_hi = 2.0f;
    m.dpt_fade_lo = 1.0f;
    m.dpt_fade_hi = 2.0f;
    m.dpt_layer_count = n == 2 ? 1 : 2;
    m.dpt[0].patch_texels = 64.0f;
    m.dpt[1].patch_texels = 16.0f;
  }
  using namespace gpu;
  const auto pairs = [](uint32_t encoded) {
    std::vector<std::pair<int, int>> out;
    for (int i = 0; i < int(tvt_sample_pairs_count(encoded)); ++i)
      out.emplace_back(tvt_sample_pairs_material(encoded, i), tvt_sample_pairs_layer(encoded, i));
    return out;
  };
  using Pairs = std::vector<std::pair<int, int>>;
  ASSERT_EQ(TVT_SAMPLE_PAIRS_MAX, 2);
  // Footprint 8: both layers exact (8 and 2 texels of patch a texel), no samples.
  EXPECT_EQ(sample_pairs(p, 3), 0u);
  EXPECT_EQ(prefiltered_parts(p, 3, sizes) & TVT_PART_DPT_SAMPLES, 0u);
  // Footprint 256: the 64-texel patches in expectation from samples (4 a side), the 16-texel ones
  // in expectation alone (16 a side).
  EXPECT_EQ(pairs(sample_pairs(p, 8)), (Pairs{{1, 0}, {2, 0}}));
  // Footprint 32: the 16-texel patches (2 a side) sampled, the 64-texel ones exact.
  EXPECT_EQ(pairs(sample_pairs(p, 5)), (Pairs{{1, 1}}));
  // Footprint 64: one patch and four a side, both sampled: three pairs, in the loop.
  EXPECT_EQ(sample_pairs(p, 6), 0u);
  EXPECT_NE(prefiltered_parts(p, 6, sizes) & TVT_PART_DPT_SAMPLES, 0u);
  // Material 2's layer below the minification fade has no samples at any footprint.
  p.materials[2].dpt[0].patch_texels = 0.5f;
  EXPECT_EQ(pairs(sample_pairs(p, 6)), (Pairs{{1, 0}, {1, 1}}));
  EXPECT_EQ(pairs(sample_pairs(p, 8)), (Pairs{{1, 0}}));
  // A weight texel every 256 level-0 texels: the lattice of footprint 256 (256 + 128 texels)
  // may span three, which only the loop's general path takes; footprint 64's still fit.
  p.weight_width = 4096;
  EXPECT_EQ(sample_pairs(p, 8), 0u);
  EXPECT_EQ(pairs(sample_pairs(p, 6)), (Pairs{{1, 0}, {1, 1}}));
  p.weight_width = 512;
  p.materials[2].dpt[0].patch_texels = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(sample_pairs(p, 6), 0u);
  // The encoding holds every material and layer index.
  uint32_t encoded = 0;
  for (int i = 0; i < TVT_SAMPLE_PAIRS_MAX; ++i) encoded = tvt_sample_pairs_add(encoded, 15 - i, 3 - i);
  EXPECT_EQ(pairs(encoded), (Pairs{{15, 3}, {14, 2}}));
  encoded = tvt_sample_pairs_add(tvt_sample_pairs_add(0, 7, 1), 9, 2);
  EXPECT_EQ(pairs(encoded), (Pairs{{7, 1}, {9, 2}}));
}

TEST(PackScene, LodBiasIsTheMaterialLodAtOneLevel0Texel) {
  const SceneAssets& assets = default_assets(16);
  auto packed = pack_scene(assets, options_for(Method::FbpbDpt));
  ASSERT_TRUE(packed.ok()) << packed.error().message;
  const gpu::TvtComposeParams& p = packed.value().params;
  for (int n = 0; n < p.material_count; ++n) {
    const gpu::TvtMaterial& m = p.materials[n];
    EXPECT_EQ(m.lod_bias, float(std::log2(double(m.resolution) * 256.0 / double(m.period_fp)))) << n;
  }
  // The cobbles: 512 texels over a 256-texel period, two material texels a level-0 texel.
  EXPECT_EQ(p.materials[4].lod_bias, 1.0f);
}

TEST(SmallCoordinates, HoldUpToTwoToThe21AndForPatchesAndHexTilesThatFit) {
  gpu::TvtComposeParams p{};
  p.log2_vt = 21;
  p.material_count = 2;
  gpu::TvtMaterial& m = p.materials[1];
  m.resolution = 1024;
  m.period_fp = 512 * 256;  // two material texels a level-0 texel
  m.dpt_layer_count = 1;
  m.dpt[0].patch_fp = int64_t(1024) * 256;
  m.hex_edge = 64;
  EXPECT_TRUE(small_coordinates(p));  // material texels up to 2^22
  p.log2_vt = 22;
  EXPECT_FALSE(small_coordinates(p));  // positions beyond 2^30 / 1.5
  p.log2_vt = 21;
  m.period_fp = 8 * 256;  // 128 material texels a level-0 texel: 2^28 of them across V
  EXPECT_FALSE(small_coordinates(p));
  m.hex_edge = 0;  // without hex-tiling, nothing divides them
  EXPECT_TRUE(small_coordinates(p));
  m.dpt[0].patch_fp = int64_t(1) << 30;
  EXPECT_FALSE(small_coordinates(p));
}

TEST_F(GpuCompose, PagesAreDeterministicAndBordersMatchNeighbours) {
  const SceneAssets& assets = default_assets(16);
  auto packed = pack_scene(assets, options_for(Method::FbpbDpt));
  ASSERT_TRUE(packed.ok());
  auto composer = GpuComposer::create(ctx(), packed.value(), 4);
  ASSERT_TRUE(composer.ok());
  const std::vector<PageId> pages = {{0, 100, 200}, {0, 101, 200}, {0, 100, 201}};
  const auto first = composer.value()->compose_pages(pages).value();
  const auto again = composer.value()->compose_pages(pages).value();
  EXPECT_EQ(first, again);
  const int P = int(assets.desc.vt.page_texels), B = int(assets.desc.vt.border_texels), S = P + 2 * B;
  for (int y = 0; y < S; ++y)
    for (int b = 0; b < B; ++b)
      for (int c = 0; c < 4; ++c) {
        EXPECT_EQ(first[0][size_t((y * S + B + P + b) * 4 + c)], first[1][size_t((y * S + B + b) * 4 + c)]);
        EXPECT_EQ(first[0][size_t(((B + P + b) * S + y) * 4 + c)], first[2][size_t(((B + b) * S + y) * 4 + c)]);
      }
}

TEST_F(GpuCompose, MaterialCullingIsExact) {
  const SceneAssets& assets = default_assets(16);
  for (Method m : {Method::FbpbDpt, Method::Linear}) {
    auto packed = pack_scene(assets, options_for(m));
    ASSERT_TRUE(packed.ok());
    auto composer = GpuComposer::create(ctx(), packed.value(), 8);
    ASSERT_TRUE(composer.ok());
    // A spread of pages, several of which cull materials (checked below).
    std::vector<PageId> pages;
    for (uint32_t i = 0; i < 8; ++i) pages.push_back(PageId{i % 3, (i * 37) % 64, (i * 53 + 11) % 64});
    const MaterialCuller culler(packed.value());
    int culled = 0;
    for (const PageId& p : pages) culled += std::popcount(~culler.mask(p) & ((1u << packed->params.material_count) - 1u));
    EXPECT_GT(culled, 0);
    const auto with = composer.value()->compose_pages(pages).value();
    composer.value()->set_culling(false);
    const auto without = composer.value()->compose_pages(pages).value();
    EXPECT_EQ(with, without) << to_string(m);
  }
}
