#include "compose/packed_scene.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <thread>

#include "shaders/shared/hash.h"

namespace tvt {

struct PackedScene::Cache {
  // The source's words (shared by every packing of the scene) and, when this layout has a
  // meta slot for a material without a meta-texture, this packing's zeros.
  struct Words {
    std::shared_ptr<const MaterialWords> shared;
    std::vector<uint32_t> zero_meta;
    std::span<const uint32_t> meta() const { return shared->has_meta ? shared->meta : zero_meta; }
  };
  struct Material {
    OnceResult<Words> words;
    bool expects_features = false; // an FBPB mode relies on features the pack took on trust
  };
  std::shared_ptr<const MaterialSource> source;
  std::string source_path;
  std::vector<std::unique_ptr<Material>> materials;
  std::vector<gpu::TvtMaterial> layout;  // offsets and sizes, as packed

  // Packs material n once; thread-safe.
  const OnceResult<Words>& get(size_t n) {
    Material& m = *materials[n];
    return m.words.get([&] { return pack(n, m.expects_features); });
  }

  Result<Words> pack(size_t n, bool expects_features) const {
    auto words = source->words(n);
    if (!words) return words.error();
    const MaterialWords& w = *words.value();
    const gpu::TvtMaterial& g = layout[n];
    if (w.resolution != g.resolution || w.mip_count != g.mip_count)
      return make_error(source_path + ": /materials/" + std::to_string(n) +
                        "/albedo: size differs from the one the scene was laid out with");
    Words out{words.value(), {}};
    if (g.meta_offset == gpu::TVT_NO_META) return out;
    if (expects_features && (!w.has_meta || w.feature_count == 0))
      return make_error(source_path + ": /materials/" + std::to_string(n) +
                        "/fbpb: the meta-texture has no features, but the scene was laid out expecting some "
                        "(give a meta-texture or mask with features, or use mode blendmap/dpt)");
    if (!w.has_meta) out.zero_meta.assign(2 * size_t(gpu::tvt_meta_block_texels(uint32_t(g.resolution))), 0u);
    return out;
  }
};

Status PackedScene::load(uint32_t mask) const {
  std::vector<size_t> todo;
  for (size_t n = 0; n < cache_->materials.size() && n < 32; ++n)
    if ((mask & (1u << n)) && !cache_->materials[n]->words.done()) todo.push_back(n);
  // Several materials at once (the top page needs them all): one thread each, at most one per
  // core; the cache makes concurrent first uses safe.
  const size_t workers = std::min<size_t>(todo.size(), std::max(1u, std::thread::hardware_concurrency()));
  if (workers > 1) {
    std::atomic<size_t> next{0};
    auto work = [&] {
      for (size_t i = next++; i < todo.size(); i = next++) cache_->get(todo[i]);
    };
    std::vector<std::jthread> threads;
    for (size_t t = 1; t < workers; ++t) threads.emplace_back(work);
    work();
  }
  for (size_t n = 0; n < cache_->materials.size() && n < 32; ++n)  // first error in material order
    if (mask & (1u << n))
      if (const auto& m = cache_->get(n); m.error()) return *m.error();
  return Ok{};
}

const MaterialSource& PackedScene::source() const { return *cache_->source; }

PackedScene PackedScene::materials_only() const {
  PackedScene s;
  s.params = params;
  s.texel_words = texel_words;
  s.meta_words = meta_words;
  s.cache_ = cache_;
  return s;
}

uint32_t PackedScene::loaded_mask() const {
  uint32_t mask = 0;
  for (size_t n = 0; n < cache_->materials.size() && n < 32; ++n) {
    if (cache_->materials[n]->words.ok()) mask |= 1u << n;
  }
  return mask;
}

std::span<const uint32_t> PackedScene::texels(size_t n) const {
  const auto& m = cache_->get(n);
  TVT_CHECK(!m.error() && "material load failed: call PackedScene::load() first to get the error");
  return m.value().shared->texels;
}

float PackedScene::stat(size_t n, int i) const {
  const gpu::TvtMaterial& m = params.materials[n];
  return std::bit_cast<float>(texels(n)[gpu::tvt_material_stats_offset(uint32_t(m.resolution), uint32_t(m.mip_count)) + size_t(i)]);
}

std::span<const uint32_t> PackedScene::meta(size_t n) const {
  const auto& m = cache_->get(n);
  TVT_CHECK(!m.error() && "material load failed: call PackedScene::load() first to get the error");
  const PackedScene::Cache::Words& w = m.value();
  if (cache_->layout[n].meta_offset == gpu::TVT_NO_META) return {};
  return w.meta();
}

namespace {
constexpr std::pair<Method, std::string_view> k_method_names[] = {
    {Method::Linear, "linear"}, {Method::BlendMap, "blendmap"}, {Method::Fbpb, "fbpb"},
    {Method::Dpt1, "dpt1"},     {Method::Dpt2, "dpt2"},         {Method::FbpbDpt, "fbpb+dpt2"},
};

int mode_code(Mode m) {
  switch (m) {
    case Mode::Linear: return gpu::TVT_MODE_LINEAR;
    case Mode::BlendMap: return gpu::TVT_MODE_BLENDMAP;
    case Mode::Fbpb: return gpu::TVT_MODE_FBPB;
    case Mode::Dpt: return gpu::TVT_MODE_DPT;
    case Mode::FbpbDpt: return gpu::TVT_MODE_FBPB_DPT;
  }
  return gpu::TVT_MODE_BLENDMAP;
}

// The coefficients of E[bilerp(m)^W] over a patch cell (TvtDptLayer::expect): its four corner
// masks m are independent, each 1 with probability q, and (fx, fy) is uniform over the cell.
// Grouped by the number of corners set, the expectation is
//   q^4 + 4 q (1-q)^3 I1 + q^2 (1-q)^2 (4 I2a + 2 I2d) + 4 q^3 (1-q) I3,
// with the mean over the cell of bilerp^W for one corner set (I1), two along an edge (I2a),
// two across a diagonal (I2d) and three (I3). I1 and I2a have closed forms; I2d and I3 are
// integrated numerically (a 128^2 midpoint rule, within ~1e-4 for W in [1e-3, 2e3]; W = 1,
// the common case, is exact: I2d = 1/2, I3 = 3/4).
std::array<double, 3> bilerp_power_expectation(double w) {
  w = std::clamp(std::isfinite(w) ? w : 1.0, 1e-3, 2e3);  // W in [1e-3, 1e3], and 2W
  if (w == 1.0) return {1.0, 3.0, 3.0};
  constexpr int k_n = 128;
  double i2d = 0.0, i3 = 0.0;
  for (int j = 0; j < k_n; ++j)
    for (int i = 0; i < k_n; ++i) {
      const double x = (i + 0.5) / k_n, y = (j + 0.5) / k_n;
      i2d += std::pow(x * y + (1 - x) * (1 - y), w);
      i3 += std::pow(1.0 - (1 - x) * (1 - y), w);
    }
  i2d /= double(k_n) * k_n;
  i3 /= double(k_n) * k_n;
  const double i1 = 1.0 / ((w + 1) * (w + 1)), i2a = 1.0 / (w + 1);
  return {4.0 * i1, 4.0 * i2a + 2.0 * i2d, 4.0 * i3};
}

int64_t to_fixed(double texels) {
  const double v = std::clamp(texels * 256.0, 1.0, 9.0e15);
  return int64_t(std::llround(v));
}
}  // namespace

std::string_view to_string(Method method) {
  for (const auto& [m, n] : k_method_names)
    if (m == method) return n;
  return "?";
}

std::optional<Method> method_from_string(std::string_view text) {
  for (const auto& [m, n] : k_method_names)
    if (n == text) return m;
  return std::nullopt;
}

std::string to_string(MipStrategy strategy) {
  if (strategy.prefiltered) return "prefiltered";
  return strategy.supersample <= 1 ? std::string("direct") : "supersample:" + std::to_string(strategy.supersample);
}

Result<MipStrategy> mip_strategy_from_string(std::string_view text) {
  const auto bad = [&] {
    return make_error("mip strategy: must be direct, prefiltered or supersample:S with S a power of two from 2 to 64, got '" +
                      std::string(text) + "'");
  };
  if (text == "direct") return MipStrategy{};
  if (text == "prefiltered") return MipStrategy{1, true};
  constexpr std::string_view k_prefix = "supersample:";
  if (!text.starts_with(k_prefix)) return bad();
  const std::string_view digits = text.substr(k_prefix.size());
  if (digits.empty() || digits.size() > 2 || !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return bad();
  uint32_t s = 0;
  for (char c : digits) s = s * 10 + uint32_t(c - '0');
  if (s < 2 || s > 64 || !std::has_single_bit(s)) return bad();
  return MipStrategy{s};
}

ComposeOptions options_for(Method method, MipStrategy strategy) {
  ComposeOptions o;
  o.supersample = strategy.supersample;
  o.prefiltered = strategy.prefiltered;
  switch (method) {
    case Method::Linear: o.method = Mode::Linear; break;
    case Method::BlendMap: o.method = Mode::BlendMap; break;
    case Method::Fbpb: o.method = Mode::Fbpb; break;
    case Method::Dpt1: o.method = Mode::Dpt; o.dpt_layer_limit = 1; break;
    case Method::Dpt2: o.method = Mode::Dpt; o.dpt_layer_limit = 2; break;
    case Method::FbpbDpt: o.method = Mode::FbpbDpt; o.dpt_layer_limit = 2; break;
  }
  return o;
}

Result<PackedScene> pack_scene(const SceneAssets& assets, const ComposeOptions& options) {
  const SceneDesc& d = assets.desc;
  if (d.materials.empty() || d.materials.size() > size_t(gpu::TVT_MAX_MATERIALS))
    return make_error(d.source_path + ": /materials: need 1 to 16 materials");
  if (options.supersample < 1 || options.supersample > 64 || !std::has_single_bit(options.supersample))
    return make_error("supersample: must be a power of two from 1 to 64, got " + std::to_string(options.supersample));
  if (options.prefiltered && options.supersample != 1)
    return make_error("mip strategy: prefiltered takes one sample per texel, got supersample " +
                      std::to_string(options.supersample));

  PackedScene out;
  gpu::TvtComposeParams& p = out.params;
  p.log2_vt = int(d.vt.log2_size);
  p.page_texels = int(d.vt.page_texels);
  p.border_texels = int(d.vt.border_texels);
  p.material_count = int(d.materials.size());
  p.weight_width = assets.weights.width;
  p.weight_height = assets.weights.height;
  p.weight_layers = assets.weights.layers;
  p.method_override = options.method ? mode_code(*options.method) : -1;
  p.dpt_layer_limit = int(options.dpt_layer_limit);
  p.supersample = int(options.supersample);
  p.prefiltered = options.prefiltered ? 1 : 0;
  p.prefilter_patch_lo = 0.5f;
  p.prefilter_patch_hi = 2.0f;
  p.linear_boost = float(d.linear_boost);
  out.weights = assets.weights.data;

  const MaterialSource& source = *assets.materials;
  if (source.size() != d.materials.size())
    return make_error(d.source_path + ": /materials: " + std::to_string(d.materials.size()) + " described, " +
                      std::to_string(source.size()) + " loaded");
  out.cache_ = std::make_shared<PackedScene::Cache>();
  out.cache_->source = assets.materials;
  out.cache_->source_path = d.source_path;
  for (size_t n = 0; n < d.materials.size(); ++n) {
    const MaterialDesc& md = d.materials[n];
    const MaterialInfo info = source.info(n);
    gpu::TvtMaterial& g = p.materials[n];
    g.period_fp = to_fixed(md.period_texels);
    g.resolution = info.resolution;
    g.lod_bias = float(std::log2(double(g.resolution) * 256.0 / double(g.period_fp)));
    g.log2_resolution = std::countr_zero(unsigned(g.resolution));
    g.mip_count = info.mip_count;
    g.texel_offset = uint32_t(out.texel_words);
    out.texel_words += size_t(gpu::tvt_material_stats_offset(uint32_t(g.resolution), uint32_t(g.mip_count))) +
                       size_t(gpu::TVT_MATERIAL_STATS_WORDS);
    g.meta_offset = gpu::TVT_NO_META;
    // Not loaded yet: an FBPB block promises features (checked when the material is loaded).
    const bool has_features = info.meta && (!info.features_known || info.feature_count > 0);
    if (has_features) {
      g.meta_offset = uint32_t(out.meta_words / 2);
      out.meta_words += 2 * size_t(gpu::tvt_meta_block_texels(uint32_t(g.resolution)));
    }
    // Effective mode: the override applies to every layer above the base.
    Mode mode = (n > 0 && options.method) ? *options.method : md.mode;
    size_t layers = md.dpt.layers.size();
    if (options.dpt_layer_limit > 0) layers = std::min<size_t>(layers, options.dpt_layer_limit);
    layers = std::min<size_t>(layers, size_t(gpu::TVT_MAX_DPT_LAYERS));
    if (mode == Mode::Fbpb && !has_features) mode = Mode::BlendMap;
    if (mode == Mode::FbpbDpt && !has_features) mode = Mode::Dpt;
    if (mode == Mode::Dpt && layers == 0) mode = Mode::BlendMap;
    if (mode == Mode::FbpbDpt && layers == 0) mode = Mode::Fbpb;
    g.mode = mode_code(mode);
    auto cached = std::make_unique<PackedScene::Cache::Material>();
    cached->expects_features = has_features && !info.features_known && (mode == Mode::Fbpb || mode == Mode::FbpbDpt);
    out.cache_->materials.push_back(std::move(cached));
    g.weight_layer = int(n);
    g.dpt_layer_count = int(layers);
    g.fbpb_salt = gpu::tvt_salt(d.seed, uint32_t(n), 0u, 1u);
    g.variation_salt = gpu::tvt_salt(d.seed, uint32_t(n), 0u, 2u);
    g.cm = float(md.fbpb.cm);
    g.cf = float(md.fbpb.cf);
    g.cn = float(md.fbpb.cn);
    g.variation_threshold = float(md.fbpb.variation_threshold);
    g.colour_coeff = float(md.fbpb.colour_coeff);
    g.blend_sharpness = float(std::clamp(md.blend_sharpness, 1e-3, 0.5));
    g.dpt_fade_lo = float(md.dpt.fade_lo_texels);
    g.dpt_fade_hi = float(md.dpt.fade_hi_texels);
    g.fbpb_fade_lo = float(md.fbpb.fade_lod_lo);
    g.fbpb_fade_hi = float(md.fbpb.fade_lod_hi);
    // Hex-tiling: off for FBPB modes above the base, whose features are found at unshifted
    // texels. The edge is even so that half an edge (the odd rows' shift) is whole texels.
    const bool fbpb_layer = n > 0 && (mode == Mode::Fbpb || mode == Mode::FbpbDpt);
    if (options.hex.value_or(md.hex.enabled) && !fbpb_layer) {
      const double edge = md.hex.edge > 0 ? md.hex.edge : 0.5 * g.resolution;
      g.hex_edge = std::max(2, 2 * int(std::lround(std::clamp(edge, 2.0, 65536.0) / 2.0)));
      g.hex_row = std::max(1, int(std::lround(g.hex_edge * std::sqrt(3.0) / 2.0)));
      g.hex_salt = gpu::tvt_salt(d.seed, uint32_t(n), 0u, 4u);
      g.hex_sharpness = float(std::clamp(md.hex.sharpness, 1.0, 64.0));
      g.hex_preserve = float(std::clamp(md.hex.preserve, 0.0, 1.0));
      g.hex_cut = 1.0f / 64.0f;
    }
    for (size_t k = 0; k < layers; ++k) {
      const DptLayerDesc& l = md.dpt.layers[k];
      gpu::TvtDptLayer& gl = g.dpt[k];
      gl.patch_fp = to_fixed(l.patch_texels);
      gl.exp_p = float(l.p);
      gl.exp_r = float(l.r);
      gl.exp_w = float(l.w);
      gl.height_h = float(l.h);
      gl.salt = gpu::tvt_salt(d.seed, uint32_t(n), uint32_t(k), 3u);
      gl.patch_texels = float(double(gl.patch_fp) / 256.0);
      const std::array<double, 3> e = bilerp_power_expectation(l.w);
      const std::array<double, 3> e_sq = bilerp_power_expectation(2.0 * l.w);  // second moment
      for (size_t i = 0; i < 3; ++i) {
        gl.expect[i] = float(e[i]);
        gl.expect_sq[i] = float(e_sq[i]);
      }
    }
  }
  out.cache_->layout.assign(p.materials, p.materials + d.materials.size());
  return out;
}

}  // namespace tvt
