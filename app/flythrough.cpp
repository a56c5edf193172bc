#include "app/flythrough.h"

#include <algorithm>
#include <chrono>

#include "app/vt_frame_driver.h"
#include "gpu/frame_ring.h"
#include "app/terrain_renderer.h"
#include "app/vt_debug.h"

namespace tvt {

namespace {
double ms_between(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}
}  // namespace

CameraPath flythrough_path(const SceneAssets& assets, const TerrainMesh& mesh) {
  return CameraPath::default_flythrough(assets.desc.terrain.extent_m, assets.desc.terrain.height_m,
                                        [&mesh](double x, double y) { return mesh.height_m_at(x, y); });
}

Result<CameraPath> flythrough_path(const SceneAssets& assets, const TerrainMesh& mesh, const CameraFile* file) {
  if (!file) return flythrough_path(assets, mesh);
  return resolve_camera_path(*file, [&mesh](double x, double y) { return mesh.height_m_at(x, y); });
}

Result<FlythroughSummary> run_flythrough(vk::Context& g, const SceneAssets& assets, const FlythroughOptions& o,
                                         const FrameCallback& on_frame) {
  if (o.frames < 1) return make_error("frames: must be at least 1");
  if (!(o.fps > 0.0)) return make_error("fps: must be > 0");
  if (o.feedback_mode == FeedbackMode::None) return make_error("feedback_mode: the loop needs feedback");
  if (o.feedback_divisor < 1 || o.feedback_divisor > 64)
    return make_error("feedback_divisor: must be 1 ... 64, got " + std::to_string(o.feedback_divisor));
  // The VT through the public API, on this device, exactly as an engine runs it; it compacts
  // the feedback of the terrain pass made below.
  terravt::detail::ToolVirtualTexture td;
  td.assets = &assets;
  td.method = o.method;
  td.mip_strategy = o.mip_strategy;
  td.runtime = o.vt;
  td.runtime.frames_in_flight = o.frames_in_flight;
  td.feedback_texels = vt_feedback_texels(o.width, o.height, o.feedback_divisor);
  // The terrain pass samples in its fragment shader; the separate feedback pass too.
  td.consumer_stages = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;
  auto made = create_tool_vt(g, td);
  if (!made) return made.error();
  terravt::VirtualTexture& vt = *made.value();
  VtSystem& v = terravt::detail::runtime(vt);  // statistics and debug read-backs only
  v.set_debug_view(o.debug_view);
  TerrainRendererOptions ro;
  ro.width = o.width;
  ro.lighting = o.lighting;
  ro.height = o.height;
  ro.vt = terrain_vt_inputs(vt, o.feedback_divisor, o.feedback_mode, o.max_anisotropy, o.mip_filter);
  auto terrain = TerrainRenderer::create(g, assets, ro);
  if (!terrain) return terrain.error();
  TerrainRenderer& t = *terrain.value();
  auto ring = FrameRing::create(g, o.frames_in_flight);
  if (!ring) return ring.error();
  FrameRing& frames = *ring.value();

  const TerrainMesh& mesh = t.mesh();
  auto resolved = flythrough_path(assets, mesh, o.camera ? &*o.camera : nullptr);
  if (!resolved) return resolved.error();
  const CameraPath& path = resolved.value();
  const Camera lens = o.camera ? o.camera->lens : Camera{};
  const std::vector<double> cuts = path.cut_times();

  FlythroughSummary sum;
  const auto start = std::chrono::steady_clock::now();
  for (uint32_t f = 0; f < o.frames; ++f) {
    const auto t0 = std::chrono::steady_clock::now();
    FlythroughFrame fr;
    fr.index = f;
    fr.time_s = path.start_time() + double(f) / o.fps;
    fr.camera = path.camera_at(std::min(fr.time_s, path.end_time()), lens);
    for (double c : cuts) fr.cut = fr.cut || (c > fr.time_s - 1.0 / o.fps && c <= fr.time_s && f > 0);
    // Back-pressure only: blocks when the GPU is frames_in_flight frames behind.
    VkCommandBuffer cmd = frames.begin(f);
    if (cmd == VK_NULL_HANDLE) return g.status().error();  // a failed Vulkan call (out of memory, device lost)
    fr.wait_ms = frames.last_wait_ms();
    for (const FrameTiming& done : frames.take_completed()) {
      fr.gpu_ms = done.gpu_ms;
      fr.gpu_ms_frame = done.frame;
      if (done.stage_ms.size() == 3) fr.gpu_stage_ms = {done.stage_ms[0], done.stage_ms[1], done.stage_ms[2]};
    }
    // The newest frame known complete: its compacted feedback (typically frames_in_flight
    // frames late, newer when the GPU keeps up) joins this frame's requests; never a wait.
    // Deterministic: exactly the previous frame's, waiting for it.
    const auto w0 = std::chrono::steady_clock::now();
    if (o.deterministic && f > 0) {
      frames.wait_completed(f - 1);
      if (auto st = g.status(); !st) return st.error();
      fr.wait_ms += ms_between(w0, std::chrono::steady_clock::now());
    }
    const auto w1 = std::chrono::steady_clock::now();
    const CameraTexel at = camera_texel(mesh, fr.camera);
    if (auto st = vt.begin_frame(f, frames.completed_through(), at.x, at.y, {}); !st) return st.error();
    fr.residency_ms = ms_between(o.deterministic ? w1 : w0, std::chrono::steady_clock::now());
    if (vt.stats().gpu_feedback) {
      fr.feedback_pages = vt.stats().feedback_pages;
      fr.feedback_frames_late = f - vt.stats().feedback_frame;
    }
    const Status recorded = vt.record(cmd);  // a complete frame even when composition failed
    frames.mark();  // GPU stage "vt": material uploads, composition, stored-page copies, table scatter
    t.record(cmd, fr.camera);
    frames.mark();  // "terrain": the terrain pass (and the separate feedback pass)
    // The compaction rides in the frame's command buffer, so its result is ready when the frame
    // is.
    const Status compacted = vt.record_feedback(cmd, t.feedback_buffer().handle());
    frames.submit();  // the last stage: "compaction"
    if (auto st = g.status(); !st) return st.error();  // before anything of this frame is reported
    if (!compacted) return compacted.error();
    if (!recorded) {
      // A device failure, or a material that could not be loaded on first use: stop before
      // this frame is reported or written anywhere; the error names the scene file, the field
      // and the image file.
      frames.wait_idle();
      g.wait_idle();
      return recorded.error();
    }
    fr.vt = v.stats();
    fr.completed = v.last_completed();
    fr.store_errors = v.producer().take_error_messages();
    fr.triangles = t.last_stats().triangles;
    fr.total_ms = ms_between(t0, std::chrono::steady_clock::now());
    fr.cpu_ms = fr.total_ms - fr.wait_ms;
    sum.frames = f + 1;
    sum.pages_composed += fr.vt.composed;
    sum.pages_loaded += fr.vt.stored.landed;
    sum.load_failures += fr.vt.stored.failed;
    sum.pages_missing += fr.vt.missing;
    sum.oversubscribed_frames += fr.vt.residency.oversubscribed ? 1u : 0u;
    sum.max_mip_bias = std::max(sum.max_mip_bias, fr.vt.residency.mip_bias);
    if (on_frame) {
      FlythroughViews views;
      views.frame = [&t] { return t.target().read_rgba8(0); };
      views.atlas = [&g, &v] { return cache_atlas_image(g, v.cache(), 32, 2); };
      views.page_table = [&v] { return page_table_image(v.residency().page_table()); };
      views.feedback = [&g, &t] { return feedback_image(g, t.feedback_buffer(), t.feedback_width(), t.feedback_height()); };
      views.page_table_bytes = [&g, &v] { return page_table_bytes(g, v.entry_buffer()); };
      const bool go_on = on_frame(fr, views);
      // A read-back that failed (latched) gave zeros: the run fails rather than keep them.
      if (auto st = g.status(); !st) return st.error();
      if (!go_on) break;
    }
  }
  sum.gpu_bytes = v.gpu_bytes();
  frames.wait_idle();
  sum.seconds = ms_between(start, std::chrono::steady_clock::now()) / 1000.0;
  g.wait_idle();
  if (auto st = g.status(); !st) return st.error();
  return sum;
}

}  // namespace tvt
