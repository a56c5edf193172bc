// The prefiltered mip strategy in the CPU reference compositor: mip 0 is direct, coarser mips
// approach the box filter of level 0 (DPT's patches in expectation and at samples, A's spread
// under the blend map, FBPB's features at points and in expectation), on hand-made scenes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <utility>
#include <vector>

#include "compose/material_source.h"
#include "compose/reference_compositor.h"
#include "shaders/shared/hash.h"
#include "support/synthetic_scene.h"

using namespace tvt;
using test::k_base;
using test::pack;

namespace {

// A DPT layer of `patch` texels over a base, weight `w` everywhere; materials of constant colour.
SceneAssets dpt_scene(double patch, float w, double p = 1, double r = 1, double wexp = 1) {
  auto a = test::make_synthetic_assets({k_base, {{0, 250, 0, 200}, w, Mode::Dpt}});
  a.desc.materials[1].dpt.layers = {{patch, p, r, wexp, 0.5}};
  return a;
}

ComposeOptions prefiltered_options() {
  ComposeOptions o;
  o.prefiltered = true;
  return o;
}

}  // namespace

// Mip 0 is direct under the prefiltered strategy too; and it refuses supersampling on top.
TEST(Prefiltered, Mip0IsTheDirectComposition) {
  auto a = dpt_scene(6, 0.5f);
  for (size_t i = 0; i < 16; ++i) a.weights.data[16 + i] = float(i % 3) / 2.f;
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  for (int64_t y = 0; y < 8; ++y)
    for (int64_t x = 0; x < 8; ++x) EXPECT_EQ(compose_texel_reference(direct, 0, x * 9, y * 5), compose_texel_reference(pre, 0, x * 9, y * 5));
  ComposeOptions both = prefiltered_options();
  both.supersample = 4;
  EXPECT_FALSE(pack_scene(a, both).ok());
}

// Patches far smaller than a texel, over a material whose blend map A spreads over [0, 1]:
// direct composition shows one patch's decision per texel, or (faded) the plain weight; the
// prefiltered texel is the patches' expected coverage through the blend map's mean over A,
// which is what the box filter of level 0 converges to. (Where A hardly varies: the next test.)
TEST(Prefiltered, ConvergesToTheBoxFilteredTruthWherePatchesAreSmall) {
  // Patches of 2 texels, present at level 0 (fade from 0.5 to 1 texel), 256 to a mip-5 texel;
  // P != R, where the coverage w^(P/R) is not the plain weight direct composition falls back to.
  for (const double pexp : {0.5, 2.0}) {
    SceneAssets a = dpt_scene(2, 0.5f, pexp, 1.0, 1.0);
    a.desc.materials[1].dpt.fade_lo_texels = 0.5;
    a.desc.materials[1].dpt.fade_hi_texels = 1.0;
    ImageRGBA8 spread(16, 16);  // every A value 0..255 once, scattered
    for (int i = 0; i < 256; ++i) {
      uint8_t* t = spread.at(i % 16, i / 16);
      t[0] = 0, t[1] = 250, t[2] = 0, t[3] = uint8_t((i * 97 + 13) % 256);
    }
    a.materials->edit(1).albedo = build_mip_chain(spread);
    const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
    double err_direct = 0, err_pre = 0;
    for (int64_t y = 0; y < 4; ++y)
      for (int64_t x = 0; x < 4; ++x) {
        const double truth = ground_truth_texel(direct, 5, x + 8, y + 8).g;  // 32^2 level-0 texels
        err_direct += std::abs(compose_texel_reference(direct, 5, x + 8, y + 8).g - truth);
        err_pre += std::abs(compose_texel_reference(pre, 5, x + 8, y + 8).g - truth);
      }
    EXPECT_LT(err_pre / 16, 0.06) << "P = " << pexp;  // the truth's own noise: ~256 patch decisions a texel
    EXPECT_LT(err_pre, 0.5 * err_direct) << "P = " << pexp;
  }
}

// The same where A does not vary at all, so the blend map is a sharp threshold of the patch
// ramps: the mean of the thresholded ramps is not the threshold of their mean coverage (here
// the mean coverage, 1/2, is over the threshold everywhere, yet much of each cell is under it).
// The prefiltered texel carries the ramps' spread (mean and variance), and lands near the box
// filter where the mean coverage alone would miss it.
TEST(Prefiltered, FollowsTheSpreadOfThePatchesUnderASharpBlendMap) {
  for (const auto& [alpha, wexp] : {std::pair{200, 1.0}, {150, 1.0}, {200, 2.0}, {90, 0.5}}) {
    SceneAssets a = dpt_scene(2, 0.5f, 1.0, 1.0, wexp);
    a.desc.materials[1].dpt.fade_lo_texels = 0.5;
    a.desc.materials[1].dpt.fade_hi_texels = 1.0;
    ImageRGBA8 flat(16, 16);
    for (int i = 0; i < 256; ++i) {
      uint8_t* t = flat.at(i % 16, i / 16);
      t[0] = 0, t[1] = 250, t[2] = 0, t[3] = uint8_t(alpha);
    }
    a.materials->edit(1).albedo = build_mip_chain(flat);
    const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
    double err_direct = 0, err_pre = 0, truth_mean = 0;
    for (int64_t y = 0; y < 4; ++y)
      for (int64_t x = 0; x < 4; ++x) {
        const double truth = ground_truth_texel(direct, 5, x + 8, y + 8).g;
        truth_mean += truth / 16;
        err_direct += std::abs(compose_texel_reference(direct, 5, x + 8, y + 8).g - truth);
        err_pre += std::abs(compose_texel_reference(pre, 5, x + 8, y + 8).g - truth);
      }
    // With the mean coverage alone the texel was the blend map's value at it: 0.33 off the
    // truth at A = 200 (all patch or none), as far as direct composition.
    const std::string what = "A " + std::to_string(alpha) + ", W " + std::to_string(wexp) + ", truth " +
                             std::to_string(truth_mean) + ", direct error " + std::to_string(err_direct / 16);
    EXPECT_LT(err_pre / 16, 0.16) << what;
    EXPECT_LT(err_pre, 0.5 * err_direct) << what;
  }
}

// Patches about as large as the footprint (16-texel patches under mip-4 and mip-5 texels): a
// texel holds one to four patch cells, so the truth is those cells' own corner decisions, which
// the expectation over random decisions misses by the size of one patch's share. The layer's
// values at points over the footprint follow them.
TEST(Prefiltered, FollowsTheFootprintsOwnPatchesWhereTheyAreFew) {
  SceneAssets a = dpt_scene(16, 0.5f);
  ImageRGBA8 varied(16, 16);  // A varies (every value once, scattered), as a height map does
  for (int i = 0; i < 256; ++i) {
    uint8_t* t = varied.at(i % 16, i / 16);
    t[0] = 0, t[1] = 250, t[2] = 0, t[3] = uint8_t((i * 97 + 13) % 256);
  }
  a.materials->edit(1).albedo = build_mip_chain(varied);
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  for (const uint32_t mip : {4u, 5u}) {
    double err = 0, spread = 0, truth_mean = 0;
    const int n = 12;
    std::vector<double> truths;
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const double truth = ground_truth_texel(direct, mip, x + 3, y + 5).g;
        truths.push_back(truth);
        truth_mean += truth / (n * n);
        err += std::abs(compose_texel_reference(pre, mip, x + 3, y + 5).g - truth) / (n * n);
      }
    for (double t : truths) spread += std::abs(t - truth_mean) / (n * n);
    // The texels differ (0.1 and more from their mean: the decisions show); the expectation
    // alone is off by about that much, the footprint's own patches by far less.
    EXPECT_GT(spread, 0.08) << "mip " << mip;
    EXPECT_LT(err, 0.3 * spread) << "mip " << mip << ": mean error " << err << ", truth's spread " << spread;
  }
}

// Where the footprint is below one patch the prefiltered texel is the exact (direct) one.
TEST(Prefiltered, IsExactWhereAPatchCoversTheFootprint) {
  auto a = dpt_scene(256, 0.5f);
  for (size_t i = 0; i < 16; ++i) a.weights.data[16 + i] = float(i % 3) / 2.f;
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  for (int64_t y = 0; y < 6; ++y)
    for (int64_t x = 0; x < 6; ++x)  // mip 2: 4 texels against patches of 256 (fade 1)
      EXPECT_EQ(compose_texel_reference(direct, 2, x * 7, y * 5), compose_texel_reference(pre, 2, x * 7, y * 5));
}

// p at and near its ends, P and R over six decades, W at both ends, patches below a texel:
// every texel is finite and in [0, 1], and the layer's share grows with p.
TEST(Prefiltered, ExtremesAreDefinedAndMonotoneInP) {
  for (const double patch : {0.004, 1.0, 64.0})
    for (const double pexp : {1e-3, 1.0, 1e3})
      for (const double rexp : {1e-3, 1.0, 1e3})
        for (const double wexp : {1e-3, 1e3}) {
          double last = -1.0;
          for (const float w : {0.f, 0x1p-24f, 0.25f, 0.5f, 1.f}) {
            const PackedScene pre = pack(dpt_scene(patch, w, pexp, rexp, wexp), prefiltered_options());
            const glm::dvec4 t = compose_texel_reference(pre, 4, 3, 5);
            for (int c = 0; c < 4; ++c) ASSERT_TRUE(std::isfinite(t[c]) && t[c] >= 0.0 && t[c] <= 1.0);
            EXPECT_GE(t.g, last - 1e-12) << "patch " << patch << " P " << pexp << " R " << rexp << " W " << wexp << " p " << w;
            last = t.g;
          }
        }
}

// The meta block's feature statistics chain: every level-l texel holds the feature fraction,
// the mean f of its feature texels and D (feature colour mean - colour mean) of the level-0
// texels under it, to the words' rounding.
TEST(Prefiltered, FeatureChainHoldsEachBlocksFractionAndColourMoment) {
  const SceneAssets a = test::big_feature_scene(0.5f);
  const std::shared_ptr<const MaterialAssets> held = a.materials->get(1).value();
  const MaterialAssets& m = *held;
  const MaterialWords w = pack_material(m);
  const uint32_t res = 64;
  ASSERT_EQ(w.meta.size(), 2 * size_t(gpu::tvt_meta_block_texels(res)));
  const ImageRGBA8& albedo = m.albedo.mips.front();
  for (uint32_t level = 1; (res >> level) >= 1; ++level) {
    const uint32_t rl = res >> level, side = 1u << level;
    for (uint32_t by = 0; by < rl; ++by)
      for (uint32_t bx = 0; bx < rl; ++bx) {
        double features = 0, soft = 0;
        glm::dvec4 all(0.0), inside(0.0);
        for (uint32_t y = by * side; y < (by + 1) * side; ++y)
          for (uint32_t x = bx * side; x < (bx + 1) * side; ++x) {
            const uint8_t* t = albedo.at(int(x), int(y));
            const glm::dvec4 c = glm::dvec4(t[0], t[1], t[2], t[3]) / 255.0;
            all += c;
            if (m.meta->at(int(x), int(y)).d) {
              features += 1, soft += m.meta->at(int(x), int(y)).f / 255.0, inside += c;
            }
          }
        const double n = double(side) * double(side);
        const size_t i = gpu::tvt_meta_chain_offset(res, level) + by * rl + bx;
        const uint32_t w0 = w.meta[2 * i], w1 = w.meta[2 * i + 1];
        const std::string where = "level " + std::to_string(level) + " texel " + std::to_string(bx) + "," + std::to_string(by);
        EXPECT_NEAR((w0 & 0xffffu) / 65535.0, features / n, 0.6 / 65535) << where;
        EXPECT_NEAR((w0 >> 16) / 65535.0, features > 0 ? soft / features : 0.0, 0.6 / 65535) << where;
        for (int c = 0; c < 4; ++c) {
          const double moment = (inside[c] - features / n * all[c]) / n;
          EXPECT_NEAR(double(int8_t(uint8_t(w1 >> (8 * c)))) / 127.0 / gpu::TVT_META_MOMENT_SCALE, moment, 0.6 / 508) << where;
        }
      }
  }
}

// A material's words: every level's texels where the layout says, each level >= 1 followed by
// A's spread chain (per texel, A within the level-0 texels under it split at their mean: the
// lower piece's share, the standard deviation of the pieces' means, each piece's half-width
// sqrt(3 var), to the unorm8 rounding), then the statistics block, and nothing after it.
TEST(Prefiltered, SpreadChainHoldsEachBlocksTwoPiecesOfA) {
  // A rough left half (hashed A) and a smooth right half (a gentle ramp): the local spread
  // differs several-fold, which the texture's pooled variance cannot tell apart.
  ImageRGBA8 albedo(64, 64);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {
      uint8_t* t = albedo.at(x, y);
      const uint32_t h = gpu::tvt_hash_coord(x, y, 7u);
      t[0] = uint8_t(h), t[1] = uint8_t(h >> 8), t[2] = uint8_t(x * 4);
      t[3] = x < 32 ? uint8_t(h >> 16) : uint8_t(100 + y);
    }
  MaterialAssets m;
  m.albedo = build_mip_chain(albedo);
  const MaterialWords w = pack_material(m);
  const uint32_t res = 64, levels = 7;
  ASSERT_EQ(w.mip_count, int(levels));
  ASSERT_EQ(w.texels.size(), size_t(gpu::tvt_material_stats_offset(res, levels)) + size_t(gpu::TVT_MATERIAL_STATS_WORDS));
  double largest = 0.0, smallest = 1.0;
  for (uint32_t level = 0; level < levels; ++level) {
    const uint32_t rl = res >> level, side = 1u << level;
    const ImageRGBA8& mip = m.albedo.mips[level];
    const uint32_t first = gpu::tvt_material_level_offset(res, level);
    for (uint32_t i = 0; i < rl * rl; ++i) {
      const uint8_t* t = &mip.texels[4 * size_t(i)];
      ASSERT_EQ(w.texels[first + i], uint32_t(t[0]) | uint32_t(t[1]) << 8 | uint32_t(t[2]) << 16 | uint32_t(t[3]) << 24)
          << "level " << level << " texel " << i;
    }
    if (level == 0) continue;
    ASSERT_EQ(gpu::tvt_material_spread_offset(res, level), first + rl * rl);
    const uint32_t next = level + 1 < levels ? gpu::tvt_material_level_offset(res, level + 1)
                                             : gpu::tvt_material_stats_offset(res, levels);
    ASSERT_EQ(next - gpu::tvt_material_spread_offset(res, level), rl * rl) << "level " << level;
    for (uint32_t by = 0; by < rl; ++by)
      for (uint32_t bx = 0; bx < rl; ++bx) {
        std::vector<double> a;
        double mean = 0;
        for (uint32_t y = by * side; y < (by + 1) * side; ++y)
          for (uint32_t x = bx * side; x < (bx + 1) * side; ++x) a.push_back(albedo.at(int(x), int(y))[3] / 255.0);
        for (double v : a) mean += v / double(a.size());
        double n[2] = {0, 0}, sum[2] = {0, 0}, squares[2] = {0, 0};
        for (double v : a) {
          const int k = v < mean ? 0 : 1;
          n[k] += 1, sum[k] += v, squares[k] += v * v;
        }
        double piece_mean[2], half[2];
        for (int k = 0; k < 2; ++k) {
          piece_mean[k] = n[k] > 0 ? sum[k] / n[k] : 0.0;
          half[k] = n[k] > 0 ? std::sqrt(std::max(0.0, 3.0 * (squares[k] / n[k] - piece_mean[k] * piece_mean[k]))) : 0.0;
        }
        const double p = n[0] / double(a.size());
        const double delta = n[0] > 0 && n[1] > 0 ? std::sqrt(p * (1 - p)) * (piece_mean[1] - piece_mean[0]) : 0.0;
        // The pieces keep A's variance: delta^2 + the pieces' own variances.
        double var = 0;
        for (double v : a) var += (v - mean) * (v - mean) / double(a.size());
        EXPECT_NEAR(delta * delta + p * half[0] * half[0] / 3 + (1 - p) * half[1] * half[1] / 3, var, 1e-9);
        const uint32_t word = w.texels[gpu::tvt_material_spread_offset(res, level) + by * rl + bx];
        const std::string where = "level " + std::to_string(level) + " texel " + std::to_string(bx) + "," + std::to_string(by);
        const double s = gpu::TVT_SPREAD_SCALE, q = 0.501 / 255;  // half a step (ties either way)
        EXPECT_NEAR((word & 0xffu) / 255.0, p, q) << where;
        EXPECT_NEAR(((word >> 8) & 0xffu) / 255.0 / s, delta, q / s) << where;
        EXPECT_NEAR(((word >> 16) & 0xffu) / 255.0 / s, half[0], q / s) << where;
        EXPECT_NEAR((word >> 24) / 255.0 / s, half[1], q / s) << where;
        if (level == 3) largest = std::max(largest, std::sqrt(var)), smallest = std::min(smallest, std::sqrt(var));
      }
  }
  EXPECT_GT(largest, 0.2);  // the rough half
  EXPECT_LT(smallest, 0.05);  // the smooth half: a local spread several-fold smaller
}

// Features larger than the footprint in expectation (the statistics block says the typical
// feature is far smaller, as where features vary in size; mip 2 is still at points, mips 3 and
// 4 in expectation): the prefiltered texel follows what its footprint holds (this feature's
// decision, the local feature fraction and colour), not the texture's mean feature fraction,
// so it lands near the box filter of level 0 inside features, on the ground between them and
// across their edges.
TEST(Prefiltered, FeaturesFollowWhatTheFootprintHolds) {
  const SceneAssets a = test::big_feature_scene(0.5f, 40);  // the expectation from LOD 2.63
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  for (const uint32_t mip : {2u, 3u, 4u}) {
    double err = 0, worst = 0, lowest = 1, highest = 0;
    const int64_t n = 32, step = std::max<int64_t>(1, (int64_t(1) << (10 - mip)) / n);  // texels over the VT
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const glm::dvec4 truth = ground_truth_texel(direct, mip, x * step + 1, y * step + 1);
        const glm::dvec4 got = compose_texel_reference(pre, mip, x * step + 1, y * step + 1);
        for (int c = 0; c < 3; ++c) {
          err += std::abs(got[c] - truth[c]) / (3 * n * n);
          worst = std::max(worst, std::abs(got[c] - truth[c]));
        }
        lowest = std::min(lowest, truth.g), highest = std::max(highest, truth.g);
      }
    EXPECT_LT(err, 0.01) << "mip " << mip;
    EXPECT_LT(worst, 0.2) << "mip " << mip;
    EXPECT_GT(highest - lowest, 0.3) << "mip " << mip;  // the truth is far from uniform: features decide
  }
}

// Algorithm 1's chipped holes in the feature expectation: the statistics block holds the
// variation map's distribution, and a prefiltered texel past the points takes the chipped share
// of each visible feature as ground, darkened, as level 0 does texel by texel.
TEST(Prefiltered, ChippedHolesAreInTheFeatureExpectation) {
  SceneAssets a = test::big_feature_scene(0.5f, 40);  // the expectation from LOD 2.63
  {
    MetaTexture& meta = a.materials->edit(1).meta.value();
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x)  // fine-grained noise, as a variation map is
        meta.texels[size_t(y) * 64 + size_t(x)].variation = uint8_t(gpu::tvt_hash_coord(x, y, 11u) & 0xffu);
  }
  const std::shared_ptr<const MaterialAssets> held = a.materials->get(1).value();
  const MaterialWords words = pack_material(*held);
  const size_t stats = gpu::tvt_material_stats_offset(64, uint32_t(words.mip_count));
  for (int i = 0; i <= gpu::TVT_STATS_VARIATION_STEPS; ++i) {
    size_t below = 0;
    for (const MetaTexel& t : held->meta->texels) below += double(t.variation) / 255.0 < double(i) / 16.0 ? 1 : 0;
    EXPECT_FLOAT_EQ(std::bit_cast<float>(words.texels[stats + size_t(gpu::TVT_STATS_VARIATION_CDF + i)]),
                    float(double(below) / 4096.0)) << i;
  }
  // A visible feature shows fully (cm = 4) and its chipped texels not at all (cn = 0), and
  // the threshold chips 0.6 of them where p < 1 (everywhere here).
  a.desc.materials[1].fbpb.variation_threshold = 0.6;
  a.desc.materials[1].fbpb.cm = 4.0;
  a.desc.materials[1].fbpb.cn = 0.0;
  // Level 0 before the FBPB fade (fade0 = 1), and half-way through it (fade0 = 0.5: level 0
  // blends half the plain weight, in the chipped texels' darkened colour as well; darker holes
  // there, Cc = 0.25, so that this share matters).
  for (const double fade_lo : {0.0, -0.5}) {
    a.desc.materials[1].fbpb.fade_lod_lo = fade_lo;
    a.desc.materials[1].fbpb.fade_lod_hi = fade_lo + 1.0;
    a.desc.materials[1].fbpb.colour_coeff = fade_lo == 0.0 ? 0.75 : 0.25;
    SceneAssets unchipped = a;
    unchipped.desc.materials[1].fbpb.variation_threshold = 0.0;
    const PackedScene direct = pack(a), pre = pack(a, prefiltered_options()), plain_truth = pack(unchipped);
    for (const uint32_t mip : {3u, 4u}) {  // in expectation (LOD 2.63 on)
      double err = 0, chipping = 0;
      const int64_t n = 24, step = (int64_t(1) << (10 - mip)) / n;
      for (int64_t y = 0; y < n; ++y)
        for (int64_t x = 0; x < n; ++x) {
          const glm::dvec4 truth = ground_truth_texel(direct, mip, x * step + 1, y * step + 1);
          const glm::dvec4 got = compose_texel_reference(pre, mip, x * step + 1, y * step + 1);
          const glm::dvec4 whole = ground_truth_texel(plain_truth, mip, x * step + 1, y * step + 1);
          for (int c = 0; c < 3; ++c) {
            err += std::abs(got[c] - truth[c]) / (3 * n * n);
            chipping += std::abs(whole[c] - truth[c]) / (3 * n * n);
          }
        }
      // The holes change the truth (half as much where level 0 blends half the plain weight).
      EXPECT_GT(chipping, fade_lo == 0.0 ? 0.04 : 0.015) << "fade from LOD " << fade_lo << ", mip " << mip;
      // And the expectation follows them: 0.11-0.12 of their effect either way. Half-way through
      // the fade, with the plain share of the chipped texels left undarkened, it was 0.22.
      EXPECT_LT(err, 0.16 * chipping) << "fade from LOD " << fade_lo << ", mip " << mip;
    }
  }
}

namespace {

// A grid of n x n texels of a mip: (x * sx.first + sx.second, y * sy.first + sy.second).
struct TexelGrid {
  int64_t n;
  std::pair<int64_t, int64_t> sx, sy;
};

// The box filter of `direct`'s level 0 and `composed`'s texel at each texel of the grid, in
// order; `visit` returns false to stop.
template <class Visit>
void against_box_filter(const PackedScene& direct, const PackedScene& composed, uint32_t mip, const TexelGrid& g, Visit visit) {
  for (int64_t y = 0; y < g.n; ++y)
    for (int64_t x = 0; x < g.n; ++x) {
      const int64_t tx = x * g.sx.first + g.sx.second, ty = y * g.sy.first + g.sy.second;
      if (!visit(tx, ty, ground_truth_texel(direct, mip, tx, ty), compose_texel_reference(composed, mip, tx, ty))) return;
    }
}

// Asserts that the prefiltered mip-`mip` texels of the grid are the box filter of level 0 (to
// 1e-9), and returns how many of them a point sample gets wrong (their level-0 texels not all
// alike: an edge or a hole inside the footprint); -1 at the first texel that is not.
int box_filter_texels(const PackedScene& direct, const PackedScene& pre, uint32_t mip, int64_t n,
                      std::pair<int64_t, int64_t> sx, std::pair<int64_t, int64_t> sy) {
  int edges = 0;
  against_box_filter(direct, pre, mip, {n, sx, sy}, [&](int64_t tx, int64_t ty, const glm::dvec4& truth, const glm::dvec4& got) {
    for (int c = 0; c < 4; ++c)
      if (!(std::abs(got[c] - truth[c]) <= 1e-9)) {
        ADD_FAILURE() << "mip " << mip << " texel " << tx << " " << ty << " channel " << c << ": " << got[c]
                      << " against the box filter's " << truth[c];
        edges = -1;
        return false;
      }
    const glm::dvec4 centre = compose_texel_reference(direct, mip, tx, ty);
    edges += std::abs(centre.g - truth.g) > 0.05 ? 1 : 0;
    return true;
  });
  return edges;
}

// Mean absolute error over r, g, b of `composed` against the box filter of `direct`'s level 0
// at mip `mip`, over the grid.
double box_filter_error(const PackedScene& direct, const PackedScene& composed, uint32_t mip, int64_t n,
                        std::pair<int64_t, int64_t> sx, std::pair<int64_t, int64_t> sy) {
  double err = 0;
  against_box_filter(direct, composed, mip, {n, sx, sy}, [&](int64_t, int64_t, const glm::dvec4& truth, const glm::dvec4& got) {
    for (int c = 0; c < 3; ++c) err += std::abs(got[c] - truth[c]);
    return true;
  });
  return err / double(3 * n * n);
}

}  // namespace

// Where the features are exact at points (a footprint no wider than a feature), each point
// stands for a quarter of the footprint with the texture one LOD finer. At mip 1 the points
// are the four level-0 texel centres and the texture is level 0's, so over a uniform base and
// a constant weight the prefiltered texel is the box filter of level 0 itself: stone edges,
// chipped holes and each stone's own decision included. At mip 2 it stays close.
TEST(Prefiltered, FeaturesAtPointsAreTheBoxFilterOfLevel0AtMip1) {
  const SceneAssets a = test::big_feature_scene(0.5f);
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  EXPECT_GT(box_filter_texels(direct, pre, 1, 64, {7, 3}, {5, 1}), 20);  // the box filter differs from a point sample on many of them
  EXPECT_LT(box_filter_error(direct, pre, 2, 32, {7, 1}, {3, 2}), 0.01);
}

// The same with level 0 half-way through the FBPB fade (fade0 = 0.5): level 0 blends each
// texel with half its feature weight and half the plain blend map, in the texel's own colour,
// darkened in a chipped hole; the points' plain share takes each point's colour, so the
// prefiltered texel at mip 1 is still the box filter of level 0 (A is uniform here, so the
// plain blend map is the same at every texel).
TEST(Prefiltered, FeaturesAtPointsFollowLevel0HalfWayThroughTheFade) {
  SceneAssets a = test::big_feature_scene(0.5f);
  a.desc.materials[1].fbpb.fade_lod_lo = -0.5;
  a.desc.materials[1].fbpb.fade_lod_hi = 0.5;
  // Chipped holes: fine-grained variation, a third of each visible feature's texels chipped,
  // shown as ground (cn = 0) in half their colour.
  MetaTexture& meta = a.materials->edit(1).meta.value();
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) meta.texels[size_t(y) * 64 + size_t(x)].variation = uint8_t(gpu::tvt_hash_coord(x, y, 5u) & 0xffu);
  a.desc.materials[1].fbpb.variation_threshold = 0.33;
  a.desc.materials[1].fbpb.cn = 0.0;
  a.desc.materials[1].fbpb.colour_coeff = 0.5;
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  EXPECT_GT(box_filter_texels(direct, pre, 1, 64, {7, 3}, {5, 1}), 20);
}

// Features smaller than the footprint under FBPB+DPT (tvt_feature_points: the material LOD
// above the log2 feature size less 1.5, and at least 2), on a footprint under 8 texels wide:
// 4 x 4 points. At mip 2 they are the sixteen level-0 texel centres with level 0's texture, so the prefiltered texel is again the
// box filter of level 0, every small stone's own decision included; with 2 x 2 points it would
// not be. The DPT layer has no patches (p = 0), so the ground's value is 0 at level 0 and in
// the footprint alike.
TEST(Prefiltered, SmallFeaturesTakeFourByFourPointsExactAtMip2) {
  const SceneAssets a = test::small_stone_scene(0.0f, 1.0f);  // at points up to LOD 2.57
  const PackedScene direct = pack(a), pre = pack(a, prefiltered_options());
  EXPECT_EQ(gpu::tvt_feature_points(2.0f, float(0.5 * std::log2(25.0)), true), 4);
  EXPECT_GT(box_filter_texels(direct, pre, 2, 48, {5, 3}, {3, 1}), 100);  // stone edges and stones of their own decision inside most footprints
}

// The same stones at mip 3, an 8-texel footprint, with the statistics block told they are 10
// texels wide (so that they stay at points there): 3 x 3 points, each reading the texture two
// LODs finer (level 1). They are no longer the box filter (a point stands for 8/3 texels), but
// against it they are far closer than a point sample, and than 2 x 2 points over the same
// stones (the block told the stones are 40 texels wide, so that k = 2): two points 4 texels
// apart a side fall both on stones or both between them across an 8-texel period, where three
// see its share. At mip 2 (a 4-texel footprint) three points a side would read 3 of its 4
// texel columns and miss one: hence 4 x 4 there (the test above). And the stones as they are,
// 5 texels wide, take the expectation at mip 3 (LOD 3 past 2.32 + TVT_FEATURE_POINTS_REL),
// closer to the box filter still: past a feature a footprint, points place the features'
// edges worse than the expectation places their share.
TEST(Prefiltered, SmallFeaturesTakeThreeByThreePointsAtMip3) {
  const float small = float(0.5 * std::log2(25.0)), large = float(0.5 * std::log2(25.0 * 64));
  EXPECT_EQ(gpu::tvt_feature_points(3.0f, small, true), 3);
  EXPECT_EQ(gpu::tvt_feature_points(2.99f, small, true), 4);  // under 8 texels
  EXPECT_EQ(gpu::tvt_feature_points(1.99f, small, true), 2);  // under 4 texels
  EXPECT_EQ(gpu::tvt_feature_points(3.0f, small, false), 2);  // FBPB alone
  EXPECT_EQ(gpu::tvt_feature_points(3.0f, large, true), 2);   // 3 < log2 40 - 1.5 = 3.82
  EXPECT_EQ(gpu::tvt_feature_point_lods(2), 1);
  EXPECT_EQ(gpu::tvt_feature_point_lods(3), 2);
  EXPECT_EQ(gpu::tvt_feature_point_lods(4), 2);
  // Mean absolute error over r, g, b at mip 3 against the box filter of level 0.
  const auto error = [](const PackedScene& direct, const PackedScene& composed) {
    return box_filter_error(direct, composed, 3, 40, {5, 3}, {3, 1});
  };
  const SceneAssets actual = test::small_stone_scene(1.0f, 2.0f);
  const SceneAssets three = test::small_stone_scene(1.0f, 2.0f, 16), two = test::small_stone_scene(1.0f, 2.0f, 1);
  const PackedScene direct = pack(actual);  // level 0 does not read the statistics
  const double e_direct = error(direct, direct), e3 = error(direct, pack(three, prefiltered_options()));
  const double e2 = error(direct, pack(two, prefiltered_options()));
  const double e_expect = error(direct, pack(actual, prefiltered_options()));
  EXPECT_LT(e3, 0.5 * e_direct) << e3 << " " << e_direct;  // 0.071 against 0.203
  EXPECT_LT(e3, 0.5 * e2) << e3 << " " << e2;              // against 0.210
  EXPECT_LT(e_expect, 0.6 * e3) << e_expect << " " << e3;  // 0.036
}

// The points' half spacing is footprint / 2k rounded to the nearest fixed-point unit, worked out
// without a division by a variable (k = 3: a halving, then a division by the constant 3), for
// every k tvt_feature_points() returns, footprints from 1/256 of a texel to 2^39 texels.
TEST(Prefiltered, FeaturePointHalfStepIsTheRoundedQuotient) {
  std::vector<int64_t> footprints;
  for (int64_t f = 1; f < 5000; ++f) footprints.push_back(f);
  for (int e = 12; e < 48; ++e)
    for (int64_t d = -7; d <= 7; ++d) footprints.push_back((int64_t(1) << e) + d);
  for (const int k : {2, 3, 4})
    for (const int64_t f : footprints) {
      const int64_t h = gpu::tvt_feature_point_half_step(f, k);
      ASSERT_EQ(h, (f + k) / (2 * k)) << "footprint " << f << " k " << k;
      ASSERT_LE(std::abs(2 * k * h - f), k) << "footprint " << f << " k " << k;  // nearest
    }
}
