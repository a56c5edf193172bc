// DPT (eq 4.1-4.4, Algorithms 2-3) for compose_sample.glsl: the patch masks, their lattices,
// the layers' point values, the prefiltered expectation and its samples. Same maths as
// compose/reference_compositor.cpp. compose_sample.glsl includes it where the weight map, the
// blend map and the ramps it reads are defined; it is not included on its own.
#ifndef TVT_COMPOSE_DPT_GLSL
#define TVT_COMPOSE_DPT_GLSL

// E[bilerp(m)^W] (coefficients expect) and E[bilerp(m)^(2W)] (expect_sq) of DPT layer k of
// material n for corner masks set with probability q.
float patch_expectation(int n, int k, float q) {
  const float r = 1.0 - q;
  return q * q * q * q + P.materials[n].dpt[k].expect[0] * q * r * r * r + P.materials[n].dpt[k].expect[1] * q * q * r * r +
         P.materials[n].dpt[k].expect[2] * q * q * q * r;
}
float patch_second_moment(int n, int k, float q) {
  const float r = 1.0 - q;
  return q * q * q * q + P.materials[n].dpt[k].expect_sq[0] * q * r * r * r +
         P.materials[n].dpt[k].expect_sq[1] * q * q * r * r + P.materials[n].dpt[k].expect_sq[2] * q * q * q * r;
}

// The blend map's means over a patch sum settled + X, X in [0, span] with this mean and variance
// taken as a two-point distribution (reference_compositor.cpp blend_map_of_patches). Where X is
// taken as its mean both calls see settled + mean and the first has weight 1 (as above).
void blend_map_of_patches(float settled, float mean, float var, float span, float a_mean, vec4 a_spread, float s,
                          out float e, out float dev) {
  const float mu = span > 0.0 ? clamp(mean / span, 0.0, 1.0) : 0.0;
  const float sd = span > 0.0 ? sqrt(clamp(var, 0.0, mu * (1.0 - mu) * span * span)) / span : 0.0;
  const bool two = part(TVT_PART_DPT_EXPECT) && sd > 1e-4 && mu > 0.0 && mu < 1.0;
  const float b_low = two ? min(settled + (mu - sd * sqrt(mu / (1.0 - mu))) * span, 1.0) : min(settled + mean, 1.0);
  const float b_high = two ? min(settled + (mu + sd * sqrt((1.0 - mu) / mu)) * span, 1.0) : b_low;
  const float w_high = two ? mu : 0.0;
  float e_low, d_low, e_high, d_high;
  blend_map_spread(b_low, a_mean, a_spread, s, e_low, d_low);
  blend_map_spread(b_high, a_mean, a_spread, s, e_high, d_high);
  e = (1.0 - w_high) * e_low + w_high * e_high;
  dev = (1.0 - w_high) * d_low + w_high * d_high;
}

// The patch cell of DPT layer k of material n that holds a terrain coordinate (one axis): its
// index and the coordinate's fraction of it.
void patch_cell(int n, int k, int64_t c_fp, out int64_t i, out float f) {
  const int64_t ps = P.materials[n].dpt[k].patch_fp;
  if (k_compose_small || (abs(c_fp) < int64_t(1 << 30) && ps < int64_t(1 << 30))) {
    // Positions within 2^22 texels of the origin (every page of V <= 2^21, and of V = 2^22 but
    // for the expectation's samples beyond its edges): 32-bit divisions, the same quotients.
    const int ps32 = int(ps), c32 = int(c_fp);
    const int i32 = tvt_floor_div32(c32, ps32);
    f = float(c32 - i32 * ps32) / float(ps32);
    i = int64_t(i32);
  } else {
    i = tvt_floor_div(c_fp, ps);
    f = float(c_fp - i * ps) / float(ps);
  }
}

// Corner (jx, jy)'s patch mask m_j = p_j > 0 && r_j^R <= p_j^P (eq 4.1, 4.2) for its weight
// p_j = w, compared in the log domain: two log2 instead of two pow; r is never 0, and p = 0 fails
// the first test.
bool patch_mask(int n, int k, int64_t jx, int64_t jy, float w) {
  const float r = tvt_rand01(tvt_hash_coord(jx, jy, P.materials[n].dpt[k].salt));
  return w > 0.0 && P.materials[n].dpt[k].exp_r * log2(r) <= P.materials[n].dpt[k].exp_p * log2(w);
}

// The mask of corner (jx, jy), its weight at the patch centre.
float patch_corner(int n, int k, int64_t jx, int64_t jy) {
  const int64_t ps = P.materials[n].dpt[k].patch_fp;
  const int64_t half_patch = ps / 2;
  const float w = weight_at(P.materials[n].weight_layer, jx * ps + half_patch, jy * ps + half_patch);
  return patch_mask(n, k, jx, jy, w) ? 1.0 : 0.0;
}

// The layer's w from its cell's four corner masks (0 or 1) and the position's fractions (eq
// 4.3); W = 1 (the default) is the bilinear value itself, which pow() need not round.
float patch_blend(int n, int k, float m00, float m10, float m01, float m11, float fx, float fy) {
  const float bl = mix(mix(m00, m10, fx), mix(m01, m11, fx), fy);
  const float w = P.materials[n].dpt[k].exp_w;
  return w == 1.0 ? bl : safe_pow(bl, w);
}

// The patch masks of the nx x ny corners from (jx, jy) (at most 8 x 8), bit j * 8 + i for
// corner (jx + i, jy + j): patch_corner() of each.
// `narrow`: the lattice spans less than a weight texel a side (the composer's part bits), so
// its corners' weights blend 3 x 3 weight texels, fetched once, and each column's and row's
// cell and fraction are worked out once: weight_at() of every corner, the same operations on
// the same texels.
uint64_t lattice_masks(int n, int k, int64_t jx, int64_t jy, int nx, int ny, bool narrow) {
  uint64_t bits = 0ul;
  if (!narrow) {
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        if (patch_corner(n, k, jx + int64_t(i), jy + int64_t(j)) > 0.0) bits |= uint64_t(1) << uint(j * 8 + i);
    return bits;
  }
  const int64_t ps = P.materials[n].dpt[k].patch_fp;
  const int layer = P.materials[n].weight_layer;
  const int64_t x0_fp = jx * ps + ps / 2, y0_fp = jy * ps + ps / 2;
  // Each column's and row's fraction, and whether it lies in the cell after the first one's.
  float col_f[8], row_f[8];
  uint col_next = 0u, row_next = 0u;
  int cell_x = 0, cell_y = 0, c0, c1;
  for (int i = 0; i < nx; ++i) {
    int cell;
    weight_axis(x0_fp + int64_t(i) * ps, P.weight_width, cell, c0, c1, col_f[i]);
    if (i == 0) cell_x = cell;
    if (cell != cell_x) col_next |= 1u << uint(i);
  }
  for (int j = 0; j < ny; ++j) {
    int cell;
    weight_axis(y0_fp + int64_t(j) * ps, P.weight_height, cell, c0, c1, row_f[j]);
    if (j == 0) cell_y = cell;
    if (cell != cell_y) row_next |= 1u << uint(j);
  }
  const WeightBlock block = weight_block_from(layer, cell_x, cell_y);
  for (int j = 0; j < ny; ++j) {
    const bool next_row = ((row_next >> uint(j)) & 1u) != 0u;
    for (int i = 0; i < nx; ++i) {
      const bool next = ((col_next >> uint(i)) & 1u) != 0u;
      const float w = block_bilinear(block, next, next_row, col_f[i], row_f[j]);
      if (patch_mask(n, k, jx + int64_t(i), jy + int64_t(j), w)) bits |= uint64_t(1) << uint(j * 8 + i);
    }
  }
  return bits;
}

// One DPT layer's w (eq 4.1-4.3) at a terrain position. Where every layer's patch is narrower
// than a weight texel (TVT_PART_DPT_CORNERS_WIDE clear) its cell's four corners read their
// weights from one 3 x 3 fetch (lattice_masks()): the same masks.
float patch_value(int n, int k, int64_t x_fp, int64_t y_fp) {
  int64_t ix, iy;
  float fx, fy;
  patch_cell(n, k, x_fp, ix, fx);
  patch_cell(n, k, y_fp, iy, fy);
  if (!part(TVT_PART_DPT_CORNERS_WIDE)) {
    const uint bits = uint(lattice_masks(n, k, ix, iy, 2, 2, true));
    return patch_blend(n, k, float(bits & 1u), float((bits >> 1u) & 1u), float((bits >> 8u) & 1u),
                       float((bits >> 9u) & 1u), fx, fy);
  }
  return patch_blend(n, k, patch_corner(n, k, ix, iy), patch_corner(n, k, ix + 1, iy), patch_corner(n, k, ix, iy + 1),
                     patch_corner(n, k, ix + 1, iy + 1), fx, fy);
}

// Prefiltered DPT: the layer's actual values at k x k points over the footprint while its
// patches are few there (reference_compositor.cpp patch_samples). The points share corners,
// so each corner's mask is decided once and every point reads its four: the same masks and
// fractions as patch_value() at each point.
void patch_samples(int n, int k, int64_t x_fp, int64_t y_fp, float footprint, inout float mean, inout float second) {
  const float patches = footprint / max(P.materials[n].dpt[k].patch_texels, 1e-6);
  const float g = ramp(patches, TVT_PATCH_SAMPLES_LO, TVT_PATCH_SAMPLES_HI);
  if (g >= 1.0) return;
  const int kk = patches <= 1.0 ? 2 : 3;
  // The points' cells on each axis from the footprint centre's by its remainder: fewer than
  // TVT_PATCH_SAMPLES_HI patches a side put every point within 4 cells of it, so a float
  // estimate of the quotient is off by at most one and an exact integer step settles it (a
  // division per axis instead of per point: the same cells and fractions as patch_cell()).
  const int64_t ps = P.materials[n].dpt[k].patch_fp;
  const float inv_ps = 1.0 / float(ps);
  int64_t cx, cy;
  float fcx, fcy;
  patch_cell(n, k, x_fp, cx, fcx);
  patch_cell(n, k, y_fp, cy, fcy);
  const int64_t rcx = x_fp - cx * ps, rcy = y_fp - cy * ps;
  int qx[3], qy[3];  // kk <= 3
  float fx[3], fy[3];
  for (int i = 0; i < kk; ++i) {
    const float d = round(((float(i) + 0.5) / float(kk) - 0.5) * footprint * 256.0);
    const int64_t di = int64_t(d);
    int q = int(floor(fcx + d * inv_ps));
    int64_t r = rcx + di - int64_t(q) * ps;
    settle_quotient(q, r, ps);
    qx[i] = q;
    fx[i] = float(int(r)) / float(ps);
    q = int(floor(fcy + d * inv_ps));
    r = rcy + di - int64_t(q) * ps;
    settle_quotient(q, r, ps);
    qy[i] = q;
    fy[i] = float(int(r)) / float(ps);
  }
  // Each corner's mask decided once, into a bit of an 8 x 8 lattice from the first point's
  // cell: below TVT_PATCH_SAMPLES_HI patches a side the points span at most 7 cells. A wider
  // span (the ramp's end, met only through rounding) leaves the layer to its expectation, as
  // the reference does.
  const int nx = qx[kk - 1] - qx[0] + 2, ny = qy[kk - 1] - qy[0] + 2;
  if (nx > 8 || ny > 8) return;
  const uint64_t bits =
      lattice_masks(n, k, cx + int64_t(qx[0]), cy + int64_t(qy[0]), nx, ny, !part(TVT_PART_DPT_SAMPLES_WIDE));
  float s1 = 0.0, s2 = 0.0;
  for (int j = 0; j < kk; ++j)
    for (int i = 0; i < kk; ++i) {
      const uint at = uint(qy[j] - qy[0]) * 8u + uint(qx[i] - qx[0]);
      const float v = patch_blend(n, k, float(uint(bits >> at) & 1u), float(uint(bits >> (at + 1u)) & 1u),
                        float(uint(bits >> (at + 8u)) & 1u), float(uint(bits >> (at + 9u)) & 1u), fx[i], fy[j]);
      s1 += v;
      s2 += v * v;
    }
  s1 /= float(kk * kk);
  s2 /= float(kk * kk);
  mean = mix(s1, mean, g);
  second = mix(s2, second, g);
}

// The samples of the (material, layer) pairs TVT_COMPOSE_SPEC_SAMPLE_PAIRS names: dpt()'s
// expectation from patch_samples() for each, worked out before the material loop with the
// material and layer as constants (a device that runs every branch pays for the samples of
// these pairs alone, not of every material and layer).
float g_pair_expected[TVT_SAMPLE_PAIRS_MAX], g_pair_second[TVT_SAMPLE_PAIRS_MAX];

// Prefiltered DPT layer k of material n (dpt()): how much level 0 shows it (`present`, its
// minification fade at one texel) and its exact share at this footprint.
void layer_shares(int n, int k, float footprint, out float present, out float exact) {
  present = ramp(P.materials[n].dpt[k].patch_texels, P.materials[n].dpt_fade_lo, P.materials[n].dpt_fade_hi);
  exact = ramp(per_footprint(P.materials[n].dpt[k].patch_texels, footprint), P.prefilter_patch_lo, P.prefilter_patch_hi);
}
// Its value's mean and second moment over many patch cells at plain weight `plain` (the
// expectation before any samples).
void layer_expectation(int n, int k, float plain, out float expected, out float second) {
  const float q = clamp01(safe_pow(plain, P.materials[n].dpt[k].exp_p / max(P.materials[n].dpt[k].exp_r, 1e-6)));
  expected = patch_expectation(n, k, q);
  second = patch_second_moment(n, k, q);
}

void sample_pair(int i, int64_t x_fp, int64_t y_fp, float footprint, float plain, uint material_mask) {
  const int n = tvt_sample_pairs_material(k_compose_sample_pairs, i), k = tvt_sample_pairs_layer(k_compose_sample_pairs, i);
  g_pair_expected[i] = 0.0;
  g_pair_second[i] = 0.0;
  // Only where dpt() reads them: the material not culled, the layer in expectation here (as
  // there; a texel with no share of it skips the samples, whose lattices are dear far out).
  float present, exact;
  layer_shares(n, k, footprint, present, exact);
  if ((material_mask & (1u << uint(n))) == 0u || present <= 0.0 || !(present * (1.0 - exact) > 0.0)) return;
  float expected, second;
  layer_expectation(n, k, plain, expected, second);
  patch_samples(n, k, x_fp, y_fp, footprint, expected, second);
  g_pair_expected[i] = expected;
  g_pair_second[i] = second;
}
void sample_pairs(int64_t x_fp, int64_t y_fp, float footprint, float wts[TVT_MAX_MATERIALS], uint material_mask) {
  const uint count = tvt_sample_pairs_count(k_compose_sample_pairs);
  if (count > 0u) sample_pair(0, x_fp, y_fp, footprint, wts[tvt_sample_pairs_material(k_compose_sample_pairs, 0)], material_mask);
  if (count > 1u) sample_pair(1, x_fp, y_fp, footprint, wts[tvt_sample_pairs_material(k_compose_sample_pairs, 1)], material_mask);
}

// DPT eq 4.1-4.4, Algorithms 2-3. Prefiltered: as reference_compositor.cpp dpt(). `plain_b` and
// `plain_dev`: the blend map of the plain weight (and, prefiltered, its deviation), which the
// caller has for the other modes as well.
void dpt(int n, int64_t x_fp, int64_t y_fp, float footprint, float plain, float height_a, bool prefiltered, vec4 a_spread,
         float plain_b, float plain_dev, out float b_out, out float h_out, out float dev) {
  float b = 0.0, h = 0.0, fade_max = 0.0;
  float settled = 0.0, mean = 0.0, var = 0.0, span = 0.0;  // prefiltered: b = settled + X, X in [0, span]
  const int layers = P.materials[n].dpt_layer_count;
  for (int k = 0; k < layers; ++k) {
    const float fade = ramp(per_footprint(P.materials[n].dpt[k].patch_texels, footprint), P.materials[n].dpt_fade_lo,
                            P.materials[n].dpt_fade_hi);
    if (prefiltered) {
      float present, exact;
      layer_shares(n, k, footprint, present, exact);
      fade_max = max(fade_max, present);
      if (present <= 0.0) continue;
      // A cleared part bit: its share is zero for every layer at this footprint (TVT_PART_*).
      const float weight = part(TVT_PART_DPT_EXPECT) ? present * (1.0 - exact) : 0.0;
      const float point = part(TVT_PART_DPT_POINT) && exact > 0.0 ? present * exact * patch_value(n, k, x_fp, y_fp) : 0.0;
      float expected = 0.0, second = 0.0;
      if (part(TVT_PART_DPT_EXPECT) && weight > 0.0) {
        layer_expectation(n, k, plain, expected, second);
        if (part(TVT_PART_DPT_SAMPLES)) patch_samples(n, k, x_fp, y_fp, footprint, expected, second);
        // The pairs' samples, composed before the material loop (sample_pairs()): the same values.
        for (int i = 0; i < TVT_SAMPLE_PAIRS_MAX; ++i)
          if (uint(i) < tvt_sample_pairs_count(k_compose_sample_pairs) &&
              n == tvt_sample_pairs_material(k_compose_sample_pairs, i) && k == tvt_sample_pairs_layer(k_compose_sample_pairs, i)) {
            expected = g_pair_expected[i];
            second = g_pair_second[i];
          }
      }
      settled += point;
      mean += weight * expected;
      var += weight * weight * max(second - expected * expected, 0.0);
      span += weight;  // b is settled + mean here, read by blend_map_of_patches
      h += (point + weight * expected) * P.materials[n].dpt[k].height_h;
      continue;
    }
    fade_max = max(fade_max, fade);
    if (fade <= 0.0) continue;
    const float w = patch_value(n, k, x_fp, y_fp);
    b += fade * w;
    h += fade * w * P.materials[n].dpt[k].height_h;
  }
  b = min(b, 1.0);
  h = min(h, 1.0);
  h_out = h;
  const float s = P.materials[n].blend_sharpness;
  if (prefiltered) {
    float e_patch, d_patch;
    blend_map_of_patches(settled, mean, var, span, height_a, a_spread, s, e_patch, d_patch);
    b_out = fade_max * e_patch + (1.0 - fade_max) * plain_b;
    dev = fade_max * d_patch + (1.0 - fade_max) * plain_dev;
    return;
  }
  dev = 0.0;
  b = blend_map(b, height_a, s);
  b_out = fade_max * b + (1.0 - fade_max) * plain_b;
}

#endif
