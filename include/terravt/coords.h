// Positions on the virtual texture as the GLSL contract (terravt/vt.glsl) takes them: a level-0
// texel as exact integers plus a small float offset. fp32 has 24 bits: over a whole 2^24-texel
// terrain a single float cannot even name a texel, so the split happens on the CPU in double
// (exact to 2^-22 texel at 2^30) and the GPU only ever adds small floats to the anchor.
// Typical use: one anchor per terrain chunk (its corner), pushed to the shader as ivec2, and
// vertex positions as float offsets from it.
#pragma once
#include <cmath>
#include <cstdint>

namespace terravt {

struct TexelAnchor {
  int32_t x = 0, y = 0;  // level-0 texel, integer part
  float fx = 0, fy = 0;  // remainder in [0, 1)
};

// Splits a level-0 texel position. Positions beyond +-2^31 texels clamp there (no terrain is
// that large); NaN gives 0. Exact: x == anchor.x + anchor.fx up to float rounding of the fraction.
inline TexelAnchor texel_anchor(double x, double y) noexcept {
  const auto split = [](double v, int32_t& whole, float& frac) {
    if (!(v == v)) v = 0.0;  // NaN
    const double lim = 2147483647.0;
    v = v < -lim ? -lim : (v > lim ? lim : v);
    const double f = std::floor(v);
    whole = static_cast<int32_t>(f);
    frac = static_cast<float>(v - f);
    if (frac >= 1.0f) frac = std::nextafter(1.0f, 0.0f);  // v - f rounded up to 1 in float
  };
  TexelAnchor a;
  split(x, a.x, a.fx);
  split(y, a.y, a.fy);
  return a;
}

// A terrain position in metres (0 ... extent_m along each side) as a level-0 texel position on
// a VT of 2^log2_size texels per side. extent_m <= 0 or NaN gives 0.
inline double texel_from_metres(double metres, double extent_m, uint32_t log2_size) noexcept {
  if (!(extent_m > 0.0) || !(metres == metres)) return 0.0;
  return metres / extent_m * std::ldexp(1.0, static_cast<int>(log2_size));
}

}  // namespace terravt
