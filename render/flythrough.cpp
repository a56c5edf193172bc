#include "render/flythrough.h"

#include <algorithm>
#include <chrono>

#include "compose/scene_identity.h"
#include "render/feedback_compactor.h"
#include "gpu/frame_ring.h"
#include "render/terrain_renderer.h"
#include "render/vt_debug.h"

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
  auto packed = pack_scene(assets, options_for(o.method, o.mip_strategy));
  if (!packed) return packed.error();
  VtSystemOptions vto = o.vt;
  vto.frames_in_flight = o.frames_in_flight;
  if (vto.store && vto.scene_hash == 0)
    vto.scene_hash = store_scene_identity(assets.desc, o.method, o.mip_strategy, vto.store->desc().pyramid);
  auto vt = VtSystem::create(g, packed.value(), vto);
  if (!vt) return vt.error();
  VtSystem& v = *vt.value();
  v.set_debug_view(o.debug_view);
  TerrainRendererOptions ro;
  ro.width = o.width;
  ro.lighting = o.lighting;
  ro.height = o.height;
  ro.vt = TerrainVtInputs{&v.info_buffer(), &v.entry_buffer(), &v.cache(), v.sampler(), o.feedback_divisor,
                          o.feedback_mode, o.max_anisotropy, o.mip_filter};
  auto terrain = TerrainRenderer::create(g, assets, ro);
  if (!terrain) return terrain.error();
  TerrainRenderer& t = *terrain.value();
  FeedbackCompactor::Options fo;
  fo.feedback_width = t.feedback_width();
  fo.feedback_height = t.feedback_height();
  // One more readback slot than frames in flight: the slot frame f reuses held frame f - K - 1,
  // complete since begin(f) waited for frame f - K (the compactor's own fence for it signals
  // right behind the frame's, so a slot is at worst found busy once and that frame goes
  // without feedback; it never waits).
  fo.ring_size = o.frames_in_flight + 1;
  auto compactor = FeedbackCompactor::create(g, fo);
  if (!compactor) return compactor.error();
  auto ring = FrameRing::create(g, o.frames_in_flight);
  if (!ring) return ring.error();
  FrameRing& frames = *ring.value();

  const TerrainMesh& mesh = t.mesh();
  auto resolved = flythrough_path(assets, mesh, o.camera ? &*o.camera : nullptr);
  if (!resolved) return resolved.error();
  const CameraPath& path = resolved.value();
  const Camera lens = o.camera ? o.camera->lens : Camera{};
  const std::vector<double> cuts = path.cut_times();
  const double mpt = mesh.metres_per_texel();
  const double vt_max = double(assets.desc.vt.size_texels() - 1);

  FlythroughSummary sum;
  const auto start = std::chrono::steady_clock::now();
  std::vector<PageFeedback> feedback;
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
    // The newest compacted feedback whose frame has completed (K frames late after begin(f),
    // newer when the GPU keeps up); never a wait. When none is ready the previous list stands,
    // so requests keep flowing.
    const auto w0 = std::chrono::steady_clock::now();
    for (uint64_t late = 1; late <= o.frames_in_flight + 1 && late <= f; ++late)
      if (auto r = o.deterministic ? compactor.value()->read_blocking(f - late)
                                   : compactor.value()->try_read(f - late, frames.completed(f - late))) {
        feedback.clear();
        for (const auto& [page, count] : r->pages) feedback.push_back(PageFeedback{page, count});
        fr.feedback_pages = r->pages.size();
        fr.feedback_frames_late = late;
        break;
      }
    if (o.deterministic) fr.wait_ms += ms_between(w0, std::chrono::steady_clock::now());
    const auto w1 = std::chrono::steady_clock::now();
    const uint32_t cx = uint32_t(std::clamp(fr.camera.position_m.x / mpt, 0.0, vt_max));
    const uint32_t cy = uint32_t(std::clamp(fr.camera.position_m.y / mpt, 0.0, vt_max));
    v.begin_frame(f + 1, cx, cy, feedback);
    fr.residency_ms = ms_between(o.deterministic ? w1 : w0, std::chrono::steady_clock::now());
    const Status recorded = v.record(cmd);  // a complete frame even when composition failed
    frames.mark();  // GPU stage "vt": material uploads, composition, stored-page copies, table scatter
    t.record(cmd, fr.camera);
    frames.mark();  // "terrain": the terrain pass (and the separate feedback pass)
    // The compaction rides in the frame's command buffer, so its result is ready when the frame
    // is: feedback is typically frames_in_flight frames late, at most one more.
    const VkFence compaction = compactor.value()->record(cmd, t.feedback_buffer(), f);
    frames.submit(compaction);  // the last stage: "compaction"
    v.end_frame();
    if (auto st = g.status(); !st) return st.error();  // before anything of this frame is reported
    if (!recorded) {
      // A material could not be loaded on first use: stop before this frame is reported or
      // written anywhere; the error names the scene file, the field and the image file.
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
