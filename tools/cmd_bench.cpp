// `terravt bench compose | mips | frame`: page-composition throughput of every method (GPU compute
// vs the CPU reference), mip strategies against the ground truth, and the frame benchmark
// (tools/bench_frame.cpp); measured side by side in one run, reported as ratios too, since
// absolute numbers on lavapipe say little about a real GPU.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>

#include "compose/packed_scene.h"
#include "compose/reference_compositor.h"
#include "compose/region.h"
#include "composer/gpu_composer.h"
#include "shaders/shared/hash.h"
#include "streaming/pyramid.h"
#include "tools/bench_frame.h"
#include "tools/cli_common.h"
#include "tools/commands.h"
#include "tools/svg_plot.h"

namespace tvt::cli {
namespace {

struct BenchComposeArgs {
  std::string scene;
  std::string json_out;
  std::string gpu_name;
  uint32_t pages = 32;      // GPU batch size
  uint32_t cpu_pages = 2;   // CPU reference pages per method
  int repeats = 5;
  uint32_t mip = 0;
  bool skip_cpu = false;
};

struct Row {
  std::string method;
  double gpu_pages_s = 0, gpu_mtexel_s = 0, cpu_pages_s = 0, cpu_mtexel_s = 0;
};

// Times every method on one page set, interleaved round after round; each method keeps its
// fastest batch, so the ratios compare like with like even when the machine's load drifts.
// Rows are named `names[i]`, or by method (then hex) when no names are given.
Result<std::vector<Row>> measure(GpuComposer& composer, const std::vector<PackedScene>& packed,
                                 const std::vector<PageId>& pages, const BenchComposeArgs& a, double texels_per_page,
                                 const std::vector<std::string>& names = {}) {
  std::vector<Row> rows(packed.size());
  std::vector<double> best(packed.size(), 1e300);
  for (const PackedScene& p : packed) {  // warm-up: pipeline and caches
    composer.set_params(p.params);
    if (auto t = composer.time_batch(pages, 1); !t) return t.error();  // measure() runs on a loaded scene (load_all)
  }
  for (int round = 0; round < a.repeats; ++round)
    for (size_t i = 0; i < packed.size(); ++i) {
      composer.set_params(packed[i].params);
      auto t = composer.time_batch(pages, 1);
      if (!t) return t.error();
      best[i] = std::min(best[i], t.value());
    }
  constexpr size_t k_methods = std::size(k_all_methods);
  for (size_t i = 0; i < packed.size(); ++i) {
    Row& row = rows[i];
    row.method = i < names.size() ? names[i]
                                  : std::string(to_string(k_all_methods[i % k_methods])) + (i >= k_methods ? " hex" : "");
    row.gpu_pages_s = double(pages.size()) / best[i];
    row.gpu_mtexel_s = row.gpu_pages_s * texels_per_page * 1e-6;
    if (!a.skip_cpu) {
      const size_t n = std::min<size_t>(a.cpu_pages, pages.size());
      const auto t0 = std::chrono::steady_clock::now();
      for (size_t k = 0; k < n; ++k)
        if (auto page = compose_page_reference(packed[i], pages[k]); !page) return page.error();
      row.cpu_pages_s = double(n) / seconds_since(t0);
      row.cpu_mtexel_s = row.cpu_pages_s * texels_per_page * 1e-6;
    }
  }
  return rows;
}

// Rows 0..5: the methods; 6..11: the same with hex-tiling on every material it applies to.
double print_rows(const char* title, const std::vector<Row>& rows, bool cpu) {
  constexpr size_t k_methods = std::size(k_all_methods);
  const double blend = rows[1].gpu_pages_s;
  std::printf("\n%s\n%-10s %12s %12s %12s %12s %10s\n", title, "method", "GPU pages/s", "GPU Mtex/s", "CPU pages/s",
              "CPU Mtex/s", "GPU/blend");
  for (size_t i = 0; i < k_methods; ++i) {
    const Row& r = rows[i];
    std::printf("%-10s %12.1f %12.2f %12.3f %12.3f %9.1f%%\n", r.method.c_str(), r.gpu_pages_s, r.gpu_mtexel_s,
                r.cpu_pages_s, r.cpu_mtexel_s, 100.0 * r.gpu_pages_s / blend);
  }
  const Row& last = rows[k_methods - 1];
  const double ratio = last.gpu_pages_s / blend;
  std::printf("FBPB+DPT2 / blend-map throughput (GPU): %.1f%% (target >= 90%%)\n", 100.0 * ratio);
  if (cpu) std::printf("GPU / CPU-reference speed, FBPB+DPT2: %.1fx\n", last.gpu_pages_s / last.cpu_pages_s);
  std::printf("Hex-tiling on every material it applies to (not FBPB layers above the base), cost per page:\n");
  for (size_t i = 0; i < k_methods && k_methods + i < rows.size(); ++i) {
    const Row &r = rows[i], &h = rows[k_methods + i];
    std::printf("%-10s %12.1f pages/s with hex, %6.2fx the time without (target <= 1.5x)\n", r.method.c_str(),
                h.gpu_pages_s, r.gpu_pages_s / h.gpu_pages_s);
  }
  return ratio;
}

// Repetition: the luminance correlation of a composed region with itself at a lag of one tile
// period (1 for a plainly tiled texture), with and without hex-tiling. One material, the
// scene's `material`, alone as the base; pages of mip `mip` composed on the GPU.
Result<std::pair<double, double>> lag_period_correlation(vk::Context& g, const SceneAssets& assets, size_t material,
                                                         uint32_t mip) {
  SceneDesc d = assets.desc;
  d.materials = {d.materials.at(material)};
  d.materials[0].weight = WeightDesc{};
  d.materials[0].mode = Mode::BlendMap;
  auto one = load_scene_assets(d);
  if (!one) return one.error();
  const VtConfig& vt = d.vt;
  const double period = d.materials[0].period_texels / double(1u << mip);  // texels of mip `mip`
  const int lag = int(std::lround(period));
  const int side = int(vt.page_texels) * int(std::ceil(2.0 * period / double(vt.page_texels) + 1.0));
  const uint32_t n = uint32_t(side) / vt.page_texels;
  std::vector<PageId> pages;
  for (uint32_t y = 0; y < n; ++y)
    for (uint32_t x = 0; x < n; ++x) pages.push_back(PageId{mip, 3 + x, 5 + y});
  double out[2];
  for (int hex = 0; hex < 2; ++hex) {
    ComposeOptions o;
    o.hex = hex == 1;
    auto packed = pack_scene(one.value(), o);
    if (!packed) return packed.error();
    if (auto l = packed->load_all(); !l) return l.error();
    auto composer = GpuComposer::create(g, packed.value(), uint32_t(pages.size()));
    if (!composer) return composer.error();
    auto composed = composer.value()->compose_pages(pages);
    if (!composed) return composed.error();
    std::vector<double> lum(size_t(side) * size_t(side));
    const uint32_t slot = vt.slot_texels(), b = vt.border_texels;
    for (size_t i = 0; i < pages.size(); ++i) {
      const std::vector<uint8_t>& px = composed.value()[i];
      const uint32_t ox = uint32_t(i % n) * vt.page_texels, oy = uint32_t(i / n) * vt.page_texels;
      for (uint32_t y = 0; y < vt.page_texels; ++y)
        for (uint32_t x = 0; x < vt.page_texels; ++x) {
          const uint8_t* t = &px[(size_t(y + b) * slot + (x + b)) * 4];
          lum[size_t(oy + y) * size_t(side) + (ox + x)] = 0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2];
        }
    }
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, cnt = 0;
    for (int y = 0; y < side; ++y)
      for (int x = 0; x + lag < side; ++x) {
        const double u = lum[size_t(y) * size_t(side) + size_t(x)], v = lum[size_t(y) * size_t(side) + size_t(x + lag)];
        sx += u, sy += v, sxx += u * u, syy += v * v, sxy += u * v, cnt += 1;
      }
    const double cov = sxy / cnt - (sx / cnt) * (sy / cnt);
    const double var = std::sqrt(std::max(0.0, (sxx / cnt - (sx / cnt) * (sx / cnt)) * (syy / cnt - (sy / cnt) * (sy / cnt))));
    out[hex] = var > 0 ? cov / var : 0.0;
  }
  return std::make_pair(out[0], out[1]);
}

int run_bench_compose(const BenchComposeArgs& a) {
  const char* cmd = "bench compose";
  if (a.pages < 1 || a.pages > 256) return fail(cmd, "--pages: must be between 1 and 256", 2);
  if (a.repeats < 1 || a.repeats > 1000) return fail(cmd, "--repeats: must be between 1 and 1000", 2);
  if (auto problem = output_collision({{"--json", a.json_out}}, {{"--scene", a.scene}})) return fail(cmd, *problem, 2);
  auto assets = load_scene_and_assets(a.scene);
  if (!assets) return fail(cmd, assets.error().message, 2);
  if (auto problem = output_in_scene({{"--json", a.json_out}}, assets->desc)) return fail(cmd, *problem, 2);
  // A benchmark times composition, not first-use loading: read every material up front.
  if (auto loaded = assets->materials->load_all(); !loaded) return fail(cmd, loaded.error().message, 2);
  const VtConfig& vt = assets->desc.vt;
  if (a.mip >= vt.mip_count()) return fail(cmd, "--mip: must be below " + std::to_string(vt.mip_count()), 2);

  // Two page sets: the most transition-rich block of the terrain (worst case: every material
  // present, where the methods differ most) and pages spread over the whole terrain (what a
  // flythrough asks for, where per-page material culling pays).
  const int side = int(std::ceil(std::sqrt(double(a.pages)))) * int(vt.page_texels);
  const Region region = interesting_region(assets.value(), a.mip, side, side);
  std::vector<PageId> dense = pages_covering(vt, region);
  dense.resize(std::min<size_t>(dense.size(), a.pages));
  std::vector<PageId> spread;
  const uint64_t n = vt.pages_per_side(a.mip);
  for (uint32_t i = 0; spread.size() < dense.size(); ++i) {
    const uint32_t h = gpu::tvt_hash_coord(int64_t(i), 0, 0x5eedu);
    spread.push_back(PageId{a.mip, uint32_t((h & 0xffffu) % n), uint32_t((h >> 16) % n)});
  }
  const double texels_per_page = double(vt.slot_texels()) * vt.slot_texels();

  auto ctx = gpu_context(a.gpu_name);
  if (!ctx) return fail(cmd, ctx.error().message, 1);
  std::vector<PackedScene> packed;
  for (bool hex : {false, true})
    for (Method method : k_all_methods) {
      ComposeOptions o = options_for(method);
      o.hex = hex;
      auto p = pack_scene(assets.value(), o);
      if (!p) return fail(cmd, p.error().message, 2);
      packed.push_back(std::move(p.value()));
    }
  auto composer = GpuComposer::create(*ctx.value(), packed[0], uint32_t(dense.size()));
  if (!composer) return fail(cmd, composer.error().message, 1);

  std::printf("terravt bench compose: %zu pages of %ux%u texels (P=%u + 2x%u border), mip %u, device %s, %d rounds\n",
              dense.size(), vt.slot_texels(), vt.slot_texels(), vt.page_texels, vt.border_texels, a.mip,
              ctx.value()->device_name().c_str(), a.repeats);
  auto measured_dense = measure(*composer.value(), packed, dense, a, texels_per_page);
  if (!measured_dense) return fail(cmd, measured_dense.error().message, 1);
  const std::vector<Row>& rows_dense = measured_dense.value();
  const double ratio_dense = print_rows("Transition-rich pages (every material present):", rows_dense, !a.skip_cpu);
  auto measured_spread = measure(*composer.value(), packed, spread, a, texels_per_page);
  if (!measured_spread) return fail(cmd, measured_spread.error().message, 1);
  const std::vector<Row>& rows_spread = measured_spread.value();
  const double ratio_spread = print_rows("Pages spread over the terrain (as a flythrough requests them):", rows_spread, !a.skip_cpu);

  // The scene as written (each material its own mode and hex-tiling, what `render` composes)
  // under the direct and the prefiltered strategy, with hex-tiling as the scene says and off:
  // what the strategy costs at this mip, on the spread pages.
  std::vector<PackedScene> as_written;
  for (bool hex_off : {false, true})
    for (bool prefiltered : {false, true}) {
      ComposeOptions o;
      o.prefiltered = prefiltered;
      if (hex_off) o.hex = false;
      auto p = pack_scene(assets.value(), o);
      if (!p) return fail(cmd, p.error().message, 2);
      as_written.push_back(std::move(p.value()));
    }
  BenchComposeArgs gpu_only = a;
  gpu_only.skip_cpu = true;
  auto measured_scene = measure(*composer.value(), as_written, spread, gpu_only, texels_per_page,
                                {"direct", "prefiltered", "direct no-hex", "prefiltered no-hex"});
  if (!measured_scene) return fail(cmd, measured_scene.error().message, 1);
  const std::vector<Row>& rows_scene = measured_scene.value();
  std::printf("\nThe scene as written (each material its own mode), spread pages, by mip strategy (mip 0 is direct under "
              "both):\n%-12s %12s %14s %12s %14s\n",
              "strategy", "pages/s", "vs direct", "no-hex p/s", "vs direct");
  for (int k = 0; k < 2; ++k)
    std::printf("%-12s %12.1f %13.2fx %12.1f %13.2fx\n", rows_scene[k].method.c_str(), rows_scene[k].gpu_pages_s,
                rows_scene[0].gpu_pages_s / rows_scene[k].gpu_pages_s, rows_scene[2 + k].gpu_pages_s,
                rows_scene[2].gpu_pages_s / rows_scene[2 + k].gpu_pages_s);

  // Repetition of each material alone, at a lag of its period (mip 1 keeps the region small).
  std::vector<std::pair<std::string, std::pair<double, double>>> repetition;
  std::printf("\nRepetition: luminance correlation at a lag of one tile period (each material alone, mip 1; "
              "1 = exact repeat; target: at least halved):\n");
  for (size_t m = 0; m < assets->desc.materials.size(); ++m) {
    auto c = lag_period_correlation(*ctx.value(), assets.value(), m, 1);
    if (!c) return fail(cmd, c.error().message, 1);
    repetition.emplace_back(assets->desc.materials[m].name, c.value());
    std::printf("  %-10s tiled %.3f   hex %.3f   (%.2fx)\n", assets->desc.materials[m].name.c_str(), c->first, c->second,
                c->first != 0 ? c->second / c->first : 0.0);
  }

  if (!a.json_out.empty()) {
    nlohmann::json j;
    j["device"] = ctx.value()->device_name();
    for (const auto& [name, c] : repetition) j["repetition_lag_period"][name] = {{"tiled", c.first}, {"hex", c.second}};
    j["pages"] = dense.size();
    j["slot_texels"] = vt.slot_texels();
    j["mip"] = a.mip;
    j["rounds"] = a.repeats;
    auto table = [](const std::vector<Row>& rows) {
      nlohmann::json t;
      for (const Row& r : rows)
        t[r.method] = {{"gpu_pages_per_s", r.gpu_pages_s}, {"gpu_mtexel_per_s", r.gpu_mtexel_s},
                       {"cpu_pages_per_s", r.cpu_pages_s}, {"cpu_mtexel_per_s", r.cpu_mtexel_s}};
      return t;
    };
    j["transition_rich"] = table(rows_dense);
    j["spread"] = table(rows_spread);
    j["fbpb_dpt2_over_blendmap"] = {{"transition_rich", ratio_dense}, {"spread", ratio_spread}};
    j["scene_as_written_spread"] = {
        {"direct", {{"gpu_pages_per_s", rows_scene[0].gpu_pages_s}, {"gpu_pages_per_s_no_hex", rows_scene[2].gpu_pages_s}}},
        {"prefiltered",
         {{"gpu_pages_per_s", rows_scene[1].gpu_pages_s}, {"gpu_pages_per_s_no_hex", rows_scene[3].gpu_pages_s}}}};
    if (auto w = write_text_file(a.json_out, j.dump(2) + "\n"); !w) return fail(cmd, "--json: " + w.error().message, 1);
  }
  return 0;
}

struct BenchMipsArgs {
  std::string scene;
  std::string gpu_name;
  std::vector<std::string> methods = {"fbpb+dpt2"};
  std::vector<uint32_t> mips = {1, 2, 3};
  std::string json_out;  // and an SVG of PSNR against cost beside it (svg_out, or the .json's name as .svg)
  std::string svg_out;
  uint32_t pages = 2;
  int repeats = 2;
  uint32_t max_supersample = 64;  // the largest supersample:S measured
  bool cost_only = false;  // time the strategies, skip the ground truth (no PSNR, no verdict, no plot)
};

// PSNR in dB of the RGB channels of two equally sized RGBA8 buffers (99 dB when identical).
double psnr_rgb(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
  double se = 0;
  size_t n = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (i % 4 == 3) continue;
    const double d = double(a[i]) - double(b[i]);
    se += d * d;
    ++n;
  }
  if (se == 0) return 99.0;
  return 10.0 * std::log10(255.0 * 255.0 / (se / double(n)));
}

// The quality target of the default mip strategy: this PSNR against the ground truth at no
// more than this multiple of the direct composition's time.
constexpr double k_mips_target_db = 35.0, k_mips_target_cost = 2.0;

// Mip strategies of docs/composition.md against the ground truth: the box-filter pyramid of
// the level-0 composition (streaming/pyramid.h, what `bake --pyramid filtered` stores), built
// from the 4^m level-0 pages under each page. Error (over payload texels) and cost side by side.
int run_bench_mips(const BenchMipsArgs& a) {
  const char* cmd = "bench mips";
  std::vector<Method> methods;
  for (const std::string& name : a.methods) {
    const auto method = method_from_string(name);
    if (!method) return fail(cmd, "--method: unknown method '" + name + "' (linear, blendmap, fbpb, dpt1, dpt2, fbpb+dpt2)", 2);
    methods.push_back(*method);
  }
  if (methods.empty()) return fail(cmd, "--method: give at least one method", 2);
  if (a.pages < 1 || a.pages > 64) return fail(cmd, "--pages: must be between 1 and 64", 2);
  if (a.repeats < 1 || a.repeats > 100) return fail(cmd, "--repeats: must be between 1 and 100", 2);
  if (a.cost_only && !a.svg_out.empty())
    return fail(cmd, "--svg: the plot is PSNR against cost, and --cost-only measures no PSNR; leave out one of them", 2);
  std::string svg_out = a.svg_out;
  if (svg_out.empty() && !a.json_out.empty() && !a.cost_only)
    svg_out = std::filesystem::path(a.json_out).replace_extension(".svg").string();
  // The plot's flag as the user sees it: given, or the --json name as .svg.
  const std::string svg_flag = a.svg_out.empty() ? "--svg (the --json name as .svg; pass --svg to move it)" : "--svg";
  const FlaggedPaths outputs = {{"--json", a.json_out}, {svg_flag, svg_out}};
  if (auto problem = output_collision(outputs, {{"--scene", a.scene}})) return fail(cmd, *problem, 2);
  for (const auto& [flag, path] : outputs)
    if (!path.empty())
      if (auto s = check_output_file(flag, path, true); !s) return fail(cmd, s.error().message, 2);
  auto assets = load_scene_and_assets(a.scene);
  if (!assets) return fail(cmd, assets.error().message, 2);
  if (auto problem = output_in_scene(outputs, assets->desc)) return fail(cmd, *problem, 2);
  // A benchmark times composition, not first-use loading: read every material up front.
  if (auto loaded = assets->materials->load_all(); !loaded) return fail(cmd, loaded.error().message, 2);
  const VtConfig& vt = assets->desc.vt;
  for (uint32_t m : a.mips)
    if (m < 1 || m > 6 || m >= vt.mip_count())
      return fail(cmd, "--mips: each mip must be between 1 and 6 (ground truth filters 4^m level-0 pages) and below " +
                           std::to_string(vt.mip_count()), 2);
  auto ctx = gpu_context(a.gpu_name);
  if (!ctx) return fail(cmd, ctx.error().message, 1);

  nlohmann::json j;
  j["device"] = ctx.value()->device_name();
  j["pages_per_mip"] = a.pages;
  if (a.cost_only) j["cost_only"] = true;
  std::vector<PlotPanel> panels;
  for (Method method : methods) {
    auto packed = pack_scene(assets.value(), options_for(method));
    if (!packed) return fail(cmd, packed.error().message, 2);
    auto composer = GpuComposer::create(*ctx.value(), packed.value(), std::max(a.pages, 32u));  // 32: the truth's level-0 batches
    if (!composer) return fail(cmd, composer.error().message, 1);
    GpuComposer& c = *composer.value();
    const std::string method_name(to_string(method));
    PlotPanel panel{method_name, {}};
    std::map<int, PlotSeries> curves;  // strategy (in table order) -> its points over the mips
    std::string target_met, target_missed;  // the default strategy against the quality target, per mip

    std::printf("terravt bench mips: method %s, %u pages per mip, device %s\n\n", method_name.c_str(), a.pages,
                ctx.value()->device_name().c_str());
    std::printf("%4s %-16s %12s %10s %12s\n", "mip", "strategy", "ms/page", "PSNR dB", "cost vs direct");
    for (uint32_t m : a.mips) {
      const int side = int(std::ceil(std::sqrt(double(a.pages)))) * int(vt.page_texels);
      std::vector<PageId> pages = pages_covering(vt, interesting_region(assets.value(), m, side, side));
      pages.resize(std::min<size_t>(pages.size(), a.pages));
      std::vector<MipStrategy> strategies = {MipStrategy{}, MipStrategy{1, true}};
      for (uint32_t s = 2; s <= (1u << m) && s <= a.max_supersample; s *= 2)  // 2^m: every level-0 texel centre
        strategies.push_back(MipStrategy{s});
      std::vector<std::vector<std::vector<uint8_t>>> results;
      std::vector<double> best(strategies.size(), 1e300);
      for (int round = 0; round <= a.repeats; ++round)
        for (size_t i = 0; i < strategies.size(); ++i) {
          gpu::TvtComposeParams params = packed->params;
          params.supersample = int(strategies[i].supersample);
          params.prefiltered = strategies[i].prefiltered ? 1 : 0;
          c.set_params(params);
          if (round == 0) {
            auto composed = c.compose_pages(pages);  // also the warm-up; the scene is loaded
            if (!composed) return fail(cmd, composed.error().message, 1);
            results.push_back(std::move(composed.value()));
            continue;
          }
          auto t = c.time_batch(pages, 1);
          if (!t) return fail(cmd, t.error().message, 1);
          best[i] = std::min(best[i], t.value());
        }
      // The truth (not with --cost-only): level-0 pages composed directly (32 at a time),
      // box-filtered up to mip m.
      std::vector<std::vector<uint8_t>> truth;
      double truth_s = 0.0;
      unsigned long long truth_pages = 0;
      if (!a.cost_only) {
        gpu::TvtComposeParams level0 = packed->params;
        level0.supersample = 1;
        level0.prefiltered = 0;
        StoreDesc desc;
        desc.vt = vt;
        FilteredPyramid pyramid(desc, [&](std::span<const PageId> ids, std::vector<std::vector<uint8_t>>& out) -> Status {
          c.set_params(level0);
          auto composed = c.compose_pages(ids);
          if (!composed) return composed.error();
          out = std::move(composed.value());
          return Ok{};
        }, PageLookup{}, FilteredPyramid::Options{});
        const auto t0 = std::chrono::steady_clock::now();
        pyramid.prepare(pages, false);
        for (const PageId& page : pages) {
          auto t = pyramid.payload(page);
          if (!t) return fail(cmd, t.error().message, 1);
          truth.push_back(std::move(t.value()));
        }
        truth_s = seconds_since(t0);
        truth_pages = pyramid.composed_pages();
      }
      for (size_t i = 0; i < strategies.size(); ++i) {
        const std::string name = to_string(strategies[i]);
        const double ms = 1000.0 * best[i] / double(pages.size()), cost = best[i] / best[0];
        nlohmann::json& row = j["methods"][method_name][std::to_string(m)][name];
        row = {{"ms_per_page", ms}, {"cost_vs_direct", cost}};
        if (a.cost_only) {  // the costs alone, to two places: what comparing two builds reads
          std::printf("%4u %-16s %12.2f %10s %11.2fx\n", m, name.c_str(), ms, "-", cost);
          continue;
        }
        double psnr = 0;
        for (size_t p = 0; p < pages.size(); ++p) psnr += psnr_rgb(page_payload(vt, results[i][p]), truth[p]);
        psnr /= double(pages.size());
        row["psnr_db"] = psnr;
        std::printf("%4u %-16s %12.2f %10.2f %11.1fx\n", m, name.c_str(), ms, psnr, cost);
        const MipStrategy& st = strategies[i];
        if (st.prefiltered) {
          char verdict[64];
          const bool met = psnr >= k_mips_target_db && cost <= k_mips_target_cost;
          std::snprintf(verdict, sizeof verdict, met ? "%u" : "%u (%.2f dB, %.2fx)", m, psnr, cost);
          std::string& list = met ? target_met : target_missed;
          list += (list.empty() ? "" : ", ") + std::string(verdict);
          j["methods"][method_name][std::to_string(m)]["target_met"] = met;
        }
        PlotSeries& curve = curves[st.prefiltered ? 1 : st.supersample <= 1 ? 0 : 1 + std::countr_zero(st.supersample)];
        curve.name = name;
        curve.points.push_back(PlotPoint{cost, psnr, "m" + std::to_string(m)});
      }
      if (a.cost_only) continue;
      std::printf("%4u %-16s %12.2f %10s %11.1fx   (%llu level-0 pages composed, box-filtered; timed once)\n", m,
                  "ground truth", 1000.0 * truth_s / double(pages.size()), "-", truth_s / best[0], truth_pages);
      j["methods"][method_name][std::to_string(m)]["ground_truth"] = {{"ms_per_page", 1000.0 * truth_s / double(pages.size())},
                                                                        {"cost_vs_direct", truth_s / best[0]}};
    }
    for (auto& [s, curve] : curves) panel.series.push_back(std::move(curve));
    panels.push_back(std::move(panel));
    const std::string verdict = a.cost_only ? "not judged (--cost-only: no ground truth)"
                                            : "met at mips " + (target_met.empty() ? "-" : target_met) + "; not met at mips " +
                                                  (target_missed.empty() ? "-" : target_missed);
    std::printf("target (prefiltered, the default: >= %.0f dB at <= %.0fx direct): %s\n\n", k_mips_target_db,
                k_mips_target_cost, verdict.c_str());
  }
  if (!a.json_out.empty())
    if (auto w = write_text_file(a.json_out, j.dump(2) + "\n"); !w) return fail(cmd, "--json: " + w.error().message, 1);
  if (!svg_out.empty()) {
    PlotLayout layout;
    layout.title = "Mip strategies: PSNR against cost";
    layout.subtitle = "truth: the box-filtered level-0 composition; " + std::to_string(a.pages) + " pages per mip on " +
                      ctx.value()->device_name();
    layout.x_label = "cost per page relative to direct composition (log scale); points labelled by mip";
    layout.y_label = "PSNR dB";
    layout.y_min = 15;
    layout.y_max = 60;
    layout.target_y = k_mips_target_db;
    layout.target_label = std::to_string(int(k_mips_target_db)) + " dB target";
    if (auto w = write_text_file(svg_out, svg_plot(layout, panels)); !w) return fail(cmd, "--svg: " + w.error().message, 1);
  }
  return 0;
}

const CommandRegistrar k_register{
    "bench", "Benchmarks: compose (throughput per method), mips (mip strategies vs ground truth), frame (VT vs plain/direct)", 90, [](CLI::App& app) -> RunFn {
      app.require_subcommand(1);
      auto a = std::make_shared<BenchComposeArgs>();
      CLI::App* c = app.add_subcommand("compose", "Pages/s and Mtexel/s of every method, GPU vs CPU reference");
      c->add_option("--scene", a->scene, "Scene JSON file (default: the built-in scene)")->check(regular_file());
      c->add_option("--pages", a->pages, "Pages per GPU batch")->capture_default_str();
      c->add_option("--cpu-pages", a->cpu_pages, "Pages per method for the CPU reference")->capture_default_str();
      c->add_option("--repeats", a->repeats, "Interleaved timing rounds (each method keeps its fastest batch)")->capture_default_str();
      c->add_option("--mip", a->mip, "Mip level of the pages")->capture_default_str();
      c->add_option("--gpu", a->gpu_name, "Vulkan device name substring or index");
      c->add_option("--json", a->json_out, "Also write the figures as JSON")->check(output_file());
      c->add_flag("--skip-cpu", a->skip_cpu, "Do not time the CPU reference");
      auto m = std::make_shared<BenchMipsArgs>();
      CLI::App* mc = app.add_subcommand("mips", "Direct, prefiltered and supersampled mip composition against the ground truth: the box-filter pyramid of level-0 pages");
      mc->add_option("--scene", m->scene, "Scene JSON file (default: the built-in scene)")->check(regular_file());
      mc->add_option("--method", m->methods, "Transition methods, comma-separated (one panel each in the SVG)")
          ->delimiter(',')
          ->capture_default_str();
      mc->add_option("--json", m->json_out, "Write the figures as JSON (and the SVG plot beside it)");
      mc->add_option("--svg", m->svg_out, "Write the PSNR-against-cost plot here (default: the --json name as .svg)");
      mc->add_option("--mips", m->mips, "Mip levels (1..6)")->delimiter(',');
      mc->add_option("--pages", m->pages, "Pages per mip")->capture_default_str();
      mc->add_option("--repeats", m->repeats, "Interleaved timing rounds")->capture_default_str();
      mc->add_option("--max-supersample", m->max_supersample, "Largest supersample:S measured (a power of two, 2..64)")
          ->check(CLI::Range(2u, 64u))
          ->capture_default_str();
      mc->add_flag("--cost-only", m->cost_only,
                   "Time the strategies only: no ground truth (minutes at mips 5-6), so no PSNR, verdict or plot");
      mc->add_option("--gpu", m->gpu_name, "Vulkan device name substring or index");
      auto fr = std::make_shared<BenchFrameArgs>();
      CLI::App* fc = app.add_subcommand(
          "frame", "VT frame cost vs plain texture, direct splatting and an untextured pass; feedback variants; "
                   "anisotropy; time-to-sharp; memory vs V");
      fc->add_option("--scene", fr->scene, "Scene JSON file (default: the built-in scene)")->check(regular_file());
      fc->add_option("--methods", fr->methods, "Methods")->delimiter(',');
      fc->add_option("--width", fr->width, "Image width")->capture_default_str();
      fc->add_option("--height", fr->height, "Image height")->capture_default_str();
      fc->add_option("--frames", fr->frames, "Frames of the flythrough")->capture_default_str();
      fc->add_option("--fps", fr->fps, "Camera path frames per second")->check(finite_range(1e-3, 1000.0))->capture_default_str();
      fc->add_option("--cache-slots", fr->cache_slots, "Physical cache pages of the flythrough")->capture_default_str();
      fc->add_option("--page-budget", fr->page_budget, "Pages composed per frame")->capture_default_str();
      fc->add_option("--feedback-divisor", fr->feedback_divisor, "N: feedback at 1/N resolution")->capture_default_str();
      fc->add_option("--plain-log2", fr->plain_log2, "Plain texture size: 2^n texels per side")->capture_default_str();
      fc->add_option("--poses", fr->poses, "Static poses of the steady-state comparison")->capture_default_str();
      fc->add_option("--rounds", fr->rounds, "Timings per pass and pose (fastest counts)")->capture_default_str();
      fc->add_option("--anisotropy", fr->anisotropy, "Taps of the anisotropic VT variant")->capture_default_str();
      fc->add_option("--brilinear-band", fr->brilinear_band, "Blend band of the brilinear VT variant (0 bilinear .. 1 trilinear)")
          ->capture_default_str();
      fc->add_option("--json", fr->json_out, "Also write the figures as JSON")->check(output_file());
      fc->add_flag("--static-only", fr->static_only, "Only the steady-state comparison (no flythrough loops)");
      add_mip_strategy_option(*fc, fr->mip_strategy);
      fc->add_option("--gpu", fr->gpu_name, "Vulkan device name substring or index");
      return [a, c, m, mc, fr, fc] {
        if (fc->parsed()) return run_bench_frame(*fr);
        if (c->parsed()) return run_bench_compose(*a);
        if (mc->parsed()) return run_bench_mips(*m);
        return 2;
      };
    }};

}  // namespace
}  // namespace tvt::cli
