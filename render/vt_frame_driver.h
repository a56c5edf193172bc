// Drives a VtSystem one blocking frame at a time for one camera: the feedback of frame f
// (written by `writer`, compacted on the GPU) is read, waiting for it, at the start of frame
// f + 1, so a static view converges in the fewest frames. For tests and benchmarks that need
// the cache converged for a pose and then render other passes (renderers bound to the same
// VtSystem) over it. The flythrough loop (render/flythrough.h) is the production form: it
// never waits for feedback.
//
// Not thread-safe; uses the context's queue (serialise with other users). `vt` and `writer`
// must outlive the driver; the writer must write feedback (any FeedbackMode but None).
#pragma once
#include <cstdint>
#include <memory>

#include "terrain/camera.h"
#include "render/feedback_compactor.h"
#include "render/terrain_renderer.h"
#include "render/vt_system.h"

namespace tvt {

struct VtConvergence {
  uint32_t frames = 0;     // frames run
  bool converged = false;  // the last quiet_frames frames requested and composed nothing
};

class VtFrameDriver {
 public:
  static Result<std::unique_ptr<VtFrameDriver>> create(vk::Context& context, VtSystem& vt, TerrainRenderer& writer);

  // One frame at `camera`: previous feedback -> residency -> compose + table scatter + the
  // writer's pass -> feedback compaction; waits for the frame. Returns the VT's frame stats,
  // or the error of a material that could not be loaded on first use (the frame still ran
  // to its end; the driver stays usable).
  Result<VtFrameStats> frame(const Camera& camera);

  // frame() until `quiet_frames` frames in a row request and compose nothing, at most
  // max_frames. quiet_frames = 0: N^2 + 1 (every pixel of the feedback block has reported
  // once, plus the frame that reads the last report).
  // Stops at the first frame that fails, with its error.
  Result<VtConvergence> converge(const Camera& camera, uint32_t max_frames, uint32_t quiet_frames = 0);

  // Distinct pages the last compacted feedback named (0 before the first frame).
  size_t last_feedback_pages() const { return last_feedback_pages_; }

 private:
  VtFrameDriver() = default;
  vk::Context* context_ = nullptr;
  VtSystem* vt_ = nullptr;
  TerrainRenderer* writer_ = nullptr;
  std::unique_ptr<FeedbackCompactor> compactor_;
  uint64_t frame_ = 0;
  size_t last_feedback_pages_ = 0;
};

}  // namespace tvt
