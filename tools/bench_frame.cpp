// `terravt bench frame` (see bench_frame.h). Two measurements per method, side by side:
//
// 1. Steady state on static poses, interleaved: one VirtualTexture (the public API), converged for each pose (by an
//    anisotropic writer, whose feedback asks for the finest pages any variant samples), then
//    every pass renders the pose `rounds` times in turn and keeps its fastest; figures are
//    medians over the poses, ratios medians of the per-pose ratios. Passes: plain texture,
//    VT (feedback on a second attachment, as it runs), VT without feedback, VT + separate
//    feedback pass, VT with main-pass feedback stores, VT
//    anisotropic, direct splatting, untextured, then plain/VT without the detail normal and VT
//    with the brilinear and bilinear mip filters (plus the image error of the mip filters). Process CPU time
//    (CPU device) or GPU timestamps around each pass (hardware GPU).
// 2. The flythrough loop (app/flythrough.h) with each feedback variant: steady frames
//    (nothing composed), all frames (page production included), time-to-sharp after the cut,
//    feedback CPU time per frame.
#include "tools/bench_frame.h"

#include <nlohmann/json.hpp>

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>

#include "compose/image_diff.h"
#include "compose/packed_scene.h"
#include "render/feedback_compactor.h"
#include "app/flythrough.h"
#include "app/plain_texture.h"
#include "app/terrain_renderer.h"
#include "app/vt_frame_driver.h"
#include "tools/cli_common.h"
#include "vt/page_table.h"

namespace tvt::cli {
namespace {

// Process CPU time (every thread: on a CPU device such as lavapipe that includes the
// rasteriser's worker threads), milliseconds.
double process_cpu_ms() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return (double(u.ru_utime.tv_sec) + double(u.ru_stime.tv_sec)) * 1e3 +
         (double(u.ru_utime.tv_usec) + double(u.ru_stime.tv_usec)) * 1e-3;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// The passes of the static comparison, in timing order.
// The *Flat passes have the detail normal off (relief 0), the *Bilinear ones sample the
// nearest mip only (VtMipFilter::Bilinear), kVtBrilinear blends only within --brilinear-band of
// the half-way LODs: the knobs' costs, measured.
enum Pass {
  kPlain, kVt, kVtNoFeedback, kVtSeparate, kVtAniso, kDirect, kUntextured,
  kPlainFlat, kVtFlat, kVtNoFeedbackFlat, kVtBilinear, kVtBilinearNoFeedback, kVtStore, kVtBrilinear, kPassCount
};
constexpr const char* k_pass_names[kPassCount] = {"plain", "vt", "vt_no_feedback", "vt_separate_feedback",
                                                  "vt_aniso", "direct", "untextured", "plain_no_detail",
                                                  "vt_no_detail", "vt_no_feedback_no_detail", "vt_bilinear",
                                                  "vt_bilinear_no_feedback", "vt_store_feedback", "vt_brilinear"};

struct StaticResult {
  std::vector<double> ms[kPassCount];  // per pose: fastest of the rounds
  double compaction_ms = 0;            // GPU feedback compaction, per frame
  uint32_t unconverged_poses = 0;
  uint32_t converge_frames = 0;
  // Image error of the mip filters, per pose (PSNR over RGB, dB): bilinear and brilinear VT
  // against trilinear VT, and each against direct splatting (the composition per pixel).
  std::vector<double> psnr_bilinear_trilinear, psnr_brilinear_trilinear, psnr_trilinear_direct, psnr_bilinear_direct,
      psnr_brilinear_direct;
  double pass(Pass p) const { return median(ms[p]); }
  double ratio(Pass a, Pass b) const {
    std::vector<double> r;
    for (size_t i = 0; i < ms[a].size(); ++i) r.push_back(ms[a][i] / ms[b][i]);
    return median(r);
  }
  double difference(Pass a, Pass b) const {
    std::vector<double> d;
    for (size_t i = 0; i < ms[a].size(); ++i) d.push_back(ms[a][i] - ms[b][i]);
    return median(d);
  }
};

struct LoopResult {
  double steady_ms = 0, all_ms = 0, feedback_cpu_ms = 0, select_ms = 0;  // all_ms: mean over the frames
  int time_to_sharp = -1;  // frames after the cut; -1 not reached
  bool cut = false;
  size_t steady_frames = 0;
  uint64_t pages_composed = 0;
  // Means over frames 1.. of the loop's own clocks: wall per frame, the frame thread's work
  // (recording, residency) and its blocking on the GPU; feedback lateness in frames.
  double wall_ms = 0, thread_ms = 0, wait_ms = 0, feedback_late = 0;
};

Result<StaticResult> measure_static(vk::Context& g, const SceneAssets& assets, Method method, const PlainTexture& plain,
                                    const BenchFrameArgs& a) {
  auto packed = pack_scene(assets, options_for(method));
  if (!packed) return packed.error();
  // The VT through the public API on this device, as the flythrough runs it. Its feedback
  // comes from the converger below (half resolution).
  terravt::detail::ToolVirtualTexture td;
  td.assets = &assets;
  td.method = method;
  td.runtime.cache_slots = std::max(a.cache_slots, 1024u);  // anisotropic poses want more pages than the loop's cache
  td.runtime.page_budget = 64;
  td.feedback_texels = vt_feedback_texels(a.width, a.height, 2);
  auto vt = create_tool_vt(g, td);
  if (!vt) return vt.error();
  terravt::VirtualTexture& v = *vt.value();
  auto composer = GpuComposer::create(g, packed.value(), 1);
  if (!composer) return composer.error();

  TerrainRendererOptions base;
  base.width = a.width;
  base.height = a.height;
  auto vt_pass = [&](FeedbackMode mode, uint32_t aniso, VtMipFilter filter = VtMipFilter::Trilinear) {
    TerrainRendererOptions o = base;
    o.vt = terrain_vt_inputs(v, a.feedback_divisor, mode, aniso, filter);
    return TerrainRenderer::create(g, assets, o);
  };
  std::unique_ptr<TerrainRenderer> passes[kPassCount];
  std::vector<Result<std::unique_ptr<TerrainRenderer>>> made;
  TerrainRendererOptions plain_o = base, direct_o = base;
  plain_o.plain = TerrainPlainInputs{&plain};
  direct_o.direct = TerrainDirectInputs{composer.value().get(), false};
  made.push_back(TerrainRenderer::create(g, assets, plain_o));
  made.push_back(vt_pass(FeedbackMode::Attachment, 1));
  made.push_back(vt_pass(FeedbackMode::None, 1));
  made.push_back(vt_pass(FeedbackMode::SeparatePass, 1));
  made.push_back(vt_pass(FeedbackMode::Attachment, a.anisotropy));
  made.push_back(TerrainRenderer::create(g, assets, direct_o));
  made.push_back(TerrainRenderer::create(g, assets, base));
  TerrainRendererOptions plain_flat = plain_o;
  plain_flat.lighting.detail_relief_m = 0.0;
  made.push_back(TerrainRenderer::create(g, assets, plain_flat));
  for (FeedbackMode mode : {FeedbackMode::Attachment, FeedbackMode::None}) {
    TerrainRendererOptions o = base;
    o.lighting.detail_relief_m = 0.0;
    o.vt = terrain_vt_inputs(v, a.feedback_divisor, mode, 1);
    made.push_back(TerrainRenderer::create(g, assets, o));
  }
  made.push_back(vt_pass(FeedbackMode::Attachment, 1, VtMipFilter::Bilinear));
  made.push_back(vt_pass(FeedbackMode::None, 1, VtMipFilter::Bilinear));
  made.push_back(vt_pass(FeedbackMode::MainPass, 1));
  made.push_back(vt_pass(FeedbackMode::Attachment, 1, VtMipFilter{a.brilinear_band}));
  for (int p = 0; p < kPassCount; ++p) {
    if (!made[size_t(p)]) return made[size_t(p)].error();
    passes[p] = std::move(made[size_t(p)].value());
  }
  // Convergence: an anisotropic writer at 1/2 resolution (every pixel reports within 4 frames);
  // its feedback asks for the finest page any timed pass samples.
  TerrainRendererOptions conv_o = base;
  conv_o.vt = terrain_vt_inputs(v, 2, FeedbackMode::Attachment, a.anisotropy);
  auto converger = TerrainRenderer::create(g, assets, conv_o);
  if (!converger) return converger.error();
  auto driver = VtFrameDriver::create(g, v, *converger.value());
  if (!driver) return driver.error();
  FeedbackCompactor::Options fo;
  fo.feedback_width = passes[kVt]->feedback_width();
  fo.feedback_height = passes[kVt]->feedback_height();
  auto compactor = FeedbackCompactor::create(g, fo);
  if (!compactor) return compactor.error();

  // On a CPU device the device's work is this process's CPU time: unlike wall clock it does not
  // depend on what else runs on the machine's cores.
  const bool cpu_device = g.properties().deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
  StaticResult r;
  const CameraPath path = flythrough_path(assets, passes[kVt]->mesh());
  const double span = std::min(path.end_time() - path.start_time(), double(a.frames) / a.fps);
  for (uint32_t k = 0; k < a.poses; ++k) {
    const Camera cam = path.camera_at(path.start_time() + (k + 0.5) * span / a.poses);
    const auto c = driver.value()->converge(cam, 80);
    if (!c) return c.error();
    r.converge_frames += c->frames;
    r.unconverged_poses += c->converged ? 0 : 1;
    double best[kPassCount];
    std::fill(std::begin(best), std::end(best), 1e300);
    for (uint32_t round = 0; round <= a.rounds; ++round)  // round 0 warms caches up
      for (int p = 0; p < kPassCount; ++p) {
        const double c0 = process_cpu_ms();
        const auto rec = [&](VkCommandBuffer cmd) { passes[p]->record(cmd, cam); };
        double ms = 0;
        if (cpu_device) {
          g.run_commands(rec);
          ms = process_cpu_ms() - c0;
        } else {
          ms = g.run_commands_timed(rec) * 1000.0;
        }
        if (round > 0) best[p] = std::min(best[p], ms);
      }
    for (int p = 0; p < kPassCount; ++p) r.ms[p].push_back(best[p]);
    const ImageRGBA8 tri = passes[kVtNoFeedback]->render(cam), bi = passes[kVtBilinearNoFeedback]->render(cam);
    const ImageRGBA8 bri = passes[kVtBrilinear]->render(cam), direct = passes[kDirect]->render(cam);
    r.psnr_bilinear_trilinear.push_back(compare_images(bi, tri).psnr_db);
    r.psnr_brilinear_trilinear.push_back(compare_images(bri, tri).psnr_db);
    r.psnr_trilinear_direct.push_back(compare_images(tri, direct).psnr_db);
    r.psnr_bilinear_direct.push_back(compare_images(bi, direct).psnr_db);
    r.psnr_brilinear_direct.push_back(compare_images(bri, direct).psnr_db);
  }
  r.compaction_ms = compactor.value()->time_compaction(passes[kVt]->feedback_buffer(), 9) * 1000.0;
  return r;
}

Result<LoopResult> measure_loop(vk::Context& g, const SceneAssets& assets, Method method, FeedbackMode mode,
                                const BenchFrameArgs& a, uint32_t frames_in_flight = FlythroughOptions{}.frames_in_flight) {
  FlythroughOptions fo;
  fo.frames_in_flight = frames_in_flight;
  fo.method = method;
  fo.frames = a.frames;
  fo.width = a.width;
  fo.height = a.height;
  fo.fps = a.fps;
  fo.feedback_divisor = a.feedback_divisor;
  fo.feedback_mode = mode;
  fo.vt.cache_slots = a.cache_slots;
  fo.vt.page_budget = a.page_budget;
  fo.mip_strategy = parsed_mip_strategy(a.mip_strategy);
  // Frame cost: on a CPU device the process CPU time from one frame's callback to the next (the
  // whole frame: residency, composition, passes, compaction; with frames in flight the GPU work
  // of a frame may fall into the next interval, which the median over steady frames absorbs);
  // else the GPU time of the frame's command buffer (timestamps: composition + table scatter +
  // terrain pass), which arrives a frame or two later.
  const bool cpu_device = g.properties().deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
  std::vector<double> frame_ms(a.frames, 0.0), feedback_cpu, select;
  std::vector<uint32_t> composed(a.frames, 0);
  LoopResult r;
  int cut_frame = -1;
  double last_cpu = process_cpu_ms();
  uint32_t frames_run = 0;
  auto run = run_flythrough(g, assets, fo, [&](const FlythroughFrame& f, const auto&) {
    const double now = process_cpu_ms();
    if (cpu_device) frame_ms[f.index] = now - last_cpu;
    else if (f.gpu_ms_frame < frame_ms.size()) frame_ms[f.gpu_ms_frame] = f.gpu_ms;
    last_cpu = now;
    frames_run = f.index + 1;
    composed[f.index] = f.vt.composed;
    r.pages_composed += f.vt.composed;
    if (f.index > 0) {
      r.wall_ms += f.total_ms;
      r.thread_ms += f.cpu_ms;
      r.wait_ms += f.wait_ms;
      r.feedback_late += double(f.feedback_frames_late);
    }
    // CPU before the frame's commands: feedback read-back parse, LRU update of the feedback
    // pages and their ancestors, window recentring; minus the request selection.
    feedback_cpu.push_back(f.residency_ms - f.vt.select_ms);
    select.push_back(f.vt.select_ms);
    if (f.cut) cut_frame = int(f.index);
    // Sharp: the feedback already comes from after the cut, and nothing is requested (every
    // page the view wants, at its wanted mip, is resident).
    const bool post_cut_feedback =
        cut_frame >= 0 && f.feedback_frames_late > 0 && f.index >= uint32_t(cut_frame) + f.feedback_frames_late;
    if (post_cut_feedback && r.time_to_sharp < 0 && f.vt.residency.requested == 0) r.time_to_sharp = int(f.index) - cut_frame;
    return true;
  });
  if (!run) return run.error();
  // Frame 0 carries the loop's set-up; on a GPU the last frames' timings may not have arrived.
  std::vector<double> steady, all;
  for (uint32_t i = 1; i < frames_run; ++i) {
    if (!cpu_device && frame_ms[i] == 0.0) continue;
    all.push_back(frame_ms[i]);
    if (composed[i] == 0 && i > 5) steady.push_back(frame_ms[i]);
  }
  r.cut = cut_frame >= 0;
  r.steady_ms = median(steady);
  r.steady_frames = steady.size();
  // Mean, not median: frames either compose a full budget or nothing, so the median of all
  // frames jumps between the two modes; the mean is the amortised cost of the run.
  double sum = 0;
  for (double x : all) sum += x;
  r.all_ms = all.empty() ? 0.0 : sum / double(all.size());
  if (frames_run > 1)
    for (double* m : {&r.wall_ms, &r.thread_ms, &r.wait_ms, &r.feedback_late}) *m /= double(frames_run - 1);
  r.feedback_cpu_ms = median(feedback_cpu);
  r.select_ms = median(select);
  return r;
}

std::string sharp_text(const LoopResult& l) {
  return !l.cut ? "no cut" : (l.time_to_sharp < 0 ? "not reached" : std::to_string(l.time_to_sharp) + " frames");
}

}  // namespace

int run_bench_frame(const BenchFrameArgs& a) {
  const char* cmd = "bench frame";
  if (auto problem = output_collision({{"--json", a.json_out}}, {{"--scene", a.scene}})) return fail(cmd, *problem, 2);
  std::vector<Method> methods;
  for (const std::string& m : a.methods) {
    auto parsed = method_from_string(m);
    if (!parsed) return fail(cmd, "--methods: unknown method '" + m + "'", 2);
    methods.push_back(*parsed);
  }
  if (methods.empty()) return fail(cmd, "--methods: name at least one method", 2);
  if (a.frames < 10 || a.frames > 10000) return fail(cmd, "--frames: must be between 10 and 10000", 2);
  if (a.poses < 1 || a.poses > 100) return fail(cmd, "--poses: must be between 1 and 100", 2);
  if (a.rounds < 1 || a.rounds > 100) return fail(cmd, "--rounds: must be between 1 and 100", 2);
  if (!VtMipFilter{a.brilinear_band}.valid()) return fail(cmd, "--brilinear-band: must be in [0, 1]", 2);
  auto assets = load_scene_and_assets(a.scene);
  if (!assets) return fail(cmd, assets.error().message, 2);
  if (auto problem = output_in_scene({{"--json", a.json_out}}, assets->desc)) return fail(cmd, *problem, 2);
  // Timings compare producers, not first-use loading: read every material up front.
  if (auto loaded = assets->materials->load_all(); !loaded) return fail(cmd, loaded.error().message, 2);
  auto ctx = gpu_context(a.gpu_name);
  if (!ctx) return fail(cmd, ctx.error().message, 1);
  vk::Context& g = *ctx.value();
  std::printf("terravt bench frame: %ux%u, feedback 1/%u, device %s\n", a.width, a.height, a.feedback_divisor,
              g.device_name().c_str());

  // The plain texture holds the last method's composition (sampling cost does not depend on
  // the content; the picture is the terrain at VT mip log2 V - plain_log2).
  auto plain_scene = pack_scene(assets.value(), options_for(methods.back()));
  if (!plain_scene) return fail(cmd, plain_scene.error().message, 2);
  PlainTextureOptions po;
  po.log2_size = a.plain_log2;
  auto plain = PlainTexture::create(g, plain_scene.value(), po);
  if (!plain) return fail(cmd, "--plain-log2: " + plain.error().message, 2);
  std::printf("plain texture: %ux%u RGBA8 + mips (%.1f MB) = VT mip %u, %u pages composed in %.1f s\n\n",
              1u << a.plain_log2, 1u << a.plain_log2, double(plain.value()->bytes()) / 1048576.0, plain.value()->vt_mip(),
              plain.value()->pages_composed(), plain.value()->compose_seconds());

  nlohmann::json j;
  j["device"] = g.device_name();
  j["width"] = a.width;
  j["height"] = a.height;
  j["feedback_divisor"] = a.feedback_divisor;
  j["mip_strategy"] = a.mip_strategy;
  j["plain_texels"] = 1u << a.plain_log2;
  const bool cpu_device = g.properties().deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
  j["static_clock"] = cpu_device ? "process_cpu" : "gpu_timestamps";
  std::printf("Steady state, converged cache, %u poses x %u rounds interleaved (median over poses, %s ms per frame):\n",
              a.poses, a.rounds, cpu_device ? "CPU-device: process CPU" : "GPU timestamps");
  std::printf("%-10s %7s %7s %9s %8s %8s %9s %9s %9s %8s %10s\n", "method", "plain", "VT", "VT/plain", "VT noFB",
              "VT aniso", "aniso/VT", "direct", "VT/direct", "untex", "converged");
  std::vector<StaticResult> statics;
  for (Method m : methods) {
    auto s = measure_static(g, assets.value(), m, *plain.value(), a);
    if (!s) return fail(cmd, s.error().message, 1);
    const StaticResult& r = s.value();
    std::printf("%-10s %7.1f %7.1f %8.2fx %8.1f %8.1f %8.2fx %9.1f %8.2fx %8.1f %7u/%u\n", std::string(to_string(m)).c_str(),
                r.pass(kPlain), r.pass(kVt), r.ratio(kVt, kPlain), r.pass(kVtNoFeedback), r.pass(kVtAniso),
                r.ratio(kVtAniso, kVt), r.pass(kDirect), r.ratio(kVt, kDirect), r.pass(kUntextured),
                a.poses - r.unconverged_poses, a.poses);
    statics.push_back(std::move(s.value()));
  }
  std::printf("Targets: VT <= 1.25x plain; VT(fbpb+dpt2) <= 0.33x direct. VT = sampling + attachment feedback as it runs;\n"
              "VT noFB = sampling alone (VT noFB / plain: ");
  for (size_t i = 0; i < methods.size(); ++i)
    std::printf("%s%s %.2fx", i ? ", " : "", std::string(to_string(methods[i])).c_str(),
                statics[i].ratio(kVtNoFeedback, kPlain));
  std::printf(").\nDetail normal off (relief 0: no height-gradient gathers):");
  for (size_t i = 0; i < methods.size(); ++i) {
    const StaticResult& r = statics[i];
    std::printf("\n  %-10s plain %.1f  VT %.1f (VT/plain %.2fx, detail costs the VT %+.1f ms)  VT noFB/plain %.2fx",
                std::string(to_string(methods[i])).c_str(), r.pass(kPlainFlat), r.pass(kVtFlat),
                r.ratio(kVtFlat, kPlainFlat), r.difference(kVt, kVtFlat), r.ratio(kVtNoFeedbackFlat, kPlainFlat));
  }
  const std::string brilinear = mip_filter_name(VtMipFilter{a.brilinear_band});
  std::printf("\nMip filter (--vt-filter): bilinear samples the nearest mip only, one page lookup instead of two;\n"
              "%s blends two only within %g mip of each half-way LOD; image error as PSNR over the frame\n"
              "(median over poses; direct = the composition per pixel):",
              brilinear.c_str(), double(a.brilinear_band));
  for (size_t i = 0; i < methods.size(); ++i) {
    const StaticResult& r = statics[i];
    std::printf("\n  %-10s VT/plain: trilinear %.2fx (%.1f ms)  %s %.2fx (%.1f ms)  bilinear %.2fx (%.1f ms); "
                "bilinear noFB %.2fx\n"
                "  %-10s PSNR vs trilinear: %s %.1f dB, bilinear %.1f dB; vs direct: trilinear %.1f, %s %.1f, "
                "bilinear %.1f dB",
                std::string(to_string(methods[i])).c_str(), r.ratio(kVt, kPlain), r.pass(kVt), brilinear.c_str(),
                r.ratio(kVtBrilinear, kPlain), r.pass(kVtBrilinear), r.ratio(kVtBilinear, kPlain), r.pass(kVtBilinear),
                r.ratio(kVtBilinearNoFeedback, kPlain), "", brilinear.c_str(), median(r.psnr_brilinear_trilinear),
                median(r.psnr_bilinear_trilinear), median(r.psnr_trilinear_direct), brilinear.c_str(),
                median(r.psnr_brilinear_direct), median(r.psnr_bilinear_direct));
  }
  std::printf("\n\nFeedback cost per frame (same poses, over VT noFB): the main pass writing a second attachment (and\n"
              "the compute pick of the rotating pixels), the main pass storing to a buffer, a separate 1/%u pass; plus compaction:\n",
              a.feedback_divisor);
  for (size_t i = 0; i < methods.size(); ++i) {
    const StaticResult& r = statics[i];
    std::printf("  %-10s attachment %+.2f ms   main-pass stores %+.2f ms   separate pass %+.2f ms   compaction %.2f ms\n",
                std::string(to_string(methods[i])).c_str(), r.difference(kVt, kVtNoFeedback),
                r.difference(kVtStore, kVtNoFeedback), r.difference(kVtSeparate, kVtNoFeedback), r.compaction_ms);
  }

  if (!a.static_only) {
    std::printf("\nFlythrough loop, %u frames at %.0f fps, cache %u pages, budget %u, mip strategy %s (ms per frame: steady =\n"
                "median of the frames that composed nothing, VT+production = mean of all frames):\n",
                a.frames, a.fps, a.cache_slots, a.page_budget, a.mip_strategy.c_str());
    std::printf("%-10s %-10s %10s %14s %10s %14s %7s %14s %14s %10s\n", "method", "feedback", "VT steady", "VT+production",
                "VT/direct", "VT+prod/direct", "pages", "time-to-sharp", "feedback CPU", "select");
  }
  nlohmann::json jm;
  for (size_t i = 0; i < methods.size(); ++i) {
    const std::string name(to_string(methods[i]));
    nlohmann::json& e = jm[name];
    for (int p = 0; p < kPassCount; ++p) e["static_ms"][k_pass_names[p]] = statics[i].pass(Pass(p));
    e["vt_over_plain"] = statics[i].ratio(kVt, kPlain);
    e["vt_no_feedback_over_plain"] = statics[i].ratio(kVtNoFeedback, kPlain);
    e["vt_over_direct"] = statics[i].ratio(kVt, kDirect);
    e["aniso_over_vt"] = statics[i].ratio(kVtAniso, kVt);
    e["no_detail"] = {{"vt_over_plain", statics[i].ratio(kVtFlat, kPlainFlat)},
                      {"vt_no_feedback_over_plain", statics[i].ratio(kVtNoFeedbackFlat, kPlainFlat)},
                      {"detail_cost_vt_ms", statics[i].difference(kVt, kVtFlat)}};
    e["bilinear"] = {{"vt_over_plain", statics[i].ratio(kVtBilinear, kPlain)},
                     {"vt_no_feedback_over_plain", statics[i].ratio(kVtBilinearNoFeedback, kPlain)},
                     {"psnr_vs_trilinear_db", median(statics[i].psnr_bilinear_trilinear)},
                     {"psnr_vs_direct_db", median(statics[i].psnr_bilinear_direct)},
                     {"trilinear_psnr_vs_direct_db", median(statics[i].psnr_trilinear_direct)}};
    e["brilinear"] = {{"band", a.brilinear_band},
                      {"vt_over_plain", statics[i].ratio(kVtBrilinear, kPlain)},
                      {"psnr_vs_trilinear_db", median(statics[i].psnr_brilinear_trilinear)},
                      {"psnr_vs_direct_db", median(statics[i].psnr_brilinear_direct)}};
    e["feedback_gpu_ms"] = {{"attachment", statics[i].difference(kVt, kVtNoFeedback)},
                            {"main_pass_stores", statics[i].difference(kVtStore, kVtNoFeedback)},
                            {"separate_pass", statics[i].difference(kVtSeparate, kVtNoFeedback)},
                            {"compaction", statics[i].compaction_ms}};
    for (FeedbackMode mode : {FeedbackMode::Attachment, FeedbackMode::MainPass, FeedbackMode::SeparatePass}) {
      if (a.static_only) break;
      auto l = measure_loop(g, assets.value(), methods[i], mode, a);
      if (!l) return fail(cmd, l.error().message, 1);
      const char* mode_name = feedback_mode_name(mode);
      char steady[32] = "no steady", steady_ratio[32] = "-";
      if (l->steady_frames > 0) {
        std::snprintf(steady, sizeof steady, "%.1f", l->steady_ms);
        std::snprintf(steady_ratio, sizeof steady_ratio, "%.2fx", l->steady_ms / statics[i].pass(kDirect));
      }
      std::printf("%-10s %-10s %10s %14.1f %10s %13.2fx %7llu %14s %11.3f ms %7.3f ms\n", name.c_str(), mode_name, steady,
                  l->all_ms, steady_ratio, l->all_ms / statics[i].pass(kDirect),
                  static_cast<unsigned long long>(l->pages_composed), sharp_text(l.value()).c_str(), l->feedback_cpu_ms,
                  l->select_ms);
      e["loop"][mode_name] = {{"steady_ms", l->steady_ms},       {"steady_frames", l->steady_frames},
                              {"with_production_ms", l->all_ms}, {"pages_composed", l->pages_composed},
                              {"time_to_sharp", l->time_to_sharp}, {"feedback_cpu_ms", l->feedback_cpu_ms},
                              {"select_ms", l->select_ms}};
    }
  }
  j["methods"] = jm;
  if (!a.static_only)
    std::printf("(Loop frames: %s;\n VT/direct: loop frame over the static direct pass. Feedback CPU: read-back parse, LRU update,\n"
                " window recentring, on the frame thread; select: request selection.)\n",
                cpu_device ? "process CPU per whole frame (residency, composition, passes, compaction)" : "GPU time of the frame's commands (timestamps)");

  if (!a.static_only) {
    // Frames in flight: the same loop recorded 1, 2 or 3 frames ahead of the GPU.
    std::printf("\nFrames in flight (%s, attachment feedback; means per frame): the frame thread blocks only when the GPU is K\n"
                "frames behind; feedback comes K frames late:\n",
                std::string(to_string(methods.back())).c_str());
    std::printf("%3s %10s %14s %12s %14s %14s %7s\n", "K", "wall ms", "thread work ms", "blocked ms", "feedback late",
                "time-to-sharp", "pages");
    for (uint32_t depth : {1u, 2u, 3u}) {
      auto l = measure_loop(g, assets.value(), methods.back(), FeedbackMode::Attachment, a, depth);
      if (!l) return fail(cmd, l.error().message, 1);
      std::printf("%3u %10.1f %14.2f %12.1f %14.2f %14s %7llu\n", depth, l->wall_ms, l->thread_ms, l->wait_ms,
                  l->feedback_late, sharp_text(l.value()).c_str(), static_cast<unsigned long long>(l->pages_composed));
      j["frames_in_flight"][std::to_string(depth)] = {{"wall_ms", l->wall_ms},         {"thread_ms", l->thread_ms},
                                                      {"blocked_ms", l->wait_ms},      {"feedback_late", l->feedback_late},
                                                      {"time_to_sharp", l->time_to_sharp}, {"pages_composed", l->pages_composed}};
    }
  }

  std::printf("\nVT memory against V (page table W = 128, cache of %u pages of %ux%u RGBA8):\n", a.cache_slots,
              assets->desc.vt.slot_texels(), assets->desc.vt.slot_texels());
  for (uint32_t log2v : {14u, 16u, 20u, 24u}) {
    VtConfig vt = assets->desc.vt;
    vt.log2_size = log2v;
    const PageTable table(vt, PageTableOptions{128});
    const double cache_mb = double(a.cache_slots) * vt.slot_texels() * vt.slot_texels() * 4 / 1048576.0;
    const double table_mb = double(table.memory_bytes()) / 1048576.0;
    std::printf("  V = 2^%-2u  page table %8.3f MB   cache %6.1f MB   total %6.1f MB\n", log2v, table_mb, cache_mb,
                table_mb + cache_mb);
    j["memory_mb"][std::to_string(log2v)] = {{"page_table", table_mb}, {"cache", cache_mb}};
  }
  if (!a.json_out.empty()) {
    if (auto w = write_text_file(a.json_out, j.dump(2) + "\n"); !w) return fail(cmd, "--json: " + w.error().message, 1);
  }
  return 0;
}

}  // namespace tvt::cli
