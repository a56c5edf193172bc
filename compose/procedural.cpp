// Built-in procedural inputs (see procedural.h). Everything here is periodic on the torus of
// the output grid: noise lattices have integer periods, cellular patterns place their sites on
// an integer cell grid and measure distances to the nearest periodic image, and stamped
// strokes wrap their texel coordinates. All randomness is integer hashing (docs/composition.md,
// shaders/shared/hash.h), so outputs are pure functions of (generator, resolution, seed).
//
// Sizes of features are fractions of the resolution, so one material at 256² and at 1024²
// shows the same pattern at different detail; below ~64² a few sizes are clamped to whole
// texels (mortar never narrower than 1.5 texels, blades never thinner than 1 texel).
#include "compose/procedural.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include <glm/glm.hpp>

#include "shaders/shared/hash.h"

namespace tvt {

namespace {

using gpu::tvt_mix32;
using glm::vec3;

constexpr std::array<std::string_view, 6> k_generators{"sand", "grass", "rock", "mud", "cobbles", "bricks"};
constexpr float k_two_pi = 6.28318530717958647692f;

// Hash purposes (the `purpose` word of tvt_salt), one per independent random decision.
enum Purpose : uint32_t {
  kVariation = 1,
  kLow, kMid, kFine, kWarpX, kWarpY, kDetail, kSites, kEdgeNoise, kSpeckle, kBlades, kOffset, kTint,
};

uint32_t salt_of(uint32_t seed, uint32_t generator, uint32_t purpose) {
  return gpu::tvt_salt(seed, generator, 0u, purpose);
}

// r in [0, 1) from the top 24 bits of a hash.
float unit(uint32_t h) { return float(h >> 8u) * 5.9604644775390625e-8f; }
uint32_t hash2(uint32_t x, uint32_t y, uint32_t salt) { return tvt_mix32(tvt_mix32(salt ^ x) ^ (y * 0x9e3779b1u)); }
float hash01(uint32_t x, uint32_t y, uint32_t salt) { return unit(hash2(x, y, salt)); }

float saturate(float v) { return std::clamp(v, 0.f, 1.f); }
float smoothstep(float e0, float e1, float x) {
  const float t = saturate((x - e0) / (e1 - e0));
  return t * t * (3.f - 2.f * t);
}
float quintic(float t) { return t * t * t * (t * (t * 6.f - 15.f) + 10.f); }
int wrap(int v, int n) { return ((v % n) + n) % n; }
float wrapf(float v, float period) { return v - std::floor(v / period) * period; }

// Adds amplitude * (one octave of periodic value noise in [-1, 1]) to `out`. The lattice has
// fx x fy points (fx, fy in [1, size]) and covers the grid exactly once, so the octave is
// periodic with the grid. Lattice rows are hashed on demand and two are kept, so the cost is
// O(size² + fx·fy) with no table of fx·fy entries.
//
// Each octave's lattice is shifted by a hashed fraction of a lattice cell (in 1/256 fixed
// point, so the field stays a function of position / size and a 2x grid samples the same
// pattern): with every lattice point on texel 0, the quintic fade (zero slope at lattice
// points) would make the wrap-around step systematically smoother than interior steps.
void add_value_octave(std::vector<float>& out, uint32_t size, uint32_t fx, uint32_t fy, uint32_t salt, float amplitude) {
  const uint64_t denom = uint64_t(size) * 256u;
  const uint64_t phase_x = (32u + tvt_mix32(salt ^ 0x3c6ef372u) % 193u) * uint64_t(size);
  const uint64_t phase_y = (32u + tvt_mix32(salt ^ 0xa54ff53au) % 193u) * uint64_t(size);
  std::vector<uint32_t> ix0(size), ix1(size);
  std::vector<float> wx(size);
  for (uint32_t x = 0; x < size; ++x) {
    const uint64_t u = uint64_t(x) * fx * 256u + phase_x;
    ix0[x] = uint32_t(u / denom) % fx;
    ix1[x] = (ix0[x] + 1u) % fx;
    wx[x] = quintic(float(double(u % denom) / double(denom)));
  }
  auto lattice_row = [&](uint32_t j, std::vector<float>& row) {
    for (uint32_t i = 0; i < fx; ++i) row[i] = unit(hash2(i, j, salt)) * 2.f - 1.f;
  };
  std::vector<float> row_a(fx), row_b(fx), row_mix(fx);
  uint32_t loaded = UINT32_MAX;
  for (uint32_t y = 0; y < size; ++y) {
    const uint64_t v = uint64_t(y) * fy * 256u + phase_y;
    const uint32_t j0 = uint32_t(v / denom) % fy;
    if (j0 != loaded) {
      lattice_row(j0, row_a);
      lattice_row((j0 + 1u) % fy, row_b);
      loaded = j0;
    }
    const float wy = quintic(float(double(v % denom) / double(denom)));
    for (uint32_t i = 0; i < fx; ++i) row_mix[i] = row_a[i] + (row_b[i] - row_a[i]) * wy;
    float* dst = &out[size_t(y) * size];
    for (uint32_t x = 0; x < size; ++x) {
      const float a = row_mix[ix0[x]];
      dst[x] += amplitude * (a + (row_mix[ix1[x]] - a) * wx[x]);
    }
  }
}

// Integer period for a requested frequency: rounded, at least 1, at most size; non-finite
// requests fall back to 1.
uint32_t period_of(double frequency, uint32_t size) {
  if (!std::isfinite(frequency) || frequency < 1.0) return 1u;
  return uint32_t(std::min(std::round(frequency), double(size)));
}

// Min-max normalisation to [0, 1]: the minimum maps to exactly 0 and the maximum to exactly 1
// ((max - min) / (max - min) is exact in IEEE). A constant field becomes all zeros.
void normalise(std::vector<float>& field) {
  if (field.empty()) return;
  const auto [lo_it, hi_it] = std::minmax_element(field.begin(), field.end());
  const double lo = *lo_it, range = double(*hi_it) - lo;
  if (!(range > 0.0)) {
    std::fill(field.begin(), field.end(), 0.f);
    return;
  }
  for (float& v : field) v = float((double(v) - lo) / range);
}

// Periodic anisotropic fBm in [0, 1] (lacunarity 2), for textures inside this file.
std::vector<float> noise(uint32_t size, uint32_t salt, uint32_t fx, uint32_t fy, uint32_t octaves, float gain = 0.5f) {
  std::vector<float> out(size_t(size) * size, 0.f);
  float amplitude = 1.f;
  for (uint32_t o = 0; o < octaves; ++o) {
    add_value_octave(out, size, std::clamp(fx, 1u, size), std::clamp(fy, 1u, size), tvt_mix32(salt + o * 0x632be5abu),
                     amplitude);
    amplitude *= gain;
    fx *= 2u;
    fy *= 2u;
  }
  normalise(out);
  return out;
}
std::vector<float> noise(uint32_t size, uint32_t salt, uint32_t freq, uint32_t octaves, float gain = 0.5f) {
  return noise(size, salt, freq, freq, octaves, gain);
}

// Ridged multifractal-style sum: each octave folded at its median (1 - |2n - 1|)³, so sharp
// crests appear where the octave crosses 0.5. Result normalised to [0, 1].
std::vector<float> ridged(uint32_t size, uint32_t salt, uint32_t freq, uint32_t octaves) {
  std::vector<float> out(size_t(size) * size, 0.f);
  float amplitude = 1.f;
  for (uint32_t o = 0; o < octaves; ++o) {
    const std::vector<float> n = noise(size, tvt_mix32(salt ^ (o + 1u) * 0x27d4eb2fu), std::min(freq, size), 1u);
    for (size_t i = 0; i < out.size(); ++i) {
      const float r = 1.f - std::fabs(2.f * n[i] - 1.f);
      out[i] += amplitude * r * r * r;
    }
    amplitude *= 0.5f;
    freq *= 2u;
  }
  normalise(out);
  return out;
}

// Jittered-grid sites on the torus: n x n cells of `cell` texels, cell (i, j)'s site at
// ((i + 0.5 + jx) cell + offset.x, ...) with |jx|, |jy| <= jitter. Queries search the 5 x 5
// nearest cells, which contains the nearest site for any jitter < 0.5 and every Voronoi
// neighbour that can bound the query's cell.
class CellSites {
 public:
  CellSites(uint32_t n, float size, float jitter, glm::vec2 offset, uint32_t salt)
      : n_(int(n)), cell_(size / float(n)), offset_(offset) {
    jitter_.resize(size_t(n) * n);
    for (uint32_t j = 0; j < n; ++j)
      for (uint32_t i = 0; i < n; ++i)
        jitter_[j * n + i] = glm::vec2(hash01(i, j, salt) - 0.5f, hash01(i, j, salt ^ 0x5bd1e995u) - 0.5f) * (2.f * jitter);
  }
  void set_jitter(int i, int j, glm::vec2 j01) { jitter_[size_t(wrap(j, n_)) * size_t(n_) + size_t(wrap(i, n_))] = j01; }
  float cell() const { return cell_; }
  int count() const { return n_ * n_; }

  struct Query {
    int site = -1;           // wrapped cell index j * n + i of the nearest site
    float distance = 0.f;    // to the nearest site, texels
    float edge = 0.f;        // exact distance to the nearest Voronoi edge (bisector), texels
    float soft_edge = 0.f;   // smooth minimum of the bisector distances (rounds cell corners)
  };

  // p: texel-space position in [0, size)². soft_k: rounding length of soft_edge (0: none).
  Query query(glm::vec2 p, float soft_k) const {
    const glm::vec2 q = p - offset_;
    const int cx = int(std::floor(q.x / cell_)), cy = int(std::floor(q.y / cell_));
    std::array<glm::vec2, 25> pos;
    std::array<int, 25> idx;
    int best = 0;
    float best_d2 = INFINITY;
    for (int dj = -2, k = 0; dj <= 2; ++dj)
      for (int di = -2; di <= 2; ++di, ++k) {
        const int ci = cx + di, cj = cy + dj;
        idx[size_t(k)] = wrap(cj, n_) * n_ + wrap(ci, n_);
        pos[size_t(k)] = (glm::vec2(float(ci), float(cj)) + 0.5f + jitter_[size_t(idx[size_t(k)])]) * cell_;
        const glm::vec2 d = pos[size_t(k)] - q;
        const float d2 = glm::dot(d, d);
        if (d2 < best_d2) best_d2 = d2, best = k;
      }
    Query out;
    out.site = idx[size_t(best)];
    out.distance = std::sqrt(best_d2);
    const glm::vec2 s = pos[size_t(best)];
    // Bisector distances. A site at distance d_k from q has its bisector with the nearest
    // site at least (d_k - d_best) / 2 away, so the outer ring is skipped once that bound
    // exceeds what the inner ring found (plus the soft-min window).
    std::array<float, 25> bis;
    bis.fill(INFINITY);
    float min_bis = INFINITY;
    const float d_best = std::sqrt(best_d2);
    for (int pass = 0; pass < 2; ++pass) {
      const float reach = d_best + 2.f * (min_bis + 6.f * soft_k);
      const float reach2 = reach * reach;
      for (size_t k = 0; k < 25; ++k) {
        const int kx = int(k % 5) - 2, ky = int(k / 5) - 2;
        const bool inner = std::abs(kx) <= 1 && std::abs(ky) <= 1;
        if (int(k) == best || inner != (pass == 0)) continue;
        const glm::vec2 e = pos[k] - s;
        if (pass == 1) {
          const glm::vec2 dq = pos[k] - q;
          if (glm::dot(dq, dq) >= reach2) continue;
        }
        const float len = glm::length(e);
        bis[k] = len > 0.f ? glm::dot((s + pos[k]) * 0.5f - q, e) / len : INFINITY;
        min_bis = std::min(min_bis, bis[k]);
      }
    }
    out.edge = min_bis;
    out.soft_edge = min_bis;
    if (soft_k > 0.f) {
      float sum = 0.f;
      for (float b : bis)
        if (b < min_bis + 6.f * soft_k) sum += std::exp(-(b - min_bis) / soft_k);
      out.soft_edge = min_bis - soft_k * std::log(sum);
    }
    return out;
  }

 private:
  int n_;
  float cell_;
  glm::vec2 offset_;
  std::vector<glm::vec2> jitter_;
};

// Turns raw per-texel feature ids (-1 = none) into exact labels with the invariants of
// GeneratedMaterial::feature_labels: texels 8-adjacent (on the torus) to a different feature
// become mortar, each raw id keeps only its largest 4-connected component, components smaller
// than min_texels are dropped, and survivors are renumbered 0..count-1 in scan order.
// Removing texels never creates a new adjacency, so the order of the passes makes them final.
uint32_t finalise_labels(uint32_t size, std::vector<int32_t>& labels, uint32_t min_texels) {
  const int n = int(size);
  auto at = [&](int x, int y) { return size_t(wrap(y, n)) * size + size_t(wrap(x, n)); };
  std::vector<uint8_t> touching(labels.size(), 0);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int32_t l = labels[at(x, y)];
      if (l < 0) continue;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int32_t o = labels[at(x + dx, y + dy)];
          if (o >= 0 && o != l) touching[at(x, y)] = 1;
        }
    }
  for (size_t i = 0; i < labels.size(); ++i)
    if (touching[i]) labels[i] = -1;

  // 4-connected components on the torus.
  std::vector<int32_t> component(labels.size(), -1);
  std::vector<uint32_t> comp_size;
  std::vector<int32_t> comp_raw;
  std::vector<size_t> stack;
  for (size_t start = 0; start < labels.size(); ++start) {
    if (labels[start] < 0 || component[start] >= 0) continue;
    const int32_t id = int32_t(comp_size.size());
    const int32_t raw = labels[start];
    uint32_t count = 0;
    component[start] = id;
    stack.push_back(start);
    while (!stack.empty()) {
      const size_t t = stack.back();
      stack.pop_back();
      ++count;
      const int x = int(t % size), y = int(t / size);
      const std::array<size_t, 4> nb{at(x + 1, y), at(x - 1, y), at(x, y + 1), at(x, y - 1)};
      for (size_t m : nb)
        if (labels[m] == raw && component[m] < 0) {
          component[m] = id;
          stack.push_back(m);
        }
    }
    comp_size.push_back(count);
    comp_raw.push_back(raw);
  }
  // Largest component per raw id (first found wins ties).
  const int32_t max_raw = comp_raw.empty() ? -1 : *std::max_element(comp_raw.begin(), comp_raw.end());
  std::vector<int32_t> best(size_t(max_raw + 1), -1);
  for (size_t c = 0; c < comp_size.size(); ++c) {
    int32_t& b = best[size_t(comp_raw[c])];
    if (b < 0 || comp_size[c] > comp_size[size_t(b)]) b = int32_t(c);
  }
  std::vector<int32_t> final_id(comp_size.size(), -1);
  uint32_t next = 0;
  for (size_t c = 0; c < comp_size.size(); ++c)
    if (best[size_t(comp_raw[c])] == int32_t(c) && comp_size[c] >= min_texels) final_id[c] = int32_t(next++);
  for (size_t i = 0; i < labels.size(); ++i) labels[i] = component[i] >= 0 ? final_id[size_t(component[i])] : -1;
  return next;
}

// Working canvas: albedo (sRGB-encoded values in [0, 1]) and height in [0, 1].
struct Canvas {
  uint32_t size;
  std::vector<vec3> rgb;
  std::vector<float> height;
  explicit Canvas(uint32_t s) : size(s), rgb(size_t(s) * s, vec3(0.f)), height(size_t(s) * s, 0.f) {}
};

uint8_t to_u8(float v) { return uint8_t(std::lround(saturate(v) * 255.f)); }

ImageRGBA8 to_image(const Canvas& c) {
  ImageRGBA8 img(int(c.size), int(c.size));
  for (size_t i = 0; i < c.rgb.size(); ++i) {
    img.texels[i * 4 + 0] = to_u8(c.rgb[i].r);
    img.texels[i * 4 + 1] = to_u8(c.rgb[i].g);
    img.texels[i * 4 + 2] = to_u8(c.rgb[i].b);
    img.texels[i * 4 + 3] = to_u8(c.height[i]);
  }
  return img;
}

// ---------------------------------------------------------------------------------------------
// Materials without features.

// Warm beige sand: per-grain speckle, soft wind ripples (a tilted sine with integer wave
// vector, domain-warped by periodic noise), broad tonal drift; low height variation.
Canvas make_sand(uint32_t R, uint32_t seed, uint32_t g) {
  Canvas c(R);
  const auto low = noise(R, salt_of(seed, g, kLow), 3, 4);
  const auto warp = noise(R, salt_of(seed, g, kWarpX), 4, 3);
  const auto mid = noise(R, salt_of(seed, g, kMid), std::max(1u, R / 16), 3);
  const auto fine = noise(R, salt_of(seed, g, kFine), std::max(1u, R / 4), 2, 0.7f);
  const uint32_t speckle = salt_of(seed, g, kSpeckle);
  const float kx = float(std::clamp(R / 64u, 1u, 4u)), ky = float(std::clamp(R / 4u, 2u, 15u));
  const vec3 base(0.80f, 0.68f, 0.49f), pale(0.88f, 0.80f, 0.63f), dark(0.62f, 0.50f, 0.34f);
  for (uint32_t y = 0; y < R; ++y)
    for (uint32_t x = 0; x < R; ++x) {
      const size_t i = size_t(y) * R + x;
      const float phase = (kx * float(x) + ky * float(y)) / float(R) + 1.6f * warp[i];
      // Asymmetric ripple: gentle windward slope, steeper lee face.
      const float s = 0.5f + 0.5f * std::sin(k_two_pi * phase);
      const float ripple = std::pow(s, 1.6f);
      const float grain = hash01(x, y, speckle);
      vec3 col = base * (0.90f + 0.16f * low[i]);
      col = glm::mix(col, pale, 0.22f * ripple);
      col = glm::mix(col, dark, 0.18f * (1.f - ripple) * (0.6f + 0.4f * mid[i]));
      col *= 0.93f + 0.10f * fine[i] + 0.06f * (grain - 0.5f);
      if (grain > 0.985f) col = glm::mix(col, vec3(0.35f, 0.30f, 0.26f), 0.6f);  // dark mineral grains
      if (grain < 0.02f) col = glm::mix(col, vec3(0.97f, 0.94f, 0.86f), 0.6f);   // quartz glints
      c.rgb[i] = col;
      c.height[i] = 0.38f + 0.14f * ripple + 0.12f * low[i] + 0.05f * fine[i] + 0.03f * grain;
    }
  return c;
}

// Grass seen from above: dark soil, then thousands of short blades stamped with a z-buffer in
// random directions, denser and brighter in clumps, hue drifting between yellow- and
// blue-greens at two scales.
Canvas make_grass(uint32_t R, uint32_t seed, uint32_t g) {
  Canvas c(R);
  const auto clump = noise(R, salt_of(seed, g, kLow), std::min(R, 6u), 4, 0.55f);
  const auto hue = noise(R, salt_of(seed, g, kMid), std::min(R, 3u), 3);
  const auto lay = noise(R, salt_of(seed, g, kWarpX), std::min(R, 2u), 2);
  const auto soil = noise(R, salt_of(seed, g, kFine), std::max(1u, R / 8), 3);
  for (size_t i = 0; i < c.rgb.size(); ++i) {
    c.rgb[i] = glm::mix(vec3(0.10f, 0.09f, 0.05f), vec3(0.16f, 0.20f, 0.08f), soil[i]);
    c.height[i] = 0.05f + 0.15f * soil[i];
  }
  const float fr = float(R);
  const float width = std::max(1.f, fr / 512.f);
  const float mean_len = std::max(2.f, fr * 0.022f);
  const uint64_t blades = uint64_t(1.9 * double(R) * double(R) / (double(mean_len) * double(width)));
  const uint32_t salt = salt_of(seed, g, kBlades);
  const vec3 yellow(0.58f, 0.62f, 0.22f), green(0.24f, 0.46f, 0.12f), blue(0.12f, 0.34f, 0.16f);
  for (uint64_t b = 0; b < blades; ++b) {
    const uint32_t lo = uint32_t(b), hi = uint32_t(b >> 32);
    const uint32_t h0 = hash2(lo, hi, salt), h1 = tvt_mix32(h0 ^ 0x68e31da4u), h2 = tvt_mix32(h1 ^ 0xb5297a4du),
                   h3 = tvt_mix32(h2 ^ 0x1b56c4e9u);
    const float ox = unit(h0) * fr, oy = unit(h1) * fr;
    const size_t oi = size_t(std::min(uint32_t(oy), R - 1)) * R + std::min(uint32_t(ox), R - 1);
    // Clumps: fewer blades where the clump field is low.
    if (unit(h2) > 0.25f + 0.75f * clump[oi]) continue;
    const float angle = k_two_pi * (0.55f * unit(h3) + 1.3f * lay[oi]);
    const float len = mean_len * (0.5f + unit(tvt_mix32(h3)) );
    const glm::vec2 dir(std::cos(angle), std::sin(angle)), side(-dir.y, dir.x);
    const float tone = saturate(hue[oi] + 0.35f * (unit(tvt_mix32(h2 + 7u)) - 0.5f));
    vec3 col = tone < 0.5f ? glm::mix(blue, green, tone * 2.f) : glm::mix(green, yellow, tone * 2.f - 1.f);
    col *= 0.75f + 0.45f * clump[oi];
    const float z_root = 0.25f + 0.2f * clump[oi], z_tip = z_root + 0.35f + 0.2f * unit(tvt_mix32(h1 + 3u));
    const int steps = std::max(2, int(std::ceil(len * 2.f)));
    for (int s = 0; s <= steps; ++s) {
      const float t = float(s) / float(steps);
      // Blades taper: the last third is one texel wide.
      const float w = t < 0.66f ? width : 1.f;
      for (float k = 0.f; k < w; k += 1.f) {
        const glm::vec2 p = glm::vec2(ox, oy) + dir * (t * len) + side * (k - 0.5f * (w - 1.f));
        const size_t ti = size_t(wrap(int(std::floor(p.y)), int(R))) * R + size_t(wrap(int(std::floor(p.x)), int(R)));
        const float z = z_root + (z_tip - z_root) * t;
        if (z > c.height[ti]) {
          c.height[ti] = z;
          c.rgb[ti] = col * (0.72f + 0.42f * t);
        }
      }
    }
  }
  return c;
}

// Grey-brown rock: ridged noise for sharp crests, two generations of cracks (exact distance
// to the edges of a domain-warped periodic Voronoi diagram), brown staining; strong height.
Canvas make_rock(uint32_t R, uint32_t seed, uint32_t g) {
  Canvas c(R);
  const auto base = noise(R, salt_of(seed, g, kLow), std::min(R, 3u), 5);
  const auto ridge = ridged(R, salt_of(seed, g, kMid), std::min(R, 4u), 6);
  const auto fine = noise(R, salt_of(seed, g, kFine), std::max(1u, R / 8), 3, 0.6f);
  const auto stain = noise(R, salt_of(seed, g, kTint), std::min(R, 4u), 4);
  const auto wx = noise(R, salt_of(seed, g, kWarpX), std::min(R, 5u), 3);
  const auto wy = noise(R, salt_of(seed, g, kWarpY), std::min(R, 5u), 3);
  const uint32_t speckle = salt_of(seed, g, kSpeckle);
  const float fr = float(R);
  const CellSites big(std::clamp(R / 16u, 1u, 5u), fr, 0.45f, glm::vec2(0.f), salt_of(seed, g, kSites));
  const CellSites small(std::clamp(R / 8u, 1u, 13u), fr, 0.45f, glm::vec2(0.f), salt_of(seed, g, kSites) ^ 0xabcdefu);
  const float w_big = std::max(0.7f, fr * 0.004f), w_small = std::max(0.5f, fr * 0.0022f);
  std::vector<float> h(c.height.size());
  std::vector<float> crack(c.height.size());
  for (uint32_t y = 0; y < R; ++y)
    for (uint32_t x = 0; x < R; ++x) {
      const size_t i = size_t(y) * R + x;
      const glm::vec2 p(float(x) + 0.5f + (wx[i] - 0.5f) * fr * 0.08f, float(y) + 0.5f + (wy[i] - 0.5f) * fr * 0.08f);
      const glm::vec2 pw(wrapf(p.x, fr), wrapf(p.y, fr));
      float k = 1.f - smoothstep(0.f, w_big * (0.6f + fine[i]), big.query(pw, 0.f).edge);
      // Hairline cracks only in fractured zones, so the surface does not read as dried mud.
      const float fractured = smoothstep(0.5f, 0.7f, stain[(i + size_t(R / 2) * R) % stain.size()]);
      if (fractured > 0.f)
        k = std::max(k, 0.7f * fractured * (1.f - smoothstep(0.f, w_small * (0.5f + fine[i]), small.query(pw, 0.f).edge)));
      crack[i] = k;
      h[i] = 0.6f * ridge[i] + 0.25f * base[i] + 0.15f * fine[i] - 0.5f * k;
    }
  normalise(h);
  const vec3 grey(0.47f, 0.46f, 0.44f), brown(0.50f, 0.40f, 0.31f), deep(0.13f, 0.12f, 0.11f);
  for (size_t i = 0; i < h.size(); ++i) {
    const uint32_t x = uint32_t(i % R), y = uint32_t(i / R);
    vec3 col = glm::mix(grey, brown, smoothstep(0.35f, 0.8f, stain[i]));
    col *= 0.55f + 0.75f * h[i] + 0.10f * (hash01(x, y, speckle) - 0.5f) + 0.12f * (fine[i] - 0.5f);
    col = glm::mix(col, deep, 0.85f * crack[i]);
    c.rgb[i] = col;
    c.height[i] = h[i];
  }
  return c;
}

// Dark brown mud: smooth multi-scale undulation, wet patches (darker, flat, low) with slightly
// raised lighter drying rims, fine silt grain.
Canvas make_mud(uint32_t R, uint32_t seed, uint32_t g) {
  Canvas c(R);
  const auto base = noise(R, salt_of(seed, g, kLow), std::min(R, 2u), 5);
  const auto wet = noise(R, salt_of(seed, g, kMid), std::min(R, 3u), 3, 0.45f);
  const auto clods = ridged(R, salt_of(seed, g, kTint), std::max(1u, R / 32), 3);
  const auto detail = noise(R, salt_of(seed, g, kFine), std::max(1u, R / 32), 4, 0.6f);
  const auto silt = noise(R, salt_of(seed, g, kDetail), std::max(1u, R / 4), 2);
  const vec3 mud(0.33f, 0.23f, 0.15f), dry(0.42f, 0.32f, 0.22f), wet_col(0.15f, 0.10f, 0.07f);
  for (size_t i = 0; i < c.rgb.size(); ++i) {
    const float wm = smoothstep(0.58f, 0.76f, wet[i] + 0.06f * (detail[i] - 0.5f));
    const float rim = smoothstep(0.48f, 0.6f, wet[i]) * (1.f - smoothstep(0.6f, 0.68f, wet[i]));
    vec3 col = mud * (0.80f + 0.35f * base[i]) * (0.92f + 0.16f * detail[i]) * (0.95f + 0.1f * silt[i]) *
               (0.9f + 0.2f * clods[i]);
    col = glm::mix(col, dry, 0.45f * rim);
    col = glm::mix(col, wet_col * (0.85f + 0.3f * detail[i]), 0.85f * wm);
    c.rgb[i] = col;
    const float land = 0.35f + 0.35f * base[i] + 0.08f * detail[i] + 0.06f * clods[i] + 0.03f * silt[i] + 0.06f * rim;
    c.height[i] = glm::mix(land, 0.22f + 0.02f * detail[i], wm);
  }
  return c;
}

// ---------------------------------------------------------------------------------------------
// Materials with salient features.

struct Features {
  std::vector<int32_t> labels;
  std::vector<float> inset;  // texels from the feature's boundary (<= 0 in mortar)
  uint32_t count = 0;
};

// Cobbles: rounded stones in the cells of a periodic jittered grid; a stone is the part of its
// Voronoi cell whose rounded distance to the cell edges exceeds the mortar half-width (plus
// noise that only widens the mortar). One stone is centred on the tile corner, so the corner
// wrap is always exercised.
Canvas make_cobbles(uint32_t R, uint32_t seed, uint32_t g, Features& f) {
  Canvas c(R);
  const float fr = float(R);
  const uint32_t n = std::clamp(R / 8u, 2u, 8u);
  CellSites sites(n, fr, 0.28f, glm::vec2(0.5f * fr / float(n)), salt_of(seed, g, kSites));
  const uint32_t corner_salt = salt_of(seed, g, kOffset);
  sites.set_jitter(int(n) - 1, int(n) - 1,
                   glm::vec2(hash01(1, 0, corner_salt) - 0.5f, hash01(0, 1, corner_salt) - 0.5f) * 0.15f);
  const float cell = sites.cell();
  const float mortar = std::max(0.75f, 0.05f * cell);
  const float round_k = 0.10f * cell;
  const auto edge_noise = noise(R, salt_of(seed, g, kEdgeNoise), std::min(R, n * 4), 3);
  f.labels.assign(size_t(R) * R, -1);
  f.inset.assign(size_t(R) * R, 0.f);
  std::vector<int32_t> site_of(size_t(R) * R);
  for (uint32_t y = 0; y < R; ++y)
    for (uint32_t x = 0; x < R; ++x) {
      const size_t i = size_t(y) * R + x;
      const auto q = sites.query(glm::vec2(float(x) + 0.5f, float(y) + 0.5f), round_k);
      const float threshold = mortar + 0.07f * cell * edge_noise[i];
      f.inset[i] = q.soft_edge - threshold;
      site_of[i] = q.site;
      if (f.inset[i] > 0.f) f.labels[i] = q.site;
    }
  f.count = finalise_labels(R, f.labels, 8u);

  std::vector<float> peak(f.count, 0.f);
  std::vector<int32_t> stone_site(f.count, 0);
  for (size_t i = 0; i < f.labels.size(); ++i)
    if (f.labels[i] >= 0) {
      peak[size_t(f.labels[i])] = std::max(peak[size_t(f.labels[i])], f.inset[i]);
      stone_site[size_t(f.labels[i])] = site_of[i];
    }
  const auto speck = noise(R, salt_of(seed, g, kFine), std::max(1u, R / 4), 2);
  const auto mottle = noise(R, salt_of(seed, g, kMid), std::min(R, n * 3), 3);
  const auto grit = noise(R, salt_of(seed, g, kDetail), std::max(1u, R / 2), 1);
  const uint32_t tint_salt = salt_of(seed, g, kTint);
  for (size_t i = 0; i < f.labels.size(); ++i) {
    const int32_t l = f.labels[i];
    if (l >= 0) {
      const uint32_t s = uint32_t(stone_site[size_t(l)]);
      const float t = saturate(f.inset[i] / std::max(peak[size_t(l)], 1e-3f));
      const float dome = std::sqrt(1.f - (1.f - t) * (1.f - t));
      const float grey = 0.40f + 0.24f * hash01(s, 1, tint_salt);
      const float tint = hash01(s, 2, tint_salt) - 0.5f;
      vec3 col = vec3(grey) + tint * vec3(0.10f, 0.02f, -0.08f);
      col *= (0.86f + 0.14f * mottle[i]) * (0.92f + 0.16f * speck[i]);
      col *= 0.72f + 0.28f * dome;
      c.rgb[i] = col;
      c.height[i] = 0.45f + 0.5f * dome * (0.85f + 0.15f * hash01(s, 3, tint_salt)) + 0.03f * (speck[i] - 0.5f);
    } else {
      // Mortar: sandy grey grit, shaded darker close to the stones.
      const float near = smoothstep(-2.f * mortar, 0.f, f.inset[i]);
      vec3 col = vec3(0.50f, 0.48f, 0.44f) * (0.78f + 0.3f * grit[i]) * (0.9f + 0.1f * mottle[i]);
      c.rgb[i] = col * (1.f - 0.30f * near);
      c.height[i] = 0.08f + 0.16f * grit[i] + 0.10f * near;
    }
  }
  return c;
}

// Bricks in running bond: `rows` courses (even, so the alternating half-brick offset wraps),
// `per_row` bricks per course; the tile is shifted by half a brick so one brick sits on the
// corner. Rounded-rectangle insets with noisy chipped edges; per-brick tint and burn.
Canvas make_bricks(uint32_t R, uint32_t seed, uint32_t g, Features& f) {
  Canvas c(R);
  const float fr = float(R);
  const uint32_t rows = std::max(2u, std::min(12u, (R / 5u) & ~1u));
  const uint32_t per_row = std::max(1u, rows / 3u);
  const float bh = fr / float(rows), bl = fr / float(per_row);
  const float mortar = std::max(0.75f, 0.075f * bh);
  const float corner_r = 0.18f * bh;
  const uint32_t off_salt = salt_of(seed, g, kOffset);
  const float off_x = bl * (0.5f + 0.2f * (hash01(0, 0, off_salt) - 0.5f)), off_y = 0.5f * bh;
  const auto chip = noise(R, salt_of(seed, g, kEdgeNoise), std::min(R, rows * 3), 3);
  f.labels.assign(size_t(R) * R, -1);
  f.inset.assign(size_t(R) * R, 0.f);
  std::vector<int32_t> brick_of(size_t(R) * R);
  for (uint32_t y = 0; y < R; ++y)
    for (uint32_t x = 0; x < R; ++x) {
      const size_t i = size_t(y) * R + x;
      const float py = wrapf(float(y) + 0.5f + off_y, fr);
      const uint32_t row = std::min(uint32_t(py / bh), rows - 1);
      const float v = py - float(row) * bh;
      const float px = float(x) + 0.5f + off_x - (row % 2u ? 0.5f * bl : 0.f);
      const float col_f = std::floor(px / bl);
      const float u = px - col_f * bl;
      const uint32_t col = uint32_t(wrap(int(col_f), int(per_row)));
      const float du = std::min(u, bl - u), dv = std::min(v, bh - v);
      float inset = std::min(du, dv);
      if (du < corner_r && dv < corner_r) inset = corner_r - glm::length(glm::vec2(corner_r - du, corner_r - dv));
      f.inset[i] = inset - (mortar + 0.05f * bh * chip[i]);
      brick_of[i] = int32_t(row * per_row + col);
      if (f.inset[i] > 0.f) f.labels[i] = brick_of[i];
    }
  f.count = finalise_labels(R, f.labels, 8u);

  std::vector<int32_t> brick_id(f.count, 0);
  for (size_t i = 0; i < f.labels.size(); ++i)
    if (f.labels[i] >= 0) brick_id[size_t(f.labels[i])] = brick_of[i];
  const auto grain = noise(R, salt_of(seed, g, kFine), std::max(1u, R / 4), 2);
  const auto blotch = noise(R, salt_of(seed, g, kMid), std::min(R, rows * 2), 3);
  const auto sand = noise(R, salt_of(seed, g, kDetail), std::max(1u, R / 2), 1);
  const uint32_t tint_salt = salt_of(seed, g, kTint), speckle = salt_of(seed, g, kSpeckle);
  const vec3 red(0.56f, 0.25f, 0.17f), orange(0.66f, 0.36f, 0.22f), burnt(0.32f, 0.17f, 0.13f);
  const float bevel = std::max(1.f, 0.12f * bh);
  for (size_t i = 0; i < f.labels.size(); ++i) {
    const int32_t l = f.labels[i];
    if (l >= 0) {
      const uint32_t b = uint32_t(brick_id[size_t(l)]);
      const float r0 = hash01(b, 1, tint_salt), r1 = hash01(b, 2, tint_salt), r2 = hash01(b, 3, tint_salt);
      vec3 col = glm::mix(red, orange, r0);
      if (r1 < 0.18f) col = glm::mix(col, burnt, 0.6f + r0 * 0.3f);  // over-fired bricks
      col *= (0.85f + 0.3f * r2) * (0.88f + 0.2f * grain[i]) * (0.9f + 0.15f * blotch[i]);
      if (hash01(uint32_t(i % R), uint32_t(i / R), speckle) > 0.97f) col *= 0.6f;  // pits
      const float edge = smoothstep(0.f, bevel, f.inset[i]);
      c.rgb[i] = col * (0.78f + 0.22f * edge);
      c.height[i] = 0.5f + 0.32f * edge + 0.08f * r2 + 0.08f * grain[i];
    } else {
      const float near = smoothstep(-1.5f * mortar, 0.f, f.inset[i]);
      c.rgb[i] = vec3(0.63f, 0.61f, 0.57f) * (0.8f + 0.25f * sand[i]) * (1.f - 0.28f * near);
      c.height[i] = 0.10f + 0.18f * sand[i] + 0.08f * near;
    }
  }
  return c;
}

bool is_power_of_two(uint32_t v) { return v != 0 && (v & (v - 1u)) == 0; }

}  // namespace

bool is_known_generator(std::string_view generator) {
  return std::find(k_generators.begin(), k_generators.end(), generator) != k_generators.end();
}

std::vector<float> fbm_grid(uint32_t size, uint32_t seed, uint32_t octaves, double frequency, double gain,
                            double lacunarity) {
  if (size == 0) return {};
  std::vector<float> out(size_t(size) * size, 0.f);
  octaves = std::clamp(octaves, 1u, 32u);
  if (!std::isfinite(gain)) gain = 0.5;
  if (!std::isfinite(lacunarity)) lacunarity = 2.0;
  // Amplitudes relative to the largest one, so any finite gain stays finite (|a| <= 1).
  std::vector<double> amplitude(octaves, 1.0);
  for (uint32_t o = 1; o < octaves; ++o) {
    amplitude[o] = amplitude[o - 1] * gain;
    if (std::fabs(amplitude[o]) > 1e100)
      for (uint32_t k = 0; k <= o; ++k) amplitude[k] *= 1e-100;
  }
  double largest = 0.0;
  for (double a : amplitude) largest = std::max(largest, std::fabs(a));
  double f = double(period_of(frequency, size));
  for (uint32_t o = 0; o < octaves; ++o) {
    const uint32_t period = period_of(f, size);
    const float a = float(amplitude[o] / largest);
    if (a != 0.f) add_value_octave(out, size, period, period, gpu::tvt_salt(seed, o, 0u, 0x66626du), a);
    f = double(period) * lacunarity;
  }
  normalise(out);
  return out;
}

Result<GeneratedMaterial> generate_material(std::string_view generator, uint32_t resolution, uint32_t seed) {
  const auto it = std::find(k_generators.begin(), k_generators.end(), generator);
  if (it == k_generators.end())
    return make_error("generate_material: unknown generator '" + std::string(generator) +
                      "' (known: sand, grass, rock, mud, cobbles, bricks)");
  if (!is_power_of_two(resolution) || resolution < 16 || resolution > 4096)
    return make_error("generate_material: generator '" + std::string(generator) + "': resolution " +
                      std::to_string(resolution) + " is not a power of two in 16..4096");
  const uint32_t g = uint32_t(it - k_generators.begin()) + 1u;
  GeneratedMaterial m;
  Features f;
  const uint32_t R = resolution;
  switch (g) {
    case 1: m.albedo = to_image(make_sand(R, seed, g)); break;
    case 2: m.albedo = to_image(make_grass(R, seed, g)); break;
    case 3: m.albedo = to_image(make_rock(R, seed, g)); break;
    case 4: m.albedo = to_image(make_mud(R, seed, g)); break;
    case 5: m.albedo = to_image(make_cobbles(R, seed, g, f)); break;
    default: m.albedo = to_image(make_bricks(R, seed, g, f)); break;
  }
  if (g >= 5) {
    m.feature_labels = std::move(f.labels);
    m.feature_count = f.count;
  }
  // FBPB variation map (Algorithm 1): fBm over several scales, full 8-bit range.
  const auto v = noise(R, salt_of(seed, g, kVariation), std::min(R, 4u), 6, 0.55f);
  m.variation = ImageGray8(int(R), int(R));
  for (size_t i = 0; i < v.size(); ++i) m.variation.texels[i] = to_u8(v[i]);
  return m;
}

ImageGray8 variation_noise(uint32_t resolution, uint32_t seed) {
  const auto grid = fbm_grid(resolution, seed, 5, 4.0, 0.55, 2.0);
  ImageGray8 out{int(resolution), int(resolution)};
  for (size_t i = 0; i < grid.size(); ++i)
    out.texels[i] = uint8_t(std::lround((std::isfinite(grid[i]) ? std::clamp(grid[i], 0.f, 1.f) : 0.f) * 255.0));
  return out;
}

}  // namespace tvt
