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
