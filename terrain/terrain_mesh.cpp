// Terrain chunk grid, LOD and culling (see terrain_mesh.h).
#include "terrain/terrain_mesh.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <string>

#include "shared/terrain_types.h"

namespace tvt {

Result<TerrainMesh> TerrainMesh::create(const ImageF& heightfield, double extent_m, double height_m,
                                        const VtConfig& vt, const TerrainMeshOptions& options) {
  const std::string where = "terrain mesh: ";
  if (heightfield.width < 2 || heightfield.height < 2 || heightfield.width > 65536 || heightfield.height > 65536 ||
      heightfield.data.size() != size_t(heightfield.width) * size_t(heightfield.height) * size_t(heightfield.channels))
    return make_error(where + "heightfield must be 2 ... 65536 texels per side");
  if (!(extent_m > 0.0) || !(height_m >= 0.0) || !std::isfinite(extent_m) || !std::isfinite(height_m))
    return make_error(where + "extent_m must be > 0 and height_m >= 0");
  if (vt.log2_size < 10 || vt.log2_size > 30) return make_error(where + "VT log2_size must be in 10 ... 30");
  const uint32_t q = options.quads_per_chunk;
  if (q < 2 || q > 256 || !std::has_single_bit(q))
    return make_error(where + "quads_per_chunk must be a power of two in 2 ... 256, got " + std::to_string(q));
  uint32_t cps = options.chunks_per_side;
  if (cps == 0) {
    const uint32_t hf = uint32_t(std::max(heightfield.width, heightfield.height));
    cps = std::max(1u, std::bit_floor(std::max(1u, hf / q)));
  }
  if (!std::has_single_bit(cps)) return make_error(where + "chunks_per_side must be a power of two");
  const int64_t v = int64_t(1) << vt.log2_size;
  if (int64_t(cps) * q > v)
    return make_error(where + "chunks_per_side * quads_per_chunk exceeds the VT size (quads must be >= 1 texel)");
  for (size_t k = 0; k < options.lod_distances_m.size(); ++k)
    if (!(options.lod_distances_m[k] > 0.0) || (k > 0 && options.lod_distances_m[k] <= options.lod_distances_m[k - 1]))
      return make_error(where + "lod_distances_m must be positive and increasing");

  TerrainMesh m;
  m.heightfield_ = ImageF(heightfield.width, heightfield.height, 1);
  for (int y = 0; y < heightfield.height; ++y)
    for (int x = 0; x < heightfield.width; ++x) m.heightfield_.at(x, y) = heightfield.at(x, y, 0);
  m.extent_m_ = extent_m;
  m.height_m_ = height_m;
  m.log2_vt_ = vt.log2_size;
  m.chunks_per_side_ = cps;
  m.chunk_texels_ = v / cps;
  m.options_ = options;
  m.options_.chunks_per_side = cps;

  // LODs: step 1, 2, ..., q; explicit distances may cap the count.
  uint32_t lod_count = uint32_t(std::countr_zero(q)) + 1;
  if (!options.lod_distances_m.empty()) lod_count = std::min(lod_count, uint32_t(options.lod_distances_m.size()) + 1);
  for (uint32_t k = 0; k + 1 < lod_count; ++k)
    m.lod_distances_m_.push_back(options.lod_distances_m.empty() ? m.chunk_m() * double(1u << k)
                                                                 : options.lod_distances_m[k]);

  // Vertices: the (q+1)^2 grid, then the same grid flagged as skirt (only edges are used).
  const uint32_t n = q + 1;
  for (uint16_t s = 0; s < 2; ++s)
    for (uint32_t j = 0; j < n; ++j)
      for (uint32_t i = 0; i < n; ++i) m.vertices_.push_back({uint16_t(i), uint16_t(j), s, 0});
  auto grid = [&](uint32_t i, uint32_t j) { return j * n + i; };
  auto skirt = [&](uint32_t i, uint32_t j) { return n * n + j * n + i; };

  // Indices per LOD. Triangles are counter-clockwise seen from above (+z).
  for (uint32_t k = 0; k < lod_count; ++k) {
    const uint32_t step = 1u << k;
    LodRange r;
    r.first_index = uint32_t(m.indices_.size());
    for (uint32_t j = 0; j < q; j += step)
      for (uint32_t i = 0; i < q; i += step) {
        const uint32_t a = grid(i, j), b = grid(i + step, j), c = grid(i + step, j + step), d = grid(i, j + step);
        m.indices_.insert(m.indices_.end(), {a, b, c, a, c, d});
      }
    if (options.skirts) {
      // Walk the boundary counter-clockwise seen from above (interior on the left); for each
      // edge segment a -> b the wall (a, a', b'), (a, b', b) faces outward.
      auto wall = [&](uint32_t ai, uint32_t aj, uint32_t bi, uint32_t bj) {
        const uint32_t a = grid(ai, aj), b = grid(bi, bj), as = skirt(ai, aj), bs = skirt(bi, bj);
        m.indices_.insert(m.indices_.end(), {a, as, bs, a, bs, b});
      };
      for (uint32_t i = 0; i < q; i += step) wall(i, 0, i + step, 0);          // south edge, +x
      for (uint32_t j = 0; j < q; j += step) wall(q, j, q, j + step);          // east edge, +y
      for (uint32_t i = q; i > 0; i -= step) wall(i, q, i - step, q);          // north edge, -x
      for (uint32_t j = q; j > 0; j -= step) wall(0, j, 0, j - step);          // west edge, -y
    }
    r.index_count = uint32_t(m.indices_.size()) - r.first_index;
    m.lods_.push_back(r);
  }

  // Bounds: every vertex height is a convex combination of the heightfield taps its
  // bilinear lookup reads, so the min/max over the taps a chunk can touch bound all LODs.
  // Cost O(heightfield texels + chunks), independent of quads_per_chunk.
  const uint32_t hw = uint32_t(m.heightfield_.width), hh = uint32_t(m.heightfield_.height);
  m.bounds_.resize(size_t(cps) * cps);
  for (uint32_t cy = 0; cy < cps; ++cy) {
    const int64_t y0 = int64_t(cy) * m.chunk_texels_, y1 = y0 + m.chunk_texels_;
    const int ty0 = gpu::tvt_hf_tap0(gpu::tvt_hf_coord_fp(y0, hh, vt.log2_size), hh);
    const int ty1 = gpu::tvt_hf_tap1(gpu::tvt_hf_coord_fp(y1, hh, vt.log2_size), hh);
    for (uint32_t cx = 0; cx < cps; ++cx) {
      const int64_t x0 = int64_t(cx) * m.chunk_texels_, x1 = x0 + m.chunk_texels_;
      const int tx0 = gpu::tvt_hf_tap0(gpu::tvt_hf_coord_fp(x0, hw, vt.log2_size), hw);
      const int tx1 = gpu::tvt_hf_tap1(gpu::tvt_hf_coord_fp(x1, hw, vt.log2_size), hw);
      float lo = std::numeric_limits<float>::max(), hi = -lo;
      for (int ty = ty0; ty <= ty1; ++ty)
        for (int tx = tx0; tx <= tx1; ++tx) {
          lo = std::min(lo, m.heightfield_.at(tx, ty));
          hi = std::max(hi, m.heightfield_.at(tx, ty));
        }
      Bounds& b = m.bounds_[size_t(cy) * cps + cx];
      b.min_z_m = double(lo) * height_m;
      b.max_z_m = double(hi) * height_m;
      // A gap at a LOD seam is at most the chunk's height range; add a small margin.
      b.skirt_depth_m = options.skirts ? (b.max_z_m - b.min_z_m) + 1e-3 * m.chunk_m() + 0.01 : 0.0;
    }
  }
  return m;
}

float TerrainMesh::height01_at_texel(int64_t x_texel, int64_t y_texel) const {
  const uint32_t w = uint32_t(heightfield_.width), h = uint32_t(heightfield_.height);
  const int64_t ux = gpu::tvt_hf_coord_fp(x_texel, w, log2_vt_), uy = gpu::tvt_hf_coord_fp(y_texel, h, log2_vt_);
  const int x0 = gpu::tvt_hf_tap0(ux, w), x1 = gpu::tvt_hf_tap1(ux, w);
  const int y0 = gpu::tvt_hf_tap0(uy, h), y1 = gpu::tvt_hf_tap1(uy, h);
  const float fx = gpu::tvt_hf_weight(ux), fy = gpu::tvt_hf_weight(uy);
  const float top = heightfield_.at(x0, y0) + (heightfield_.at(x1, y0) - heightfield_.at(x0, y0)) * fx;
  const float bottom = heightfield_.at(x0, y1) + (heightfield_.at(x1, y1) - heightfield_.at(x0, y1)) * fx;
  return top + (bottom - top) * fy;
}

double TerrainMesh::height_m_at(double x_m, double y_m) const {
  const int w = heightfield_.width, h = heightfield_.height;
  const double u = std::clamp(x_m / extent_m_, 0.0, 1.0) * w - 0.5;
  const double v = std::clamp(y_m / extent_m_, 0.0, 1.0) * h - 0.5;
  const double fu = std::floor(u), fv = std::floor(v);
  const int x0 = std::clamp(int(fu), 0, w - 1), x1 = std::clamp(int(fu) + 1, 0, w - 1);
  const int y0 = std::clamp(int(fv), 0, h - 1), y1 = std::clamp(int(fv) + 1, 0, h - 1);
  const double ax = u - fu, ay = v - fv;
  const double top = heightfield_.at(x0, y0) * (1 - ax) + heightfield_.at(x1, y0) * ax;
  const double bottom = heightfield_.at(x0, y1) * (1 - ax) + heightfield_.at(x1, y1) * ax;
  return (top * (1 - ay) + bottom * ay) * height_m_;
}

uint32_t TerrainMesh::select_lod(double distance_m) const {
  uint32_t k = 0;
  while (k < lod_distances_m_.size() && distance_m > lod_distances_m_[k]) ++k;
  return k;
}

std::vector<ChunkDraw> TerrainMesh::select(const Camera& camera, double aspect, ChunkSelectStats* stats) const {
  const Frustum frustum = Frustum::from_clip(camera.clip_from_relative(aspect));
  const double cm = chunk_m();
  std::vector<ChunkDraw> draws;
  ChunkSelectStats s;
  s.per_lod.assign(lod_count(), 0);
  for (uint32_t cy = 0; cy < chunks_per_side_; ++cy)
    for (uint32_t cx = 0; cx < chunks_per_side_; ++cx) {
      ++s.total;
      const Bounds& b = bounds(cx, cy);
      // Camera-relative box, in double.
      const glm::dvec3 lo = glm::dvec3(cx * cm, cy * cm, b.min_z_m - b.skirt_depth_m) - camera.position_m;
      const glm::dvec3 hi = glm::dvec3((cx + 1) * cm, (cy + 1) * cm, b.max_z_m) - camera.position_m;
      if (!frustum.intersects_box(lo, hi)) {
        ++s.culled;
        continue;
      }
      const glm::dvec3 nearest = glm::clamp(glm::dvec3(0.0), lo, hi);
      ChunkDraw d;
      d.origin_x = int64_t(cx) * chunk_texels_;
      d.origin_y = int64_t(cy) * chunk_texels_;
      d.distance_m = glm::length(nearest);
      d.lod = select_lod(d.distance_m);
      d.skirt_depth_m = b.skirt_depth_m;
      ++s.per_lod[d.lod];
      draws.push_back(d);
    }
  if (stats) *stats = std::move(s);
  return draws;
}

}  // namespace tvt
