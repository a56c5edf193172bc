// `terravt compose`: a region of the terrain at one mip, composed by each transition method,
// side by side in one labelled image — the comparison the papers' figures make.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

#include "compose/label_font.h"
#include "compose/packed_scene.h"
#include "compose/reference_compositor.h"
#include "compose/region.h"
#include "composer/gpu_composer.h"
#include "tools/cli_common.h"
#include "tools/commands.h"

namespace tvt::cli {
namespace {

struct ComposeArgs {
  std::string scene;
  std::string out = "compose.png";
  std::string panels_dir;
  std::string device = "gpu";
  std::string gpu_name;
  std::vector<std::string> methods;
  std::vector<int64_t> region;  // x, y, w, h at the chosen mip
  int size = 512;
  uint32_t mip = 0;
  std::string mip_strategy = "prefiltered";
  std::string hex = "scene";
  int columns = 3;
};

// Where --panels puts a method's panel.
std::string panel_path(const std::string& folder, Method method) {
  return (std::filesystem::path(folder) / ("compose-" + std::string(to_string(method)) + ".png")).string();
}

int run_compose(const ComposeArgs& a) {
  const char* cmd = "compose";
  std::vector<Method> methods;
  if (a.methods.empty()) methods.assign(std::begin(k_all_methods), std::end(k_all_methods));
  for (const std::string& m : a.methods) {
    auto parsed = method_from_string(m);
    if (!parsed) return fail(cmd, "--methods: unknown method '" + m + "' (linear, blendmap, fbpb, dpt1, dpt2, fbpb+dpt2)", 2);
    methods.push_back(*parsed);
  }
  if (a.device != "gpu" && a.device != "cpu") return fail(cmd, "--device: must be gpu or cpu, got " + a.device, 2);
  // No output replaces the scene, and the sheet no panel (their locks and panels included).
  FlaggedPaths outputs = {{"--out", a.out}, {"--panels", a.panels_dir}};
  if (!a.panels_dir.empty())
    for (Method method : methods) outputs.push_back({"--panels " + std::string(to_string(method)), panel_path(a.panels_dir, method)});
  if (auto problem = output_collision(outputs, {{"--scene", a.scene}})) return fail(cmd, *problem, 2);
  if (!a.region.empty() && a.region.size() != 4) return fail(cmd, "--region: needs x,y,width,height", 2);
  if (!a.panels_dir.empty() && !std::filesystem::is_directory(a.panels_dir))
    return fail(cmd, "--panels: folder does not exist: " + a.panels_dir, 2);
  // The output is checked and owned before the (possibly long) composition.
  if (auto problem = check_image_output("--out", a.out); !problem.empty()) return fail(cmd, problem, 2);
  auto owned = OutputLock::acquire("--out", a.out);
  if (!owned) return fail(cmd, owned.error().message, 2);
  std::optional<OutputLock> owned_panels;
  if (!a.panels_dir.empty()) {
    auto p = OutputLock::acquire("--panels", a.panels_dir);
    if (!p) return fail(cmd, p.error().message, 2);
    owned_panels.emplace(std::move(p.value()));
  }

  const auto t0 = std::chrono::steady_clock::now();
  auto assets = load_scene_and_assets(a.scene, a.hex);
  if (!assets) return fail(cmd, assets.error().message, 2);
  if (auto problem = output_in_scene(outputs, assets->desc)) return fail(cmd, *problem, 2);
  const VtConfig& vt = assets->desc.vt;
  if (a.mip >= vt.mip_count())
    return fail(cmd, "--mip: must be below " + std::to_string(vt.mip_count()) + " for this scene, got " + std::to_string(a.mip), 2);
  const int64_t mip_size = int64_t(vt.mip_texels(a.mip));
  Region region;
  if (a.region.empty()) {
    region = interesting_region(assets.value(), a.mip, a.size, a.size);
  } else {
    region = Region{a.mip, a.region[0], a.region[1], int(a.region[2]), int(a.region[3])};
    if (region.x < 0 || region.y < 0 || region.width < 1 || region.height < 1 || region.width > 8192 ||
        region.height > 8192 || region.x + region.width > mip_size || region.y + region.height > mip_size)
      return fail(cmd, "--region: must lie inside the " + std::to_string(mip_size) + "^2 texels of mip " +
                           std::to_string(a.mip) + " and be at most 8192 wide",
                  2);
  }
  const std::vector<PageId> pages = pages_covering(vt, region);
  std::printf("scene %s, V = 2^%u, mip %u, region (%lld, %lld) %dx%d, %zu pages per method, %s, mip strategy %s\n",
              assets->desc.source_path.c_str(), vt.log2_size, a.mip, (long long)region.x, (long long)region.y,
              region.width, region.height, pages.size(), a.device.c_str(), a.mip_strategy.c_str());
  for (size_t n = 0; n < assets->materials->size(); ++n)
    if (const std::string& note = assets->materials->info(n).image_note; !note.empty())
      std::printf("  material %zu %s: %s\n", n, assets->desc.materials[n].name.c_str(), note.c_str());

  std::unique_ptr<vk::Context> context;
  std::unique_ptr<GpuComposer> composer;
  std::vector<ImageRGBA8> panels;
  // --panels files written so far: a run that fails later removes them, so the panels and the
  // sheet are written all or none (the sheet last).
  std::vector<std::string> panel_files;
  auto failed = [&](const std::string& message, int code) {
    std::error_code ignored;
    for (const std::string& f : panel_files) std::filesystem::remove(f, ignored);
    return fail(cmd, message, code);
  };
  for (Method method : methods) {
    const ComposeOptions options = options_for(method, parsed_mip_strategy(a.mip_strategy));
    auto packed = pack_scene(assets.value(), options);
    if (!packed) return failed(packed.error().message, 2);
    const auto tm = std::chrono::steady_clock::now();
    std::vector<std::vector<uint8_t>> texels;
    if (a.device == "gpu") {
      if (!context) {
        auto ctx = gpu_context(a.gpu_name);
        if (!ctx) return failed(ctx.error().message + " (use --device cpu for the CPU reference)", 1);
        context = std::move(ctx.value());
        auto c = GpuComposer::create(*context, packed.value(), uint32_t(std::min<size_t>(pages.size(), 64)));
        if (!c) return failed(c.error().message, 1);
        composer = std::move(c.value());
      }
      composer->set_params(packed->params);
      auto composed = composer->compose_pages(pages);
      if (!composed) return failed(composed.error().message, 1);
      texels = std::move(composed.value());
    } else {
      for (const PageId& id : pages) {
        auto page = compose_page_reference(packed.value(), id);
        if (!page) return failed(page.error().message, 1);
        texels.push_back(std::move(page.value()));
      }
    }
    panels.push_back(assemble_region(vt, region, pages, [&](size_t i) -> const std::vector<uint8_t>& { return texels[i]; }));
    std::printf("  %-10s %7.3f s\n", std::string(to_string(method)).c_str(), seconds_since(tm));
    if (!a.panels_dir.empty()) {
      const std::string path = panel_path(a.panels_dir, method);
      auto s = write_image(path, panels.back());
      if (!s) return failed(s.error().message, 1);
      panel_files.push_back(path);
    }
  }

  // Labelled grid of panels with a 4-texel gutter.
  const int cols = std::clamp(a.columns, 1, int(panels.size()));
  const int rows = (int(panels.size()) + cols - 1) / cols;
  const int gap = 4;
  ImageRGBA8 sheet(cols * region.width + (cols + 1) * gap, rows * region.height + (rows + 1) * gap);
  for (size_t t = 3; t < sheet.texels.size(); t += 4) sheet.texels[t] = 255;
  for (size_t i = 0; i < panels.size(); ++i) {
    const int ox = gap + int(i % size_t(cols)) * (region.width + gap), oy = gap + int(i / size_t(cols)) * (region.height + gap);
    for (int y = 0; y < region.height; ++y)
      for (int x = 0; x < region.width; ++x) {
        uint8_t* d = sheet.at(ox + x, oy + y);
        const uint8_t* s = panels[i].at(x, y);
        d[0] = s[0], d[1] = s[1], d[2] = s[2], d[3] = 255;  // height channel is not shown
      }
    draw_label(sheet, ox + 4, oy + 4, to_string(methods[i]), std::max(1, region.width / 256));
  }
  auto s = write_image(a.out, sheet);
  if (!s) return failed(s.error().message, 1);
  std::printf("wrote %s (%dx%d) in %.2f s\n", a.out.c_str(), sheet.width, sheet.height, seconds_since(t0));
  return 0;
}

const CommandRegistrar k_register{
    "compose", "Compose a terrain region with each transition method, side by side", 20, [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<ComposeArgs>();
      app.add_option("--scene", a->scene, "Scene JSON file (default: the built-in scene)")->check(regular_file());
      app.add_option("--out", a->out, "Output image (PNG, EXR, ...)")->capture_default_str();
      app.add_option("--panels", a->panels_dir, "Also write each method's panel into this folder");
      app.add_option("--device", a->device, "gpu (compute shader) or cpu (double-precision reference)")->capture_default_str();
      app.add_option("--gpu", a->gpu_name, "Vulkan device name substring or index (default: TERRAVT_DEVICE / best)");
      app.add_option("--methods", a->methods, "Subset of linear,blendmap,fbpb,dpt1,dpt2,fbpb+dpt2")->delimiter(',');
      app.add_option("--mip", a->mip, "Mip level to compose")->capture_default_str();
      app.add_option("--region", a->region, "x,y,width,height in texels of the mip (default: auto)")->delimiter(',');
      app.add_option("--size", a->size, "Edge of the automatic region in texels")->check(CLI::Range(16, 4096))->capture_default_str();
      add_mip_strategy_option(app, a->mip_strategy);
      add_hex_option(app, a->hex);
      app.add_option("--columns", a->columns, "Panels per row")->check(CLI::Range(1, 16))->capture_default_str();
      return [a] { return run_compose(*a); };
    }};

}  // namespace
}  // namespace tvt::cli
