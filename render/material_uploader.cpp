#include "render/material_uploader.h"

#include <algorithm>
#include <cstring>

namespace tvt {

namespace {
constexpr VkBufferUsageFlags k_device_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;

// At least 16 bytes: an empty input still binds a buffer.
VkDeviceSize device_bytes(size_t bytes) { return std::max<VkDeviceSize>(16, VkDeviceSize(bytes)); }
}  // namespace

MaterialUploader::MaterialUploader(vk::Context& context, const PackedScene& scene) : context_(&context) {
  const gpu::TvtComposeParams& p = scene.params;
  TVT_CHECK(p.material_count >= 1 && p.material_count <= gpu::TVT_MAX_MATERIALS);
  layer_floats_ = size_t(p.weight_width) * size_t(p.weight_height);
  TVT_CHECK(scene.weights.size() == layer_floats_ * size_t(p.weight_layers));
  layer_resident_.assign(size_t(p.weight_layers), false);
  std::vector<bool> layer_counted(size_t(p.weight_layers), false);
  for (int n = 0; n < p.material_count; ++n) {
    const gpu::TvtMaterial& m = p.materials[n];
    Material mat;
    mat.layout = m;
    size_t words = 0;  // the whole mip chain, as material_texel() in compose_sample.glsl reads it
    for (int l = 0; l < m.mip_count; ++l) words += (size_t(m.resolution) >> l) * (size_t(m.resolution) >> l);
    mat.texels = {m.texel_offset, words};
    TVT_CHECK(mat.texels.first + mat.texels.count <= scene.material_texels.size());
    if (m.meta_offset != gpu::TVT_NO_META) {
      mat.meta = {2 * size_t(m.meta_offset), 2 * size_t(m.resolution) * size_t(m.resolution)};
      TVT_CHECK(mat.meta.first + mat.meta.count <= scene.meta_texels.size());
    }
    TVT_CHECK(m.weight_layer >= 0 && m.weight_layer < p.weight_layers);
    mat.weight_layer = m.weight_layer;
    stats_.bytes_total += 4 * (mat.texels.count + mat.meta.count);
    if (!layer_counted[size_t(m.weight_layer)]) stats_.bytes_total += 4 * layer_floats_;
    layer_counted[size_t(m.weight_layer)] = true;
    materials_.push_back(mat);
  }
  stats_.materials = uint32_t(p.material_count);
  host_texels_ = scene.material_texels;
  host_meta_ = scene.meta_texels;
  host_weights_ = scene.weights;
  texel_buffer_ = context.create_buffer(device_bytes(host_texels_.size() * 4), k_device_usage, false);
  meta_buffer_ = context.create_buffer(device_bytes(host_meta_.size() * 4), k_device_usage, false);
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

void MaterialUploader::record(VkCommandBuffer cmd, uint32_t mask) {
  staging_.clear();  // the previous record()'s commands have completed (class contract)
  stats_.last_materials = 0;
  stats_.last_bytes = 0;
  const uint32_t all = materials_.size() >= 32 ? ~0u : (1u << materials_.size()) - 1u;
  const uint32_t missing = mask & all & ~stats_.resident_mask;
  if (missing != 0) record_copies(cmd, missing, staging_);
}

void MaterialUploader::upload_all() {
  if (all_resident()) return;
  stats_.last_materials = 0;
  stats_.last_bytes = 0;
  // One material per submission bounds the staging memory; not staging_: a recorded upload
  // that is not submitted yet may still own it.
  for (size_t n = 0; n < materials_.size(); ++n) {
    if (stats_.resident_mask & (1u << n)) continue;
    std::vector<vk::Buffer> keep;
    context_->run_commands([&](VkCommandBuffer cmd) { record_copies(cmd, 1u << n, keep); });
  }
}

void MaterialUploader::record_copies(VkCommandBuffer cmd, uint32_t mask, std::vector<vk::Buffer>& keep) {
  // Gather the ranges: one staging buffer, up to three destination buffers.
  struct Piece {
    const void* src;
    size_t bytes;
    const vk::Buffer* dst;
    VkDeviceSize dst_offset;
  };
  std::vector<Piece> pieces;
  uint32_t count = 0;
  uint64_t bytes = 0;
  for (size_t n = 0; n < materials_.size(); ++n) {
    if (!(mask & (1u << n))) continue;
    const Material& m = materials_[n];
    pieces.push_back({host_texels_.data() + m.texels.first, 4 * m.texels.count, &texel_buffer_, 4 * m.texels.first});
    if (m.meta.count > 0)
      pieces.push_back({host_meta_.data() + m.meta.first, 4 * m.meta.count, &meta_buffer_, 4 * m.meta.first});
    const size_t layer = size_t(m.weight_layer);
    if (!layer_resident_[layer]) {
      pieces.push_back({host_weights_.data() + layer * layer_floats_, 4 * layer_floats_, &weight_buffer_,
                        4 * layer * layer_floats_});
      layer_resident_[layer] = true;
    }
    ++count;
    stats_.resident_mask |= 1u << n;
  }
  if (pieces.empty()) return;
  for (const Piece& p : pieces) bytes += p.bytes;
  vk::Buffer staging = context_->create_buffer(VkDeviceSize(bytes), VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
  auto* dst = static_cast<unsigned char*>(staging.mapped());
  VkDeviceSize at = 0;
  std::vector<VkBufferCopy> regions[3];
  const vk::Buffer* targets[3] = {&texel_buffer_, &meta_buffer_, &weight_buffer_};
  for (const Piece& p : pieces) {
    std::memcpy(dst + at, p.src, p.bytes);  // host writes: visible at submit
    const size_t t = size_t(std::find(targets, targets + 3, p.dst) - targets);
    regions[t].push_back(VkBufferCopy{at, p.dst_offset, VkDeviceSize(p.bytes)});
    at += VkDeviceSize(p.bytes);
  }
  for (size_t t = 0; t < 3; ++t)
    if (!regions[t].empty())
      vkCmdCopyBuffer(cmd, staging.handle(), targets[t]->handle(), uint32_t(regions[t].size()), regions[t].data());
  // Visible to whatever reads next: the compose dispatch, or a per-pixel pass.
  VkMemoryBarrier barrier{};
  barrier.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
  barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  barrier.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 1, &barrier, 0,
                       nullptr, 0, nullptr);
  keep.push_back(std::move(staging));
  stats_.resident += count;
  stats_.bytes_uploaded += bytes;
  stats_.last_materials += count;
  stats_.last_bytes += bytes;
  if (all_resident()) {  // nothing left to upload: the host copies are no longer needed
    host_texels_ = {};
    host_meta_ = {};
    host_weights_ = {};
  }
}

}  // namespace tvt
