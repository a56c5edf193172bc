// A packed scene's material data on the GPU, uploaded per material on first use (issue 3:
// "a material's textures and meta-texture are loaded and uploaded only when the first page
// that uses them is requested"). Material n's data is its texel mip chain, its FBPB
// meta-texture and its weight-grid layer; compose_sample.glsl reads none of them for a page
// whose culling mask (compose/material_culling.h) excludes n, so the upload can wait until a
// page that includes n is recorded.
//
// The device buffers are allocated whole at construction (sizes and offsets come from the
// PackedScene, so the shaders' view of them never changes); only the copies are deferred.
// The host keeps the scene's texels until everything is uploaded.
//
// Not thread-safe. record() releases the staging buffers of the previous record(): the
// commands the previous call recorded must have completed (the composer's job ring already
// requires this).
#pragma once
#include <cstdint>
#include <vector>

#include "compose/packed_scene.h"
#include "render/vk_context.h"

namespace tvt {

// What is on the GPU. Bytes count texels + meta-texture + weight layer of each material.
struct MaterialUploadStats {
  uint32_t materials = 0;           // in the scene
  uint32_t resident = 0;            // uploaded so far
  uint32_t resident_mask = 0;       // bit n: material n is on the GPU
  uint64_t bytes_total = 0;         // what uploading every material copies
  uint64_t bytes_uploaded = 0;      // copied so far (each material once)
  uint32_t last_materials = 0;      // uploaded by the latest record() / upload_all()
  uint64_t last_bytes = 0;
};

class MaterialUploader {
 public:
  MaterialUploader(vk::Context& context, const PackedScene& scene);
  ~MaterialUploader();
  MaterialUploader(const MaterialUploader&) = delete;
  MaterialUploader& operator=(const MaterialUploader&) = delete;

  // Records the copies of every material in `mask` that is not on the GPU yet (from a staging
  // buffer kept until the next call) and a barrier that makes them visible to every later
  // command. Bits of materials the scene does not have are ignored. Nothing when all are there.
  // The materials count as resident from here on: `cmd` must be submitted.
  void record(VkCommandBuffer cmd, uint32_t mask);
  // Uploads everything still missing and waits for it (for passes that compose per pixel).
  void upload_all();

  bool all_resident() const { return stats_.resident == stats_.materials; }
  const MaterialUploadStats& stats() const { return stats_; }
  // True when `params` places every material's data where the uploader put (or will put) it.
  bool same_layout(const gpu::TvtComposeParams& params) const;

  const vk::Buffer& texels() const { return texel_buffer_; }
  const vk::Buffer& meta() const { return meta_buffer_; }
  const vk::Buffer& weights() const { return weight_buffer_; }

 private:
  struct Range {          // in elements of the host vector (uint32 words or floats)
    size_t first = 0, count = 0;
  };
  struct Material {
    Range texels, meta;
    int weight_layer = 0;
    gpu::TvtMaterial layout{};  // the fields same_layout() compares
  };
  // Records the copies of the materials in `mask` (all missing) into `cmd`; the staging
  // buffer goes to `keep`.
  void record_copies(VkCommandBuffer cmd, uint32_t mask, std::vector<vk::Buffer>& keep);

  vk::Context* context_ = nullptr;
  std::vector<Material> materials_;
  std::vector<uint32_t> host_texels_, host_meta_;
  std::vector<float> host_weights_;
  size_t layer_floats_ = 0;
  std::vector<bool> layer_resident_;
  vk::Buffer texel_buffer_, meta_buffer_, weight_buffer_;
  std::vector<vk::Buffer> staging_;  // in use by the latest recorded upload
  MaterialUploadStats stats_;
};

}  // namespace tvt
