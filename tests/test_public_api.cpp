// The public API's header-only parts: texel anchors at the extremes.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "terravt/coords.h"

namespace {

TEST(TexelAnchor, SplitsIntoAnExactIntegerAndAFractionBelowOne) {
  const double v = double((1u << 24) - 3) + 0.625;  // far corner of a 2^24 terrain
  const terravt::TexelAnchor a = terravt::texel_anchor(v, -2.25);
  EXPECT_EQ(a.x, (1 << 24) - 3);
  EXPECT_FLOAT_EQ(a.fx, 0.625f);
  EXPECT_EQ(a.y, -3);  // floor, not truncation
  EXPECT_FLOAT_EQ(a.fy, 0.75f);
}

TEST(TexelAnchor, ExtremesGiveDefinedValues) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const terravt::TexelAnchor a = terravt::texel_anchor(nan, inf);
  EXPECT_EQ(a.x, 0);
  EXPECT_EQ(a.fx, 0.f);
  EXPECT_EQ(a.y, 2147483647);
  const terravt::TexelAnchor b = terravt::texel_anchor(-inf, 1e300);
  EXPECT_EQ(b.x, -2147483647);
  EXPECT_EQ(b.y, 2147483647);
  // A fraction that rounds to 1.0f in float stays below 1.
  const terravt::TexelAnchor c = terravt::texel_anchor(5.0 - 1e-12, 0.0);
  EXPECT_EQ(c.x, 4);
  EXPECT_LT(c.fx, 1.0f);
  EXPECT_GE(c.fx, 0.0f);
}

TEST(TexelAnchor, MetresMapOntoTheTexelGridAndBadExtentsGiveZero) {
  EXPECT_DOUBLE_EQ(terravt::texel_from_metres(500.0, 1000.0, 24), double(1u << 23));
  EXPECT_DOUBLE_EQ(terravt::texel_from_metres(1000.0, 1000.0, 30), std::ldexp(1.0, 30));
  EXPECT_EQ(terravt::texel_from_metres(1.0, 0.0, 24), 0.0);
  EXPECT_EQ(terravt::texel_from_metres(1.0, -5.0, 24), 0.0);
  EXPECT_EQ(terravt::texel_from_metres(std::nan(""), 10.0, 24), 0.0);
}

}  // namespace
