// `terravt render`: the main job. A camera flies over the terrain; feedback finds the pages
// the view needs, the residency policy requests them, the compute composer writes them into
// the physical cache, the page table is updated on the GPU, and the terrain pass samples
// through it. Frames (PNG/EXR), a JSON stats line per frame and a summary are written.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numbers>
#include <optional>

#include "compose/packed_scene.h"
#include "compose/scene_identity.h"
#include "terrain/camera_file.h"
#include "app/flythrough.h"
#include "render/stored_producer.h"
#include "streaming/file_io.h"
#include "streaming/page_store.h"
#include "tools/cli_common.h"
#include "tools/commands.h"

namespace tvt::cli {
namespace {

struct RenderArgs {
  std::string scene;
  std::string camera;       // camera path file (default: the built-in flythrough)
  std::string save_camera;  // write the camera path in use here and stop
  std::string out = "out/render";
  std::string method = "fbpb+dpt2";
  std::string mip_strategy = "prefiltered";
  std::string hex = "scene";
  std::string gpu_name;
  std::string format = "png";
  std::string source = "procedural";
  std::string store;
  uint32_t loader_threads = 2;
  uint32_t staging = 64;
  bool sync_loads = false;
  std::string feedback = "auto";
  uint32_t anisotropy = 1;
  std::string vt_filter = "trilinear";
  uint32_t frames_in_flight = 2;
  double detail_relief = TerrainLighting{}.detail_relief_m;
  std::string lighting = "sun";  // "none": the image is the albedo
  std::string page_table;        // write the GPU page table after the last frame here
  uint32_t frames = 120;
  bool frames_given = false;  // else: 120 on the built-in flythrough, the whole --camera path
  uint32_t every = 10;
  uint32_t width = 640, height = 360;
  uint32_t cache_slots = 512;
  uint32_t page_budget = 48;
  uint32_t feedback_divisor = 8;
  uint32_t window = 64;
  double fps = 10.0;
  bool quiet = false;
  bool debug = false;       // also write cache atlas, page table and feedback images
  bool debug_mips = false;  // colour every texel by the mip its data comes from
  bool overwrite = false;   // replace an earlier run's output in `out` / an existing save_camera file
  bool strict = false;      // hybrid: a store that cannot be opened fails the run instead of degrading
  // Given on the command line (an empty value is then an error, not "use the default").
  bool camera_given = false, save_camera_given = false, gpu_given = false;
};

// What a run writes into its folder: frames, debug images, stats (and the temporary stats of a
// run that was killed).
bool is_run_output(const std::filesystem::path& file) {
  const std::string name = file.filename().string(), ext = file.extension().string();
  if (name == "stats.jsonl" || name.starts_with("stats.jsonl.tmp-")) return true;
  for (const char* prefix : {"frame_", "atlas_", "pagetable_", "feedback_"}) {
    const std::string_view p(prefix);
    if (name.size() == p.size() + 5 + ext.size() && name.starts_with(p) && (ext == ".png" || ext == ".exr") &&
        std::all_of(name.begin() + long(p.size()), name.end() - long(ext.size()), [](char c) { return c >= '0' && c <= '9'; }))
      return true;
  }
  return false;
}

// Checked before any work: `out` is a folder or can be made one, and holds no earlier run's
// output unless `overwrite`. Nothing is created here (see open_output_folder()).
Status check_output_folder(const std::string& out, bool overwrite) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path dir(out);
  if (fs::exists(fs::symlink_status(dir, ec))) {
    if (!fs::is_directory(dir, ec)) return make_error("--out: " + out + " exists and is not a folder");
    size_t earlier = 0;
    std::string example;
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (is_run_output(e.path())) {
        if (example.empty() || e.path().filename() == "stats.jsonl") example = e.path().filename().string();
        ++earlier;
      }
    if (ec) return make_error("--out: cannot read folder " + out + " (" + ec.message() + ")");
    if (earlier > 0 && !overwrite)
      return make_error("--out: " + out + " holds the output of an earlier run (" + std::to_string(earlier) +
                        (earlier == 1 ? " file: " : " files such as ") + example + "); pass --overwrite to replace it, or choose another folder");
    return Ok{};
  }
  // The nearest existing ancestor must be a folder for create_directories() to succeed.
  for (fs::path p = fs::absolute(dir, ec).parent_path(); !p.empty(); p = p.parent_path()) {
    if (fs::exists(p, ec)) {
      if (!fs::is_directory(p, ec)) return make_error("--out: cannot create folder " + out + " (" + p.string() + " is not a folder)");
      break;
    }
    if (p == p.root_path()) break;
  }
  return Ok{};
}

// The files of this run in --out. stats.jsonl is staged under a temporary name and renamed
// into place only once every frame is written: a stats.jsonl in the folder says the run
// completed. A run that fails part-way takes back what it wrote (take_back()).
struct RunOutput {
  std::string folder;
  bool made_folder = false;  // the folder did not exist before this run
  fileio::StagedFile stats;
  std::vector<std::filesystem::path> files;  // frames and debug images written so far

  bool is_open() const { return stats.is_open(); }
  Status write_image_file(const std::string& name, const ImageRGBA8& image) {
    const std::filesystem::path file = std::filesystem::path(folder) / name;
    if (auto w = write_image(file.string(), image); !w) return w;
    files.push_back(file);
    return Ok{};
  }
  // Removes the frames written so far and the temporary stats (and the folder, if this run
  // made it and it is empty again).
  void take_back() {
    std::error_code ec;
    for (const auto& f : files) std::filesystem::remove(f, ec);
    files.clear();
    stats = fileio::StagedFile{};
    if (made_folder && std::filesystem::is_empty(folder, ec)) std::filesystem::remove(folder, ec);
  }
};

// At the first frame, once everything the run needs exists: makes the folder, removes an
// earlier run's output (check_output_folder() allowed it: --overwrite) and starts stats.jsonl.
Status open_output_folder(const std::string& out, RunOutput& run) {
  namespace fs = std::filesystem;
  std::error_code ec;
  run.folder = out;
  run.made_folder = !fs::exists(fs::symlink_status(out, ec));
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out)) return make_error("--out: cannot create folder " + out + (ec ? " (" + ec.message() + ")" : ""));
  std::vector<fs::path> earlier;
  for (const auto& e : fs::directory_iterator(out, ec))
    if (is_run_output(e.path())) earlier.push_back(e.path());
  // Symbolic links are removed, never followed: a stats.jsonl linking elsewhere is not written through.
  for (const fs::path& f : earlier)
    if (!fs::remove(f, ec)) return make_error("--out: cannot remove " + f.string() + " of an earlier run");
  auto stats = fileio::StagedFile::create((fs::path(out) / "stats.jsonl").string());
  if (!stats) return make_error("--out: " + stats.error().message);
  run.stats = std::move(stats.value());
  return Ok{};
}

int run_render(const RenderArgs& a) {
  const char* cmd = "render";
  const auto method = method_from_string(a.method);
  if (!method) return fail(cmd, "--method: unknown method '" + a.method + "' (linear, blendmap, fbpb, dpt1, dpt2, fbpb+dpt2)", 2);
  if (a.frames < 1 || a.frames > 100000) return fail(cmd, "--frames: must be between 1 and 100000", 2);
  if (a.every < 1) return fail(cmd, "--every: must be at least 1", 2);
  if (a.frames_in_flight < 1 || a.frames_in_flight > 8) return fail(cmd, "--frames-in-flight: must be between 1 and 8", 2);
  if (!(a.detail_relief >= 0.0 && a.detail_relief <= 1000.0))
    return fail(cmd, "--detail-relief: metres in [0, 1000], got " + std::to_string(a.detail_relief), 2);
  if (a.lighting != "sun" && a.lighting != "none") return fail(cmd, "--lighting: sun or none, got '" + a.lighting + "'", 2);
  if (a.width < 16 || a.height < 16 || a.width > 8192 || a.height > 8192)
    return fail(cmd, "--width/--height: must be between 16 and 8192", 2);
  // At least one frame per 1000 s: path times stay finite and meaningful.
  if (!(a.fps >= 1e-3 && a.fps <= 1000.0)) return fail(cmd, "--fps: must be in [0.001, 1000]", 2);
  if (a.camera_given && a.camera.empty()) return fail(cmd, "--camera: empty path", 2);
  if (a.save_camera_given && a.save_camera.empty()) return fail(cmd, "--save-camera: empty path", 2);
  // --overwrite replaces an earlier output, never what this run reads.
  const FlaggedPaths inputs = {{"--scene", a.scene}, {"--camera", a.camera}, {"--store", a.store}};
  if (auto problem = output_collision({{"--out", a.out}, {"--save-camera", a.save_camera}, {"--page-table", a.page_table}}, inputs))
    return fail(cmd, *problem, 2);
  if (a.gpu_given && a.gpu_name.empty()) return fail(cmd, "--gpu: empty device name (omit --gpu for the default device)", 2);
  if (a.cache_slots < 2) return fail(cmd, "--cache-slots: must be at least 2, got " + std::to_string(a.cache_slots), 2);
  if (a.page_budget < 1 || a.page_budget > a.cache_slots)
    return fail(cmd, "--page-budget: must be between 1 and --cache-slots (" + std::to_string(a.cache_slots) + ")", 2);
  if (a.window < 4 || a.window > 4096 || (a.window & (a.window - 1)) != 0)
    return fail(cmd, "--window: a power of two between 4 and 4096, got " + std::to_string(a.window), 2);
  // Larger than the image, most rotating positions would fall outside it: feedback would be rare.
  if (a.feedback_divisor < 1 || a.feedback_divisor > 64 || a.feedback_divisor > std::min(a.width, a.height))
    return fail(cmd, "--feedback-divisor: must be between 1 and 64 and at most the image's width and height (" +
                         std::to_string(std::min(a.width, a.height)) + ")", 2);
  if (a.format != "png" && a.format != "exr") return fail(cmd, "--format: png or exr", 2);
  const auto source = vt_source_from_string(a.source);
  if (!source) return fail(cmd, "--source: procedural, stored or hybrid, got '" + a.source + "'", 2);
  if (*source != VtSource::procedural && a.store.empty()) return fail(cmd, "--store: --source " + a.source + " needs a page store (terravt bake)", 2);
  if (*source == VtSource::procedural && !a.store.empty()) return fail(cmd, "--store: only used with --source stored or hybrid", 2);
  if (a.strict && *source != VtSource::hybrid) return fail(cmd, "--strict: only used with --source hybrid", 2);
  if (a.loader_threads < 1 || a.loader_threads > 64) return fail(cmd, "--loader-threads: must be between 1 and 64", 2);
  if (a.staging < 1 || a.staging > 4096) return fail(cmd, "--staging: must be between 1 and 4096", 2);
  // Unset for auto: the device decides, once there is one.
  std::optional<FeedbackMode> feedback;
  if (a.feedback != "auto") {
    feedback = feedback_mode_from_string(a.feedback);
    if (!feedback || *feedback == FeedbackMode::None)
      return fail(cmd, "--feedback: auto, attachment, main or separate, got '" + a.feedback + "'", 2);
  }
  const auto mip_filter = mip_filter_from_string(a.vt_filter);
  if (!mip_filter) return fail(cmd, "--vt-filter: trilinear, bilinear, brilinear or brilinear:W with W in [0, 1], got '" + a.vt_filter + "'", 2);
  std::shared_ptr<const PageStoreReader> store;
  VtSource vt_source = *source;
  if (!a.store.empty()) {
    auto opened = PageStoreReader::open(a.store);
    if (opened) {
      store = std::move(opened.value());
    } else if (*source == VtSource::hybrid && !a.strict) {
      // Hybrid composes whatever the store cannot give: without a store, that is every page.
      std::fprintf(stderr, "terravt render: --store: %s; composing every page instead (hybrid; --strict makes this an error, "
                           "terravt verify --salvage can rescue the intact pages)\n",
                   opened.error().message.c_str());
      vt_source = VtSource::procedural;
    } else {
      return fail(cmd, "--store: " + opened.error().message, 2);
    }
  }
  // Inputs first: a bad scene or a missing device leaves no output folder behind.
  auto assets = load_scene_and_assets(a.scene, a.hex);
  if (!assets) return fail(cmd, assets.error().message, 2);
  if (auto problem = output_in_scene({{"--save-camera", a.save_camera}, {"--page-table", a.page_table}}, assets->desc))
    return fail(cmd, *problem, 2);
  // A store of another scene, method or VT geometry is as unusable as one that cannot be opened.
  if (store) {
    const uint64_t wanted =
        store_scene_identity(assets->desc, *method, parsed_mip_strategy(a.mip_strategy), store->desc().pyramid);
    if (auto s = StoredProducer::matches(*store, assets->desc.vt, wanted); !s) {
      if (vt_source != VtSource::hybrid || a.strict) return fail(cmd, "--store: " + s.error().message, 2);
      std::fprintf(stderr, "terravt render: --store: %s; composing every page instead (hybrid; --strict makes this an "
                           "error)\n",
                   s.error().message.c_str());
      vt_source = VtSource::procedural;
      store.reset();
    }
  }
  const uint32_t max_taps = std::max(1u, assets->desc.vt.border_texels);
  if (a.anisotropy < 1 || a.anisotropy > max_taps)
    return fail(cmd, "--anisotropy: must be between 1 and the scene's vt.border_texels (" + std::to_string(max_taps) + ")", 2);
  auto camera = choose_camera(a.camera, assets.value());
  if (!camera) return fail(cmd, camera.error().message, 2);
  const double duration_s = camera->path.end_time() - camera->path.start_time();
  if (!a.save_camera.empty()) {
    if (auto s = check_output_file("--save-camera", a.save_camera, a.overwrite); !s) return fail(cmd, s.error().message, 2);
    auto owned = OutputLock::acquire("--save-camera", a.save_camera);
    if (!owned) return fail(cmd, owned.error().message, 2);
    const std::string text = camera_file_json(camera->path, camera->lens);
    // A path made for a huge terrain can leave the file format's limits: never write a file
    // that would not load again.
    if (auto back = parse_camera_file(text, a.save_camera); !back)
      return fail(cmd, "--save-camera: this path does not fit the camera file limits, nothing written (" +
                           back.error().message + ")", 2);
    if (auto w = write_text_file(a.save_camera, text); !w) return fail(cmd, "--save-camera: " + w.error().message, 1);
    std::printf("wrote the camera path of %s to %s\n", camera->describe().c_str(), a.save_camera.c_str());
    return 0;
  }
  uint32_t frames = a.frames;
  if (camera->file && !a.frames_given) {
    const double whole = std::floor(duration_s * a.fps + 1e-9) + 1.0;
    if (whole > 100000.0) {
      char why[160];
      std::snprintf(why, sizeof(why),
                    "--frames: the camera path is %.1f s long, more than 100000 frames at --fps %g; give --frames or a lower --fps",
                    duration_s, a.fps);
      return fail(cmd, why, 2);
    }
    frames = uint32_t(whole);
  }
  auto owned = OutputLock::acquire("--out", a.out);  // one run per folder: frames of two runs never mix
  if (!owned) return fail(cmd, owned.error().message, 2);
  {
    // With --overwrite an earlier run's frames and stats go: never an input under such a name.
    FlaggedPaths all_inputs = inputs;
    for (auto& named : scene_inputs(assets->desc)) all_inputs.push_back(std::move(named));
    if (auto problem = input_in_output_folder("--out", a.out, is_run_output, all_inputs)) return fail(cmd, *problem, 2);
  }
  if (auto s = check_output_folder(a.out, a.overwrite); !s) return fail(cmd, s.error().message, 2);
  if (!a.page_table.empty()) {
    // A frame or stats.jsonl written later would replace it (or it them).
    if (written_into_folder(a.page_table, a.out, is_run_output))
      return fail(cmd, "--page-table " + a.page_table + ": is a name this run writes into --out " + a.out +
                           " (frames, debug images, stats.jsonl); choose another name", 2);
    if (auto s = check_output_file("--page-table", a.page_table, a.overwrite); !s) return fail(cmd, s.error().message, 2);
  }
  auto ctx = gpu_context(a.gpu_name);
  if (!ctx) return fail(cmd, ctx.error().message, 1);
  vk::Context& g = *ctx.value();
  const uint32_t max_layers = g.properties().limits.maxImageArrayLayers;
  if (a.cache_slots > max_layers)  // >= 2 was checked with the flags
    return fail(cmd, "--cache-slots: must be between 2 and " + std::to_string(max_layers) + " (image layers on " +
                         g.device_name() + ")", 2);
  // Made at the first frame, when the VT, the renderer and every device resource exist: a run
  // that cannot start writes nothing.
  RunOutput run;

  FlythroughOptions fo;
  fo.method = *method;
  fo.mip_strategy = parsed_mip_strategy(a.mip_strategy);
  fo.frames = frames;
  fo.camera = camera->file;
  fo.width = a.width;
  fo.height = a.height;
  fo.fps = a.fps;
  fo.feedback_divisor = a.feedback_divisor;
  fo.vt.cache_slots = a.cache_slots;
  fo.vt.page_budget = a.page_budget;
  fo.vt.window_pages = a.window;
  fo.vt.source = vt_source;
  fo.vt.store = store;
  fo.vt.loader.threads = a.loader_threads;
  fo.vt.loader.staging_slots = a.staging;
  fo.vt.sync_loads = a.sync_loads;
  fo.feedback_mode = feedback.value_or(default_feedback_mode(g.properties().deviceType));
  fo.max_anisotropy = a.anisotropy;
  fo.mip_filter = *mip_filter;
  fo.frames_in_flight = a.frames_in_flight;
  fo.lighting.detail_relief_m = a.detail_relief;
  if (a.lighting == "none") {  // albedo * (0 * lambert + 1), no fog: the image is the albedo
    fo.lighting.sun_intensity = 0.0;
    fo.lighting.ambient = 1.0;
    fo.lighting.fog_density_per_m = 0.0;
    fo.lighting.detail_relief_m = 0.0;
  }
  fo.debug_view = a.debug_mips ? 1 : 0;
  std::printf("terravt render: %s, V = 2^%u, %ux%u, %u frames, method %s, mip strategy %s, source %s, cache %u pages, "
              "budget %u/frame, %s filter, device %s\n",
              assets->desc.source_path.c_str(), assets->desc.vt.log2_size, a.width, a.height, frames, a.method.c_str(),
              a.mip_strategy.c_str(),
              (vt_source == *source ? a.source : a.source + " without its store").c_str(), a.cache_slots, a.page_budget, mip_filter_name(*mip_filter).c_str(), g.device_name().c_str());
  std::printf("camera: %s\n", camera->describe().c_str());
  uint32_t written = 0;
  std::string write_error;
  bool wrote_table = false;
  auto summary = run_flythrough(g, assets.value(), fo, [&](const FlythroughFrame& fr, const FlythroughViews& views) {
    const VtFrameStats& s = fr.vt;
    if (!run.is_open())
      if (auto opened = open_output_folder(a.out, run); !opened) {
        write_error = opened.error().message;
        return false;
      }
    if (fr.index % a.every == 0 || fr.index + 1 == frames) {
      char name[64];
      std::snprintf(name, sizeof(name), "frame_%05u.%s", fr.index, a.format.c_str());
      if (auto w = run.write_image_file(name, views.frame()); !w) {
        write_error = w.error().message;
        return false;
      }
      ++written;
      if (a.debug) {
        const std::pair<const char*, const std::function<ImageRGBA8()>*> extra[] = {
            {"atlas", &views.atlas}, {"pagetable", &views.page_table}, {"feedback", &views.feedback}};
        for (const auto& [what, fn] : extra) {
          std::snprintf(name, sizeof(name), "%s_%05u.png", what, fr.index);
          if (auto w = run.write_image_file(name, (*fn)()); !w) {
            write_error = w.error().message;
            return false;
          }
        }
      }
    }
    if (!a.page_table.empty() && fr.index + 1 == frames) {
      const std::vector<uint8_t> table = views.page_table_bytes();
      if (auto w = fileio::write_file_durable(a.page_table, table.data(), table.size()); !w) {
        write_error = "--page-table: " + w.error().message;
        return false;
      }
      wrote_table = true;
    }
    nlohmann::json j;
    j["frame"] = fr.index;
    j["time_s"] = fr.time_s;
    j["camera"] = {{"position_m", {fr.camera.position_m.x, fr.camera.position_m.y, fr.camera.position_m.z}},
                   {"yaw_deg", fr.camera.yaw_rad * 180.0 / std::numbers::pi},
                   {"pitch_deg", fr.camera.pitch_rad * 180.0 / std::numbers::pi},
                   {"cut", fr.cut}};
    j["feedback_pages"] = fr.feedback_pages;
    j["feedback_frames_late"] = fr.feedback_frames_late;
    j["working_set"] = s.residency.working_set;
    j["requested"] = s.residency.requested;
    j["produced"] = s.composed;
    j["evicted"] = s.residency.evicted;
    j["resident"] = s.residency.resident;
    j["occupancy"] = s.residency.occupancy;
    j["mip_bias"] = s.residency.mip_bias;
    j["oversubscribed"] = s.residency.oversubscribed;
    j["table_updates"] = s.table_updates;
    j["materials"] = {{"resident", s.materials.resident}, {"uploaded_bytes", s.materials.last_bytes},
                      {"uploaded_total_bytes", s.materials.bytes_uploaded}, {"all_bytes", s.materials.bytes_total},
                      // CPU side: materials read from disk (or generated) on first use
                      {"cpu_loaded", s.materials.cpu_loaded}, {"cpu_loaded_now", s.materials.last_cpu_loaded},
                      {"cpu_load_ms", s.materials.last_cpu_load_ms},
                      {"cpu_load_total_ms", s.materials.cpu_load_ms},
                      {"load_failures", s.materials.load_failures}};
    if (vt_source != VtSource::procedural) {
      j["stored"] = {{"requested", s.stored.requested}, {"landed", s.stored.landed}, {"failed", s.stored.failed},
                     {"cancelled", s.stored.cancelled}, {"outstanding", s.stored.outstanding},
                     {"staging_in_use", s.stored.staging_in_use}, {"read_ms", s.stored.read_ms},
                     {"decode_ms", s.stored.decode_ms}, {"missing", s.missing}, {"fallback_composed", s.fallback_composed}};
    }
    for (const std::string& e : fr.store_errors) std::fprintf(stderr, "\n  bad page: %s", e.c_str());
    j["triangles"] = fr.triangles;
    // gpu: the GPU time of an earlier frame (frames in flight), named by its index.
    j["ms"] = {{"select", s.select_ms}, {"residency", fr.residency_ms}, {"cpu", fr.cpu_ms}, {"wait", fr.wait_ms},
               {"total", fr.total_ms}};
    if (fr.gpu_ms_frame > 0 || fr.gpu_ms > 0)
      j["gpu"] = {{"frame", fr.gpu_ms_frame},         {"ms", fr.gpu_ms},
                  {"vt_ms", fr.gpu_stage_ms[0]},      {"terrain_ms", fr.gpu_stage_ms[1]},
                  {"compaction_ms", fr.gpu_stage_ms[2]}};
    if (auto w = run.stats.append(j.dump() + "\n"); !w) {
      write_error = w.error().message;
      return false;
    }
    if (!a.quiet)
      std::fprintf(stderr, "\r  frame %u/%u  %6.1f ms  resident %u  +%u pages  bias %u%s   ", fr.index + 1, frames,
                   fr.total_ms, s.residency.resident, s.composed + s.stored.landed, s.residency.mip_bias,
                   s.residency.oversubscribed ? "  OVERSUBSCRIBED" : "");
    return true;
  });
  if (!a.quiet) std::fprintf(stderr, "\n");
  if (write_error.empty() && summary && run.is_open())
    if (auto committed = run.stats.commit(); !committed) write_error = committed.error().message;
  if (!write_error.empty() || !summary) {
    run.take_back();
    std::error_code ec;
    if (wrote_table) std::filesystem::remove(a.page_table, ec);
    const std::string why = write_error.empty() ? summary.error().message : write_error;
    const bool started = !run.folder.empty();  // the folder was touched: say what is left of the run
    return fail(cmd, why + (started ? "; no frame or stats of this run is kept in " + a.out : std::string()),
                write_error.empty() ? 2 : 1);
  }
  const FlythroughSummary& s = summary.value();
  std::printf("%u frames in %.1f s (%.1f ms/frame), %llu pages composed, %llu loaded, max mip bias %u%s\n", s.frames,
              s.seconds, 1000.0 * s.seconds / s.frames, (unsigned long long)s.pages_composed,
              (unsigned long long)s.pages_loaded, s.max_mip_bias,
              s.oversubscribed_frames ? (", oversubscribed in " + std::to_string(s.oversubscribed_frames) + " frames").c_str()
                                      : "");
  if (s.load_failures || s.pages_missing)
    std::printf("store: %llu pages failed verification or reading (each reported once above), %llu requests not in the store\n",
                (unsigned long long)s.load_failures, (unsigned long long)s.pages_missing);
  std::printf("GPU memory: cache + page table %.1f MB; wrote %u frames and stats.jsonl to %s\n",
              double(s.gpu_bytes) / 1048576.0, written, a.out.c_str());
  return 0;
}

const CommandRegistrar k_register{
    "render", "Fly a camera over the terrain through the virtual texture (the main job)", 10, [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<RenderArgs>();
      app.add_option("--scene", a->scene, "Scene JSON file (default: the built-in scene)")->check(regular_file());
      app.add_option("--out", a->out, "Output folder for frames and stats")->capture_default_str();
      const CLI::Option* camera = app.add_option("--camera", a->camera, "Camera path file (docs/renderer.md; default: the built-in flythrough)");
      const CLI::Option* save_camera = app.add_option(
          "--save-camera", a->save_camera, "Write the camera path (the built-in flythrough unless --camera) to this file and stop");
      app.add_flag("--overwrite", a->overwrite,
                   "Replace the output of an earlier run in --out (its frames, debug images and stats.jsonl; other files "
                   "stay) and an existing --save-camera or --page-table file");
      const CLI::Option* frames = app.add_option("--frames", a->frames,
                                                 "Frames to render (default: 120 on the built-in flythrough, the whole --camera path)");
      app.add_option("--every", a->every, "Write every k-th frame")->capture_default_str();
      app.add_option("--width", a->width, "Image width")->capture_default_str();
      app.add_option("--height", a->height, "Image height")->capture_default_str();
      app.add_option("--fps", a->fps, "Camera path frames per second")->capture_default_str();
      app.add_option("--method", a->method, "Transition method")->capture_default_str();
      add_mip_strategy_option(app, a->mip_strategy);
      add_hex_option(app, a->hex);
      app.add_option("--cache-slots", a->cache_slots, "Physical cache size in pages")->capture_default_str();
      app.add_option("--page-budget", a->page_budget, "Pages composed per frame at most")->capture_default_str();
      app.add_option("--feedback-divisor", a->feedback_divisor, "N: one feedback texel per N x N pixels")->capture_default_str();
      app.add_option("--window", a->window, "Page-table window per mip (pages, power of two)")->capture_default_str();
      app.add_option("--format", a->format, "Frame format: png or exr")->capture_default_str();
      app.add_option("--source", a->source, "Pages from: procedural (composed), stored (a baked store) or hybrid")->capture_default_str();
      app.add_option("--store", a->store, "Page store for --source stored|hybrid (terravt bake)");
      app.add_option("--loader-threads", a->loader_threads, "Store reader/decoder threads")->capture_default_str();
      app.add_option("--staging", a->staging, "Stored pages staged at once (loads outstanding at most)")->capture_default_str();
      app.add_option("--feedback", a->feedback,
                     "Who writes feedback (one rotating pixel per N x N): attachment (the main pass, on a second colour "
                     "attachment), main (the main pass, storage-buffer stores), separate (a 1/N pass) or auto (attachment "
                     "on a CPU device, main on a GPU: the cheaper of the two on each, as measured by bench frame)")
          ->capture_default_str();
      app.add_option("--anisotropy", a->anisotropy, "VT taps per mip along the footprint (1: isotropic; at most the page border)")->capture_default_str();
      app.add_option("--vt-filter", a->vt_filter,
                     "Between VT mips: trilinear (two page lookups, blended), bilinear (nearest mip, one lookup, cheaper, "
                     "visible mip bands) or brilinear[:W] (blend only within W of each half-way LOD, default 0.25: one "
                     "lookup outside that band)")
          ->capture_default_str();
      app.add_option("--detail-relief", a->detail_relief, "Metres of material height relief for the detail normal (0: off)")->capture_default_str();
      app.add_option("--lighting", a->lighting,
                     "sun (Lambert sun + ambient, distance fog, detail normal) or none (the image is the albedo: for "
                     "comparing with another renderer)")
          ->capture_default_str();
      app.add_option("--page-table", a->page_table,
                     "After the last frame, write the GPU page table here (raw little-endian uint32 entries, every mip's "
                     "window: what VirtualTextureBindings::table_buffer holds)");
      app.add_option("--frames-in-flight", a->frames_in_flight, "Frames recorded ahead of the GPU (1: wait for each frame)")->capture_default_str();
      app.add_flag("--sync-loads", a->sync_loads, "Wait for each frame's stored pages (frame-exact comparisons)");
      app.add_flag("--strict", a->strict,
                   "With --source hybrid: a --store that cannot be opened is an error (default: reported once, every "
                   "page composed)");
      const CLI::Option* gpu = app.add_option("--gpu", a->gpu_name, "Vulkan device name substring or index");
      app.add_flag("--quiet", a->quiet, "No progress line");
      app.add_flag("--debug", a->debug, "With each written frame, also write the cache atlas, page table and feedback images");
      app.add_flag("--debug-mips", a->debug_mips, "Colour every texel by the mip of its data (red 0, green 1, yellow 2, blue 3...)");
      return [a, frames, camera, save_camera, gpu] {
        a->frames_given = frames->count() > 0;
        a->camera_given = camera->count() > 0;
        a->save_camera_given = save_camera->count() > 0;
        a->gpu_given = gpu->count() > 0;
        return run_render(*a);
      };
    }};

}  // namespace
}  // namespace tvt::cli
