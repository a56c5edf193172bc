// `terravt render`: the main job. A camera flies over the terrain; feedback finds the pages
// the view needs, the residency policy requests them, the compute composer writes them into
// the physical cache, the page table is updated on the GPU, and the terrain pass samples
// through it. Frames (PNG/EXR), a JSON stats line per frame and a summary are written.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

#include "compose/packed_scene.h"
#include "render/camera.h"
#include "render/feedback_compactor.h"
#include "render/terrain_renderer.h"
#include "render/vt_system.h"
#include "tools/cli_common.h"
#include "tools/commands.h"

namespace tvt::cli {
namespace {

struct RenderArgs {
  std::string scene;
  std::string out = "out/render";
  std::string method = "fbpb+dpt2";
  std::string gpu_name;
  std::string format = "png";
  uint32_t frames = 120;
  uint32_t every = 10;
  uint32_t width = 640, height = 360;
  uint32_t cache_slots = 512;
  uint32_t page_budget = 48;
  uint32_t feedback_divisor = 8;
  uint32_t window = 64;
  double fps = 10.0;
  bool quiet = false;
};

int run_render(const RenderArgs& a) {
  const char* cmd = "render";
  const auto method = method_from_string(a.method);
  if (!method) return fail(cmd, "--method: unknown method '" + a.method + "' (linear, blendmap, fbpb, dpt1, dpt2, fbpb+dpt2)", 2);
  if (a.frames < 1 || a.frames > 100000) return fail(cmd, "--frames: must be between 1 and 100000", 2);
  if (a.every < 1) return fail(cmd, "--every: must be at least 1", 2);
  if (a.width < 16 || a.height < 16 || a.width > 8192 || a.height > 8192)
    return fail(cmd, "--width/--height: must be between 16 and 8192", 2);
  if (!(a.fps > 0.0 && a.fps <= 1000.0)) return fail(cmd, "--fps: must be in (0, 1000]", 2);
  if (a.format != "png" && a.format != "exr") return fail(cmd, "--format: png or exr", 2);
  std::error_code ec;
  std::filesystem::create_directories(a.out, ec);
  if (ec || !std::filesystem::is_directory(a.out)) return fail(cmd, "--out: cannot create folder " + a.out, 2);

  auto assets = load_scene_and_assets(a.scene);
  if (!assets) return fail(cmd, assets.error().message, 2);
  auto packed = pack_scene(assets.value(), options_for(*method));
  if (!packed) return fail(cmd, packed.error().message, 2);
  vk::ContextOptions co;
  co.device = a.gpu_name;
  auto ctx = vk::Context::create(co);
  if (!ctx) return fail(cmd, ctx.error().message, 1);
  vk::Context& g = *ctx.value();

  VtSystemOptions vo;
  vo.cache_slots = a.cache_slots;
  vo.page_budget = a.page_budget;
  vo.window_pages = a.window;
  auto vt = VtSystem::create(g, packed.value(), vo);
  if (!vt) return fail(cmd, vt.error().message, 2);
  TerrainRendererOptions ro;
  ro.width = a.width;
  ro.height = a.height;
  ro.vt = TerrainVtInputs{&vt.value()->info_buffer(), &vt.value()->entry_buffer(), &vt.value()->cache(),
                          vt.value()->sampler(), a.feedback_divisor};
  auto terrain = TerrainRenderer::create(g, assets.value(), ro);
  if (!terrain) return fail(cmd, terrain.error().message, 2);
  FeedbackCompactor::Options fo;
  fo.feedback_width = terrain.value()->feedback_width();
  fo.feedback_height = terrain.value()->feedback_height();
  fo.ring_size = 3;
  auto compactor = FeedbackCompactor::create(g, fo);
  if (!compactor) return fail(cmd, compactor.error().message, 2);

  const TerrainMesh& mesh = terrain.value()->mesh();
  const CameraPath path = CameraPath::default_flythrough(assets->desc.terrain.extent_m, assets->desc.terrain.height_m,
                                                         [&mesh](double x, double y) { return mesh.height_m_at(x, y); });
  const double mpt = mesh.metres_per_texel();
  const double vt_max = double(assets->desc.vt.size_texels() - 1);
  std::ofstream stats_file(std::filesystem::path(a.out) / "stats.jsonl");
  if (!stats_file) return fail(cmd, "--out: cannot write stats.jsonl in " + a.out, 1);

  std::printf("terravt render: %s, V = 2^%u, %ux%u, %u frames, method %s, cache %u pages, budget %u/frame, device %s\n",
              assets->desc.source_path.c_str(), assets->desc.vt.log2_size, a.width, a.height, a.frames,
              a.method.c_str(), a.cache_slots, a.page_budget, g.device_name().c_str());
  const auto t_start = std::chrono::steady_clock::now();
  std::vector<PageFeedback> feedback;
  uint64_t total_composed = 0, oversubscribed_frames = 0;
  uint32_t written = 0, max_bias = 0;
  for (uint32_t f = 0; f < a.frames; ++f) {
    const auto t0 = std::chrono::steady_clock::now();
    const double time_s = path.start_time() + double(f) / a.fps;
    const Camera camera = path.camera_at(std::min(time_s, path.end_time()));
    // The newest compacted feedback whose fence has signalled (1 or 2 frames late); never a
    // wait. When none is ready the previous list is used again, so requests keep flowing.
    size_t feedback_pages = 0;
    uint64_t feedback_age = 0;
    for (uint64_t late = 1; late <= 2 && late <= f; ++late)
      if (auto r = compactor.value()->try_read(f - late)) {
        feedback.clear();
        for (const auto& [page, count] : r->pages) feedback.push_back(PageFeedback{page, count});
        feedback_pages = r->pages.size();
        feedback_age = late;
        break;
      }
    const uint32_t cx = uint32_t(std::clamp(camera.position_m.x / mpt, 0.0, vt_max));
    const uint32_t cy = uint32_t(std::clamp(camera.position_m.y / mpt, 0.0, vt_max));
    vt.value()->begin_frame(f + 1, cx, cy, feedback);
    const auto t1 = std::chrono::steady_clock::now();
    g.run_commands([&](VkCommandBuffer c) {
      vt.value()->record(c);
      terrain.value()->record(c, camera);
    });
    const auto t2 = std::chrono::steady_clock::now();
    compactor.value()->submit(terrain.value()->feedback_buffer(), f);
    vt.value()->end_frame();
    const VtFrameStats& s = vt.value()->stats();
    total_composed += s.composed;
    oversubscribed_frames += s.residency.oversubscribed;
    max_bias = std::max(max_bias, s.residency.mip_bias);
    if (f % a.every == 0 || f + 1 == a.frames) {
      const ImageRGBA8 image = terrain.value()->target().read_rgba8(0);
      char name[64];
      std::snprintf(name, sizeof(name), "frame_%05u.%s", f, a.format.c_str());
      if (auto w = write_image((std::filesystem::path(a.out) / name).string(), image); !w)
        return fail(cmd, w.error().message, 1);
      ++written;
    }
    const double frame_ms = seconds_since(t0) * 1000.0;
    nlohmann::json j;
    j["frame"] = f;
    j["time_s"] = time_s;
    j["feedback_pages"] = feedback_pages;
    j["feedback_frames_late"] = feedback_age;
    j["requested"] = s.residency.requested;
    j["produced"] = s.composed;
    j["evicted"] = s.residency.evicted;
    j["resident"] = s.residency.resident;
    j["occupancy"] = s.residency.occupancy;
    j["mip_bias"] = s.residency.mip_bias;
    j["oversubscribed"] = s.residency.oversubscribed;
    j["table_updates"] = s.table_updates;
    j["ms"] = {{"select", s.select_ms},
               {"cpu_before_gpu", std::chrono::duration<double, std::milli>(t1 - t0).count()},
               {"gpu_frame", std::chrono::duration<double, std::milli>(t2 - t1).count()},
               {"total", frame_ms}};
    j["triangles"] = terrain.value()->last_stats().triangles;
    stats_file << j.dump() << "\n";
    if (!a.quiet)
      std::fprintf(stderr, "\r  frame %u/%u  %6.1f ms  resident %u  +%u pages  bias %u%s   ", f + 1, a.frames, frame_ms,
                   s.residency.resident, s.composed, s.residency.mip_bias, s.residency.oversubscribed ? "  OVERSUBSCRIBED" : "");
  }
  if (!a.quiet) std::fprintf(stderr, "\n");
  const double total_s = seconds_since(t_start);
  std::printf("%u frames in %.1f s (%.1f ms/frame), %llu pages composed, %u resident of %u slots, max mip bias %u%s\n",
              a.frames, total_s, 1000.0 * total_s / a.frames, (unsigned long long)total_composed,
              vt.value()->residency().stats().resident, a.cache_slots, max_bias,
              oversubscribed_frames ? (", oversubscribed in " + std::to_string(oversubscribed_frames) + " frames").c_str() : "");
  std::printf("GPU memory: cache + page table %.1f MB; wrote %u frames and stats.jsonl to %s\n",
              double(vt.value()->gpu_bytes()) / 1048576.0, written, a.out.c_str());
  return 0;
}

const CommandRegistrar k_register{
    "render", "Fly a camera over the terrain through the virtual texture (the main job)", 10, [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<RenderArgs>();
      app.add_option("--scene", a->scene, "Scene JSON file (default: the built-in scene)")->check(CLI::ExistingFile);
      app.add_option("--out", a->out, "Output folder for frames and stats")->capture_default_str();
      app.add_option("--frames", a->frames, "Frames to render")->capture_default_str();
      app.add_option("--every", a->every, "Write every k-th frame")->capture_default_str();
      app.add_option("--width", a->width, "Image width")->capture_default_str();
      app.add_option("--height", a->height, "Image height")->capture_default_str();
      app.add_option("--fps", a->fps, "Camera path frames per second")->capture_default_str();
      app.add_option("--method", a->method, "Transition method")->capture_default_str();
      app.add_option("--cache-slots", a->cache_slots, "Physical cache size in pages")->capture_default_str();
      app.add_option("--page-budget", a->page_budget, "Pages composed per frame at most")->capture_default_str();
      app.add_option("--feedback-divisor", a->feedback_divisor, "N: one feedback texel per N x N pixels")->capture_default_str();
      app.add_option("--window", a->window, "Page-table window per mip (pages, power of two)")->capture_default_str();
      app.add_option("--format", a->format, "Frame format: png or exr")->capture_default_str();
      app.add_option("--gpu", a->gpu_name, "Vulkan device name substring or index");
      app.add_flag("--quiet", a->quiet, "No progress line");
      return [a] { return run_render(*a); };
    }};

}  // namespace
}  // namespace tvt::cli
