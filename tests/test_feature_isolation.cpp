// Automatic feature isolation (compose/feature_isolation.h) on synthetic textures: the
// watershed split, the torus, pin-holes, specks and the polarity decision.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "compose/feature_isolation.h"
#include "compose/material_image.h"

namespace {

constexpr int R = 64;

// Texels of `rects` (x, y, w, h; wrapping) have height 220 and luminance `inside`, the rest 30
// and `outside`.
struct Rect {
  int x, y, w, h;
};
tvt::ImageRGBA8 rect_texture(const std::vector<Rect>& rects, uint8_t inside, uint8_t outside, int r = R) {
  tvt::ImageRGBA8 image(r, r);
  for (auto& t : image.texels) t = outside;
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) image.at(x, y)[3] = 30;
  for (const Rect& rc : rects)
    for (int y = rc.y; y < rc.y + rc.h; ++y)
      for (int x = rc.x; x < rc.x + rc.w; ++x) {
        uint8_t* t = image.at(((x % r) + r) % r, ((y % r) + r) % r);
        t[0] = t[1] = t[2] = inside;
        t[3] = 220;
      }
  return image;
}

int32_t label_at(const tvt::FeatureLabels& l, int x, int y) {
  return l.labels[size_t(((y % l.resolution) + l.resolution) % l.resolution) * size_t(l.resolution) +
                  size_t(((x % l.resolution) + l.resolution) % l.resolution)];
}

tvt::IsolationOptions exact() {
  tvt::IsolationOptions o;
  o.smooth_sigma = 0.0;  // synthetic edges are exact already
  return o;
}

TEST(FeatureIsolation, WatershedSplitsTwoSquaresJoinedByAOneTexelBridge) {
  const auto image = rect_texture({{10, 10, 12, 12}, {25, 10, 12, 12}, {22, 16, 3, 1}}, 200, 40);
  tvt::IsolationOptions no_split = exact();
  no_split.split_touching = false;
  EXPECT_EQ(tvt::isolate_features(image, no_split).count, 1u);
  tvt::IsolationReport report;
  const auto split = tvt::isolate_features(image, exact(), &report);
  ASSERT_EQ(split.count, 2u);
  EXPECT_EQ(report.split_added, 1u);
  // Each square keeps its own label everywhere inside it, away from the bridge.
  for (int y = 10; y < 22; ++y)
    for (int x = 0; x < 10; ++x) {
      EXPECT_EQ(label_at(split, 10 + x, y), label_at(split, 10, 10));
      EXPECT_EQ(label_at(split, 27 + x, y), label_at(split, 36, 10));
    }
  EXPECT_NE(label_at(split, 10, 10), label_at(split, 36, 10));
  EXPECT_NE(std::count(report.marks.begin(), report.marks.end(), uint8_t(3)), 0) << "split line marked";
}

TEST(FeatureIsolation, SquaresCutByTheTextureEdgesStayWholeOnTheTorusAndStillSplit) {
  // One square across the left/right edge, one across the corner, joined to a third by a bridge.
  const auto image = rect_texture({{R - 6, 20, 12, 12}, {R - 5, R - 5, 10, 10}, {20, 40, 12, 12}, {32, 45, 4, 1},
                                   {36, 40, 12, 12}},
                                  200, 40);
  const auto labels = tvt::isolate_features(image, exact());
  EXPECT_EQ(labels.count, 4u);
  EXPECT_EQ(label_at(labels, R - 6, 25), label_at(labels, 5, 25));  // pieces across the x edge
  EXPECT_EQ(label_at(labels, R - 5, R - 5), label_at(labels, 4, 4));  // pieces in all four corners
  EXPECT_EQ(label_at(labels, R - 5, R - 5), label_at(labels, 4, R - 5));
  EXPECT_EQ(label_at(labels, R - 5, R - 5), label_at(labels, R - 5, 4));
  EXPECT_NE(label_at(labels, 21, 41), label_at(labels, 46, 41));  // the bridged pair split
}

TEST(FeatureIsolation, PinHolesAreFilledAndSpecksDropped) {
  auto image = rect_texture({{10, 10, 20, 20}, {40, 40, 16, 16}, {4, 50, 2, 1}}, 200, 40);
  for (int x : {19, 20}) {  // a 2-texel pin-hole inside the first square
    uint8_t* t = image.at(x, 19);
    t[0] = t[1] = t[2] = 40;
    t[3] = 30;
  }
  tvt::IsolationReport report;
  const auto labels = tvt::isolate_features(image, exact(), &report);
  EXPECT_EQ(labels.count, 2u);
  EXPECT_EQ(report.holes_filled, 1u);
  EXPECT_EQ(report.specks_dropped, 1u);
  EXPECT_EQ(label_at(labels, 19, 19), label_at(labels, 10, 10)) << "the pin-hole belongs to its square";
  EXPECT_EQ(label_at(labels, 4, 50), -1) << "the 2-texel speck is gone";
  EXPECT_EQ(report.marks[size_t(19) * R + 19], 1);
  EXPECT_EQ(report.marks[size_t(50) * R + 4], 2);
  tvt::IsolationOptions keep = exact();
  keep.fill_holes = false;
  EXPECT_EQ(label_at(tvt::isolate_features(image, keep), 19, 19), -1);
}

// A brick bond: 14 x 6 bricks with 2-texel mortar joints, rows offset by half a brick.
std::vector<Rect> brick_bond(int r) {
  std::vector<Rect> bricks;
  for (int row = 0; row * 8 < r; ++row)
    for (int col = 0; col * 16 < r; ++col) bricks.push_back({col * 16 + (row % 2) * 8, row * 8, 14, 6});
  return bricks;
}

TEST(FeatureIsolation, PolarityPicksTheBricksWhetherTheMortarIsLightOrDark) {
  const auto bricks = brick_bond(R);
  const uint32_t expected = uint32_t(bricks.size());  // 8 rows x 4 bricks
  tvt::IsolationOptions luminance = exact();
  luminance.channel = tvt::IsolationOptions::Channel::Luminance;
  for (bool light_mortar : {true, false}) {
    const auto image = rect_texture(bricks, light_mortar ? 60 : 200, light_mortar ? 210 : 30);
    tvt::IsolationReport report;
    const auto labels = tvt::isolate_features(image, luminance, &report);
    EXPECT_EQ(labels.count, expected) << (light_mortar ? "light mortar" : "dark mortar");
    EXPECT_EQ(report.features_light, !light_mortar);
    EXPECT_EQ(label_at(labels, 3, 3) >= 0, true);
    EXPECT_EQ(label_at(labels, 15, 3), -1) << "the mortar joint is background";
    // Forcing the other side gives the mortar: one connected network.
    tvt::IsolationOptions other = luminance;
    other.polarity = light_mortar ? tvt::IsolationOptions::Polarity::Light : tvt::IsolationOptions::Polarity::Dark;
    other.split_touching = false;
    EXPECT_EQ(tvt::isolate_features(image, other).count, 1u);
  }
}

TEST(FeatureIsolation, TheSameImageAndOptionsGiveTheSameLabels) {
  const auto image = rect_texture(brick_bond(R), 60, 210);
  const auto a = tvt::isolate_features(image, tvt::IsolationOptions{});
  const auto b = tvt::isolate_features(image, tvt::IsolationOptions{});
  EXPECT_EQ(a.labels, b.labels);
  EXPECT_EQ(a.count, b.count);
}

}  // namespace

// ---- the editable mask (terravt metatex --mask-out) ----------------------------------------

// Labels of a brick wall with no mortar at all on the torus: every brick touches its
// neighbours, so only the mask's split lines keep them apart; the courses are offset by half a
// brick and one brick crosses the texture's corner.
tvt::FeatureLabels touching_bricks() {
  tvt::FeatureLabels l;
  l.resolution = R;
  l.labels.assign(size_t(R) * R, -1);
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) {
      const int course = ((y + 3) % R) / 8, shift = course % 2 ? 8 : 0;
      const int brick = ((x + 5 + shift) % R) / 16;
      // A few background texels (the mask keeps them background) and bricks numbered in no order.
      l.labels[size_t(y) * R + size_t(x)] = (x + 2 * y) % 37 == 0 ? -1 : (course * 4 + brick) * 7 % 32;
    }
  l.count = 32;
  return l;
}

// Whether texel (x, y) of a feature touches a feature of a lower label (4-neighbours, on the
// torus): the split texels the mask leaves out.
bool split_texel(const tvt::FeatureLabels& l, int x, int y) {
  const int32_t f = label_at(l, x, y);
  if (f < 0) return false;
  for (const auto& [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}})
    if (const int32_t n = label_at(l, x + dx, y + dy); n >= 0 && n < f) return true;
  return false;
}

// The mask at `w` x `h` read back as scene loading and `--mask` read it: nearest texel, then
// components. Every feature comes back as one component, with exactly its texels less the
// split ones.
void expect_round_trip(const tvt::FeatureLabels& original, int w, int h) {
  SCOPED_TRACE(std::to_string(w) + " x " + std::to_string(h));
  const tvt::ImageGray8 mask = tvt::mask_from_labels(original, w, h);
  ASSERT_EQ(mask.width, w);
  ASSERT_EQ(mask.height, h);
  tvt::ImageRGBA8 rgba(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) rgba.at(x, y)[0] = mask.at(x, y);
  const tvt::FeatureLabels back = tvt::labels_from_mask(tvt::resample_mask_nearest(rgba, R), 1);
  ASSERT_EQ(back.count, original.count);
  std::vector<int32_t> from(back.count, -2);
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) {
      const int32_t was = label_at(original, x, y), now = label_at(back, x, y);
      ASSERT_EQ(now >= 0, was >= 0 && !split_texel(original, x, y)) << x << ", " << y;
      if (now < 0) continue;
      int32_t& f = from[size_t(now)];
      if (f == -2) f = was;
      EXPECT_EQ(f, was) << "one feature read back over two at " << x << ", " << y;
    }
}

TEST(MaskFromLabels, KeepsTouchingFeaturesApartAtTheMaterialSizeAndAtLargerImageSizes) {
  const tvt::FeatureLabels bricks = touching_bricks();
  const tvt::ImageGray8 mask = tvt::mask_from_labels(bricks, R, R);
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x)
      EXPECT_EQ(mask.at(x, y), label_at(bricks, x, y) >= 0 && !split_texel(bricks, x, y) ? 255 : 0) << x << ", " << y;
  // The material's own size and images larger than it on both sides, square or not (the loader
  // reads a subset of their pixels).
  for (const auto& [w, h] : {std::pair{R, R}, {100, 70}, {64, 200}, {128, 128}}) expect_round_trip(bricks, w, h);
}

TEST(MaskFromLabels, ASmallerImageStillNeverJoinsTwoFeatures) {
  // 48 pixels for 64 texels: some pixels are read by two texels, and background wins, so the
  // features shrink but none joins another (the CLI writes such masks at the material's size).
  const tvt::FeatureLabels bricks = touching_bricks();
  const tvt::ImageGray8 mask = tvt::mask_from_labels(bricks, 48, 48);
  tvt::ImageRGBA8 rgba(48, 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 48; ++x) rgba.at(x, y)[0] = mask.at(x, y);
  const tvt::FeatureLabels back = tvt::labels_from_mask(tvt::resample_mask_nearest(rgba, R), 1);
  EXPECT_GT(back.count, 0u);
  std::vector<int32_t> from(back.count, -2);
  for (size_t i = 0; i < back.labels.size(); ++i) {
    if (back.labels[i] < 0) continue;
    ASSERT_GE(bricks.labels[i], 0);
    int32_t& f = from[size_t(back.labels[i])];
    if (f == -2) f = bricks.labels[i];
    EXPECT_EQ(f, bricks.labels[i]) << "texel " << i;
  }
}
