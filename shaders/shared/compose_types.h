// GPU-visible composition parameters (std430), shared by compose.comp and the C++ host.
// Units: *_fp values are level-0 VT texels in 1/256 fixed point (docs/composition.md).
#ifndef TVT_SHARED_COMPOSE_TYPES_H
#define TVT_SHARED_COMPOSE_TYPES_H
#include "bridge.h"

TVT_BEGIN

TVT_CONST int TVT_MAX_MATERIALS = 16;
TVT_CONST int TVT_MAX_DPT_LAYERS = 4;
TVT_CONST int TVT_FIXED_BITS = 8;  // positions and sizes carry 8 fractional bits
TVT_CONST uint TVT_NO_META = 0xffffffffu;

// Transition modes (per material; a method override replaces them for all but the base).
TVT_CONST int TVT_MODE_LINEAR = 0;    // Bloom splatting, boosted normalisation
TVT_CONST int TVT_MODE_BLENDMAP = 1;  // Hardy & McRoberts blend maps
TVT_CONST int TVT_MODE_FBPB = 2;      // Feature-Based Probabilistic Blending
TVT_CONST int TVT_MODE_DPT = 3;       // Dynamic Patch Transitions
TVT_CONST int TVT_MODE_FBPB_DPT = 4;  // FBPB features over a DPT-shaped non-feature blend

// Specialization constants of the composition (compose_sample.glsl), set by the GPU composer
// per scene and per batch so that a pipeline carries only the paths its pages can take (some
// devices, lavapipe among them, execute both sides of every branch). Includers that do not
// set them (the direct-splat pass) keep every path. Ids clear of the terrain passes' own.
// Bit m set: some material n >= 1 has mode m (TVT_MODE_*).
#define TVT_COMPOSE_SPEC_MODES 16
// Some material has hex-tiling (hex_edge > 0).
#define TVT_COMPOSE_SPEC_HEX 17
// Mips >= 1 of the prefiltered strategy may be composed (false: every sample is direct).
#define TVT_COMPOSE_SPEC_PREFILTERED 18
// Which parts a page of this mip can reach (TVT_PART_* bits; the composer works them out per
// mip from the parameters, conservatively: a cleared bit is a part whose weight is zero for
// every material at that footprint, or a general path the scene never needs). Direct pages
// use TVT_PART_DPT_CORNERS_WIDE alone.
#define TVT_COMPOSE_SPEC_PARTS 19
// Every position a DPT layer or hex-tiling divides fits their 32-bit paths (V <= 2^21, patches
// and hex tiles of fewer than 2^22 texels; the composer checks the scene): the 64-bit
// divisions they otherwise keep for far terrain are left out.
#define TVT_COMPOSE_SPEC_SMALL 20
// Every page of the dispatch is a prefiltered one (a mip >= 1 under the prefiltered strategy;
// implies TVT_COMPOSE_SPEC_PREFILTERED): the direct paths, which such a page never takes but a
// device that runs both sides of a branch would pay for, are left out.
#define TVT_COMPOSE_SPEC_ONLY_PREFILTERED 21
// The DPT layers whose samples (TVT_PART_DPT_SAMPLES) a prefiltered page of this mip can
// reach, when they are few and their lattices narrow: up to TVT_SAMPLE_PAIRS_MAX (material,
// layer) pairs, composed once per texel before the material loop, each with its own material
// and layer as constants (tvt_sample_pairs_*), instead of inside the loop for every material
// and layer; the composer then clears TVT_PART_DPT_SAMPLES. 0: none. (Each pair is a copy of
// the samples' code, which a CPU driver compiles at length: hence few.)
#define TVT_COMPOSE_SPEC_SAMPLE_PAIRS 22
TVT_CONST int TVT_SAMPLE_PAIRS_MAX = 2;
TVT_FN uint tvt_sample_pairs_count(uint pairs) { return pairs & 7u; }
TVT_FN int tvt_sample_pairs_material(uint pairs, int i) { return int((pairs >> uint(3 + 6 * i)) & 15u); }
TVT_FN int tvt_sample_pairs_layer(uint pairs, int i) { return int((pairs >> uint(7 + 6 * i)) & 3u); }
TVT_FN uint tvt_sample_pairs_add(uint pairs, int material, int layer) {
  const uint i = pairs & 7u;
  return (pairs & ~7u) + (i + 1u) + ((uint(material) & 15u) << (3u + 6u * i)) + ((uint(layer) & 3u) << (7u + 6u * i));
}
TVT_CONST uint TVT_PART_DPT_POINT = 1u;        // a DPT layer's point value (exact share > 0)
TVT_CONST uint TVT_PART_DPT_EXPECT = 2u;       // a DPT layer's expectation (exact share < 1)
TVT_CONST uint TVT_PART_DPT_SAMPLES = 4u;      // ... from samples (fewer than _HI patches a side)
TVT_CONST uint TVT_PART_FEATURES = 8u;         // FBPB's exact features (fade > 0)
TVT_CONST uint TVT_PART_FEATURE_EXPECT = 16u;  // FBPB's features in expectation (fade0 > 0)
// ... samples whose corner lattice may span a weight texel or more a side (else its corners'
// weights come from 3 x 3 weight texels fetched once per lattice).
TVT_CONST uint TVT_PART_DPT_SAMPLES_WIDE = 32u;
// Some DPT layer's patch may be a weight texel wide or more (else a patch cell's four corners
// read their weights from 3 x 3 weight texels fetched once). Direct pages as well: the
// composer clears it in its direct variant too.
TVT_CONST uint TVT_PART_DPT_CORNERS_WIDE = 64u;
// Some FBPB feature centroid that a prefiltered texel's points reach may lie half a weight
// texel or more from the footprint's centre (else the points' centroid weights come from 3 x 3
// weight texels fetched once per texel). Direct pages keep it: one point, one fetch.
TVT_CONST uint TVT_PART_FEATURE_WEIGHTS_WIDE = 128u;
TVT_CONST uint TVT_PART_ALL = 255u;

// A material's texel words (texel_offset): its mip chain, level l = 0 .. log2 R of
// (R >> l)^2 RGBA8 texels, each level l >= 1 followed by its spread chain, then the statistics
// block. The spread chain of level l holds one word per level-l texel describing A within the
// 2^l x 2^l level-0 texels under it as two pieces, the texels below the block's mean A and the
// others: byte 0 the share p of the lower piece, byte 1 the standard deviation delta of the
// two-point distribution of the pieces' means (the lower at mean - delta sqrt((1-p)/p), the
// upper at mean + delta sqrt(p/(1-p))), bytes 2 and 3 each piece's half-width sqrt(3 var)
// (its texels' spread about the piece's mean); unorm8, delta and the half-widths of
// TVT_SPREAD_SCALE times the value (each is at most 1/2). Read by the prefiltered strategy:
// A's distribution within what a footprint covers, rather than the texture's mean spread.
TVT_CONST float TVT_SPREAD_SCALE = 2.0;
// Words before level `level` (its first texel), relative to texel_offset: the closed forms of
// sum_{j<l} (R >> j)^2 = (R^2 - r^2) * 4/3 and of the spread words sum_{1<=j<l} (R >> j)^2.
TVT_FN uint tvt_material_level_offset(uint res, uint level) {
  if (level == 0u) return 0u;
  const uint rl = res >> level;
  return (res * res - rl * rl) / 3u * 4u + (res * res / 4u - rl * rl) / 3u * 4u;
}
// First word of level `level`'s spread chain (level >= 1), relative to texel_offset.
TVT_FN uint tvt_material_spread_offset(uint res, uint level) {
  const uint rl = res >> level;
  return tvt_material_level_offset(res, level) + rl * rl;
}
// First word of the statistics block, relative to texel_offset: after the 1x1 level and its
// one spread word (a 1x1 material has neither chain nor spread).
TVT_FN uint tvt_material_stats_offset(uint res, uint levels) {
  return levels <= 1u ? res * res : tvt_material_level_offset(res, levels - 1u) + 2u;
}

// Each material's texel words end with its statistics block, after the 1x1 mip: float bits,
// four words per level l < 15 (the mean over level-l texels of the variance of A within the
// level-0 texels under the texel, and of the covariances of A with R, G and B), then log2 of the
// FBPB features' mean size in material texels (the side of their mean area; 0 without
// features), then the distribution of the variation map (Algorithm 1): word
// TVT_STATS_VARIATION_CDF + i is the share of the meta-texture's texels whose variation is
// below i / TVT_STATS_VARIATION_STEPS, i = 0 .. TVT_STATS_VARIATION_STEPS (zeros without a
// meta-texture): the share of a visible feature's texels that a threshold chips, since each
// feature reads the map at its own random offset (docs/composition.md, "Prefiltered mips").
TVT_CONST int TVT_MATERIAL_STATS_WORDS = 78;
TVT_CONST int TVT_STATS_FEATURE_LOG2_SIZE = 60;
TVT_CONST int TVT_STATS_VARIATION_CDF = 61;
TVT_CONST int TVT_STATS_VARIATION_STEPS = 16;

// A material's meta block (meta_offset, two words a texel): its R x R level-0 meta texels, then
// its feature statistics chain, levels 1 .. log2 R of (R >> l)^2 texels each, level l's texel
// summing the 2^l x 2^l level-0 texels under it: word 0 the feature fraction D (low 16 bits) and
// the mean f over its feature texels (high 16 bits), unorm; word 1 the feature colour moment
// D * (mean feature colour - mean colour), RGBA snorm8 of TVT_META_MOMENT_SCALE times it (the
// moment is at most 1/4 in size). Read by the prefiltered strategy's FBPB expectation.
TVT_CONST float TVT_META_MOMENT_SCALE = 4.0;
TVT_FN uint tvt_meta_block_texels(uint res) { return (4u * res * res - 1u) / 3u; }
// First texel of chain level `level` >= 1, relative to meta_offset.
TVT_FN uint tvt_meta_chain_offset(uint res, uint level) {
  const uint above = res >> (level - 1u);
  return res * res + (res * res - above * above) / 3u;
}

// Prefiltered DPT: where a layer's patches are few in a footprint (footprint / patch size below
// TVT_PATCH_SAMPLES_HI), its share in expectation takes the mean and variance of the layer's
// actual values at k x k points spread evenly over the footprint (k = 2 while a patch spans it,
// else 3), faded to the expectation between TVT_PATCH_SAMPLES_LO and _HI patches a side.
TVT_CONST float TVT_PATCH_SAMPLES_LO = 4.0;
TVT_CONST float TVT_PATCH_SAMPLES_HI = 8.0;
// Prefiltered FBPB: the features stay exact, at k x k points of the footprint, while the
// footprint is no wider than the typical feature and a little more: the material LOD below the
// statistics block's log2 feature size + TVT_FEATURE_POINTS_REL (2^0.25 = 1.19 features a side);
// coarser, they take their expectation. Past a feature a footprint, a handful of points places
// the features' edges worse than the expectation places their share, and before that the
// expectation misses how few features a footprint holds (docs/composition.md, "FBPB features
// at points"). A switch, not a ramp: in between a page would pay for both. Host and shaders
// evaluate it in the same float arithmetic (tvt_feature_points_hold), so the host knows which
// of the two a prefiltered mip takes.
TVT_CONST float TVT_FEATURE_POINTS_REL = 0.25;  // exact in binary: the host and GLSL constants agree
TVT_FN bool tvt_feature_points_hold(float lod, float feature_log2_size) {
  return lod < feature_log2_size + TVT_FEATURE_POINTS_REL;
}
// k: 2, or under FBPB+DPT (`with_dpt`) 3 where the footprint is wider than about a third of
// the typical feature (material LOD above the statistics block's log2 feature size less
// TVT_FEATURE_POINTS_FINER_LODS, 2^-1.5 = 0.35) and spans 4 material texels or more: a point
// stands for its cell of the footprint, so the cells must be small against a feature for the
// features' edges to fall at the right share of them. How much a misplaced edge costs is the
// step in w across it: under FBPB+DPT the ground takes DPT's patch value, 0 or 1 away from
// the patches' edges, against a feature's min(cm max(p, f), 1); under FBPB alone it takes the
// plain weight p, a smaller step, and 2 x 2 points keep the error within the budget at half
// the cost. 3 x 3 rather than 4 x 4: within 1 dB of it at 9/16 of the points, and the same
// budget lets the finer grid start half a LOD earlier. Under 8 texels (LOD < 3) 4 x 4
// instead: three points a side of a 4-texel footprint read 3 of its 4 texel columns, where
// four are its texel centres (docs/composition.md, "FBPB features at points").
TVT_CONST float TVT_FEATURE_POINTS_FINER_LODS = 1.5;
TVT_FN int tvt_feature_points(float lod, float feature_log2_size, bool with_dpt) {
  if (!(with_dpt && lod >= 2.0 && lod > feature_log2_size - TVT_FEATURE_POINTS_FINER_LODS)) return 2;
  return lod < 3.0 ? 4 : 3;
}

// How many LODs finer than the footprint's the k x k points read the texture: the coarsest
// whole step whose texels are no wider than a point's cell (footprint / k), 1 for k = 2 and
// 2 for k = 3 and 4 (the material's levels are a whole LOD apart, so a whole step reads one level
// wherever the footprint's LOD is whole).
TVT_FN int tvt_feature_point_lods(int k) { return k > 2 ? 2 : 1; }

// Half the points' spacing, footprint / 2k, in fixed point (footprint_fp: the footprint in
// level-0 texels * 2^TVT_FIXED_BITS), rounded to the nearest; the points sit at its odd
// multiples from the footprint's centre, one at the centre of each of the k x k cells. For the
// k that tvt_feature_points() returns the quotient needs no division by a variable (a software
// loop for 64-bit integers on GPUs): a shift for 2k = 4 and 8, a halving and a division by the
// constant 3 (a multiply-high) for 2k = 6; floor(floor(x / 2) / 3) = floor(x / 6) for x >= 0.
TVT_FN int64_t tvt_feature_point_half_step(int64_t footprint_fp, int k) {
  const int64_t num = footprint_fp + int64_t(k);
  return k == 3 ? (num >> 1) / int64_t(3) : num >> (k == 2 ? 2 : 3);
}

TVT_CONST int TVT_COMPOSE_GROUP = 16;  // compute workgroup edge (texels); lavapipe pays ~16 us per group

struct TvtDptLayer {      // 56 bytes
  int64_t patch_fp;       // patch edge S_k, level-0 texels * 256
  float exp_p;            // P_k (eq 4.1)
  float exp_r;            // R_k (eq 4.2)
  float exp_w;            // W_k (eq 4.3)
  float height_h;         // H_k (Algorithm 3)
  uint salt;              // hash salt of (scene seed, material, layer)
  float patch_texels;     // S_k as float, for the minification fade only
  // Prefiltered strategy: E[bilerp(m)^W] over a patch cell whose four corner masks are
  // independent with P(m = 1) = q is q^4 + sum_i expect[i] q^(i+1) (1 - q)^(3-i), i = 0, 1, 2
  // (docs/composition.md, "Prefiltered mips").
  float expect[3];
  // ... and E[bilerp(m)^(2W)], the same polynomial with these coefficients: with expect, the
  // variance of the layer's value over many patch cells.
  float expect_sq[3];
};

struct TvtMaterial {      // 352 bytes
  int64_t period_fp;      // tiling period T_n: level-0 texels per repeat * 256
  uint texel_offset;      // first texel of mip 0 in the material texel buffer (RGBA8 words)
  uint meta_offset;       // first texel in the meta buffer (uvec2 each), or TVT_NO_META
  int resolution;         // R_n: material texels per side (power of two)
  int log2_resolution;
  int mip_count;          // log2_resolution + 1
  int mode;               // TVT_MODE_*
  int weight_layer;       // layer of the weight grid holding this material's weight
  int dpt_layer_count;
  uint fbpb_salt;
  uint variation_salt;
  float cm, cf, cn;       // FBPB eq 3.1 constants
  float variation_threshold;
  float colour_coeff;     // Cc, Algorithm 1
  float blend_sharpness;  // s of BlendMap, (0, 0.5]
  float dpt_fade_lo;      // DPT layer fully faded below this many texels per patch
  float dpt_fade_hi;      // ... and fully present above this many
  float fbpb_fade_lo;     // FBPB fades to blend map between these material LODs
  float fbpb_fade_hi;
  // Material LOD at a footprint of one level-0 texel, log2(R_n * 256 / period_fp): the LOD at
  // a power-of-two footprint 2^k is k + lod_bias, one correctly rounded add that the host
  // repeats to decide which prefiltered parts a mip reaches.
  float lod_bias;
  float pad1;
  // Hex-tiling (anti-repetition, docs/composition.md): 0 = off; else the triangle lattice's
  // edge L (even) and row height H = round(L sqrt(3) / 2), in material texels.
  int hex_edge;
  int hex_row;
  uint hex_salt;          // per-vertex tile offset hash salt
  float hex_sharpness;    // gamma: barycentric weights raised to this power
  float hex_preserve;     // 0: linear blend of the tiles; 1: variance-preserving about the mean
  float hex_cut;          // normalised weights below this are dropped (their fetch skipped)
  float pad2, pad3;
  TvtDptLayer dpt[TVT_MAX_DPT_LAYERS];
};

struct TvtComposeParams {
  int log2_vt;            // V = 2^log2_vt level-0 texels per side
  int page_texels;        // P
  int border_texels;      // B
  int material_count;
  int weight_width;       // weight grid covering the whole terrain
  int weight_height;
  int weight_layers;
  int method_override;    // -1: per-material modes; else TVT_MODE_* for every material n >= 1
  int dpt_layer_limit;    // 0: all layers; else at most this many DPT layers
  int supersample;        // s: s*s sub-samples per texel (1 = direct)
  float linear_boost;     // Bloom: normalised weights sum to this, then clamped (>= 1)
  int pattern;            // TVT_COMPOSE_PATTERN_* (compose_coord.h): 0 = the composition
  int prefiltered;        // 1: mips >= 1 compose with expected coverages (docs/composition.md)
  // Prefiltered: a DPT layer is exact (its point value) where its patches span at least
  // prefilter_patch_hi texels of the footprint, its expectation below prefilter_patch_lo.
  float prefilter_patch_lo;
  float prefilter_patch_hi;
  int pad0;
  TvtMaterial materials[TVT_MAX_MATERIALS];
};

struct TvtPageJob {       // one page to compose into one cache slot
  uint mip;
  uint page_x;
  uint page_y;
  uint slot;              // layer of the output array image
  uint material_mask;     // bit n: material n may have weight within reach of the page
  uint pad0, pad1, pad2;
};

TVT_END

#ifdef __cplusplus
static_assert(sizeof(tvt::gpu::TvtDptLayer) == 56);
static_assert(sizeof(tvt::gpu::TvtMaterial) == 352);
static_assert(offsetof(tvt::gpu::TvtMaterial, dpt) == 128);
static_assert(sizeof(tvt::gpu::TvtComposeParams) == 64 + 16 * 352);
static_assert(offsetof(tvt::gpu::TvtComposeParams, materials) == 64);
static_assert(sizeof(tvt::gpu::TvtPageJob) == 32);
#endif
#endif
