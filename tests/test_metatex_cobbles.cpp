// Meta-textures of the built-in feature materials against the generators' exact truth.
#include <gtest/gtest.h>

#include <set>

#include "compose/metatex.h"
#include "compose/procedural.h"

using namespace tvt;

namespace {

std::set<std::pair<int, int>> wrapped_centroids(const MetaTexture& m) {
  std::set<std::pair<int, int>> c;
  const int R = m.resolution;
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) {
      const MetaTexel& t = m.at(x, y);
      if (t.d) c.insert({((x + t.dx) % R + R) % R, ((y + t.dy) % R + R) % R});
    }
  return c;
}

}  // namespace

class BuiltInFeatures : public ::testing::TestWithParam<std::tuple<const char*, uint32_t, uint32_t>> {};

TEST_P(BuiltInFeatures, ExactLabelsGiveOneCentroidPerFeature) {
  const auto [name, resolution, seed] = GetParam();
  auto g = generate_material(name, resolution, seed);
  ASSERT_TRUE(g.ok()) << g.error().message;
  FeatureLabels labels{int(resolution), g->feature_labels, g->feature_count};
  const MetaTexture meta = build_meta_texture(labels, g->variation, 2.0);
  EXPECT_EQ(meta.feature_count, g->feature_count);
  EXPECT_EQ(wrapped_centroids(meta).size(), size_t(g->feature_count));
}

TEST_P(BuiltInFeatures, AutomaticIsolationFindsTheGeneratorsFeatures) {
  const auto [name, resolution, seed] = GetParam();
  auto g = generate_material(name, resolution, seed);
  ASSERT_TRUE(g.ok());
  const FeatureLabels found = isolate_features(g->albedo, IsolationOptions{});
  EXPECT_EQ(found.count, g->feature_count) << name << " at " << resolution;
  // Found features overlap the true ones: texel agreement of the binary masks.
  size_t agree = 0;
  for (size_t i = 0; i < found.labels.size(); ++i) agree += (found.labels[i] >= 0) == (g->feature_labels[i] >= 0);
  EXPECT_GT(double(agree) / double(found.labels.size()), 0.9);
  const MetaTexture meta = build_meta_texture(found, g->variation, 2.0);
  EXPECT_EQ(wrapped_centroids(meta).size(), size_t(found.count));
}

INSTANTIATE_TEST_SUITE_P(Generators, BuiltInFeatures,
                         ::testing::Values(std::make_tuple("cobbles", 256u, 1u), std::make_tuple("cobbles", 512u, 7u),
                                           std::make_tuple("bricks", 256u, 3u)));
