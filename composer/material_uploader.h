// A packed scene's material data on the GPU, uploaded on first use (issue 3: "a material's
// textures and meta-texture are loaded and uploaded only when the first page that uses them is
// requested"). Material n's data is its texture mip chain, its FBPB meta-texture and its
// weight-grid layer. compose_sample.glsl reads none of them for a page whose culling mask
// excludes n, only the mip levels the page's footprint selects, and the meta-texture only while
// FBPB has not faded out (MaterialNeeds, compose/material_culling.h). So the weight layer comes
// with the first page that includes n, the texture from the coarsest level down to the finest
// any recorded page reads (a coarse-first VT starts with a few texels per material), the
// meta-texture with the first page close enough to show features.
//
// The device buffers are allocated whole at construction (sizes and offsets come from the
// PackedScene, so the shaders' view of them never changes); only the copies are deferred.
// A material's texels are read from disk (or generated) by the first record() that needs it
// (PackedScene::load()); a load error fails that record() and nothing of it is recorded.
//
// Not thread-safe. Staging buffers live for `records_in_flight` record() calls: the commands
// that many calls ago recorded must have completed before the next call (the frame ring of
// the caller guarantees it; the composer's job ring has the same depth).
#pragma once
#include <cstdint>
#include <vector>

#include "compose/material_culling.h"
#include "compose/packed_scene.h"
#include "gpu/context.h"
#include "render/page_producer.h"  // MaterialUploadStats

namespace tvt {

class MaterialUploader {
 public:
  MaterialUploader(vk::Context& context, const PackedScene& scene, uint32_t records_in_flight = 1);
  ~MaterialUploader();
  MaterialUploader(const MaterialUploader&) = delete;
  MaterialUploader& operator=(const MaterialUploader&) = delete;

  // Records the copies of whatever `needs` names that is not on the GPU yet (from a staging
  // buffer kept for records_in_flight calls) and a barrier that makes them visible to every later
  // command. Bits of materials the scene does not have are ignored. Nothing when all is there.
  // The data counts as resident from here on: `cmd` must be submitted. Loads the needed
  // materials' texels first; on a load error records nothing and returns it (file and field).
  Status record(VkCommandBuffer cmd, const MaterialNeeds& needs);
  // Uploads everything still missing and waits for it (for passes that compose per pixel).
  Status upload_all();
  // Records a fill of every device buffer with `word` (tests: data read before its upload
  // then shows up as this pattern instead of whatever the allocation held).
  void fill(VkCommandBuffer cmd, uint32_t word);

  bool all_resident() const { return stats_.complete_mask == all_mask(); }
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
    Range texels, meta;                // the whole chain; level l starts at level_first[l]
    std::vector<size_t> level_first;   // mip_count + 1 entries, the last = texels end
    int weight_layer = 0;
    gpu::TvtMaterial layout{};         // the fields same_layout() compares
    int resident_from = 0;             // levels [resident_from, mip_count) are on the GPU
    bool meta_resident = false;
  };
  uint32_t all_mask() const { return materials_.size() >= 32 ? ~0u : (1u << materials_.size()) - 1u; }
  // Everything of every material.
  MaterialNeeds everything() const;
  // Records the copies of what `needs` names and is missing into `cmd`; the staging buffer
  // goes to `keep`. Updates the residency and the counters.
  Status record_copies(VkCommandBuffer cmd, const MaterialNeeds& needs, std::vector<vk::Buffer>& keep);

  vk::Context* context_ = nullptr;
  std::vector<Material> materials_;
  // Loads the materials of `mask` on the host, with the CPU counters.
  Status load(uint32_t mask);

  PackedScene scene_;  // shares the scene's per-material cache: the host texels
  size_t texel_words_ = 0, meta_words_ = 0;
  std::vector<float> host_weights_;
  size_t layer_floats_ = 0;
  std::vector<bool> layer_resident_;
  vk::Buffer texel_buffer_, meta_buffer_, weight_buffer_;
  // Staging of the latest records_in_flight record() calls, by call index modulo that.
  std::vector<std::vector<vk::Buffer>> staging_ring_;
  uint64_t records_ = 0;
  MaterialUploadStats stats_;
};

}  // namespace tvt
