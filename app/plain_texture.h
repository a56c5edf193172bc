// One ordinary mip-mapped RGBA8 texture over the whole terrain, filled with composed content:
// the baseline that the virtual texture's sampling cost is measured against ("VT <= 1.25x a
// plain pre-composed texture", `terravt bench frame`).
//
// Level 0 is VT mip m = log2 V - log2_size, composed page by page by the compute composer (the
// same pages the VT would hold at that mip) and copied, payload only, into place; the rest of
// the chain is box-filtered by linear 2:1 blits, as an ordinary asset pipeline would build it.
// The terrain pass samples it with hardware trilinear filtering (terrain_plain.frag).
//
// Built once (blocking, on the context's queue); then read-only. Not thread-safe.
#pragma once
#include <cstdint>
#include <memory>

#include "compose/packed_scene.h"
#include "gpu/context.h"

namespace tvt {

struct PlainTextureOptions {
  uint32_t log2_size = 12;    // texels per side = 2^log2_size (4096); log2 P ... log2 V
  uint32_t batch_pages = 64;  // pages composed per submission
};

class PlainTexture {
 public:
  static Result<std::unique_ptr<PlainTexture>> create(vk::Context& context, const PackedScene& scene,
                                                      const PlainTextureOptions& options = {});
  ~PlainTexture();
  PlainTexture(const PlainTexture&) = delete;
  PlainTexture& operator=(const PlainTexture&) = delete;

  // Layout SHADER_READ_ONLY_OPTIMAL, every level; view over all levels (sampler2DArray, layer 0).
  const vk::Image& image() const { return image_; }
  // Trilinear (linear min/mag, linear between levels), clamp to edge, no anisotropy.
  VkSampler sampler() const { return sampler_; }
  uint32_t log2_size() const { return log2_size_; }
  // log2 of level-0 VT texels per plain texel (the VT mip that level 0 equals).
  uint32_t vt_mip() const { return vt_mip_; }
  uint64_t bytes() const;               // every level
  uint32_t pages_composed() const { return pages_; }
  double compose_seconds() const { return seconds_; }

 private:
  PlainTexture() = default;
  vk::Context* context_ = nullptr;
  vk::Image image_;
  VkSampler sampler_ = VK_NULL_HANDLE;
  uint32_t log2_size_ = 0, vt_mip_ = 0, pages_ = 0;
  double seconds_ = 0;
};

}  // namespace tvt
