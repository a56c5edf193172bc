// Composition of one sample (docs/composition.md), shared by compose.comp (pages into the cache) and the
// direct-splat baseline fragment shader. Same maths as compose/reference_compositor.cpp, in fp32
// on top of exact 64-bit integer terrain coordinates: only small in-cell remainders ever become
// floats. The includer declares, before including this file:
//   TvtComposeParams P; uint material_texels[]; uint meta_texels[]; float weights[];
// and enables GL_EXT_shader_explicit_arithmetic_types_int64.
#ifndef TVT_COMPOSE_SAMPLE_GLSL
#define TVT_COMPOSE_SAMPLE_GLSL

// What this pipeline may meet (compose_types.h, TVT_COMPOSE_SPEC_*): a path it cannot take
// folds away at pipeline creation. The defaults keep every path.
layout(constant_id = TVT_COMPOSE_SPEC_MODES) const uint k_compose_modes = 0xffffffffu;
layout(constant_id = TVT_COMPOSE_SPEC_HEX) const bool k_compose_hex = true;
layout(constant_id = TVT_COMPOSE_SPEC_PREFILTERED) const bool k_compose_prefiltered = true;
layout(constant_id = TVT_COMPOSE_SPEC_PARTS) const uint k_compose_parts = 0xffffffffu;
layout(constant_id = TVT_COMPOSE_SPEC_SMALL) const bool k_compose_small = false;
layout(constant_id = TVT_COMPOSE_SPEC_ONLY_PREFILTERED) const bool k_compose_only_prefiltered = false;
layout(constant_id = TVT_COMPOSE_SPEC_SAMPLE_PAIRS) const uint k_compose_sample_pairs = 0u;
bool part(uint bit) { return (k_compose_parts & bit) != 0u; }
bool mode_is(int mode, int m) { return (k_compose_modes & (1u << uint(m))) != 0u && mode == m; }

float clamp01(float v) { return (isnan(v) || isinf(v)) ? 0.0 : clamp(v, 0.0, 1.0); }
float safe_pow(float b, float e) { return b <= 0.0 ? 0.0 : pow(b, e); }
float blend_map(float b, float a, float s) { return smoothstep(1.0 - clamp01(b) - s, 1.0 - clamp01(b) + s, s + a * (1.0 - 2.0 * s)); }
// Exactly 0 at or below lo and 1 at or above hi, decided by comparison before any division, so
// that the host can tell from the same float v which side of a ramp a footprint is on.
float ramp(float v, float lo, float hi) {
  if (hi <= lo) return v >= lo ? 1.0 : 0.0;
  if (v >= hi) return 1.0;
  if (v <= lo) return 0.0;
  return clamp((v - lo) / (hi - lo), 0.0, 1.0);
}
// Whether the footprint is a power of two 2^k (every footprint compose.comp passes), and k: the
// host repeats what follows from it exactly (prefiltered_parts()).
bool footprint_log2(float footprint, out int k) {
  int e;
  const bool pow2 = frexp(footprint, e) == 0.5;
  k = e - 1;
  return pow2;
}
// v / footprint, exact at a power-of-two footprint: an exponent shift instead of a division,
// whose rounding a device may choose.
float per_footprint(float v, float footprint) {
  int k;
  return footprint_log2(footprint, k) ? ldexp(v, -k) : v / footprint;
}

// Prefiltered blend map (reference_compositor.cpp blend_map_expected): the means over A uniform
// on [mean - h, mean + h], h = sqrt(3 var), of blend_map and of blend_map * (A - mean).
float smoothstep_integral(float t) {
  if (t <= 0.0) return 0.0;
  if (t >= 1.0) return t - 0.5;
  return t * t * t * (1.0 - 0.5 * t);
}
float smoothstep_moment(float t) {
  if (t <= 0.0) return 0.0;
  if (t >= 1.0) return 0.35 + 0.5 * (t * t - 1.0);
  return t * t * t * t * (0.75 - 0.4 * t);
}
void blend_map_expected(float b, float a_mean, float a_var, float s, out float e, out float dev) {
  b = clamp01(b);
  const float c1 = (1.0 - 2.0 * s) / (2.0 * s);
  const float half_width = c1 * sqrt(3.0 * max(a_var, 0.0));
  if (!(half_width >= 2.5e-3)) {
    e = blend_map(b, a_mean, s);
    dev = 0.0;
    return;
  }
  const float tm = (b + 2.0 * s - 1.0) / (2.0 * s) + c1 * a_mean;
  const float t0 = tm - half_width, t1 = tm + half_width;
  e = clamp01((smoothstep_integral(t1) - smoothstep_integral(t0)) / (2.0 * half_width));
  dev = ((smoothstep_moment(t1) - smoothstep_moment(t0)) / (2.0 * half_width) - tm * e) / c1;
}

// A's variance within the footprint from its two pieces (p, delta, h_lo, h_hi): the pieces'
// means' delta^2 and each piece's uniform spread h^2 / 3.
float spread_variance(vec4 spread) {
  return spread.y * spread.y + (spread.x * spread.z * spread.z + (1.0 - spread.x) * spread.w * spread.w) / 3.0;
}

// The blend map's means over A in two pieces, `spread` = (p, delta, h_lo, h_hi) from the spread
// chain (reference_compositor.cpp blend_map_spread). Where A is one piece (delta too small, or p
// at an end) both calls see it and the first has weight 1, which gives its values exactly: one
// code path for both cases, which a SIMD-on-CPU device runs once instead of both.
void blend_map_spread(float b, float a_mean, vec4 spread, float s, out float e, out float dev) {
  const float p = clamp01(spread.x), delta = max(spread.y, 0.0);
  const bool two = delta > 1e-4 && p > 0.0 && p < 1.0;
  const float lo = two ? max(a_mean - delta * sqrt((1.0 - p) / p), -1.0) : a_mean;
  const float hi = two ? min(a_mean + delta * sqrt(p / (1.0 - p)), 2.0) : a_mean;
  const float var_lo = two ? spread.z * spread.z / 3.0 : spread_variance(vec4(p, delta, spread.z, spread.w));
  const float w_lo = two ? p : 1.0;
  float e_lo, d_lo, e_hi, d_hi;
  blend_map_expected(b, lo, var_lo, s, e_lo, d_lo);
  blend_map_expected(b, hi, spread.w * spread.w / 3.0, s, e_hi, d_hi);
  e = w_lo * e_lo + (1.0 - w_lo) * e_hi;
  dev = w_lo * (d_lo + e_lo * (lo - a_mean)) + (1.0 - w_lo) * (d_hi + e_hi * (hi - a_mean));
}

// One axis of weight_at(): the grid cell (unclamped) whose texels a bilinear fetch of a
// `size`-texel axis blends at c_fp, the pair it reads and the fraction towards the second.
void weight_axis(int64_t c_fp, int size, out int cell, out int c0, out int c1, out float f) {
  const int shift = P.log2_vt + TVT_FIXED_BITS;
  const int64_t vt_fp = int64_t(1) << shift;
  const float inv = exp2(-float(shift));
  const float u = float(clamp(c_fp, int64_t(0), vt_fp)) * inv * float(size) - 0.5;
  const float fu = floor(u);
  f = u - fu;
  cell = int(fu);
  c0 = clamp(cell, 0, size - 1);
  c1 = clamp(cell + 1, 0, size - 1);
}

float weight_texel(int layer, int x, int y) { return weights[(layer * P.weight_height + y) * P.weight_width + x]; }

// Bilinear weight at a terrain position, clamped at the terrain edge. The position becomes a
// float only after clamping, as a fraction of the terrain: its rounding (2^-24 of the terrain,
// at most 2^-11 of a weight texel for grids up to 8192) is far below what the smooth weight
// fields resolve, and it keeps the hot path in 32-bit arithmetic.
float weight_at(int layer, int64_t x_fp, int64_t y_fp) {
  int cell, x0, x1, y0, y1;
  float fx, fy;
  weight_axis(x_fp, P.weight_width, cell, x0, x1, fx);
  weight_axis(y_fp, P.weight_height, cell, y0, y1, fy);
  const float w00 = weight_texel(layer, x0, y0), w10 = weight_texel(layer, x1, y0);
  const float w01 = weight_texel(layer, x0, y1), w11 = weight_texel(layer, x1, y1);
  return clamp01(mix(mix(w00, w10, fx), mix(w01, w11, fx), fy));
}

// 3 x 3 weight texels from cell (x, y) on, fetched once: where every bilinear weight a caller
// needs blends texels of cell x or x + 1 a side (y likewise), each picks its four from them
// (block_bilinear()) with its own cell and fraction, as weight_at() works them out: the same
// texels and operations, so the same value. DPT's narrow lattices (lattice_masks()) and the
// FBPB points' centroids (weight_block()) read weights this way.
struct WeightBlock {
  int x, y;
  vec3 row0, row1, row2;
};
WeightBlock weight_block_from(int layer, int x, int y) {
  WeightBlock b;
  b.x = x;
  b.y = y;
  const ivec3 tx = clamp(ivec3(x) + ivec3(0, 1, 2), ivec3(0), ivec3(P.weight_width - 1));
  const ivec3 ty = clamp(ivec3(y) + ivec3(0, 1, 2), ivec3(0), ivec3(P.weight_height - 1));
  b.row0 = vec3(weight_texel(layer, tx.x, ty.x), weight_texel(layer, tx.y, ty.x), weight_texel(layer, tx.z, ty.x));
  b.row1 = vec3(weight_texel(layer, tx.x, ty.y), weight_texel(layer, tx.y, ty.y), weight_texel(layer, tx.z, ty.y));
  b.row2 = vec3(weight_texel(layer, tx.x, ty.z), weight_texel(layer, tx.y, ty.z), weight_texel(layer, tx.z, ty.z));
  return b;
}
WeightBlock no_weight_block() { return WeightBlock(0, 0, vec3(0.0), vec3(0.0), vec3(0.0)); }
// The bilinear weight in cell (b.x + next_x, b.y + next_y) at fractions (fx, fy).
float block_bilinear(WeightBlock b, bool next_x, bool next_y, float fx, float fy) {
  const vec3 top = next_y ? b.row1 : b.row0, bottom = next_y ? b.row2 : b.row1;
  const float w00 = next_x ? top.y : top.x, w10 = next_x ? top.z : top.y;
  const float w01 = next_x ? bottom.y : bottom.x, w11 = next_x ? bottom.z : bottom.y;
  return clamp01(mix(mix(w00, w10, fx), mix(w01, w11, fx), fy));
}
// The block around a prefiltered texel that holds every weight its FBPB points' feature
// centroids read, where the composer has found them all within half a weight texel of the
// footprint's centre (TVT_PART_FEATURE_WEIGHTS_WIDE clear): the centre's cell and its nearer
// neighbour a side.
WeightBlock weight_block(int layer, int64_t x_fp, int64_t y_fp) {
  int cx, cy, c0, c1;
  float fx, fy;
  weight_axis(x_fp, P.weight_width, cx, c0, c1, fx);
  weight_axis(y_fp, P.weight_height, cy, c0, c1, fy);
  return weight_block_from(layer, fx < 0.5 ? cx - 1 : cx, fy < 0.5 ? cy - 1 : cy);
}
// weight_at() of a position in the block.
float block_weight(WeightBlock b, int64_t x_fp, int64_t y_fp) {
  int cx, cy, c0, c1;
  float fx, fy;
  weight_axis(x_fp, P.weight_width, cx, c0, c1, fx);
  weight_axis(y_fp, P.weight_height, cy, c0, c1, fy);
  return block_bilinear(b, cx != b.x, cy != b.y, fx, fy);
}

// Resolutions are powers of two, so wrapping is a mask (also right for negative indices) and
// the level offsets have closed forms (compose_types.h).
vec4 material_texel(int n, int level, int x, int y) {
  const uint res = uint(P.materials[n].resolution);
  const uint rl = res >> uint(level);
  const uint offset = P.materials[n].texel_offset + tvt_material_level_offset(res, uint(level));
  return unpackUnorm4x8(material_texels[offset + (uint(y) & (rl - 1u)) * rl + (uint(x) & (rl - 1u))]);
}

// Word i of material n's statistics block, after its 1x1 mip (TVT_MATERIAL_STATS_WORDS).
float material_stat(int n, int i) {
  const uint at = tvt_material_stats_offset(uint(P.materials[n].resolution), uint(P.materials[n].mip_count));
  return uintBitsToFloat(material_texels[P.materials[n].texel_offset + at + uint(i)]);
}

// The level-`level` texels around tile-local material texel (u, v) a bilinear fetch blends: the
// first (i, j) and the fractions towards the next (reference_compositor.cpp bilinear_cell).
void bilinear_cell(int level, float u, float v, out int i, out int j, out float fx, out float fy) {
  const float scale = exp2(-float(level));
  const float ul = u * scale - 0.5, vl = v * scale - 0.5;
  const float fi = floor(ul), fj = floor(vl);
  fx = ul - fi;
  fy = vl - fj;
  i = int(fi);
  j = int(fj);
}

// A within the level-0 texels under level-`level` texel (x, y) as (p, delta, h_lo, h_hi) (the
// spread chain, compose_types.h); none at level 0 (reference_compositor.cpp spread_texel).
vec4 spread_texel(int n, int level, int x, int y) {
  if (level == 0) return vec4(0.0);
  const uint res = uint(P.materials[n].resolution);
  const uint rl = res >> uint(level);
  const uint i = (uint(y) & (rl - 1u)) * rl + (uint(x) & (rl - 1u));
  const vec4 v = unpackUnorm4x8(material_texels[P.materials[n].texel_offset + tvt_material_spread_offset(res, uint(level)) + i]);
  return vec4(v.x, v.yzw / TVT_SPREAD_SCALE);
}

vec4 spread_bilinear(int n, int level, float u, float v) {
  if (level == 0) return vec4(0.0);
  int i, j;
  float fx, fy;
  bilinear_cell(level, u, v, i, j, fx, fy);
  return mix(mix(spread_texel(n, level, i, j), spread_texel(n, level, i + 1, j), fx),
             mix(spread_texel(n, level, i, j + 1), spread_texel(n, level, i + 1, j + 1), fx), fy);
}

// Variance of A and its covariances with R, G, B within a footprint of material LOD `lod`.
vec4 material_a_stats(int n, float lod) {
  const int top = min(P.materials[n].mip_count - 1, 14);
  const float l = clamp(lod, 0.0, float(top));
  const int l0 = int(floor(l));
  const int l1 = min(l0 + 1, top);
  const float t = l - float(l0);
  const vec4 a = vec4(material_stat(n, 4 * l0), material_stat(n, 4 * l0 + 1), material_stat(n, 4 * l0 + 2), material_stat(n, 4 * l0 + 3));
  const vec4 b = vec4(material_stat(n, 4 * l1), material_stat(n, 4 * l1 + 1), material_stat(n, 4 * l1 + 2), material_stat(n, 4 * l1 + 3));
  return a * (1.0 - t) + b * t;
}

vec4 material_bilinear(int n, int level, float u, float v) {
  int i, j;
  float fx, fy;
  bilinear_cell(level, u, v, i, j, fx, fy);
  return mix(mix(material_texel(n, level, i, j), material_texel(n, level, i + 1, j), fx),
             mix(material_texel(n, level, i, j + 1), material_texel(n, level, i + 1, j + 1), fx), fy);
}

// Global material texel index (exact) and the position's fraction of that texel.
void material_texel_coord(int n, int64_t pos_fp, out int64_t global_, out float frac_) {
  const int64_t period = P.materials[n].period_fp;
  const int64_t num = pos_fp * int64_t(P.materials[n].resolution);
  global_ = tvt_floor_div(num, period);
  frac_ = float(num - global_ * period) / float(period);
}

// Settles a quotient estimate q that is off by at most one: r = remainder for q, brought into
// [0, period) with q (material_texel_near(), patch_samples()).
void settle_quotient(inout int q, inout int64_t r, int64_t period) {
  if (r < 0) {
    --q;
    r += period;
  } else if (r >= period) {
    ++q;
    r -= period;
  }
}

// material_texel_coord() of pos_fp + delta_fp from pos_fp's global texel g and its remainder
// rem = pos_fp * R - g * period: while delta spans fewer than 2^20 texels (`near`, a property of
// the footprint alone) a float estimate of the extra quotient is off by at most one and an
// integer step settles it, instead of a 64-bit division; the same texel and fraction.
void material_texel_near(int n, int64_t pos_fp, int64_t g, int64_t rem, float frac, int64_t delta_fp, bool near,
                         out int64_t global_, out float frac_) {
  if (!near) {
    material_texel_coord(n, pos_fp + delta_fp, global_, frac_);
    return;
  }
  const int64_t period = P.materials[n].period_fp;
  const int64_t d = delta_fp * int64_t(P.materials[n].resolution);
  int q = int(floor(frac + float(delta_fp) * (float(P.materials[n].resolution) / float(period))));
  int64_t r = rem + d - int64_t(q) * period;
  settle_quotient(q, r, period);
  global_ = g + int64_t(q);
  frac_ = float(r) / float(period);
}

// The material's LOD at a footprint of `footprint` level-0 texels: log2(footprint) + lod_bias,
// exactly k + lod_bias at a power-of-two footprint 2^k (every one compose.comp passes), which
// the host evaluates as the same float (prefiltered_parts()).
float material_lod(int n, float footprint) {
  int k;
  return (footprint_log2(footprint, k) ? float(k) : log2(footprint)) + P.materials[n].lod_bias;
}

// The trilinear pair of levels of material n at LOD `lod`: l0, l1 and the weight t of l1
// (t = 0 where only l0 is read). The texture and the feature statistics chain share it.
void trilinear_levels(int n, float lod, out int l0, out int l1, out float t) {
  const float l = clamp(lod, 0.0, float(P.materials[n].mip_count - 1));
  l0 = int(floor(l));
  l1 = min(l0 + 1, P.materials[n].mip_count - 1);
  t = l1 == l0 ? 0.0 : l - float(l0);
}

// Trilinear, wrapping material sample at tile-local coordinates (u, v) in [0, R).
vec4 sample_material(int n, float u, float v, float lod) {
  int l0, l1;
  float t;
  trilinear_levels(n, lod, l0, l1, t);
  const vec4 a = material_bilinear(n, l0, u, v);
  if (t <= 0.0) return a;
  return mix(a, material_bilinear(n, l1, u, v), t);
}

// The level of the trilinear pair (l0, l1, t) nearest the LOD: the one level the second-order
// statistics are read at (reference_compositor.cpp nearest_level).
int nearest_level(int l0, int l1, float t) { return t < 0.5 ? l0 : l1; }

// A's distribution within the footprint at (u, v): bilinear at the level nearest the LOD
// (reference_compositor.cpp spread): one level's fetches, not two.
vec4 material_spread(int n, float u, float v, int l0, int l1, float t) {
  return spread_bilinear(n, nearest_level(l0, l1, t), u, v);
}

// Hex-tiling at global material texel (gx + fx, gy + fy): reference_compositor.cpp hex_sample.
// `want_spread` (prefiltered): also A's distribution within the footprint, the tiles' blended as
// their values (reference_compositor.cpp).
vec4 hex_sample(int n, int64_t gx, float fx, int64_t gy, float fy, float lod, bool want_spread, out vec4 a_spread) {
  const int64_t L = int64_t(P.materials[n].hex_edge), H = int64_t(P.materials[n].hex_row);
  const int64_t R = int64_t(P.materials[n].resolution);
  int64_t i, j;
  float a, b;
  if (k_compose_small || (abs(gx) < int64_t(1 << 29) && abs(gy) < int64_t(1 << 29))) {
    // Terrains up to 2^29 material texels a side (the default scene at V = 2^24 is 2^23): the
    // same floor divisions in 32 bits, several times cheaper than 64-bit ones on GPUs.
    const int gy32 = int(gy), h32 = int(H), l32 = int(L);
    const int j32 = tvt_floor_div32(gy32, h32);
    b = (float(gy32 - j32 * h32) + fy) / float(h32);
    const int xs32 = int(gx) - j32 * (l32 / 2);
    const int i32 = tvt_floor_div32(xs32, l32);
    a = (float(xs32 - i32 * l32) + fx) / float(l32) - 0.5 * b;
    i = int64_t(i32);
    j = int64_t(j32);
  } else {
    j = tvt_floor_div(gy, H);
    b = (float(gy - j * H) + fy) / float(H);
    const int64_t xs = gx - j * (L / 2);
    i = tvt_floor_div(xs, L);
    a = (float(xs - i * L) + fx) / float(L) - 0.5 * b;
  }
  if (a < 0.0) {
    i -= 1;
    a += 1.0;
  }
  int64_t vx[3], vy[3];
  float w[3];
  if (a + b < 1.0) {
    vx[0] = i; vy[0] = j; w[0] = 1.0 - a - b;
    vx[1] = i + 1; vy[1] = j; w[1] = a;
    vx[2] = i; vy[2] = j + 1; w[2] = b;
  } else {
    vx[0] = i + 1; vy[0] = j + 1; w[0] = a + b - 1.0;
    vx[1] = i + 1; vy[1] = j; w[1] = 1.0 - b;
    vx[2] = i; vy[2] = j + 1; w[2] = 1.0 - a;
  }
  const float gamma = P.materials[n].hex_sharpness, cut = P.materials[n].hex_cut;
  float sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    w[k] = safe_pow(max(w[k], 0.0), gamma);
    sum += w[k];
  }
  float kept = 0.0;
  for (int k = 0; k < 3; ++k) {
    w[k] = max(w[k] / sum - cut, 0.0);
    kept += w[k];
  }
  // sample_material() for each tile, its level pair worked out once; the offset tile's
  // coordinates wrap in 32 bits (the low bits of the 64-bit sum).
  int l0, l1;
  float t;
  trilinear_levels(n, lod, l0, l1, t);
  const int wrap = P.materials[n].resolution - 1;
  const int gx_tile = int(gx & (R - 1)), gy_tile = int(gy & (R - 1));
  vec4 linear = vec4(0.0);
  float squares = 0.0;
  vec4 spread_sum = vec4(0.0);  // sum of w_k^2 (p, delta^2, h_lo^2, h_hi^2)
  for (int k = 0; k < 3; ++k) {
    const float wk = w[k] / kept;
    if (wk <= 0.0) continue;  // most of the plane: one or two tiles, their fetches only
    squares += wk * wk;
    const uint h = tvt_hash_coord(vx[k], vy[k], P.materials[n].hex_salt);
    const float u = float((gx_tile + int(h & 0xffffu)) & wrap) + fx;
    const float v = float((gy_tile + int(h >> 16u)) & wrap) + fy;
    vec4 texel = material_bilinear(n, l0, u, v);
    if (t > 0.0) texel = mix(texel, material_bilinear(n, l1, u, v), t);
    linear += wk * texel;
    if (want_spread) {
      const vec4 sp = material_spread(n, u, v, l0, l1, t);
      spread_sum += wk * wk * vec4(sp.x, sp.yzw * sp.yzw);
    }
  }
  const float scale = 1.0 + P.materials[n].hex_preserve * (1.0 / sqrt(squares) - 1.0);
  a_spread = want_spread ? vec4(spread_sum.x / squares, scale * sqrt(spread_sum.yzw)) : vec4(0.0);
  const vec4 mean = material_texel(n, P.materials[n].mip_count - 1, 0, 0);
  const vec4 preserved = mean + (linear - mean) / sqrt(squares);
  const vec4 r = mix(linear, preserved, P.materials[n].hex_preserve);
  return vec4(clamp01(r.x), clamp01(r.y), clamp01(r.z), clamp01(r.w));
}

// The material at a terrain position (x, y): its coordinates (global texel, for FBPB) and the
// tiled texture, or hex-tiling where the material has it.
// `want_spread` (prefiltered): a_spread is A's distribution within the footprint there.
vec4 material_at(int n, int64_t x_fp, int64_t y_fp, float lod, bool want_spread, out int64_t gx, out int64_t gy,
                 out float fx, out float fy, out vec4 a_spread) {
  material_texel_coord(n, x_fp, gx, fx);
  material_texel_coord(n, y_fp, gy, fy);
  if (k_compose_hex && P.materials[n].hex_edge > 0) return hex_sample(n, gx, fx, gy, fy, lod, want_spread, a_spread);
  const int64_t mask = int64_t(P.materials[n].resolution - 1);
  const float u = float(gx & mask) + fx, v = float(gy & mask) + fy;
  a_spread = vec4(0.0);
  if (want_spread) {
    int l0, l1;
    float t;
    trilinear_levels(n, lod, l0, l1, t);
    a_spread = material_spread(n, u, v, l0, l1, t);
  }
  return sample_material(n, u, v, lod);
}

// One texel of material n's feature statistics chain (compose_types.h) as (D, mean f) and the
// colour moment; level 0 is the meta texel itself (reference_compositor.cpp feature_texel).
void feature_texel(int n, int level, int x, int y, out vec2 df, out vec4 moment) {
  const uint res = uint(P.materials[n].resolution), rl = res >> uint(level);
  const uint base = level == 0 ? 0u : tvt_meta_chain_offset(res, uint(level));
  const uint i = P.materials[n].meta_offset + base + (uint(y) & (rl - 1u)) * rl + (uint(x) & (rl - 1u));
  const uint w0 = meta_texels[2u * i], w1 = meta_texels[2u * i + 1u];
  if (level == 0) {
    const float d = (w1 & 0xffu) != 0u ? 1.0 : 0.0;
    df = vec2(d, d * float((w1 >> 8u) & 0xffu) / 255.0);
    moment = vec4(0.0);
    return;
  }
  df = unpackUnorm2x16(w0);
  moment = unpackSnorm4x8(w1) / TVT_META_MOMENT_SCALE;
}
void feature_bilinear(int n, int level, float u, float v, out vec2 df, out vec4 moment) {
  int i, j;
  float fx, fy;
  bilinear_cell(level, u, v, i, j, fx, fy);
  vec2 d00, d10, d01, d11;
  vec4 m00, m10, m01, m11;
  feature_texel(n, level, i, j, d00, m00);
  feature_texel(n, level, i + 1, j, d10, m10);
  feature_texel(n, level, i, j + 1, d01, m01);
  feature_texel(n, level, i + 1, j + 1, d11, m11);
  df = mix(mix(d00, d10, fx), mix(d01, d11, fx), fy);
  moment = mix(mix(m00, m10, fx), mix(m01, m11, fx), fy);
}
// The chain at tile-local material texel (u, v) and material LOD `lod`: bilinear at the level
// nearest the LOD, as material_spread() (reference_compositor.cpp feature_stats).
void feature_stats(int n, float u, float v, float lod, out vec2 df, out vec4 moment) {
  int l0, l1;
  float t;
  trilinear_levels(n, lod, l0, l1, t);
  feature_bilinear(n, nearest_level(l0, l1, t), u, v, df, moment);
}

// The feature at global material texel (gx, gy): its mask d, soft f, the weight p at its
// centroid (cx, cy) (`plain` off features, and for every feature where `at_centroid` is false;
// from `block` where `in_block`, see WeightBlock) and whether it is visible (eq 3.1);
// reference_compositor.cpp feature_at.
bool feature_at(int n, int64_t gx, int64_t gy, float plain, bool at_centroid, bool in_block, WeightBlock block,
                out float d, out float f, out float pw, out int64_t cx, out int64_t cy) {
  const int64_t R = int64_t(P.materials[n].resolution);
  const uint mi = P.materials[n].meta_offset + uint((gy & (R - 1)) * R + (gx & (R - 1)));
  const uint w0 = meta_texels[2u * mi], w1 = meta_texels[2u * mi + 1u];
  d = float(w1 & 0xffu);
  f = float((w1 >> 8u) & 0xffu) / 255.0;
  cx = gx + int64_t(bitfieldExtract(int(w0), 0, 16));
  cy = gy + int64_t(bitfieldExtract(int(w0), 16, 16));
  const int64_t period = P.materials[n].period_fp;
  const int shift = P.materials[n].log2_resolution + 1;  // / 2R, a power of two
  const int64_t cx_fp = ((2 * cx + 1) * period) >> shift;
  const int64_t cy_fp = ((2 * cy + 1) * period) >> shift;
  pw = plain;
  if (d > 0.0 && at_centroid)
    pw = in_block ? block_weight(block, cx_fp, cy_fp) : weight_at(P.materials[n].weight_layer, cx_fp, cy_fp);
  const float r = tvt_rand01(tvt_hash_coord(cx, cy, P.materials[n].fbpb_salt));
  return d > 0.0 && pw > 0.0 && r <= pw * P.materials[n].cf;
}

#include "compose_dpt.glsl"

// The share of a visible feature's texels that Algorithm 1 chips: the variation map below the
// threshold, interpolated in the statistics block's distribution of it (each feature reads the
// map at its own random offset); reference_compositor.cpp chipped_share.
float chipped_share(int n) {
  const float t = P.materials[n].variation_threshold;
  if (!(t > 0.0)) return 0.0;
  if (t > 1.0) return 1.0;
  const float x = t * float(TVT_STATS_VARIATION_STEPS);
  const int i = min(int(floor(x)), TVT_STATS_VARIATION_STEPS - 1);
  return mix(material_stat(n, TVT_STATS_VARIATION_CDF + i), material_stat(n, TVT_STATS_VARIATION_CDF + i + 1), x - float(i));
}

// FBPB's w at global material texel (gx, gy): eq 3.1 with Algorithm 1's chipped holes (which
// darken `colour`, the material there, and show the layer below); `non_feature` is what a
// non-feature texel blends with under FBPB+DPT (`with_dpt`). reference_compositor.cpp fbpb_exact.
float fbpb_exact(int n, int64_t gx, int64_t gy, float plain, bool with_dpt, float non_feature, bool in_block,
                 WeightBlock block, inout vec4 colour, out bool visible) {
  const int64_t R = int64_t(P.materials[n].resolution);
  const int64_t lx = gx & (R - 1), ly = gy & (R - 1);
  float d, f, pw;
  int64_t cx, cy;
  visible = feature_at(n, gx, gy, plain, true, in_block, block, d, f, pw, cx, cy);
  if (visible && pw < 1.0) {
    const uint hv = tvt_hash_coord(cx, cy, P.materials[n].variation_salt);
    const int64_t vx = (lx + int64_t(hv & 0xffffu)) & (R - 1);
    const int64_t vy = (ly + int64_t(hv >> 16u)) & (R - 1);
    const uint vw = meta_texels[2u * (P.materials[n].meta_offset + uint(vy * R + vx)) + 1u];
    const float variation = float((vw >> 16u) & 0xffu) / 255.0;
    if (variation < P.materials[n].variation_threshold) {
      d = 0.0;
      visible = false;
      colour.rgb *= P.materials[n].colour_coeff;
    }
  }
  const float nf = with_dpt ? non_feature : pw;
  return visible ? min(P.materials[n].cm * max(pw, f), 1.0) : min((1.0 - d) * nf * P.materials[n].cn, 1.0);
}

// `prefiltered`: mips >= 1 of the prefiltered strategy (reference_compositor.cpp).
vec4 compose_sample(int64_t x_fp, int64_t y_fp, float footprint, uint material_mask, bool prefiltered) {
  footprint = (isnan(footprint) || isinf(footprint)) ? 1.0 : max(footprint, 1.0 / 256.0);
  // A variant made for prefiltered pages alone knows; one without the prefiltered maths too.
  prefiltered = k_compose_only_prefiltered || (k_compose_prefiltered && prefiltered);
  float wts[TVT_MAX_MATERIALS];
  for (int n = 0; n < P.material_count; ++n)
    wts[n] = (material_mask & (1u << uint(n))) != 0u ? weight_at(P.materials[n].weight_layer, x_fp, y_fp) : 0.0;
  if (prefiltered) sample_pairs(x_fp, y_fp, footprint, wts, material_mask);

  int64_t g0x, g0y;
  float f0x, f0y;
  vec4 unused_spread;
  vec4 result = material_at(0, x_fp, y_fp, material_lod(0, footprint), false, g0x, g0y, f0x, f0y, unused_spread);
  float weight_sum = wts[0];
  bool feature_above = false;

  for (int n = 1; n < P.material_count; ++n) {
    // Culled on the host: zero weight everywhere within reach, so b = 0 (material_culling.h).
    if ((material_mask & (1u << uint(n))) == 0u) continue;
    const float plain = wts[n];
    weight_sum += plain;
    const int mode = P.materials[n].mode;
    if (plain <= 0.0 && (mode_is(mode, TVT_MODE_LINEAR) || mode_is(mode, TVT_MODE_BLENDMAP))) continue;

    const float lod = material_lod(n, footprint);
    int64_t gx, gy;  // global material texel (FBPB centroids) and the position's fraction of it
    float fx, fy;
    vec4 a_spread;  // prefiltered: A's distribution within the footprint
    vec4 colour = material_at(n, x_fp, y_fp, lod, prefiltered, gx, gy, fx, fy, a_spread);
    float b = 0.0;
    float height = colour.a;
    bool visible = false;
    const vec4 a_stats = prefiltered ? material_a_stats(n, lod) : vec4(0.0);
    float dev = 0.0;
    bool dev_height = false;
    float feature_shift = 0.0;  // prefiltered FBPB: weight of the features' colour moment
    vec4 feature_moment = vec4(0.0);
    const float s = P.materials[n].blend_sharpness;
    // What several modes read, worked out once: every branch below is code a SIMD-on-CPU device
    // runs for each material whatever its mode. The blend map of the plain weight (blendmap, the
    // fallback of FBPB, DPT away from its patches) and DPT's value (dpt, fbpb+dpt).
    float plain_b = 0.0, plain_dev = 0.0;
    if (!mode_is(mode, TVT_MODE_LINEAR)) {
      if (prefiltered) blend_map_spread(plain, colour.a, a_spread, s, plain_b, plain_dev);
      else plain_b = blend_map(plain, colour.a, s);
    }
    float dpt_b = 0.0, dpt_h = colour.a, dpt_dev = 0.0;
    if (mode_is(mode, TVT_MODE_DPT) || mode_is(mode, TVT_MODE_FBPB_DPT))
      dpt(n, x_fp, y_fp, footprint, plain, colour.a, prefiltered, a_spread, plain_b, plain_dev, dpt_b, dpt_h, dpt_dev);

    if (mode_is(mode, TVT_MODE_LINEAR)) {
      b = weight_sum > 0.0 ? min(1.0, P.linear_boost * plain / weight_sum) : 0.0;
    } else if (mode_is(mode, TVT_MODE_BLENDMAP)) {
      b = plain_b;
      dev = plain_dev;
      dev_height = prefiltered;
    } else if (mode_is(mode, TVT_MODE_DPT)) {
      b = dpt_b;
      height = dpt_h;
      dev = dpt_dev;
    } else if (mode_is(mode, TVT_MODE_FBPB) || mode_is(mode, TVT_MODE_FBPB_DPT)) {
      const float non_feature = dpt_b;
      // Prefiltered: level 0's own feature fade (what the truth holds; 1 for the default scenes),
      // and the features exact at points while the footprint is about a feature or less, then in
      // expectation (tvt_feature_points_hold: 1 or 0, never both).
      const float fade0 =
          prefiltered ? 1.0 - ramp(material_lod(n, 1.0), P.materials[n].fbpb_fade_lo, P.materials[n].fbpb_fade_hi) : 1.0;
      const float fade =
          prefiltered ? (fade0 > 0.0 && tvt_feature_points_hold(lod, material_stat(n, TVT_STATS_FEATURE_LOG2_SIZE)) ? 1.0 : 0.0)
                      : 1.0 - ramp(lod, P.materials[n].fbpb_fade_lo, P.materials[n].fbpb_fade_hi);
      const bool with_dpt = mode_is(mode, TVT_MODE_FBPB_DPT);
      const float plain_fallback = with_dpt ? non_feature : plain_b;
      // Prefiltered FBPB+DPT: a ground texel takes DPT's blend value at its own A, the
      // footprint's b moved along its regression on A (dpt_dev over A's variance within the
      // footprint, the spread chain's two pieces): the gaps between features are the low A that a
      // blend map shows last. ground_slope * (A_x - mean) is the move for mean A_x.
      const float a_var = prefiltered && with_dpt ? spread_variance(a_spread) : 0.0;
      const float ground_slope = a_var > 1e-5 ? dpt_dev / a_var : 0.0;
      float fallback = plain_fallback;
      if (part(TVT_PART_FEATURE_EXPECT) && prefiltered && fade < 1.0 && fade0 > 0.0) {
        const float nf = with_dpt ? non_feature : plain;
        const int64_t mask = int64_t(P.materials[n].resolution - 1);
        vec2 df;
        feature_stats(n, float(gx & mask) + fx, float(gy & mask) + fy, lod, df, feature_moment);
        // FBPB+DPT: ground and chipped texels at their own mean A (ground_slope): the chain's
        // moment gives the features' mean A, mean + moment.a / D, and the ground's,
        // mean - moment.a / (1 - D).
        const float nf_ground = with_dpt ? clamp01(non_feature - ground_slope * feature_moment.a / max(1.0 - df.x, 1e-3)) : nf;
        const float nf_chip = with_dpt ? clamp01(non_feature + ground_slope * feature_moment.a / max(df.x, 1e-3)) : nf;
        // A visible feature's texel where its p < 1 is chipped (Algorithm 1) with the share q of
        // the variation map below the threshold: then it blends as ground (w_chip) in a colour
        // darkened by colour_coeff.
        const float q = chipped_share(n);
        const float w_chip = min(nf_chip * P.materials[n].cn, 1.0);
        const float q_plain = plain < 1.0 ? q : 0.0;
        const float visible_p = min(plain * P.materials[n].cf, 1.0);
        // The share of the footprint's features that show: while few fall in it, their own
        // decisions under k x k points spread over it (k = 1 while a feature spans it, up to 4
        // where 16 do), faded to the expectation as more fall in (docs/composition.md). Each is
        // decided at the footprint's weight, as the expectation is, not at its own centroid.
        float visible_share = visible_p;
        const float rel = lod - material_stat(n, TVT_STATS_FEATURE_LOG2_SIZE);
        const float e = 1.0 - ramp(rel, 2.0, 3.0);
        if (e > 0.0) {
          const int k = 1 << clamp(int(ceil(rel)) + 1, 0, 2);
          const int64_t step = int64_t(max(1.0, round(exp2(lod) / float(k))));
          int hits = 0, shown = 0;
          for (int j = 0; j < k; ++j)
            for (int i = 0; i < k; ++i) {
              float fd, ff, fp;
              int64_t fcx, fcy;
              const bool fvisible = feature_at(n, gx + ((int64_t(2 * i + 1 - k) * step) >> 1),
                                               gy + ((int64_t(2 * j + 1 - k) * step) >> 1), plain, false, false, no_weight_block(), fd,
                                               ff, fp, fcx, fcy);
              hits += fd > 0.0 ? 1 : 0;
              shown += fvisible ? 1 : 0;
            }
          if (hits > 0) visible_share = mix(visible_p, float(shown) / float(hits), e);
        }
        // The footprint's feature texels, each feature shown or not: their mean w (eq 3.1 at the
        // footprint's weight, the chipped share q_plain as ground) and its chipped texels' part.
        const float w_feature = visible_share * mix(min(P.materials[n].cm * max(plain, df.y), 1.0), w_chip, q_plain);
        const float chip_feature = visible_share * q_plain * w_chip;
        const float chip_share = visible_share * q_plain;  // the footprint's feature texels that are chipped
        const float w_ground = min(nf_ground * P.materials[n].cn, 1.0);
        const float expected = df.x * w_feature + (1.0 - df.x) * w_ground;
        fallback = fade0 * expected + (1.0 - fade0) * fallback;
        // The chipped texels' share of the fallback shows darkened: level 0 darkens a chipped
        // texel's colour, so its plain share (1 - fade0) too.
        const float chip_b = df.x * (fade0 * chip_feature + (1.0 - fade0) * plain_fallback * chip_share);
        if (fallback > 0.0) colour.rgb *= 1.0 - (1.0 - P.materials[n].colour_coeff) * min(chip_b / fallback, 1.0);
        feature_shift = fade0 * (w_feature - w_ground);  // fade is 0 here
      }
      float w = 0.0;
      if (part(TVT_PART_FEATURES) && fade > 0.0) {
        // Direct: the feature at the sample. Prefiltered: the mean w over k x k points of the
        // footprint, each with the texture over its own cell of it (tvt_feature_point_lods finer),
        // and their w-weighted colour (docs/composition.md, "FBPB features at points").
        const int kk = prefiltered ? tvt_feature_points(lod, material_stat(n, TVT_STATS_FEATURE_LOG2_SIZE), with_dpt) : 1;
        const float point_lod = lod - float(tvt_feature_point_lods(kk));
        const int64_t half_step = tvt_feature_point_half_step(int64_t(round(ldexp(footprint, TVT_FIXED_BITS))), kk);
        const bool near = footprint * float(P.materials[n].resolution) * 256.0 < float(P.materials[n].period_fp) * 1048576.0;
        const int64_t mask = int64_t(P.materials[n].resolution - 1);
        const int64_t rx = x_fp * int64_t(P.materials[n].resolution) - gx * P.materials[n].period_fp;
        const int64_t ry = y_fp * int64_t(P.materials[n].resolution) - gy * P.materials[n].period_fp;
        // Prefiltered: the centroids' weights from one 3 x 3 fetch where the composer has found
        // them all within it (WeightBlock), not four fetches a point.
        const bool in_block = prefiltered && !part(TVT_PART_FEATURE_WEIGHTS_WIDE);
        const WeightBlock block = in_block ? weight_block(P.materials[n].weight_layer, x_fp, y_fp) : no_weight_block();
        vec4 weighted = vec4(0.0), points_colour = vec4(0.0);
        int shown = 0;
        for (int j = 0; j < kk; ++j)
          for (int i = 0; i < kk; ++i) {
            vec4 c = colour;
            int64_t px = gx, py = gy;
            if (prefiltered) {
              // Never hex-tiled: pack_scene() leaves FBPB layers above the base untiled, so the
              // points fetch the tiled texture alone (a device that runs every branch would
              // otherwise pay hex-tiling's fetches again at each point).
              float pfx, pfy;
              material_texel_near(n, x_fp, gx, rx, fx, int64_t(2 * i + 1 - kk) * half_step, near, px, pfx);
              material_texel_near(n, y_fp, gy, ry, fy, int64_t(2 * j + 1 - kk) * half_step, near, py, pfy);
              c = sample_material(n, float(px & mask) + pfx, float(py & mask) + pfy, point_lod);
            }
            bool v;  // FBPB+DPT: the point's ground at its own A (ground_slope)
            const float wi = fbpb_exact(n, px, py, plain, with_dpt, clamp01(non_feature + ground_slope * (c.a - colour.a)),
                                        in_block, block, c, v);
            w += wi;
            weighted += wi * c;
            points_colour += c;
            shown += v ? 1 : 0;
            if (!prefiltered) colour = c;  // darkened in a chipped hole
          }
        visible = 2 * shown >= kk * kk;  // direct: the sample's feature; prefiltered: half the points
        if (prefiltered) {
          // The points' mean, faded as level 0 fades them (its plain share in each point's own
          // colour, darkened where chipped), and their w-weighted colour: mix(result, colour, b)
          // is then that mean of the points' blends.
          const float per_point = 1.0 / float(kk * kk);
          w = fade0 * per_point * w + (1.0 - fade0) * plain_fallback;
          weighted = per_point * (fade0 * weighted + (1.0 - fade0) * plain_fallback * points_colour);
          if (w > 0.0) colour = weighted / w;  // fade is 1 here: a switch, not a ramp
        }
      }
      b = fade * w + (1.0 - fade) * fallback;
      visible = visible && fade > 0.0;
      if (with_dpt) height = dpt_h;
    }
    const float bn = (visible || !feature_above) ? clamp01(b) : 0.0;
    feature_above = feature_above || visible;
    result = vec4(mix(result.rgb, colour.rgb, bn), mix(result.a, height, bn));
    if (prefiltered && bn > 0.0 && dev != 0.0 && a_stats.x > 1e-6)
      result += vec4(a_stats.yzw / a_stats.x * dev, dev_height ? dev : 0.0);
    if (prefiltered && bn > 0.0 && feature_shift != 0.0) {
      if (mode_is(mode, TVT_MODE_FBPB_DPT)) feature_moment.a = 0.0;  // its height is DPT's, not A
      result += feature_moment * feature_shift;
    }
  }
  return vec4(clamp01(result.r), clamp01(result.g), clamp01(result.b), clamp01(result.a));
}

#endif
