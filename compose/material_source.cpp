#include "compose/material_source.h"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>

#include "compose/procedural.h"
#include "shaders/shared/hash.h"

namespace tvt {

namespace {

double clamp01(double v) { return std::isfinite(v) ? std::clamp(v, 0.0, 1.0) : 0.0; }

std::string material_ptr(size_t index, const char* what) {
  return "/materials/" + std::to_string(index) + "/" + what;
}

ImageGray8 noise_gray(uint32_t resolution, uint32_t seed) {
  const auto grid = fbm_grid(resolution, seed, 5, 4.0, 0.55, 2.0);
  ImageGray8 out{int(resolution), int(resolution)};
  for (size_t i = 0; i < grid.size(); ++i) out.texels[i] = uint8_t(std::lround(clamp01(grid[i]) * 255.0));
  return out;
}

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

Status check_albedo_size(const SceneDesc& d, size_t index, int width, int height) {
  if (width != height || !std::has_single_bit(unsigned(width)) || width > 4096)
    return make_error(scene_field(d, material_ptr(index, "albedo/image")) + ": " + d.materials[index].albedo.image_path +
                      ": must be square with a power-of-two size up to 4096, got " + size_text(width, height));
  return Ok{};
}

Status check_height_size(const SceneDesc& d, size_t index, int width, int height, int albedo) {
  if (width != albedo || height != albedo)
    return make_error(scene_field(d, material_ptr(index, "albedo/height")) + ": " + d.materials[index].albedo.height_path +
                      ": size " + size_text(width, height) + " differs from the albedo's " + size_text(albedo, albedo));
  return Ok{};
}

Status check_meta_size(const SceneDesc& d, size_t index, int resolution, int albedo) {
  if (resolution != albedo)
    return make_error(scene_field(d, material_ptr(index, "fbpb/meta")) + ": " + d.materials[index].fbpb.meta_path +
                      ": resolution " + std::to_string(resolution) + " differs from the albedo's " +
                      std::to_string(albedo));
  return Ok{};
}

Status check_mask_size(const SceneDesc& d, size_t index, int width, int height, int albedo) {
  if (width != albedo || height != albedo)
    return make_error(scene_field(d, material_ptr(index, "fbpb/mask")) + ": " + d.materials[index].fbpb.mask_path +
                      ": size differs from the albedo's");
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
  if (m.albedo.image_path.empty()) {
    info.resolution = int(m.albedo.resolution);  // the generator validates it on first use
  } else {
    auto h = header(d, material_ptr(index, "albedo/image"), m.albedo.image_path);
    if (!h) return h.error();
    if (auto s = check_albedo_size(d, index, h->width, h->height); !s) return s;
    info.resolution = h->width;
    if (!m.albedo.height_path.empty()) {
      auto hh = header(d, material_ptr(index, "albedo/height"), m.albedo.height_path);
      if (!hh) return hh.error();
      if (auto s = check_height_size(d, index, hh->width, hh->height, info.resolution); !s) return s;
    }
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
    if (auto s = check_mask_size(d, index, h->width, h->height, info.resolution); !s) return s;
  }
  return Ok{};
}

Result<ImageRGBA8> load_albedo(const SceneDesc& d, size_t index, GeneratedMaterial* generated) {
  const MaterialDesc& m = d.materials[index];
  if (m.albedo.image_path.empty()) {
    const uint32_t seed = m.albedo.seed ? m.albedo.seed : derived_asset_seed(d.seed, uint32_t(index), 1);
    auto g = generate_material(m.albedo.generator, m.albedo.resolution, seed);
    if (!g) return make_error(scene_field(d, material_ptr(index, "albedo/generator")) + ": " + g.error().message);
    *generated = std::move(g.value());
    return generated->albedo;
  }
  auto img = read_image_rgba8(m.albedo.image_path);
  if (!img) return make_error(scene_field(d, material_ptr(index, "albedo/image")) + ": " + img.error().message);
  ImageRGBA8 albedo = std::move(img.value());
  if (auto s = check_albedo_size(d, index, albedo.width, albedo.height); !s) return s.error();
  if (!m.albedo.height_path.empty()) {
    auto h = read_image_float(m.albedo.height_path);
    if (!h) return make_error(scene_field(d, material_ptr(index, "albedo/height")) + ": " + h.error().message);
    if (auto s = check_height_size(d, index, h->width, h->height, albedo.width); !s) return s.error();
    for (int y = 0; y < albedo.height; ++y)
      for (int x = 0; x < albedo.width; ++x)
        albedo.at(x, y)[3] = uint8_t(std::lround(clamp01(h->at(x, y, 0)) * 255.0));
  }
  return albedo;
}

Result<std::optional<MetaTexture>> load_meta(const SceneDesc& d, size_t index, const ImageRGBA8& albedo,
                                             const GeneratedMaterial& generated) {
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
                                   : noise_gray(res, derived_asset_seed(d.seed, uint32_t(index), 2));
  FeatureLabels labels;
  if (!m.fbpb.mask_path.empty()) {
    auto mask = read_image_rgba8(m.fbpb.mask_path);
    if (!mask) return make_error(scene_field(d, material_ptr(index, "fbpb/mask")) + ": " + mask.error().message);
    if (auto s = check_mask_size(d, index, mask->width, mask->height, albedo.width); !s) return s.error();
    ImageGray8 gray(mask->width, mask->height);
    for (int y = 0; y < gray.height; ++y)
      for (int x = 0; x < gray.width; ++x) gray.at(x, y) = mask->at(x, y)[0];
    labels = labels_from_mask(gray, 8);
  } else if (!generated.feature_labels.empty()) {
    labels.resolution = int(res);
    labels.labels = generated.feature_labels;
    labels.count = generated.feature_count;
  } else {
    labels = isolate_features(albedo, IsolationOptions{});
  }
  return std::optional<MetaTexture>(build_meta_texture(labels, variation, 2.0));
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
  auto albedo = load_albedo(d, n, &generated);
  if (!albedo) return albedo.error();
  // The header promised this size; a file replaced since scene load must not change the layout.
  if (albedo->width != slots_[n]->info.resolution)
    return make_error(scene_field(d, material_ptr(n, "albedo")) + ": size changed since the scene was loaded (" +
                      std::to_string(albedo->width) + " instead of " + std::to_string(slots_[n]->info.resolution) + ")");
  auto meta = load_meta(d, n, albedo.value(), generated);
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

MaterialWords pack_material(const MaterialAssets& a) {
  MaterialWords w;
  w.resolution = a.albedo.resolution;
  w.mip_count = int(a.albedo.mips.size());
  size_t count = 0;
  for (const ImageRGBA8& mip : a.albedo.mips) count += mip.texels.size() / 4;
  w.texels.reserve(count);
  for (const ImageRGBA8& mip : a.albedo.mips)
    for (size_t t = 0; t < mip.texels.size(); t += 4)
      w.texels.push_back(uint32_t(mip.texels[t]) | uint32_t(mip.texels[t + 1]) << 8 |
                         uint32_t(mip.texels[t + 2]) << 16 | uint32_t(mip.texels[t + 3]) << 24);
  if (a.meta) {
    w.has_meta = true;
    w.feature_count = a.meta->feature_count;
    w.meta.reserve(2 * a.meta->texels.size());
    for (const MetaTexel& t : a.meta->texels) {
      w.meta.push_back(uint32_t(uint16_t(t.dx)) | uint32_t(uint16_t(t.dy)) << 16);
      w.meta.push_back(uint32_t(t.d) | uint32_t(t.f) << 8 | uint32_t(t.variation) << 16);
    }
  }
  return w;
}

MaterialLoadStats MaterialSource::stats() const {
  std::lock_guard lock(stats_mutex_);
  return stats_;
}

}  // namespace tvt
