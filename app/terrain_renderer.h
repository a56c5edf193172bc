// Terrain raster pass: draws the chunked heightfield (TerrainMesh) for a Camera into its own
// RenderTarget with sun + ambient lighting and distance fog toward the sky colour; the sky is
// the clear colour. Planned once from TerrainRendererOptions, then record(cmd, camera)
// See docs/renderer.md for coordinates, precision, LOD and cracks.
//
// Not thread-safe. record() updates the frame uniform buffer inside the command buffer
// (vkCmdUpdateBuffer), so several recorded frames may be in flight as long as they are
// executed in submission order on one queue.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <glm/glm.hpp>

#include "compose/scene_assets.h"
#include "terrain/camera.h"
#include "composer/gpu_composer.h"
#include "app/plain_texture.h"
#include "app/render_target.h"
#include "terrain/terrain_mesh.h"
#include "gpu/context.h"
#include "shared/terrain_types.h"

namespace tvt {

struct TerrainLighting {
  glm::dvec3 sun_direction{0.45, 0.30, 0.84};  // toward the sun, world (normalised on use)
  double sun_intensity = 1.0;
  glm::dvec3 sun_color{1.0, 0.95, 0.86};       // linear
  double ambient = 0.28;
  glm::dvec3 sky_color{0.56, 0.70, 0.88};      // linear; also the fog colour and clear colour
  double fog_density_per_m = -1.0;             // < 0: 1.5 / extent_m; 0: no fog
  std::optional<glm::dvec3> albedo_override;   // set: constant albedo instead of terrain_albedo()
  // Relief of the material height (albedo alpha 0 .. 1) in metres for the detail normal; 0: the
  // heightfield normal alone (VT passes then skip the height-gradient gathers: cheaper). Must
  // be finite and >= 0.
  double detail_relief_m = 1.0;
};

// Who writes the virtual texture's feedback (page ids at 1/N of the view resolution, docs/virtual-texture.md).
enum class FeedbackMode : uint8_t {
  None,          // no feedback (a second view of the same VT, or measuring the sampling alone)
  MainPass,      // the colour pass stores it (storage buffer) for one rotating pixel per N x N block
  Attachment,    // the colour pass writes every pixel's page on a second colour attachment
                 // (R32G32_UINT) and a compute pass (feedback_pick.comp) takes the same rotating
                 // pixel per block into the feedback buffer: MainPass's texels without a store
                 // in the shader (default: nearly free on lavapipe, where the store doubled the pass)
  SeparatePass,  // a separate pass at 1/N resolution with its own depth writes every texel;
                 // its viewport is shifted so texel (x, y) sees the scene point of the same
                 // rotating full-resolution pixel MainPass would report (terrain_types.h)
};

// "none", "main", "attachment", "separate" (the CLI's names); nullopt for anything else.
// The cheaper feedback writer on a device type, from `terravt bench frame`: on a CPU device
// (lavapipe) main-pass stores make the colour pass about twice as slow, so the attachment; on a
// GPU (H200, 1280x720) stores cost +0.03 ms over no feedback where the attachment and its pick
// cost +0.17 ms, so main-pass stores.
FeedbackMode default_feedback_mode(VkPhysicalDeviceType type);
std::optional<FeedbackMode> feedback_mode_from_string(std::string_view name);
const char* feedback_mode_name(FeedbackMode mode);

// How a VT sample filters between mips (vt_lod.glsl, tvt_filtered_lod): the two mips around
// the LOD are blended only while the LOD's fraction lies within band / 2 of one half; outside
// that band the nearer mip alone is read, with one page lookup and fetch, and feedback asks for
// that mip only (nothing finer is produced than is sampled). The blend weight is continuous:
// it ramps from 0 to 1 across the band.
//   band 1        trilinear: blends everywhere, two lookups and fetches per sample
//   band 0        bilinear: the nearest mip (GL_LINEAR_MIPMAP_NEAREST), visible mip bands
//   0 < band < 1  "brilinear", the trilinear optimisation GPU drivers apply: a narrower blend,
//                 two lookups for about `band` of the samples
struct VtMipFilter {
  float band = 1.f;  // in [0, 1]
  bool valid() const { return band >= 0.f && band <= 1.f; }  // false for NaN too
  static const VtMipFilter Trilinear, Bilinear;
  friend bool operator==(const VtMipFilter&, const VtMipFilter&) = default;
};
inline constexpr VtMipFilter VtMipFilter::Trilinear{1.f};
inline constexpr VtMipFilter VtMipFilter::Bilinear{0.f};
inline constexpr float kDefaultBrilinearBand = 0.25f;
// "trilinear", "bilinear", "brilinear" (band kDefaultBrilinearBand) or "brilinear:W" with W a
// number in [0, 1]; nullopt for anything else (including NaN).
std::optional<VtMipFilter> mip_filter_from_string(std::string_view name);
// "trilinear", "bilinear" or "brilinear:W" (shortest text that parses back to the same band).
std::string mip_filter_name(VtMipFilter filter);

// Virtual-texture mode: albedo comes from the VT (terrain_vt*.frag) and, unless the feedback
// mode is None, the renderer fills feedback_buffer(). The objects must outlive the renderer
// (render/vt_system.h owns them).
struct TerrainVtInputs {
  const vk::Buffer* info = nullptr;     // TvtVtInfo
  const vk::Buffer* entries = nullptr;  // page table
  const vk::Image* cache = nullptr;     // physical cache (layout GENERAL)
  VkSampler sampler = VK_NULL_HANDLE;
  uint32_t feedback_divisor = 8;        // N: one feedback texel per N x N pixels
  FeedbackMode feedback = FeedbackMode::Attachment;
  // Anisotropic filtering: up to this many bilinear taps per mip along the footprint's major
  // axis, the LOD from major axis / taps (vt_lod.glsl). 1: isotropic trilinear. At most the
  // page border B, so the taps stay inside the looked-up slot (docs/renderer.md). Feedback
  // asks for the mips the anisotropic LOD selects.
  uint32_t max_anisotropy = 1;
  VtMipFilter mip_filter = VtMipFilter::Trilinear;  // also the separate feedback pass's
  // Adds colour attachment 1 (R32G32B32A32_SFLOAT), per pixel: x LOD, y data mip of the finer
  // lookup, z data mip of the coarser one (-1: one mip only), w distance in data-mip texels from
  // the sample points to the nearest page-payload edge (< 1/2: bilinear taps read the border).
  // Sky pixels: -1. For tests; needs feedback None or SeparatePass.
  bool probe_output = false;
};

// Direct-splat mode: the composition per pixel (terrain_direct*.frag). The composer (its
// scene buffers) must outlive the renderer.
struct TerrainDirectInputs {
  const GpuComposer* composer = nullptr;
  // false: the composition at the pixel's exact position with the pixel's footprint (the
  // papers' form). true: at the texel centres of the VT mip(s) the VT LOD (no bias) selects,
  // filtered as the VT sampler filters the cache — what the VT shows when every wanted page
  // is resident (tests).
  bool matched_lod = false;
  VtMipFilter mip_filter = VtMipFilter::Trilinear;  // matched_lod: the VT filter to match
};

// Plain-texture mode: one mip-mapped texture over the terrain (app/plain_texture.h), which
// must outlive the renderer.
struct TerrainPlainInputs {
  const PlainTexture* texture = nullptr;
};

struct TerrainRendererOptions {
  uint32_t width = 1280;   // pixels
  uint32_t height = 720;
  TerrainMeshOptions mesh;
  TerrainLighting lighting;
  bool cull_back_faces = true;
  // Adds colour attachment 1 (R32G32B32A32_UINT): per pixel the level-0 VT texel coordinate
  // as floor (x, y: low 32 bits) and fraction (z, w: float bits); sky pixels keep
  // kNoTexel in every channel. For precision tests and debugging.
  bool texel_output = false;
  // At most one albedo source; none: the height/slope colour ramp.
  std::optional<TerrainVtInputs> vt;          // sample the virtual texture (and write feedback)
  std::optional<TerrainDirectInputs> direct;  // compose per pixel
  std::optional<TerrainPlainInputs> plain;    // sample one plain texture
};

struct TerrainFrameStats {
  ChunkSelectStats chunks;
  uint64_t triangles = 0;
};

class TerrainRenderer {
 public:
  static constexpr uint32_t kNoTexel = 0xffffffffu;

  static Result<std::unique_ptr<TerrainRenderer>> create(vk::Context& context, const ImageF& heightfield,
                                                         const TerrainDesc& terrain, const VtConfig& vt,
                                                         const TerrainRendererOptions& options = {});
  static Result<std::unique_ptr<TerrainRenderer>> create(vk::Context& context, const SceneAssets& assets,
                                                         const TerrainRendererOptions& options = {});

  // Records the whole pass into the render target (begin, draws, end): the colour attachments
  // end in TRANSFER_SRC_OPTIMAL. Chunk selection (culling, LOD) runs on the CPU here. With
  // FeedbackMode::SeparatePass the low-resolution feedback pass and its copy into
  // feedback_buffer() follow, with Attachment the compute pick into it; with any feedback, a
  // barrier makes the buffer readable by compute.
  void record(VkCommandBuffer cmd, const Camera& camera);
  // Blocking convenience: record + submit + wait + read back attachment 0.
  ImageRGBA8 render(const Camera& camera);

  double aspect() const { return double(options_.width) / double(options_.height); }
  const TerrainMesh& mesh() const { return mesh_; }
  const vk::RenderTarget& target() const { return target_; }
  const TerrainFrameStats& last_stats() const { return stats_; }
  const TerrainRendererOptions& options() const { return options_; }
  // VT mode with feedback: the feedback texels of the last recorded frame (feedback_types.h
  // format, empty texels all ones), feedback_width() x feedback_height(); ready for the
  // compute stage (and transfers) after record().
  const vk::Buffer& feedback_buffer() const { return feedback_buffer_; }
  uint32_t feedback_width() const { return feedback_.width; }
  // Feedback texels along a side of `pixels` pixels: one per divisor x divisor block (0 for
  // divisor 0, which create() refuses).
  static uint32_t feedback_extent(uint32_t pixels, uint32_t divisor) {
    return divisor == 0 ? 0 : uint32_t((uint64_t(pixels) + divisor - 1) / divisor);
  }
  uint32_t feedback_height() const { return feedback_.height; }
  // The frame constants record() would use for `camera` (exposed for tests).
  gpu::TvtTerrainFrame frame_constants(const Camera& camera) const;

 private:
  TerrainRenderer() = default;
  vk::Context* context_ = nullptr;
  TerrainRendererOptions options_;
  TerrainMesh mesh_;
  double fog_density_ = 0.0;
  vk::Buffer vertex_buffer_, index_buffer_, height_buffer_, frame_buffer_;
  vk::Buffer feedback_buffer_, feedback_params_buffer_;
  gpu::TvtFeedbackWrite feedback_{};
  uint64_t frames_recorded_ = 0;
  vk::GraphicsPipeline pipeline_;
  vk::DescriptorSet descriptors_;
  vk::RenderTarget target_;
  // FeedbackMode::SeparatePass: the low-resolution pass.
  vk::GraphicsPipeline feedback_pipeline_;
  vk::DescriptorSet feedback_descriptors_;
  vk::RenderTarget feedback_target_;
  // FeedbackMode::Attachment: the pick pass (feedback_pick.comp).
  vk::ComputePipeline pick_pipeline_;
  vk::DescriptorSet pick_descriptors_;

  void draw_chunks(VkCommandBuffer cmd, const vk::GraphicsPipeline& pipeline, const vk::DescriptorSet& set,
                   const std::vector<ChunkDraw>& draws, const gpu::TvtTerrainFrame& frame);
  void record_feedback_pass(VkCommandBuffer cmd, const std::vector<ChunkDraw>& draws, const gpu::TvtTerrainFrame& frame);
  void record_feedback_pick(VkCommandBuffer cmd);
  TerrainFrameStats stats_;
};

}  // namespace tvt
