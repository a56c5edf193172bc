#include <gtest/gtest.h>

#include "compose/material_culling.h"
#include "compose/reference_compositor.h"
#include "support/synthetic_scene.h"

using namespace tvt;

// Material 1 has weight only in weight texel (3, 3) of a 4x4 grid over V = 2^10 (cells of
// 256 texels). Pages far from it cull it; pages within reach keep it, and a culled page's
// texels equal those composed with the material present (its b is 0 there).
TEST(MaterialCulling, CullsOnlyWhatCannotContribute) {
  test::SyntheticMaterial base{{100, 0, 0, 100}, 0.f, Mode::BlendMap};
  test::SyntheticMaterial top{{0, 200, 0, 100}, 0.f, Mode::Dpt};
  auto a = test::make_synthetic_assets({base, top});
  a.desc.materials[1].dpt.layers = {{16, 1, 1, 1, 0.5}};
  a.weights.data[16 + 3 * 4 + 3] = 1.f;
  auto packed = pack_scene(a, {});
  ASSERT_TRUE(packed.ok());
  const MaterialCuller culler(packed.value());
  EXPECT_EQ(culler.mask(PageId{0, 0, 0}), 1u);        // texels 0..15: far from cell (3,3)
  EXPECT_EQ(culler.mask(PageId{0, 63, 63}), 3u);      // inside it
  EXPECT_EQ(culler.mask(PageId{0, 40, 40}), 3u);      // bilinear reach of the neighbouring cell
  EXPECT_EQ(culler.mask(PageId{6, 0, 0}), 3u);        // the top mip sees everything
  // Exactness: wherever the culler drops material 1, the reference gives it b = 0.
  for (uint32_t py = 0; py < 64; py += 3)
    for (uint32_t px = 0; px < 64; px += 3) {
      if (culler.mask(PageId{0, px, py}) & 2u) continue;
      const glm::dvec4 c = compose_texel_reference(packed.value(), 0, px * 16 + 7, py * 16 + 7);
      EXPECT_EQ(c.g, 0.0) << px << "," << py;
    }
}

// An FBPB feature's texels may lie almost a tile from its centroid (a lopsided shape: the
// meta-texture keeps offsets inside one tile, not half of one), and the feature shows there
// at its centroid's weight. Material 1's weight is in weight texel (3, 3) alone (cells of
// 1024 texels over V = 2^12); every texel of its 16-texel tile is a feature texel 14 texels
// left of its centroid, 1536 level-0 texels a tile (96 a material texel), so a texel at
// x ~ 1250 reads the weight at x ~ 2640, inside cell 3's bilinear reach. With Cf = 100 a
// feature with any weight there shows. Wherever the culler drops material 1, the reference
// gives it b = 0; pages far enough away are still dropped.
TEST(MaterialCulling, ReachesFeaturesWhoseCentroidsAreAlmostATileAway) {
  test::SyntheticMaterial base{{100, 0, 0, 100}, 0.f, Mode::BlendMap};
  test::SyntheticMaterial top{{0, 200, 0, 100}, 0.f, Mode::Fbpb};
  auto a = test::make_synthetic_assets({base, top}, 12);
  a.weights.data[16 + 3 * 4 + 3] = 1.f;
  a.desc.materials[1].period_texels = 1536.0;
  a.desc.materials[1].has_fbpb = true;
  a.desc.materials[1].fbpb.cf = 100.0;
  MetaTexture meta;
  meta.resolution = 16;
  meta.feature_count = 1;
  meta.texels.resize(16 * 16);
  for (MetaTexel& t : meta.texels) {
    t.d = 1;
    t.f = 200;
    t.dx = 14;
    t.variation = 255;
  }
  a.materials->edit(1).meta = std::move(meta);
  auto packed = pack_scene(a, {});
  ASSERT_TRUE(packed.ok()) << packed.error().message;
  ASSERT_EQ(packed->params.materials[1].mode, gpu::TVT_MODE_FBPB);
  const MaterialCuller culler(packed.value());
  int culled = 0, shown = 0;
  for (uint32_t py = 160; py < 256; py += 8)
    for (uint32_t px = 0; px < 128; ++px) {
      const bool kept = (culler.mask(PageId{0, px, py}) & 2u) != 0;
      culled += kept ? 0 : 1;
      for (const uint32_t t : {1u, 8u, 14u}) {
        const glm::dvec4 c = compose_texel_reference(packed.value(), 0, px * 16 + t, py * 16 + 8);
        shown += c.g > 0.0 ? 1 : 0;
        if (!kept) {
          EXPECT_EQ(c.g, 0.0) << px << "," << py << " texel " << t;
        }
      }
    }
  EXPECT_GT(culled, 0);
  EXPECT_GT(shown, 0);  // features reach the weighted cell from pages left of it
}
