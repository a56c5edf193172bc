// Terrain chunk grid, LOD selection, frustum culling and the VT texel precision of the
// raster path (terrain/terrain_mesh.h, shaders/shared/terrain_types.h).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "terrain/terrain_mesh.h"
#include "shared/terrain_types.h"

namespace tvt {
namespace {

ImageF hilly(int n) {
  ImageF hf(n, n, 1);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      hf.at(x, y) = float(0.5 + 0.4 * std::sin(x * 0.21) * std::cos(y * 0.17));
  return hf;
}

VtConfig vt_config(uint32_t log2_size) {
  VtConfig vt;
  vt.log2_size = log2_size;
  return vt;
}

TEST(TerrainMeshTest, LayoutLodRangesAndSkirts) {
  auto mesh = TerrainMesh::create(hilly(256), 4096.0, 500.0, vt_config(16));
  ASSERT_TRUE(mesh) << mesh.error().message;
  EXPECT_EQ(mesh->chunks_per_side(), 8u);  // 256 heightfield texels / 32 quads
  EXPECT_EQ(mesh->chunk_texels(), 65536 / 8);
  EXPECT_EQ(mesh->quad_texels(), 65536u / 8u / 32u);
  EXPECT_EQ(mesh->lod_count(), 6u);  // steps 1 ... 32
  for (uint32_t k = 0; k < mesh->lod_count(); ++k) {
    const uint32_t q = 32u >> k;
    EXPECT_EQ(mesh->lod(k).index_count, 6u * q * q + 4u * 6u * q) << k;  // grid + four skirt walls
  }
  auto no_skirts = TerrainMesh::create(hilly(256), 4096.0, 500.0, vt_config(16), {32, 0, {}, false});
  ASSERT_TRUE(no_skirts);
  EXPECT_EQ(no_skirts->lod(0).index_count, 6u * 32u * 32u);
  // Rejections name the field.
  auto bad = TerrainMesh::create(hilly(256), 4096.0, 500.0, vt_config(16), TerrainMeshOptions{24, 0, {}, true});
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("quads_per_chunk"), std::string::npos);
}

TEST(TerrainMeshTest, HeightsMatchTheHeightfieldAndBoundsHoldEveryVertex) {
  const ImageF hf = hilly(64);
  auto mesh = TerrainMesh::create(hf, 1000.0, 200.0, vt_config(12), TerrainMeshOptions{16, 4, {}, true});
  ASSERT_TRUE(mesh);
  const int64_t v = mesh->vt_texels(), cell = v / 64;
  // At a heightfield texel centre the bilinear sample is that texel.
  for (int j : {0, 5, 63})
    for (int i : {0, 17, 63})
      EXPECT_EQ(mesh->height01_at_texel(i * cell + cell / 2, j * cell + cell / 2), hf.at(i, j));
  // The fixed-point path agrees with the double bilinear sample at vertex positions.
  for (int64_t y = 0; y <= v; y += 97)
    for (int64_t x = 0; x <= v; x += 89) {
      const double xm = double(x) * mesh->metres_per_texel(), ym = double(y) * mesh->metres_per_texel();
      EXPECT_NEAR(mesh->height01_at_texel(x, y) * 200.0, mesh->height_m_at(xm, ym), 1e-3);
    }
  // Every LOD-0 vertex of every chunk lies inside its chunk's bounds.
  for (uint32_t cy = 0; cy < 4; ++cy)
    for (uint32_t cx = 0; cx < 4; ++cx) {
      const auto& b = mesh->bounds(cx, cy);
      for (uint32_t j = 0; j <= 16; ++j)
        for (uint32_t i = 0; i <= 16; ++i) {
          const double h = mesh->height01_at_texel(cx * mesh->chunk_texels() + i * mesh->quad_texels(),
                                                   cy * mesh->chunk_texels() + j * mesh->quad_texels()) * 200.0;
          EXPECT_GE(h, b.min_z_m - 1e-9);
          EXPECT_LE(h, b.max_z_m + 1e-9);
        }
      EXPECT_GT(b.skirt_depth_m, b.max_z_m - b.min_z_m);
    }
}

TEST(TerrainMeshTest, LodGrowsWithDistance) {
  auto mesh = TerrainMesh::create(hilly(256), 8192.0, 500.0, vt_config(16), {32, 16, {300.0, 900.0, 2000.0}});
  ASSERT_TRUE(mesh);
  EXPECT_EQ(mesh->lod_count(), 4u);
  EXPECT_EQ(mesh->select_lod(0.0), 0u);
  EXPECT_EQ(mesh->select_lod(299.0), 0u);
  EXPECT_EQ(mesh->select_lod(301.0), 1u);
  EXPECT_EQ(mesh->select_lod(1000.0), 2u);
  EXPECT_EQ(mesh->select_lod(1e9), 3u);

  Camera cam;
  cam.position_m = {4096.0, 4096.0, 800.0};
  cam.pitch_rad = -0.3;
  cam.far_m = 20000.0;
  ChunkSelectStats stats;
  const auto draws = mesh->select(cam, 16.0 / 9.0, &stats);
  ASSERT_FALSE(draws.empty());
  uint32_t max_lod = 0;
  for (const ChunkDraw& d : draws) {
    EXPECT_EQ(d.lod, mesh->select_lod(d.distance_m));
    max_lod = std::max(max_lod, d.lod);
    if (d.distance_m == 0.0) {
      EXPECT_EQ(d.lod, 0u);
    }
  }
  EXPECT_EQ(max_lod, 3u);
  uint32_t sum = 0;
  for (uint32_t c : stats.per_lod) sum += c;
  EXPECT_EQ(sum, draws.size());
  EXPECT_EQ(stats.total, 256u);
  EXPECT_EQ(stats.total - stats.culled, draws.size());
}

TEST(TerrainMeshTest, FrustumCullingKeepsEveryVisibleChunkAndDropsTheRest) {
  auto mesh = TerrainMesh::create(hilly(256), 8192.0, 500.0, vt_config(16), TerrainMeshOptions{32, 32, {}, true});
  ASSERT_TRUE(mesh);
  Camera cam;
  cam.position_m = {2000.0, 3000.0, 600.0};
  cam.yaw_rad = 0.4;
  cam.pitch_rad = -0.25;
  cam.far_m = 5000.0;
  const double aspect = 1.5;
  ChunkSelectStats stats;
  const auto draws = mesh->select(cam, aspect, &stats);
  std::vector<char> drawn(32 * 32, 0);
  for (const ChunkDraw& d : draws) drawn[size_t(d.origin_y / mesh->chunk_texels()) * 32 + size_t(d.origin_x / mesh->chunk_texels())] = 1;
  // Some chunks are culled (behind the camera, beyond far), some drawn.
  EXPECT_GT(stats.culled, 32u * 32u / 3);
  EXPECT_GT(draws.size(), 10u);
  // Every terrain surface point inside the view volume belongs to a drawn chunk.
  const glm::dmat4 clip = cam.clip_from_relative(aspect);
  int inside = 0;
  for (double y = 1.0; y < 8192.0; y += 16.0)
    for (double x = 1.0; x < 8192.0; x += 16.0) {
      const glm::dvec4 c = clip * glm::dvec4(glm::dvec3(x, y, mesh->height_m_at(x, y)) - cam.position_m, 1.0);
      if (c.w <= 0 || std::abs(c.x) > c.w || std::abs(c.y) > c.w || c.z < 0 || c.z > c.w) continue;
      ++inside;
      const size_t cx = size_t(x / mesh->chunk_m()), cy = size_t(y / mesh->chunk_m());
      EXPECT_TRUE(drawn[cy * 32 + cx]) << "visible point (" << x << ", " << y << ") in a culled chunk";
    }
  EXPECT_GT(inside, 100);
  // And no drawn chunk is far outside: every drawn chunk's box touches the view volume
  // (checked by construction); a chunk wholly behind the camera must be culled.
  for (const ChunkDraw& d : draws) {
    const double cx = (double(d.origin_x) + 0.5 * double(mesh->chunk_texels())) * mesh->metres_per_texel();
    const double cy = (double(d.origin_y) + 0.5 * double(mesh->chunk_texels())) * mesh->metres_per_texel();
    const glm::dvec3 to = glm::dvec3(cx, cy, cam.position_m.z) - cam.position_m;
    EXPECT_GT(glm::dot(to, cam.forward()), -mesh->chunk_m());
  }
}

// The fragment's VT texel coordinate at V = 2^24 and the far corner, with the arithmetic of
// terrain.vert/terrain_fragment.glsl emulated in fp32: integer anchor-relative vertex texels
// (tvt_vertex_rel_texel), one conversion to float, barycentric interpolation in float, then
// floor/fract reconstruction against the int64 anchor.
TEST(TerrainPrecisionTest, FarCornerTexelWithinOne256thOfATexel) {
  const uint32_t log2_vt = 24;
  const int64_t v = int64_t(1) << log2_vt;
  const uint32_t quad_texels = 8192;  // e.g. 64 chunks x 32 quads
  const int64_t chunk_texels = 32 * int64_t(quad_texels);
  const double mpt = 0.01;  // 1 cm texels: a 168 km terrain
  const glm::dvec2 camera_m = glm::dvec2(double(v) - 330.7, double(v) - 270.3) * mpt;
  const int64_t anchor_x = int64_t(std::floor(camera_m.x / mpt)), anchor_y = int64_t(std::floor(camera_m.y / mpt));
  const int64_t chunk_x = v - chunk_texels, chunk_y = v - chunk_texels;  // the far-corner chunk
  const glm::ivec2 rel_chunk(int32_t(chunk_x - anchor_x), int32_t(chunk_y - anchor_y));

  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double worst = 0.0, worst_naive = 0.0;
  for (int n = 0; n < 20000; ++n) {
    // A point in one of the LOD-0 quads around the camera (and the far-corner quad itself).
    const uint32_t i = n % 7 == 0 ? 31u : 29u + uint32_t(n % 3), j = n % 7 == 0 ? 31u : 30u + uint32_t(n % 2);
    const double a = unit(rng), b = unit(rng) * (1.0 - a);  // barycentrics of (i,j), (i+1,j), (i+1,j+1)
    const glm::ivec2 p0 = gpu::tvt_vertex_rel_texel(rel_chunk, i, j, quad_texels);
    const glm::ivec2 p1 = gpu::tvt_vertex_rel_texel(rel_chunk, i + 1, j, quad_texels);
    const glm::ivec2 p2 = gpu::tvt_vertex_rel_texel(rel_chunk, i + 1, j + 1, quad_texels);
    // Analytic level-0 texel coordinate (double, exact enough: |x| < 2^25, 2^-28 resolution).
    const glm::dvec2 exact = glm::dvec2(anchor_x, anchor_y) + glm::dvec2(p0) * a + glm::dvec2(p1) * b +
                             glm::dvec2(p2) * (1.0 - a - b);
    // GPU arithmetic in fp32.
    const float fa = float(a), fb = float(b), fc = 1.0f - fa - fb;
    const glm::vec2 local = glm::vec2(p0) * fa + glm::vec2(p1) * fb + glm::vec2(p2) * fc;
    const glm::vec2 whole = glm::floor(local);
    const glm::vec2 frac = local - whole;
    const double rx = double(anchor_x + int64_t(whole.x)) + double(frac.x);
    const double ry = double(anchor_y + int64_t(whole.y)) + double(frac.y);
    // Keep only the barycentric rounding of the inputs out of the comparison: the analytic
    // point is the one the float barycentrics describe.
    const glm::dvec2 exact_f = glm::dvec2(anchor_x, anchor_y) + glm::dvec2(p0) * double(fa) +
                               glm::dvec2(p1) * double(fb) + glm::dvec2(p2) * double(fc);
    worst = std::max({worst, std::abs(rx - exact_f.x), std::abs(ry - exact_f.y)});
    // A whole-terrain float UV in [0,1] cannot name the texel at all (docs/composition.md).
    const float uv = float(exact.x / double(v));
    worst_naive = std::max(worst_naive, std::abs(double(uv) * double(v) - exact.x));
  }
  EXPECT_LE(worst, 1.0 / 256.0) << "worst error " << worst << " texels";
  EXPECT_GT(worst_naive, 0.25) << "the naive fp32 UV should fail by a large fraction of a texel";
}

}  // namespace
}  // namespace tvt
