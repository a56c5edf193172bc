// Terrain raster pass (see terrain_renderer.h, docs/renderer.md).
#include "app/terrain_renderer.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>

#include <embedded_shaders.h>

#include "shared/feedback_types.h"

namespace tvt {

namespace {

template <class T>
vk::Buffer upload_vector(vk::Context& ctx, const std::vector<T>& v, VkBufferUsageFlags usage) {
  const VkDeviceSize bytes = VkDeviceSize(v.size() * sizeof(T));
  vk::Buffer b = ctx.create_buffer(bytes, usage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
  ctx.upload(b, v.data(), bytes);
  return b;
}

glm::vec4 v4(const glm::dvec3& v, double w) { return glm::vec4(glm::dvec4(v, w)); }

}  // namespace

std::optional<FeedbackMode> feedback_mode_from_string(std::string_view name) {
  for (FeedbackMode m : {FeedbackMode::None, FeedbackMode::MainPass, FeedbackMode::Attachment, FeedbackMode::SeparatePass})
    if (name == feedback_mode_name(m)) return m;
  return std::nullopt;
}

FeedbackMode default_feedback_mode(VkPhysicalDeviceType type) {
  return type == VK_PHYSICAL_DEVICE_TYPE_CPU ? FeedbackMode::Attachment : FeedbackMode::MainPass;
}

const char* feedback_mode_name(FeedbackMode mode) {
  switch (mode) {
    case FeedbackMode::None: return "none";
    case FeedbackMode::MainPass: return "main";
    case FeedbackMode::Attachment: return "attachment";
    case FeedbackMode::SeparatePass: return "separate";
  }
  return "?";
}

std::optional<VtMipFilter> mip_filter_from_string(std::string_view name) {
  if (name == "trilinear") return VtMipFilter::Trilinear;
  if (name == "bilinear") return VtMipFilter::Bilinear;
  constexpr std::string_view kBrilinear = "brilinear";
  if (!name.starts_with(kBrilinear)) return std::nullopt;
  name.remove_prefix(kBrilinear.size());
  if (name.empty()) return VtMipFilter{kDefaultBrilinearBand};
  if (name.front() != ':' || name.size() == 1) return std::nullopt;
  name.remove_prefix(1);
  float band = 0.f;
  const auto [end, ec] = std::from_chars(name.data(), name.data() + name.size(), band);
  if (ec != std::errc() || end != name.data() + name.size() || !VtMipFilter{band}.valid()) return std::nullopt;
  return VtMipFilter{band};
}

std::string mip_filter_name(VtMipFilter filter) {
  if (filter == VtMipFilter::Trilinear) return "trilinear";
  if (filter == VtMipFilter::Bilinear) return "bilinear";
  char digits[32];
  const auto [end, ec] = std::to_chars(digits, digits + sizeof digits, filter.band);
  return "brilinear:" + std::string(digits, ec == std::errc() ? end : digits);
}

Result<std::unique_ptr<TerrainRenderer>> TerrainRenderer::create(vk::Context& context, const SceneAssets& assets,
                                                                 const TerrainRendererOptions& options) {
  return create(context, assets.heightfield, assets.desc.terrain, assets.desc.vt, options);
}

Result<std::unique_ptr<TerrainRenderer>> TerrainRenderer::create(vk::Context& context, const ImageF& heightfield,
                                                                 const TerrainDesc& terrain, const VtConfig& vt,
                                                                 const TerrainRendererOptions& options) {
  if (options.width == 0 || options.height == 0 || options.width > 16384 || options.height > 16384)
    return make_error("terrain renderer: width and height must be 1 ... 16384 pixels");
  if (!context.features().dynamic_rendering)
    return make_error("terrain renderer: device " + context.device_name() + " lacks dynamicRendering (Vulkan 1.3)");
  const int sources = int(options.vt.has_value()) + int(options.direct.has_value()) + int(options.plain.has_value());
  if (sources > 1 || (sources == 1 && options.texel_output))
    return make_error("terrain renderer: vt, direct, plain and texel_output are exclusive");
  if (!(std::isfinite(options.lighting.detail_relief_m) && options.lighting.detail_relief_m >= 0.0 &&
        options.lighting.detail_relief_m <= 1e6))
    return make_error("terrain renderer: lighting.detail_relief_m must be in [0, 1e6] metres, got " +
                      std::to_string(options.lighting.detail_relief_m));
  const bool probe = options.vt && options.vt->probe_output;
  const FeedbackMode feedback = options.vt ? options.vt->feedback : FeedbackMode::None;
  if (probe && (feedback == FeedbackMode::MainPass || feedback == FeedbackMode::Attachment))
    return make_error("terrain renderer: vt.probe_output needs feedback None or SeparatePass");

  // A direct-splat pass reads every material: a material that cannot be loaded is this call's
  // error (naming scene file, field and image), not a fatal check in the buffer accessors.
  if (options.direct && options.direct->composer)
    if (auto loaded = options.direct->composer->upload_all_materials(); !loaded) return loaded.error();
  auto mesh = TerrainMesh::create(heightfield, terrain.extent_m, terrain.height_m, vt, options.mesh);
  if (!mesh) return mesh.error();

  std::unique_ptr<TerrainRenderer> r(new TerrainRenderer());
  r->context_ = &context;
  r->options_ = options;
  r->mesh_ = std::move(mesh).value();
  r->fog_density_ = options.lighting.fog_density_per_m < 0.0 ? 1.5 / terrain.extent_m : options.lighting.fog_density_per_m;

  r->vertex_buffer_ = upload_vector(context, r->mesh_.vertices(), VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  r->index_buffer_ = upload_vector(context, r->mesh_.indices(), VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
  r->height_buffer_ = upload_vector(context, r->mesh_.heightfield().data, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  r->frame_buffer_ = context.create_buffer(sizeof(gpu::TvtTerrainFrame),
                                           VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);

  vk::RenderTargetDesc td;
  td.width = options.width;
  td.height = options.height;
  td.color_formats = {VK_FORMAT_R8G8B8A8_UNORM};
  if (options.texel_output) td.color_formats.push_back(VK_FORMAT_R32G32B32A32_UINT);
  if (probe) td.color_formats.push_back(VK_FORMAT_R32G32B32A32_SFLOAT);
  if (feedback == FeedbackMode::Attachment) {
    td.color_formats.push_back(VK_FORMAT_R32G32_UINT);
    td.extra_color_usage = VK_IMAGE_USAGE_STORAGE_BIT;  // read by feedback_pick.comp
  }
  td.depth = true;
  r->target_ = vk::RenderTarget(context, td);

  vk::GraphicsPipelineDesc pd;
  pd.vertex_spirv = shaders::terrain_vert();
  if (options.vt)
    pd.fragment_spirv = probe                                ? shaders::terrain_vt_probe_frag()
                        : feedback == FeedbackMode::MainPass ? shaders::terrain_vt_frag()
                        : feedback == FeedbackMode::Attachment ? shaders::terrain_vt_attach_frag()
                                                             : shaders::terrain_vt_nofb_frag();
  else if (options.direct)
    pd.fragment_spirv = options.direct->matched_lod ? shaders::terrain_direct_matched_frag() : shaders::terrain_direct_frag();
  else if (options.plain)
    pd.fragment_spirv = shaders::terrain_plain_frag();
  else
    pd.fragment_spirv = options.texel_output ? shaders::terrain_texel_frag() : shaders::terrain_frag();
  // TVT_TERRAIN_SPEC_MAX_ANISOTROPY, _FEEDBACK_DIVISOR, _DETAIL_NORMAL, _MIP_BAND (a float)
  if (options.vt)
    pd.fragment_constants = {options.vt->max_anisotropy, options.vt->feedback_divisor,
                             options.lighting.detail_relief_m > 0.0 ? 1u : 0u,
                             std::bit_cast<uint32_t>(options.vt->mip_filter.band)};
  else if (options.direct && options.direct->matched_lod)  // only _MIP_BAND is declared there
    pd.fragment_constants = {1u, 8u, 1u, std::bit_cast<uint32_t>(options.direct->mip_filter.band)};
  pd.vertex_bindings = {{0, sizeof(TerrainVertex), VK_VERTEX_INPUT_RATE_VERTEX}};
  pd.vertex_attributes = {{gpu::TVT_TERRAIN_ATTR_GRID, 0, VK_FORMAT_R16G16B16A16_UINT, 0}};
  pd.bindings = {
      {gpu::TVT_BIND_TERRAIN_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER,
       VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT},
      {gpu::TVT_BIND_TERRAIN_HEIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_SHADER_STAGE_VERTEX_BIT},
  };
  const VkShaderStageFlags fs = VK_SHADER_STAGE_FRAGMENT_BIT;
  if (options.direct) {
    if (!options.direct->composer) return make_error("terrain renderer: direct inputs need a composer");
    if (!options.direct->mip_filter.valid())
      return make_error("terrain renderer: direct.mip_filter.band must be in [0, 1], got " +
                        std::to_string(options.direct->mip_filter.band));
    pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_COMPOSE_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, fs});
    pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_MATERIAL_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, fs});
    pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_META_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, fs});
    pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_WEIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, fs});
  }
  if (options.plain) {
    if (!options.plain->texture) return make_error("terrain renderer: plain inputs need a texture");
    pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_PLAIN, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, fs});
  }
  if (options.vt) {
    const TerrainVtInputs& v = *options.vt;
    if (!v.info || !v.entries || !v.cache || v.sampler == VK_NULL_HANDLE || v.feedback_divisor < 1 || v.feedback_divisor > 64)
      return make_error("terrain renderer: vt inputs incomplete or feedback_divisor outside 1..64");
    const uint32_t max_aniso = std::max(1u, vt.border_texels);
    if (v.max_anisotropy < 1 || v.max_anisotropy > max_aniso)
      return make_error("terrain renderer: vt.max_anisotropy must be between 1 and the page border B = " +
                        std::to_string(max_aniso));
    if (!v.mip_filter.valid())
      return make_error("terrain renderer: vt.mip_filter.band must be in [0, 1], got " + std::to_string(v.mip_filter.band));
    pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_VT_INFO, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, fs});
    pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_VT_ENTRIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, fs});
    pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_VT_CACHE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, fs});
    if (feedback == FeedbackMode::MainPass) {
      pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_FEEDBACK, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, fs});
      pd.bindings.push_back({gpu::TVT_BIND_TERRAIN_FEEDBACK_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, fs});
    }
    if (feedback != FeedbackMode::None) {
      r->feedback_.divisor = v.feedback_divisor;
      r->feedback_.width = feedback_extent(options.width, v.feedback_divisor);
      r->feedback_.height = feedback_extent(options.height, v.feedback_divisor);
      r->feedback_buffer_ = context.create_buffer(VkDeviceSize(r->feedback_.width) * r->feedback_.height * 8,
                                                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                                      VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                                  false);
      if (feedback != FeedbackMode::Attachment)  // the pick pass takes them as push constants
        r->feedback_params_buffer_ = context.create_buffer(
            sizeof(gpu::TvtFeedbackWrite), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
    }
  }
  pd.push_constant_bytes = sizeof(gpu::TvtTerrainDraw);
  pd.push_constant_stages = VK_SHADER_STAGE_VERTEX_BIT;
  pd.color_formats = td.color_formats;
  pd.depth_format = vk::RenderTarget::kDepthFormat;
  pd.depth_compare = VK_COMPARE_OP_GREATER_OR_EQUAL;  // reverse-Z
  pd.cull_mode = options.cull_back_faces ? VK_CULL_MODE_BACK_BIT : VK_CULL_MODE_NONE;
  // Triangles are counter-clockwise seen from above (and skirts seen from outside). The
  // projection flips y, and Vulkan's orientation rule (spec "Basic Polygon Rasterization":
  // a = -1/2 sum x_i y_{i+1} - x_{i+1} y_i in framebuffer coordinates) carries its own minus
  // sign, so they stay COUNTER_CLOCKWISE.
  pd.front_face = VK_FRONT_FACE_COUNTER_CLOCKWISE;
  r->pipeline_ = context.create_graphics_pipeline(pd);
  r->descriptors_ = context.allocate_descriptor_set(r->pipeline_);
  r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, r->frame_buffer_);
  r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_HEIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, r->height_buffer_);
  if (options.direct) {
    const GpuComposer& c = *options.direct->composer;
    r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_COMPOSE_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c.params_buffer());
    r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_MATERIAL_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c.material_buffer());
    r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_META_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c.meta_buffer());
    r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_WEIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, c.weight_buffer());
  }
  if (options.plain) {
    const PlainTexture& p = *options.plain->texture;
    r->descriptors_.write_sampled_image(gpu::TVT_BIND_TERRAIN_PLAIN, p.image(), p.sampler(),
                                        VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  }
  if (options.vt) {
    const TerrainVtInputs& v = *options.vt;
    r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_VT_INFO, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, *v.info);
    r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_VT_ENTRIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, *v.entries);
    r->descriptors_.write_sampled_image(gpu::TVT_BIND_TERRAIN_VT_CACHE, *v.cache, v.sampler, VK_IMAGE_LAYOUT_GENERAL);
    if (feedback == FeedbackMode::MainPass) {
      r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_FEEDBACK, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, r->feedback_buffer_);
      r->descriptors_.write_buffer(gpu::TVT_BIND_TERRAIN_FEEDBACK_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER,
                                   r->feedback_params_buffer_);
    }
    if (feedback == FeedbackMode::Attachment) {
      const vk::ComputeBinding pick_bindings[] = {{gpu::TVT_BIND_FEEDBACK_PICK_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
                                                  {gpu::TVT_BIND_FEEDBACK_PICK_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
      r->pick_pipeline_ =
          context.create_compute_pipeline(shaders::feedback_pick_comp(), pick_bindings, sizeof(gpu::TvtFeedbackWrite));
      r->pick_descriptors_ = context.allocate_descriptor_set(r->pick_pipeline_);
      r->pick_descriptors_.write_storage_image(gpu::TVT_BIND_FEEDBACK_PICK_IMAGE, r->target_.color(1));
      r->pick_descriptors_.write_buffer(gpu::TVT_BIND_FEEDBACK_PICK_TEXELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                        r->feedback_buffer_);
    }
    if (feedback == FeedbackMode::SeparatePass) {
      // Same vertex stage, draws and depth test at 1/N resolution; colour = feedback texel.
      vk::RenderTargetDesc fd;
      fd.width = r->feedback_.width;
      fd.height = r->feedback_.height;
      fd.color_formats = {VK_FORMAT_R32G32_UINT};
      fd.depth = true;
      r->feedback_target_ = vk::RenderTarget(context, fd);
      vk::GraphicsPipelineDesc fp = pd;
      fp.fragment_spirv = shaders::terrain_feedback_frag();
      fp.color_formats = fd.color_formats;
      fp.bindings = {
          pd.bindings[0], pd.bindings[1],
          {gpu::TVT_BIND_TERRAIN_VT_INFO, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, fs},
          {gpu::TVT_BIND_TERRAIN_FEEDBACK_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, fs},
      };
      r->feedback_pipeline_ = context.create_graphics_pipeline(fp);
      r->feedback_descriptors_ = context.allocate_descriptor_set(r->feedback_pipeline_);
      vk::DescriptorSet& s = r->feedback_descriptors_;
      s.write_buffer(gpu::TVT_BIND_TERRAIN_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, r->frame_buffer_);
      s.write_buffer(gpu::TVT_BIND_TERRAIN_HEIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, r->height_buffer_);
      s.write_buffer(gpu::TVT_BIND_TERRAIN_VT_INFO, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, *v.info);
      s.write_buffer(gpu::TVT_BIND_TERRAIN_FEEDBACK_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, r->feedback_params_buffer_);
    }
  }
  if (auto st = context.status(); !st) return st.error();  // a failed Vulkan call (r frees what was made)
  return r;
}

gpu::TvtTerrainFrame TerrainRenderer::frame_constants(const Camera& camera) const {
  const TerrainLighting& l = options_.lighting;
  const double mpt = mesh_.metres_per_texel();
  // Anchor: the camera's level-0 texel, from double precision; everything on the GPU is
  // relative to it (integers) or to the camera (small floats).
  const double cx = camera.position_m.x / mpt, cy = camera.position_m.y / mpt;
  gpu::TvtTerrainFrame f{};
  f.clip_from_relative = glm::mat4(camera.clip_from_relative(aspect()));
  f.sun = v4(glm::normalize(l.sun_direction), l.sun_intensity);
  f.sun_color = v4(l.sun_color, l.ambient);
  f.sky = v4(l.sky_color, fog_density_);
  f.albedo_override = l.albedo_override ? v4(*l.albedo_override, 1.0) : glm::vec4(0.0f);
  // Clamped to [-V/2, 3V/2] so every anchor-relative texel fits int32 (|.| <= 3V/2 < 2^31 for
  // V <= 2^30); a camera farther out only loses sub-texel precision on a far-away terrain.
  const double v = double(mesh_.vt_texels());
  f.anchor_x = int64_t(std::floor(std::clamp(cx, -0.5 * v, 1.5 * v)));
  f.anchor_y = int64_t(std::floor(std::clamp(cy, -0.5 * v, 1.5 * v)));
  f.camera = glm::vec4(float(cx - double(f.anchor_x)), float(cy - double(f.anchor_y)), float(camera.position_m.z),
                       float(mpt));
  const ImageF& hf = mesh_.heightfield();
  f.terrain = glm::vec4(float(mesh_.height_m()), float(mesh_.extent_m() / hf.width),
                        float(mesh_.extent_m() / hf.height), float(l.detail_relief_m));
  f.hf = glm::uvec4(uint32_t(hf.width), uint32_t(hf.height), mesh_.log2_vt(), 0u);
  f.sampling = glm::uvec4(0u);
  if (options_.plain) {
    f.sampling.x = options_.plain->texture->vt_mip();
    f.sampling.z = options_.plain->texture->log2_size();
  }
  return f;
}

void TerrainRenderer::record(VkCommandBuffer cmd, const Camera& camera) {
  if (!context_->status()) return;  // nothing is recorded after a failed Vulkan call (latched)
  const gpu::TvtTerrainFrame frame = frame_constants(camera);
  const FeedbackMode feedback = options_.vt ? options_.vt->feedback : FeedbackMode::None;
  // Earlier frames' shader reads of the frame buffer finish before it is overwritten (WAR:
  // an execution dependency is enough).
  // (The compute stage: the feedback compactor of an earlier frame reads the feedback buffer.)
  context_->fn().vkCmdPipelineBarrier(cmd,
                       VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT |
                           VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0, nullptr, 0, nullptr);
  context_->fn().vkCmdUpdateBuffer(cmd, frame_buffer_.handle(), 0, sizeof(frame), &frame);
  if (feedback != FeedbackMode::None) {
    // This frame's rotating pixel of every N x N block; main-pass feedback starts from all
    // texels empty (the separate pass clears its own target, the pick writes every texel).
    const uint32_t n = feedback_.divisor, i = uint32_t(frames_recorded_ % (uint64_t(n) * n));
    feedback_.offset_x = (i * 7u) % n;  // a scrambled walk over the block
    feedback_.offset_y = (i / n + i * 3u) % n;
    if (feedback != FeedbackMode::Attachment)
      context_->fn().vkCmdUpdateBuffer(cmd, feedback_params_buffer_.handle(), 0, sizeof(feedback_), &feedback_);
    if (feedback == FeedbackMode::MainPass) context_->fn().vkCmdFillBuffer(cmd, feedback_buffer_.handle(), 0, VK_WHOLE_SIZE, 0xffffffffu);
  }
  ++frames_recorded_;
  context_->memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                              VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                              VK_ACCESS_UNIFORM_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);

  const glm::dvec3& sky = options_.lighting.sky_color;
  std::vector<VkClearColorValue> clears(2);
  clears[0].float32[0] = float(sky.r);
  clears[0].float32[1] = float(sky.g);
  clears[0].float32[2] = float(sky.b);
  clears[0].float32[3] = 1.0f;
  if (options_.texel_output)
    for (uint32_t& c : clears[1].uint32) c = kNoTexel;
  else if (feedback == FeedbackMode::Attachment)
    for (uint32_t& c : clears[1].uint32) c = gpu::TVT_FEEDBACK_EMPTY_WORD;
  else
    for (float& c : clears[1].float32) c = -1.0f;  // the VT probe's "sky"

  stats_ = {};
  std::vector<ChunkDraw> draws = mesh_.select(camera, aspect(), &stats_.chunks);
  // Front to back, so early depth tests reject hidden fragments before they shade (and, in VT
  // mode, before they sample the cache or write feedback).
  std::stable_sort(draws.begin(), draws.end(),
                   [](const ChunkDraw& a, const ChunkDraw& b) { return a.distance_m < b.distance_m; });
  target_.begin(cmd, clears, 0.0f);
  draw_chunks(cmd, pipeline_, descriptors_, draws, frame);
  target_.end(cmd);
  if (feedback == FeedbackMode::SeparatePass) record_feedback_pass(cmd, draws, frame);
  if (feedback == FeedbackMode::Attachment) record_feedback_pick(cmd);
  if (feedback != FeedbackMode::None) {
    // Feedback texels (fragment stores, the pick pass or the separate pass's copy) are read by
    // the compactor's compute passes.
    context_->memory_barrier(cmd,
                                VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT |
                                    VK_PIPELINE_STAGE_TRANSFER_BIT,
                                VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
                                VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT);
  }
}

void TerrainRenderer::draw_chunks(VkCommandBuffer cmd, const vk::GraphicsPipeline& pipeline, const vk::DescriptorSet& set,
                                  const std::vector<ChunkDraw>& draws, const gpu::TvtTerrainFrame& frame) {
  context_->fn().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline.handle());
  const VkDescriptorSet s = set.handle();
  context_->fn().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline.layout(), 0, 1, &s, 0, nullptr);
  const VkDeviceSize offset = 0;
  const VkBuffer vb = vertex_buffer_.handle();
  context_->fn().vkCmdBindVertexBuffers(cmd, 0, 1, &vb, &offset);
  context_->fn().vkCmdBindIndexBuffer(cmd, index_buffer_.handle(), 0, VK_INDEX_TYPE_UINT32);
  uint64_t triangles = 0;
  for (const ChunkDraw& d : draws) {
    gpu::TvtTerrainDraw push{};
    const int64_t rx = d.origin_x - frame.anchor_x, ry = d.origin_y - frame.anchor_y;  // |.| <= 3V/2
    TVT_CHECK(rx > INT32_MIN && rx < INT32_MAX && ry > INT32_MIN && ry < INT32_MAX);
    push.rel_texel = glm::ivec2(int32_t(rx), int32_t(ry));
    push.quad_texels = mesh_.quad_texels();
    push.skirt_depth_m = float(d.skirt_depth_m);
    context_->fn().vkCmdPushConstants(cmd, pipeline.layout(), VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(push), &push);
    const LodRange& lod = mesh_.lod(d.lod);
    context_->fn().vkCmdDrawIndexed(cmd, lod.index_count, 1, lod.first_index, 0, 0);
    triangles += lod.index_count / 3;
  }
  if (&pipeline == &pipeline_) stats_.triangles = triangles;
}

// FeedbackMode::SeparatePass: the same draws into the 1/N-resolution target. The viewport is
// W/N x H/N pixels (fractional), shifted so that the centre of texel (x, y) lands on the centre
// of full-resolution pixel (x N + offset_x, y N + offset_y): x_fb = x_full / N + 1/2 - (offset +
// 1/2) / N. Then the image is copied into the feedback buffer (the layout main-pass feedback uses).
void TerrainRenderer::record_feedback_pass(VkCommandBuffer cmd, const std::vector<ChunkDraw>& draws,
                                           const gpu::TvtTerrainFrame& frame) {
  std::vector<VkClearColorValue> clears(1);
  for (uint32_t& c : clears[0].uint32) c = gpu::TVT_FEEDBACK_EMPTY_WORD;
  feedback_target_.begin(cmd, clears, 0.0f);
  const float n = float(feedback_.divisor);
  VkViewport vp{};
  vp.x = 0.5f - (float(feedback_.offset_x) + 0.5f) / n;
  vp.y = 0.5f - (float(feedback_.offset_y) + 0.5f) / n;
  vp.width = float(options_.width) / n;
  vp.height = float(options_.height) / n;
  vp.minDepth = 0.0f;
  vp.maxDepth = 1.0f;
  context_->fn().vkCmdSetViewport(cmd, 0, 1, &vp);
  draw_chunks(cmd, feedback_pipeline_, feedback_descriptors_, draws, frame);
  feedback_target_.end(cmd);
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageExtent = {feedback_.width, feedback_.height, 1};
  context_->fn().vkCmdCopyImageToBuffer(cmd, feedback_target_.color(0).handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                         feedback_buffer_.handle(), 1, &region);
}

// FeedbackMode::Attachment: feedback_pick.comp copies the rotating pixel of every N x N block
// from attachment 1 into the feedback buffer (every texel written). The attachment goes to
// GENERAL for the compute pass and back, so end()'s layout contract (TRANSFER_SRC) holds.
void TerrainRenderer::record_feedback_pick(VkCommandBuffer cmd) {
  const vk::Image& image = target_.color(1);
  context_->transition(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
  context_->fn().vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pick_pipeline_.handle());
  const VkDescriptorSet set = pick_descriptors_.handle();
  context_->fn().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pick_pipeline_.layout(), 0, 1, &set, 0, nullptr);
  context_->fn().vkCmdPushConstants(cmd, pick_pipeline_.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(feedback_), &feedback_);
  const uint32_t texels = feedback_.width * feedback_.height;
  context_->fn().vkCmdDispatch(cmd, (texels + gpu::TVT_FEEDBACK_GROUP - 1) / gpu::TVT_FEEDBACK_GROUP, 1, 1);
  context_->transition(cmd, image, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
}

ImageRGBA8 TerrainRenderer::render(const Camera& camera) {
  context_->run_commands([&](VkCommandBuffer cmd) { record(cmd, camera); });
  return target_.read_rgba8(0);
}

}  // namespace tvt
