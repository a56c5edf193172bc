#include "render/flythrough.h"

#include <algorithm>
#include <chrono>

#include "compose/scene_identity.h"
#include "render/feedback_compactor.h"
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

Result<FlythroughSummary> run_flythrough(vk::Context& g, const SceneAssets& assets, const FlythroughOptions& o,
                                         const FrameCallback& on_frame) {
  if (o.frames < 1) return make_error("frames: must be at least 1");
  if (!(o.fps > 0.0)) return make_error("fps: must be > 0");
  if (o.feedback_mode == FeedbackMode::None) return make_error("feedback_mode: the loop needs feedback");
  auto packed = pack_scene(assets, options_for(o.method));
  if (!packed) return packed.error();
  VtSystemOptions vto = o.vt;
  if (vto.store && vto.scene_hash == 0) vto.scene_hash = scene_identity(assets.desc, o.method);
  auto vt = VtSystem::create(g, packed.value(), vto);
  if (!vt) return vt.error();
  VtSystem& v = *vt.value();
  v.set_debug_view(o.debug_view);
  TerrainRendererOptions ro;
  ro.width = o.width;
  ro.height = o.height;
  ro.vt = TerrainVtInputs{&v.info_buffer(), &v.entry_buffer(), &v.cache(), v.sampler(), o.feedback_divisor,
                          o.feedback_mode, o.max_anisotropy};
  auto terrain = TerrainRenderer::create(g, assets, ro);
  if (!terrain) return terrain.error();
  TerrainRenderer& t = *terrain.value();
  FeedbackCompactor::Options fo;
  fo.feedback_width = t.feedback_width();
  fo.feedback_height = t.feedback_height();
  fo.ring_size = 3;
  auto compactor = FeedbackCompactor::create(g, fo);
  if (!compactor) return compactor.error();

  const TerrainMesh& mesh = t.mesh();
  const CameraPath path = flythrough_path(assets, mesh);
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
    fr.camera = path.camera_at(std::min(fr.time_s, path.end_time()));
    for (double c : cuts) fr.cut = fr.cut || (c > fr.time_s - 1.0 / o.fps && c <= fr.time_s && f > 0);
    // The newest compacted feedback whose fence has signalled (1 or 2 frames late); never a
    // wait. When none is ready the previous list stands, so requests keep flowing.
    for (uint64_t late = 1; late <= 2 && late <= f; ++late)
      if (auto r = o.deterministic ? compactor.value()->read_blocking(f - late) : compactor.value()->try_read(f - late)) {
        feedback.clear();
        for (const auto& [page, count] : r->pages) feedback.push_back(PageFeedback{page, count});
        fr.feedback_pages = r->pages.size();
        fr.feedback_frames_late = late;
        break;
      }
    const uint32_t cx = uint32_t(std::clamp(fr.camera.position_m.x / mpt, 0.0, vt_max));
    const uint32_t cy = uint32_t(std::clamp(fr.camera.position_m.y / mpt, 0.0, vt_max));
    v.begin_frame(f + 1, cx, cy, feedback);
    const auto t1 = std::chrono::steady_clock::now();
    g.run_commands([&](VkCommandBuffer c) {
      v.record(c);
      t.record(c, fr.camera);
    });
    const auto t2 = std::chrono::steady_clock::now();
    compactor.value()->submit(t.feedback_buffer(), f);
    v.end_frame();
    fr.vt = v.stats();
    fr.completed = v.last_completed();
    if (v.stored()) fr.store_errors = v.stored()->take_error_messages();
    fr.triangles = t.last_stats().triangles;
    fr.cpu_ms = ms_between(t0, t1);
    fr.gpu_ms = ms_between(t1, t2);
    fr.total_ms = ms_between(t0, std::chrono::steady_clock::now());
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
      if (!on_frame(fr, views)) break;
    }
  }
  sum.gpu_bytes = v.gpu_bytes();
  sum.seconds = ms_between(start, std::chrono::steady_clock::now()) / 1000.0;
  g.wait_idle();
  return sum;
}

}  // namespace tvt
