// Blocking VT frame driver (see vt_frame_driver.h).
#include "app/vt_frame_driver.h"

#include <algorithm>
#include <optional>
#include <string>

namespace tvt {

Result<std::unique_ptr<terravt::VirtualTexture>> create_tool_vt(vk::Context& context,
                                                                terravt::detail::ToolVirtualTexture desc) {
  auto handles = context.device_handles();
  if (!handles) return handles.error();
  return terravt::detail::create_virtual_texture(handles.value(), desc);
}

CameraTexel camera_texel(const TerrainMesh& mesh, const Camera& camera) {
  const double mpt = mesh.metres_per_texel(), vt_max = double(mesh.vt_texels() - 1);
  return CameraTexel{int64_t(std::clamp(camera.position_m.x / mpt, 0.0, vt_max)),
                     int64_t(std::clamp(camera.position_m.y / mpt, 0.0, vt_max))};
}

TerrainVtInputs terrain_vt_inputs(terravt::VirtualTexture& vt, uint32_t feedback_divisor, FeedbackMode mode,
                                  uint32_t max_anisotropy, VtMipFilter mip_filter) {
  const VtSystem& v = terravt::detail::runtime(vt);
  return TerrainVtInputs{&v.info_buffer(), &v.entry_buffer(), &v.cache(), v.sampler(), feedback_divisor, mode,
                         max_anisotropy, mip_filter};
}

Result<std::unique_ptr<VtFrameDriver>> VtFrameDriver::create(vk::Context& context, terravt::VirtualTexture& vt,
                                                             TerrainRenderer& writer, uint64_t first_frame) {
  const auto& vo = writer.options().vt;
  if (!vo || vo->feedback == FeedbackMode::None)
    return make_error("vt frame driver: the writer must sample the VT and write feedback");
  const uint64_t texels = uint64_t(writer.feedback_width()) * writer.feedback_height();
  if (terravt::detail::Access::feedback_texels(vt) != texels)
    return make_error("vt frame driver: the VT compacts " + std::to_string(terravt::detail::Access::feedback_texels(vt)) +
                      " feedback texels, the writer writes " + std::to_string(texels) +
                      " (make the VT with vt_feedback_texels() of the writer's size)");
  std::unique_ptr<VtFrameDriver> d(new VtFrameDriver());
  d->context_ = &context;
  d->vt_ = &vt;
  d->writer_ = &writer;
  d->frame_ = d->first_frame_ = first_frame;
  return d;
}

Result<VtFrameStats> VtFrameDriver::frame(const Camera& camera) {
  const CameraTexel at = camera_texel(writer_->mesh(), camera);
  // Every earlier frame has completed (run_commands waited): the previous one's feedback joins.
  const std::optional<uint64_t> completed = frame_ > 0 ? std::optional<uint64_t>(frame_ - 1) : std::nullopt;
  if (auto st = vt_->begin_frame(frame_, completed, at.x, at.y, {}); !st) return st.error();
  if (vt_->stats().gpu_feedback) last_feedback_pages_ = vt_->stats().feedback_pages;
  Status recorded = Ok{}, compacted = Ok{};
  context_->run_commands([&](VkCommandBuffer cmd) {
    recorded = vt_->record(cmd);  // a complete frame even when composition failed
    writer_->record(cmd, camera);
    compacted = vt_->record_feedback(cmd, writer_->feedback_buffer().handle());
  });
  if (auto st = context_->status(); !st) return st.error();  // a failed Vulkan call (latched)
  ++frame_;
  if (!compacted) return compacted.error();
  // A material that could not be loaded on first use: the frame finished, the error names the
  // scene file, the field and the image file.
  if (!recorded) return recorded.error();
  return terravt::detail::runtime(*vt_).stats();
}

Result<VtConvergence> VtFrameDriver::converge(const Camera& camera, uint32_t max_frames, uint32_t quiet_frames) {
  if (quiet_frames == 0) {
    const uint32_t n = writer_->options().vt->feedback_divisor;
    quiet_frames = n * n + 1;
  }
  VtConvergence c;
  uint32_t quiet = 0;
  while (c.frames < max_frames && quiet < quiet_frames) {
    const auto s = frame(camera);
    if (!s) return s.error();
    ++c.frames;
    // Frame 1 has no feedback yet: it cannot count as quiet.
    quiet = (frame_ > first_frame_ + 1 && s->residency.requested == 0 && s->composed == 0) ? quiet + 1 : 0;
  }
  c.converged = quiet >= quiet_frames;
  return c;
}

}  // namespace tvt
