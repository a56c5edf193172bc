// Automatic feature isolation (compose/feature_isolation.h) on synthetic textures: the
// watershed split, the torus, pin-holes, specks and the polarity decision.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "compose/feature_isolation.h"

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
