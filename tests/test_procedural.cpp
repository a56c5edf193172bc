// Procedural materials and fBm grids (compose/procedural.h): determinism, seamless tiling,
// exact feature labels on the torus, fbm_grid range/periodicity/robustness, input errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "compose/procedural.h"

using namespace tvt;

namespace {

const std::vector<std::string> k_all{"sand", "grass", "rock", "mud", "cobbles", "bricks"};

GeneratedMaterial make(const std::string& g, uint32_t r, uint32_t seed = 11) {
  auto m = generate_material(g, r, seed);
  EXPECT_TRUE(m.ok()) << g << " " << r << ": " << (m.ok() ? "" : m.error().message);
  return std::move(m).value();
}

int wrap(int v, int n) { return ((v % n) + n) % n; }

// Mean |a - b| over channel c between column xa and column xb (or rows if rows == true).
double line_diff(const ImageRGBA8& img, int a, int b, int c, bool rows) {
  double sum = 0.0;
  for (int t = 0; t < img.width; ++t) {
    const uint8_t* p = rows ? img.at(t, a) : img.at(a, t);
    const uint8_t* q = rows ? img.at(t, b) : img.at(b, t);
    sum += std::abs(int(p[c]) - int(q[c]));
  }
  return sum / img.width;
}

// Sizes of the 4-connected components (on the torus) of each label.
std::vector<std::vector<int>> component_sizes(const std::vector<int32_t>& labels, int n, uint32_t count) {
  std::vector<std::vector<int>> sizes(count);
  std::vector<uint8_t> seen(labels.size(), 0);
  std::vector<int> stack;
  for (int start = 0; start < n * n; ++start) {
    if (labels[size_t(start)] < 0 || seen[size_t(start)]) continue;
    const int32_t l = labels[size_t(start)];
    int size = 0;
    seen[size_t(start)] = 1;
    stack.push_back(start);
    while (!stack.empty()) {
      const int t = stack.back();
      stack.pop_back();
      ++size;
      const int x = t % n, y = t / n;
      const int nb[4] = {y * n + wrap(x + 1, n), y * n + wrap(x - 1, n), wrap(y + 1, n) * n + x, wrap(y - 1, n) * n + x};
      for (int m : nb)
        if (labels[size_t(m)] == l && !seen[size_t(m)]) {
          seen[size_t(m)] = 1;
          stack.push_back(m);
        }
    }
    sizes[size_t(l)].push_back(size);
  }
  return sizes;
}

}  // namespace

TEST(Procedural, KnownGeneratorsAndErrorsNameTheGeneratorAndValue) {
  for (const auto& g : k_all) EXPECT_TRUE(is_known_generator(g)) << g;
  EXPECT_FALSE(is_known_generator("lava"));
  EXPECT_FALSE(is_known_generator(""));
  EXPECT_FALSE(is_known_generator("Sand"));

  auto bad = generate_material("lava", 64, 1);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("lava"), std::string::npos);
  for (uint32_t r : {0u, 8u, 100u, 8192u, 48u}) {
    auto e = generate_material("rock", r, 1);
    ASSERT_FALSE(e.ok()) << r;
    EXPECT_NE(e.error().message.find("rock"), std::string::npos) << e.error().message;
    EXPECT_NE(e.error().message.find(std::to_string(r)), std::string::npos) << e.error().message;
  }
  EXPECT_TRUE(generate_material("rock", 16, 1).ok());
}

TEST(Procedural, DeterministicInSeedAndDifferentAcrossSeedsAndGenerators) {
  std::set<std::vector<uint8_t>> distinct;
  for (const auto& g : k_all) {
    const auto a = make(g, 64, 5), b = make(g, 64, 5), c = make(g, 64, 6);
    EXPECT_EQ(a.albedo.texels, b.albedo.texels) << g;
    EXPECT_EQ(a.variation.texels, b.variation.texels) << g;
    EXPECT_EQ(a.feature_labels, b.feature_labels) << g;
    EXPECT_NE(a.albedo.texels, c.albedo.texels) << g;
    EXPECT_NE(a.variation.texels, c.variation.texels) << g;
    distinct.insert(a.albedo.texels);
  }
  EXPECT_EQ(distinct.size(), k_all.size());
}

TEST(Procedural, ShapesAndMaterialColoursAreDistinct) {
  // Mean albedo per generator: the six must be clearly apart (they are compared side by side).
  std::vector<std::array<double, 4>> means;
  for (const auto& g : k_all) {
    const auto m = make(g, 128);
    ASSERT_EQ(m.albedo.width, 128);
    ASSERT_EQ(m.albedo.texels.size(), size_t(128 * 128 * 4));
    ASSERT_EQ(m.variation.texels.size(), size_t(128 * 128));
    const bool features = g == "cobbles" || g == "bricks";
    EXPECT_EQ(m.feature_labels.size(), features ? size_t(128 * 128) : size_t(0)) << g;
    EXPECT_EQ(m.feature_count > 0, features) << g;
    std::array<double, 4> mean{};
    for (size_t i = 0; i < m.albedo.texels.size(); ++i) mean[i % 4] += m.albedo.texels[i];
    for (double& v : mean) v /= 128.0 * 128.0;
    means.push_back(mean);
  }
  for (size_t a = 0; a < means.size(); ++a)
    for (size_t b = a + 1; b < means.size(); ++b) {
      const double d = std::abs(means[a][0] - means[b][0]) + std::abs(means[a][1] - means[b][1]) +
                       std::abs(means[a][2] - means[b][2]);
      EXPECT_GT(d, 10.0) << k_all[a] << " vs " << k_all[b];
    }
  // Recognisable hues: sand warm (R > G > B), grass green, bricks red, mud dark.
  EXPECT_TRUE(means[0][0] > means[0][1] && means[0][1] > means[0][2]);
  EXPECT_GT(means[1][1], means[1][0]);
  EXPECT_GT(means[1][1], means[1][2]);
  EXPECT_GT(means[5][0], means[5][1] + 30.0);
  EXPECT_LT(means[3][0] + means[3][1] + means[3][2], means[0][0] + means[0][1] + means[0][2] - 150.0);
  // Rock has strong relief, sand weak: compare alpha standard deviations.
  auto alpha_sd = [](const GeneratedMaterial& m) {
    double s = 0, s2 = 0;
    const double n = double(m.albedo.texels.size() / 4);
    for (size_t i = 3; i < m.albedo.texels.size(); i += 4) s += m.albedo.texels[i], s2 += double(m.albedo.texels[i]) * m.albedo.texels[i];
    return std::sqrt(s2 / n - (s / n) * (s / n));
  };
  EXPECT_GT(alpha_sd(make("rock", 256)), 2.0 * alpha_sd(make("sand", 256)));
}

// A seam shows as a wrap-around step (texel R-1 next to texel 0) unlike the steps inside the
// tile. Unstructured materials: compare with the mean interior step. Bricks repeat their
// layout every R/2 (two brick lengths, three course pairs) and cobble cells every R/2 (half
// the jittered grid), so for them the seam must look like the step at the same phase in the
// middle of the tile (the mean over all steps depends on whether a step crosses mortar or a
// dome top). Summed over three seeds to tame single-row noise.
TEST(Procedural, EveryChannelTilesSeamlessly) {
  for (uint32_t r : {64u, 256u}) {
    for (const auto& g : k_all) {
      const int n = int(r);
      std::array<std::array<double, 2>, 4> seam{}, interior{}, mid{};
      double var_seam = 0, var_interior = 0;
      for (uint32_t seed : {3u, 4u, 5u}) {
        const auto m = make(g, r, seed);
        for (int c = 0; c < 4; ++c)
          for (int rows = 0; rows < 2; ++rows) {
            for (int i = 0; i + 1 < n; ++i) interior[size_t(c)][size_t(rows)] += line_diff(m.albedo, i, i + 1, c, rows) / (n - 1);
            seam[size_t(c)][size_t(rows)] += line_diff(m.albedo, n - 1, 0, c, rows);
            mid[size_t(c)][size_t(rows)] += line_diff(m.albedo, n / 2 - 1, n / 2, c, rows);
          }
        for (int y = 0; y < n; ++y) {
          for (int x = 0; x + 1 < n; ++x) var_interior += std::abs(int(m.variation.at(x, y)) - int(m.variation.at(x + 1, y)));
          var_seam += std::abs(int(m.variation.at(n - 1, y)) - int(m.variation.at(0, y)));
        }
      }
      for (size_t c = 0; c < 4; ++c)
        for (size_t rows = 0; rows < 2; ++rows) {
          const double ref = (g == "bricks" || g == "cobbles") ? mid[c][rows] : interior[c][rows];
          const double s = seam[c][rows];
          EXPECT_LE(s, 2.0 * ref + 1.5) << g << " " << r << " channel " << c << (rows ? " rows" : " cols");
          EXPECT_GE(s, 0.5 * ref - 1.5) << g << " " << r << " channel " << c << (rows ? " rows" : " cols");
        }
      var_interior /= double(n - 1);
      EXPECT_LE(var_seam, 2.0 * var_interior + 1.5) << g;
      EXPECT_GE(var_seam, 0.5 * var_interior - 1.5) << g;
    }
  }
}

TEST(Procedural, VariationMapUsesFullRangeAroundMidGrey) {
  for (const auto& g : k_all) {
    const auto m = make(g, 256);
    const auto [lo, hi] = std::minmax_element(m.variation.texels.begin(), m.variation.texels.end());
    EXPECT_EQ(*lo, 0) << g;
    EXPECT_EQ(*hi, 255) << g;
    double mean = 0;
    for (uint8_t v : m.variation.texels) mean += v;
    mean /= double(m.variation.texels.size());
    EXPECT_GT(mean, 90.0) << g;
    EXPECT_LT(mean, 166.0) << g;
  }
}

class FeatureLabels : public ::testing::TestWithParam<std::tuple<std::string, uint32_t>> {};

TEST_P(FeatureLabels, AreExactComponentsOnTheTorus) {
  const auto& [g, r] = GetParam();
  const auto m = make(g, r, 21);
  const int n = int(r);
  ASSERT_EQ(m.feature_labels.size(), size_t(n) * size_t(n));
  ASSERT_GT(m.feature_count, 0u);

  // Labels in range, every id used.
  std::vector<int> texels(m.feature_count, 0);
  for (int32_t l : m.feature_labels) {
    ASSERT_GE(l, -1);
    ASSERT_LT(l, int32_t(m.feature_count));
    if (l >= 0) ++texels[size_t(l)];
  }
  for (uint32_t l = 0; l < m.feature_count; ++l) EXPECT_GE(texels[l], 8) << "label " << l;

  // Each label is exactly one 4-connected component on the torus.
  const auto comps = component_sizes(m.feature_labels, n, m.feature_count);
  for (uint32_t l = 0; l < m.feature_count; ++l) EXPECT_EQ(comps[l].size(), 1u) << "label " << l;

  // No two different labels touch, even diagonally, across the tile edges included.
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int32_t l = m.feature_labels[size_t(y * n + x)];
      if (l < 0) continue;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int32_t o = m.feature_labels[size_t(wrap(y + dy, n) * n + wrap(x + dx, n))];
          ASSERT_TRUE(o < 0 || o == l) << "labels " << l << " and " << o << " touch at " << x << "," << y;
        }
    }

  // Features reach the tile edges and wrap around them: some label occupies both column 0
  // and column n-1 in the same row (and likewise for rows), and the corner feature has all
  // four corner texels.
  bool wraps_x = false, wraps_y = false, on_left = false, on_top = false;
  for (int t = 0; t < n; ++t) {
    const int32_t left = m.feature_labels[size_t(t * n)], right = m.feature_labels[size_t(t * n + n - 1)];
    const int32_t top = m.feature_labels[size_t(t)], bottom = m.feature_labels[size_t((n - 1) * n + t)];
    on_left |= left >= 0;
    on_top |= top >= 0;
    wraps_x |= left >= 0 && left == right;
    wraps_y |= top >= 0 && top == bottom;
  }
  EXPECT_TRUE(on_left && on_top);
  EXPECT_TRUE(wraps_x);
  EXPECT_TRUE(wraps_y);
  const int32_t corner = m.feature_labels[0];
  EXPECT_GE(corner, 0);
  EXPECT_EQ(m.feature_labels[size_t(n - 1)], corner);
  EXPECT_EQ(m.feature_labels[size_t((n - 1) * n)], corner);
  EXPECT_EQ(m.feature_labels[size_t(n * n - 1)], corner);

  // The height map reveals features first: features stand above the mortar, and most of the
  // tile's mortar is lower than any feature's mean height.
  double feat = 0, mortar = 0;
  size_t nf = 0, nm = 0;
  for (size_t i = 0; i < m.feature_labels.size(); ++i) {
    const double a = m.albedo.texels[i * 4 + 3];
    if (m.feature_labels[i] >= 0) feat += a, ++nf;
    else mortar += a, ++nm;
  }
  ASSERT_GT(nm, 0u);
  EXPECT_GT(feat / double(nf), mortar / double(nm) + 60.0);
  // A meaningful share of the tile is feature, and a meaningful share is mortar.
  EXPECT_GT(double(nf) / double(n * n), 0.35);
  EXPECT_GT(double(nm) / double(n * n), 0.08);
}

INSTANTIATE_TEST_SUITE_P(CobblesAndBricks, FeatureLabels,
                         ::testing::Combine(::testing::Values("cobbles", "bricks"), ::testing::Values(64u, 256u, 512u)),
                         [](const auto& param_info) {
                           return std::get<0>(param_info.param) + "_" + std::to_string(std::get<1>(param_info.param));
                         });

TEST(Procedural, FeatureCountsScaleWithResolutionAndSmallestSizeStillWorks) {
  for (const std::string g : {"cobbles", "bricks"}) {
    for (uint32_t seed = 0; seed < 4; ++seed) {
      const auto m = make(g, 16, seed);
      ASSERT_EQ(m.feature_labels.size(), 256u);
      std::vector<int> texels(m.feature_count, 0);
      for (int32_t l : m.feature_labels) {
        ASSERT_LT(l, int32_t(m.feature_count));
        if (l >= 0) ++texels[size_t(l)];
      }
      for (int t : texels) EXPECT_GE(t, 8) << g;
      const auto comps = component_sizes(m.feature_labels, 16, m.feature_count);
      for (const auto& c : comps) EXPECT_EQ(c.size(), 1u) << g;
    }
    // The same pattern at higher resolution: the feature count does not depend on the
    // resolution once features are large enough.
    EXPECT_EQ(make(g, 256, 2).feature_count, make(g, 1024, 2).feature_count) << g;
  }
  for (const auto& g : k_all) EXPECT_TRUE(generate_material(g, 16, 9).ok()) << g;
}

TEST(FbmGrid, RangeIsExactlyZeroToOneAndPeriodic) {
  const uint32_t n = 128;
  const auto f = fbm_grid(n, 42, 6, 4.0, 0.5, 2.0);
  ASSERT_EQ(f.size(), size_t(n) * n);
  const auto [lo, hi] = std::minmax_element(f.begin(), f.end());
  EXPECT_EQ(*lo, 0.f);
  EXPECT_EQ(*hi, 1.f);
  // Periodic: the wrap-around step is like an interior step.
  double interior = 0, seam_x = 0, seam_y = 0;
  for (uint32_t y = 0; y < n; ++y) {
    for (uint32_t x = 0; x + 1 < n; ++x) interior += std::abs(f[y * n + x] - f[y * n + x + 1]);
    seam_x += std::abs(f[y * n + n - 1] - f[y * n]);
    seam_y += std::abs(f[(n - 1) * n + y] - f[y]);
  }
  interior /= double(n - 1);
  EXPECT_LE(seam_x, 2.0 * interior);
  EXPECT_LE(seam_y, 2.0 * interior);
  // Base octave alone (one octave, frequency 1): a smooth field with one period.
  const auto one = fbm_grid(n, 42, 1, 1.0, 0.5, 2.0);
  EXPECT_LT(std::abs(one[0] - one[n - 1]), 0.05f);
}

TEST(FbmGrid, OctavesAtHigherFrequencyAreTheSamePatternAtHigherResolution) {
  // Lattice points sit at texel positions k * size / frequency, so a 64-grid and a 128-grid with
  // the same seed and parameters agree at the shared texels before normalisation; after
  // normalisation both span [0,1], so they must still agree closely.
  const auto a = fbm_grid(64, 9, 3, 4.0, 0.5, 2.0);
  const auto b = fbm_grid(128, 9, 3, 4.0, 0.5, 2.0);
  double err = 0;
  for (uint32_t y = 0; y < 64; ++y)
    for (uint32_t x = 0; x < 64; ++x) err = std::max(err, double(std::abs(a[y * 64 + x] - b[(2 * y) * 128 + 2 * x])));
  EXPECT_LT(err, 0.05);
}

TEST(FbmGrid, DeterministicAndSeedDependent) {
  EXPECT_EQ(fbm_grid(64, 1, 5, 3.0, 0.5, 2.0), fbm_grid(64, 1, 5, 3.0, 0.5, 2.0));
  EXPECT_NE(fbm_grid(64, 1, 5, 3.0, 0.5, 2.0), fbm_grid(64, 2, 5, 3.0, 0.5, 2.0));
  EXPECT_NE(fbm_grid(64, 1, 5, 3.0, 0.5, 2.0), fbm_grid(64, 1, 5, 3.0, 0.6, 2.0));
  EXPECT_NE(fbm_grid(64, 1, 5, 3.0, 0.5, 2.0), fbm_grid(64, 1, 4, 3.0, 0.5, 2.0));
  // Frequency rounds to whole periods, so 3.2 and 3.0 give the same grid.
  EXPECT_EQ(fbm_grid(64, 1, 5, 3.2, 0.5, 2.0), fbm_grid(64, 1, 5, 3.0, 0.5, 2.0));
}

TEST(FbmGrid, ExtremeParametersNeverCrashOrProduceNaN) {
  EXPECT_TRUE(fbm_grid(0, 1, 4, 2.0, 0.5, 2.0).empty());
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  struct P {
    uint32_t size, octaves;
    double freq, gain, lac;
  };
  const P cases[] = {
      {1, 4, 2.0, 0.5, 2.0},     {2, 8, 1.0, 0.5, 2.0},   {33, 6, 3.0, 0.5, 2.0},     {64, 0, 4.0, 0.5, 2.0},
      {64, 1000, 4.0, 0.5, 2.0}, {64, 6, 0.0, 0.5, 2.0},  {64, 6, -5.0, 0.5, 2.0},    {64, 6, 1e300, 0.5, 2.0},
      {64, 6, 4.0, 0.0, 2.0},    {64, 6, 4.0, 1e300, 2.0}, {64, 6, 4.0, -1e300, 2.0}, {64, 6, 4.0, 1e-300, 2.0},
      {64, 6, 4.0, 0.5, 0.0},    {64, 6, 4.0, 0.5, -3.0}, {64, 6, 4.0, 0.5, 1e300},   {64, 6, 4.0, 0.5, 1.0},
      {64, 6, inf, nan, -inf},   {64, 6, nan, inf, nan},
  };
  for (const P& p : cases) {
    const auto f = fbm_grid(p.size, 7, p.octaves, p.freq, p.gain, p.lac);
    ASSERT_EQ(f.size(), size_t(p.size) * p.size);
    for (float v : f) {
      ASSERT_TRUE(std::isfinite(v)) << p.size << " " << p.octaves << " " << p.freq << " " << p.gain << " " << p.lac;
      ASSERT_GE(v, 0.f);
      ASSERT_LE(v, 1.f);
    }
    if (p.size > 1) {
      const auto [lo, hi] = std::minmax_element(f.begin(), f.end());
      EXPECT_EQ(*lo, 0.f);
      EXPECT_TRUE(*hi == 1.f || *hi == 0.f);
    }
  }
  // Huge frequency clamps to one lattice point per texel: still a varied field.
  const auto white = fbm_grid(32, 3, 1, 1e9, 0.5, 2.0);
  EXPECT_EQ(*std::max_element(white.begin(), white.end()), 1.f);
}
