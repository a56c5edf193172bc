// compose/metatex.cpp: isolation and centroids on the torus (docs/composition.md), soft map, EXR file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "compose/image.h"
#include "compose/metatex.h"

namespace fs = std::filesystem;

namespace {

constexpr int R = 64;

int wrap(int v, int r = R) { return ((v % r) + r) % r; }
int minimal(int v, int r = R) {
  const int m = wrap(v, r);
  return m > r / 2 ? m - r : m;
}

// Mask with discs (radius in texels, distance measured on the torus) at integer centres.
struct Disc {
  int cx, cy, radius;
};
tvt::ImageGray8 disc_mask(const std::vector<Disc>& discs, int r = R) {
  tvt::ImageGray8 mask(r, r);
  for (const Disc& d : discs)
    for (int y = 0; y < r; ++y)
      for (int x = 0; x < r; ++x) {
        const int dx = minimal(x - d.cx, r), dy = minimal(y - d.cy, r);
        if (dx * dx + dy * dy <= d.radius * d.radius) mask.at(x, y) = 255;
      }
  return mask;
}

// Axis-aligned rectangle [x0, x0+w) x [y0, y0+h), wrapped.
void add_rect(tvt::ImageGray8& mask, int x0, int y0, int w, int h) {
  for (int y = y0; y < y0 + h; ++y)
    for (int x = x0; x < x0 + w; ++x) mask.at(wrap(x, mask.width), wrap(y, mask.width)) = 255;
}

std::pair<int, int> wrapped_centroid(const tvt::MetaTexture& m, int x, int y) {
  const tvt::MetaTexel& t = m.at(x, y);
  return {wrap(x + t.dx, m.resolution), wrap(y + t.dy, m.resolution)};
}

// Every texel of a label points at one wrapped centroid; returns label -> centroid.
std::map<int32_t, std::pair<int, int>> centroids_by_label(const tvt::FeatureLabels& labels, const tvt::MetaTexture& m) {
  std::map<int32_t, std::pair<int, int>> out;
  const int r = labels.resolution;
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      const int32_t l = labels.labels[size_t(y) * size_t(r) + size_t(x)];
      const tvt::MetaTexel& t = m.at(x, y);
      if (l < 0) {
        EXPECT_EQ(t.d, 0);
        EXPECT_EQ(t.dx, 0);
        EXPECT_EQ(t.dy, 0);
        continue;
      }
      EXPECT_EQ(t.d, 1);
      EXPECT_LT(std::abs(int(t.dx)), r);
      EXPECT_LT(std::abs(int(t.dy)), r);
      const auto c = wrapped_centroid(m, x, y);
      auto [it, inserted] = out.emplace(l, c);
      if (!inserted) {
        EXPECT_EQ(it->second, c) << "texel (" << x << ", " << y << ") of feature " << l;
      }
    }
  return out;
}

// Run-time property (docs/composition.md: C = floor(U) + (dx, dy)): crossing from texel x to its
// neighbour x+1 (unwrapped, possibly into the next tile) inside one feature gives the same C.
void expect_unwrapped_agreement(const tvt::FeatureLabels& labels, const tvt::MetaTexture& m) {
  const int r = labels.resolution;
  auto label = [&](int x, int y) { return labels.labels[size_t(wrap(y, r)) * size_t(r) + size_t(wrap(x, r))]; };
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      const int32_t l = label(x, y);
      if (l < 0) continue;
      const tvt::MetaTexel& a = m.at(x, y);
      if (label(x + 1, y) == l) {
        const tvt::MetaTexel& b = m.at(wrap(x + 1, r), y);
        EXPECT_EQ(x + a.dx, x + 1 + b.dx) << "x-step at (" << x << ", " << y << ")";
      }
      if (label(x, y + 1) == l) {
        const tvt::MetaTexel& b = m.at(x, wrap(y + 1, r));
        EXPECT_EQ(y + a.dy, y + 1 + b.dy) << "y-step at (" << x << ", " << y << ")";
      }
    }
}

class MetatexFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("tvt_metatex_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST(Metatex, FeaturesAcrossEdgesAndCornerHaveOneCentroidAtTheAnalyticCentre) {
  // (0,0): split over all four corners; (63,32): across the left/right edge; (20,0): across
  // top/bottom; (40,45): interior, away from edges.
  const std::vector<Disc> discs = {{0, 0, 5}, {R - 1, R / 2, 4}, {20, 0, 3}, {40, 45, 6}};
  const auto labels = tvt::labels_from_mask(disc_mask(discs), 1);
  ASSERT_EQ(labels.count, discs.size());
  const auto meta = tvt::build_meta_texture(labels, {}, 2.0);
  EXPECT_EQ(meta.feature_count, discs.size());
  const auto centroids = centroids_by_label(labels, meta);
  std::set<std::pair<int, int>> found, expected;
  for (const auto& [l, c] : centroids) found.insert(c);
  for (const Disc& d : discs) expected.insert({d.cx, d.cy});
  EXPECT_EQ(found, expected);
  expect_unwrapped_agreement(labels, meta);
  // The corner disc: texels on all four sides of the corner point at the same instance.
  EXPECT_EQ(meta.at(0, 0).dx, 0);
  EXPECT_EQ(meta.at(R - 1, R - 1).dx, 1);
  EXPECT_EQ(meta.at(R - 1, R - 1).dy, 1);
  EXPECT_EQ(meta.at(2, R - 3).dx, -2);
  EXPECT_EQ(meta.at(2, R - 3).dy, 3);
}

TEST(Metatex, CentroidOfEvenSquareRoundsHalfUpAndSquareAcrossCorner) {
  tvt::ImageGray8 mask(R, R);
  add_rect(mask, 10, 20, 4, 6);   // mean (11.5, 22.5) -> (12, 23)
  add_rect(mask, R - 3, R - 2, 5, 5);  // x: 61..65 -> mean 63 ; y: 62..66 -> mean 64 -> 0
  const auto labels = tvt::labels_from_mask(mask, 1);
  ASSERT_EQ(labels.count, 2u);
  const auto meta = tvt::build_meta_texture(labels, {}, 0.0);
  std::set<std::pair<int, int>> found;
  for (const auto& [l, c] : centroids_by_label(labels, meta)) found.insert(c);
  EXPECT_EQ(found, (std::set<std::pair<int, int>>{{12, 23}, {63, 0}}));
  expect_unwrapped_agreement(labels, meta);
}

TEST(Metatex, FeatureWiderThanHalfTheTextureKeepsItsTrueCentroid) {
  // A 40-texel brick from x = 50 across the edge to x = 25: a minimal-image unwrap around one
  // texel would fold it; walking the feature gives mean x = 69.5 -> 70 -> 6.
  tvt::ImageGray8 mask(R, R);
  add_rect(mask, 50, 10, 40, 4);
  const auto labels = tvt::labels_from_mask(mask, 1);
  ASSERT_EQ(labels.count, 1u);
  const auto meta = tvt::build_meta_texture(labels, {}, 1.0);
  const auto centroids = centroids_by_label(labels, meta);
  ASSERT_EQ(centroids.size(), 1u);
  EXPECT_EQ(centroids.begin()->second, std::make_pair(6, 12));
  expect_unwrapped_agreement(labels, meta);
  EXPECT_EQ(meta.at(50, 10).dx, 20);   // leftmost texel: 70 - 50
  EXPECT_EQ(meta.at(25, 10).dx, -19);  // rightmost texel, unwrapped 89: 70 - 89
}

TEST(Metatex, SpecksAreDroppedAndLabelsRenumberedCompactly) {
  tvt::ImageGray8 mask = disc_mask({{30, 30, 6}});
  mask.at(5, 5) = 255;                        // 1 texel
  add_rect(mask, 10, 50, 3, 1);               // 3 texels
  add_rect(mask, R - 1, R - 1, 2, 2);         // 4 texels split over the corner: one component
  mask.at(50, 10) = 255;                      // diagonal neighbours are not 4-connected
  mask.at(51, 11) = 255;
  const auto all = tvt::labels_from_mask(mask, 1);
  EXPECT_EQ(all.count, 6u);
  const auto no_small = tvt::labels_from_mask(mask, 4);
  EXPECT_EQ(no_small.count, 2u);  // disc + corner square
  const auto only_disc = tvt::labels_from_mask(mask, 5);
  ASSERT_EQ(only_disc.count, 1u);
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) {
      const int32_t l = only_disc.labels[size_t(y) * R + size_t(x)];
      const int dx = minimal(x - 30), dy = minimal(y - 30);
      EXPECT_EQ(l, dx * dx + dy * dy <= 36 ? 0 : -1);
    }
  // Compact: every label 0..count-1 is used.
  std::set<int32_t> used(no_small.labels.begin(), no_small.labels.end());
  EXPECT_EQ(used, (std::set<int32_t>{-1, 0, 1}));
}

tvt::ImageRGBA8 bimodal_albedo(const tvt::ImageGray8& features, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> noise(-12, 12);
  tvt::ImageRGBA8 albedo(features.width, features.height);
  for (int y = 0; y < features.height; ++y)
    for (int x = 0; x < features.width; ++x) {
      const bool f = features.at(x, y) != 0;
      uint8_t* t = albedo.at(x, y);
      t[0] = t[1] = t[2] = uint8_t(f ? 40 + noise(rng) : 180 + noise(rng));  // features are dark in colour
      t[3] = uint8_t(f ? 200 + noise(rng) : 60 + noise(rng));                 // and high in height
    }
  return albedo;
}

void expect_labels_match_mask(const tvt::FeatureLabels& labels, const tvt::ImageGray8& mask, bool complement = false) {
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x)
      EXPECT_EQ(labels.labels[size_t(y) * size_t(mask.width) + size_t(x)] >= 0, (mask.at(x, y) != 0) != complement)
          << "(" << x << ", " << y << ")";
}

TEST(Metatex, OtsuSeparatesABimodalHeightAndAnExplicitThresholdAgrees) {
  const auto features = disc_mask({{0, 0, 7}, {32, 20, 5}, {50, 50, 9}});
  const auto albedo = bimodal_albedo(features, 5);
  tvt::IsolationOptions options;  // auto channel (height: it varies), Otsu
  options.smooth_sigma = 0.0;     // exact disc outlines
  const auto otsu = tvt::isolate_features(albedo, options);
  EXPECT_EQ(otsu.count, 3u);
  expect_labels_match_mask(otsu, features);
  options.threshold = 0.5;
  const auto fixed = tvt::isolate_features(albedo, options);
  EXPECT_EQ(fixed.labels, otsu.labels);
  options.threshold = 0.99;  // above every texel: nothing
  EXPECT_EQ(tvt::isolate_features(albedo, options).count, 0u);
}

TEST(Metatex, LuminanceFindsTheDarkDiscsByItselfAndEitherSideWhenTold) {
  const auto features = disc_mask({{10, 10, 6}, {R - 1, 40, 5}});
  const auto albedo = bimodal_albedo(features, 9);
  tvt::IsolationOptions options;
  options.channel = tvt::IsolationOptions::Channel::Luminance;
  options.smooth_sigma = 0.0;
  tvt::IsolationReport report;
  const auto automatic = tvt::isolate_features(albedo, options, &report);  // the light side is the network
  EXPECT_FALSE(report.features_light);
  EXPECT_FALSE(report.polarity_forced);
  EXPECT_GT(report.light_network_share, report.dark_network_share);
  EXPECT_EQ(automatic.count, 2u);
  expect_labels_match_mask(automatic, features);
  options.polarity = tvt::IsolationOptions::Polarity::Dark;  // features are dark in colour
  const auto dark = tvt::isolate_features(albedo, options);
  EXPECT_EQ(dark.labels, automatic.labels);
  options.polarity = tvt::IsolationOptions::Polarity::Light;  // the bright background: one connected region
  options.split_touching = false;
  options.fill_holes = false;  // the discs are holes in it
  const auto bright = tvt::isolate_features(albedo, options);
  EXPECT_EQ(bright.count, 1u);
  expect_labels_match_mask(bright, features, true);
}

TEST(Metatex, FlatChannelHasNoFeatures) {
  tvt::ImageRGBA8 flat(16, 16);
  for (auto& t : flat.texels) t = 128;
  for (auto polarity : {tvt::IsolationOptions::Polarity::Auto, tvt::IsolationOptions::Polarity::Light,
                        tvt::IsolationOptions::Polarity::Dark}) {
    tvt::IsolationOptions options;
    options.polarity = polarity;
    const auto labels = tvt::isolate_features(flat, options);
    EXPECT_EQ(labels.count, 0u);
    EXPECT_EQ(labels.labels.size(), 256u);
  }
}

TEST(Metatex, ErosionSplitsTouchingFeaturesAndGrowsThemBack) {
  tvt::ImageGray8 mask(R, R);
  add_rect(mask, 10, 10, 9, 9);
  add_rect(mask, 22, 10, 9, 9);
  add_rect(mask, 19, 14, 3, 1);  // a 1-texel-wide bridge of 3 texels joins them
  tvt::ImageRGBA8 albedo(R, R);
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) albedo.at(x, y)[3] = mask.at(x, y);
  tvt::IsolationOptions options;
  options.threshold = 0.5;
  options.smooth_sigma = 0.0;
  options.split_touching = false;
  EXPECT_EQ(tvt::isolate_features(albedo, options).count, 1u);
  options.erode_texels = 1;
  const auto split = tvt::isolate_features(albedo, options);
  ASSERT_EQ(split.count, 2u);
  auto label = [&](int x, int y) { return split.labels[size_t(y) * R + size_t(x)]; };
  for (int y = 10; y < 19; ++y)
    for (int x = 0; x < 9; ++x) {
      EXPECT_EQ(label(10 + x, y), 0);  // squares fully grown back
      EXPECT_EQ(label(22 + x, y), 1);
    }
  for (int x = 19; x < 22; ++x) EXPECT_EQ(label(x, 14), -1);  // the bridge was eroded away entirely
}

TEST(Metatex, EmptyMaskGivesNoFeatures) {
  const auto labels = tvt::labels_from_mask(tvt::ImageGray8(R, R), 8);
  EXPECT_EQ(labels.count, 0u);
  const auto meta = tvt::build_meta_texture(labels, {}, 3.0);
  EXPECT_EQ(meta.feature_count, 0u);
  for (const auto& t : meta.texels) {
    EXPECT_EQ(t.d, 0);
    EXPECT_EQ(t.f, 0);
    EXPECT_EQ(t.dx, 0);
    EXPECT_EQ(t.dy, 0);
    EXPECT_EQ(t.variation, 255);
  }
}

TEST(Metatex, FeatureCoveringTheWholeTorusHasOneDefinedCentroid) {
  tvt::ImageGray8 all(R, R);
  for (auto& t : all.texels) t = 1;
  const auto labels = tvt::labels_from_mask(all, 8);
  ASSERT_EQ(labels.count, 1u);
  const auto meta = tvt::build_meta_texture(labels, {}, 2.0);
  const auto centroids = centroids_by_label(labels, meta);  // all agree, offsets inside ±R
  ASSERT_EQ(centroids.size(), 1u);
  for (const auto& t : meta.texels) {
    EXPECT_EQ(t.f, 255);
    EXPECT_LE(std::abs(int(t.dx)), R / 2);
  }
}

TEST(Metatex, BandAroundTheTorusAgreesModuloR) {
  tvt::ImageGray8 mask(R, R);
  add_rect(mask, 0, 10, R, 4);  // closes on itself in x
  const auto labels = tvt::labels_from_mask(mask, 1);
  ASSERT_EQ(labels.count, 1u);
  const auto meta = tvt::build_meta_texture(labels, {}, 1.0);
  const auto centroids = centroids_by_label(labels, meta);
  ASSERT_EQ(centroids.size(), 1u);
  EXPECT_EQ(centroids.begin()->second.second, 12);  // y is still the true mean (11.5 -> 12)
}

TEST(Metatex, SoftMapRangeAndZeroBlur) {
  const auto labels = tvt::labels_from_mask(disc_mask({{0, 0, 12}, {40, 30, 2}}), 1);
  const auto sharp = tvt::build_meta_texture(labels, {}, 0.0);
  for (const auto& t : sharp.texels) EXPECT_EQ(t.f, t.d * 255);
  const auto soft = tvt::build_meta_texture(labels, {}, 2.5);
  int partial = 0;
  for (const auto& t : soft.texels) partial += (t.f > 0 && t.f < 255) ? 1 : 0;
  EXPECT_GT(partial, 0);
  EXPECT_EQ(soft.at(0, 0).f, 255);  // deep inside the corner disc (across every edge)
  EXPECT_EQ(soft.at(20, 50).f, 0);  // far from both
  EXPECT_LT(soft.at(40, 30).f, 200);  // small disc: blur takes a lot of its centre
  EXPECT_GT(soft.at(40, 30).f, 0);
}

TEST(Metatex, SoftMapWrapsExactlyUnderTranslationAndMirror) {
  const std::vector<Disc> discs = {{5, 7, 4}, {30, 2, 3}};
  std::vector<Disc> shifted;
  const int sx = 37, sy = 51;
  for (const Disc& d : discs) shifted.push_back({wrap(d.cx + sx), wrap(d.cy + sy), d.radius});
  const auto a = tvt::build_meta_texture(tvt::labels_from_mask(disc_mask(discs), 1), {}, 3.0);
  const auto b = tvt::build_meta_texture(tvt::labels_from_mask(disc_mask(shifted), 1), {}, 3.0);
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) ASSERT_EQ(a.at(x, y).f, b.at(wrap(x + sx), wrap(y + sy)).f) << x << ", " << y;
  // A disc centred on the corner is symmetric under x -> -x and y -> -y on the torus.
  const auto c = tvt::build_meta_texture(tvt::labels_from_mask(disc_mask({{0, 0, 9}}), 1), {}, 2.0);
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) {
      EXPECT_NEAR(c.at(x, y).f, c.at(wrap(-x), y).f, 1);
      EXPECT_NEAR(c.at(x, y).f, c.at(x, wrap(-y)).f, 1);
    }
}

TEST(Metatex, VariationIsCopied) {
  tvt::ImageGray8 variation(R, R);
  for (size_t i = 0; i < variation.texels.size(); ++i) variation.texels[i] = uint8_t(i * 7);
  const auto meta = tvt::build_meta_texture(tvt::labels_from_mask(disc_mask({{3, 3, 3}}), 1), variation, 1.0);
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) EXPECT_EQ(meta.at(x, y).variation, variation.at(x, y));
}

TEST(Metatex, DebugImageTintsFeaturesAndMarksCentroids) {
  const auto labels = tvt::labels_from_mask(disc_mask({{0, 0, 6}, {32, 32, 6}}), 1);
  const auto meta = tvt::build_meta_texture(labels, {}, 1.0);
  tvt::ImageRGBA8 albedo(R, R);
  for (auto& t : albedo.texels) t = 200;
  const auto debug = tvt::meta_debug_image(meta, albedo);
  EXPECT_EQ(debug.at(16, 50)[0], 100);  // background: darkened 50%
  for (auto [x, y] : std::vector<std::pair<int, int>>{{0, 0}, {R - 2, 0}, {0, 2}, {32, 32}, {34, 32}})
    EXPECT_EQ(debug.at(x, y)[0] + debug.at(x, y)[1] + debug.at(x, y)[2], 3 * 255) << x << ", " << y;  // crosses wrap
  // One colour per feature, different between the two.
  const uint8_t* a = debug.at(4, 3);
  const uint8_t* b = debug.at(36, 35);
  EXPECT_EQ(std::vector<uint8_t>(a, a + 3), std::vector<uint8_t>(debug.at(R - 4, R - 3), debug.at(R - 4, R - 3) + 3));
  EXPECT_NE(std::vector<uint8_t>(a, a + 3), std::vector<uint8_t>(b, b + 3));
}

tvt::MetaTexture sample_meta() {
  tvt::ImageGray8 variation(R, R);
  std::mt19937 rng(1);
  for (auto& v : variation.texels) v = uint8_t(rng() & 0xff);
  tvt::ImageGray8 mask = disc_mask({{0, 0, 5}, {R - 1, R / 2, 4}, {40, 45, 6}});
  add_rect(mask, 50, 10, 40, 4);
  return tvt::build_meta_texture(tvt::labels_from_mask(mask, 1), variation, 2.0);
}

TEST_F(MetatexFileTest, ExrRoundTripIsIdentical) {
  const auto meta = sample_meta();
  ASSERT_TRUE(tvt::write_meta_texture(path("m.exr"), meta).ok());
  auto back = tvt::read_meta_texture(path("m.exr"));
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->resolution, meta.resolution);
  EXPECT_EQ(back->feature_count, meta.feature_count);
  ASSERT_EQ(back->texels.size(), meta.texels.size());
  for (size_t i = 0; i < meta.texels.size(); ++i) {
    const auto& a = meta.texels[i];
    const auto& b = back->texels[i];
    ASSERT_TRUE(a.dx == b.dx && a.dy == b.dy && a.d == b.d && a.f == b.f && a.variation == b.variation) << i;
  }
}

TEST_F(MetatexFileTest, WriteRequiresExrAndLeavesNothingOnError) {
  auto w = tvt::write_meta_texture(path("m.png"), sample_meta());
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.error().message.find(path("m.png")), std::string::npos);
  EXPECT_FALSE(tvt::write_meta_texture(path("no/such/m.exr"), sample_meta()).ok());
  EXPECT_TRUE(fs::is_empty(dir_));
}

// Writes `meta` as raw named float channels, after `corrupt` edits them, and expects the reader
// to fail naming the file and `problem`.
void expect_rejected(const std::string& file, const tvt::MetaTexture& meta, std::vector<std::string> names,
                     const std::function<void(tvt::ImageF&)>& corrupt, const std::string& problem) {
  tvt::ImageF image(meta.resolution, meta.resolution, 5);
  for (int y = 0; y < meta.resolution; ++y)
    for (int x = 0; x < meta.resolution; ++x) {
      const auto& t = meta.at(x, y);
      const float values[5] = {float(t.dx), float(t.dy), float(t.d), float(t.f), float(t.variation)};
      for (int c = 0; c < 5; ++c) image.at(x, y, c) = values[c];
    }
  corrupt(image);
  if (names.size() < 5) {  // drop trailing channels
    tvt::ImageF fewer(image.width, image.height, int(names.size()));
    for (int y = 0; y < image.height; ++y)
      for (int x = 0; x < image.width; ++x)
        for (int c = 0; c < fewer.channels; ++c) fewer.at(x, y, c) = image.at(x, y, c);
    image = fewer;
  }
  ASSERT_TRUE(tvt::write_image(file, image, names).ok());
  auto r = tvt::read_meta_texture(file);
  ASSERT_FALSE(r.ok()) << "accepted a file with: " << problem;
  EXPECT_NE(r.error().message.find(file), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find(problem), std::string::npos) << r.error().message;
}

TEST_F(MetatexFileTest, ReadRejectsCorruptFilesNamingFileAndProblem) {
  const auto meta = sample_meta();
  const std::vector<std::string> names = {"dx", "dy", "d", "f", "v"};
  // Find a feature texel and a background texel to corrupt.
  int fx = -1, fy = -1, bx = -1, by = -1;
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) {
      if (meta.at(x, y).d && fx < 0) fx = x, fy = y;
      if (!meta.at(x, y).d && bx < 0) bx = x, by = y;
    }
  ASSERT_GE(fx, 0);
  ASSERT_GE(bx, 0);
  auto nothing = [](tvt::ImageF&) {};
  expect_rejected(path("missing.exr"), meta, {"dx", "dy", "d", "f"}, nothing, "missing channel(s) v");
  expect_rejected(path("renamed.exr"), meta, {"dx", "dy", "mask", "f", "v"}, nothing, "missing channel(s) d");
  expect_rejected(path("fraction.exr"), meta, names, [&](tvt::ImageF& i) { i.at(fx, fy, 0) += 0.5f; },
                  "dx = " + std::to_string(meta.at(fx, fy).dx) + ".5 is not an integer");
  expect_rejected(path("d2.exr"), meta, names, [&](tvt::ImageF& i) { i.at(fx, fy, 2) = 2.0f; }, "d = 2");
  expect_rejected(path("far.exr"), meta, names, [&](tvt::ImageF& i) { i.at(fx, fy, 1) = float(R); }, "outside the texture");
  expect_rejected(path("stray.exr"), meta, names, [&](tvt::ImageF& i) { i.at(bx, by, 0) = 3.0f; }, "not a feature");
  expect_rejected(path("f.exr"), meta, names, [&](tvt::ImageF& i) { i.at(bx, by, 3) = 256.0f; }, "f = 256 outside 0..255");
  expect_rejected(path("v.exr"), meta, names, [&](tvt::ImageF& i) { i.at(bx, by, 4) = -1.0f; }, "v = -1 outside 0..255");

  // Non-square.
  tvt::ImageF wide(8, 4, 5);
  ASSERT_TRUE(tvt::write_image(path("wide.exr"), wide, names).ok());
  auto r = tvt::read_meta_texture(path("wide.exr"));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("not square"), std::string::npos);
  EXPECT_NE(r.error().message.find(path("wide.exr")), std::string::npos);

  // Not a file at all.
  auto missing = tvt::read_meta_texture(path("absent.exr"));
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find(path("absent.exr")), std::string::npos);
}

}  // namespace

namespace {

// A binary format's reader: every truncated prefix and every flipped byte of a meta-texture file is either
// rejected with the file's name or read back as a meta-texture that satisfies the format rules.
TEST_F(MetatexFileTest, EveryTruncationAndFlippedByteIsRejectedOrValid) {
  constexpr int r = 16;
  tvt::ImageGray8 mask(r, r);
  add_rect(mask, r - 2, r - 2, 5, 4);
  add_rect(mask, 5, 6, 3, 3);
  const auto meta = tvt::build_meta_texture(tvt::labels_from_mask(mask, 1), {}, 1.0);
  ASSERT_TRUE(tvt::write_meta_texture(path("good.exr"), meta).ok());
  std::vector<char> bytes;
  {
    std::ifstream in(path("good.exr"), std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_GT(bytes.size(), 100u);
  const std::string bad = path("bad.exr");
  auto check = [&](const std::vector<char>& data, const std::string& what) {
    {
      std::ofstream out(bad, std::ios::binary | std::ios::trunc);
      out.write(data.data(), std::streamsize(data.size()));
    }
    auto result = tvt::read_meta_texture(bad);
    if (!result.ok()) {
      EXPECT_NE(result.error().message.find(bad), std::string::npos) << what << ": " << result.error().message;
      return;
    }
    const int rr = result->resolution;
    ASSERT_EQ(result->texels.size(), size_t(rr) * size_t(rr)) << what;
    for (const auto& t : result->texels) {
      ASSERT_LE(t.d, 1) << what;
      ASSERT_LT(std::abs(int(t.dx)), rr) << what;
      ASSERT_LT(std::abs(int(t.dy)), rr) << what;
      if (!t.d) {
        ASSERT_TRUE(t.dx == 0 && t.dy == 0) << what;
      }
    }
  };
  for (size_t n = 0; n < bytes.size(); ++n) check({bytes.begin(), bytes.begin() + std::ptrdiff_t(n)}, "prefix " + std::to_string(n));
  for (size_t i = 0; i < bytes.size(); ++i) {
    auto flipped = bytes;
    flipped[i] = char(flipped[i] ^ 0x5a);
    check(flipped, "flip at " + std::to_string(i));
  }
}

}  // namespace
