// Terrain raster pass on the GPU (app/terrain_renderer.h): default-scene image sanity and
// determinism, uniform shading of flat ground, no cracks at LOD seams, and the VT texel
// coordinate at V = 2^24 against the analytic ray/ground intersection.
// TERRAVT_TEST_OUTPUT_DIR=<dir> also writes the rendered images there as PNG.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <numbers>
#include <set>

#include "compose/scene.h"
#include "compose/scene_assets.h"
#include "app/terrain_renderer.h"
#include "support/gpu_test.h"

namespace tvt {
namespace {

void maybe_write(const ImageRGBA8& image, const std::string& name) {
  const char* dir = std::getenv("TERRAVT_TEST_OUTPUT_DIR");
  if (!dir || !*dir) return;
  const Status s = write_image(std::string(dir) + "/" + name + ".png", image);
  EXPECT_TRUE(s) << s.error().message;
}

// UNORM8 encoding of a float colour as the device does it (round to nearest of x * 255 in fp32).
std::array<uint8_t, 3> unorm(const glm::dvec3& c) {
  auto enc = [](double v) { return uint8_t(std::lround(float(v) * 255.0f)); };
  return {enc(c.r), enc(c.g), enc(c.b)};
}

// Within one step per channel (the device's float-to-UNORM rounding may differ from ours).
bool is_colour(const ImageRGBA8& img, int x, int y, const std::array<uint8_t, 3>& c) {
  const uint8_t* p = img.at(x, y);
  for (int i = 0; i < 3; ++i)
    if (std::abs(int(p[i]) - int(c[size_t(i)])) > 1) return false;
  return true;
}

TerrainDesc terrain_desc(double extent_m, double height_m) {
  TerrainDesc t;
  t.extent_m = extent_m;
  t.height_m = height_m;
  return t;
}

VtConfig vt_config(uint32_t log2_size) {
  VtConfig vt;
  vt.log2_size = log2_size;
  return vt;
}

using TerrainRenderTest = GpuTest;

TEST_F(TerrainRenderTest, DefaultSceneHasSkyAndTerrainNoNaNAndIsDeterministic) {
  auto assets = load_scene_assets(default_scene());
  ASSERT_TRUE(assets) << assets.error().message;
  TerrainRendererOptions options;
  options.width = 160;
  options.height = 90;
  options.texel_output = true;
  auto renderer = TerrainRenderer::create(ctx(), *assets, options);
  ASSERT_TRUE(renderer) << renderer.error().message;
  TerrainRenderer& r = **renderer;

  const double e = assets->desc.terrain.extent_m;
  Camera cam;
  cam.position_m = {0.3 * e, 0.35 * e, 0.0};
  cam.position_m.z = r.mesh().height_m_at(cam.position_m.x, cam.position_m.y) + 250.0;
  cam.yaw_rad = 0.6;
  cam.pitch_rad = -0.12;
  cam.far_m = 2.0 * e;

  const ImageRGBA8 a = r.render(cam);
  const std::vector<uint8_t> texels = r.target().read_color(1);
  const ImageRGBA8 b = r.render(cam);
  maybe_write(a, "terrain_default_scene");
  EXPECT_EQ(a.texels, b.texels) << "two renders of the same camera differ";
  EXPECT_GT(r.last_stats().chunks.culled, 0u);
  EXPECT_GT(r.last_stats().triangles, 1000u);

  const auto sky = unorm(options.lighting.sky_color);
  int sky_pixels = 0, terrain_pixels = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      const uint8_t* p = a.at(x, y);
      EXPECT_EQ(p[3], 255) << x << "," << y;
      EXPECT_FALSE(p[0] == 255 && p[1] == 0 && p[2] == 255) << "non-finite colour at " << x << "," << y;
      uint32_t t[4];
      std::memcpy(t, &texels[(size_t(y) * size_t(a.width) + size_t(x)) * 16], 16);
      const bool covered = t[0] != TerrainRenderer::kNoTexel;
      if (covered) {
        ++terrain_pixels;
        float fx, fy;
        std::memcpy(&fx, &t[2], 4);
        std::memcpy(&fy, &t[3], 4);
        EXPECT_TRUE(fx >= 0.0f && fx < 1.0f && fy >= 0.0f && fy < 1.0f) << x << "," << y;
        EXPECT_LT(t[0], uint32_t(1) << assets->desc.vt.log2_size);
      } else {
        ++sky_pixels;
        EXPECT_TRUE(is_colour(a, x, y, sky)) << "uncovered pixel is not sky at " << x << "," << y;
      }
    }
  EXPECT_GT(sky_pixels, a.width * a.height / 20) << "image is (almost) all terrain";
  EXPECT_GT(terrain_pixels, a.width * a.height / 4) << "image is (almost) all sky";
  // The terrain is shaded, not flat: many distinct colours.
  std::set<uint32_t> colours;
  for (size_t i = 0; i < a.texels.size(); i += 4)
    colours.insert(uint32_t(a.texels[i]) | uint32_t(a.texels[i + 1]) << 8 | uint32_t(a.texels[i + 2]) << 16);
  EXPECT_GT(colours.size(), 100u);
}

TEST_F(TerrainRenderTest, FlatGroundSeenStraightDownIsUniformlyShaded) {
  ImageF flat(64, 64, 1);
  for (float& h : flat.data) h = 0.5f;
  TerrainRendererOptions options;
  options.width = 96;
  options.height = 64;
  options.lighting.fog_density_per_m = 0.0;
  options.mesh.chunks_per_side = 8;
  auto renderer = TerrainRenderer::create(ctx(), flat, terrain_desc(2000.0, 100.0), vt_config(16), options);
  ASSERT_TRUE(renderer) << renderer.error().message;
  Camera cam;
  cam.position_m = {1000.0, 1000.0, 50.0 + 80.0};
  cam.yaw_rad = 0.3;
  cam.pitch_rad = -std::numbers::pi / 2;
  const ImageRGBA8 img = (*renderer)->render(cam);
  maybe_write(img, "terrain_flat_down");
  // Expected: the ramp's grass at height 0.5, lit by sun and ambient with a vertical normal.
  const TerrainLighting& l = options.lighting;
  const glm::dvec3 grass(0.20, 0.36, 0.12);
  const double lambert = glm::normalize(l.sun_direction).z;
  const glm::dvec3 expected = grass * (l.sun_color * (l.sun_intensity * lambert) + glm::dvec3(l.ambient));
  const auto want = unorm(expected);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(int(img.at(x, y)[c]), int(want[size_t(c)]), 1) << x << "," << y << " channel " << c;
}

TEST_F(TerrainRenderTest, DefaultFlythroughFramesShowTerrainFromAboveGround) {
  auto assets = load_scene_assets(default_scene());
  ASSERT_TRUE(assets) << assets.error().message;
  TerrainRendererOptions options;
  options.width = 96;
  options.height = 54;
  options.texel_output = true;
  auto renderer = TerrainRenderer::create(ctx(), *assets, options);
  ASSERT_TRUE(renderer) << renderer.error().message;
  TerrainRenderer& r = **renderer;
  const TerrainMesh& mesh = r.mesh();
  const CameraPath path = CameraPath::default_flythrough(
      mesh.extent_m(), mesh.height_m(), [&](double x, double y) { return mesh.height_m_at(x, y); });
  Camera lens;
  lens.far_m = 2.0 * mesh.extent_m();
  for (double t = path.start_time(); t <= path.end_time(); t += 3.0) {
    const Camera cam = path.camera_at(t, lens);
    EXPECT_GE(cam.position_m.z, mesh.height_m_at(cam.position_m.x, cam.position_m.y) + path.clearance_m() - 1e-9);
    const ImageRGBA8 img = r.render(cam);
    const std::vector<uint8_t> texels = r.target().read_color(1);
    int covered = 0;
    for (size_t i = 0; i < texels.size(); i += 16) {
      uint32_t x;
      std::memcpy(&x, &texels[i], 4);
      covered += x != TerrainRenderer::kNoTexel ? 1 : 0;
    }
    EXPECT_GT(covered, img.width * img.height / 5) << "t = " << t;
    for (size_t i = 0; i < img.texels.size(); i += 4)
      ASSERT_FALSE(img.texels[i] == 255 && img.texels[i + 1] == 0 && img.texels[i + 2] == 255) << "t = " << t;
    maybe_write(img, "terrain_flythrough_" + std::to_string(int(t)));
  }
}

// Hilly or flat ground, white and unlit, over a black sky, seen from a low grazing angle with
// several LODs in view: every pixel must be terrain (the view ends on the ground everywhere).
int leaking_pixels(vk::Context& ctx, bool hilly, bool skirts, uint32_t* lods_seen) {
  const int n = 256;
  ImageF hf(n, n, 1);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      hf.at(x, y) = hilly ? float(0.5 + 0.5 * std::sin(x * 0.37) * std::cos(y * 0.29)) : 0.25f;
  TerrainRendererOptions options;
  options.width = 160;
  options.height = 90;
  options.mesh.quads_per_chunk = 32;
  options.mesh.chunks_per_side = 64;  // 64 m chunks, 2 m quads
  options.mesh.lod_distances_m = {30.0, 60.0, 120.0, 200.0};
  options.mesh.skirts = skirts;
  options.lighting.albedo_override = glm::dvec3(1.0);
  options.lighting.sun_intensity = 0.0;
  options.lighting.ambient = 1.0;
  options.lighting.fog_density_per_m = 0.0;
  options.lighting.sky_color = glm::dvec3(0.0);
  auto renderer = TerrainRenderer::create(ctx, hf, terrain_desc(4096.0, 40.0), vt_config(16), options);
  EXPECT_TRUE(renderer) << renderer.error().message;
  if (!renderer) return -1;
  TerrainRenderer& r = **renderer;
  Camera cam;
  cam.position_m = {2048.0 + 7.3, 2048.0 + 3.1, 0.0};
  cam.position_m.z = r.mesh().height_m_at(cam.position_m.x, cam.position_m.y) + 25.0;
  cam.yaw_rad = 0.37;
  cam.pitch_rad = -0.40;  // the top row looks 0.05 rad below the horizon: ground everywhere
  cam.vertical_fov_rad = 0.7;
  cam.far_m = 5000.0;
  const ImageRGBA8 img = r.render(cam);
  maybe_write(img, std::string("terrain_cracks_") + (hilly ? "hilly" : "flat") + (skirts ? "" : "_noskirts"));
  *lods_seen = 0;
  for (uint32_t c : r.last_stats().chunks.per_lod) *lods_seen += c > 0 ? 1u : 0u;
  int leaks = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) leaks += img.at(x, y)[0] != 255 ? 1 : 0;
  return leaks;
}

TEST_F(TerrainRenderTest, NoCracksAtLodSeams) {
  for (bool hilly : {false, true}) {
    uint32_t lods = 0;
    EXPECT_EQ(leaking_pixels(ctx(), hilly, true, &lods), 0) << (hilly ? "hilly" : "flat");
    EXPECT_GE(lods, 4u) << "the view must contain several LOD transitions";
  }
}

TEST_F(TerrainRenderTest, WithoutSkirtsTheCrackTestFindsCracks) {
  uint32_t lods = 0;
  EXPECT_GT(leaking_pixels(ctx(), true, false, &lods), 0) << "the crack test cannot see cracks";
}

// V = 2^24 texels of 1 cm (a 168 km terrain), camera 0.5 m above flat ground near the far
// corner looking straight down: every pixel's VT texel coordinate (integer + fraction from
// the fragment shader) must be within 1/256 texel of the analytic ray/ground intersection.
TEST_F(TerrainRenderTest, FarCornerTexelCoordinateAtTwoPow24) {
  const uint32_t log2_vt = 24;
  const double v = std::ldexp(1.0, int(log2_vt)), mpt = 0.01;
  ImageF flat(64, 64, 1);  // all zero: ground at z = 0
  TerrainRendererOptions options;
  options.width = 160;
  options.height = 90;
  options.texel_output = true;
  options.mesh.chunks_per_side = 64;  // 2^18-texel chunks, 8192-texel (82 m) quads
  auto renderer = TerrainRenderer::create(ctx(), flat, terrain_desc(v * mpt, 100.0), vt_config(log2_vt), options);
  ASSERT_TRUE(renderer) << renderer.error().message;
  TerrainRenderer& r = **renderer;
  Camera cam;
  cam.position_m = {(v - 330.7) * mpt, (v - 270.3) * mpt, 0.5};
  cam.yaw_rad = 0.9;
  cam.pitch_rad = -std::numbers::pi / 2;
  cam.near_m = 0.05;
  cam.far_m = 100.0;
  (void)r.render(cam);
  const std::vector<uint8_t> texels = r.target().read_color(1);

  const double t = std::tan(cam.vertical_fov_rad / 2), aspect = r.aspect();
  double worst = 0.0;
  for (uint32_t py = 0; py < options.height; ++py)
    for (uint32_t px = 0; px < options.width; ++px) {
      uint32_t w[4];
      std::memcpy(w, &texels[(size_t(py) * options.width + px) * 16], 16);
      ASSERT_NE(w[0], TerrainRenderer::kNoTexel) << px << "," << py;
      float fx, fy;
      std::memcpy(&fx, &w[2], 4);
      std::memcpy(&fy, &w[3], 4);
      const double gx = double(w[0]) + double(fx), gy = double(w[1]) + double(fy);
      // Analytic: the ray through the pixel centre meets z = 0.
      const double nx = (px + 0.5) / options.width * 2 - 1, ny = (py + 0.5) / options.height * 2 - 1;
      const glm::dvec3 dir = cam.forward() + cam.right() * (nx * t * aspect) - cam.up() * (ny * t);
      const glm::dvec3 hit = cam.position_m + dir * (-cam.position_m.z / dir.z);
      worst = std::max({worst, std::abs(gx - hit.x / mpt), std::abs(gy - hit.y / mpt)});
    }
  EXPECT_LE(worst, 1.0 / 256.0) << "worst texel error " << worst;
  RecordProperty("worst_texel_error", std::to_string(worst));
  std::printf("far-corner worst texel error: %.6f texels (limit %.6f)\n", worst, 1.0 / 256.0);
}

}  // namespace
}  // namespace tvt
