#include "composer/material_uploader.h"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstring>

namespace tvt {

namespace {
constexpr VkBufferUsageFlags k_device_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;

// At least 16 bytes: an empty input still binds a buffer.
VkDeviceSize device_bytes(size_t bytes) { return std::max<VkDeviceSize>(16, VkDeviceSize(bytes)); }
}  // namespace

MaterialUploader::MaterialUploader(vk::Context& context, const PackedScene& scene, uint32_t records_in_flight)
    : context_(&context), scene_(scene), staging_ring_(std::max(records_in_flight, 1u)) {
  const gpu::TvtComposeParams& p = scene.params;
  TVT_CHECK(p.material_count >= 1 && p.material_count <= gpu::TVT_MAX_MATERIALS);
  layer_floats_ = size_t(p.weight_width) * size_t(p.weight_height);
  TVT_CHECK(scene.weights.size() == layer_floats_ * size_t(p.weight_layers));
  layer_resident_.assign(size_t(p.weight_layers), false);
  std::vector<bool> layer_counted(size_t(p.weight_layers), false);
  for (int n = 0; n < p.material_count; ++n) {
    const gpu::TvtMaterial& m = p.materials[n];
    TVT_CHECK(m.mip_count >= 1 && m.mip_count <= 31 && m.resolution >= 1);
    Material mat;
    mat.layout = m;
    // Level l of the chain, as material_texel() in compose_sample.glsl addresses it.
    // Each level travels with its spread chain; the statistics travel with the 1x1 level.
    for (int l = 0; l < m.mip_count; ++l)
      mat.level_first.push_back(m.texel_offset + size_t(gpu::tvt_material_level_offset(uint32_t(m.resolution), uint32_t(l))));
    const size_t at = m.texel_offset +
                      size_t(gpu::tvt_material_stats_offset(uint32_t(m.resolution), uint32_t(m.mip_count))) +
                      size_t(gpu::TVT_MATERIAL_STATS_WORDS);
    mat.level_first.push_back(at);
    mat.texels = {m.texel_offset, at - m.texel_offset};
    TVT_CHECK(at <= scene.texel_words);
    if (m.meta_offset != gpu::TVT_NO_META) {
      mat.meta = {2 * size_t(m.meta_offset), 2 * size_t(gpu::tvt_meta_block_texels(uint32_t(m.resolution)))};
      TVT_CHECK(mat.meta.first + mat.meta.count <= scene.meta_words);
    }
    mat.meta_resident = mat.meta.count == 0;
    mat.resident_from = m.mip_count;
    TVT_CHECK(m.weight_layer >= 0 && m.weight_layer < p.weight_layers);
    mat.weight_layer = m.weight_layer;
    stats_.bytes_total += 4 * (mat.texels.count + mat.meta.count);
    if (!layer_counted[size_t(m.weight_layer)]) stats_.bytes_total += 4 * layer_floats_;
    layer_counted[size_t(m.weight_layer)] = true;
    materials_.push_back(std::move(mat));
  }
  stats_.materials = uint32_t(p.material_count);
  texel_words_ = scene.texel_words;
  meta_words_ = scene.meta_words;
  host_weights_ = scene.weights;
  texel_buffer_ = context.create_buffer(device_bytes(texel_words_ * 4), k_device_usage, false);
  meta_buffer_ = context.create_buffer(device_bytes(meta_words_ * 4), k_device_usage, false);
  weight_buffer_ = context.create_buffer(device_bytes(host_weights_.size() * 4), k_device_usage, false);
}

MaterialUploader::~MaterialUploader() = default;

bool MaterialUploader::same_layout(const gpu::TvtComposeParams& params) const {
  if (params.material_count != int(materials_.size())) return false;
  for (size_t n = 0; n < materials_.size(); ++n) {
    const gpu::TvtMaterial& a = materials_[n].layout;
    const gpu::TvtMaterial& b = params.materials[n];
    if (a.texel_offset != b.texel_offset || a.meta_offset != b.meta_offset || a.resolution != b.resolution ||
        a.mip_count != b.mip_count || a.weight_layer != b.weight_layer)
      return false;
  }
  return true;
}

MaterialNeeds MaterialUploader::everything() const {
  MaterialNeeds all;
  all.mask = all_mask();
  all.meta_mask = all_mask();
  return all;  // finest_level 0 everywhere
}

void MaterialUploader::fill(VkCommandBuffer cmd, uint32_t word) {
  for (const vk::Buffer* b : {&texel_buffer_, &meta_buffer_, &weight_buffer_})
    context_->fn().vkCmdFillBuffer(cmd, b->handle(), 0, VK_WHOLE_SIZE, word);
  context_->memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                              VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                              VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT);
}

Status MaterialUploader::load(uint32_t mask) {
  mask &= all_mask();
  const uint32_t before = scene_.loaded_mask();
  stats_.last_cpu_loaded = 0;
  stats_.last_cpu_load_ms = 0.0;
  if ((before & mask) == mask) return Ok{};
  const auto t0 = std::chrono::steady_clock::now();
  const Status s = scene_.load(mask);
  const uint32_t after = scene_.loaded_mask();
  stats_.last_cpu_load_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  stats_.cpu_load_ms += stats_.last_cpu_load_ms;
  stats_.last_cpu_loaded = uint32_t(std::popcount(after & ~before));
  stats_.cpu_loaded = uint32_t(std::popcount(after));
  if (!s) ++stats_.load_failures;
  return s;
}

Status MaterialUploader::record(VkCommandBuffer cmd, const MaterialNeeds& needs) {
  // The call that used this ring entry records_in_flight calls ago has completed (contract).
  std::vector<vk::Buffer>& keep = staging_ring_[records_++ % staging_ring_.size()];
  keep.clear();
  stats_.last_materials = 0;
  stats_.last_bytes = 0;
  if (all_resident()) return Ok{};
  if (auto s = load(needs.mask); !s) return s;
  return record_copies(cmd, needs, keep);
}

Status MaterialUploader::upload_all() {
  if (all_resident()) return Ok{};
  stats_.last_materials = 0;
  stats_.last_bytes = 0;
  if (auto s = load(all_mask()); !s) return s;
  // One material per submission bounds the staging memory; not the ring: a recorded upload
  // that is not submitted yet may still own it.
  const MaterialNeeds all = everything();
  for (size_t n = 0; n < materials_.size(); ++n) {
    if (stats_.complete_mask & (1u << n)) continue;
    MaterialNeeds one = all;
    one.mask = one.meta_mask = 1u << n;
    std::vector<vk::Buffer> keep;
    Status copied = Ok{};
    context_->run_commands([&](VkCommandBuffer cmd) { copied = record_copies(cmd, one, keep); });
    if (!copied) return copied;
  }
  return context_->status();
}

Status MaterialUploader::record_copies(VkCommandBuffer cmd, const MaterialNeeds& needs, std::vector<vk::Buffer>& keep) {
  struct Piece {  // host range -> one of the three device buffers
    const void* src;
    size_t bytes;
    int target;  // 0 texels, 1 meta, 2 weights
    VkDeviceSize dst_offset;
  };
  std::vector<Piece> pieces;
  uint32_t touched = 0;
  for (size_t n = 0; n < materials_.size(); ++n) {
    const uint32_t bit = 1u << n;
    if (!(needs.mask & bit)) continue;
    Material& m = materials_[n];
    const int finest = std::min<int>(needs.finest_level[n], m.layout.mip_count - 1);
    if (finest < m.resident_from) {  // levels [finest, resident_from): contiguous in the chain
      const size_t first = m.level_first[size_t(finest)], end = m.level_first[size_t(m.resident_from)];
      pieces.push_back({scene_.texels(n).data() + (first - m.texels.first), 4 * (end - first), 0, 4 * first});
      m.resident_from = finest;
      touched |= bit;
    }
    if ((needs.meta_mask & bit) && !m.meta_resident) {
      TVT_CHECK(scene_.meta(n).size() == m.meta.count);
      pieces.push_back({scene_.meta(n).data(), 4 * m.meta.count, 1, 4 * m.meta.first});
      m.meta_resident = true;
      touched |= bit;
    }
    const size_t layer = size_t(m.weight_layer);
    if (!layer_resident_[layer]) {
      pieces.push_back({host_weights_.data() + layer * layer_floats_, 4 * layer_floats_, 2, 4 * layer * layer_floats_});
      layer_resident_[layer] = true;
      touched |= bit;
    }
    if (!(stats_.resident_mask & bit)) ++stats_.resident;
    stats_.resident_mask |= bit;
    if (m.resident_from == 0 && m.meta_resident) stats_.complete_mask |= bit;
  }
  if (pieces.empty()) return Ok{};
  size_t bytes = 0;
  for (const Piece& p : pieces) bytes += p.bytes;
  vk::Buffer staging = context_->create_buffer(VkDeviceSize(bytes), VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
  // A failed allocation is latched on the context: the uploader (marked resident above) is
  // not used again, every later call of the runtime returns that error.
  if (!staging) return context_->status();
  auto* dst = static_cast<unsigned char*>(staging.mapped());
  std::vector<VkBufferCopy> regions[3];
  VkDeviceSize at = 0;
  for (const Piece& p : pieces) {
    std::memcpy(dst + at, p.src, p.bytes);  // host writes: visible at submit
    regions[p.target].push_back(VkBufferCopy{at, p.dst_offset, VkDeviceSize(p.bytes)});
    at += VkDeviceSize(p.bytes);
  }
  const vk::Buffer* targets[3] = {&texel_buffer_, &meta_buffer_, &weight_buffer_};
  for (size_t t = 0; t < 3; ++t)
    if (!regions[t].empty())
      context_->fn().vkCmdCopyBuffer(cmd, staging.handle(), targets[t]->handle(), uint32_t(regions[t].size()), regions[t].data());
  // Visible to whatever reads next: the compose dispatch, or a per-pixel pass.
  context_->memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                              VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_ACCESS_MEMORY_READ_BIT);
  keep.push_back(std::move(staging));
  stats_.bytes_uploaded += bytes;
  stats_.last_materials += uint32_t(std::popcount(touched));
  stats_.last_bytes += bytes;
  if (all_resident()) host_weights_ = {};  // nothing left to upload (the texels stay in the scene's cache)
  return Ok{};
}

}  // namespace tvt
