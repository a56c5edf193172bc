// `terravt bench compose`: page-composition throughput of every method, GPU compute vs the
// CPU reference, measured side by side in one run (speed is reported as ratios too, since
// absolute numbers on lavapipe say little about a real GPU).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>

#include "compose/packed_scene.h"
#include "compose/reference_compositor.h"
#include "compose/region.h"
#include "render/gpu_composer.h"
#include "tools/cli_common.h"
#include "tools/commands.h"

namespace tvt::cli {
namespace {

struct BenchComposeArgs {
  std::string scene;
  std::string json_out;
  std::string gpu_name;
  uint32_t pages = 32;      // GPU batch size
  uint32_t cpu_pages = 2;   // CPU reference pages per method
  int repeats = 3;
  uint32_t mip = 0;
  bool skip_cpu = false;
};

struct Row {
  std::string method;
  double gpu_pages_s = 0, gpu_mtexel_s = 0, cpu_pages_s = 0, cpu_mtexel_s = 0;
};

int run_bench_compose(const BenchComposeArgs& a) {
  const char* cmd = "bench compose";
  if (a.pages < 1 || a.pages > 256) return fail(cmd, "--pages: must be between 1 and 256", 2);
  if (a.repeats < 1 || a.repeats > 1000) return fail(cmd, "--repeats: must be between 1 and 1000", 2);
  auto assets = load_scene_and_assets(a.scene);
  if (!assets) return fail(cmd, assets.error().message, 2);
  const VtConfig& vt = assets->desc.vt;
  if (a.mip >= vt.mip_count()) return fail(cmd, "--mip: must be below " + std::to_string(vt.mip_count()), 2);

  // Pages from the most transition-rich part of the terrain: where the methods differ.
  const int side = int(std::ceil(std::sqrt(double(a.pages)))) * int(vt.page_texels);
  const Region region = interesting_region(assets.value(), a.mip, side, side);
  std::vector<PageId> pages = pages_covering(vt, region);
  pages.resize(std::min<size_t>(pages.size(), a.pages));
  const double texels_per_page = double(vt.slot_texels()) * vt.slot_texels();

  vk::ContextOptions co;
  co.device = a.gpu_name;
  auto ctx = vk::Context::create(co);
  if (!ctx) return fail(cmd, ctx.error().message, 1);
  std::unique_ptr<GpuComposer> composer;

  std::printf("terravt bench compose: %zu pages of %ux%u texels (P=%u + 2x%u border), mip %u, device %s\n",
              pages.size(), vt.slot_texels(), vt.slot_texels(), vt.page_texels, vt.border_texels, a.mip,
              ctx.value()->device_name().c_str());
  std::vector<Row> rows;
  for (Method method : k_all_methods) {
    auto packed = pack_scene(assets.value(), options_for(method));
    if (!packed) return fail(cmd, packed.error().message, 2);
    if (!composer) {
      auto c = GpuComposer::create(*ctx.value(), packed.value(), uint32_t(pages.size()));
      if (!c) return fail(cmd, c.error().message, 1);
      composer = std::move(c.value());
    }
    composer->set_params(packed->params);
    composer->time_batch(pages, 1);  // warm-up (pipeline, caches)
    const double gpu_s = composer->time_batch(pages, a.repeats);
    Row row;
    row.method = std::string(to_string(method));
    row.gpu_pages_s = double(pages.size()) / gpu_s;
    row.gpu_mtexel_s = row.gpu_pages_s * texels_per_page * 1e-6;
    if (!a.skip_cpu) {
      const size_t n = std::min<size_t>(a.cpu_pages, pages.size());
      const auto t0 = std::chrono::steady_clock::now();
      for (size_t i = 0; i < n; ++i) (void)compose_page_reference(packed.value(), pages[i]);
      const double cpu_s = seconds_since(t0);
      row.cpu_pages_s = double(n) / cpu_s;
      row.cpu_mtexel_s = row.cpu_pages_s * texels_per_page * 1e-6;
    }
    rows.push_back(row);
  }

  const double blend = rows[1].gpu_pages_s;
  std::printf("\n%-10s %12s %12s %12s %12s %10s\n", "method", "GPU pages/s", "GPU Mtex/s", "CPU pages/s", "CPU Mtex/s",
              "GPU/blend");
  for (const Row& r : rows)
    std::printf("%-10s %12.1f %12.2f %12.3f %12.3f %9.1f%%\n", r.method.c_str(), r.gpu_pages_s, r.gpu_mtexel_s,
                r.cpu_pages_s, r.cpu_mtexel_s, 100.0 * r.gpu_pages_s / blend);
  const double ratio = rows.back().gpu_pages_s / blend;
  std::printf("\nFBPB+DPT2 / blend-map throughput (GPU): %.1f%% (target >= 90%%; the DPT paper measured 95%% in fragment shading)\n",
              100.0 * ratio);
  if (!a.skip_cpu)
    std::printf("GPU / CPU-reference speed-up, FBPB+DPT2: %.0fx\n", rows.back().gpu_pages_s / rows.back().cpu_pages_s);

  if (!a.json_out.empty()) {
    nlohmann::json j;
    j["device"] = ctx.value()->device_name();
    j["pages"] = pages.size();
    j["slot_texels"] = vt.slot_texels();
    j["mip"] = a.mip;
    for (const Row& r : rows)
      j["methods"][r.method] = {{"gpu_pages_per_s", r.gpu_pages_s}, {"gpu_mtexel_per_s", r.gpu_mtexel_s},
                                {"cpu_pages_per_s", r.cpu_pages_s}, {"cpu_mtexel_per_s", r.cpu_mtexel_s}};
    j["fbpb_dpt2_over_blendmap"] = ratio;
    std::ofstream f(a.json_out);
    if (!f) return fail(cmd, "--json: cannot write " + a.json_out, 1);
    f << j.dump(2) << "\n";
  }
  return 0;
}

const CommandRegistrar k_register{
    "bench", "Benchmarks (compose: page composition throughput per method)", 90, [](CLI::App& app) -> RunFn {
      app.require_subcommand(1);
      auto a = std::make_shared<BenchComposeArgs>();
      CLI::App* c = app.add_subcommand("compose", "Pages/s and Mtexel/s of every method, GPU vs CPU reference");
      c->add_option("--scene", a->scene, "Scene JSON file (default: the built-in scene)")->check(CLI::ExistingFile);
      c->add_option("--pages", a->pages, "Pages per GPU batch")->capture_default_str();
      c->add_option("--cpu-pages", a->cpu_pages, "Pages per method for the CPU reference")->capture_default_str();
      c->add_option("--repeats", a->repeats, "Timed GPU batches per method")->capture_default_str();
      c->add_option("--mip", a->mip, "Mip level of the pages")->capture_default_str();
      c->add_option("--gpu", a->gpu_name, "Vulkan device name substring or index");
      c->add_option("--json", a->json_out, "Also write the figures as JSON");
      c->add_flag("--skip-cpu", a->skip_cpu, "Do not time the CPU reference");
      return [a, c] { return c->parsed() ? run_bench_compose(*a) : 2; };
    }};

}  // namespace
}  // namespace tvt::cli
