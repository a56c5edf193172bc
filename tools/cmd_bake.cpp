// `terravt bake`: composes level-0 pages with the same compositor the VT uses and writes them
// to a page store (zstd pages, per-page checksums; docs/page-store.md) with every coarser mip the
// box filter of the mip below (`--pyramid filtered`, the default), or every page composed at its
// own mip (`--pyramid composed`: byte-identical to what the VT composes). Whole VT or a region
// and a mip range; atomic (temp file + rename); an interrupted bake resumes when run again;
// `--shard i/n` bakes one deterministic part for `terravt merge`.
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>

#include "streaming/file_io.h"
#include "tools/cli_common.h"
#include "tools/commands.h"
#include "tools/page_producers.h"

namespace tvt::cli {
namespace {

struct BakeArgs {
  std::string scene;
  std::string out;
  std::string method = "fbpb+dpt2";
  std::string mip_strategy;  // empty: prefiltered for a composed pyramid (a filtered one composes level 0 only)
  std::string hex = "scene";
  std::string gpu_name;
  std::string shard = "0/1";
  std::string dict = "none";     // none | auto | a dictionary file
  std::string save_dict;
  std::string pyramid = "filtered";
  std::vector<std::string> finer;  // stores holding pages of this filtered bake
  std::vector<int64_t> region;   // x, y, width, height in level-0 texels
  std::vector<uint32_t> mips;    // lo, hi
  uint32_t dict_kb = 110;
  uint32_t dict_samples = 64;
  uint32_t threads = 0;
  uint32_t batch = 32;
  int level = 3;
  bool cpu = false;
  bool restart = false;
  bool overwrite = false;  // replace an existing --out store
  bool ignore_free_space = false;
  bool quiet = false;
};

// Composed terrain pages compress about 1.4-3:1 with zstd (docs/page-store.md); a plan that would not fit
// on the disk even at this ratio is refused before anything is written.
constexpr uint64_t k_best_compression = 32;

std::string gigabytes(uint64_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f GB", double(bytes) / 1e9);
  return buf;
}

// Why a bake of `pages` pages of `page_bytes` cannot fit in the free space of `out`'s folder
// (plus what an interrupted bake there already holds) even at k_best_compression; nothing when
// it can, or when the file system reports no sizes (some virtual ones).
std::optional<std::string> too_big_for_disk(const std::string& out, uint64_t pages, uint64_t page_bytes) {
  const uint64_t raw = pages * page_bytes;
  std::error_code ec;
  const std::filesystem::path folder = std::filesystem::absolute(out, ec).parent_path();
  const std::filesystem::space_info space = std::filesystem::space(folder, ec);
  if (ec || space.capacity == 0) return std::nullopt;
  const uintmax_t partial = std::filesystem::file_size(out + ".partial", ec);
  const uint64_t have = uint64_t(space.available) + (ec ? 0 : uint64_t(partial));
  if (raw / k_best_compression <= have) return std::nullopt;
  return "--out: " + out + ": the bake of " + std::to_string(pages) + " pages is " + gigabytes(raw) +
         " raw and needs at least " + gigabytes(raw / k_best_compression) + " even at " +
         std::to_string(k_best_compression) + ":1 compression, but " + folder.string() + " has " + gigabytes(have) +
         " free; bake a --region or fewer --mips, split it with --shard onto several disks, or pass "
         "--ignore-free-space";
}

std::atomic<bool> g_interrupted{false};
extern "C" void on_sigint(int) { g_interrupted = true; }

std::string duration_text(double s) {
  if (!(s >= 0) || s > 1e7) return "?";
  char buf[32];
  const long t = long(s + 0.5);
  if (t >= 3600) std::snprintf(buf, sizeof(buf), "%ldh%02ldm", t / 3600, t / 60 % 60);
  else std::snprintf(buf, sizeof(buf), "%ldm%02lds", t / 60, t % 60);
  return buf;
}

Status parse_shard(const std::string& text, uint32_t& index, uint32_t& count) {
  unsigned i = 0, n = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%u/%u%c", &i, &n, &tail) != 2 || n < 1 || i >= n || n > 1000000)
    return make_error("--shard: expected i/n with 0 <= i < n, got '" + text + "'");
  index = i;
  count = n;
  return Ok{};
}

// A dictionary trained on pages spread evenly over the whole plan (not the shard), so every
// shard of a bake trains the same dictionary and the parts still merge byte for byte.
Result<std::vector<uint8_t>> auto_dictionary(const std::vector<PageId>& plan, PageSource& source, uint32_t samples,
                                             size_t bytes) {
  std::vector<PageId> picks;
  const size_t n = std::min<size_t>(samples, plan.size());
  for (size_t i = 0; i < n; ++i) picks.push_back(plan[i * plan.size() / n]);
  std::vector<std::vector<uint8_t>> pages;
  if (auto s = source(picks, pages); !s) return s.error();
  return train_dictionary(pages, bytes);
}

int run_bake(const BakeArgs& a) {
  const char* cmd = "bake";
  if (a.out.empty()) return fail(cmd, "--out: a store file is required", 2);
  const auto method = method_from_string(a.method);
  if (!method) return fail(cmd, "--method: unknown method '" + a.method + "' (linear, blendmap, fbpb, dpt1, dpt2, fbpb+dpt2)", 2);
  if (a.level < -5 || a.level > 19 || a.level == 0) return fail(cmd, "--level: zstd level must be -5..-1 or 1..19", 2);
  if (!a.region.empty() && a.region.size() != 4) return fail(cmd, "--region: needs x,y,width,height in level-0 texels", 2);
  if (!a.mips.empty() && a.mips.size() != 2) return fail(cmd, "--mips: needs lo,hi", 2);
  if (a.batch < 1 || a.batch > 1024) return fail(cmd, "--batch: must be between 1 and 1024", 2);
  if (a.pyramid != "filtered" && a.pyramid != "composed")
    return fail(cmd, "--pyramid: must be filtered or composed, got '" + a.pyramid + "'", 2);
  const StorePyramid pyramid = a.pyramid == "filtered" ? StorePyramid::filtered : StorePyramid::composed;
  if (!a.finer.empty() && pyramid != StorePyramid::filtered) return fail(cmd, "--finer: only used with --pyramid filtered", 2);
  if (pyramid == StorePyramid::filtered && !a.mip_strategy.empty() && !parsed_mip_strategy(a.mip_strategy).direct())
    return fail(cmd, "--mip-strategy: only used with --pyramid composed (a filtered pyramid composes level 0 alone, "
                     "where every strategy is direct)", 2);
  for (const std::string& f : a.finer)
    if (auto why = not_a_regular_file(f)) return fail(cmd, "--finer: " + *why, 2);
  uint32_t shard_index = 0, shard_count = 1;
  if (auto s = parse_shard(a.shard, shard_index, shard_count); !s) return fail(cmd, s.error().message, 2);
  {
    // --overwrite replaces an earlier output, never what this run reads (nor the .partial it
    // writes first): said before any advice to pass --overwrite.
    FlaggedPaths inputs = {{"--scene", a.scene}};
    if (a.dict != "none" && a.dict != "auto") inputs.push_back({"--dict", a.dict});
    for (const std::string& f : a.finer) inputs.push_back({"--finer", f});
    if (auto problem = output_collision({{"--out", a.out}, {"--save-dict", a.save_dict}}, inputs)) return fail(cmd, *problem, 2);
  }
  // A finished store may have taken hours: it is replaced only when asked (an interrupted bake's
  // <out>.partial is resumed, not refused), and never when it is not a regular file.
  if (auto s = check_output_file("--out", a.out, a.overwrite); !s) return fail(cmd, s.error().message, 2);
  if (a.dict != "none" && a.dict != "auto")
    if (auto why = not_a_regular_file(a.dict)) return fail(cmd, "--dict: " + *why, 2);
  if (!a.save_dict.empty())
    if (auto s = check_output_file("--save-dict", a.save_dict, a.overwrite); !s) return fail(cmd, s.error().message, 2);

  auto assets = load_scene_and_assets(a.scene, a.hex);
  if (!assets) return fail(cmd, assets.error().message, 2);
  if (auto problem = output_in_scene({{"--out", a.out}, {"--save-dict", a.save_dict}}, assets->desc))
    return fail(cmd, *problem, 2);
  const VtConfig& vt = assets->desc.vt;
  BakeRegion region;
  // Out-of-range values are refused, not clamped: --mips 0,99 would silently bake every mip.
  const uint64_t size = vt.size_texels();
  const uint32_t top = vt.mip_count() - 1;
  if (!a.mips.empty() && (a.mips[0] > a.mips[1] || a.mips[1] > top))
    return fail(cmd, "--mips: lo,hi with 0 <= lo <= hi <= " + std::to_string(top) + " (the top mip of this scene's 2^" +
                         std::to_string(vt.log2_size) + " texels), got " + std::to_string(a.mips[0]) + "," +
                         std::to_string(a.mips[1]), 2);
  if (!a.region.empty()) {
    if (a.region[0] < 0 || a.region[1] < 0 || a.region[2] < 1 || a.region[3] < 1 || uint64_t(a.region[0]) >= size ||
        uint64_t(a.region[1]) >= size || uint64_t(a.region[2]) > size - uint64_t(a.region[0]) ||
        uint64_t(a.region[3]) > size - uint64_t(a.region[1]))
      return fail(cmd, "--region: x,y,width,height must lie inside the " + std::to_string(size) + " x " +
                           std::to_string(size) + " level-0 texels of this scene (x, y >= 0, width, height >= 1), got " +
                           std::to_string(a.region[0]) + "," + std::to_string(a.region[1]) + "," +
                           std::to_string(a.region[2]) + "," + std::to_string(a.region[3]), 2);
    region.x0 = uint64_t(a.region[0]);
    region.y0 = uint64_t(a.region[1]);
    region.x1 = region.x0 + uint64_t(a.region[2]);
    region.y1 = region.y0 + uint64_t(a.region[3]);
  }
  if (!a.mips.empty()) {
    region.mip_lo = a.mips[0];
    region.mip_hi = a.mips[1];
  }
  // Counted before it is enumerated, so that a plan that cannot fit is refused before its page
  // ids are listed (the whole built-in scene's plan is 89 M of them, 1 GB).
  const auto plan_pages = bake_plan_pages(vt, region);
  if (!plan_pages) return fail(cmd, "--region/--mips: " + plan_pages.error().message, 2);
  const ShardRange part = shard_range(plan_pages.value(), shard_index, shard_count);

  const std::string strategy_name =
      !a.mip_strategy.empty() ? a.mip_strategy : pyramid == StorePyramid::filtered ? "direct" : "prefiltered";
  auto producers = PageProducers::create(assets.value(), *method, parsed_mip_strategy(strategy_name), a.cpu, a.gpu_name);
  if (!producers) return fail(cmd, producers.error().message, 1);
  StoreDesc desc = producers.value()->store_desc(a.level);
  desc.pyramid = pyramid;
  if (!a.ignore_free_space) {
    if (auto why = too_big_for_disk(a.out, part.count, desc.page_bytes())) return fail(cmd, *why, 2);
  }
  auto plan = bake_plan(vt, region, pyramid);
  if (!plan) return fail(cmd, "--region/--mips: " + plan.error().message, 2);
  PageSource source = producers.value()->source();

  const auto t0 = std::chrono::steady_clock::now();
  if (a.dict == "auto") {
    auto d = auto_dictionary(plan.value(), source, a.dict_samples, size_t(a.dict_kb) * 1024);
    if (!d) return fail(cmd, "--dict auto: " + d.error().message, 1);
    desc.dictionary = std::move(d.value());
    std::printf("trained a %zu-byte zstd dictionary on %u pages in %.1f s\n", desc.dictionary.size(),
                std::min<uint32_t>(a.dict_samples, uint32_t(plan->size())), seconds_since(t0));
  } else if (a.dict != "none") {
    // A regular file (checked above); read errors are results, never stream exceptions.
    std::ifstream f(a.dict, std::ios::binary);
    if (!f) return fail(cmd, "--dict: cannot read " + a.dict, 2);
    desc.dictionary.assign(std::istreambuf_iterator<char>(f), {});
    if (f.bad()) return fail(cmd, "--dict: cannot read " + a.dict, 2);
    if (desc.dictionary.empty()) return fail(cmd, "--dict: " + a.dict + " is empty", 2);
  }
  if (!a.save_dict.empty()) {
    if (desc.dictionary.empty()) return fail(cmd, "--save-dict: no dictionary (use --dict auto)", 2);
    if (auto w = fileio::write_file_durable(a.save_dict, desc.dictionary.data(), desc.dictionary.size()); !w)
      return fail(cmd, "--save-dict: " + w.error().message, 1);
  }

  std::printf("terravt bake: %s, V = 2^%u, %s, mip strategy %s, %s pyramid, %zu pages in the plan, shard %u/%u = %llu pages, zstd %d%s, %s\n",
              assets->desc.source_path.c_str(), vt.log2_size, a.method.c_str(), strategy_name.c_str(), a.pyramid.c_str(), plan->size(), shard_index, shard_count,
              (unsigned long long)part.count, a.level, desc.dictionary.empty() ? "" : " + dictionary",
              producers.value()->device_name().c_str());

  BakeOptions bo;
  bo.threads = a.threads;
  bo.batch_pages = a.batch;
  bo.resume = !a.restart;
  bo.shard_index = shard_index;
  bo.shard_count = shard_count;
  bo.finer = a.finer;
  bo.cancelled = [] { return g_interrupted.load(); };
  bo.progress = [&](const BakeProgress& p) {
    if (a.quiet) return;
    const double rate = p.seconds > 0 ? double(p.done - p.resumed) / p.seconds : 0.0;
    std::fprintf(stderr, "\r  %llu/%llu pages %5.1f%%  %.1f pages/s  ratio %.2f  ETA %s   ",
                 (unsigned long long)p.done, (unsigned long long)p.total, p.total ? 100.0 * double(p.done) / double(p.total) : 100.0,
                 rate, p.stored_bytes ? double(p.raw_bytes) / double(p.stored_bytes) : 0.0, duration_text(p.eta_seconds).c_str());
  };
  std::signal(SIGINT, on_sigint);
  std::signal(SIGTERM, on_sigint);
  auto summary = bake_store(a.out, desc, plan.value(), source, bo);
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (!a.quiet) std::fprintf(stderr, "\n");
  if (g_interrupted) return fail(cmd, "interrupted; " + a.out + ".partial is kept: run the same command again to resume", 1);
  if (!summary) return fail(cmd, summary.error().message, 1);
  const BakeSummary& s = summary.value();
  std::printf("%llu pages (%llu resumed) in %.1f s: %.1f MB raw -> %.1f MB stored (ratio %.2f), file %.1f MB, %.1f pages/s\n",
              (unsigned long long)s.pages, (unsigned long long)s.resumed_pages, s.seconds, double(s.raw_bytes) / 1e6,
              double(s.stored_bytes) / 1e6, s.stored_bytes ? double(s.raw_bytes) / double(s.stored_bytes) : 0.0,
              double(s.file_bytes) / 1e6, s.seconds > 0 ? double(s.pages - s.resumed_pages) / s.seconds : 0.0);
  if (pyramid == StorePyramid::filtered)
    std::printf("filtered pyramid: %llu finer pages read back, %llu level-0 pages composed that the store does not hold\n",
                (unsigned long long)s.read_back, (unsigned long long)s.extra_composed);
  std::printf("wrote %s\n", a.out.c_str());
  return 0;
}

const CommandRegistrar k_register{
    "bake", "Bake pages of the scene into a stored megatexture (zstd page store)", 40, [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<BakeArgs>();
      app.add_option("--out", a->out, "Store file to write (atomically: <out>.partial, then rename)")->required();
      app.add_option("--scene", a->scene, "Scene JSON file (default: the built-in scene)")->check(regular_file());
      app.add_option("--method", a->method, "Transition method")->capture_default_str();
      add_mip_strategy_option(app, a->mip_strategy);
      add_hex_option(app, a->hex);
      app.add_option("--region", a->region, "x,y,width,height in level-0 texels (default: whole VT)")->delimiter(',');
      app.add_option("--mips", a->mips, "lo,hi: mip range (default: all)")->delimiter(',');
      app.add_option("--pyramid", a->pyramid,
                     "filtered: level 0 composed, every coarser mip the box filter of the one below (what a "
                     "megatexture should hold); composed: every mip composed directly, byte-identical to what the VT "
                     "composes (docs/page-store.md)")
          ->capture_default_str();
      app.add_option("--finer", a->finer,
                     "Filtered bakes: stores holding pages of this same bake (finished shards) to filter from instead "
                     "of composing them again")
          ->delimiter(',');
      app.add_option("--level", a->level, "zstd level (-5..-1, 1..19)")->capture_default_str();
      app.add_option("--dict", a->dict, "zstd dictionary: none, auto (trained on sample pages) or a file")->capture_default_str();
      app.add_option("--dict-kb", a->dict_kb, "Size of a trained dictionary in KiB")->check(CLI::Range(1, 4096))->capture_default_str();
      app.add_option("--dict-samples", a->dict_samples, "Pages a trained dictionary learns from")->check(CLI::Range(1, 100000))->capture_default_str();
      app.add_option("--save-dict", a->save_dict, "Also write the dictionary to this file (for other shards)");
      app.add_option("--threads", a->threads, "Compression threads (0: all cores)")->capture_default_str();
      app.add_option("--batch", a->batch, "Pages composed per batch")->capture_default_str();
      app.add_option("--shard", a->shard, "i/n: bake only part i of n (join the parts with terravt merge)")->capture_default_str();
      app.add_flag("--cpu", a->cpu, "Compose with the double-precision CPU reference instead of the GPU");
      app.add_flag("--restart", a->restart,
                   "Discard an interrupted <out>.partial instead of resuming it (a partial of another plan, scene or "
                   "settings is refused without it)");
      app.add_flag("--overwrite", a->overwrite, "Replace an existing --out store and --save-dict file (otherwise an error)");
      app.add_flag("--ignore-free-space", a->ignore_free_space,
                   "Start even when the plan cannot fit in the free space of --out's folder at 32:1 compression "
                   "(refused by default, before anything is written)");
      app.add_option("--gpu", a->gpu_name, "Vulkan device name substring or index");
      app.add_flag("--quiet", a->quiet, "No progress line");
      return [a] { return run_bake(*a); };
    }};

}  // namespace
}  // namespace tvt::cli
