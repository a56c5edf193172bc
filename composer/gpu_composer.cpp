#include "composer/gpu_composer.h"

#include <embedded_shaders.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <limits>

#include "shaders/shared/compose_bindings.h"
#include "shaders/shared/compose_coord.h"

namespace tvt {

namespace {

// Conservative forms of compose_sample.glsl's ramp(): whether it can be above 0 / below 1 at
// v, the shader's float v being within a relative `slack` of the host's double.
constexpr double k_slack = 1e-4;
bool ramp_may_be_positive(double v, double lo, double hi) {
  const double v_hi = v + std::abs(v) * k_slack + 1e-30;
  return hi <= lo ? v_hi >= lo : v_hi > lo;
}
bool ramp_may_be_below_one(double v, double lo, double hi) {
  const double v_lo = v - std::abs(v) * k_slack - 1e-30;
  return hi <= lo ? v_lo < lo : v_lo < hi;
}
// The same where the host holds the shader's own float v: ramp() decides its ends by
// comparison, so no slack is needed.
bool ramp_is_positive(float v, float lo, float hi) { return hi <= lo ? v >= lo : v > lo; }
bool ramp_is_below_one(float v, float lo, float hi) { return hi <= lo ? v < lo : v < hi; }

// lattice_masks(): a lattice of patch corners spanning `span` level-0 texels a side. Below a
// weight texel's spacing a side, less a margin far above the float rounding of weight_at()'s
// grid coordinate, its corners fall in two adjacent weight cells a side, which the shader's
// narrow path assumes.
bool lattice_is_narrow(const gpu::TvtComposeParams& p, double span) {
  if (p.weight_width <= 0 || p.weight_height <= 0 || p.log2_vt < 0 || p.log2_vt > 62) return false;
  const double spacing = std::ldexp(1.0, p.log2_vt) / double(std::max(p.weight_width, p.weight_height));
  return span < spacing * (1.0 - 1.0 / 64.0);
}

// patch_samples(): the corners of a layer's sample lattice span at most the footprint and a
// patch on either side (and at most 7 patches), + 1 for the rounding of the offsets.
bool sample_lattice_is_narrow(const gpu::TvtComposeParams& p, double footprint, double patch_texels) {
  return lattice_is_narrow(p, std::min(footprint + 2.0 * patch_texels, 7.0 * patch_texels) + 1.0);
}

// patch_value(): a patch cell's four corners, one patch apart.
bool patch_cell_is_narrow(const gpu::TvtComposeParams& p, double patch_texels) {
  return lattice_is_narrow(p, patch_texels + 1.0);
}

// compose_sample()'s FBPB points: each reads the weight at the centroid of the feature under it,
// within half the footprint of its centre and a feature's reach of the point. A meta-texture's
// offsets stay inside one tile (R material texels, one period), the centroid a texel's centre
// on, + 1 for the fixed-point rounding; twice that reach a side must fall in two adjacent
// weight cells (the centre's and its nearer neighbour, WeightBlock).
bool feature_weights_are_narrow(const gpu::TvtComposeParams& p, const gpu::TvtMaterial& m, double footprint) {
  if (m.period_fp <= 0 || m.resolution <= 0) return false;
  const double period = double(m.period_fp) / 256.0;
  const double reach = 0.5 * footprint + period * (1.0 + 1.0 / double(m.resolution)) + 1.0;
  return lattice_is_narrow(p, 2.0 * reach);
}

// A DPT layer of a material with DPT that level 0 shows (its fade at one texel a texel), so
// the prefiltered maths do (dpt()'s `present`).
bool dpt_layer_present(const gpu::TvtMaterial& m, int k) {
  return (m.mode == gpu::TVT_MODE_DPT || m.mode == gpu::TVT_MODE_FBPB_DPT) &&
         ramp_may_be_positive(m.dpt[k].patch_texels, m.dpt_fade_lo, m.dpt_fade_hi);
}

}  // namespace

bool small_coordinates(const gpu::TvtComposeParams& p) {
  // Sample positions lie in [0, V] level-0 texels, the prefiltered samples up to half a
  // footprint (at most V/2) beyond: |position| <= 1.5 V * 256 < 2^30 for V <= 2^21.
  if (p.log2_vt > 21) return false;
  const double v_fp = std::ldexp(1.0, p.log2_vt + gpu::TVT_FIXED_BITS);
  for (int n = 0; n < p.material_count && n < gpu::TVT_MAX_MATERIALS; ++n) {
    const gpu::TvtMaterial& m = p.materials[n];
    for (int k = 0; k < std::min(m.dpt_layer_count, gpu::TVT_MAX_DPT_LAYERS); ++k)
      if (m.dpt[k].patch_fp <= 0 || m.dpt[k].patch_fp >= (int64_t(1) << 30)) return false;
    // hex_sample(): global material texels of positions in [0, V], below 2^29 with room to spare.
    if (m.hex_edge > 0 && (m.period_fp <= 0 || v_fp * double(m.resolution) / double(m.period_fp) >= std::ldexp(1.0, 28)))
      return false;
  }
  return true;
}

namespace {
// prefiltered_parts() and sample_pairs(): the parts of mip `mip`, and in `pairs` every
// (material, layer) pair whose samples it reaches, in material and layer order, where they are at
// most TVT_SAMPLE_PAIRS_MAX with narrow lattices (else 0).
uint32_t prefiltered_reach(const gpu::TvtComposeParams& p, uint32_t mip, const FeatureSizes& sizes, uint32_t* pairs) {
  *pairs = 0;
  bool more = false;  // a sampled layer the pairs do not take
  // compose.comp's footprint: 2^mip level-0 texels over at most 2^mip sub-samples a side.
  const double s = std::min(std::max(double(p.supersample), 1.0), std::ldexp(1.0, int(std::min(mip, 62u))));
  const double footprint = std::max(std::ldexp(1.0, int(std::min(mip, 62u))) / s, 1.0 / 256.0);
  // A power-of-two footprint (every validated one) makes the shader's patch ratio exact
  // (per_footprint(): an exponent shift by 1 - e), so the host can evaluate the same float.
  int e = 0;
  const bool exact_ratio = std::frexp(footprint, &e) == 0.5 && std::abs(e) < 100;
  uint32_t parts = 0;
  for (int n = 1; n < p.material_count && n < gpu::TVT_MAX_MATERIALS; ++n) {
    const gpu::TvtMaterial& m = p.materials[n];
    bool finite = std::isfinite(double(m.fbpb_fade_lo)) && std::isfinite(double(m.fbpb_fade_hi)) &&
                  std::isfinite(double(m.lod_bias)) && m.period_fp > 0;
    for (int k = 0; k < std::min(m.dpt_layer_count, gpu::TVT_MAX_DPT_LAYERS); ++k)
      finite = finite && std::isfinite(double(m.dpt[k].patch_texels));
    if (!finite) {  // not a validated scene: keep every part, the samples in the loop
      *pairs = 0;
      return gpu::TVT_PART_ALL;
    }
    for (int k = 0; k < std::min(m.dpt_layer_count, gpu::TVT_MAX_DPT_LAYERS); ++k) {  // dpt()
      if (!dpt_layer_present(m, k)) continue;
      const double texels = m.dpt[k].patch_texels;
      const float lo = p.prefilter_patch_lo, hi = p.prefilter_patch_hi;
      const float ratio_f = exact_ratio ? std::ldexp(m.dpt[k].patch_texels, 1 - e) : 0.0f;
      const double ratio = texels / footprint;
      if (exact_ratio ? ramp_is_positive(ratio_f, lo, hi) : ramp_may_be_positive(ratio, lo, hi)) {
        parts |= gpu::TVT_PART_DPT_POINT;
        if (!patch_cell_is_narrow(p, texels)) parts |= gpu::TVT_PART_DPT_CORNERS_WIDE;
      }
      if (exact_ratio ? ramp_is_below_one(ratio_f, lo, hi) : ramp_may_be_below_one(ratio, lo, hi)) {
        parts |= gpu::TVT_PART_DPT_EXPECT;
        const double patches = footprint / std::max(texels, 1e-6);
        if (ramp_may_be_below_one(patches, gpu::TVT_PATCH_SAMPLES_LO, gpu::TVT_PATCH_SAMPLES_HI)) {
          parts |= gpu::TVT_PART_DPT_SAMPLES;
          const bool narrow = sample_lattice_is_narrow(p, footprint, texels);
          if (!narrow) parts |= gpu::TVT_PART_DPT_SAMPLES_WIDE;
          if (narrow && int(gpu::tvt_sample_pairs_count(*pairs)) < gpu::TVT_SAMPLE_PAIRS_MAX)
            *pairs = gpu::tvt_sample_pairs_add(*pairs, n, k);
          else
            more = true;
        }
      }
    }
    if (fbpb_mode(m) && !std::isnan(sizes[size_t(n)])) {
      // compose_sample()'s FBPB branch: the features at points where tvt_feature_points_hold(),
      // else in expectation, both only where level 0 has them (fade0 = 1 - ramp(LOD at one
      // texel, lo, hi) > 0). material_lod() is exactly k + lod_bias at a footprint of 2^k, and
      // both sides evaluate the switch in the same float arithmetic.
      const bool fade0_positive = ramp_is_below_one(m.lod_bias, m.fbpb_fade_lo, m.fbpb_fade_hi);
      const float size = sizes[size_t(n)];
      bool features = false;
      if (exact_ratio) {
        const bool points = gpu::tvt_feature_points_hold(float(e - 1) + m.lod_bias, size);
        if (fade0_positive) features = points;
        if (fade0_positive && !points) parts |= gpu::TVT_PART_FEATURE_EXPECT;
      } else {
        const double lod = std::log2(footprint) + double(m.lod_bias), slack = 1e-3;  // a float log2
        const double edge = double(size) + double(gpu::TVT_FEATURE_POINTS_REL);
        if (lod - slack < edge && fade0_positive) features = true;
        if (lod + slack >= edge && fade0_positive) parts |= gpu::TVT_PART_FEATURE_EXPECT;
      }
      if (features) {
        parts |= gpu::TVT_PART_FEATURES;
        if (!feature_weights_are_narrow(p, m, footprint)) parts |= gpu::TVT_PART_FEATURE_WEIGHTS_WIDE;
      }
    }
  }
  if (more) *pairs = 0;  // the samples stay in the loop
  return parts;
}
}  // namespace

FeatureSizes unknown_feature_sizes() {
  FeatureSizes sizes;
  sizes.fill(std::numeric_limits<float>::quiet_NaN());
  return sizes;
}

FeatureSizes loaded_feature_sizes(const PackedScene& scene) {
  FeatureSizes sizes = unknown_feature_sizes();
  const uint32_t loaded = scene.loaded_mask();
  for (int n = 0; n < scene.params.material_count && n < gpu::TVT_MAX_MATERIALS; ++n)
    if (loaded >> n & 1u) sizes[size_t(n)] = scene.stat(size_t(n), gpu::TVT_STATS_FEATURE_LOG2_SIZE);
  return sizes;
}

uint32_t prefiltered_parts(const gpu::TvtComposeParams& p, uint32_t mip, const FeatureSizes& sizes) {
  uint32_t pairs = 0;
  return prefiltered_reach(p, mip, sizes, &pairs);
}

uint32_t sample_pairs(const gpu::TvtComposeParams& p, uint32_t mip) {
  uint32_t pairs = 0;
  prefiltered_reach(p, mip, unknown_feature_sizes(), &pairs);  // the pairs are DPT's alone
  return pairs;
}

uint32_t direct_parts(const gpu::TvtComposeParams& p) {
  for (int n = 1; n < p.material_count && n < gpu::TVT_MAX_MATERIALS; ++n) {
    const gpu::TvtMaterial& m = p.materials[n];
    if (m.mode != gpu::TVT_MODE_DPT && m.mode != gpu::TVT_MODE_FBPB_DPT) continue;
    // Every layer, whatever its fade: a supersampled page's footprint is below a level-0
    // texel, where a layer too small for level 0 can show. A NaN patch is not narrow.
    for (int k = 0; k < std::min(m.dpt_layer_count, gpu::TVT_MAX_DPT_LAYERS); ++k)
      if (!patch_cell_is_narrow(p, m.dpt[k].patch_texels)) return gpu::TVT_PART_ALL;
  }
  return gpu::TVT_PART_ALL & ~gpu::TVT_PART_DPT_CORNERS_WIDE;
}

GpuComposer::~GpuComposer() = default;

Result<std::unique_ptr<GpuComposer>> GpuComposer::create(vk::Context& context, const PackedScene& scene,
                                                         uint32_t slots, const GpuComposerOptions& options) {
  if (slots == 0 || slots > context.properties().limits.maxImageArrayLayers)
    return make_error("compose slots: must be between 1 and " +
                      std::to_string(context.properties().limits.maxImageArrayLayers) + ", got " +
                      std::to_string(slots));
  std::unique_ptr<GpuComposer> c(new GpuComposer());
  c->context_ = &context;
  c->slots_ = slots;
  c->slot_texels_ = uint32_t(scene.params.page_texels + 2 * scene.params.border_texels);
  c->params_ = scene.params;
  c->culler_ = std::make_unique<MaterialCuller>(scene);
  c->scene_ = scene.materials_only();

  c->params_buffer_ = context.create_buffer(sizeof(gpu::TvtComposeParams), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  if (!c->params_buffer_) return context.status().error();
  std::memcpy(c->params_buffer_.mapped(), &c->params_, sizeof(c->params_));
  c->records_in_flight_ = std::max(options.records_in_flight, 1u);
  c->specialise_ = options.specialise;
  c->derive_specialisation();
  c->materials_ = std::make_unique<MaterialUploader>(context, scene, c->records_in_flight_);
  if (options.poison_materials)
    context.run_commands([m = c->materials_.get()](VkCommandBuffer cmd) { m->fill(cmd, 0xffffffffu); });  // by value: may be deferred
  if (!options.lazy_materials)
    if (auto s = c->materials_->upload_all(); !s) return s.error();
  c->job_buffer_ = context.create_buffer(sizeof(gpu::TvtPageJob) * slots * c->records_in_flight_,
                                         VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  // The read-back buffer of compose_pages() is made on its first use: a VT cache never needs it.
  if (options.target) {
    const vk::Image& t = *options.target;
    if (t.format() != VK_FORMAT_R8G8B8A8_UNORM || t.width() != c->slot_texels_ || t.height() != c->slot_texels_ ||
        t.layers() < slots)
      return make_error("compose target: must be RGBA8 " + std::to_string(c->slot_texels_) + "^2 with at least " +
                        std::to_string(slots) + " layers");
    c->target_ = options.target;
  } else {
    const VkImageUsageFlags usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT |
                                    VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
    if (auto fits = context.check_image_fits(VK_FORMAT_R8G8B8A8_UNORM, c->slot_texels_, c->slot_texels_, slots, usage,
                                             "compose slots (one per cached page, vt.page_texels + 2 vt.border_texels "
                                             "texels a side; use fewer slots or smaller pages)");
        !fits)
      return fits.error();
    c->own_output_ = context.create_image(VK_FORMAT_R8G8B8A8_UNORM, c->slot_texels_, c->slot_texels_, slots, usage);
    c->target_ = &c->own_output_;
    // By value: with deferred set-up (gpu/context.h) this runs after create() returned.
    context.run_commands([ctx = &context, image = &c->own_output_](VkCommandBuffer cmd) {
      ctx->transition(cmd, *image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL);
    });
  }

  // The direct variant, and the prefiltered ones of every mip the VT has, now: a driver
  // compiles at pipeline creation, which inside a frame would be a hitch.
  if (!c->make_variants()) return context.status().error();
  const vk::ComputePipeline* pipeline = c->variant(false, c->direct_parts_);  // made above
  c->descriptors_ = context.allocate_descriptor_set(*pipeline);
  c->descriptors_.write_buffer(TVT_BIND_COMPOSE_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->params_buffer_);
  c->descriptors_.write_buffer(TVT_BIND_MATERIAL_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->materials_->texels());
  c->descriptors_.write_buffer(TVT_BIND_META_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->materials_->meta());
  c->descriptors_.write_buffer(TVT_BIND_WEIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->materials_->weights());
  c->descriptors_.write_buffer(TVT_BIND_PAGE_JOBS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c->job_buffer_);
  c->descriptors_.write_storage_image(TVT_BIND_PAGE_OUTPUT, *c->target_);
  if (auto st = context.status(); !st) return st.error();  // a failed Vulkan call (c frees what was made)
  return c;
}

void GpuComposer::derive_specialisation() {
  spec_modes_ = 0xffffffffu;
  spec_hex_ = true;
  spec_small_ = false;
  parts_by_mip_.fill(gpu::TVT_PART_ALL);
  pairs_by_mip_.fill(0);
  direct_parts_ = gpu::TVT_PART_ALL;
  if (!specialise_) return;
  spec_modes_ = 0;
  spec_hex_ = false;
  for (int n = 0; n < params_.material_count; ++n) {
    const uint32_t mode = uint32_t(params_.materials[n].mode);
    // An unknown mode (parameters not from pack_scene): keep every mode's path.
    if (n > 0) spec_modes_ |= mode < 32 ? 1u << mode : 0xffffffffu;
    spec_hex_ = spec_hex_ || params_.materials[n].hex_edge > 0;
  }
  spec_small_ = small_coordinates(params_);
  // Where a prefiltered mip takes an FBPB material's features at points and where in
  // expectation follows from the feature size in its statistics (tvt_feature_points_hold):
  // loaded here, on the host, so that every variant is made now, not by the page that first
  // reads the material. One that fails to load is left out: a page that reads it fails its
  // upload, so it is never dispatched (a load's error is kept, not retried).
  if (params_.prefiltered != 0)
    for (int n = 1; n < params_.material_count && n < gpu::TVT_MAX_MATERIALS; ++n)
      if (fbpb_mode(params_.materials[n])) (void)scene_.load(1u << n);  // one at a time: a failure stops no other
  const FeatureSizes sizes = loaded_feature_sizes(scene_);
  for (uint32_t mip = 0; mip < parts_by_mip_.size(); ++mip) {
    // prefiltered_parts() and sample_pairs() from one pass over the layers; the layers the
    // pairs name are sampled before the material loop, not in it.
    const uint32_t parts = prefiltered_reach(params_, mip, sizes, &pairs_by_mip_[mip]);
    parts_by_mip_[mip] = parts & (pairs_by_mip_[mip] ? ~gpu::TVT_PART_DPT_SAMPLES : ~0u);
  }
  direct_parts_ = direct_parts(params_);
}

bool GpuComposer::make_variants() {
  if (!variant(false, direct_parts_)) return false;
  if (!specialise_ || params_.prefiltered == 0) return true;
  // Mips 1 to the VT's top one (a single page); record() takes deeper mips as the table's last.
  const VtConfig vt{uint32_t(params_.log2_vt), uint32_t(params_.page_texels), uint32_t(params_.border_texels)};
  const uint32_t top = uint32_t(std::clamp(int(vt.mip_count()) - 1, 1, int(parts_by_mip_.size()) - 1));
  for (uint32_t mip = 1; mip <= top; ++mip)
    if (!variant(true, parts_by_mip_[mip], pairs_by_mip_[mip])) return false;
  return true;
}

const vk::ComputePipeline* GpuComposer::variant(bool prefiltered, uint32_t parts, uint32_t pairs) {
  if (!specialise_) {
    prefiltered = true;  // compose.comp decides per page
    parts = gpu::TVT_PART_ALL;
    pairs = 0;
  }
  const uint32_t modes = spec_modes_;
  const bool hex = spec_hex_, small = spec_small_;
  for (const Variant& v : variants_)
    if (v.modes == modes && v.hex == hex && v.prefiltered == prefiltered && v.parts == parts && v.pairs == pairs &&
        v.small == small)
      return &v.pipeline;
  // Every variant has the same bindings, so one descriptor set serves them all.
  static constexpr vk::ComputeBinding bindings[] = {
      {TVT_BIND_COMPOSE_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}, {TVT_BIND_MATERIAL_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
      {TVT_BIND_META_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},    {TVT_BIND_WEIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
      {TVT_BIND_PAGE_JOBS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},      {TVT_BIND_PAGE_OUTPUT, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
  };
  const vk::SpecConstant constants[] = {
      {TVT_COMPOSE_SPEC_MODES, modes},
      {TVT_COMPOSE_SPEC_HEX, hex ? 1u : 0u},
      {TVT_COMPOSE_SPEC_PREFILTERED, prefiltered ? 1u : 0u},
      {TVT_COMPOSE_SPEC_PARTS, parts},
      {TVT_COMPOSE_SPEC_SMALL, small ? 1u : 0u},
      {TVT_COMPOSE_SPEC_ONLY_PREFILTERED, specialise_ && prefiltered ? 1u : 0u},
      {TVT_COMPOSE_SPEC_SAMPLE_PAIRS, pairs}};
  vk::ComputePipeline pipeline =
      context_->create_compute_pipeline(shaders::compose_comp(), bindings, sizeof(gpu::TvtComposePush), constants);
  if (pipeline.handle() == VK_NULL_HANDLE) return nullptr;
  variants_.push_back(Variant{modes, hex, prefiltered, parts, pairs, small, std::move(pipeline)});
  return &variants_.back().pipeline;
}

void GpuComposer::set_params(const gpu::TvtComposeParams& params) {
  TVT_CHECK(materials_->same_layout(params));
  params_ = params;
  derive_specialisation();
  make_variants();  // a failure shows in the context's status, which record() returns
  culler_->set_params(params);
  std::memcpy(params_buffer_.mapped(), &params_, sizeof(params_));
}

Status GpuComposer::record(VkCommandBuffer cmd, std::span<const PageJob> jobs) {
  TVT_CHECK(jobs.size() <= slots_);
  if (auto st = context_->status(); !st) return st;  // nothing is recorded after a failed Vulkan call
  // This call's part of the job ring; the call that last used it has completed (contract).
  const uint32_t job_offset = uint32_t(records_++ % records_in_flight_) * slots_;
  auto* dst = static_cast<gpu::TvtPageJob*>(job_buffer_.mapped()) + job_offset;
  MaterialNeeds needed;  // what any of the pages reads
  // One dispatch per pipeline variant: direct pages (mip 0, or every mip under the direct and
  // supersampled strategies), then prefiltered ones grouped by the parts their mip can reach.
  // A job names its slot, so the order is free.
  const auto key = [&](const PageJob& j) -> uint64_t {
    if (!specialise_ || params_.prefiltered == 0 || j.page.mip == 0) return 0;
    const size_t mip = std::min<size_t>(j.page.mip, parts_by_mip_.size() - 1);
    return 1 + (uint64_t(pairs_by_mip_[mip]) << 32 | parts_by_mip_[mip]);
  };
  std::vector<std::pair<uint64_t, uint32_t>> order;  // (variant key, job)
  order.reserve(jobs.size());
  for (uint32_t i = 0; i < jobs.size(); ++i) order.emplace_back(key(jobs[i]), i);
  std::stable_sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (size_t i = 0; i < order.size(); ++i) {
    const PageJob& j = jobs[order[i].second];
    TVT_CHECK(j.slot < slots_);
    const uint32_t mask = culling_ ? culler_->mask(j.page) : 0xffffffffu;
    dst[i] = gpu::TvtPageJob{j.page.mip, j.page.x, j.page.y, j.slot, mask, 0u, 0u, 0u};
    if (params_.pattern == gpu::TVT_COMPOSE_PATTERN_NONE) needed.merge(culler_->needs(j.page, mask));
  }
  // Also with no jobs: the per-record counters restart.
  if (auto s = materials_->record(cmd, needed); !s) return s;
  const uint32_t groups = (slot_texels_ + gpu::TVT_COMPOSE_GROUP - 1) / gpu::TVT_COMPOSE_GROUP;
  for (size_t first = 0; first < order.size();) {
    size_t end = first;
    while (end < order.size() && order[end].first == order[first].first) ++end;
    const uint64_t k = order[first].first;
    const vk::ComputePipeline* pipeline =
        k == 0 ? variant(false, direct_parts_) : variant(true, uint32_t(k - 1), uint32_t((k - 1) >> 32));
    if (!pipeline) return context_->status().error();
    context_->fn().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline->handle());
    const VkDescriptorSet set = descriptors_.handle();
    context_->fn().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline->layout(), 0, 1, &set, 0,
                                           nullptr);
    const gpu::TvtComposePush push{job_offset + uint32_t(first), uint32_t(end - first)};
    context_->fn().vkCmdPushConstants(cmd, pipeline->layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
    context_->fn().vkCmdDispatch(cmd, groups, groups, uint32_t(end - first));
    first = end;
  }
  return Ok{};
}

Result<std::vector<std::vector<uint8_t>>> GpuComposer::compose_pages(std::span<const PageId> pages) {
  std::vector<std::vector<uint8_t>> out;
  out.reserve(pages.size());
  const size_t page_bytes = size_t(slot_texels_) * slot_texels_ * 4;
  if (!readback_buffer_ && !pages.empty())
    readback_buffer_ = context_->create_buffer(VkDeviceSize(page_bytes) * slots_, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  if (!pages.empty() && !readback_buffer_) return context_->status().error();
  for (size_t first = 0; first < pages.size(); first += slots_) {
    const size_t count = std::min<size_t>(slots_, pages.size() - first);
    std::vector<PageJob> jobs(count);
    for (size_t i = 0; i < count; ++i) jobs[i] = PageJob{pages[first + i], uint32_t(i)};
    Status recorded = Ok{};
    context_->run_commands([&](VkCommandBuffer cmd) {
      recorded = record(cmd, jobs);
      if (!recorded) return;
      context_->transition(cmd, *target_, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
      VkBufferImageCopy region{};
      region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, uint32_t(count)};
      region.imageExtent = {slot_texels_, slot_texels_, 1};
      context_->fn().vkCmdCopyImageToBuffer(cmd, target_->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, readback_buffer_.handle(), 1,
                             &region);
      context_->transition(cmd, *target_, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
    });
    if (!recorded) return recorded.error();
    if (auto st = context_->status(); !st) return st.error();  // nothing ran
    const auto* src = static_cast<const uint8_t*>(readback_buffer_.mapped());
    for (size_t i = 0; i < count; ++i) out.emplace_back(src + i * page_bytes, src + (i + 1) * page_bytes);
  }
  return out;
}

Result<double> GpuComposer::time_batch(std::span<const PageId> pages, int repeats) {
  TVT_CHECK(pages.size() <= slots_);
  std::vector<PageJob> jobs(pages.size());
  for (size_t i = 0; i < pages.size(); ++i) jobs[i] = PageJob{pages[i], uint32_t(i)};
  // A hardware GPU is timed by timestamps around the batch (submit and fence latency would
  // swamp a batch that takes a fraction of a millisecond); a CPU device by the wall clock.
  const bool cpu_device = context_->properties().deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
  const auto start = std::chrono::steady_clock::now();
  double device_seconds = 0;
  Status recorded = Ok{};
  for (int r = 0; r < repeats && recorded; ++r) {
    const auto rec = [&](VkCommandBuffer cmd) { recorded = record(cmd, jobs); };
    if (cpu_device)
      context_->run_commands(rec);
    else
      device_seconds += context_->run_commands_timed(rec);
  }
  if (!recorded) return recorded.error();
  if (auto st = context_->status(); !st) return st.error();
  const double seconds =
      cpu_device ? std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() : device_seconds;
  return seconds / std::max(repeats, 1);
}

}  // namespace tvt
