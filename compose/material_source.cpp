#include "compose/material_source.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <bit>
#include <chrono>
#include <cmath>

#include <glm/glm.hpp>

#include "compose/material_image.h"
#include "compose/procedural.h"
#include "shaders/shared/compose_types.h"
#include "shaders/shared/hash.h"
#include "streaming/store_format.h"

namespace tvt {

namespace {

std::string material_ptr(size_t index, const char* what) {
  return "/materials/" + std::to_string(index) + "/" + what;
}


std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

MaterialImageOptions image_options(const MaterialDesc& m) {
  MaterialImageOptions o;
  o.height = m.albedo.height_source;
  o.height_path = m.albedo.height_path;
  o.invert_height = m.albedo.height_invert;
  o.resolution = int(m.albedo.image_resolution);
  return o;
}

// The field an image error belongs to: the albedo image or its separate height image.
std::string image_field(const SceneDesc& d, size_t index, bool height_failed) {
  return scene_field(d, material_ptr(index, height_failed ? "albedo/height" : "albedo/image"));
}

Status check_meta_size(const SceneDesc& d, size_t index, int resolution, int albedo) {
  if (resolution != albedo)
    return make_error(scene_field(d, material_ptr(index, "fbpb/meta")) + ": " + d.materials[index].fbpb.meta_path +
                      ": resolution " + std::to_string(resolution) + " differs from the albedo's " +
                      std::to_string(albedo));
  return Ok{};
}

// Masks are drawn on the albedo image as given, so they must have its size; they are
// resampled with it (nearest texel, a mask is binary).
Status check_mask_size(const SceneDesc& d, size_t index, int width, int height, int albedo_w, int albedo_h,
                       int resolution) {
  if (!mask_size_fits(width, height, albedo_w, albedo_h, resolution))
    return make_error(scene_field(d, material_ptr(index, "fbpb/mask")) + ": " + d.materials[index].fbpb.mask_path +
                      ": size " + size_text(width, height) + " differs from the albedo image's " +
                      size_text(albedo_w, albedo_h) +
                      (albedo_w == resolution && albedo_h == resolution
                           ? std::string()
                           : " and from the material's " + size_text(resolution, resolution)));
  return Ok{};
}

// Header of an image a field names; the error carries the field.
Result<ImageHeader> header(const SceneDesc& d, const std::string& pointer, const std::string& path) {
  auto h = read_image_header(path);
  if (!h) return make_error(scene_field(d, pointer) + ": " + h.error().message);
  return h;
}

// What open() checks of material `index` without reading texels; fills `info`.
Status check_headers(const SceneDesc& d, size_t index, MaterialInfo& info) {
  const MaterialDesc& m = d.materials[index];
  int albedo_w = 0, albedo_h = 0;
  if (m.albedo.image_path.empty()) {
    info.resolution = int(m.albedo.resolution);  // the generator validates it on first use
  } else {
    bool height_failed = false;
    auto r = material_image_resolution(m.albedo.image_path, image_options(m), &height_failed);
    if (!r) return make_error(image_field(d, index, height_failed) + ": " + r.error().message);
    info.resolution = r.value();
    auto h = read_image_header(m.albedo.image_path);
    if (!h) return make_error(image_field(d, index, false) + ": " + h.error().message);
    albedo_w = h->width;
    albedo_h = h->height;
    const MaterialImageOptions o = image_options(m);
    HeightSource source = o.height;
    if (source == HeightSource::Auto)
      source = !o.height_path.empty() ? HeightSource::File
               : (h->channels == 2 || h->channels >= 4) ? HeightSource::Alpha
                                                        : HeightSource::Luminance;
    info.image_note = m.albedo.image_path + ": " + size_text(albedo_w, albedo_h) + ", " + std::to_string(h->channels) +
                      " channel(s), " +
                      (albedo_w == info.resolution && albedo_h == info.resolution
                           ? "used as it is"
                           : "resampled to " + size_text(info.resolution, info.resolution) + " (Lanczos-3, wrap)") +
                      ", height from " + std::string(to_string(source)) +
                      (source == HeightSource::Alpha && o.height == HeightSource::Auto ? " (luminance if constant)" : "") +
                      (source == HeightSource::Luminance && o.invert_height ? " (inverted)" : "");
    // Features from the image alone: what the user cannot see in the scene, and how to look.
    if (m.has_fbpb && m.fbpb.meta_path.empty() && m.fbpb.mask_path.empty())
      info.image_note += ", FBPB features isolated automatically at first use (`terravt metatex --input " +
                         m.albedo.image_path + " --debug <png>` shows them)";
  }
  info.mip_count = std::countr_zero(unsigned(std::max(info.resolution, 1))) + 1;
  info.meta = m.has_fbpb;
  if (m.has_fbpb && !m.fbpb.meta_path.empty()) {
    auto h = header(d, material_ptr(index, "fbpb/meta"), m.fbpb.meta_path);
    if (!h) return h.error();
    if (auto s = check_meta_size(d, index, h->width, info.resolution); !s) return s;
  } else if (m.has_fbpb && !m.fbpb.mask_path.empty()) {
    auto h = header(d, material_ptr(index, "fbpb/mask"), m.fbpb.mask_path);
    if (!h) return h.error();
    if (auto s = check_mask_size(d, index, h->width, h->height, albedo_w ? albedo_w : info.resolution,
                                 albedo_h ? albedo_h : info.resolution, info.resolution);
        !s)
      return s;
  }
  return Ok{};
}

Result<ImageRGBA8> load_albedo(const SceneDesc& d, size_t index, GeneratedMaterial* generated,
                               MaterialImageReport* report) {
  const MaterialDesc& m = d.materials[index];
  if (m.albedo.image_path.empty()) {
    const uint32_t seed = m.albedo.seed ? m.albedo.seed : derived_asset_seed(d.seed, uint32_t(index), 1);
    auto g = generate_material(m.albedo.generator, m.albedo.resolution, seed);
    if (!g) return make_error(scene_field(d, material_ptr(index, "albedo/generator")) + ": " + g.error().message);
    *generated = std::move(g.value());
    return generated->albedo;
  }
  bool height_failed = false;
  auto img = load_material_image(m.albedo.image_path, image_options(m), &height_failed);
  if (!img) return make_error(image_field(d, index, height_failed) + ": " + img.error().message);
  *report = std::move(img->report);
  return std::move(img->image);
}

// Automatic isolation is the slow step of loading an FBPB image material (seconds for a 4096²
// texture), so its meta-texture is cached next to the scene file, as
// <scene folder>/.terravt-cache/meta-<key>.exr, the key an XXH3-64 of everything it is made
// from: the resampled albedo, the variation map, the blur and k_isolation_version (bump it
// whenever isolate_features() or its defaults change). Best effort: a missing, unreadable or
// mismatched file is rebuilt and rewritten (atomically, so concurrent loads are safe); a
// folder that cannot be written costs only the time. The built-in scene never uses it.
constexpr uint32_t k_isolation_version = 3;
constexpr double k_meta_blur_texels = 2.0;
std::atomic<uint64_t> g_isolation_runs{0};

std::string meta_cache_path(const SceneDesc& d, const ImageRGBA8& albedo, const ImageGray8& variation) {
  if (d.base_dir.empty() || d.source_path == "<built-in>") return {};
  const uint64_t parts[] = {k_isolation_version,
                            uint64_t(albedo.width),
                            uint64_t(albedo.height),
                            store_format::hash(albedo.texels),
                            uint64_t(variation.width),
                            store_format::hash(variation.texels),
                            std::bit_cast<uint64_t>(k_meta_blur_texels)};
  const uint64_t key = store_format::hash({reinterpret_cast<const uint8_t*>(parts), sizeof(parts)});
  char name[40];
  std::snprintf(name, sizeof(name), "meta-%016llx.exr", static_cast<unsigned long long>(key));
  return (std::filesystem::path(d.base_dir) / ".terravt-cache" / name).string();
}

MetaTexture isolated_meta(const SceneDesc& d, const ImageRGBA8& albedo, const ImageGray8& variation) {
  const std::string cached = meta_cache_path(d, albedo, variation);
  if (!cached.empty()) {
    std::error_code ec;
    if (std::filesystem::is_regular_file(cached, ec))
      if (auto meta = read_meta_texture(cached); meta && meta->resolution == albedo.width) return std::move(meta.value());
  }
  ++g_isolation_runs;
  const FeatureLabels labels = isolate_features(albedo, IsolationOptions{});  // the defaults of `terravt metatex`
  MetaTexture meta = build_meta_texture(labels, variation, k_meta_blur_texels);
  if (!cached.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(std::filesystem::path(cached).parent_path(), ec);
    if (!ec) (void)write_meta_texture(cached, meta);  // best effort: a failure only costs the next load's time
  }
  return meta;
}

Result<std::optional<MetaTexture>> load_meta(const SceneDesc& d, size_t index, const ImageRGBA8& albedo,
                                             const GeneratedMaterial& generated, const MaterialImageReport& image) {
  const MaterialDesc& m = d.materials[index];
  if (!m.has_fbpb) return std::optional<MetaTexture>{};
  const uint32_t res = uint32_t(albedo.width);
  if (!m.fbpb.meta_path.empty()) {
    auto meta = read_meta_texture(m.fbpb.meta_path);
    if (!meta) return make_error(scene_field(d, material_ptr(index, "fbpb/meta")) + ": " + meta.error().message);
    if (auto s = check_meta_size(d, index, meta->resolution, albedo.width); !s) return s.error();
    return std::optional<MetaTexture>(std::move(meta.value()));
  }
  const ImageGray8 variation = generated.variation.width == int(res)
                                   ? generated.variation
                                   : variation_noise(res, m.albedo.image_path.empty()
                                                              ? derived_asset_seed(d.seed, uint32_t(index), 2)
                                                              : k_image_variation_seed);
  FeatureLabels labels;
  if (!m.fbpb.mask_path.empty()) {
    auto mask = read_image_rgba8(m.fbpb.mask_path);
    if (!mask) return make_error(scene_field(d, material_ptr(index, "fbpb/mask")) + ": " + mask.error().message);
    const bool from_image = image.source_width > 0;  // else a generator made the albedo at its size
    if (auto s = check_mask_size(d, index, mask->width, mask->height, from_image ? image.source_width : albedo.width,
                                 from_image ? image.source_height : albedo.height, albedo.width);
        !s)
      return s.error();
    const ImageGray8 gray = resample_mask_nearest(*mask, albedo.width);
    labels = labels_from_mask(gray, 8);
  } else if (!generated.feature_labels.empty()) {
    labels.resolution = int(res);
    labels.labels = generated.feature_labels;
    labels.count = generated.feature_count;
  } else {
    return std::optional<MetaTexture>(isolated_meta(d, albedo, variation));
  }
  return std::optional<MetaTexture>(build_meta_texture(labels, variation, k_meta_blur_texels));
}

MaterialInfo info_of(const MaterialAssets& a) {
  MaterialInfo info;
  info.resolution = a.albedo.resolution;
  info.mip_count = int(a.albedo.mips.size());
  info.meta = a.meta.has_value();
  info.features_known = true;
  info.feature_count = a.meta ? a.meta->feature_count : 0;
  return info;
}

}  // namespace

uint64_t automatic_isolation_runs() { return g_isolation_runs.load(); }

std::string scene_field(const SceneDesc& d, const std::string& pointer) { return d.source_path + ": " + pointer; }

uint32_t derived_asset_seed(uint32_t scene_seed, uint32_t index, uint32_t purpose) {
  return gpu::tvt_salt(scene_seed, index, 0u, purpose + 100u);
}

MipChain build_mip_chain(const ImageRGBA8& level0) {
  MipChain chain;
  chain.resolution = level0.width;
  chain.mips.push_back(level0);
  while (chain.mips.back().width > 1) {
    const ImageRGBA8& src = chain.mips.back();
    ImageRGBA8 dst(src.width / 2, src.height / 2);
    for (int y = 0; y < dst.height; ++y)
      for (int x = 0; x < dst.width; ++x)
        for (int c = 0; c < 4; ++c) {
          const int sum = src.at(2 * x, 2 * y)[c] + src.at(2 * x + 1, 2 * y)[c] + src.at(2 * x, 2 * y + 1)[c] +
                          src.at(2 * x + 1, 2 * y + 1)[c];
          dst.at(x, y)[c] = uint8_t((sum + 2) / 4);
        }
    chain.mips.push_back(std::move(dst));
  }
  return chain;
}

Result<std::shared_ptr<MaterialSource>> MaterialSource::open(const SceneDesc& desc) {
  std::shared_ptr<MaterialSource> s(new MaterialSource());
  s->desc_ = desc;
  for (size_t i = 0; i < desc.materials.size(); ++i) {
    auto slot = std::make_unique<Slot>();
    if (auto st = check_headers(desc, i, slot->info); !st) return st.error();
    s->slots_.push_back(std::move(slot));
  }
  return s;
}

std::shared_ptr<MaterialSource> MaterialSource::in_memory(std::vector<MaterialAssets> materials) {
  std::shared_ptr<MaterialSource> s(new MaterialSource());
  for (MaterialAssets& m : materials) s->push_back(std::move(m));
  return s;
}

MaterialAssets& MaterialSource::edit(size_t n) {
  TVT_CHECK(!desc_ && n < slots_.size() && !slots_[n]->assets.done());
  return slots_[n]->editable;
}

void MaterialSource::push_back(MaterialAssets assets) {
  TVT_CHECK(!desc_);
  auto slot = std::make_unique<Slot>();
  slot->editable = std::move(assets);
  slots_.push_back(std::move(slot));
}

Result<MaterialAssets> MaterialSource::produce(size_t n) const {
  const SceneDesc& d = *desc_;
  GeneratedMaterial generated;
  MaterialImageReport image;
  auto albedo = load_albedo(d, n, &generated, &image);
  if (!albedo) return albedo.error();
  // The header promised this size; a file replaced since scene load must not change the layout.
  if (albedo->width != slots_[n]->info.resolution)
    return make_error(scene_field(d, material_ptr(n, "albedo")) + ": size changed since the scene was loaded (" +
                      std::to_string(albedo->width) + " instead of " + std::to_string(slots_[n]->info.resolution) + ")");
  auto meta = load_meta(d, n, albedo.value(), generated, image);
  if (!meta) return meta.error();
  MaterialAssets m;
  m.albedo = build_mip_chain(albedo.value());
  m.meta = std::move(meta.value());
  return m;
}

Result<MaterialAssets> MaterialSource::produce_counted(size_t n) const {
  const auto t0 = std::chrono::steady_clock::now();
  auto r = produce(n);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::lock_guard stats_lock(stats_mutex_);
  ++stats_.reads;
  stats_.load_ms += ms;
  if (!r) {
    ++stats_.failures;
    return r.error();
  }
  ++stats_.loaded;
  return r;
}

Result<std::shared_ptr<const MaterialAssets>> MaterialSource::get(size_t n) const {
  TVT_CHECK(n < slots_.size());
  Slot& s = *slots_[n];
  s.assets_wanted.store(true, std::memory_order_release);
  const auto& once = s.assets.get([&]() -> Result<std::shared_ptr<const MaterialAssets>> {
    // In memory: nothing to read; the editable copy becomes the shared one.
    if (!desc_) return std::make_shared<const MaterialAssets>(std::move(s.editable));
    // Words made already: their images were dropped, so this reads the files again.
    auto r = produce_counted(n);
    if (!r) return r.error();
    return std::make_shared<const MaterialAssets>(std::move(r.value()));
  });
  if (once.error()) return *once.error();
  return once.value();
}

Result<std::shared_ptr<const MaterialWords>> MaterialSource::words(size_t n) const {
  TVT_CHECK(n < slots_.size());
  Slot& s = *slots_[n];
  const auto& once = s.words.get([&]() -> Result<std::shared_ptr<const MaterialWords>> {
    // Images someone holds (an in-memory source, or an earlier get()) are packed as they are;
    // otherwise the files are read for this packing alone and their images freed right after.
    if (!desc_ || s.assets_wanted.load(std::memory_order_acquire)) {
      auto assets = get(n);
      if (!assets) return assets.error();
      return std::make_shared<const MaterialWords>(pack_material(*assets.value()));
    }
    auto r = produce_counted(n);
    if (!r) return r.error();
    return std::make_shared<const MaterialWords>(pack_material(r.value()));
  });
  if (once.error()) return *once.error();
  return once.value();
}

Status MaterialSource::load_all() const {
  for (size_t n = 0; n < slots_.size(); ++n)
    if (auto r = words(n); !r) return r.error();
  return Ok{};
}

MaterialInfo MaterialSource::info(size_t n) const {
  TVT_CHECK(n < slots_.size());
  const Slot& s = *slots_[n];
  if (desc_) return s.info;
  if (s.assets.ok()) return info_of(*s.assets.value());
  return info_of(s.editable);
}

bool MaterialSource::loaded(size_t n) const { return slots_[n]->words.ok() || slots_[n]->assets.ok(); }

namespace {

// The statistics block that follows the mip chain (TVT_MATERIAL_STATS_WORDS, read by the
// prefiltered strategy). Level l: the mean over level-l texels of the variance of A, and of
// its covariance with R, G, B, within the level-0 texels under each: E[A X] - E[mean_A mean_X]
// with exact (unrounded) block means, so level 0 is all zeros. Then the features' mean size.
void append_material_stats(const MaterialAssets& a, std::vector<uint32_t>& words) {
  std::array<float, gpu::TVT_MATERIAL_STATS_WORDS> stats{};
  const ImageRGBA8& top = a.albedo.mips.front();
  const int res = a.albedo.resolution;
  if (res > 0 && top.width == res && top.height == res) {
    // Level-0 values and the raw second moments E[A*X] over all texels (X = R, G, B, A).
    std::vector<glm::dvec4> mean(size_t(res) * size_t(res));
    glm::dvec4 raw(0.0);
    for (int y = 0; y < res; ++y)
      for (int x = 0; x < res; ++x) {
        const uint8_t* t = top.at(x, y);
        const glm::dvec4 v = glm::dvec4(t[0], t[1], t[2], t[3]) / 255.0;
        mean[size_t(y) * size_t(res) + size_t(x)] = v;
        raw += v.a * glm::dvec4(v.r, v.g, v.b, v.a);
      }
    raw /= double(res) * double(res);
    for (int l = 1, r = res / 2; r >= 1 && l < 15; ++l, r /= 2) {
      std::vector<glm::dvec4> next(size_t(r) * size_t(r));
      glm::dvec4 block(0.0);  // E over level-l texels of mean_A * mean_X
      for (int y = 0; y < r; ++y)
        for (int x = 0; x < r; ++x) {
          const size_t w2 = size_t(2 * r);
          const glm::dvec4 m = 0.25 * (mean[size_t(2 * y) * w2 + size_t(2 * x)] + mean[size_t(2 * y) * w2 + size_t(2 * x + 1)] +
                                       mean[size_t(2 * y + 1) * w2 + size_t(2 * x)] +
                                       mean[size_t(2 * y + 1) * w2 + size_t(2 * x + 1)]);
          next[size_t(y) * size_t(r) + size_t(x)] = m;
          block += m.a * glm::dvec4(m.r, m.g, m.b, m.a);
        }
      block /= double(r) * double(r);
      const glm::dvec4 within = raw - block;
      stats[size_t(4 * l)] = float(std::max(within.a, 0.0));  // variance of A
      for (int c = 0; c < 3; ++c) stats[size_t(4 * l + 1 + c)] = float(within[c]);
      mean = std::move(next);
    }
  }
  if (a.meta && a.meta->feature_count > 0) {
    size_t feature_texels = 0;
    for (const MetaTexel& t : a.meta->texels) feature_texels += t.d ? 1 : 0;
    if (feature_texels > 0)
      stats[gpu::TVT_STATS_FEATURE_LOG2_SIZE] = float(0.5 * std::log2(double(feature_texels) / double(a.meta->feature_count)));
  }
  if (a.meta && !a.meta->texels.empty()) {
    // The variation map's distribution: the share of texels below each step (exact counts).
    std::array<size_t, 256> histogram{};
    for (const MetaTexel& t : a.meta->texels) ++histogram[t.variation];
    for (int i = 0; i <= gpu::TVT_STATS_VARIATION_STEPS; ++i) {
      const double level = double(i) / gpu::TVT_STATS_VARIATION_STEPS;  // variation / 255 < level
      size_t below = 0;
      for (int v = 0; v < 256; ++v)
        if (double(v) / 255.0 < level) below += histogram[size_t(v)];
      stats[size_t(gpu::TVT_STATS_VARIATION_CDF + i)] = float(double(below) / double(a.meta->texels.size()));
    }
  }
  for (float f : stats) words.push_back(std::bit_cast<uint32_t>(f));
}

uint32_t unorm16(double v) { return uint32_t(std::lround(std::clamp(v, 0.0, 1.0) * 65535.0)); }

// The spread chain (compose_types.h): per level l >= 1 and texel, A over the level-0 texels
// under it as two pieces split at the block's exact mean (below it, and the rest): the lower
// piece's share p, the standard deviation of the pieces' means and each piece's half-width, from
// exact sums. Index l of the result is level l's words (index 0 empty); zeros where level 0 is
// not the material's resolution. Two passes over level 0 a level.
std::vector<std::vector<uint32_t>> a_spread_chain(const MipChain& albedo) {
  std::vector<std::vector<uint32_t>> chain(albedo.mips.size());
  for (size_t l = 1; l < chain.size(); ++l) {
    const size_t rl = size_t(albedo.resolution) >> l;
    chain[l].assign(rl * rl, 0u);
  }
  const int res = albedo.resolution;
  if (albedo.mips.empty() || res < 2 || albedo.mips.front().width != res || albedo.mips.front().height != res)
    return chain;
  const ImageRGBA8& top = albedo.mips.front();
  auto a_at = [&](int x, int y) { return top.texels[4 * (size_t(y) * size_t(res) + size_t(x)) + 3] / 255.0; };
  auto unorm8 = [](double v) { return uint32_t(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); };
  const double scale = double(gpu::TVT_SPREAD_SCALE);
  struct Piece {
    double count = 0, sum = 0, squares = 0;
    void add(double v) { count += 1, sum += v, squares += v * v; }
    double mean() const { return count > 0 ? sum / count : 0.0; }
    double var() const { return count > 0 ? std::max(squares / count - mean() * mean(), 0.0) : 0.0; }
  };
  for (int l = 1; size_t(l) < chain.size() && (res >> l) >= 1; ++l) {
    const int rl = res >> l;
    std::vector<double> mean(size_t(rl) * size_t(rl), 0.0);
    for (int y = 0; y < res; ++y)
      for (int x = 0; x < res; ++x) mean[size_t(y >> l) * size_t(rl) + size_t(x >> l)] += a_at(x, y);
    const double n = std::ldexp(1.0, 2 * l);
    for (double& m : mean) m /= n;
    std::vector<Piece> lower(mean.size()), upper(mean.size());
    for (int y = 0; y < res; ++y)
      for (int x = 0; x < res; ++x) {
        const size_t b = size_t(y >> l) * size_t(rl) + size_t(x >> l);
        const double v = a_at(x, y);
        (v < mean[b] ? lower[b] : upper[b]).add(v);
      }
    for (size_t b = 0; b < mean.size(); ++b) {
      const double p = lower[b].count / n;
      const double delta = std::sqrt(p * (1.0 - p)) * std::max(upper[b].mean() - lower[b].mean(), 0.0);
      chain[size_t(l)][b] = unorm8(p) | unorm8(delta * scale) << 8 | unorm8(std::sqrt(3.0 * lower[b].var()) * scale) << 16 |
                            unorm8(std::sqrt(3.0 * upper[b].var()) * scale) << 24;
    }
  }
  return chain;
}

uint32_t snorm8(double v) { return uint32_t(uint8_t(int8_t(std::lround(std::clamp(v, -1.0, 1.0) * 127.0)))); }

// The feature statistics chain after the level-0 meta words (compose_types.h,
// tvt_meta_chain_offset): per level-l texel, over the level-0 texels under it, the feature
// fraction D, the mean f of its feature texels and D * (feature colour mean - colour mean),
// from exact block sums. The colour is the albedo's level 0 (zero moment if its size differs).
void append_feature_chain(const MetaTexture& meta, const ImageRGBA8& albedo, std::vector<uint32_t>& words) {
  const int res = meta.resolution;
  if (res <= 1 || meta.texels.size() != size_t(res) * size_t(res)) return;
  const bool colour = albedo.width == res && albedo.height == res;
  // Per texel of the current level: sums over the level-0 texels under it, as means.
  struct Sums {
    double feature = 0.0, soft = 0.0;
    glm::dvec4 colour{0.0}, feature_colour{0.0};
  };
  std::vector<Sums> level(meta.texels.size());
  for (size_t i = 0; i < level.size(); ++i) {
    const MetaTexel& t = meta.texels[i];
    Sums& s = level[i];
    if (colour) {
      const uint8_t* c = &albedo.texels[4 * i];
      s.colour = glm::dvec4(c[0], c[1], c[2], c[3]) / 255.0;
    }
    if (t.d) {
      s.feature = 1.0;
      s.soft = t.f / 255.0;
      s.feature_colour = s.colour;
    }
  }
  for (int r = res / 2; r >= 1; r /= 2) {
    std::vector<Sums> next(size_t(r) * size_t(r));
    const size_t w2 = size_t(2 * r);
    for (int y = 0; y < r; ++y)
      for (int x = 0; x < r; ++x) {
        Sums& o = next[size_t(y) * size_t(r) + size_t(x)];
        for (int k = 0; k < 4; ++k) {
          const Sums& c = level[size_t(2 * y + (k >> 1)) * w2 + size_t(2 * x + (k & 1))];
          o.feature += 0.25 * c.feature;
          o.soft += 0.25 * c.soft;
          o.colour += 0.25 * c.colour;
          o.feature_colour += 0.25 * c.feature_colour;
        }
        const double mean_f = o.feature > 0.0 ? o.soft / o.feature : 0.0;
        words.push_back(unorm16(o.feature) | unorm16(mean_f) << 16);
        const glm::dvec4 moment = (o.feature_colour - o.feature * o.colour) * double(gpu::TVT_META_MOMENT_SCALE);
        words.push_back(snorm8(moment.r) | snorm8(moment.g) << 8 | snorm8(moment.b) << 16 | snorm8(moment.a) << 24);
      }
    level = std::move(next);
  }
}

}  // namespace

MaterialWords pack_material(const MaterialAssets& a) {
  MaterialWords w;
  w.resolution = a.albedo.resolution;
  w.mip_count = int(a.albedo.mips.size());
  size_t count = 0;
  for (const ImageRGBA8& mip : a.albedo.mips) count += mip.texels.size() / 4;
  w.texels.reserve(count + size_t(gpu::TVT_MATERIAL_STATS_WORDS));
  const std::vector<std::vector<uint32_t>> spread = a_spread_chain(a.albedo);
  for (size_t l = 0; l < a.albedo.mips.size(); ++l) {
    const ImageRGBA8& mip = a.albedo.mips[l];
    for (size_t t = 0; t < mip.texels.size(); t += 4)
      w.texels.push_back(uint32_t(mip.texels[t]) | uint32_t(mip.texels[t + 1]) << 8 |
                         uint32_t(mip.texels[t + 2]) << 16 | uint32_t(mip.texels[t + 3]) << 24);
    if (l >= 1 && l < spread.size()) w.texels.insert(w.texels.end(), spread[l].begin(), spread[l].end());
  }
  append_material_stats(a, w.texels);
  if (a.meta) {
    w.has_meta = true;
    w.feature_count = a.meta->feature_count;
    w.meta.reserve(2 * a.meta->texels.size());
    for (const MetaTexel& t : a.meta->texels) {
      w.meta.push_back(uint32_t(uint16_t(t.dx)) | uint32_t(uint16_t(t.dy)) << 16);
      w.meta.push_back(uint32_t(t.d) | uint32_t(t.f) << 8 | uint32_t(t.variation) << 16);
    }
    append_feature_chain(*a.meta, a.albedo.mips.front(), w.meta);
  }
  return w;
}

MaterialLoadStats MaterialSource::stats() const {
  std::lock_guard lock(stats_mutex_);
  return stats_;
}

}  // namespace tvt
