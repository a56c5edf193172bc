// `terravt metatex`: builds the FBPB meta-texture of a material (docs/metatex.md).
// Everything the user can get wrong is checked before anything is written; exit code 2 for
// bad flags or input, 1 for failures while writing.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "compose/image.h"
#include "compose/metatex.h"
#include "compose/procedural.h"
#include "tools/cli_common.h"
#include "tools/commands.h"

namespace tvt::cli {

namespace {

constexpr int k_max_resolution = 16384;  // offsets are int16 and stay inside ±R

struct MetatexArgs {
  std::string input, height, generator, mask, channel, out, debug;
  uint32_t resolution = 512;
  uint32_t seed = 1;
  double threshold = -1.0;
  bool invert = false;
  bool automatic = false;
  uint32_t min_texels = 8;
  uint32_t erode = 0;
  double blur = 2.0;
};

int usage_error(const std::string& message) {
  std::fprintf(stderr, "terravt metatex: %s\n", message.c_str());
  return 2;
}

int runtime_error(const std::string& message) {
  std::fprintf(stderr, "terravt metatex: %s\n", message.c_str());
  return 1;
}

bool is_power_of_two(int v) { return v > 0 && (v & (v - 1)) == 0; }

struct Material {
  ImageRGBA8 albedo;
  ImageGray8 variation;  // empty: never chips
  bool has_height = false;
  bool has_exact_labels = false;
  FeatureLabels exact_labels;
  std::string source;  // for messages: file name or generator name
};

int load_material(const MetatexArgs& a, Material& m) {
  if (!a.input.empty()) {
    auto albedo = read_image_rgba8(a.input);
    if (!albedo) return usage_error("--input " + albedo.error().message);
    m.albedo = std::move(*albedo);
    m.source = a.input;
    // Height present: an alpha channel that is not constant 255.
    for (size_t i = 3; i < m.albedo.texels.size() && !m.has_height; i += 4) m.has_height = m.albedo.texels[i] != 255;
    if (!a.height.empty()) {
      auto height = read_image_float(a.height);
      if (!height) return usage_error("--height " + height.error().message);
      if (height->width != m.albedo.width || height->height != m.albedo.height)
        return usage_error("--height " + a.height + ": " + std::to_string(height->width) + " x " +
                           std::to_string(height->height) + " texels, but --input is " +
                           std::to_string(m.albedo.width) + " x " + std::to_string(m.albedo.height));
      for (int y = 0; y < m.albedo.height; ++y)
        for (int x = 0; x < m.albedo.width; ++x)
          m.albedo.at(x, y)[3] = uint8_t(std::lround(std::clamp(height->at(x, y, 0), 0.0f, 1.0f) * 255.0f));
      m.has_height = true;
    }
  } else {
    if (!is_known_generator(a.generator))
      return usage_error("--generator " + a.generator + ": unknown generator (sand, grass, rock, mud, cobbles, bricks)");
    if (a.resolution > uint32_t(k_max_resolution) || !is_power_of_two(int(a.resolution)))
      return usage_error("--resolution " + std::to_string(a.resolution) + ": must be a power of two");
    auto generated = generate_material(a.generator, a.resolution, a.seed);
    if (!generated) return usage_error("--generator " + a.generator + ": " + generated.error().message);
    m.albedo = std::move(generated->albedo);
    m.source = "generator " + a.generator;
    m.has_height = true;
    const int r = m.albedo.width;
    if (generated->variation.width == r && generated->variation.height == r) m.variation = std::move(generated->variation);
    if (!a.automatic) {
      // Exact labels; a material without features gets an empty (all background) meta-texture.
      m.has_exact_labels = true;
      FeatureLabels& labels = m.exact_labels;
      labels.resolution = r;
      labels.count = generated->feature_count;
      labels.labels = std::move(generated->feature_labels);
      if (labels.labels.empty()) {
        labels.labels.assign(size_t(r) * size_t(r), -1);
        labels.count = 0;
      }
      if (labels.labels.size() != size_t(r) * size_t(r))
        return runtime_error(m.source + ": returned " + std::to_string(labels.labels.size()) + " labels for " +
                             std::to_string(r) + " x " + std::to_string(r) + " texels");
      for (int32_t l : labels.labels)
        if (l < -1 || (l >= 0 && uint32_t(l) >= labels.count))
          return runtime_error(m.source + ": feature label " + std::to_string(l) + " outside -1.." +
                               std::to_string(int64_t(labels.count) - 1));
    }
  }
  const int w = m.albedo.width, h = m.albedo.height;
  if (w != h || !is_power_of_two(w) || w > k_max_resolution)
    return usage_error(m.source + ": material is " + std::to_string(w) + " x " + std::to_string(h) +
                       " texels; it must be square with a power-of-two side of at most " +
                       std::to_string(k_max_resolution));
  return 0;
}

int run_metatex(const MetatexArgs& a, bool threshold_given, bool channel_given) {
  const auto start = std::chrono::steady_clock::now();
  if (a.input.empty() == a.generator.empty()) return usage_error("give exactly one of --input or --generator");
  if (auto problem = check_image_output("--out", a.out, true); !problem.empty()) return usage_error(problem);
  if (!a.debug.empty())
    if (auto problem = check_image_output("--debug", a.debug, false); !problem.empty()) return usage_error(problem);

  // One process per output: two runs writing the same meta-texture never interleave.
  auto owned = OutputLock::acquire("--out", a.out);
  if (!owned) return usage_error(owned.error().message);
  std::optional<OutputLock> owned_debug;
  if (!a.debug.empty()) {
    auto d = OutputLock::acquire("--debug", a.debug);
    if (!d) return usage_error(d.error().message);
    owned_debug.emplace(std::move(d.value()));
  }

  Material m;
  if (int code = load_material(a, m); code != 0) return code;
  const int r = m.albedo.width;

  FeatureLabels labels;
  uint32_t specks = 0;
  std::string method;
  if (!a.mask.empty()) {
    auto mask_rgba = read_image_rgba8(a.mask);
    if (!mask_rgba) return usage_error("--mask " + mask_rgba.error().message);
    if (mask_rgba->width != r || mask_rgba->height != r)
      return usage_error("--mask " + a.mask + ": " + std::to_string(mask_rgba->width) + " x " +
                         std::to_string(mask_rgba->height) + " texels, but the material is " + std::to_string(r) +
                         " x " + std::to_string(r));
    ImageGray8 mask(r, r);
    for (int y = 0; y < r; ++y)
      for (int x = 0; x < r; ++x) mask.at(x, y) = mask_rgba->at(x, y)[0];
    labels = labels_from_mask(mask, a.min_texels);
    specks = labels_from_mask(mask, 1).count - labels.count;
    method = "hand-made mask " + a.mask;
  } else if (m.has_exact_labels) {
    labels = std::move(m.exact_labels);
    method = "exact labels of " + m.source;
  } else {
    IsolationOptions options;
    const bool use_height = channel_given ? a.channel == "height" : m.has_height;
    options.channel = use_height ? IsolationOptions::Channel::Height : IsolationOptions::Channel::Luminance;
    options.threshold = threshold_given ? a.threshold : -1.0;
    options.invert = a.invert;
    options.min_feature_texels = a.min_texels;
    options.erode_texels = a.erode;
    labels = isolate_features(m.albedo, options);
    IsolationOptions keep_all = options;
    keep_all.min_feature_texels = 1;
    specks = isolate_features(m.albedo, keep_all).count - labels.count;
    method = std::string("automatic on ") + (use_height ? "height" : "luminance") +
             (threshold_given ? ", threshold " + std::to_string(a.threshold) : ", Otsu threshold") +
             (a.invert ? ", inverted" : "") + (a.erode ? ", erode " + std::to_string(a.erode) : "");
  }

  const MetaTexture meta = build_meta_texture(labels, m.variation, a.blur);

  if (auto written = write_meta_texture(a.out, meta); !written) return runtime_error(written.error().message);
  if (!a.debug.empty()) {
    if (auto written = write_image(a.debug, meta_debug_image(meta, m.albedo)); !written) {
      std::error_code ignored;
      std::filesystem::remove(a.out, ignored);  // all or nothing
      return runtime_error(written.error().message);
    }
  }

  std::vector<uint64_t> sizes(labels.count, 0);
  uint64_t covered = 0;
  for (int32_t l : labels.labels)
    if (l >= 0) {
      ++sizes[size_t(l)];
      ++covered;
    }
  const auto [smallest, largest] = std::minmax_element(sizes.begin(), sizes.end());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("metatex: %s\n", m.source.c_str());
  std::printf("  resolution       %d x %d texels\n", r, r);
  std::printf("  isolation        %s\n", method.c_str());
  std::printf("  features         %u\n", labels.count);
  std::printf("  texels covered   %.2f %%\n", 100.0 * double(covered) / (double(r) * double(r)));
  if (labels.count > 0)
    std::printf("  feature size     smallest %llu, largest %llu texels\n", (unsigned long long)*smallest,
                (unsigned long long)*largest);
  std::printf("  specks dropped   %u (below %u texels)\n", specks, a.min_texels);
  std::printf("  soft map blur    sigma %.2f texels\n", a.blur);
  std::printf("  wrote            %s%s%s\n", a.out.c_str(), a.debug.empty() ? "" : ", ", a.debug.c_str());
  std::printf("  time             %.3f s\n", seconds);
  return 0;
}

const CommandRegistrar k_register{
    "metatex", "Build an FBPB meta-texture (centroid offsets, feature mask, soft map) for a material", 30,
    [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<MetatexArgs>();
      auto* input = app.add_option("--input", a->input, "Material albedo image (alpha = height if present)");
      auto* generator = app.add_option("--generator", a->generator, "Built-in material generator (cobbles, bricks, ...)");
      input->excludes(generator);
      app.add_option("--height", a->height, "Height image; its first channel replaces the albedo's alpha")
          ->needs(input);
      app.add_option("--resolution", a->resolution, "Generator resolution, power of two")->needs(generator);
      app.add_option("--seed", a->seed, "Generator seed")->needs(generator);
      app.add_flag("--auto", a->automatic, "Isolate features automatically instead of using the generator's labels")
          ->needs(generator);
      auto* mask = app.add_option("--mask", a->mask, "Hand-made feature mask (non-zero first channel = feature)");
      auto* channel = app.add_option("--channel", a->channel, "Channel to threshold (default: height if present)")
                          ->check(CLI::IsMember({"height", "luminance"}));
      auto* threshold = app.add_option("--threshold", a->threshold, "Feature if value > threshold (0..1); default Otsu")
                            ->check(finite_range(0.0, 1.0));
      auto* invert = app.add_flag("--invert", a->invert, "Features are the dark side");
      app.add_option("--min-texels", a->min_texels, "Drop components smaller than this (specks)")->capture_default_str();
      auto* erode = app.add_option("--erode", a->erode, "Erode by this many texels before labelling (splits touching features)")
                        ->check(CLI::Range(0u, 256u));
      app.add_option("--blur", a->blur, "Gaussian sigma of the soft feature map, texels")
          ->check(finite_range(0.0, 1024.0))
          ->capture_default_str();
      app.add_option("--out", a->out, "Meta-texture output (.exr)")->required();
      app.add_option("--debug", a->debug, "Colour-coded debug image output (.png ...)");
      for (CLI::Option* automatic_only : {channel, threshold, invert, erode}) automatic_only->excludes(mask);
      return [a, threshold, channel] { return run_metatex(*a, threshold->count() > 0, channel->count() > 0); };
    }};

}  // namespace

}  // namespace tvt::cli
