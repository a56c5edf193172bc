#include "compose/reference_compositor.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include "compose/material_culling.h"
#include "shaders/shared/hash.h"

namespace tvt {

namespace {

using gpu::tvt_floor_div;
using gpu::tvt_floor_mod;

double clamp01(double v) { return std::isfinite(v) ? std::clamp(v, 0.0, 1.0) : 0.0; }

// pow with a zero (or negative) base defined as 0: "no weight stays no weight".
double safe_pow(double base, double e) { return base <= 0.0 ? 0.0 : std::pow(base, e); }

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// BlendMap (Hardy & McRoberts 2006): monotone in b, 0 at b = 0, 1 at b = 1; texels with a
// high blend map value A appear first. s is the transition half-width.
double blend_map(double b, double a, double s) {
  b = clamp01(b);
  return smoothstep(1.0 - b - s, 1.0 - b + s, s + a * (1.0 - 2.0 * s));
}

// The prefiltered blend map (docs/composition.md, "Prefiltered mips"): with A uniform over
// [mean - h, mean + h], h = sqrt(3 var), the means over A of blend_map(b, A, s) (`e`) and of
// blend_map(b, A, s) * (A - mean) (`dev`, what the colour's covariance with A multiplies).
// blend_map is smoothstep(t) of t = c0 + c1 A, so both are differences of the antiderivatives
// of smoothstep(t) and t * smoothstep(t) over [t0, t1]. Below a width of 1/200 in t, the
// point value (dev = 0).
double smoothstep_integral(double t) {  // of the clamped smoothstep, from 0
  if (t <= 0.0) return 0.0;
  if (t >= 1.0) return t - 0.5;
  return t * t * t * (1.0 - 0.5 * t);
}
double smoothstep_moment(double t) {  // of t * smoothstep(t), from 0
  if (t <= 0.0) return 0.0;
  if (t >= 1.0) return 0.35 + 0.5 * (t * t - 1.0);
  return t * t * t * t * (0.75 - 0.4 * t);
}
void blend_map_expected(double b, double a_mean, double a_var, double s, double& e, double& dev) {
  b = clamp01(b);
  const double c1 = (1.0 - 2.0 * s) / (2.0 * s);
  const double half = c1 * std::sqrt(3.0 * std::max(a_var, 0.0));
  if (!(half >= 2.5e-3)) {
    e = blend_map(b, a_mean, s);
    dev = 0.0;
    return;
  }
  const double tm = (b + 2.0 * s - 1.0) / (2.0 * s) + c1 * a_mean;
  const double t0 = tm - half, t1 = tm + half;
  e = clamp01((smoothstep_integral(t1) - smoothstep_integral(t0)) / (2.0 * half));
  dev = ((smoothstep_moment(t1) - smoothstep_moment(t0)) / (2.0 * half) - tm * e) / c1;
}

// A's variance within the footprint from its two pieces (p, delta, h_lo, h_hi): the pieces'
// means' delta^2 and each piece's uniform spread h^2 / 3.
double spread_variance(const glm::dvec4& spread) {
  return spread.y * spread.y + (spread.x * spread.z * spread.z + (1.0 - spread.x) * spread.w * spread.w) / 3.0;
}

// The blend map's means over A in two pieces (the spread chain, compose_types.h): `spread` =
// (p, delta, h_lo, h_hi), the lower piece's share, the standard deviation of the pieces' means
// about a_mean and their half-widths; each piece uniform (blend_map_expected), mixed by share.
// `dev` stays the mean of blend_map * (A - a_mean).
void blend_map_spread(double b, double a_mean, const glm::dvec4& spread, double s, double& e, double& dev) {
  const double p = clamp01(spread.x), delta = std::max(spread.y, 0.0);
  if (!(delta > 1e-4) || p <= 0.0 || p >= 1.0) {  // one piece: the pieces' widths and delta pooled
    blend_map_expected(b, a_mean, spread_variance(glm::dvec4(p, delta, spread.z, spread.w)), s, e, dev);
    return;
  }
  const double lo = std::max(a_mean - delta * std::sqrt((1.0 - p) / p), -1.0);
  const double hi = std::min(a_mean + delta * std::sqrt(p / (1.0 - p)), 2.0);
  double e_lo, d_lo, e_hi, d_hi;
  blend_map_expected(b, lo, spread.z * spread.z / 3.0, s, e_lo, d_lo);
  blend_map_expected(b, hi, spread.w * spread.w / 3.0, s, e_hi, d_hi);
  e = p * e_lo + (1.0 - p) * e_hi;
  dev = p * (d_lo + e_lo * (lo - a_mean)) + (1.0 - p) * (d_hi + e_hi * (hi - a_mean));
}

// E[bilerp(m)^W] (coefficients TvtDptLayer::expect) or E[bilerp(m)^(2W)] (expect_sq) of a DPT
// layer whose corner masks are 1 with probability q.
double patch_moment(const float (&c)[3], double q) {
  const double r = 1.0 - q;
  return q * q * q * q + double(c[0]) * q * r * r * r + double(c[1]) * q * q * r * r + double(c[2]) * q * q * q * r;
}

// The blend map's means (blend_map_expected) over a patch sum b = settled + X, where X, the
// layers taken in expectation, lies in [0, span] with mean `mean` and variance `var` over the
// footprint: X is replaced by the two-point distribution on [0, span] with that mean and
// variance whose weights are those of a Bernoulli variable of the same mean mu (X/span is the
// lower point with probability 1 - mu, the higher with probability mu; at the largest variance
// the two points are 0 and span, at none both are the mean; docs/composition.md). The blend map is a sharp threshold where A hardly varies, so the
// mean of its values is not its value at the mean coverage.
void blend_map_of_patches(double settled, double mean, double var, double span, double a_mean, const glm::dvec4& a_spread,
                          double s, double& e, double& dev) {
  const double mu = span > 0.0 ? std::clamp(mean / span, 0.0, 1.0) : 0.0;
  const double sd = span > 0.0 ? std::sqrt(std::clamp(var, 0.0, mu * (1.0 - mu) * span * span)) / span : 0.0;
  if (!(sd > 1e-4) || mu <= 0.0 || mu >= 1.0) {
    blend_map_spread(std::min(settled + mean, 1.0), a_mean, a_spread, s, e, dev);
    return;
  }
  const double low = mu - sd * std::sqrt(mu / (1.0 - mu)), high = mu + sd * std::sqrt((1.0 - mu) / mu);
  double e_low, d_low, e_high, d_high;
  blend_map_spread(std::min(settled + low * span, 1.0), a_mean, a_spread, s, e_low, d_low);
  blend_map_spread(std::min(settled + high * span, 1.0), a_mean, a_spread, s, e_high, d_high);
  e = (1.0 - mu) * e_low + mu * e_high;
  dev = (1.0 - mu) * d_low + mu * d_high;
}

// Linear fade: 0 at or below lo, 1 at or above hi (a step at lo when hi <= lo).
double ramp(double v, double lo, double hi) {
  if (hi <= lo) return v >= lo ? 1.0 : 0.0;
  if (v >= hi) return 1.0;  // as the shader: ends decided by comparison
  if (v <= lo) return 0.0;
  return std::clamp((v - lo) / (hi - lo), 0.0, 1.0);
}

struct Ctx {
  const PackedScene& s;
  const gpu::TvtComposeParams& p;
  int64_t vt_fp;  // V * 256

  explicit Ctx(const PackedScene& scene)
      : s(scene), p(scene.params), vt_fp(int64_t(1) << (scene.params.log2_vt + gpu::TVT_FIXED_BITS)) {}

  // Bilinear weight of a layer at a terrain position; positions outside the terrain clamp.
  double weight(int layer, int64_t x_fp, int64_t y_fp) const {
    const int shift = p.log2_vt + gpu::TVT_FIXED_BITS;
    const int64_t half = int64_t(1) << (shift - 1);
    x_fp = std::clamp<int64_t>(x_fp, 0, vt_fp);
    y_fp = std::clamp<int64_t>(y_fp, 0, vt_fp);
    const int64_t nx = x_fp * p.weight_width - half, ny = y_fp * p.weight_height - half;
    const int64_t ix = nx >> shift, iy = ny >> shift;
    const double fx = std::ldexp(double(nx - (ix << shift)), -shift);
    const double fy = std::ldexp(double(ny - (iy << shift)), -shift);
    auto at = [&](int64_t i, int64_t j) {
      const int x = int(std::clamp<int64_t>(i, 0, p.weight_width - 1));
      const int y = int(std::clamp<int64_t>(j, 0, p.weight_height - 1));
      return double(s.weights[(size_t(layer) * size_t(p.weight_height) + size_t(y)) * size_t(p.weight_width) +
                              size_t(x)]);
    };
    const double w = (at(ix, iy) * (1 - fx) + at(ix + 1, iy) * fx) * (1 - fy) +
                     (at(ix, iy + 1) * (1 - fx) + at(ix + 1, iy + 1) * fx) * fy;
    return clamp01(w);
  }

  // Index of `m` in the parameter block (materials are always passed by reference into it).
  size_t index_of(const gpu::TvtMaterial& m) const { return size_t(&m - &p.materials[0]); }

  glm::dvec4 texel(const gpu::TvtMaterial& m, int level, int64_t x, int64_t y) const {
    const uint32_t offset = gpu::tvt_material_level_offset(uint32_t(m.resolution), uint32_t(level));  // within m's words
    const int64_t rl = m.resolution >> level;
    const uint32_t w = s.texels(index_of(m))[offset + uint32_t(tvt_floor_mod(y, rl) * rl + tvt_floor_mod(x, rl))];
    return glm::dvec4(w & 0xffu, (w >> 8) & 0xffu, (w >> 16) & 0xffu, w >> 24) / 255.0;
  }

  // The level-`level` texels around tile-local material texel (u, v) a bilinear fetch blends:
  // the first (i, j) and the fractions towards the next. The texture, the feature statistics
  // chain and the spread chain share it.
  struct Cell {
    int64_t i, j;
    double fx, fy;
  };
  static Cell bilinear_cell(int level, double u, double v) {
    const double scale = std::ldexp(1.0, -level);
    const double ul = u * scale - 0.5, vl = v * scale - 0.5;
    const double fi = std::floor(ul), fj = std::floor(vl);
    return {int64_t(fi), int64_t(fj), ul - fi, vl - fj};
  }

  glm::dvec4 bilinear(const gpu::TvtMaterial& m, int level, double u, double v) const {
    const Cell c = bilinear_cell(level, u, v);
    const int64_t i = c.i, j = c.j;
    const double fx = c.fx, fy = c.fy;
    return (texel(m, level, i, j) * (1 - fx) + texel(m, level, i + 1, j) * fx) * (1 - fy) +
           (texel(m, level, i, j + 1) * (1 - fx) + texel(m, level, i + 1, j + 1) * fx) * fy;
  }

  // Material texel coordinate inside the tile (in [0, R)) and the global material texel index.
  void material_coord(const gpu::TvtMaterial& m, int64_t pos_fp, double& local, int64_t& global) const {
    const int64_t num = pos_fp * m.resolution;
    global = tvt_floor_div(num, m.period_fp);
    const int64_t rem = num - global * m.period_fp;
    local = double(tvt_floor_mod(global, m.resolution)) + double(rem) / double(m.period_fp);
  }

  // log2 of material texels per sample footprint.
  double material_lod(const gpu::TvtMaterial& m, double footprint) const {
    return std::log2(footprint * m.resolution * 256.0 / double(m.period_fp));
  }

  // The trilinear pair of levels of m at LOD `lod`: l0, l1 and the weight t of l1 (0 where only
  // l0 is read). The texture and the feature statistics chain share it.
  struct Levels {
    int l0, l1;
    double t;
  };
  static Levels trilinear_levels(const gpu::TvtMaterial& m, double lod) {
    const double l = std::clamp(lod, 0.0, double(m.mip_count - 1));
    const int l0 = int(std::floor(l));
    const int l1 = std::min(l0 + 1, m.mip_count - 1);
    return {l0, l1, l1 == l0 ? 0.0 : l - l0};
  }
  // The level of the pair nearest the LOD: the one level the second-order statistics (A's
  // spread, the feature statistics chain) are read at (compose_sample.glsl nearest_level).
  static int nearest_level(const Levels& L) { return L.t < 0.5 ? L.l0 : L.l1; }

  // Trilinear, wrapping material sample at tile-local coordinates (u, v) in [0, R).
  glm::dvec4 trilinear(const gpu::TvtMaterial& m, double u, double v, double lod) const {
    const Levels L = trilinear_levels(m, lod);
    const glm::dvec4 a = bilinear(m, L.l0, u, v);
    if (L.t <= 0.0) return a;
    return a * (1 - L.t) + bilinear(m, L.l1, u, v) * L.t;
  }

  // Feature statistics of one texel of material m's chain (compose_types.h): D, mean f, and
  // the colour moment D (feature colour - colour). Level 0 is the meta texel itself.
  struct FeatureStats {
    double fraction = 0.0, soft = 0.0;
    glm::dvec4 moment{0.0};
    FeatureStats& operator+=(const FeatureStats& o) {
      fraction += o.fraction;
      soft += o.soft;
      moment += o.moment;
      return *this;
    }
    FeatureStats operator*(double k) const { return {fraction * k, soft * k, moment * k}; }
  };
  FeatureStats feature_texel(const gpu::TvtMaterial& m, int level, int64_t x, int64_t y) const {
    const std::span<const uint32_t> meta = s.meta(index_of(m));
    const uint32_t res = uint32_t(m.resolution), rl = res >> level;
    const size_t base = level == 0 ? 0 : gpu::tvt_meta_chain_offset(res, uint32_t(level));
    const size_t i = base + size_t(tvt_floor_mod(y, rl) * rl + tvt_floor_mod(x, rl));
    const uint32_t w0 = meta[2 * i], w1 = meta[2 * i + 1];
    FeatureStats t;
    if (level == 0) {
      t.fraction = (w1 & 0xffu) != 0 ? 1.0 : 0.0;
      t.soft = t.fraction * double((w1 >> 8) & 0xffu) / 255.0;
      return t;
    }
    t.fraction = double(w0 & 0xffffu) / 65535.0;
    t.soft = double(w0 >> 16) / 65535.0;
    for (int c = 0; c < 4; ++c)
      t.moment[c] = std::clamp(double(int8_t(uint8_t(w1 >> (8 * c)))) / 127.0, -1.0, 1.0) / double(gpu::TVT_META_MOMENT_SCALE);
    return t;
  }
  // The chain at tile-local material texel (u, v) and material LOD `lod`: bilinear at the level
  // nearest the LOD, as A's spread (spread(); compose_sample.glsl feature_stats).
  FeatureStats feature_stats(const gpu::TvtMaterial& m, double u, double v, double lod) const {
    const Levels L = trilinear_levels(m, lod);
    auto bilerp = [&](int level) {
      const Cell c = bilinear_cell(level, u, v);
      const int64_t i = c.i, j = c.j;
      const double fx = c.fx, fy = c.fy;
      FeatureStats r = feature_texel(m, level, i, j) * ((1 - fx) * (1 - fy));
      r += feature_texel(m, level, i + 1, j) * (fx * (1 - fy));
      r += feature_texel(m, level, i, j + 1) * ((1 - fx) * fy);
      r += feature_texel(m, level, i + 1, j + 1) * (fx * fy);
      return r;
    };
    return bilerp(nearest_level(L));
  }

  // The feature at global material texel (gx, gy): its mask d, soft f, the weight p at its
  // centroid (cx, cy) (every texel of a feature shares it; `plain` off features, and for every
  // feature where `at_centroid` is false: the prefiltered expectation's decisions take the
  // footprint's weight, as the expectation they fade into does) and whether it is visible,
  // eq 3.1: sgn(floor(p Cf / r)).
  struct Feature {
    double d = 0.0, f = 0.0, p = 0.0;
    int64_t cx = 0, cy = 0;
    bool visible = false;
  };
  Feature feature_at(const gpu::TvtMaterial& m, int64_t gx, int64_t gy, double plain, bool at_centroid) const {
    const int64_t R = m.resolution;
    const std::span<const uint32_t> meta = s.meta(index_of(m));
    const size_t mi = size_t(tvt_floor_mod(gy, R) * R + tvt_floor_mod(gx, R));
    const uint32_t w0 = meta[2 * mi], w1 = meta[2 * mi + 1];
    Feature ft;
    ft.d = double(w1 & 0xffu);
    ft.f = double((w1 >> 8) & 0xffu) / 255.0;
    // Centroid in global material texels: unique per feature instance over the terrain.
    ft.cx = gx + int16_t(w0 & 0xffffu);
    ft.cy = gy + int16_t(w0 >> 16);
    const int64_t cx_fp = tvt_floor_div((2 * ft.cx + 1) * m.period_fp, 2 * R);
    const int64_t cy_fp = tvt_floor_div((2 * ft.cy + 1) * m.period_fp, 2 * R);
    ft.p = ft.d > 0.0 && at_centroid ? weight(m.weight_layer, cx_fp, cy_fp) : plain;
    const double r = gpu::tvt_rand01(gpu::tvt_hash_coord(ft.cx, ft.cy, m.fbpb_salt));
    ft.visible = ft.d > 0.0 && ft.p > 0.0 && r <= ft.p * double(m.cf);
    return ft;
  }

  // FBPB's w at global material texel (gx, gy): eq 3.1 with Algorithm 1's chipped holes (which
  // darken `colour`, the material there, and show the layer below); `non_feature` is what a
  // non-feature texel blends with under FBPB+DPT (`with_dpt`).
  double fbpb_exact(const gpu::TvtMaterial& m, int64_t gx, int64_t gy, double plain, bool with_dpt, double non_feature,
                    glm::dvec4& colour, bool& visible) const {
    const int64_t R = m.resolution;
    const int64_t lx = tvt_floor_mod(gx, R), ly = tvt_floor_mod(gy, R);
    const Feature ft = feature_at(m, gx, gy, plain, true);
    double d = ft.d;
    visible = ft.visible;
    if (visible && ft.p < 1.0) {
      // Algorithm 1: variation map at the material uv plus a per-feature random offset.
      const std::span<const uint32_t> meta = s.meta(index_of(m));
      const uint32_t hv = gpu::tvt_hash_coord(ft.cx, ft.cy, m.variation_salt);
      const int64_t vx = tvt_floor_mod(lx + int64_t(hv & 0xffffu), R);
      const int64_t vy = tvt_floor_mod(ly + int64_t(hv >> 16), R);
      const uint32_t vw = meta[2 * size_t(vy * R + vx) + 1];
      const double variation = double((vw >> 16) & 0xffu) / 255.0;
      if (variation < double(m.variation_threshold)) {
        d = 0.0;  // a chipped hole shows the layer below
        visible = false;
        colour = glm::dvec4(glm::dvec3(colour) * double(m.colour_coeff), colour.a);
      }
    }
    const double nf = with_dpt ? non_feature : ft.p;
    return visible ? std::min(double(m.cm) * std::max(ft.p, ft.f), 1.0) : std::min((1.0 - d) * nf * double(m.cn), 1.0);
  }

  // The share of a visible feature's texels that Algorithm 1 chips: the variation map below the
  // threshold, interpolated in the statistics block's distribution of it (each feature reads
  // the map at its own random offset).
  double chipped_share(const gpu::TvtMaterial& m) const {
    const double t = m.variation_threshold;
    if (!(t > 0.0)) return 0.0;
    if (t > 1.0) return 1.0;
    const double x = t * gpu::TVT_STATS_VARIATION_STEPS;
    const int i = std::min(int(std::floor(x)), gpu::TVT_STATS_VARIATION_STEPS - 1);
    const double lo = stat(m, gpu::TVT_STATS_VARIATION_CDF + i), hi = stat(m, gpu::TVT_STATS_VARIATION_CDF + i + 1);
    return lo + (hi - lo) * (x - i);
  }

  // The statistics block word `i` of material m (TVT_MATERIAL_STATS_WORDS).
  double stat(const gpu::TvtMaterial& m, int i) const { return double(s.stat(index_of(m), i)); }

  // Variance of A and its covariances with R, G, B within a footprint of material LOD `lod`,
  // interpolated between levels as trilinear() interpolates the texels.
  glm::dvec4 a_stats(const gpu::TvtMaterial& m, double lod) const {
    const double l = std::clamp(lod, 0.0, double(std::min(m.mip_count - 1, 14)));
    const int l0 = int(std::floor(l));
    const int l1 = std::min(l0 + 1, std::min(m.mip_count - 1, 14));
    const double t = l - l0;
    glm::dvec4 a, b;
    for (int i = 0; i < 4; ++i) {
      a[i] = stat(m, 4 * l0 + i);
      b[i] = stat(m, 4 * l1 + i);
    }
    return a * (1.0 - t) + b * t;
  }

  // A within the level-0 texels under level-`level` texel (x, y) of m as (p, delta, h_lo, h_hi)
  // (the spread chain, compose_types.h); none at level 0, a single texel.
  glm::dvec4 spread_texel(const gpu::TvtMaterial& m, int level, int64_t x, int64_t y) const {
    if (level == 0) return glm::dvec4(0.0);
    const uint32_t res = uint32_t(m.resolution);
    const int64_t rl = int64_t(res >> level);
    const size_t i = size_t(tvt_floor_mod(y, rl) * rl + tvt_floor_mod(x, rl));
    const uint32_t w = s.texels(index_of(m))[gpu::tvt_material_spread_offset(res, uint32_t(level)) + i];
    const glm::dvec4 v = glm::dvec4(w & 0xffu, (w >> 8) & 0xffu, (w >> 16) & 0xffu, w >> 24) / 255.0;
    return glm::dvec4(v.x, glm::dvec3(v.y, v.z, v.w) / double(gpu::TVT_SPREAD_SCALE));
  }
  // A's distribution within the footprint at tile-local material texel (u, v) and LOD `lod`:
  // bilinear at the level nearest the LOD, whose blocks are within a factor sqrt(2) of the
  // footprint's side (compose_sample.glsl material_spread; docs/composition.md).
  glm::dvec4 spread(const gpu::TvtMaterial& m, double u, double v, double lod) const {
    const Levels L = trilinear_levels(m, lod);
    auto bilerp = [&](int level) {
      const Cell c = bilinear_cell(level, u, v);
      const int64_t i = c.i, j = c.j;
      const double fx = c.fx, fy = c.fy;
      return (spread_texel(m, level, i, j) * (1 - fx) + spread_texel(m, level, i + 1, j) * fx) * (1 - fy) +
             (spread_texel(m, level, i, j + 1) * (1 - fx) + spread_texel(m, level, i + 1, j + 1) * fx) * fy;
    };
    return bilerp(nearest_level(L));
  }

  // Material sample at a terrain position: the tiled texture, or hex-tiling where it is on.
  // `a_spread` (prefiltered): A's distribution within the footprint there (spread()).
  glm::dvec4 sample_material(const gpu::TvtMaterial& m, int64_t x_fp, int64_t y_fp, double lod,
                             glm::dvec4* a_spread = nullptr) const {
    double u, v;
    int64_t gx, gy;
    material_coord(m, x_fp, u, gx);
    material_coord(m, y_fp, v, gy);
    if (m.hex_edge <= 0) {
      if (a_spread) *a_spread = spread(m, u, v, lod);
      return trilinear(m, u, v, lod);
    }
    const double fx = u - double(tvt_floor_mod(gx, m.resolution)), fy = v - double(tvt_floor_mod(gy, m.resolution));
    return hex_sample(m, gx, fx, gy, fy, lod, a_spread);
  }

  // Hex-tiling at global material texel (gx + fx, gy + fy): the triangle of a lattice with edge
  // L and row height H holding the point, each corner a tile of the texture shifted by its own
  // hashed whole-texel offset, blended by barycentric weights raised to gamma (normalised, the
  // ones below `cut` dropped) about the material's mean (its top mip) so that the blend keeps
  // one tile's variance (docs/composition.md).
  // `a_spread`: A's distribution within the footprint, the tiles' own blended as their values
  // are (independent tiles: the deviations and half-widths as sqrt(sum w_k^2 x_k^2), scaled as
  // the histogram preservation scales A; the share weighted by w_k^2).
  glm::dvec4 hex_sample(const gpu::TvtMaterial& m, int64_t gx, double fx, int64_t gy, double fy, double lod,
                        glm::dvec4* a_spread = nullptr) const {
    const int64_t L = m.hex_edge, H = m.hex_row, R = m.resolution;
    const int64_t j = tvt_floor_div(gy, H);
    const double b = (double(gy - j * H) + fy) / double(H);
    const int64_t xs = gx - j * (L / 2);  // odd rows are shifted by half an edge per row
    int64_t i = tvt_floor_div(xs, L);
    double a = (double(xs - i * L) + fx) / double(L) - 0.5 * b;
    if (a < 0.0) {
      i -= 1;
      a += 1.0;
    }
    int64_t vx[3], vy[3];
    double w[3];
    if (a + b < 1.0) {
      vx[0] = i, vy[0] = j, w[0] = 1.0 - a - b;
      vx[1] = i + 1, vy[1] = j, w[1] = a;
      vx[2] = i, vy[2] = j + 1, w[2] = b;
    } else {
      vx[0] = i + 1, vy[0] = j + 1, w[0] = a + b - 1.0;
      vx[1] = i + 1, vy[1] = j, w[1] = 1.0 - b;
      vx[2] = i, vy[2] = j + 1, w[2] = 1.0 - a;
    }
    double sum = 0.0;
    for (double& x : w) sum += (x = safe_pow(std::max(x, 0.0), m.hex_sharpness));
    double kept = 0.0;
    for (double& x : w) kept += (x = std::max(x / sum - double(m.hex_cut), 0.0));
    glm::dvec4 linear(0.0);
    double squares = 0.0;
    glm::dvec4 spread_sum(0.0);  // sum of w_k^2 (p, delta^2, h_lo^2, h_hi^2)
    for (int k = 0; k < 3; ++k) {
      const double wk = w[k] / kept;
      if (wk <= 0.0) continue;
      squares += wk * wk;
      const uint32_t h = gpu::tvt_hash_coord(vx[k], vy[k], m.hex_salt);
      const double u = double(tvt_floor_mod(gx + int64_t(h & 0xffffu), R)) + fx;
      const double v = double(tvt_floor_mod(gy + int64_t(h >> 16), R)) + fy;
      linear += wk * trilinear(m, u, v, lod);
      if (a_spread) {
        const glm::dvec4 t = spread(m, u, v, lod);
        spread_sum += wk * wk * glm::dvec4(t.x, t.y * t.y, t.z * t.z, t.w * t.w);
      }
    }
    if (a_spread) {
      const double scale = 1.0 + double(m.hex_preserve) * (1.0 / std::sqrt(squares) - 1.0);
      *a_spread = glm::dvec4(spread_sum.x / squares, scale * glm::sqrt(glm::dvec3(spread_sum.y, spread_sum.z, spread_sum.w)));
    }
    const glm::dvec4 mean = texel(m, m.mip_count - 1, 0, 0);
    const glm::dvec4 preserved = mean + (linear - mean) / std::sqrt(squares);
    const glm::dvec4 r = linear + (preserved - linear) * double(m.hex_preserve);
    return glm::dvec4(clamp01(r.x), clamp01(r.y), clamp01(r.z), clamp01(r.w));
  }

  // DPT (eq. 4.1–4.4, Algorithms 2–3): blend weight b and patch height h for material m.
  // Prefiltered (`a_spread` given): a layer whose patches are small against the footprint
  // takes its expected coverage instead of its point value, and the blend maps their mean
  // over A; `dev` is the blend map's covariance term (blend_map_expected).
  void dpt(const gpu::TvtMaterial& m, int64_t x_fp, int64_t y_fp, double footprint, double plain, double height_a,
           double& b_out, double& h_out, bool prefiltered = false, const glm::dvec4& a_spread = glm::dvec4(0.0),
           double* dev = nullptr) const {
    double b = 0, h = 0, fade_max = 0;
    double settled = 0, mean = 0, var = 0, span = 0;  // prefiltered: b = settled + X, X in [0, span]
    for (int k = 0; k < m.dpt_layer_count; ++k) {
      const gpu::TvtDptLayer& L = m.dpt[k];
      const double fade = ramp(double(L.patch_texels) / footprint, m.dpt_fade_lo, m.dpt_fade_hi);  // eq 4.4
      if (prefiltered) {
        const double exact = ramp(double(L.patch_texels) / footprint, double(p.prefilter_patch_lo), double(p.prefilter_patch_hi));
        // The layer is present as at level 0; its point value is blended with its expectation
        // by how much of the footprint one patch covers.
        const double present = ramp(double(L.patch_texels), m.dpt_fade_lo, m.dpt_fade_hi);
        fade_max = std::max(fade_max, present);
        if (present <= 0.0) continue;
        const double q = clamp01(safe_pow(plain, double(L.exp_p) / std::max(double(L.exp_r), 1e-6)));  // P(r^R <= p^P)
        double expected = patch_moment(L.expect, q);
        double second = patch_moment(L.expect_sq, q);
        const double weight = present * (1.0 - exact);
        const double point = exact > 0.0 ? present * exact * patch_value(m, L, x_fp, y_fp) : 0.0;
        if (weight > 0.0) patch_samples(m, L, x_fp, y_fp, footprint, expected, second);
        settled += point;
        mean += weight * expected;
        var += weight * weight * std::max(second - expected * expected, 0.0);
        span += weight;  // b is settled + mean here, read by blend_map_of_patches
        h += (point + weight * expected) * L.height_h;
        continue;
      }
      fade_max = std::max(fade_max, fade);
      if (fade <= 0.0) continue;
      const double w = patch_value(m, L, x_fp, y_fp);
      b += fade * w;
      h += fade * w * L.height_h;
    }
    b = std::min(b, 1.0);
    h = std::min(h, 1.0);
    if (prefiltered) {
      double e_patch, d_patch, e_plain, d_plain;
      blend_map_of_patches(settled, mean, var, span, height_a, a_spread, m.blend_sharpness, e_patch, d_patch);
      blend_map_spread(plain, height_a, a_spread, m.blend_sharpness, e_plain, d_plain);
      b_out = fade_max * e_patch + (1.0 - fade_max) * e_plain;
      if (dev) *dev = fade_max * d_patch + (1.0 - fade_max) * d_plain;
      h_out = h;
      return;
    }
    b = blend_map(b, height_a, m.blend_sharpness);
    // When even the largest layer's patches are too small, fall back to the plain weight.
    b_out = fade_max * b + (1.0 - fade_max) * blend_map(plain, height_a, m.blend_sharpness);
    h_out = h;
  }

  // Prefiltered DPT: while few of layer L's patches fall in the footprint, the mean and second
  // moment of its actual values at k x k points spread evenly over it (k = 2 while a patch
  // spans the footprint, else 3) replace the expectation over random corner masks, faded to
  // it between TVT_PATCH_SAMPLES_LO and _HI patches a side (compose_types.h): the footprint's
  // own few decisions, which the expectation over many does not know.
  void patch_samples(const gpu::TvtMaterial& m, const gpu::TvtDptLayer& L, int64_t x_fp, int64_t y_fp, double footprint,
                     double& mean, double& second) const {
    const double patches = footprint / std::max(double(L.patch_texels), 1e-6);
    const double g = ramp(patches, double(gpu::TVT_PATCH_SAMPLES_LO), double(gpu::TVT_PATCH_SAMPLES_HI));
    if (g >= 1.0) return;
    const int k = patches <= 1.0 ? 2 : 3;
    const auto offset = [&](int i) { return std::llround(((i + 0.5) / k - 0.5) * footprint * 256.0); };
    // The shader decides the points' corners once, on a lattice of at most 8 a side: a wider
    // span (only through rounding at the ramp's end) leaves the layer to its expectation.
    const auto cells = [&](int64_t c_fp) {
      return tvt_floor_div(c_fp + offset(k - 1), L.patch_fp) - tvt_floor_div(c_fp + offset(0), L.patch_fp) + 2;
    };
    if (cells(x_fp) > 8 || cells(y_fp) > 8) return;
    double s1 = 0.0, s2 = 0.0;
    for (int j = 0; j < k; ++j)
      for (int i = 0; i < k; ++i) {
        const double v = patch_value(m, L, x_fp + offset(i), y_fp + offset(j));
        s1 += v, s2 += v * v;
      }
    s1 /= double(k * k), s2 /= double(k * k);
    mean = (1.0 - g) * s1 + g * mean;
    second = (1.0 - g) * s2 + g * second;
  }

  // One DPT layer's w (eq 4.1-4.3) at a terrain position.
  double patch_value(const gpu::TvtMaterial& m, const gpu::TvtDptLayer& L, int64_t x_fp, int64_t y_fp) const {
    const int64_t ps = L.patch_fp;
    const int64_t ix = tvt_floor_div(x_fp, ps), iy = tvt_floor_div(y_fp, ps);
    const double fx = double(x_fp - ix * ps) / double(ps), fy = double(y_fp - iy * ps) / double(ps);
    double mask[2][2];
    for (int cy = 0; cy < 2; ++cy)
      for (int cx = 0; cx < 2; ++cx) {
        const int64_t jx = ix + cx, jy = iy + cy;
        const double pj = safe_pow(weight(m.weight_layer, jx * ps + ps / 2, jy * ps + ps / 2), L.exp_p);  // eq 4.1
        const double rj = safe_pow(gpu::tvt_rand01(gpu::tvt_hash_coord(jx, jy, L.salt)), L.exp_r);
        mask[cy][cx] = (pj > 0.0 && rj <= pj) ? 1.0 : 0.0;  // eq 4.2
      }
    const double bl = (mask[0][0] * (1 - fx) + mask[0][1] * fx) * (1 - fy) + (mask[1][0] * (1 - fx) + mask[1][1] * fx) * fy;
    return safe_pow(bl, L.exp_w);  // eq 4.3
  }
};

}  // namespace

uint8_t to_unorm8(double v) { return uint8_t(std::lround(clamp01(v) * 255.0)); }

namespace {

// `mask`: materials the page may show (MaterialCuller); the others contribute b = 0 exactly, so
// they are skipped without reading their texels.
// `prefiltered`: the composition of docs/composition.md, "Prefiltered mips" (mips >= 1 of the
// prefiltered strategy).
glm::dvec4 compose_sample(const PackedScene& scene, int64_t x_fp, int64_t y_fp, double footprint, uint32_t mask,
                          bool prefiltered = false) {
  const Ctx c(scene);
  const gpu::TvtComposeParams& p = scene.params;
  footprint = std::isfinite(footprint) ? std::max(footprint, 1.0 / 256.0) : 1.0;

  // Raw weights of every layer, and the running sum for Bloom's sequential normalisation.
  double weights[gpu::TVT_MAX_MATERIALS];
  for (int n = 0; n < p.material_count; ++n) weights[n] = c.weight(p.materials[n].weight_layer, x_fp, y_fp);

  const gpu::TvtMaterial& base = p.materials[0];
  glm::dvec4 result = c.sample_material(base, x_fp, y_fp, c.material_lod(base, footprint));
  double weight_sum = weights[0];
  bool feature_above = false;  // F_{n-1} of eq 3.2: a lower layer shows a visible feature

  for (int n = 1; n < p.material_count; ++n) {
    const gpu::TvtMaterial& m = p.materials[n];
    const double plain = weights[n];
    weight_sum += plain;
    const int mode = m.mode;
    if (!(mask & (1u << n))) continue;  // culled: no weight within its reach of the page
    // Layers with no weight anywhere the mode looks contribute nothing: skip the fetches.
    if (plain <= 0.0 && (mode == gpu::TVT_MODE_LINEAR || mode == gpu::TVT_MODE_BLENDMAP)) continue;

    const double lod = c.material_lod(m, footprint);
    glm::dvec4 a_spread(0.0);  // prefiltered: A's distribution within the footprint
    glm::dvec4 colour = c.sample_material(m, x_fp, y_fp, lod, prefiltered ? &a_spread : nullptr);
    double b = 0.0;
    double height = colour.a;
    bool visible = false;
    // Prefiltered: the texture's pooled variance of A and covariances with RGB at this LOD (the
    // regression of RGB on A), and the blend map's covariance term with A (zero: no
    // correction); A's own distribution within the footprint is the local a_spread.
    const glm::dvec4 a_stats = prefiltered ? c.a_stats(m, lod) : glm::dvec4(0.0);
    double dev = 0.0;
    bool dev_height = false;  // the layer's height is its A: A's own deviation shifts it too
    double feature_shift = 0.0;  // prefiltered FBPB: weight of the features' colour moment
    glm::dvec4 feature_moment(0.0);

    if (mode == gpu::TVT_MODE_LINEAR) {
      // Bloom: weights normalised over the layers so far, boosted, clamped.
      b = weight_sum > 0.0 ? std::min(1.0, double(p.linear_boost) * plain / weight_sum) : 0.0;
    } else if (mode == gpu::TVT_MODE_BLENDMAP) {
      if (prefiltered) {
        blend_map_spread(plain, colour.a, a_spread, m.blend_sharpness, b, dev);
        dev_height = true;
      } else {
        b = blend_map(plain, colour.a, m.blend_sharpness);
      }
    } else if (mode == gpu::TVT_MODE_DPT) {
      c.dpt(m, x_fp, y_fp, footprint, plain, colour.a, b, height, prefiltered, a_spread, &dev);
    } else {  // FBPB, FBPB+DPT
      double non_feature = 0.0;  // what a non-feature texel blends with: p (FBPB) or DPT's b
      double dpt_h = colour.a;
      double dpt_dev = 0.0;  // prefiltered: E[b (A - mean)] of DPT's blend map
      const bool with_dpt = mode == gpu::TVT_MODE_FBPB_DPT;
      if (with_dpt) c.dpt(m, x_fp, y_fp, footprint, plain, colour.a, non_feature, dpt_h, prefiltered, a_spread, &dpt_dev);
      // Prefiltered FBPB+DPT: a ground texel takes DPT's blend value at its own A, the
      // footprint's b moved along its regression on A (dpt_dev over A's variance within the
      // footprint, the spread chain's two pieces): the gaps between features are the low A that a
      // blend map shows last. ground_slope * (A_x - mean) is the move for mean A_x.
      const double a_var = prefiltered && with_dpt ? spread_variance(a_spread) : 0.0;
      const double ground_slope = a_var > 1e-5 ? dpt_dev / a_var : 0.0;
      // Prefiltered: features stay exact (coherent per feature), at points of the footprint,
      // while it is about a feature or less, then take their expectation: a switch, decided in
      // float from the LOD as the shader has it (a prefiltered footprint is a power of two, 2^k,
      // where material_lod() there is float(k) + lod_bias). Level 0's own feature fade (what the
      // truth holds; 1 for the default scenes).
      const double fade0 = prefiltered ? 1.0 - ramp(c.material_lod(m, 1.0), m.fbpb_fade_lo, m.fbpb_fade_hi) : 1.0;
      const double fade =
          prefiltered ? (fade0 > 0.0 && gpu::tvt_feature_points_hold(float(std::log2(footprint)) + m.lod_bias, float(c.stat(m, gpu::TVT_STATS_FEATURE_LOG2_SIZE))) ? 1.0 : 0.0)
                      : 1.0 - ramp(lod, m.fbpb_fade_lo, m.fbpb_fade_hi);
      double fallback = 0.0;
      if (with_dpt) {
        fallback = non_feature;
      } else if (prefiltered) {
        double unused;
        blend_map_spread(plain, colour.a, a_spread, m.blend_sharpness, fallback, unused);
      } else {
        fallback = blend_map(plain, colour.a, m.blend_sharpness);
      }
      // Tile-local (u, v) and global material texel of the sample (features and their chain).
      double u, v;
      int64_t gx, gy;
      c.material_coord(m, x_fp, u, gx);
      c.material_coord(m, y_fp, v, gy);
      const double plain_fallback = fallback;
      if (prefiltered && fade < 1.0 && fade0 > 0.0) {
        // Features smaller than the footprint: their expected w (eq 3.1) over the feature
        // fraction D of the footprint (the chain), each visible with probability min(p Cf, 1),
        // mixed with the level-0 fallback as level 0 mixes them.
        const double nf = with_dpt ? non_feature : plain;
        const Ctx::FeatureStats local = c.feature_stats(m, u, v, lod);
        // FBPB+DPT: ground and chipped texels at their own mean A (ground_slope): the chain's
        // moment gives the features' mean A, mean + moment.a / D, and the ground's,
        // mean - moment.a / (1 - D).
        const double nf_ground =
            with_dpt ? clamp01(non_feature - ground_slope * local.moment.a / std::max(1.0 - local.fraction, 1e-3)) : nf;
        const double nf_chip = with_dpt ? clamp01(non_feature + ground_slope * local.moment.a / std::max(local.fraction, 1e-3)) : nf;
        // A visible feature's texel where its p < 1 is chipped (Algorithm 1) with the share q of
        // the variation map below the threshold: then it blends as ground (w_chip) in a colour
        // darkened by colour_coeff.
        const double q = c.chipped_share(m);
        const double w_chip = std::min(nf_chip * double(m.cn), 1.0);
        const double q_plain = plain < 1.0 ? q : 0.0;
        const double visible_p = std::min(plain * double(m.cf), 1.0);
        // The share of the footprint's features that show: while few fall in it, their own
        // decisions under k x k points spread over it (k = 1 while a feature spans it, up to 4
        // where 16 do), faded to the expectation as more fall in (docs/composition.md). Each is
        // decided at the footprint's weight, as the expectation is, not at its own centroid.
        double visible_share = visible_p;
        const double rel = lod - c.stat(m, gpu::TVT_STATS_FEATURE_LOG2_SIZE);
        const double e = 1.0 - ramp(rel, 2.0, 3.0);
        if (e > 0.0) {
          const int k = 1 << std::clamp(int(std::ceil(rel)) + 1, 0, 2);
          const int64_t step = std::max<int64_t>(1, std::llround(std::exp2(lod) / k));
          int hits = 0, shown = 0;
          for (int j = 0; j < k; ++j)
            for (int i = 0; i < k; ++i) {
              const Ctx::Feature ft = c.feature_at(m, gx + (((2 * i + 1 - k) * step) >> 1),
                                                   gy + (((2 * j + 1 - k) * step) >> 1), plain, false);
              hits += ft.d > 0.0 ? 1 : 0;
              shown += ft.visible ? 1 : 0;
            }
          if (hits > 0) visible_share = e * double(shown) / double(hits) + (1.0 - e) * visible_p;
        }
        // The footprint's feature texels, each feature shown or not: their mean w (eq 3.1 at the
        // footprint's weight, the chipped share q_plain as ground) and its chipped texels' part.
        const double w_feature =
            visible_share * ((1.0 - q_plain) * std::min(double(m.cm) * std::max(plain, local.soft), 1.0) + q_plain * w_chip);
        const double chip_feature = visible_share * q_plain * w_chip;
        const double chip_share = visible_share * q_plain;  // the footprint's feature texels that are chipped
        const double w_ground = std::min(nf_ground * double(m.cn), 1.0);
        const double expected = local.fraction * w_feature + (1.0 - local.fraction) * w_ground;
        fallback = fade0 * expected + (1.0 - fade0) * fallback;
        // The chipped texels' share of the fallback shows darkened: level 0 darkens a chipped
        // texel's colour, so its plain share (1 - fade0) too.
        const double chip_b = local.fraction * (fade0 * chip_feature + (1.0 - fade0) * plain_fallback * chip_share);
        if (fallback > 0.0)
          colour = glm::dvec4(glm::dvec3(colour) * (1.0 - (1.0 - double(m.colour_coeff)) * std::min(chip_b / fallback, 1.0)),
                              colour.a);
        // E[b colour] - E[b] mean: feature texels (their own mean colour) take w_F, the others
        // w_N, so the shift is (w_F - w_N) times the moment D (feature colour mean - mean).
        feature_shift = fade0 * (w_feature - w_ground);  // fade is 0 here
        feature_moment = local.moment;
      }
      double w = 0.0;
      if (fade > 0.0) {
        // Direct: the feature at the sample. Prefiltered: the mean w over k x k points of the
        // footprint (tvt_feature_points), each with the texture over its own cell of it
        // (tvt_feature_point_lods finer), and their w-weighted colour (docs/composition.md,
        // "FBPB features at points").
        if (!prefiltered) {
          w = c.fbpb_exact(m, gx, gy, plain, with_dpt, non_feature, colour, visible);
        } else {
          const int k = gpu::tvt_feature_points(float(lod), float(c.stat(m, gpu::TVT_STATS_FEATURE_LOG2_SIZE)), with_dpt);
          const int lods = gpu::tvt_feature_point_lods(k);
          const int64_t half_step = gpu::tvt_feature_point_half_step(std::llround(std::ldexp(footprint, gpu::TVT_FIXED_BITS)), k);
          glm::dvec4 weighted(0.0), points_colour(0.0);
          int shown = 0;
          for (int j = 0; j < k; ++j)
            for (int i = 0; i < k; ++i) {
              const int64_t px = x_fp + (2 * i + 1 - k) * half_step, py = y_fp + (2 * j + 1 - k) * half_step;
              // Never hex-tiled (pack_scene() leaves FBPB layers above the base untiled).
              double pu, pv;
              int64_t pgx, pgy;
              c.material_coord(m, px, pu, pgx);
              c.material_coord(m, py, pv, pgy);
              glm::dvec4 pc = c.trilinear(m, pu, pv, lod - lods);
              bool shows = false;
              const double ground = clamp01(non_feature + ground_slope * (pc.a - colour.a));  // at its own A
              const double wi = c.fbpb_exact(m, pgx, pgy, plain, with_dpt, ground, pc, shows);
              w += wi;
              weighted += wi * pc;
              points_colour += pc;
              shown += shows ? 1 : 0;
            }
          visible = 2 * shown >= k * k;  // half the points
          // The points' mean, faded as level 0 fades them (its plain share in each point's own
          // colour, darkened where chipped), and their w-weighted colour: mix(result, colour, b)
          // is then that mean of the points' blends.
          const double per_point = 1.0 / double(k * k);
          w = fade0 * per_point * w + (1.0 - fade0) * plain_fallback;
          weighted = per_point * (fade0 * weighted + (1.0 - fade0) * plain_fallback * points_colour);
          if (w > 0.0) colour = weighted / w;  // fade is 1 here: a switch, not a ramp
        }
      }
      b = fade * w + (1.0 - fade) * fallback;
      visible = visible && fade > 0.0;
      if (with_dpt) height = dpt_h;
    }
    // Precedence (eq 3.2/3.3): a visible lower feature is never covered by non-feature texels.
    const double bn = (visible || !feature_above) ? clamp01(b) : 0.0;
    feature_above = feature_above || visible;
    result = glm::dvec4(glm::dvec3(result) * (1.0 - bn) + glm::dvec3(colour) * bn, result.a * (1.0 - bn) + height * bn);
    if (prefiltered && bn > 0.0 && dev != 0.0 && a_stats.x > 1e-6) {
      // E[b colour] = E[b] mean + beta E[b (A - mean)], beta = cov(A, colour) / var(A).
      const glm::dvec3 beta = glm::dvec3(a_stats.y, a_stats.z, a_stats.w) / a_stats.x;
      result = glm::dvec4(glm::dvec3(result) + beta * dev, result.a + (dev_height ? dev : 0.0));
    }
    if (prefiltered && bn > 0.0 && feature_shift != 0.0) {
      glm::dvec4 offset = feature_moment;
      if (mode == gpu::TVT_MODE_FBPB_DPT) offset.a = 0.0;  // its height is DPT's, not A
      result += offset * feature_shift;
    }
  }
  for (int i = 0; i < 4; ++i) result[i] = clamp01(result[i]);
  return result;
}

glm::dvec4 compose_texel(const PackedScene& scene, uint32_t mip, int64_t x, int64_t y, uint32_t mask) {
  const gpu::TvtComposeParams& p = scene.params;
  const int64_t last = (int64_t(1) << (p.log2_vt - int(mip))) - 1;
  x = std::clamp<int64_t>(x, 0, last);
  y = std::clamp<int64_t>(y, 0, last);
  const int64_t s = std::min<int64_t>(p.supersample, int64_t(1) << mip);  // as compose.comp
  const int sub_shift = int(mip) + gpu::TVT_FIXED_BITS;  // one mip texel = 2^sub_shift fixed units
  const double footprint = std::ldexp(1.0, int(mip)) / double(s);
  glm::dvec4 sum(0.0);
  for (int64_t sy = 0; sy < s; ++sy)
    for (int64_t sx = 0; sx < s; ++sx) {
      const int64_t xf = (x << sub_shift) + (((2 * sx + 1) << sub_shift) / (2 * s));
      const int64_t yf = (y << sub_shift) + (((2 * sy + 1) << sub_shift) / (2 * s));
      sum += compose_sample(scene, xf, yf, footprint, mask, p.prefiltered != 0 && mip > 0);
    }
  return sum / double(s * s);
}

}  // namespace

glm::dvec4 compose_sample_reference(const PackedScene& scene, int64_t x_fp, int64_t y_fp, double footprint) {
  return compose_sample(scene, x_fp, y_fp, footprint, ~0u);
}

glm::dvec4 compose_texel_reference(const PackedScene& scene, uint32_t mip, int64_t x, int64_t y) {
  return compose_texel(scene, mip, x, y, ~0u);
}

glm::dvec4 ground_truth_texel(const PackedScene& scene, uint32_t mip, int64_t x, int64_t y) {
  glm::dvec4 sum(0.0);
  const int64_t n = int64_t(1) << mip;
  for (int64_t j = 0; j < n; ++j)
    for (int64_t i = 0; i < n; ++i) {
      const int64_t xf = ((x * n + i) << gpu::TVT_FIXED_BITS) + (1 << (gpu::TVT_FIXED_BITS - 1));
      const int64_t yf = ((y * n + j) << gpu::TVT_FIXED_BITS) + (1 << (gpu::TVT_FIXED_BITS - 1));
      sum += compose_sample_reference(scene, xf, yf, 1.0);
    }
  return sum / double(n * n);
}

Result<std::vector<uint8_t>> compose_page_reference(const PackedScene& scene, const PageId& page) {
  const gpu::TvtComposeParams& p = scene.params;
  // Exactly the materials the GPU composer reads for this page (its culling mask).
  const uint32_t mask = MaterialCuller(scene).mask(page);
  if (auto s = scene.load(mask); !s) return s.error();
  const int size = p.page_texels + 2 * p.border_texels;
  std::vector<uint8_t> out(size_t(size) * size_t(size) * 4);
  for (int ty = 0; ty < size; ++ty)
    for (int tx = 0; tx < size; ++tx) {
      const int64_t x = int64_t(page.x) * p.page_texels - p.border_texels + tx;
      const int64_t y = int64_t(page.y) * p.page_texels - p.border_texels + ty;
      const glm::dvec4 v = compose_texel(scene, page.mip, x, y, mask);
      uint8_t* o = &out[(size_t(ty) * size_t(size) + size_t(tx)) * 4];
      for (int c = 0; c < 4; ++c) o[c] = to_unorm8(v[c]);
    }
  return out;
}

}  // namespace tvt
