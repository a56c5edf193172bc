// Drives a terravt::VirtualTexture one blocking frame at a time for one camera: the feedback of
// frame f (written by `writer`, compacted on the GPU by VirtualTexture::record_feedback) joins
// the requests of frame f + 1, which waits for frame f, so a static view converges in the
// fewest frames. For tests and benchmarks that need the cache converged for a pose and then
// render other passes (renderers bound to the same VT) over it. The flythrough loop
// (app/flythrough.h) is the production form: it never waits for feedback.
//
// Not thread-safe; uses the context's queue (serialise with other users). `vt` and `writer`
// must outlive the driver; the writer must write feedback (any FeedbackMode but None), as many
// texels as the VT was made to compact (vt_feedback_texels()).
#pragma once
#include <cstdint>
#include <memory>

#include "api/compose/tool_vt.h"
#include "app/terrain_renderer.h"
#include "terrain/camera.h"
#include "terrain/terrain_mesh.h"

namespace tvt {

struct VtConvergence {
  uint32_t frames = 0;     // frames run
  bool converged = false;  // the last quiet_frames frames requested and composed nothing
};

// The feedback texels a terrain pass of width x height pixels writes with `divisor`: the
// ToolVirtualTexture::feedback_texels of the VT it feeds.
inline uint32_t vt_feedback_texels(uint32_t width, uint32_t height, uint32_t divisor) {
  return TerrainRenderer::feedback_extent(width, divisor) * TerrainRenderer::feedback_extent(height, divisor);
}

// The VT on the device `context` made, through the public API: its handles go to
// terravt::VirtualTexture exactly as an engine hands in its own (api/tool_access.h).
Result<std::unique_ptr<terravt::VirtualTexture>> create_tool_vt(vk::Context& context,
                                                                terravt::detail::ToolVirtualTexture desc);

// The level-0 VT texel under `camera` (clamped to the terrain): begin_frame()'s camera texel.
struct CameraTexel {
  int64_t x = 0, y = 0;
};
CameraTexel camera_texel(const TerrainMesh& mesh, const Camera& camera);

// What a terrain pass binds to sample `vt` (its runtime's buffers, cache and sampler).
TerrainVtInputs terrain_vt_inputs(terravt::VirtualTexture& vt, uint32_t feedback_divisor, FeedbackMode mode,
                                  uint32_t max_anisotropy = 1, VtMipFilter mip_filter = VtMipFilter::Trilinear);

class VtFrameDriver {
 public:
  // first_frame: the frame number the driver's first frame gets; > 0 when the caller ran frames
  // on `vt` before, the last of them first_frame - 1, all completed. The writer must write the
  // VT's feedback_texels (checked).
  static Result<std::unique_ptr<VtFrameDriver>> create(vk::Context& context, terravt::VirtualTexture& vt,
                                                       TerrainRenderer& writer, uint64_t first_frame = 0);

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
  terravt::VirtualTexture* vt_ = nullptr;
  TerrainRenderer* writer_ = nullptr;
  uint64_t frame_ = 0, first_frame_ = 0;
  size_t last_feedback_pages_ = 0;
};

}  // namespace tvt
