// FBPB meta-texture (thesis §3.4.4, docs/composition.md): feature isolation on the torus, centroid
// offsets, soft feature map, EXR file and debug image.
//
// Decisions (see docs/metatex.md):
// - A material texture tiles, so it is a torus: 4-connectivity wraps in x and y, and a feature
//   split by the tile edge is one component. The thesis instead treats split pieces as
//   separate features and puts their centroid on the boundary (§3.4.4, Fig. 3.7).
// - Each feature is unwrapped by walking it (BFS): a texel's unwrapped position is its
//   neighbour's plus the step taken. Unlike a minimal-image unwrap around one reference texel,
//   this is exact for features wider than half the texture (long bricks). The offset stored
//   is centroid − unwrapped position, so at run time `floor(U) + (dx, dy)` names the same
//   centroid from every texel of one feature instance, on either side of a tile edge.
// - A feature that closes on itself around the torus (a band, the whole texture) has no
//   unique unwrapping; its texels get minimal-image offsets to one centroid instead, which
//   still agrees modulo R.
#include "compose/metatex.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "compose/image_io_detail.h"
#include "shared/hash.h"

namespace tvt {

namespace {

constexpr int32_t k_background = -1;
// Offsets are int16 and must stay inside ±R: the largest meta-texture is 16384 texels per side.
constexpr int k_max_meta_resolution = 16384;
constexpr const char* k_channel_names[5] = {"dx", "dy", "d", "f", "v"};
constexpr const char* k_format_key = "terravt:meta_format";
constexpr const char* k_format_value = "fbpb-meta-1";
constexpr const char* k_count_key = "terravt:feature_count";

int wrap(int64_t v, int r) { return int(gpu::tvt_floor_mod(v, r)); }
size_t texel_index(int x, int y, int r) { return size_t(y) * size_t(r) + size_t(x); }

// Minimal-image representative of v modulo r, in (-r/2, r/2].
int minimal_image(int64_t v, int r) {
  int m = wrap(v, r);
  if (m > r / 2) m -= r;
  return m;
}

constexpr int k_step_x[4] = {1, -1, 0, 0};
constexpr int k_step_y[4] = {0, 0, 1, -1};

// Circular Gaussian of standard deviation `sigma` texels, folded onto a period of r texels and
// normalised: (offset, weight) taps. sigma 0 is the identity.
std::vector<std::pair<int, double>> circular_gaussian(int r, double sigma) {
  std::vector<double> folded(size_t(r), 0.0);
  if (sigma <= 0.0) {
    folded[0] = 1.0;
  } else {
    const int radius = int(std::ceil(3.0 * sigma));
    for (int t = -radius; t <= radius; ++t) folded[size_t(wrap(t, r))] += std::exp(-double(t) * t / (2.0 * sigma * sigma));
  }
  double total = 0.0;
  for (double w : folded) total += w;
  std::vector<std::pair<int, double>> taps;
  for (int t = 0; t < r; ++t)
    if (folded[size_t(t)] > 0.0) taps.emplace_back(t, folded[size_t(t)] / total);
  return taps;
}

// Separable wrap-around Gaussian blur of d (0/1) into f (0..255). Each row is read from three
// copies of itself laid end to end, so a tap's texel needs no wrap; the taps are summed in the
// same order as with a wrap per tap, so the result is the same to the bit.
std::vector<uint8_t> soft_feature_map(const std::vector<uint8_t>& d, int r, double sigma) {
  const auto taps = circular_gaussian(r, sigma);
  std::vector<std::pair<int, double>> signed_taps;  // offsets in (-r/2, r/2]: x - t stays in (-r, 2r)
  for (const auto& [t, w] : taps) signed_taps.emplace_back(t > r / 2 ? t - r : t, w);
  std::vector<double> rows(d.size(), 0.0), both(d.size(), 0.0), row(3 * size_t(r));
  for (int y = 0; y < r; ++y) {
    const uint8_t* src = &d[texel_index(0, y, r)];
    for (size_t k = 0; k < 3; ++k)
      for (int x = 0; x < r; ++x) row[k * size_t(r) + size_t(x)] = src[x];
    double* dst = &rows[texel_index(0, y, r)];
    for (int x = 0; x < r; ++x) {
      double sum = 0.0;
      for (const auto& [t, w] : signed_taps) sum += w * row[size_t(r + x - t)];
      dst[x] = sum;
    }
  }
  for (int y = 0; y < r; ++y)
    for (const auto& [t, w] : taps) {
      const double* src = &rows[texel_index(0, wrap(y - t, r), r)];
      double* dst = &both[texel_index(0, y, r)];
      for (int x = 0; x < r; ++x) dst[x] += w * src[x];
    }
  std::vector<uint8_t> f(d.size());
  for (size_t i = 0; i < f.size(); ++i) f[i] = uint8_t(std::lround(std::clamp(both[i], 0.0, 1.0) * 255.0));
  return f;
}

std::string at_text(int x, int y) { return "texel (" + std::to_string(x) + ", " + std::to_string(y) + ")"; }

std::string number_text(double v) {
  char buffer[32];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  return ec == std::errc() ? std::string(buffer, end) : std::string("?");
}

bool has_exr_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext == ".exr";
}

}  // namespace

MetaTexture build_meta_texture(const FeatureLabels& labels, const ImageGray8& variation, double blur_texels) {
  const int r = labels.resolution;
  TVT_CHECK(r > 0 && r <= k_max_meta_resolution);
  TVT_CHECK(labels.labels.size() == size_t(r) * size_t(r));
  TVT_CHECK(variation.texels.empty() || (variation.width == r && variation.height == r &&
                                         variation.texels.size() == size_t(r) * size_t(r)));
  TVT_CHECK(std::isfinite(blur_texels) && blur_texels >= 0.0);
  for (int32_t label : labels.labels) TVT_CHECK(label >= k_background && (label < 0 || uint32_t(label) < labels.count));

  const size_t n = labels.labels.size();
  struct Feature {
    bool seen = false;
    bool closes_on_itself = false;  // no unique unwrapping on the torus
    int64_t ref_x = 0, ref_y = 0;   // unwrapped position of the first texel
    int64_t sum_x = 0, sum_y = 0, texels = 0;
    int64_t min_x = 0, max_x = 0, min_y = 0, max_y = 0;
  };
  std::vector<Feature> features(labels.count);
  // Unwrapped position of texel (x, y) = (x + wind_x·R, y + wind_y·R). |wind| <= R, so int16.
  std::vector<int16_t> wind_x(n, 0), wind_y(n, 0);
  std::vector<uint8_t> visited(n, 0);
  std::vector<size_t> queue;
  auto unwrapped_x = [&](size_t i) { return int64_t(i % size_t(r)) + int64_t(wind_x[i]) * r; };
  auto unwrapped_y = [&](size_t i) { return int64_t(i / size_t(r)) + int64_t(wind_y[i]) * r; };

  for (size_t seed = 0; seed < n; ++seed) {
    const int32_t label = labels.labels[seed];
    if (label < 0 || visited[seed]) continue;
    Feature& feature = features[size_t(label)];
    const int sx = int(seed % size_t(r)), sy = int(seed / size_t(r));
    if (!feature.seen) {
      feature.seen = true;
      feature.ref_x = feature.min_x = feature.max_x = sx;
      feature.ref_y = feature.min_y = feature.max_y = sy;
    } else {
      // Another piece of a label that is not connected on the torus: place it at the
      // minimal-image position relative to the feature's first texel.
      wind_x[seed] = int16_t(gpu::tvt_floor_div(feature.ref_x + minimal_image(sx - feature.ref_x, r), r));
      wind_y[seed] = int16_t(gpu::tvt_floor_div(feature.ref_y + minimal_image(sy - feature.ref_y, r), r));
    }
    visited[seed] = 1;
    queue.assign(1, seed);
    for (size_t head = 0; head < queue.size(); ++head) {
      const size_t i = queue[head];
      const int x = int(i % size_t(r)), y = int(i / size_t(r));
      const int64_t ux = x + int64_t(wind_x[i]) * r, uy = y + int64_t(wind_y[i]) * r;  // unwrapped_x/y(i)
      feature.sum_x += ux;
      feature.sum_y += uy;
      ++feature.texels;
      feature.min_x = std::min(feature.min_x, ux);
      feature.max_x = std::max(feature.max_x, ux);
      feature.min_y = std::min(feature.min_y, uy);
      feature.max_y = std::max(feature.max_y, uy);
      for (int s = 0; s < 4; ++s) {
        // The neighbour one step away: its texel and winding, without a division per step.
        int nx = x + k_step_x[s], ny = y + k_step_y[s];
        int64_t wx = wind_x[i], wy = wind_y[i];
        if (nx < 0) nx += r, --wx;
        if (nx >= r) nx -= r, ++wx;
        if (ny < 0) ny += r, --wy;
        if (ny >= r) ny -= r, ++wy;
        const size_t j = texel_index(nx, ny, r);
        if (labels.labels[j] != label) continue;
        if (visited[j]) {
          if (wind_x[j] != wx || wind_y[j] != wy) feature.closes_on_itself = true;
          continue;
        }
        if (std::abs(wx) > r || std::abs(wy) > r) {  // cannot happen with |wind| <= texels / R
          feature.closes_on_itself = true;
          continue;
        }
        visited[j] = 1;
        wind_x[j] = int16_t(wx);
        wind_y[j] = int16_t(wy);
        queue.push_back(j);
      }
    }
  }

  // Centroid = mean unwrapped position rounded to the nearest texel (halves round up), exact in
  // integers: floor((2·sum + count) / (2·count)).
  struct Centroid {
    int64_t x = 0, y = 0;  // unwrapped
    bool minimal_image = false;
  };
  std::vector<Centroid> centroids(labels.count);
  for (size_t l = 0; l < features.size(); ++l) {
    const Feature& feature = features[l];
    if (feature.texels == 0) continue;
    Centroid& c = centroids[l];
    c.x = gpu::tvt_floor_div(2 * feature.sum_x + feature.texels, 2 * feature.texels);
    c.y = gpu::tvt_floor_div(2 * feature.sum_y + feature.texels, 2 * feature.texels);
    // Offsets must stay inside ±R (int16, file rule): otherwise fall back to minimal images.
    const int64_t reach = std::max({c.x - feature.min_x, feature.max_x - c.x, c.y - feature.min_y, feature.max_y - c.y});
    c.minimal_image = feature.closes_on_itself || reach >= r;
  }

  MetaTexture meta;
  meta.resolution = r;
  meta.feature_count = labels.count;
  meta.texels.resize(n);
  std::vector<uint8_t> d(n, 0);
  for (size_t i = 0; i < n; ++i) {
    MetaTexel& t = meta.texels[i];
    t.variation = variation.texels.empty() ? uint8_t(255) : variation.texels[i];
    const int32_t label = labels.labels[i];
    if (label < 0) continue;
    const Centroid& c = centroids[size_t(label)];
    const int x = int(i % size_t(r)), y = int(i / size_t(r));
    d[i] = 1;
    t.d = 1;
    if (c.minimal_image) {
      t.dx = int16_t(minimal_image(c.x - x, r));
      t.dy = int16_t(minimal_image(c.y - y, r));
    } else {
      t.dx = int16_t(c.x - unwrapped_x(i));
      t.dy = int16_t(c.y - unwrapped_y(i));
    }
  }
  const std::vector<uint8_t> f = soft_feature_map(d, r, blur_texels);
  for (size_t i = 0; i < n; ++i) meta.texels[i].f = f[i];
  return meta;
}

Status write_meta_texture(const std::string& path, const MetaTexture& meta) {
  if (!has_exr_extension(path))
    return make_error(path + ": meta-textures are OpenEXR files; give the file the .exr extension");
  const int r = meta.resolution;
  if (r <= 0 || r > k_max_meta_resolution || meta.texels.size() != size_t(r) * size_t(r))
    return make_error(path + ": invalid meta-texture (resolution " + std::to_string(r) + ", " +
                      std::to_string(meta.texels.size()) + " texels)");
  ImageF image(r, r, 5);
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      const MetaTexel& t = meta.at(x, y);
      image.at(x, y, 0) = float(t.dx);
      image.at(x, y, 1) = float(t.dy);
      image.at(x, y, 2) = float(t.d);
      image.at(x, y, 3) = float(t.f);
      image.at(x, y, 4) = float(t.variation);
    }
  return detail::write_named_float_image(path, image, {std::begin(k_channel_names), std::end(k_channel_names)},
                                         {{k_format_key, k_format_value},
                                          {k_count_key, std::to_string(meta.feature_count)},
                                          // OpenImageIO's EXR option: ZIP at its fastest level. At
                                          // 4096² it writes in half the time of the default level
                                          // for a file 15 % larger (dx, dy, d, f are runs).
                                          {"compression", "zip:1"}});
}

Result<MetaTexture> read_meta_texture(const std::string& path) {
  auto file = detail::read_named_float_image(path);
  if (!file) return file.error();
  const ImageF& image = file->image;
  const int r = image.width;
  if (image.width != image.height)
    return make_error(path + ": meta-texture is not square (" + std::to_string(image.width) + " x " +
                      std::to_string(image.height) + " texels)");
  if (r > k_max_meta_resolution)
    return make_error(path + ": meta-texture too large (" + std::to_string(r) + " texels per side; at most " +
                      std::to_string(k_max_meta_resolution) + ")");

  int channel[5];
  std::string missing;
  for (int c = 0; c < 5; ++c) {
    const auto& names = file->channel_names;
    const auto it = std::find(names.begin(), names.end(), k_channel_names[c]);
    channel[c] = it == names.end() ? -1 : int(it - names.begin());
    if (channel[c] < 0) missing += std::string(missing.empty() ? "" : ", ") + k_channel_names[c];
  }
  if (!missing.empty()) {
    std::string present;
    for (const auto& name : file->channel_names) present += (present.empty() ? "" : ", ") + name;
    return make_error(path + ": not a meta-texture: missing channel(s) " + missing + " (file has: " + present + ")");
  }

  MetaTexture meta;
  meta.resolution = r;
  meta.texels.resize(size_t(r) * size_t(r));
  std::vector<uint8_t> centroid_seen(meta.texels.size(), 0);
  uint32_t distinct_centroids = 0;
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      double v[5];
      for (int c = 0; c < 5; ++c) {
        v[c] = image.at(x, y, channel[c]);
        if (v[c] != std::floor(v[c]))
          return make_error(path + ": " + at_text(x, y) + ": " + k_channel_names[c] + " = " + number_text(v[c]) +
                            " is not an integer");
      }
      if (v[2] != 0.0 && v[2] != 1.0)
        return make_error(path + ": " + at_text(x, y) + ": d = " + number_text(v[2]) + " (must be 0 or 1)");
      for (int c = 0; c < 2; ++c)
        if (std::abs(v[c]) >= r)
          return make_error(path + ": " + at_text(x, y) + ": " + k_channel_names[c] + " = " + number_text(v[c]) +
                            " points outside the texture (|offset| must be < " + std::to_string(r) + ")");
      for (int c = 3; c < 5; ++c)
        if (v[c] < 0.0 || v[c] > 255.0)
          return make_error(path + ": " + at_text(x, y) + ": " + k_channel_names[c] + " = " + number_text(v[c]) +
                            " outside 0..255");
      if (v[2] == 0.0 && (v[0] != 0.0 || v[1] != 0.0))
        return make_error(path + ": " + at_text(x, y) + ": not a feature (d = 0) but has offset (" +
                          number_text(v[0]) + ", " + number_text(v[1]) + "); must be (0, 0)");
      MetaTexel& t = meta.texels[texel_index(x, y, r)];
      t.dx = int16_t(v[0]);
      t.dy = int16_t(v[1]);
      t.d = uint8_t(v[2]);
      t.f = uint8_t(v[3]);
      t.variation = uint8_t(v[4]);
      if (t.d) {
        // The centroid (x + dx, y + dy) wraps to a texel of the texture; count distinct ones.
        const size_t c = texel_index(wrap(x + t.dx, r), wrap(y + t.dy, r), r);
        if (!centroid_seen[c]) {
          centroid_seen[c] = 1;
          ++distinct_centroids;
        }
      }
    }

  meta.feature_count = distinct_centroids;
  for (const auto& [key, value] : file->metadata) {
    if (key == k_format_key && value != k_format_value)
      return make_error(path + ": unknown meta-texture format '" + value + "' (expected " + k_format_value + ")");
    if (key != k_count_key) continue;
    uint32_t count = 0;
    const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), count);
    if (ec != std::errc() || end != value.data() + value.size())
      return make_error(path + ": " + k_count_key + " = '" + value + "' is not a feature count");
    // Every feature has exactly one centroid, so features >= distinct centroids.
    if (count < distinct_centroids)
      return make_error(path + ": " + k_count_key + " says " + value + " features but the texels point at " +
                        std::to_string(distinct_centroids) + " distinct centroids");
    meta.feature_count = count;
  }
  return meta;
}

ImageRGBA8 meta_debug_image(const MetaTexture& meta, const ImageRGBA8& albedo, const std::vector<uint8_t>& marks) {
  const int r = meta.resolution;
  TVT_CHECK(r > 0 && meta.texels.size() == size_t(r) * size_t(r));
  TVT_CHECK(albedo.width == r && albedo.height == r && albedo.texels.size() == size_t(r) * size_t(r) * 4);
  TVT_CHECK(marks.empty() || marks.size() == size_t(r) * size_t(r));
  ImageRGBA8 out(r, r);
  std::vector<uint8_t> is_centroid(size_t(r) * size_t(r), 0);
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      const uint8_t* src = albedo.at(x, y);
      uint8_t* dst = out.at(x, y);
      dst[3] = 255;
      const MetaTexel& t = meta.at(x, y);
      if (!t.d) {
        for (int c = 0; c < 3; ++c) dst[c] = uint8_t(src[c] / 2);
        continue;
      }
      const int cx = wrap(x + t.dx, r), cy = wrap(y + t.dy, r);
      is_centroid[texel_index(cx, cy, r)] = 1;
      // Tint from the centroid position: every texel of one feature gets the same colour.
      const uint32_t h = gpu::tvt_hash_coord(cx, cy, 0x6d657461u);
      for (int c = 0; c < 3; ++c) {
        const int tint = 64 + int((h >> (8 * c)) & 0xbfu);  // 64..255: never black
        dst[c] = uint8_t((src[c] * 35 + tint * 65 * 2 + 100) / 200);
      }
    }
  // Isolation marks (compose/feature_isolation.h): 1 filled pin-hole, 2 dropped speck, 3 split line.
  constexpr uint8_t k_mark_rgb[4][3] = {{0, 0, 0}, {40, 90, 255}, {255, 40, 40}, {255, 230, 0}};
  for (size_t i = 0; i < marks.size(); ++i)
    if (marks[i] >= 1 && marks[i] <= 3)
      for (int c = 0; c < 3; ++c) out.texels[i * 4 + size_t(c)] = k_mark_rgb[marks[i]][c];
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      if (!is_centroid[texel_index(x, y, r)]) continue;
      for (int k = -2; k <= 2; ++k) {
        for (uint8_t* p : {out.at(wrap(x + k, r), y), out.at(x, wrap(y + k, r))}) p[0] = p[1] = p[2] = 255;
      }
    }
  return out;
}

}  // namespace tvt
