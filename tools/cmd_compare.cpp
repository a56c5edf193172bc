// `terravt compare`: procedural composition vs a stored megatexture on the same scene and
// camera path, in one run (docs/stored-megatexture.md). Runs the flythrough composing pages, bakes exactly the
// pages that run needed (or takes --store), runs it again from the store (once frame-exact,
// waiting for every frame's loads, to prove the images identical; once asynchronous, as an
// engine would), and reports pages/s, ms per page, disk bytes, GPU memory, frame times, image
// difference, and the disk size of a full stored set at larger V, extrapolated from the bytes
// per page measured per mip, and the image error of procedural pages per mip against the
// filtered pyramid (level 0 box-filtered up: what a baked megatexture should hold; taken from
// a filtered --store, else computed for a few pages per mip). Writes a JSON report, an SVG plot
// and a table.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>

#include "compose/image_diff.h"
#include "app/flythrough.h"
#include "streaming/bake.h"
#include "streaming/page_store.h"
#include "streaming/pyramid.h"
#include "tools/cli_common.h"
#include "tools/commands.h"
#include "tools/page_producers.h"

namespace tvt::cli {
namespace {

struct CompareArgs {
  std::string scene;
  std::string method = "fbpb+dpt2";
  std::string mip_strategy = "prefiltered";
  std::string hex = "scene";
  std::string out = "out/compare";
  std::string camera;  // camera path file (default: the built-in flythrough)
  std::string store;
  std::string gpu_name;
  bool overwrite = false;  // replace an earlier run's compare.tvt, compare.json, disk_vs_v.svg
  uint32_t frames = 30;
  uint32_t width = 320, height = 180;
  uint32_t cache_slots = 512;
  uint32_t page_budget = 48;
  uint32_t every = 5;
  uint32_t loader_threads = 2;
  uint32_t staging = 64;
  int level = 3;
  uint32_t truth_pages = 2;    // computed truth: pages per mip
  uint32_t truth_max_mip = 3;  // computed truth: mips 1..this (a mip-m page composes 4^m level-0 pages)
  bool quiet = false;
};

// Procedural pages against the filtered pyramid, one mip.
struct MipError {
  uint64_t pages = 0, texels = 0, level0_pages = 0;
  double squared_error = 0;  // summed over RGB of every payload texel
  uint32_t max_abs = 0;
  double seconds = 0;        // making the truth
  const char* truth = "";    // "store" or "computed"
  double psnr_db() const {
    if (squared_error == 0) return 99.0;
    return 10.0 * std::log10(255.0 * 255.0 / (squared_error / double(3 * texels)));
  }
};

// Per mip >= 1 of the pages the run used: the procedural pages (composed at their mip, as the VT
// shows them) against the filtered pyramid's payload texels. The truth is the store's page when
// the store holds the filtered pyramid (every page of the run it holds), else computed from
// level-0 pages (streaming/pyramid.h) for the first `truth_pages` pages of mips up to
// `truth_max_mip`.
Result<std::map<uint32_t, MipError>> error_vs_filtered(const std::set<PageId>& run_pages, const PageStoreReader& store,
                                                       PageProducers& producers, const CompareArgs& a) {
  const VtConfig& vt = store.desc().vt;
  const bool stored_truth = store.desc().pyramid == StorePyramid::filtered;
  PageSource compose = producers.source();
  FilteredPyramid pyramid(producers.store_desc(a.level), compose, PageLookup{}, FilteredPyramid::Options{});
  auto decoder = store.make_decoder();
  std::map<uint32_t, MipError> out;
  for (const PageId& page : run_pages) {
    if (page.mip == 0) continue;  // level 0 is the composition itself
    MipError& e = out[page.mip];
    std::vector<uint8_t> truth;
    const auto t0 = std::chrono::steady_clock::now();
    if (stored_truth) {
      if (!store.contains(page)) continue;
      std::vector<uint8_t> full(store.page_bytes());
      std::string message;
      if (store.read_page(page, full, *decoder, &message) != PageError::none) return make_error(message);
      truth = page_payload(vt, full);
      e.truth = "store";
    } else {
      if (page.mip > a.truth_max_mip || e.pages >= a.truth_pages) continue;
      const uint64_t before = pyramid.composed_pages();
      auto t = pyramid.payload(page);
      if (!t) return t.error();
      truth = std::move(t.value());
      e.level0_pages += pyramid.composed_pages() - before;
      e.truth = "computed";
    }
    e.seconds += seconds_since(t0);
    std::vector<std::vector<uint8_t>> composed;
    if (auto s = compose(std::span(&page, 1), composed); !s) return s.error();
    const std::vector<uint8_t> procedural = page_payload(vt, composed[0]);
    for (size_t i = 0; i < procedural.size(); ++i) {
      if (i % 4 == 3) continue;  // RGB: alpha holds height
      const int d = int(procedural[i]) - int(truth[i]);
      e.squared_error += double(d * d);
      e.max_abs = std::max(e.max_abs, uint32_t(std::abs(d)));
    }
    e.texels += procedural.size() / 4;
    ++e.pages;
  }
  std::erase_if(out, [](const auto& kv) { return kv.second.pages == 0; });
  return out;
}

struct RunResult {
  FlythroughSummary summary;
  std::vector<double> frame_ms;
  std::vector<ImageRGBA8> images;           // frames 0, every, 2*every, ..., last
  std::set<PageId> pages;                   // every page that became resident
  uint64_t landed = 0;
  double read_ms = 0, decode_ms = 0;        // loader threads, summed over landed pages
};

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t h = v.size() / 2;
  return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

Result<RunResult> run(vk::Context& g, const SceneAssets& assets, const FlythroughOptions& fo, const CompareArgs& a,
                      const char* label) {
  RunResult r;
  auto s = run_flythrough(g, assets, fo, [&](const FlythroughFrame& f, const FlythroughViews& views) {
    r.frame_ms.push_back(f.total_ms);
    r.pages.insert(f.completed.begin(), f.completed.end());
    r.landed += f.vt.stored.landed;
    r.read_ms += f.vt.stored.read_ms;
    r.decode_ms += f.vt.stored.decode_ms;
    if (f.index % a.every == 0 || f.index + 1 == a.frames) r.images.push_back(views.frame());
    if (!a.quiet) std::fprintf(stderr, "\r  %-22s frame %u/%u   ", label, f.index + 1, a.frames);
    return true;
  });
  if (!a.quiet) std::fprintf(stderr, "\n");
  if (!s) return s.error();
  r.summary = s.value();
  return r;
}

// Bytes of a file, 0 when the path is empty or unreadable.
uint64_t file_bytes(const std::string& path) {
  std::error_code ec;
  const auto n = path.empty() ? 0 : std::filesystem::file_size(path, ec);
  return ec ? 0 : uint64_t(n);
}

// Disk size of a full stored set at V = 2^log2_v with the store's page size: every page of
// every mip, each at the bytes per page measured for that mip (mips coarser than any
// measured mip take the next coarser measured mip's figure; coarser than all, the coarsest).
double extrapolate_bytes(const std::map<uint32_t, double>& per_mip, const VtConfig& like, uint32_t log2_v) {
  VtConfig vt = like;
  vt.log2_size = log2_v;
  double total = 0;
  for (uint32_t m = 0; m < vt.mip_count(); ++m) {
    // Bytes per page depend on the page's footprint in level-0 texels, i.e. on the mip, not on V.
    const auto it = per_mip.lower_bound(m);
    const double bpp = it != per_mip.end() ? it->second : per_mip.rbegin()->second;
    const double n = double(vt.pages_per_side(m));
    total += n * n * bpp;
  }
  return total;
}

std::string svg_plot(const std::vector<std::pair<uint32_t, double>>& stored, double procedural) {
  const double x0 = 70, y0 = 20, w = 520, h = 300;
  double lo = std::floor(std::log10(std::max(1.0, procedural))) - 1, hi = lo + 1;
  for (const auto& [v, b] : stored) hi = std::max(hi, std::ceil(std::log10(std::max(1.0, b))));
  const uint32_t vmin = stored.front().first, vmax = stored.back().first;
  auto px = [&](uint32_t v) { return x0 + w * double(v - vmin) / double(std::max(1u, vmax - vmin)); };
  auto py = [&](double bytes) { return y0 + h * (1.0 - (std::log10(std::max(1.0, bytes)) - lo) / (hi - lo)); };
  std::string s = "<svg xmlns='http://www.w3.org/2000/svg' width='640' height='380' font-family='sans-serif' font-size='12'>\n";
  s += "<rect width='640' height='380' fill='white'/>\n";
  for (double e = lo; e <= hi; e += 1) {
    char buf[160];
    std::snprintf(buf, sizeof(buf), "<line x1='%g' y1='%g' x2='%g' y2='%g' stroke='#ddd'/><text x='%g' y='%g' text-anchor='end'>1e%.0f B</text>\n",
                  x0, py(std::pow(10, e)), x0 + w, py(std::pow(10, e)), x0 - 6, py(std::pow(10, e)) + 4, e);
    s += buf;
  }
  for (const auto& [v, b] : stored) {
    char buf[120];
    std::snprintf(buf, sizeof(buf), "<text x='%g' y='%g' text-anchor='middle'>2^%u</text>\n", px(v), y0 + h + 18, v);
    s += buf;
  }
  std::string line;
  for (const auto& [v, b] : stored) line += std::to_string(px(v)) + "," + std::to_string(py(b)) + " ";
  s += "<polyline fill='none' stroke='#c33' stroke-width='2' points='" + line + "'/>\n";
  char buf[400];
  std::snprintf(buf, sizeof(buf),
                "<line x1='%g' y1='%g' x2='%g' y2='%g' stroke='#36c' stroke-width='2'/>\n"
                "<text x='%g' y='%g' fill='#c33'>stored megatexture (all mips)</text>\n"
                "<text x='%g' y='%g' fill='#36c'>procedural inputs</text>\n"
                "<text x='%g' y='%g' text-anchor='middle'>V (texels per side)</text>\n",
                x0, py(procedural), x0 + w, py(procedural), x0 + 10, y0 + 14, x0 + 10, py(procedural) - 6, x0 + w / 2,
                y0 + h + 36);
  s += buf;
  return s + "</svg>\n";
}

// The files a run writes into its --out folder (the store only when it bakes one: not with --store).
std::vector<std::string> compare_outputs(const std::string& out, bool bakes_store) {
  std::vector<std::string> files;
  for (const char* name : {"compare.tvt", "compare.json", "disk_vs_v.svg"})
    if (bakes_store || std::string_view(name) != "compare.tvt") files.push_back((std::filesystem::path(out) / name).string());
  return files;
}

// Checked before any work: `out` is a folder or does not exist yet, and holds no earlier run's
// files unless `overwrite` (never a non-file in their place).
Status check_compare_folder(const std::string& out, bool bakes_store, bool overwrite) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(out, ec))) return Ok{};
  if (!fs::is_directory(out, ec)) return make_error("--out: " + out + " exists and is not a folder");
  for (const std::string& file : compare_outputs(out, bakes_store))
    if (auto s = check_output_file("--out", file, overwrite); !s) {
      const std::string& why = s.error().message;
      return make_error(why.ends_with("pass --overwrite to replace it") ? why + " (an earlier run's output)" : why);
    }
  return Ok{};
}

int run_compare(const CompareArgs& a) {
  const char* cmd = "compare";
  const auto method = method_from_string(a.method);
  if (!method) return fail(cmd, "--method: unknown method '" + a.method + "'", 2);
  if (a.frames < 1 || a.every < 1) return fail(cmd, "--frames/--every: must be at least 1", 2);
  // The folder (its lock) and the files written into it; the store only when compare bakes it.
  FlaggedPaths outputs = {{"--out", a.out}};
  for (const std::string& file : compare_outputs(a.out, a.store.empty())) outputs.push_back({"--out", file});
  if (auto problem = output_collision(outputs, {{"--scene", a.scene}, {"--store", a.store}, {"--camera", a.camera}}))
    return fail(cmd, *problem, 2);
  // Every flag and input is checked before the procedural run, which takes minutes.
  if (a.width < 16 || a.height < 16 || a.width > 8192 || a.height > 8192)
    return fail(cmd, "--width/--height: must be between 16 and 8192", 2);
  if (a.cache_slots < 2) return fail(cmd, "--cache-slots: must be at least 2, got " + std::to_string(a.cache_slots), 2);
  if (a.page_budget < 1 || a.page_budget > a.cache_slots)
    return fail(cmd, "--page-budget: must be between 1 and --cache-slots (" + std::to_string(a.cache_slots) + ")", 2);
  if (a.loader_threads < 1 || a.loader_threads > 64) return fail(cmd, "--loader-threads: must be between 1 and 64", 2);
  if (a.staging < 1 || a.staging > 4096) return fail(cmd, "--staging: must be between 1 and 4096", 2);
  if (a.level < -5 || a.level > 19 || a.level == 0) return fail(cmd, "--level: zstd level must be -5..-1 or 1..19", 2);
  std::shared_ptr<const PageStoreReader> given_store;
  if (!a.store.empty()) {
    auto opened = PageStoreReader::open(a.store);
    if (!opened) return fail(cmd, "--store: " + opened.error().message, 2);
    given_store = std::move(opened.value());
  }
  auto owned = OutputLock::acquire("--out", a.out);  // one run per folder
  if (!owned) return fail(cmd, owned.error().message, 2);
  // Inputs first: a bad scene or camera file leaves no output folder behind.
  auto assets = load_scene_and_assets(a.scene, a.hex);
  if (!assets) return fail(cmd, assets.error().message, 2);
  // A file the scene names in the place of an output is refused before any advice to pass --overwrite.
  if (auto problem = output_in_scene(outputs, assets->desc)) return fail(cmd, *problem, 2);
  if (auto s = check_compare_folder(a.out, a.store.empty(), a.overwrite); !s) return fail(cmd, s.error().message, 2);
  auto camera = choose_camera(a.camera, assets.value());
  if (!camera) return fail(cmd, camera.error().message, 2);
  // Timings compare producers, not first-use loading: read every material up front.
  if (auto loaded = assets->materials->load_all(); !loaded) return fail(cmd, loaded.error().message, 2);
  auto ctx = gpu_context(a.gpu_name);
  if (!ctx) return fail(cmd, ctx.error().message, 1);
  vk::Context& g = *ctx.value();
  const VtConfig& vt = assets->desc.vt;
  std::error_code ec;
  std::filesystem::create_directories(a.out, ec);
  if (!std::filesystem::is_directory(a.out)) return fail(cmd, "--out: cannot create folder " + a.out, 2);

  FlythroughOptions fo;
  fo.method = *method;
  fo.mip_strategy = parsed_mip_strategy(a.mip_strategy);
  fo.frames = a.frames;
  fo.width = a.width;
  fo.height = a.height;
  fo.vt.cache_slots = a.cache_slots;
  fo.vt.page_budget = a.page_budget;
  fo.vt.loader.threads = a.loader_threads;
  fo.vt.loader.staging_slots = a.staging;
  fo.deterministic = true;  // procedural and frame-exact stored runs see the same feedback
  fo.camera = camera->file;
  std::printf("terravt compare: %s, V = 2^%u, %s, mip strategy %s, %u frames at %ux%u, camera %s, device %s\n",
              assets->desc.source_path.c_str(), vt.log2_size, a.method.c_str(), a.mip_strategy.c_str(), a.frames, a.width, a.height,
              camera->describe().c_str(), g.device_name().c_str());

  // 1. Procedural.
  auto proc = run(g, assets.value(), fo, a, "procedural");
  if (!proc) return fail(cmd, proc.error().message, 1);

  // 2. The store: exactly the pages the path needed, in bake order (or --store).
  auto producers = PageProducers::create(assets.value(), *method, fo.mip_strategy, false, "", &g);
  if (!producers) return fail(cmd, producers.error().message, 1);
  std::string store_path = a.store;
  double bake_s = 0;
  if (store_path.empty()) {
    std::vector<PageId> plan(proc->pages.begin(), proc->pages.end());
    std::sort(plan.begin(), plan.end(), [](const PageId& p, const PageId& q) {
      if (p.mip != q.mip) return p.mip > q.mip;
      return p.y != q.y ? p.y < q.y : p.x < q.x;
    });
    store_path = (std::filesystem::path(a.out) / "compare.tvt").string();
    BakeOptions bo;
    bo.resume = false;
    std::filesystem::remove(store_path + ".partial", ec);
    bo.progress = [&](const BakeProgress& p) {
      if (!a.quiet) std::fprintf(stderr, "\r  %-22s %llu/%llu pages   ", "bake", (unsigned long long)p.done, (unsigned long long)p.total);
    };
    const auto t0 = std::chrono::steady_clock::now();
    auto baked = bake_store(store_path, producers.value()->store_desc(a.level), plan, producers.value()->source(), bo);
    if (!a.quiet) std::fprintf(stderr, "\n");
    if (!baked) return fail(cmd, baked.error().message, 1);
    bake_s = seconds_since(t0);
  }
  std::shared_ptr<const PageStoreReader> store = given_store;
  if (!store) {
    auto opened = PageStoreReader::open(store_path);
    if (!opened) return fail(cmd, opened.error().message, 1);
    store = std::move(opened.value());
  }

  // 3. Stored, frame-exact (identical images expected) and asynchronous (timing).
  fo.vt.source = VtSource::stored;
  fo.vt.store = store;
  fo.vt.sync_loads = true;
  auto exact = run(g, assets.value(), fo, a, "stored (frame-exact)");
  if (!exact) return fail(cmd, exact.error().message, 1);
  fo.vt.sync_loads = false;
  fo.deterministic = false;
  auto async = run(g, assets.value(), fo, a, "stored (async)");
  if (!async) return fail(cmd, async.error().message, 1);

  // 4. Per-page costs, side by side: GPU composition of a batch vs read + verify + decode.
  std::vector<PageId> sample(proc->pages.begin(), proc->pages.end());
  if (sample.size() > 32) sample.resize(32);
  double compose_ms = 0;
  if (!sample.empty()) {
    auto batch_s = producers.value()->composer()->time_batch(sample, 2);
    if (!batch_s) return fail(cmd, batch_s.error().message, 1);
    compose_ms = 1000.0 * batch_s.value() / double(sample.size());
  }
  auto decoder = store->make_decoder();
  std::vector<uint8_t> page(store->desc().page_bytes());
  const auto t1 = std::chrono::steady_clock::now();
  uint64_t read_ok = 0;
  for (const StoreEntry& e : store->entries()) read_ok += store->read_page(e.page, page, *decoder) == PageError::none ? 1 : 0;
  const double read_ms = store->entries().empty() ? 0 : 1000.0 * seconds_since(t1) / double(store->entries().size());

  // 5. Images; procedural pages against the filtered pyramid, per mip.
  auto mip_error = error_vs_filtered(proc->pages, *store, *producers.value(), a);
  if (!mip_error) return fail(cmd, mip_error.error().message, 1);
  const bool filtered_store = store->desc().pyramid == StorePyramid::filtered;
  double worst_psnr = std::numeric_limits<double>::infinity();
  uint32_t worst_abs = 0;
  std::vector<double> frame_psnr;  // per compared frame; identical frames count as 99 dB
  for (size_t i = 0; i < proc->images.size() && i < exact->images.size(); ++i) {
    const ImageDiff d = compare_images(proc->images[i], exact->images[i]);
    worst_psnr = std::min(worst_psnr, d.psnr_db);
    worst_abs = std::max(worst_abs, d.max_abs);
    frame_psnr.push_back(std::isinf(d.psnr_db) ? 99.0 : d.psnr_db);
  }
  const double median_psnr = frame_psnr.empty() ? 99.0 : median(frame_psnr);

  // 6. Disk: the store, the procedural inputs (files the scene names + the scene itself) and,
  // since built-in materials are generated, the packed inputs as files would hold them.
  uint64_t input_files = a.scene.empty() ? default_scene_json().size() : file_bytes(a.scene);
  input_files += file_bytes(assets->desc.terrain.heightmap.image_path);
  for (const MaterialDesc& m : assets->desc.materials)
    for (const std::string& p : {m.albedo.image_path, m.albedo.height_path, m.weight.splat_path, m.fbpb.meta_path, m.fbpb.mask_path})
      input_files += file_bytes(p);
  auto packed = pack_scene(assets.value(), options_for(*method, fo.mip_strategy));
  if (!packed) return fail(cmd, packed.error().message, 2);
  const uint64_t input_packed = (packed->texel_words + packed->meta_words) * 4 +
                                packed->weights.size() * 4 + assets->heightfield.data.size() * 4;
  std::map<uint32_t, double> per_mip;
  std::map<uint32_t, uint64_t> per_mip_pages;
  for (const StoreEntry& e : store->entries()) {
    per_mip[e.page.mip] += e.stored_bytes;
    ++per_mip_pages[e.page.mip];
  }
  for (auto& [m, b] : per_mip) b /= double(per_mip_pages[m]);

  // 7. Report.
  nlohmann::json j;
  j["scene"] = assets->desc.source_path;
  j["method"] = a.method;
  j["mip_strategy"] = a.mip_strategy;
  j["vt"] = {{"log2_size", vt.log2_size}, {"page_texels", vt.page_texels}, {"border_texels", vt.border_texels}};
  j["frames"] = a.frames;
  j["camera"] = camera->describe();
  j["resolution"] = {a.width, a.height};
  j["device"] = g.device_name();
  auto run_json = [&](const RunResult& r, double ms_per_page) {
    return nlohmann::json{{"median_frame_ms", median(r.frame_ms)},
                          {"seconds", r.summary.seconds},
                          {"pages_composed", r.summary.pages_composed},
                          {"pages_loaded", r.summary.pages_loaded},
                          {"pages_per_s", double(r.summary.pages_composed + r.summary.pages_loaded) / std::max(1e-9, r.summary.seconds)},
                          {"ms_per_page", ms_per_page},
                          {"load_failures", r.summary.load_failures},
                          {"gpu_bytes", r.summary.gpu_bytes}};
  };
  j["procedural"] = run_json(proc.value(), compose_ms);
  j["stored_exact"] = run_json(exact.value(), read_ms);
  j["stored_async"] = run_json(async.value(), read_ms);
  j["stored_async"]["loader_read_ms_per_page"] = async->landed ? async->read_ms / double(async->landed) : 0.0;
  j["stored_async"]["loader_decode_ms_per_page"] = async->landed ? async->decode_ms / double(async->landed) : 0.0;
  j["images"] = {{"frames_compared", std::min(proc->images.size(), exact->images.size())},
                 {"identical", worst_abs == 0},
                 {"worst_psnr_db", std::isinf(worst_psnr) ? 99.0 : worst_psnr},
                 {"median_psnr_db", median_psnr},
                 {"psnr_db_per_frame", frame_psnr},
                 {"max_abs_diff", worst_abs}};
  for (const auto& [m, e] : mip_error.value())
    j["error_vs_filtered"][std::to_string(m)] = {{"pages", e.pages}, {"psnr_db", e.psnr_db()}, {"max_abs_diff", e.max_abs},
                                                 {"truth", e.truth}, {"truth_level0_pages", e.level0_pages},
                                                 {"truth_seconds", e.seconds}};
  j["store"] = {{"path", store_path}, {"pyramid", std::string(to_string(store->desc().pyramid))},
                {"file_bytes", store->file_bytes()}, {"pages", store->entries().size()},
                {"bake_seconds", bake_s}, {"read_ok", read_ok}};
  j["inputs"] = {{"file_bytes", input_files}, {"packed_bytes", input_packed}};
  std::vector<std::pair<uint32_t, double>> curve;
  for (uint32_t v = std::max(vt.log2_page() + 1, 14u); v <= 24; v += 2) {
    const double bytes = extrapolate_bytes(per_mip, vt, v);
    curve.emplace_back(v, bytes);
    j["extrapolated"].push_back({{"log2_size", v}, {"stored_bytes", bytes},
                                 {"inputs_over_stored_files", double(input_files) / bytes},
                                 {"inputs_over_stored_packed", double(input_packed) / bytes}});
  }
  for (const auto& [m, b] : per_mip) j["bytes_per_page_by_mip"][std::to_string(m)] = b;
  const std::string report = (std::filesystem::path(a.out) / "compare.json").string();
  const std::string plot = (std::filesystem::path(a.out) / "disk_vs_v.svg").string();
  // The plot first, the report last: a compare.json says both were written.
  if (!curve.empty())
    if (auto w = write_text_file(plot, svg_plot(curve, double(input_packed))); !w) return fail(cmd, w.error().message, 1);
  if (auto w = write_text_file(report, j.dump(2) + "\n"); !w) {
    std::error_code ignored;
    std::filesystem::remove(plot, ignored);
    return fail(cmd, w.error().message, 1);
  }

  std::printf("\n%-22s %12s %12s %12s %12s %12s\n", "", "frame ms", "pages/s run", "ms/page", "GPU MB", "pages");
  auto row = [&](const char* name, const RunResult& r, double ms_page) {
    std::printf("%-22s %12.1f %12.1f %12.2f %12.1f %12llu\n", name, median(r.frame_ms),
                double(r.summary.pages_composed + r.summary.pages_loaded) / std::max(1e-9, r.summary.seconds), ms_page,
                double(r.summary.gpu_bytes) / 1048576.0, (unsigned long long)(r.summary.pages_composed + r.summary.pages_loaded));
  };
  row("procedural", proc.value(), compose_ms);
  row("stored (frame-exact)", exact.value(), read_ms);
  row("stored (async)", async.value(), read_ms);
  std::printf("\nms/page: GPU composition of a %zu-page batch vs read + verify + decode on one thread\n", sample.size());
  std::printf("images: %s (worst PSNR %s, max difference %u/255 over %zu frames)\n",
              worst_abs == 0 ? "IDENTICAL" : filtered_store ? "DIFFER (expected: the store holds the filtered pyramid)" : "DIFFER", std::isinf(worst_psnr) ? "inf" : std::to_string(worst_psnr).c_str(),
              worst_abs, std::min(proc->images.size(), exact->images.size()));
  if (worst_abs != 0) {
    std::printf("frame PSNR dB (every %u frames; identical = 99): median %.2f;", a.every, median_psnr);
    for (double p : frame_psnr) std::printf(" %.2f", p);
    std::printf("\n");
  }
  std::printf("disk: store %.2f MB for %zu pages; procedural inputs %.1f KB of files (%.1f MB as packed texels)\n",
              double(store->file_bytes()) / 1e6, store->entries().size(), double(input_files) / 1e3, double(input_packed) / 1e6);
  std::printf("\nprocedural pages vs the filtered pyramid (payload RGB; truth from %s):\n%4s %6s %10s %8s %14s\n",
              filtered_store ? "the store" : "level-0 pages, box-filtered", "mip", "pages", "PSNR dB", "max abs",
              "truth s/page");
  for (const auto& [m, e] : mip_error.value())
    std::printf("%4u %6llu %10.2f %8u %14.2f\n", m, (unsigned long long)e.pages, e.psnr_db(), e.max_abs,
                e.seconds / double(e.pages));
  std::printf("\n%-8s %16s %18s %18s\n", "V", "stored set", "files / stored", "packed / stored");
  for (const auto& [v, b] : curve)
    std::printf("2^%-6u %13.3g B %18.3g %18.3g\n", v, b, double(input_files) / b, double(input_packed) / b);
  std::printf("\nwrote %s and %s\n", report.c_str(), plot.c_str());
  return worst_abs == 0 || filtered_store ? 0 : 1;
}

const CommandRegistrar k_register{
    "compare", "Procedural vs stored megatexture on one scene and camera path: speed, disk, memory, images", 45,
    [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<CompareArgs>();
      app.add_option("--scene", a->scene, "Scene JSON file (default: the built-in scene)")->check(regular_file());
      app.add_option("--method", a->method, "Transition method")->capture_default_str();
      add_mip_strategy_option(app, a->mip_strategy);
      add_hex_option(app, a->hex);
      app.add_option("--out", a->out, "Folder for the store, compare.json and disk_vs_v.svg")->capture_default_str();
      app.add_option("--store", a->store, "Use this store instead of baking the pages the path needs")->check(regular_file());
      app.add_option("--camera", a->camera, "Camera path file (docs/renderer.md; default: the built-in flythrough)");
      app.add_flag("--overwrite", a->overwrite, "Replace an earlier run's compare.tvt, compare.json and disk_vs_v.svg in --out");
      app.add_option("--frames", a->frames, "Frames of the camera path (from its start)")->capture_default_str();
      app.add_option("--width", a->width, "Image width")->capture_default_str();
      app.add_option("--height", a->height, "Image height")->capture_default_str();
      app.add_option("--cache-slots", a->cache_slots, "Physical cache size in pages")->capture_default_str();
      app.add_option("--page-budget", a->page_budget, "Pages produced per frame at most")->capture_default_str();
      app.add_option("--every", a->every, "Compare every k-th frame's image")->capture_default_str();
      app.add_option("--loader-threads", a->loader_threads, "Store reader/decoder threads")->capture_default_str();
      app.add_option("--staging", a->staging, "Stored pages staged at once")->capture_default_str();
      app.add_option("--level", a->level, "zstd level of the baked store")->capture_default_str();
      app.add_option("--truth-pages", a->truth_pages,
                     "Error vs the filtered pyramid without a filtered --store: pages per mip whose truth is computed")
          ->check(CLI::Range(0, 1000))->capture_default_str();
      app.add_option("--truth-max-mip", a->truth_max_mip,
                     "... and the coarsest such mip (a mip-m page composes the 4^m level-0 pages under it)")
          ->check(CLI::Range(1, 12))->capture_default_str();
      app.add_option("--gpu", a->gpu_name, "Vulkan device name substring or index");
      app.add_flag("--quiet", a->quiet, "No progress lines");
      return [a] { return run_compare(*a); };
    }};

}  // namespace
}  // namespace tvt::cli
