// Host side of compose.comp: owns the scene buffers on the GPU and composes batches of pages
// into layers of a storage image (RGBA8, (P+2B)^2 per layer). Planned once from a
// PackedScene, then only records. Not thread-safe; one queue.
//
// Materials are uploaded lazily by default (composer/material_uploader.h): record() uploads what
// its pages read for the first time (weight layer, texture levels, meta-texture; exactly as
// compose/material_culling.h predicts) just before their dispatch. Output is byte-identical to
// uploading everything at create(). Under the prefiltered strategy create() and set_params()
// load the FBPB materials on the host (not onto the device): their feature size decides which
// pipeline variant each mip takes (prefiltered_parts()), and every variant is made there.
#pragma once
#include <array>
#include <cstdint>
#include <deque>
#include <memory>
#include <span>
#include <vector>

#include "compose/material_culling.h"
#include "compose/packed_scene.h"
#include "composer/material_uploader.h"
#include "gpu/context.h"
#include "vt/vt_config.h"

namespace tvt {

struct PageJob {
  PageId page;
  uint32_t slot = 0;  // output image layer
};

struct GpuComposerOptions {
  // true: material data reaches the GPU with the first recorded page that reads it (the
  // material, the levels of its texture, its meta-texture); false: create() uploads it all.
  bool lazy_materials = true;
  // Tests: fill the material buffers with 0xffffffff first, so that a read of anything not
  // uploaded yet shows instead of reading whatever the allocation held.
  bool poison_materials = false;
  // record() calls whose commands may still run when the next call comes (frames in flight):
  // each owns its part of the job buffer and its material staging.
  uint32_t records_in_flight = 1;
  // Set: compose into this image (RGBA8, (P+2B)^2, at least `slots` layers, layout GENERAL,
  // STORAGE usage; e.g. the VT's cache, owned by the caller and outliving the composer)
  // instead of an image of its own.
  vk::Image* target = nullptr;
  // false: one pipeline with every path of compose.comp for all pages, instead of variants
  // specialised to the scene and each page's mip (tests: the variants change no byte).
  bool specialise = true;
};

// The log2 feature size of each material (its statistics block's TVT_STATS_FEATURE_LOG2_SIZE),
// which decides where a prefiltered mip takes an FBPB material's features at points and where
// in expectation (tvt_feature_points_hold). NaN for a material not loaded yet: no page that
// reads it is composed before it is, so its FBPB parts are left out until then (the composer
// works the parts out again when one loads; see GpuComposer).
using FeatureSizes = std::array<float, gpu::TVT_MAX_MATERIALS>;
// Every size NaN: no material loaded.
FeatureSizes unknown_feature_sizes();
// The sizes of the materials `scene` has loaded (0 where a material has no features), NaN for
// the rest; none NaN after load_all().
FeatureSizes loaded_feature_sizes(const PackedScene& scene);

// Which parts of the prefiltered composition (TVT_PART_* bits, compose_types.h) a page of mip
// `mip` can reach under `params`: a cleared bit is a part whose weight is zero for every
// material at that footprint, so the pipeline for that mip leaves it out. Conservative (a bit
// is kept where float rounding could decide either way); all bits for unvalidated numbers.
uint32_t prefiltered_parts(const gpu::TvtComposeParams& params, uint32_t mip, const FeatureSizes& sizes);

// The (material, layer) pairs whose DPT samples a page of mip `mip` can reach
// (TVT_COMPOSE_SPEC_SAMPLE_PAIRS, tvt_sample_pairs_*), in material and layer order, where
// prefiltered_parts() has TVT_PART_DPT_SAMPLES, they are at most TVT_SAMPLE_PAIRS_MAX and
// their sample lattices narrow (no TVT_PART_DPT_SAMPLES_WIDE); else 0, and the samples stay in
// the material loop (also for numbers no validated scene has). The composer's variant for that
// mip samples these pairs once a texel before the loop, each with its material and layer as
// constants.
uint32_t sample_pairs(const gpu::TvtComposeParams& params, uint32_t mip);

// The TVT_PART_* bits of direct pages (every mip under the direct and supersampled
// strategies, mip 0 under the prefiltered one): all but TVT_PART_DPT_CORNERS_WIDE where every
// DPT layer has patches narrower than a weight texel (whatever its fade: a supersampled
// page's footprint is below a level-0 texel).
uint32_t direct_parts(const gpu::TvtComposeParams& params);

// Whether every position compose.comp divides by a DPT patch or a hex tile fits their 32-bit
// paths (TVT_COMPOSE_SPEC_SMALL): V <= 2^21, patches below 2^22 texels, and hex-tiled
// materials' texel coordinates below 2^28.
bool small_coordinates(const gpu::TvtComposeParams& params);

class GpuComposer {
 public:
  // slots: layers of the owned output image; also the most pages one dispatch composes.
  static Result<std::unique_ptr<GpuComposer>> create(vk::Context& context, const PackedScene& scene, uint32_t slots,
                                                     const GpuComposerOptions& options = {});
  ~GpuComposer();

  // Replaces the parameter block (method, supersampling...) keeping the uploaded textures:
  // `params` must come from the same scene (same material layout; checked). The GPU must not
  // be using the composer (call between batches).
  void set_params(const gpu::TvtComposeParams& params);
  const gpu::TvtComposeParams& params() const { return params_; }

  // Per-page material culling (on by default; exact, see material_culling.h).
  void set_culling(bool enabled) { culling_ = enabled; }

  // Records the composition of `jobs` into the output image, which must be in layout GENERAL
  // (create() leaves it so), preceded by the upload of materials the jobs need for the first
  // time. Jobs are copied into a host-visible buffer; at most slots() jobs. The commands of
  // the previous record() must have completed, and `cmd` must be submitted. A material read
  // for the first time is loaded from disk first; if that fails, nothing is recorded and the
  // error (scene file, field, image file) is returned: the jobs' slots hold nothing new.
  Status record(VkCommandBuffer cmd, std::span<const PageJob> jobs);

  // Composes pages and reads them back (blocking; tools and tests). Any number of pages:
  // they are processed in batches of slots(). Each result is (P+2B)^2 RGBA8, row-major.
  Result<std::vector<std::vector<uint8_t>>> compose_pages(std::span<const PageId> pages);

  // Times `repeats` batches of `pages` on the GPU (submit + wait), returns seconds per batch.
  Result<double> time_batch(std::span<const PageId> pages, int repeats);

  // Loads and uploads every material (blocking, once; later calls return the same result): a
  // pass that composes per pixel may read any material, so it calls this before it samples the
  // buffers below (TerrainRenderer::create() does for its direct-splat pass).
  Status upload_all_materials() const { return materials_->upload_all(); }

  // The scene buffers (compose_sample.glsl's inputs). Lazily filled: complete only once
  // upload_all_materials() has returned Ok.
  const vk::Buffer& params_buffer() const { return params_buffer_; }
  const vk::Buffer& material_buffer() const { return materials_->texels(); }
  const vk::Buffer& meta_buffer() const { return materials_->meta(); }
  const vk::Buffer& weight_buffer() const { return materials_->weights(); }

  // Material upload counters (what is on the GPU, bytes copied; `last_*`: by the latest
  // record()). For per-frame statistics.
  const MaterialUploadStats& upload_stats() const { return materials_->stats(); }

  vk::Image& output() { return *target_; }
  const vk::Image& output() const { return *target_; }
  uint32_t slots() const { return slots_; }
  uint32_t slot_texels() const { return slot_texels_; }
  // Compute pipelines made so far (one per specialised variant). After create() and
  // set_params() this holds every variant a page of the VT's mips needs: recording makes no
  // more unless a page lies beyond them.
  size_t pipeline_count() const { return variants_.size(); }

 private:
  GpuComposer() = default;
  vk::Context* context_ = nullptr;
  gpu::TvtComposeParams params_{};
  std::unique_ptr<MaterialCuller> culler_;
  bool culling_ = true;
  uint32_t slots_ = 0;
  uint32_t slot_texels_ = 0;
  uint32_t records_in_flight_ = 1;
  uint64_t records_ = 0;
  bool specialise_ = true;
  // The const buffer accessors complete the lazy upload through it (a cache, not state).
  std::unique_ptr<MaterialUploader> materials_;
  vk::Buffer params_buffer_, job_buffer_, readback_buffer_;
  vk::Image own_output_;            // unless GpuComposerOptions::target
  vk::Image* target_ = nullptr;     // what compose.comp writes
  // compose.comp specialised to what the parameters can take (compose_types.h,
  // TVT_COMPOSE_SPEC_*): the modes present, hex-tiling, direct or prefiltered pages, and which
  // parts of the prefiltered maths a page's mip can reach (prefiltered_parts()), and whether
  // the 32-bit coordinate paths always hold (small_coordinates()). Those of the VT's mips are
  // made by create() and set_params() (make_variants()), any other on first use; all are kept.
  // A batch of mixed mips is one dispatch per variant.
  struct Variant {
    uint32_t modes = 0;
    bool hex = false;
    bool prefiltered = false;
    uint32_t parts = 0;  // TVT_PART_*
    uint32_t pairs = 0;  // sample_pairs()
    bool small = false;  // small_coordinates()
    vk::ComputePipeline pipeline;
  };
  // The variant for the current parameters; nullptr after a failed Vulkan call.
  const vk::ComputePipeline* variant(bool prefiltered, uint32_t parts, uint32_t pairs = 0);
  // Makes the variants the parameters need: the direct one, and the prefiltered ones of every
  // mip of the VT when they ask for that strategy (create() and set_params(), so that no
  // driver compiles inside a frame); false after a failed Vulkan call.
  bool make_variants();
  // What the variants are specialised to, from params_ and the FBPB materials' feature sizes
  // (create() and set_params(), which load those materials on the host for it under the
  // prefiltered strategy): record() only looks them up.
  void derive_specialisation();
  uint32_t spec_modes_ = 0xffffffffu;
  bool spec_hex_ = true;
  bool spec_small_ = false;
  std::array<uint32_t, 64> parts_by_mip_{};  // prefiltered_parts() of each mip (62 on: as 62),
                                              // less the samples where sample_pairs() has them
  std::array<uint32_t, 64> pairs_by_mip_{};   // sample_pairs() of each mip
  uint32_t direct_parts_ = 0xffffffffu;       // direct_parts()
  PackedScene scene_;  // the materials' shared cache (not the weights): their feature sizes
  std::deque<Variant> variants_;  // a deque: variant() pointers stay valid as it grows
  vk::DescriptorSet descriptors_;  // from the first variant's (identically defined) layout
};

}  // namespace tvt
