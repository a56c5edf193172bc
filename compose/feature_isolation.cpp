// FBPB feature isolation: see compose/feature_isolation.h for the method and its steps.
//
// Why OpenCV: its cv::distanceTransform (exact Euclidean, Felzenszwalb) and cv::watershed
// (Meyer's marker-based flooding) are the textbook pair for separating touching objects, are
// packaged by Debian (libopencv-imgproc-dev, already a dependency of OpenImageIO's runtime) and
// need nothing else of OpenCV. Neither knows about a torus, so both run on the texture padded
// periodically (cv::copyMakeBorder with BORDER_WRAP) and the labels of the padding are joined
// to those of the texels they repeat.
#include "compose/feature_isolation.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "compose/material_image.h"
#include "shared/hash.h"
#include "vt/result.h"

namespace tvt {

namespace {

constexpr int32_t k_background = -1;

int wrap(int64_t v, int r) { return int(gpu::tvt_floor_mod(v, r)); }
size_t texel_index(int x, int y, int r) { return size_t(y) * size_t(r) + size_t(x); }

constexpr int k_step_x[4] = {1, -1, 0, 0};
constexpr int k_step_y[4] = {0, 0, 1, -1};

struct UnionFind {
  std::vector<int32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int32_t find(int32_t a) {
    while (parent[size_t(a)] != a) a = parent[size_t(a)] = parent[size_t(parent[size_t(a)])];
    return a;
  }
  void join(int32_t a, int32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[size_t(std::max(a, b))] = std::min(a, b);  // smaller id wins: deterministic
  }
};

// Connected components of the non-zero texels of `mask` (4- or 8-connected on the torus):
// OpenCV's labelling of the plane, then the labels that meet across the texture's edges joined.
// Labels are numbered in row-major order of each component's first texel.
std::vector<int32_t> label_components(const std::vector<uint8_t>& mask, int r, uint32_t& count,
                                      int connectivity = 4) {
  const cv::Mat plane(r, r, CV_8UC1, const_cast<uint8_t*>(mask.data()));
  cv::Mat plane_labels;
  const int n = cv::connectedComponents(plane, plane_labels, connectivity, CV_32S);  // 0: background
  const auto* l = reinterpret_cast<const int32_t*>(plane_labels.data);
  auto at = [&](int x, int y) { return l[texel_index(wrap(x, r), wrap(y, r), r)]; };
  UnionFind joined(size_t(std::max(n, 1)));
  const int reach = connectivity == 8 ? 1 : 0;  // diagonal neighbours across the edges
  for (int i = 0; i < r; ++i)
    for (int d = -reach; d <= reach; ++d) {
      if (const int32_t a = at(r - 1, i), b = at(0, i + d); a && b) joined.join(a, b);
      if (const int32_t a = at(i, r - 1), b = at(i + d, 0); a && b) joined.join(a, b);
    }
  std::vector<int32_t> labels(mask.size(), k_background), renumber(size_t(std::max(n, 1)), k_background);
  count = 0;
  for (size_t i = 0; i < mask.size(); ++i) {
    if (!l[i]) continue;
    const int32_t root = joined.find(l[i]);
    if (renumber[size_t(root)] == k_background) renumber[size_t(root)] = int32_t(count++);
    labels[i] = renumber[size_t(root)];
  }
  return labels;
}

// Extent of the component `id` of `labels` that holds `seed`: the larger side of its bounding
// box, walking its texels (4-connected) on the unrolled plane; r or more if it wraps around
// the torus. For small components only: the walk visits every texel of it.
int component_extent(const std::vector<int32_t>& labels, int r, size_t seed, int32_t id) {
  std::vector<std::pair<size_t, std::pair<int64_t, int64_t>>> queue{{seed, {0, 0}}};
  std::unordered_map<size_t, std::pair<int64_t, int64_t>> seen{{seed, {0, 0}}};
  int64_t x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  for (size_t head = 0; head < queue.size(); ++head) {
    const auto [texel, at] = queue[head];
    const int x = int(texel % size_t(r)), y = int(texel / size_t(r));
    for (int s = 0; s < 4; ++s) {
      const size_t n = texel_index(wrap(x + k_step_x[s], r), wrap(y + k_step_y[s], r), r);
      if (labels[n] != id) continue;
      const std::pair<int64_t, int64_t> next{at.first + k_step_x[s], at.second + k_step_y[s]};
      const auto [it, added] = seen.emplace(n, next);
      if (!added) {
        if (it->second != next) return r;  // the same texel at another place: it wraps
        continue;
      }
      x0 = std::min(x0, next.first), x1 = std::max(x1, next.first);
      y0 = std::min(y0, next.second), y1 = std::max(y1, next.second);
      queue.push_back({n, next});
    }
  }
  return int(std::max(x1 - x0, y1 - y0) + 1);
}

// Drops labels with fewer than `min_texels` texels and renumbers the rest 0..count-1 in
// row-major order of their first texel.
FeatureLabels compact_labels(std::vector<int32_t> labels, uint32_t count, int r, uint32_t min_texels) {
  std::vector<uint32_t> sizes(count, 0);
  for (int32_t label : labels)
    if (label >= 0) ++sizes[size_t(label)];
  std::vector<int32_t> renumber(count, k_background);
  FeatureLabels result;
  result.resolution = r;
  for (int32_t& label : labels) {
    if (label < 0) continue;
    const size_t old = size_t(label);
    if (sizes[old] < min_texels) {
      label = k_background;
      continue;
    }
    if (renumber[old] == k_background) renumber[old] = int32_t(result.count++);
    label = renumber[old];
  }
  result.labels = std::move(labels);
  return result;
}

// 8-neighbourhood, for erosion and growing back: a (2e+1)^2 square structuring element, so
// that eroding and growing a square feature by e texels gives back the same square.
constexpr int k_ring_x[8] = {1, 1, 0, -1, -1, -1, 0, 1};
constexpr int k_ring_y[8] = {0, 1, 1, 1, 0, -1, -1, -1};

// Erosion on the torus by a (2·steps+1)^2 square: one 3x3 step, `steps` times.
std::vector<uint8_t> erode(std::vector<uint8_t> mask, int r, uint32_t steps) {
  std::vector<uint8_t> next(mask.size());
  for (uint32_t step = 0; step < steps; ++step) {
    for (int y = 0; y < r; ++y)
      for (int x = 0; x < r; ++x) {
        bool keep = mask[texel_index(x, y, r)] != 0;
        for (int s = 0; s < 8 && keep; ++s)
          keep = mask[texel_index(wrap(x + k_ring_x[s], r), wrap(y + k_ring_y[s], r), r)] != 0;
        next[texel_index(x, y, r)] = keep ? 1 : 0;
      }
    mask.swap(next);
  }
  return mask;
}

// Grows labels back into the un-eroded mask: every mask texel within `steps` 8-connected steps
// (walking inside the mask) of a labelled texel takes the label of the nearest one (ties: first
// reached, sources in row-major order). Mask texels farther away stay background, so parts
// the erosion removed entirely (thin bridges, specks) are not brought back.
void grow_into_mask(std::vector<int32_t>& labels, const std::vector<uint8_t>& mask, int r, uint32_t steps) {
  std::vector<size_t> frontier;
  for (size_t i = 0; i < labels.size(); ++i)
    if (labels[i] >= 0) frontier.push_back(i);
  std::vector<size_t> next;
  for (uint32_t step = 0; step < steps && !frontier.empty(); ++step) {
    next.clear();
    for (size_t i : frontier) {
      const int x = int(i % size_t(r));
      const int y = int(i / size_t(r));
      for (int s = 0; s < 8; ++s) {
        const size_t n = texel_index(wrap(x + k_ring_x[s], r), wrap(y + k_ring_y[s], r), r);
        if (mask[n] && labels[n] == k_background) {
          labels[n] = labels[i];
          next.push_back(n);
        }
      }
    }
    frontier.swap(next);
  }
}

// Otsu's method on a 256-bin histogram: the level k maximising the between-class variance of
// {<= k} and {> k}. None when the histogram holds a single value (nothing to separate).
std::optional<int> otsu_level(const std::vector<uint8_t>& values) {
  double histogram[256] = {};
  for (uint8_t v : values) histogram[v] += 1.0;
  const double total = double(values.size());
  double sum_all = 0.0;
  for (int i = 0; i < 256; ++i) sum_all += i * histogram[i];
  double weight_low = 0.0, sum_low = 0.0, best = -1.0;
  std::optional<int> level;
  for (int k = 0; k < 255; ++k) {
    weight_low += histogram[k];
    sum_low += k * histogram[k];
    const double weight_high = total - weight_low;
    if (weight_low == 0.0) continue;
    if (weight_high == 0.0) break;
    const double mean_low = sum_low / weight_low;
    const double mean_high = (sum_all - sum_low) / weight_high;
    const double between = weight_low * weight_high * (mean_low - mean_high) * (mean_low - mean_high);
    if (between > best) {
      best = between;
      level = k;
    }
  }
  return level;
}



// Component sizes of `labels` (count labels).
std::vector<uint32_t> label_sizes(const std::vector<int32_t>& labels, uint32_t count) {
  std::vector<uint32_t> sizes(count, 0);
  for (int32_t l : labels)
    if (l >= 0) ++sizes[size_t(l)];
  return sizes;
}

// Area-weighted median: the size of the component that holds the median texel of all
// components. Specks, however many, hold few texels and barely move it. 0 when empty.
uint32_t typical_area(std::vector<uint32_t> sizes) {
  std::sort(sizes.begin(), sizes.end());
  const uint64_t total = std::accumulate(sizes.begin(), sizes.end(), uint64_t(0));
  uint64_t running = 0;
  for (uint32_t s : sizes) {
    running += s;
    if (2 * running >= total) return s;
  }
  return 0;
}

// Share of the side's texels in its largest component (0 for an empty side).
// Only sizes are needed: OpenCV's areas of the plane's components, summed over the components
// joined across the edges (4-connected, as label_components).
double network_share(const std::vector<uint8_t>& side, int r) {
  const cv::Mat plane(r, r, CV_8UC1, const_cast<uint8_t*>(side.data()));
  cv::Mat plane_labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(plane, plane_labels, stats, centroids, 4, CV_32S);
  if (n < 2) return 0.0;
  const auto* l = reinterpret_cast<const int32_t*>(plane_labels.data);
  UnionFind joined{size_t(n)};
  for (int i = 0; i < r; ++i) {
    if (const int32_t a = l[texel_index(r - 1, i, r)], b = l[texel_index(0, i, r)]; a && b) joined.join(a, b);
    if (const int32_t a = l[texel_index(i, r - 1, r)], b = l[texel_index(i, 0, r)]; a && b) joined.join(a, b);
  }
  std::vector<uint64_t> sizes(size_t(n), 0);
  uint64_t total = 0;
  for (int c = 1; c < n; ++c) {
    const auto area = uint64_t(stats.at<int32_t>(c, cv::CC_STAT_AREA));
    sizes[size_t(joined.find(c))] += area;
    total += area;
  }
  return double(*std::max_element(sizes.begin(), sizes.end())) / double(total);
}

// Wrap-around Gaussian of the channel values: padded periodically, blurred, cropped.
std::vector<uint8_t> smooth_wrapped(const std::vector<uint8_t>& values, int r, double sigma) {
  if (sigma <= 0.0) return values;
  const int pad = int(std::ceil(3.0 * sigma)) + 1;
  const cv::Mat plane(r, r, CV_8UC1, const_cast<uint8_t*>(values.data()));
  cv::Mat padded, blurred;
  cv::copyMakeBorder(plane, padded, pad, pad, pad, pad, cv::BORDER_WRAP);
  cv::GaussianBlur(padded, blurred, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
  std::vector<uint8_t> out(values.size());
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) out[texel_index(x, y, r)] = blurred.at<uint8_t>(y + pad, x + pad);
  return out;
}

// Fills background components other than the largest (the network) smaller than `limit`
// texels and shorter than `max_extent` texels (bounding box, on the torus): a pin-hole is a
// small blob, while a piece of joint cut off from the network is long and separates two
// features, so it is kept. Returns how many were filled; marks their texels 1.
uint32_t fill_pin_holes(std::vector<uint8_t>& mask, int r, uint32_t limit, int max_extent,
                        std::vector<uint8_t>& marks) {
  std::vector<uint8_t> background(mask.size());
  for (size_t i = 0; i < mask.size(); ++i) background[i] = mask[i] ? 0 : 1;
  uint32_t count = 0;
  const auto labels = label_components(background, r, count);
  if (count < 2) return 0;
  const auto sizes = label_sizes(labels, count);
  const size_t network = size_t(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
  std::vector<size_t> first(count, 0);  // first texel of each label (labels are in row-major order)
  for (size_t i = mask.size(); i-- > 0;)
    if (labels[i] >= 0) first[size_t(labels[i])] = i;
  uint32_t filled = 0;
  std::vector<uint8_t> fill(count, 0);
  for (size_t l = 0; l < count; ++l)
    if (l != network && sizes[l] < limit && component_extent(labels, r, first[l], int32_t(l)) < max_extent) {
      fill[l] = 1;
      ++filled;
    }
  for (size_t i = 0; i < mask.size(); ++i)
    if (labels[i] >= 0 && fill[size_t(labels[i])]) {
      mask[i] = 1;
      marks[i] = 1;
    }
  return filled;
}

// Step 6: splits touching features. Distance transform of the padded mask; per component,
// the cores where the distance exceeds half its maximum are the markers (a thin bridge has a
// small distance, so the two sides get separate cores); the watershed floods the rest of the
// mask from them over the channel values. Labels of the padding are joined to those of the
// texels they repeat, so a feature cut by the texture edge stays one.
std::vector<int32_t> split_touching(const std::vector<uint8_t>& mask, const std::vector<uint8_t>& values, int r,
                                    uint32_t typical, uint32_t& count, std::vector<uint8_t>& marks) {
  // Padding: R/4 texels (at least 16, at most R), but no more than 4 typical feature sides:
  // far wider than the features that cross the edges, and on a large texture of small
  // features a fraction of the work.
  const int feature_side = int(std::ceil(std::sqrt(double(typical))));
  const int pad = std::min(r, std::max(16, std::min(r / 4, 4 * feature_side)));
  const int side = r + 2 * pad;
  cv::Mat plane(r, r, CV_8UC1), value_plane(r, r, CV_8UC1, const_cast<uint8_t*>(values.data()));
  for (size_t i = 0; i < mask.size(); ++i) plane.data[i] = mask[i] ? 255 : 0;
  cv::Mat padded, padded_values;
  cv::copyMakeBorder(plane, padded, pad, pad, pad, pad, cv::BORDER_WRAP);
  cv::copyMakeBorder(value_plane, padded_values, pad, pad, pad, pad, cv::BORDER_WRAP);

  cv::Mat distance, components;
  cv::distanceTransform(padded, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const int component_count = cv::connectedComponents(padded, components, 4, CV_32S);
  std::vector<float> peak(size_t(component_count), 0.f);
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      const int c = components.at<int32_t>(y, x);
      if (c > 0) peak[size_t(c)] = std::max(peak[size_t(c)], distance.at<float>(y, x));
    }
  // A core is where the distance is at least 0.4 of its component's peak, or of the typical
  // peak if that is lower: in two features merged through a gap, the smaller one keeps a core
  // of its own (its peak may be below half the larger one's), while the gap, narrower than
  // either, has none.
  // Typical peak: area-weighted median over the components (specks barely count).
  std::vector<uint64_t> area(size_t(component_count), 0);
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) ++area[size_t(components.at<int32_t>(y, x))];
  std::vector<std::pair<float, uint64_t>> peaks;
  uint64_t total = 0;
  for (int c = 1; c < component_count; ++c) peaks.emplace_back(peak[size_t(c)], area[size_t(c)]), total += area[size_t(c)];
  std::sort(peaks.begin(), peaks.end());
  float typical_peak = 0.f;
  for (uint64_t running = 0; const auto& [p, a] : peaks)
    if (2 * (running += a) >= total) {
      typical_peak = p;
      break;
    }
  constexpr float core_fraction = 0.4f;
  cv::Mat cores(side, side, CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      const int c = components.at<int32_t>(y, x);
      if (c > 0 && distance.at<float>(y, x) >= core_fraction * std::min(peak[size_t(c)], std::max(typical_peak, 1.f)))
        cores.at<uint8_t>(y, x) = 255;
    }
  cv::Mat markers;
  cv::connectedComponents(cores, markers, 4, CV_32S);
  // Watershed markers: 1 = background, 2.. = cores, 0 = to flood.
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      int32_t& m = markers.at<int32_t>(y, x);
      m = padded.at<uint8_t>(y, x) == 0 ? 1 : m > 0 ? m + 1 : 0;
    }
  cv::Mat colour;
  cv::cvtColor(padded_values, colour, cv::COLOR_GRAY2BGR);
  cv::watershed(colour, markers);

  // Mask texels the flood left on a boundary (-1) or gave to the background (1) join the
  // feature of a 4-neighbour, breadth first; split lines (boundaries between two cores) are
  // marked for the debug image.
  std::vector<size_t> frontier;
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x)
      if (padded.at<uint8_t>(y, x) && markers.at<int32_t>(y, x) >= 2) frontier.push_back(size_t(y) * size_t(side) + size_t(x));
  auto* m = reinterpret_cast<int32_t*>(markers.data);
  std::vector<uint8_t> boundary(size_t(side) * size_t(side), 0);
  for (size_t i = 0; i < boundary.size(); ++i) boundary[i] = m[i] == -1 && padded.data[i] ? 1 : 0;
  std::vector<size_t> next;
  while (!frontier.empty()) {
    next.clear();
    for (size_t i : frontier) {
      const int x = int(i % size_t(side)), y = int(i / size_t(side));
      for (int s = 0; s < 4; ++s) {
        const int nx = x + k_step_x[s], ny = y + k_step_y[s];
        if (nx < 0 || ny < 0 || nx >= side || ny >= side) continue;
        const size_t n = size_t(ny) * size_t(side) + size_t(nx);
        if (padded.data[n] && m[n] < 2) {
          m[n] = m[i];
          next.push_back(n);
        }
      }
    }
    frontier.swap(next);
  }

  double max_marker = 0.0;
  cv::minMaxLoc(markers, nullptr, &max_marker);
  UnionFind joined(size_t(max_marker) + 1);
  // Padding within pad/2 of the texture: far enough from the outer edge that the flood there
  // saw the same neighbourhood as the texels it repeats.
  const int reach = std::max(1, pad / 2);
  for (int y = pad - reach; y < pad + r + reach; ++y)
    for (int x = pad - reach; x < pad + r + reach; ++x) {
      const int32_t a = markers.at<int32_t>(y, x);
      if (a < 2) continue;
      const int32_t b = markers.at<int32_t>(wrap(y - pad, r) + pad, wrap(x - pad, r) + pad);
      if (b >= 2) joined.join(a, b);
    }
  std::vector<int32_t> labels(mask.size(), k_background);
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      const size_t p = size_t(y + pad) * size_t(side) + size_t(x + pad);
      if (!mask[texel_index(x, y, r)] || m[p] < 2) continue;
      labels[texel_index(x, y, r)] = joined.find(m[p]);
      if (!boundary[p]) continue;
      // A boundary texel between two different features is a split line.
      bool split = false;
      for (int s = 0; s < 4 && !split; ++s) {
        const size_t n = size_t(y + pad + k_step_y[s]) * size_t(side) + size_t(x + pad + k_step_x[s]);
        split = m[n] >= 2 && joined.find(m[n]) != joined.find(m[p]);
      }
      if (split) marks[texel_index(x, y, r)] = 3;
    }
  // Renumber 0..count-1 in row-major order of first texel.
  std::vector<int32_t> renumber(size_t(max_marker) + 1, k_background);
  count = 0;
  for (int32_t& l : labels) {
    if (l < 0) continue;
    if (renumber[size_t(l)] == k_background) renumber[size_t(l)] = int32_t(count++);
    l = renumber[size_t(l)];
  }
  return labels;
}

FeatureLabels label_mask(std::vector<uint8_t>& mask, const std::vector<uint8_t>& values, int r,
                         const IsolationOptions& options, IsolationReport& rep) {
  uint32_t count = 0;
  auto components = label_components(mask, r, count);
  const uint32_t typical = typical_area(label_sizes(components, count));
  if (options.fill_holes) {
    // With joints cut, a background component must also be shorter than a quarter of the
    // typical feature's side: a piece of joint cut off from the network is long and separates
    // two features.
    const int max_extent = options.cut_joints ? std::max(2, int(std::lround(0.25 * std::sqrt(double(typical)))))
                                              : std::numeric_limits<int>::max();
    rep.holes_filled = fill_pin_holes(mask, r, std::max<uint32_t>(1, typical / 16), max_extent, rep.marks);
    if (rep.holes_filled) components = label_components(mask, r, count);
  }
  rep.components = count;

  std::vector<int32_t> labels;
  if (options.erode_texels > 0) {
    labels = label_components(erode(mask, r, options.erode_texels), r, count);
    grow_into_mask(labels, mask, r, options.erode_texels);
  } else if (options.split_touching && count > 0) {
    labels = split_touching(mask, values, r, typical, count, rep.marks);
  } else {
    labels = std::move(components);
  }
  rep.split_added = count > rep.components ? count - rep.components : 0;

  const auto sizes = label_sizes(labels, count);
  rep.speck_limit = std::max(options.min_feature_texels,
                             uint32_t(std::ceil(options.speck_fraction * double(typical_area(sizes)))));
  for (size_t i = 0; i < labels.size(); ++i)
    if (labels[i] >= 0 && sizes[size_t(labels[i])] < rep.speck_limit) rep.marks[i] = 2;
  FeatureLabels result = compact_labels(std::move(labels), count, r, rep.speck_limit);
  rep.specks_dropped = count - result.count;
  return result;
}

struct Candidate {
  FeatureLabels labels;
  IsolationReport report;
};

// Step 4: thin joints. A ridge (light line) or valley (dark line) measure from the Hessian of
// the values smoothed at sigma 1 and 2 texels, on the texture padded periodically: per texel,
// sigma^2 (l1 - |l2|) where l1 >= l2 are the Hessian's eigenvalues taken with the sign that
// makes the line's cross-section positive, 0 where l1 <= 0; the larger over both scales. A line
// (one strong curvature across it, little along it) scores high, a blob (both strong) or a
// smooth shading gradient low.
std::vector<float> line_response(const std::vector<uint8_t>& values, int r, bool dark_lines) {
  std::vector<float> best(values.size(), 0.f);
  cv::Mat plane(r, r, CV_32FC1);
  for (size_t i = 0; i < values.size(); ++i) reinterpret_cast<float*>(plane.data)[i] = float(values[i]);
  for (const double sigma : {1.0, 2.0}) {
    const int pad = std::min(r, int(std::ceil(4.0 * sigma)) + 2);
    cv::Mat padded, blurred, dxx, dyy, dxy;
    cv::copyMakeBorder(plane, padded, pad, pad, pad, pad, cv::BORDER_WRAP);
    cv::GaussianBlur(padded, blurred, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
    cv::Sobel(blurred, dxx, CV_32F, 2, 0, 3);
    cv::Sobel(blurred, dyy, CV_32F, 0, 2, 3);
    cv::Sobel(blurred, dxy, CV_32F, 1, 1, 3);
    const float sign = dark_lines ? 1.f : -1.f, scale = float(sigma * sigma);
    for (int y = 0; y < r; ++y) {
      const float* a = dxx.ptr<float>(y + pad) + pad;
      const float* b = dyy.ptr<float>(y + pad) + pad;
      const float* c = dxy.ptr<float>(y + pad) + pad;
      float* out = best.data() + texel_index(0, y, r);
      for (int x = 0; x < r; ++x) {
        const float xx = sign * a[x], yy = sign * b[x], xy = sign * c[x];
        const float mean = 0.5f * (xx + yy), half = std::sqrt(0.25f * (xx - yy) * (xx - yy) + xy * xy);
        const float l1 = mean + half, l2 = mean - half;
        if (l1 > 0.f) out[x] = std::max(out[x], scale * (l1 - std::abs(l2)));
      }
    }
  }
  return best;
}

// Joints of the background's polarity (dark lines when the features are light): the line
// measure scaled so that its 99th percentile (of the positive texels) is 255; texels above
// Otsu's level of that are strong, above 0.4 of it weak; the joints are the 8-connected weak
// components that hold a strong texel and at least 1/50 of the texels of the largest one, the
// network (hysteresis, as in Canny's edge detector: a faint stretch of a joint is kept because
// it continues a clear one, isolated grain is not). Relative to the network, so the same at
// any resolution; a texture made of many repeats of a small one keeps fewer isolated pieces.
// Returns 1 per joint texel.
std::vector<uint8_t> find_joints(const std::vector<uint8_t>& values, int r, bool dark_lines) {
  const std::vector<float> response = line_response(values, r, dark_lines);
  std::vector<float> positive;
  for (float v : response)
    if (v > 0.f) positive.push_back(v);
  std::vector<uint8_t> joints(values.size(), 0);
  if (positive.empty()) return joints;
  const size_t k = size_t(0.99 * double(positive.size() - 1));
  std::nth_element(positive.begin(), positive.begin() + ptrdiff_t(k), positive.end());
  const float p99 = std::max(positive[k], 1e-6f);
  std::vector<uint8_t> scaled(values.size());
  for (size_t i = 0; i < values.size(); ++i) scaled[i] = uint8_t(std::clamp(response[i] / p99 * 255.f, 0.f, 255.f));
  const std::optional<int> level = otsu_level(scaled);
  if (!level) return joints;
  const double strong = *level, weak = 0.4 * *level;
  std::vector<uint8_t> weak_mask(values.size());
  for (size_t i = 0; i < values.size(); ++i) weak_mask[i] = scaled[i] > weak ? 1 : 0;
  uint32_t count = 0;
  const auto labels = label_components(weak_mask, r, count, 8);
  if (count == 0) return joints;
  const auto sizes = label_sizes(labels, count);
  const uint32_t largest = *std::max_element(sizes.begin(), sizes.end());
  std::vector<uint8_t> keep(count, 0);
  for (size_t i = 0; i < values.size(); ++i)
    if (labels[i] >= 0 && scaled[i] > strong) keep[size_t(labels[i])] = 1;
  for (size_t l = 0; l < count; ++l)
    if (50.0 * double(sizes[l]) < double(largest)) keep[l] = 0;
  for (size_t i = 0; i < values.size(); ++i) joints[i] = labels[i] >= 0 && keep[size_t(labels[i])] ? 1 : 0;
  return joints;
}

// The channel at one smoothing scale, optionally relative to its wide neighbourhood.
std::vector<uint8_t> channel_values(const std::vector<uint8_t>& raw, int r, double sigma, double background_sigma) {
  std::vector<uint8_t> values = smooth_wrapped(raw, r, sigma);
  if (background_sigma > 0.0) {
    // Shading removed: the value relative to its neighbourhood, centred on 128.
    const auto background = smooth_wrapped(values, r, background_sigma);
    for (size_t i = 0; i < values.size(); ++i)
      values[i] = uint8_t(std::clamp(128 + int(values[i]) - int(background[i]), 0, 255));
  }
  return values;
}

// Steps 1-7 with the options' smoothing and background scale.
Candidate isolate_once(const std::vector<uint8_t>& raw, int r, double sigma, double background_sigma,
                       const IsolationOptions& options) {
  Candidate c;
  IsolationReport& rep = c.report;
  rep.marks.assign(raw.size(), 0);
  rep.smooth_sigma = sigma;
  rep.background_sigma = background_sigma;
  const std::vector<uint8_t> values = channel_values(raw, r, sigma, background_sigma);
  c.labels.resolution = r;
  c.labels.labels.assign(values.size(), k_background);
  // Light side: value > cut, value and cut in 0..255 units. Otsu's level k becomes the cut
  // k + 0.5, so the light and dark sides are complements.
  auto cut_of = [&](const std::vector<uint8_t>& v) -> std::optional<double> {
    if (options.threshold >= 0.0) return std::min(options.threshold, 1.0) * 255.0;
    const std::optional<int> level = otsu_level(v);
    if (!level) return std::nullopt;
    return *level + 0.5;
  };
  const std::optional<double> cut = cut_of(values);
  if (!cut) return c;  // a flat channel has no features on either side
  rep.cut = *cut;
  std::vector<uint8_t> light(values.size()), dark(values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    light[i] = values[i] > rep.cut ? 1 : 0;
    dark[i] = 1 - light[i];
  }
  // Polarity: the network shares at the smoothing scale and at half and twice it, summed, so
  // that neither the grain (fine scale) nor the shading (coarse scale) decides alone.
  rep.polarity_forced = options.polarity != IsolationOptions::Polarity::Auto;
  double light_share = 0.0, dark_share = 0.0;
  for (const double factor : {0.5, 1.0, 2.0}) {
    if (factor == 1.0) {
      light_share += network_share(light, r);
      dark_share += network_share(dark, r);
      continue;
    }
    const std::vector<uint8_t> v = channel_values(raw, r, sigma * factor, background_sigma);
    const std::optional<double> k = cut_of(v);
    std::vector<uint8_t> l(v.size()), d(v.size());
    for (size_t i = 0; i < v.size(); ++i) {
      l[i] = k && v[i] > *k ? 1 : 0;
      d[i] = 1 - l[i];
    }
    light_share += network_share(l, r);
    dark_share += network_share(d, r);
  }
  rep.light_network_share = light_share / 3.0;
  rep.dark_network_share = dark_share / 3.0;
  rep.features_light = rep.polarity_forced ? options.polarity == IsolationOptions::Polarity::Light
                                           : rep.dark_network_share >= rep.light_network_share;
  std::vector<uint8_t>& mask = rep.features_light ? light : dark;
  if (options.cut_joints) {
    // Joints cut the mask where they are faint (the level alone joins features there); the
    // cells between the joints that are at least 15 % feature-coloured take back their
    // shaded, background-coloured texels.
    const std::vector<uint8_t> joints = find_joints(values, r, rep.features_light);
    std::vector<uint8_t> open(values.size());
    for (size_t i = 0; i < values.size(); ++i) open[i] = joints[i] ? 0 : 1;
    uint32_t cells = 0;
    const auto cell = label_components(open, r, cells);
    std::vector<uint32_t> inside(cells, 0), total(cells, 0);
    for (size_t i = 0; i < values.size(); ++i)
      if (cell[i] >= 0) {
        ++total[size_t(cell[i])];
        if (mask[i]) ++inside[size_t(cell[i])];
      }
    std::vector<uint8_t> reclaims(cells, 0);
    for (size_t l = 0; l < cells; ++l) reclaims[l] = double(inside[l]) > 0.15 * double(total[l]);
    for (size_t i = 0; i < values.size(); ++i) {
      rep.joint_texels += joints[i];
      const bool feature_cell = cell[i] >= 0 && reclaims[size_t(cell[i])];
      const uint8_t m = !joints[i] && (mask[i] || feature_cell) ? 1 : 0;
      if (m && !mask[i]) ++rep.reclaimed_texels;
      mask[i] = m;
    }
  }
  c.labels = label_mask(mask, values, r, options, rep);
  return c;
}

}  // namespace

std::string IsolationReport::summary() const {
  char joints[96] = "";
  if (joint_texels > 0 || reclaimed_texels > 0)
    std::snprintf(joints, sizeof joints, "%u joint texels cut, %u shaded texels reclaimed; ", joint_texels,
                  reclaimed_texels);
  char text[768];
  std::snprintf(text, sizeof text,
                "%s features on %s (smoothed, sigma %.1f%s), cut %.1f/255; largest-component share of the light "
                "side %.2f, dark side %.2f (%s); %s%u components, %u pin-holes filled, +%u split by the watershed, "
                "%u specks dropped (< %u texels)",
                features_light ? "light" : "dark", used_height ? "height" : "luminance", smooth_sigma,
                background_sigma > 0.0 ? (", relative to a sigma " + std::to_string(int(std::lround(background_sigma))) +
                                          " background").c_str()
                                       : "",
                cut, light_network_share, dark_network_share,
                polarity_forced ? "polarity given" : "the other side is the network", joints, components,
                holes_filled, split_added, specks_dropped, speck_limit);
  return text;
}

FeatureLabels isolate_features(const ImageRGBA8& albedo, const IsolationOptions& options, IsolationReport* report) {
  TVT_CHECK(albedo.width > 0 && albedo.width == albedo.height);
  TVT_CHECK(albedo.texels.size() == size_t(albedo.width) * size_t(albedo.height) * 4);
  const int r = albedo.width;
  bool height = options.channel == IsolationOptions::Channel::Height;
  if (options.channel == IsolationOptions::Channel::Auto)
    for (size_t i = 3; i < albedo.texels.size() && !height; i += 4) height = albedo.texels[i] != albedo.texels[3];
  std::vector<uint8_t> raw(size_t(r) * size_t(r));
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      const uint8_t* t = albedo.at(x, y);
      raw[texel_index(x, y, r)] = height ? t[3] : luminance8(t);
    }
  Candidate c = isolate_once(raw, r, options.smooth_sigma, options.background_sigma, options);
  c.report.used_height = height;
  if (report) *report = std::move(c.report);
  return std::move(c.labels);
}

FeatureLabels labels_from_mask(const ImageGray8& mask, uint32_t min_feature_texels) {
  TVT_CHECK(mask.width > 0 && mask.width == mask.height);
  TVT_CHECK(mask.texels.size() == size_t(mask.width) * size_t(mask.height));
  std::vector<uint8_t> binary(mask.texels.size());
  for (size_t i = 0; i < binary.size(); ++i) binary[i] = mask.texels[i] != 0 ? 1 : 0;
  uint32_t count = 0;
  auto labels = label_components(binary, mask.width, count);
  return compact_labels(std::move(labels), count, mask.width, min_feature_texels);
}

ImageGray8 mask_from_labels(const FeatureLabels& labels, int width, int height) {
  const int r = labels.resolution;
  TVT_CHECK(r > 0 && labels.labels.size() == size_t(r) * size_t(r) && width > 0 && height > 0);
  std::vector<uint8_t> texel(labels.labels.size(), 0);
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) {
      const int32_t l = labels.labels[texel_index(x, y, r)];
      if (l < 0) continue;
      bool split = false;
      for (int s = 0; s < 4 && !split; ++s) {
        const int32_t n = labels.labels[texel_index(wrap(x + k_step_x[s], r), wrap(y + k_step_y[s], r), r)];
        split = n >= 0 && n < l;
      }
      texel[texel_index(x, y, r)] = split ? 0 : 255;
    }
  // Per pixel p of an axis of `size` pixels, the texels reading it, [first, end):
  // floor(t * size / r) = p, i.e. ceil(p r / size) <= t < ceil((p + 1) r / size); none where
  // the image is larger, and then the texel under it.
  auto readers = [r](int size) {
    std::vector<std::pair<int, int>> range(static_cast<size_t>(size));
    for (int p = 0; p < size; ++p) {
      const int lo = int((int64_t(p) * r + size - 1) / size), hi = int((int64_t(p + 1) * r + size - 1) / size);
      const int under = int(int64_t(p) * r / size);
      range[size_t(p)] = lo < hi ? std::pair{lo, hi} : std::pair{under, under + 1};
    }
    return range;
  };
  const auto columns = readers(width), rows = readers(height);
  ImageGray8 mask(width, height);
  for (int py = 0; py < height; ++py)
    for (int px = 0; px < width; ++px) {
      uint8_t v = 255;
      for (int y = rows[size_t(py)].first; y < rows[size_t(py)].second; ++y)
        for (int x = columns[size_t(px)].first; x < columns[size_t(px)].second; ++x) v = std::min(v, texel[texel_index(x, y, r)]);
      mask.at(px, py) = v;
    }
  return mask;
}

}  // namespace tvt
