#include "compose/scene_assets.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <new>
#include <numbers>

#include "compose/procedural.h"
#include "shaders/shared/hash.h"

namespace tvt {

namespace {

std::string field(const SceneDesc& d, const std::string& pointer) { return scene_field(d, pointer); }

double clamp01(double v) { return std::isfinite(v) ? std::clamp(v, 0.0, 1.0) : 0.0; }

Result<ImageF> load_heightfield(const SceneDesc& d) {
  const HeightmapDesc& h = d.terrain.heightmap;
  if (!h.image_path.empty()) {
    auto img = read_image_float(h.image_path);
    if (!img) return make_error(field(d, "/terrain/heightmap/image") + ": " + img.error().message);
    // The terrain mesh interpolates between texels: one row or column has no slope to sample.
    if (img->width < 2 || img->height < 2)
      return make_error(field(d, "/terrain/heightmap/image") + ": " + h.image_path + ": heightmap is " +
                        std::to_string(img->width) + " x " + std::to_string(img->height) +
                        " texels; it needs at least 2 x 2");
    ImageF out(img->width, img->height, 1);
    for (int y = 0; y < out.height; ++y)
      for (int x = 0; x < out.width; ++x) out.at(x, y) = float(clamp01(img->at(x, y, 0)));
    return out;
  }
  const auto grid = fbm_grid(h.size, h.seed, h.octaves, h.frequency, h.gain, h.lacunarity);
  ImageF out(int(h.size), int(h.size), 1);
  for (size_t i = 0; i < grid.size(); ++i) out.data[i] = float(clamp01(grid[i]));
  return out;
}

// Slope in degrees at grid texel (x, y), central differences, one-sided at the edges.
double slope_deg(const ImageF& hf, int x, int y, double texel_m_x, double texel_m_y, double height_m) {
  const int x0 = std::max(x - 1, 0), x1 = std::min(x + 1, hf.width - 1);
  const int y0 = std::max(y - 1, 0), y1 = std::min(y + 1, hf.height - 1);
  const double dx = x1 > x0 ? (hf.at(x1, y) - hf.at(x0, y)) * height_m / (double(x1 - x0) * texel_m_x) : 0.0;
  const double dy = y1 > y0 ? (hf.at(x, y1) - hf.at(x, y0)) * height_m / (double(y1 - y0) * texel_m_y) : 0.0;
  return std::atan(std::sqrt(dx * dx + dy * dy)) * 180.0 / std::numbers::pi;
}

Status fill_weight_layer(const SceneDesc& d, size_t index, const ImageF& hf, WeightGrid& grid) {
  const MaterialDesc& m = d.materials[index];
  const WeightDesc& w = m.weight;
  float* out = &grid.data[index * size_t(grid.width) * size_t(grid.height)];
  if (w.kind == WeightDesc::Kind::Rule) {
    const double tx = d.terrain.extent_m / grid.width, ty = d.terrain.extent_m / grid.height;
    std::vector<float> noise;
    uint32_t ns = 0;
    if (w.noise_amplitude > 0) {
      ns = std::bit_ceil(uint32_t(std::max(grid.width, grid.height)));
      noise = fbm_grid(ns, derived_asset_seed(d.seed, uint32_t(index), 3), 5, w.noise_frequency, 0.5, 2.0);
    }
    for (int y = 0; y < grid.height; ++y)
      for (int x = 0; x < grid.width; ++x) {
        double v = window_weight(hf.at(x, y), w.height_lo, w.height_hi, w.height_fade) *
                   window_weight(slope_deg(hf, x, y, tx, ty, d.terrain.height_m), w.slope_lo_deg, w.slope_hi_deg,
                                 w.slope_fade_deg);
        if (!noise.empty()) {
          // Noise breaks up the transition band only: 4v(1-v) is 0 where the rule says 0 or
          // 1, so zero-weight regions stay exactly zero (and are culled per page).
          const size_t nx = size_t(x) * ns / size_t(grid.width), ny = size_t(y) * ns / size_t(grid.height);
          v += w.noise_amplitude * (double(noise[ny * ns + nx]) - 0.5) * 4.0 * v * (1.0 - v);
        }
        out[size_t(y) * size_t(grid.width) + size_t(x)] = float(clamp01(v));
      }
    return Ok{};
  }
  if (w.kind == WeightDesc::Kind::Splat) {
    auto img = read_image_float(w.splat_path);
    const std::string ptr = "/materials/" + std::to_string(index) + "/weight/splat";
    if (!img) return make_error(field(d, ptr + "/image") + ": " + img.error().message);
    if (int(w.splat_channel) >= img->channels)
      return make_error(field(d, ptr + "/channel") + ": " + w.splat_path + " has " + std::to_string(img->channels) +
                        " channel(s), channel " + std::to_string(w.splat_channel) + " requested");
    // Bilinear resampling of the splat image onto the weight grid (both cover the terrain).
    for (int y = 0; y < grid.height; ++y)
      for (int x = 0; x < grid.width; ++x) {
        const double u = (x + 0.5) * img->width / grid.width - 0.5, v = (y + 0.5) * img->height / grid.height - 0.5;
        const int i0 = int(std::floor(u)), j0 = int(std::floor(v));
        const double fu = u - i0, fv = v - j0;
        auto at = [&](int i, int j) {
          return double(img->at(std::clamp(i, 0, img->width - 1), std::clamp(j, 0, img->height - 1),
                                int(w.splat_channel)));
        };
        const double s = (at(i0, j0) * (1 - fu) + at(i0 + 1, j0) * fu) * (1 - fv) +
                         (at(i0, j0 + 1) * (1 - fu) + at(i0 + 1, j0 + 1) * fu) * fv;
        out[size_t(y) * size_t(grid.width) + size_t(x)] = float(clamp01(s));
      }
    return Ok{};
  }
  return Ok{};  // Remainder: filled once every other layer is known
}

}  // namespace

double window_weight(double v, double lo, double hi, double fade) {
  if (!std::isfinite(v)) return 0.0;
  auto smooth = [](double e0, double e1, double x) {
    if (e1 <= e0) return x >= e1 ? 1.0 : 0.0;
    const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
  };
  return smooth(lo - fade, lo, v) * (1.0 - smooth(hi, hi + fade, v));
}

static Result<SceneAssets> load_scene_assets_unguarded(const SceneDesc& desc) {
  SceneAssets assets;
  assets.desc = desc;
  auto hf = load_heightfield(desc);
  if (!hf) return hf.error();
  assets.heightfield = std::move(hf.value());

  auto materials = MaterialSource::open(desc);
  if (!materials) return materials.error();
  assets.materials = std::move(materials.value());

  WeightGrid& grid = assets.weights;
  grid.width = assets.heightfield.width;
  grid.height = assets.heightfield.height;
  grid.layers = int(desc.materials.size());
  grid.data.assign(size_t(grid.width) * size_t(grid.height) * size_t(grid.layers), 0.f);
  for (size_t i = 0; i < desc.materials.size(); ++i) {
    auto s = fill_weight_layer(desc, i, assets.heightfield, grid);
    if (!s) return s.error();
  }
  const size_t plane = size_t(grid.width) * size_t(grid.height);
  for (size_t i = 0; i < desc.materials.size(); ++i) {
    if (desc.materials[i].weight.kind != WeightDesc::Kind::Remainder) continue;
    for (size_t t = 0; t < plane; ++t) {
      double others = 0;
      for (size_t j = 0; j < desc.materials.size(); ++j)
        if (j != i && desc.materials[j].weight.kind != WeightDesc::Kind::Remainder) others += grid.data[j * plane + t];
      grid.data[i * plane + t] = float(1.0 - std::clamp(others, 0.0, 1.0));
    }
  }
  return assets;
}

// A scene whose files each pass their own limits can still ask for more than the machine has
// (a 16384^2 heightmap and many materials: weights alone are 1 GiB per material). Running out
// is an error naming the scene, never an abort.
Result<SceneAssets> load_scene_assets(const SceneDesc& desc) {
  try {
    return load_scene_assets_unguarded(desc);
  } catch (const std::bad_alloc&) {
    return Error{ErrorKind::out_of_memory,
                 desc.source_path + ": not enough memory to load the scene (heightmap " +
                     std::to_string(desc.terrain.heightmap.image_path.empty() ? desc.terrain.heightmap.size : 0) +
                     (desc.terrain.heightmap.image_path.empty() ? " texels a side" : " from " + desc.terrain.heightmap.image_path) +
                     ", " + std::to_string(desc.materials.size()) +
                     " materials, one float weight layer each at the heightmap's size, plus their images); use a "
                     "smaller heightmap or fewer materials"};
  }
}

}  // namespace tvt
