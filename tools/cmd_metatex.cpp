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

#include "compose/feature_isolation.h"
#include "compose/image.h"
#include "compose/material_image.h"
#include "compose/metatex.h"
#include "compose/procedural.h"
#include "tools/cli_common.h"
#include "tools/commands.h"

namespace tvt::cli {

namespace {

constexpr int k_max_resolution = 16384;  // offsets are int16 and stay inside ±R

// Isolation defaults are IsolationOptions{}'s: the same as scene loading uses.
struct MetatexArgs {
  std::string input, height, generator, mask, out, debug, mask_out;
  std::string channel = "auto", polarity = "auto", height_source = "auto";
  bool height_invert = false;
  uint32_t resolution = 0;  // 0: generator 512, image the size rule
  uint32_t seed = 1;
  double threshold = -1.0;
  bool invert = false;
  bool automatic = false;
  bool no_split = false, no_fill = false, joints = false;
  uint32_t min_texels = IsolationOptions{}.min_feature_texels;
  double speck_fraction = IsolationOptions{}.speck_fraction;
  double smooth = IsolationOptions{}.smooth_sigma;
  double background = IsolationOptions{}.background_sigma;
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
  std::string image_summary;  // what was done to the input image
  int source_width = 0, source_height = 0;  // of the input image (0: generator)
  bool has_exact_labels = false;
  FeatureLabels exact_labels;
  std::string source;  // for messages: file name or generator name
};

int load_material(const MetatexArgs& a, Material& m) {
  if (!a.input.empty()) {
    // The scene loader's path (compose/material_image.h): same texels for the same options.
    MaterialImageOptions o;
    o.height = *height_source_from_string(a.height_source);  // CLI::IsMember checked it
    o.height_path = a.height;
    o.invert_height = a.height_invert;
    if (a.resolution != 0 && (!is_power_of_two(int(a.resolution)) || a.resolution < uint32_t(k_min_material_resolution) ||
                              a.resolution > uint32_t(k_max_material_resolution)))
      return usage_error("--resolution " + std::to_string(a.resolution) + ": must be a power of two from " +
                         std::to_string(k_min_material_resolution) + " to " + std::to_string(k_max_material_resolution));
    o.resolution = int(a.resolution);
    if (o.height == HeightSource::File && a.height.empty()) return usage_error("--height-source file needs --height");
    bool height_failed = false;
    auto image = load_material_image(a.input, o, &height_failed);
    if (!image) return usage_error((height_failed ? "--height " : "--input ") + image.error().message);
    m.albedo = std::move(image->image);
    m.image_summary = image->report.summary();
    m.source_width = image->report.source_width;
    m.source_height = image->report.source_height;
    m.variation = variation_noise(uint32_t(m.albedo.width), k_image_variation_seed);  // as scene loading does
    m.source = a.input;
  } else {
    if (!is_known_generator(a.generator))
      return usage_error("--generator " + a.generator + ": unknown generator (sand, grass, rock, mud, cobbles, bricks)");
    const uint32_t resolution = a.resolution ? a.resolution : 512;
    if (resolution > uint32_t(k_max_resolution) || !is_power_of_two(int(resolution)))
      return usage_error("--resolution " + std::to_string(resolution) + ": must be a power of two");
    auto generated = generate_material(a.generator, resolution, a.seed);
    if (!generated) return usage_error("--generator " + a.generator + ": " + generated.error().message);
    m.albedo = std::move(generated->albedo);
    m.source = "generator " + a.generator;
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

int run_metatex(const MetatexArgs& a, bool threshold_given) {
  const auto start = std::chrono::steady_clock::now();
  if (a.input.empty() == a.generator.empty()) return usage_error("give exactly one of --input or --generator");
  if (auto problem = check_image_output("--out", a.out, true); !problem.empty()) return usage_error(problem);
  if (!a.debug.empty())
    if (auto problem = check_image_output("--debug", a.debug, false); !problem.empty()) return usage_error(problem);
  if (!a.mask_out.empty())
    if (auto problem = check_image_output("--mask-out", a.mask_out, false); !problem.empty()) return usage_error(problem);
  // No output replaces an input or another output (`--debug` on the --input image would lose it).
  const FlaggedPaths inputs = {{"--input", a.input}, {"--height", a.height}, {"--mask", a.mask}};
  const FlaggedPaths outputs = {{"--out", a.out}, {"--debug", a.debug}, {"--mask-out", a.mask_out}};
  if (auto problem = output_collision(outputs, inputs)) return usage_error(*problem);

  // One process per output: two runs writing the same meta-texture never interleave.
  std::vector<OutputLock> owned;
  for (const auto& [flag, output] : outputs) {
    if (output.empty()) continue;
    auto lock = OutputLock::acquire(flag, output);
    if (!lock) return usage_error(lock.error().message);
    owned.push_back(std::move(lock.value()));
  }

  // Phase times, printed with the total: what a user waits for is mostly isolation.
  using Clock = std::chrono::steady_clock;
  auto since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  Material m;
  if (int code = load_material(a, m); code != 0) return code;
  const int r = m.albedo.width;
  const double load_seconds = since(start);
  const auto isolation_start = Clock::now();

  FeatureLabels labels;
  IsolationReport report;
  uint32_t specks = 0;
  std::string method;
  if (!a.mask.empty()) {
    auto mask_rgba = read_image_rgba8(a.mask);
    if (!mask_rgba) return usage_error("--mask " + mask_rgba.error().message);
    // Drawn on the input as given (its size, resampled with it) or at the material's resolution
    // (--mask-out of a smaller image), as scene loading takes it.
    const int want_w = m.source_width ? m.source_width : r, want_h = m.source_height ? m.source_height : r;
    if (!mask_size_fits(mask_rgba->width, mask_rgba->height, want_w, want_h, r))
      return usage_error("--mask " + a.mask + ": " + std::to_string(mask_rgba->width) + " x " +
                         std::to_string(mask_rgba->height) + " texels, but the material image is " +
                         std::to_string(want_w) + " x " + std::to_string(want_h) +
                         (want_w == r && want_h == r ? std::string()
                                                     : " (and the material " + std::to_string(r) + " x " +
                                                           std::to_string(r) + ")"));
    const ImageGray8 mask = resample_mask_nearest(*mask_rgba, r);
    labels = labels_from_mask(mask, a.min_texels);
    specks = labels_from_mask(mask, 1).count - labels.count;
    method = "hand-made mask " + a.mask;
  } else if (m.has_exact_labels) {
    labels = std::move(m.exact_labels);
    method = "exact labels of " + m.source;
  } else {
    IsolationOptions options;
    options.channel = a.channel == "height"      ? IsolationOptions::Channel::Height
                      : a.channel == "luminance" ? IsolationOptions::Channel::Luminance
                                                 : IsolationOptions::Channel::Auto;
    options.threshold = threshold_given ? a.threshold : -1.0;
    options.polarity = a.invert || a.polarity == "dark" ? IsolationOptions::Polarity::Dark
                       : a.polarity == "light"          ? IsolationOptions::Polarity::Light
                                                        : IsolationOptions::Polarity::Auto;
    options.min_feature_texels = a.min_texels;
    options.speck_fraction = a.speck_fraction;
    options.smooth_sigma = a.smooth;
    options.background_sigma = a.background;
    options.split_touching = !a.no_split;
    options.fill_holes = !a.no_fill;
    options.cut_joints = a.joints;
    options.erode_texels = a.erode;
    labels = isolate_features(m.albedo, options, &report);
    specks = report.specks_dropped;
    method = "automatic: " + report.summary() + (a.erode ? ", erode " + std::to_string(a.erode) : "");
  }

  const double isolation_seconds = since(isolation_start);
  const auto build_start = Clock::now();
  const MetaTexture meta = build_meta_texture(labels, m.variation, a.blur);
  const double build_seconds = since(build_start);

  const auto write_start = Clock::now();
  if (auto written = write_meta_texture(a.out, meta); !written) return runtime_error(written.error().message);
  std::optional<uint32_t> mask_read_back;  // --mask-out's feature count, read back
  // All or nothing: a failed write removes what this run wrote before it.
  auto remove_written = [&](std::initializer_list<const std::string*> written) {
    std::error_code ignored;
    for (const std::string* path : written) std::filesystem::remove(*path, ignored);
  };
  if (!a.debug.empty()) {
    if (auto written = write_image(a.debug, meta_debug_image(meta, m.albedo, report.marks)); !written) {
      remove_written({&a.out});
      return runtime_error(written.error().message);
    }
  }
  if (!a.mask_out.empty()) {
    // Drawn on the input as given (its size), so that --mask (and a scene's fbpb.mask) reads it
    // back; at the material's resolution where the image is smaller on a side, whose pixels
    // could not keep the split lines.
    const bool at_source = m.source_width >= r && m.source_height >= r;
    const int mask_w = at_source ? m.source_width : r, mask_h = at_source ? m.source_height : r;
    const ImageGray8 mask = mask_from_labels(labels, mask_w, mask_h);
    if (auto written = write_image(a.mask_out, mask); !written) {
      remove_written({&a.out, &a.debug});
      return runtime_error(written.error().message);
    }
    // Read back as --mask reads it: a feature whose split line cut it in two, or left it below
    // --min-texels, comes back otherwise.
    mask_read_back = labels_from_mask(resample_mask_nearest(mask, r), a.min_texels).count;
  }

  const double write_seconds = since(write_start);
  std::vector<uint64_t> sizes(labels.count, 0);
  uint64_t covered = 0;
  for (int32_t l : labels.labels)
    if (l >= 0) {
      ++sizes[size_t(l)];
      ++covered;
    }
  std::sort(sizes.begin(), sizes.end());
  const double seconds = since(start);
  std::printf("metatex: %s\n", m.source.c_str());
  std::printf("  resolution       %d x %d texels\n", r, r);
  if (!m.image_summary.empty()) std::printf("  image            %s\n", m.image_summary.c_str());
  std::printf("  isolation        %s\n", method.c_str());
  std::printf("  features         %u\n", labels.count);
  std::printf("  texels covered   %.2f %%\n", 100.0 * double(covered) / (double(r) * double(r)));
  // The largest against the median (the upper one of an even count): one feature many times
  // the typical one is usually several merged, unless the image really has such a feature.
  const uint64_t median = labels.count > 0 ? sizes[sizes.size() / 2] : 0;
  const double largest_ratio = labels.count > 0 ? double(sizes.back()) / double(median) : 0.0;
  if (labels.count > 0)
    std::printf("  feature size     smallest %llu, median %llu, largest %llu texels (largest / median %.2f)\n",
                (unsigned long long)sizes.front(), (unsigned long long)median, (unsigned long long)sizes.back(),
                largest_ratio);
  std::printf("  specks dropped   %u (below %u texels)\n", specks,
              report.speck_limit ? report.speck_limit : a.min_texels);
  // What the figures say of an automatic isolation that went wrong (the usual failures on
  // photographs, docs/metatex.md): one feature more than 3x the typical one, or more specks
  // than features.
  const bool isolated = a.mask.empty() && !m.has_exact_labels;  // neither a hand-made mask nor exact labels
  if (isolated && labels.count > 0) {
    const bool merged = largest_ratio > 3.0, broken = specks > labels.count;
    if (merged)
      std::printf("  check            the largest feature is %.1fx the median: features merged across faint joints, "
                  "or one that large in the image? See --debug\n",
                  largest_ratio);
    if (broken)
      std::printf("  check            %u specks dropped against %u features: features broken into pieces "
                  "(shaded parts on the background's side)? See --debug\n",
                  specks, labels.count);
    if (merged || broken)
      std::printf("  remedy           %scorrect the features by hand: --mask-out writes them as a mask to edit and give "
                  "back with --mask\n",
                  a.joints ? "" : "--joints may do better; or ");
  }
  if (mask_read_back && *mask_read_back != labels.count)
    std::printf("  check            --mask-out reads back as %u features, not %u: a split line cut a feature in two "
                "or left it below --min-texels; see the mask before giving it back\n",
                *mask_read_back, labels.count);
  std::printf("  soft map blur    sigma %.2f texels\n", a.blur);
  std::string wrote = a.out;
  for (const std::string* more : {&a.debug, &a.mask_out})
    if (!more->empty()) wrote += ", " + *more;
  std::printf("  wrote            %s\n", wrote.c_str());
  std::printf("  time             %.3f s (reading and preparing the image %.3f s, isolation %.3f s, meta-texture %.3f s, "
              "writing %.3f s)\n",
              seconds, load_seconds, isolation_seconds, build_seconds, write_seconds);
  return 0;
}

const CommandRegistrar k_register{
    "metatex", "Build an FBPB meta-texture (centroid offsets, feature mask, soft map) for a material", 30,
    [](CLI::App& app) -> RunFn {
      auto a = std::make_shared<MetatexArgs>();
      auto* input = app.add_option("--input", a->input,
                                   "Material image, any size (resampled to a power-of-two square like a scene's)");
      auto* generator = app.add_option("--generator", a->generator, "Built-in material generator (cobbles, bricks, ...)");
      input->excludes(generator);
      app.add_option("--height", a->height, "Height image (any size); its first channel becomes the height")
          ->needs(input);
      app.add_option("--height-source", a->height_source,
                     "Height (alpha) from: auto (height image, else varying alpha, else luminance), alpha, "
                     "luminance, file, none")
          ->check(CLI::IsMember({"auto", "alpha", "luminance", "file", "none"}))
          ->needs(input)
          ->capture_default_str();
      app.add_flag("--height-invert", a->height_invert, "Luminance height: the lightest pixel is the deepest")
          ->needs(input);
      app.add_option("--resolution", a->resolution,
                     "Texels per side, power of two (generator: default 512; image: default the size rule)");
      app.add_option("--seed", a->seed, "Generator seed")->needs(generator);
      app.add_flag("--auto", a->automatic, "Isolate features automatically instead of using the generator's labels")
          ->needs(generator);
      auto* mask = app.add_option("--mask", a->mask, "Hand-made feature mask (non-zero first channel = feature)");
      auto* channel = app.add_option("--channel", a->channel, "Channel to threshold: auto (height if it varies), height, luminance")
                          ->check(CLI::IsMember({"auto", "height", "luminance"}))
                          ->capture_default_str();
      auto* threshold = app.add_option("--threshold", a->threshold, "Cut between the sides (0..1); default Otsu")
                            ->check(finite_range(0.0, 1.0));
      auto* polarity = app.add_option("--polarity", a->polarity,
                                      "Which side are features: auto (the side that is not the connected network), "
                                      "light, dark")
                           ->check(CLI::IsMember({"auto", "light", "dark"}))
                           ->capture_default_str();
      auto* invert = app.add_flag("--invert", a->invert, "Features are the dark side (--polarity dark)");
      invert->excludes(polarity);
      app.add_option("--min-texels", a->min_texels, "Drop components smaller than this (specks)")->capture_default_str();
      auto* speck = app.add_option("--speck-fraction", a->speck_fraction,
                                   "Also drop components smaller than this fraction of the typical feature")
                        ->check(finite_range(0.0, 1.0))
                        ->capture_default_str();
      auto* smooth = app.add_option("--smooth", a->smooth, "Gaussian sigma before thresholding, texels")
                         ->check(finite_range(0.0, 64.0))
                         ->capture_default_str();
      auto* background = app.add_option("--background", a->background,
                                        "Threshold the value relative to a Gaussian of this sigma (texels; removes "
                                        "shading); 0: off")
                             ->check(finite_range(0.0, 4096.0))
                             ->capture_default_str();
      auto* no_split = app.add_flag("--no-split", a->no_split, "Do not split touching features (watershed)");
      auto* no_fill = app.add_flag("--no-fill", a->no_fill, "Do not fill pin-holes inside features");
      auto* joints = app.add_flag("--joints", a->joints,
                                  "Also cut along thin joint lines (ridge/valley lines; experimental)");
      auto* erode = app.add_option("--erode", a->erode,
                                   "Erode by this many texels before labelling (the older splitter; replaces the watershed)")
                        ->check(CLI::Range(0u, 256u));
      app.add_option("--blur", a->blur, "Gaussian sigma of the soft feature map, texels")
          ->check(finite_range(0.0, 1024.0))
          ->capture_default_str();
      app.add_option("--out", a->out, "Meta-texture output (.exr)")->required();
      app.add_option("--debug", a->debug,
                     "Debug image (.png ...): features tinted, centroids white, split lines yellow, filled holes "
                     "blue, dropped specks red");
      app.add_option("--mask-out", a->mask_out,
                     "Also write the features as an editable mask (.png ...) at the input's size: white features, "
                     "black background and split lines; edit it and pass it back with --mask (or a scene's "
                     "fbpb.mask)");
      for (CLI::Option* automatic_only : {channel, threshold, polarity, invert, erode, speck, smooth, background, no_split, no_fill, joints})
        automatic_only->excludes(mask);
      return [a, threshold] { return run_metatex(*a, threshold->count() > 0); };
    }};

}  // namespace

}  // namespace tvt::cli
