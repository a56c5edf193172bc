// Material images of any size and kind (compose/material_image.h): the size rule, tileable
// resampling, every input kind, luminance height, and bad files.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <numeric>
#include <string>
#include <vector>

#include "compose/image.h"
#include "compose/material_image.h"
#include "compose/scene_assets.h"
#include "support/bad_images.h"
#include "support/file_scene.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;

namespace {

class MaterialImage : public ::testing::Test {
 protected:
  void SetUp() override { dir = tvt::test::fresh_test_dir("tvt_material_image"); }
  void TearDown() override { fs::remove_all(dir); }
  std::string path(const std::string& name) const { return (dir / name).string(); }
  fs::path dir;
};

// Writes `values` (w x h x channels, 0..1) as `name` with OpenImageIO in the given type.
void write_raw(const std::string& file, int w, int h, int channels, OIIO::TypeDesc type, const std::vector<float>& values) {
  auto out = OIIO::ImageOutput::create(file);
  ASSERT_TRUE(out);
  OIIO::ImageSpec spec(w, h, channels, type);
  spec.attribute("oiio:UnassociatedAlpha", 1);
  ASSERT_TRUE(out->open(file, spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, values.data()));
  ASSERT_TRUE(out->close());
}

// A tileable pattern of period w x h: two cycles across x, one across y.
float wave(double x, double y, int w, int h) {
  return float(0.5 + 0.25 * std::sin(2 * std::numbers::pi * 2 * x / w) + 0.2 * std::cos(2 * std::numbers::pi * y / h));
}

TEST(MaterialImageRule, PicksTheNearestPowerOfTwoOfTheGeometricMeanSide) {
  EXPECT_EQ(tvt::material_resolution_for(100, 100), 128);
  EXPECT_EQ(tvt::material_resolution_for(96, 96), 128);  // log2 96 = 6.58
  EXPECT_EQ(tvt::material_resolution_for(90, 90), 64);   // log2 90 = 6.49
  EXPECT_EQ(tvt::material_resolution_for(256, 256), 256);
  EXPECT_EQ(tvt::material_resolution_for(1000, 250), 512);  // sqrt = 500
  EXPECT_EQ(tvt::material_resolution_for(2, 2), 16);        // clamped up
  EXPECT_EQ(tvt::material_resolution_for(16384, 16384), 4096);  // clamped down
}

TEST_F(MaterialImage, EveryInputKindLoads) {
  struct Kind {
    const char* name;
    int channels;
    OIIO::TypeDesc type;
    tvt::HeightSource expected;
  };
  const Kind kinds[] = {
      {"grey8.png", 1, OIIO::TypeDesc::UINT8, tvt::HeightSource::Luminance},
      {"greyalpha8.png", 2, OIIO::TypeDesc::UINT8, tvt::HeightSource::Alpha},
      {"rgb8.png", 3, OIIO::TypeDesc::UINT8, tvt::HeightSource::Luminance},
      {"rgba8.png", 4, OIIO::TypeDesc::UINT8, tvt::HeightSource::Alpha},
      {"rgb16.png", 3, OIIO::TypeDesc::UINT16, tvt::HeightSource::Luminance},
      {"rgba16.tif", 4, OIIO::TypeDesc::UINT16, tvt::HeightSource::Alpha},
      {"grey_float.tif", 1, OIIO::TypeDesc::FLOAT, tvt::HeightSource::Luminance},
      {"rgba_half.exr", 4, OIIO::TypeDesc::HALF, tvt::HeightSource::Alpha},
      {"rgb_float.exr", 3, OIIO::TypeDesc::FLOAT, tvt::HeightSource::Luminance},
  };
  const int w = 100, h = 60;  // neither square nor a power of two
  for (const Kind& k : kinds) {
    std::vector<float> values(size_t(w) * h * size_t(k.channels));
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < k.channels; ++c) values[(size_t(y) * w + x) * size_t(k.channels) + size_t(c)] = wave(x + c, y, w, h);
    write_raw(path(k.name), w, h, k.channels, k.type, values);
    auto m = tvt::load_material_image(path(k.name), {});
    ASSERT_TRUE(m.ok()) << k.name << ": " << m.error().message;
    EXPECT_EQ(m->image.width, 64) << k.name;  // sqrt(6000) = 77.5: log2 6.27 -> 64
    EXPECT_EQ(m->image.height, 64) << k.name;
    EXPECT_TRUE(m->report.resampled);
    EXPECT_EQ(m->report.source_channels, k.channels);
    EXPECT_EQ(m->report.height, k.expected) << k.name;
    uint8_t lo = 255, hi = 0;
    for (size_t i = 0; i < m->image.texels.size(); i += 4) lo = std::min(lo, m->image.texels[i]), hi = std::max(hi, m->image.texels[i]);
    EXPECT_GT(hi - lo, 100) << k.name << ": the pattern survived";
  }
}

TEST_F(MaterialImage, ResamplingKeepsTheTextureTileable) {
  // Squares up and down, and oblong images stretched on one axis and shrunk on the other.
  for (const auto& [w, h] : {std::pair{100, 100}, {96, 96}, {300, 300}, {200, 50}, {72, 450}}) {
    tvt::ImageRGBA8 image(w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 4; ++c) image.at(x, y)[c] = uint8_t(std::lround(255 * wave(x + 0.5, y + 0.5, w, h)));
    const int r = tvt::material_resolution_for(w, h);
    const std::string what = std::to_string(w) + "x" + std::to_string(h) + " -> " + std::to_string(r);
    const tvt::ImageRGBA8 out = tvt::resample_tileable(image, r);
    ASSERT_EQ(out.width, r);
    // Against the pattern itself, at the output texel centres: the edges are as good as the middle.
    double worst_edge = 0, worst_inside = 0;
    for (int y = 0; y < r; ++y)
      for (int x = 0; x < r; ++x) {
        const double expected = 255 * wave((x + 0.5) * w / r, (y + 0.5) * h / r, w, h);
        const double error = std::abs(out.at(x, y)[0] - expected);
        const bool edge = x < 3 || y < 3 || x >= r - 3 || y >= r - 3;
        (edge ? worst_edge : worst_inside) = std::max(edge ? worst_edge : worst_inside, error);
      }
    EXPECT_LE(worst_edge, 3.0) << what;
    EXPECT_LE(worst_inside, 3.0) << what;
    // The seam: the step across the wrap is no larger than the steepest step inside.
    int seam = 0, inside = 0;
    for (int y = 0; y < r; ++y) {
      seam = std::max(seam, std::abs(out.at(r - 1, y)[0] - out.at(0, y)[0]));
      for (int x = 0; x + 1 < r; ++x) inside = std::max(inside, std::abs(out.at(x + 1, y)[0] - out.at(x, y)[0]));
    }
    EXPECT_LE(seam, inside + 1) << what;

    // On the torus every texel is an inside texel: noise (energy up to the texel frequency,
    // which an edge that is clamped rather than wrapped would get wrong) shifted circularly by
    // a whole number of output texels resamples to the shifted result (float rounding: 1/255).
    tvt::ImageRGBA8 noise(w, h), shifted(w, h);
    for (size_t i = 0; i < noise.texels.size(); ++i) noise.texels[i] = uint8_t((i * 2654435761u) >> 24);
    auto shift_of = [r](int side) {
      const int step = side / std::gcd(side, r);  // source texels that map to whole output texels
      return step * std::max(1, side / 3 / step);
    };
    const int sx = shift_of(w), sy = shift_of(h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) std::memcpy(shifted.at((x + sx) % w, (y + sy) % h), noise.at(x, y), 4);
    const tvt::ImageRGBA8 a = tvt::resample_tileable(noise, r), b = tvt::resample_tileable(shifted, r);
    const int ox = int(int64_t(sx) * r / w), oy = int(int64_t(sy) * r / h);
    int worst = 0;
    for (int y = 0; y < r; ++y)
      for (int x = 0; x < r; ++x)
        for (int c = 0; c < 4; ++c) worst = std::max(worst, std::abs(int(a.at(x, y)[c]) - int(b.at((x + ox) % r, (y + oy) % r)[c])));
    EXPECT_LE(worst, 1) << what << ", shifted by " << sx << ", " << sy;
  }
}

TEST_F(MaterialImage, PowerOfTwoSquaresAreTakenTexelForTexel) {
  tvt::ImageRGBA8 image(32, 32);
  for (size_t i = 0; i < image.texels.size(); ++i) image.texels[i] = uint8_t(i * 37 % 251);
  ASSERT_TRUE(tvt::write_image(path("a.png"), image).ok());
  auto m = tvt::load_material_image(path("a.png"), {});
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_FALSE(m->report.resampled);
  EXPECT_EQ(m->image.texels, image.texels);
}

TEST_F(MaterialImage, HeightComesFromLuminanceAlphaAFileOrNothingAsChosen) {
  tvt::ImageRGBA8 image(16, 16);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      uint8_t* t = image.at(x, y);
      t[0] = uint8_t(16 * x), t[1] = uint8_t(8 * y), t[2] = 200, t[3] = 255;  // alpha constant: no height
    }
  ASSERT_TRUE(tvt::write_image(path("flat_alpha.png"), image).ok());
  tvt::ImageGray8 height(16, 16);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) height.at(x, y) = uint8_t(x * 16 + y);
  ASSERT_TRUE(tvt::write_image(path("h.png"), height).ok());

  auto automatic = tvt::load_material_image(path("flat_alpha.png"), {});
  ASSERT_TRUE(automatic.ok());
  EXPECT_EQ(automatic->report.height, tvt::HeightSource::Luminance);
  tvt::MaterialImageOptions o;
  o.invert_height = true;
  auto inverted = tvt::load_material_image(path("flat_alpha.png"), o);
  o = {};
  o.height = tvt::HeightSource::Alpha;
  auto alpha = tvt::load_material_image(path("flat_alpha.png"), o);
  o.height = tvt::HeightSource::None;
  auto none = tvt::load_material_image(path("flat_alpha.png"), o);
  o = {};
  o.height_path = path("h.png");
  auto file = tvt::load_material_image(path("flat_alpha.png"), o);
  ASSERT_TRUE(inverted.ok() && alpha.ok() && none.ok() && file.ok());
  EXPECT_EQ(file->report.height, tvt::HeightSource::File);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      const uint8_t l = tvt::luminance8(image.at(x, y));
      EXPECT_EQ(automatic->image.at(x, y)[3], l);
      EXPECT_EQ(inverted->image.at(x, y)[3], 255 - l);
      EXPECT_EQ(alpha->image.at(x, y)[3], 255);
      EXPECT_EQ(none->image.at(x, y)[3], 255);
      EXPECT_EQ(file->image.at(x, y)[3], height.at(x, y));
      EXPECT_EQ(file->image.at(x, y)[0], image.at(x, y)[0]);  // RGB untouched
    }
}

TEST_F(MaterialImage, BadFilesGiveAnErrorNamingTheFile) {
  const auto cases = tvt::test::write_bad_images(dir);
  for (const auto& [name, why] : cases) {
    auto m = tvt::load_material_image(path(name), {});
    ASSERT_FALSE(m.ok()) << name;
    EXPECT_EQ(m.error().message.rfind(path(name) + ": ", 0), 0u) << m.error().message;
    EXPECT_NE(m.error().message.find(why), std::string::npos) << m.error().message;
  }
}

// Through a scene: the error names the scene file, the field and the image file, whether it
// shows at scene load (headers) or at the material's first use (texels).
TEST_F(MaterialImage, BadImagesFailTheSceneNamingTheFieldAndTheFile) {
  for (const auto& [name, why] : tvt::test::write_bad_images(dir)) {
    for (const char* key : {"image", "height"}) {
      const std::string albedo = std::string(key) == "image"
                                     ? R"({"image": ")" + name + R"("})"
                                     : R"({"image": "good.png", "height": ")" + name + R"("})";
      ASSERT_TRUE(tvt::write_image(path("good.png"), tvt::ImageRGBA8(8, 8)).ok());
      const std::string scene = tvt::test::write_scene_json(dir, "scene.json", R"(
        {"name": "ground", "albedo": {"generator": "sand", "resolution": 16}, "weight": "remainder"},
        {"name": "wall", "albedo": )" + albedo + R"(, "mode": "blendmap", "weight": {"rule": {"height": [0, 1]}}})");
      std::string message;
      auto desc = tvt::load_scene_file(scene);
      if (!desc.ok()) {
        message = desc.error().message;
      } else if (auto assets = tvt::load_scene_assets(desc.value()); !assets.ok()) {
        message = assets.error().message;
      } else if (auto wall = assets->materials->get(1); !wall.ok()) {
        message = wall.error().message;
      }
      ASSERT_FALSE(message.empty()) << name << " as " << key << " was accepted";
      EXPECT_NE(message.find(scene + ": /materials/1/albedo/" + key), std::string::npos) << message;
      EXPECT_NE(message.find(name), std::string::npos) << message;
    }
  }
}

}  // namespace
