// Blocking VT frame driver (see vt_frame_driver.h).
#include "render/vt_frame_driver.h"

#include <algorithm>
#include <vector>

namespace tvt {

Result<std::unique_ptr<VtFrameDriver>> VtFrameDriver::create(vk::Context& context, VtSystem& vt, TerrainRenderer& writer) {
  const auto& vo = writer.options().vt;
  if (!vo || vo->feedback == FeedbackMode::None)
    return make_error("vt frame driver: the writer must sample the VT and write feedback");
  FeedbackCompactor::Options fo;
  fo.feedback_width = writer.feedback_width();
  fo.feedback_height = writer.feedback_height();
  fo.ring_size = 2;
  auto compactor = FeedbackCompactor::create(context, fo);
  if (!compactor) return compactor.error();
  std::unique_ptr<VtFrameDriver> d(new VtFrameDriver());
  d->context_ = &context;
  d->vt_ = &vt;
  d->writer_ = &writer;
  d->compactor_ = std::move(compactor.value());
  return d;
}

Result<VtFrameStats> VtFrameDriver::frame(const Camera& camera) {
  std::vector<PageFeedback> feedback;
  if (frame_ > 0)
    if (auto r = compactor_->read_blocking(frame_ - 1)) {
      for (const auto& [page, count] : r->pages) feedback.push_back(PageFeedback{page, count});
      last_feedback_pages_ = r->pages.size();
    }
  const TerrainMesh& mesh = writer_->mesh();
  const double mpt = mesh.metres_per_texel(), vt_max = double(mesh.vt_texels() - 1);
  const uint32_t cx = uint32_t(std::clamp(camera.position_m.x / mpt, 0.0, vt_max));
  const uint32_t cy = uint32_t(std::clamp(camera.position_m.y / mpt, 0.0, vt_max));
  vt_->begin_frame(frame_ + 1, cx, cy, feedback);
  Status recorded = Ok{};
  context_->run_commands([&](VkCommandBuffer cmd) {
    recorded = vt_->record(cmd);  // a complete frame even when composition failed
    writer_->record(cmd, camera);
  });
  const bool submitted = compactor_->submit(writer_->feedback_buffer(), frame_);
  if (auto st = context_->status(); !st) return st.error();  // a failed Vulkan call (latched)
  TVT_CHECK(submitted);  // the ring slot was read: free
  vt_->end_frame();
  ++frame_;
  // A material that could not be loaded on first use: the frame finished, the error names the
  // scene file, the field and the image file.
  if (!recorded) return recorded.error();
  return vt_->stats();
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
    quiet = (frame_ > 1 && s->residency.requested == 0 && s->composed == 0) ? quiet + 1 : 0;
  }
  c.converged = quiet >= quiet_frames;
  return c;
}

}  // namespace tvt
