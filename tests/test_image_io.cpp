// compose/image_io.cpp: round trips, conversions, and that every bad file is reported with
// its name and never leaves a half-written output behind.
#include <gtest/gtest.h>
#include <unistd.h>

#include <OpenImageIO/imageio.h>  // only to write files the library itself refuses to write

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>

#include "support/temp_dir.h"
#include "compose/image.h"

namespace fs = std::filesystem;

namespace {

class ImageIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tvt::test::fresh_test_dir("tvt_image_io");
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  size_t files_in_dir() const { return size_t(std::distance(fs::directory_iterator(dir_), fs::directory_iterator())); }
  fs::path dir_;
};

tvt::ImageRGBA8 pattern_rgba(int w, int h) {
  tvt::ImageRGBA8 image(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* t = image.at(x, y);
      t[0] = uint8_t(x * 7 + y);
      t[1] = uint8_t(y * 13);
      t[2] = uint8_t(x ^ y);
      t[3] = uint8_t((x * 31 + y * 17) % 256);  // includes alpha 0 under non-zero colour
    }
  return image;
}

bool mentions(const tvt::Error& error, const std::string& text) { return error.message.find(text) != std::string::npos; }

TEST_F(ImageIoTest, PngRgba8RoundTripKeepsColourUnderAnyAlpha) {
  const auto image = pattern_rgba(37, 21);
  ASSERT_TRUE(tvt::write_image(path("a.png"), image).ok());
  auto back = tvt::read_image_rgba8(path("a.png"));
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->width, 37);
  EXPECT_EQ(back->height, 21);
  EXPECT_EQ(back->texels, image.texels);  // no premultiplication: alpha is height, not coverage
  EXPECT_EQ(files_in_dir(), 1u);          // no temporary file left
}

TEST_F(ImageIoTest, PngGrayRoundTripAndExpansionToRgba) {
  tvt::ImageGray8 gray(16, 9);
  for (size_t i = 0; i < gray.texels.size(); ++i) gray.texels[i] = uint8_t(i * 5);
  ASSERT_TRUE(tvt::write_image(path("g.png"), gray).ok());
  auto as_float = tvt::read_image_float(path("g.png"));
  ASSERT_TRUE(as_float.ok()) << as_float.error().message;
  EXPECT_EQ(as_float->channels, 1);
  auto rgba = tvt::read_image_rgba8(path("g.png"));
  ASSERT_TRUE(rgba.ok());
  for (int y = 0; y < 9; ++y)
    for (int x = 0; x < 16; ++x) {
      const uint8_t g = gray.at(x, y);
      EXPECT_NEAR(as_float->at(x, y), float(g) / 255.0f, 1e-6f);
      const uint8_t* t = rgba->at(x, y);
      EXPECT_EQ(t[0], g);
      EXPECT_EQ(t[1], g);
      EXPECT_EQ(t[2], g);
      EXPECT_EQ(t[3], 255);
    }
}

TEST_F(ImageIoTest, ExrFloatRoundTripIsExactWithChannelNames) {
  tvt::ImageF image(13, 8, 3);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> value(-1000.0f, 1000.0f);
  for (float& v : image.data) v = value(rng);
  ASSERT_TRUE(tvt::write_image(path("f.exr"), image, {"R", "G", "B"}).ok());
  auto back = tvt::read_image_float(path("f.exr"));
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->channels, 3);
  EXPECT_EQ(back->data, image.data);
}

TEST_F(ImageIoTest, FloatToRgba8RoundsAndClamps) {
  tvt::ImageF image(5, 1, 1);
  const float values[5] = {-0.5f, 0.2f, 0.5f, 127.4f / 255.0f, 2.0f};
  for (int x = 0; x < 5; ++x) image.at(x, 0) = values[x];
  ASSERT_TRUE(tvt::write_image(path("c.exr"), image, {"Y"}).ok());
  auto rgba = tvt::read_image_rgba8(path("c.exr"));
  ASSERT_TRUE(rgba.ok()) << rgba.error().message;
  const uint8_t expected[5] = {0, 51, 128, 127, 255};
  for (int x = 0; x < 5; ++x) EXPECT_EQ(rgba->at(x, 0)[0], expected[x]) << "x = " << x;
}

TEST_F(ImageIoTest, TwoChannelIsGreyPlusAlphaAndSixteenBitRounds) {
  // 16-bit grey + alpha written with OIIO directly (the library writes 8-bit or float).
  // 32768 / 257 = 127.502 -> 128; 385 / 257 = 1.498 -> 1 (rounded, not truncated).
  const uint16_t texels[4] = {65535, 32768, 385, 0};
  {
    auto out = OIIO::ImageOutput::create(path("ga.png"));
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(2, 1, 2, OIIO::TypeDesc::UINT16);
    spec.attribute("oiio:UnassociatedAlpha", 1);
    ASSERT_TRUE(out->open(path("ga.png"), spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT16, texels));
    ASSERT_TRUE(out->close());
  }
  auto rgba = tvt::read_image_rgba8(path("ga.png"));
  ASSERT_TRUE(rgba.ok()) << rgba.error().message;
  EXPECT_EQ(rgba->at(0, 0)[0], 255);
  EXPECT_EQ(rgba->at(0, 0)[2], 255);
  EXPECT_EQ(rgba->at(0, 0)[3], 128);
  EXPECT_EQ(rgba->at(1, 0)[0], 1);
  EXPECT_EQ(rgba->at(1, 0)[3], 0);
}

TEST_F(ImageIoTest, MissingFileIsNamed) {
  auto r = tvt::read_image_rgba8(path("nope.png"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(mentions(r.error(), path("nope.png")));
  EXPECT_TRUE(mentions(r.error(), "not found"));
  auto f = tvt::read_image_float(path("nope.exr"));
  ASSERT_FALSE(f.ok());
  EXPECT_TRUE(mentions(f.error(), path("nope.exr")));
}

TEST_F(ImageIoTest, RandomBytesAreNotAnImage) {
  std::mt19937 rng(3);
  {
    std::ofstream file(path("noise.png"), std::ios::binary);
    for (int i = 0; i < 4096; ++i) file.put(char(rng() & 0xff));
  }
  auto r = tvt::read_image_rgba8(path("noise.png"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(mentions(r.error(), path("noise.png")));
  EXPECT_TRUE(mentions(r.error(), "not an image"));
}

TEST_F(ImageIoTest, TruncatedPngIsRejectedWithItsName) {
  tvt::ImageRGBA8 image = pattern_rgba(64, 64);
  std::mt19937 rng(11);
  for (uint8_t& t : image.texels) t = uint8_t(rng() & 0xff);  // incompressible
  ASSERT_TRUE(tvt::write_image(path("t.png"), image).ok());
  const auto full = fs::file_size(path("t.png"));
  for (double keep : {0.9, 0.5, 0.1}) {
    fs::copy_file(path("t.png"), path("cut.png"), fs::copy_options::overwrite_existing);
    fs::resize_file(path("cut.png"), uintmax_t(double(full) * keep));
    auto r = tvt::read_image_rgba8(path("cut.png"));
    ASSERT_FALSE(r.ok()) << "kept " << keep;
    EXPECT_TRUE(mentions(r.error(), path("cut.png"))) << r.error().message;
  }
}

TEST_F(ImageIoTest, NanInFloatExrIsRejectedAtItsTexel) {
  tvt::ImageF image(6, 4, 2);
  image.at(4, 3, 1) = std::numeric_limits<float>::quiet_NaN();
  image.at(5, 3, 0) = std::numeric_limits<float>::infinity();
  ASSERT_TRUE(tvt::write_image(path("nan.exr"), image).ok());
  auto f = tvt::read_image_float(path("nan.exr"));
  ASSERT_FALSE(f.ok());
  EXPECT_TRUE(mentions(f.error(), path("nan.exr")));
  EXPECT_TRUE(mentions(f.error(), "(4, 3) channel 1")) << f.error().message;
  EXPECT_TRUE(mentions(f.error(), "NaN"));
  auto rgba = tvt::read_image_rgba8(path("nan.exr"));
  ASSERT_FALSE(rgba.ok());
  EXPECT_TRUE(mentions(rgba.error(), "(4, 3) channel 1"));
}

TEST_F(ImageIoTest, TooLargeImageIsRejected) {
  const int wide = 32769;
  std::vector<uint8_t> row(size_t(wide), 9);
  {
    auto out = OIIO::ImageOutput::create(path("wide.png"));
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(path("wide.png"), OIIO::ImageSpec(wide, 1, 1, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, row.data()));
    ASSERT_TRUE(out->close());
  }
  auto r = tvt::read_image_rgba8(path("wide.png"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(mentions(r.error(), path("wide.png")));
  EXPECT_TRUE(mentions(r.error(), "too large"));
}

// A header claiming more channels (or more texel bytes) than any texture has is refused from
// the header, before the texels are allocated: no bad_alloc from a small hostile file.
TEST_F(ImageIoTest, HeadersClaimingTooManyChannelsOrBytesAreRejectedBeforeAllocating) {
  const int channels = 65;
  std::vector<float> texels(size_t(2) * 2 * channels, 0.5f);
  {
    auto out = OIIO::ImageOutput::create(path("many.exr"));
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(path("many.exr"), OIIO::ImageSpec(2, 2, channels, OIIO::TypeDesc::HALF)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, texels.data()));
    ASSERT_TRUE(out->close());
  }
  auto as_float = tvt::read_image_float(path("many.exr"));
  ASSERT_FALSE(as_float.ok());
  EXPECT_TRUE(mentions(as_float.error(), path("many.exr"))) << as_float.error().message;
  EXPECT_TRUE(mentions(as_float.error(), "65 channels")) << as_float.error().message;
  auto as_rgba = tvt::read_image_rgba8(path("many.exr"));
  ASSERT_FALSE(as_rgba.ok());
  EXPECT_TRUE(mentions(as_rgba.error(), "65 channels")) << as_rgba.error().message;
  // 16384 x 16384 x 5 channels (uint8 in the file, 5 GiB as float): within the side limit,
  // beyond the byte limit. Written a scanline at a time; the file is a few MB of zeros.
  const int side = 16384, wide_channels = 5;
  std::vector<uint8_t> scanline(size_t(side) * wide_channels, 0);
  {
    auto out = OIIO::ImageOutput::create(path("huge.tif"));
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(side, side, wide_channels, OIIO::TypeDesc::UINT8);
    spec.attribute("compression", "zip");
    ASSERT_TRUE(out->open(path("huge.tif"), spec));
    for (int y = 0; y < side; ++y) ASSERT_TRUE(out->write_scanline(y, 0, OIIO::TypeDesc::UINT8, scanline.data()));
    ASSERT_TRUE(out->close());
  }
  auto huge = tvt::read_image_float(path("huge.tif"));
  ASSERT_FALSE(huge.ok());
  EXPECT_TRUE(mentions(huge.error(), path("huge.tif"))) << huge.error().message;
  EXPECT_TRUE(mentions(huge.error(), "5120 MiB as float")) << huge.error().message;
}

TEST_F(ImageIoTest, WriteIntoMissingFolderFailsAndLeavesNothing) {
  const std::string target = path("missing/sub/out.png");
  auto w = tvt::write_image(target, pattern_rgba(4, 4));
  ASSERT_FALSE(w.ok());
  EXPECT_TRUE(mentions(w.error(), target));
  EXPECT_TRUE(mentions(w.error(), "does not exist"));
  EXPECT_FALSE(fs::exists(path("missing")));
  EXPECT_EQ(files_in_dir(), 0u);
}

TEST_F(ImageIoTest, FailedWritesLeaveNoFileOrTemporary) {
  // Unknown extension, no extension, zero size, wrong channel-name count, a folder as target.
  EXPECT_FALSE(tvt::write_image(path("a.notaformat"), pattern_rgba(4, 4)).ok());
  EXPECT_FALSE(tvt::write_image(path("noext"), pattern_rgba(4, 4)).ok());
  EXPECT_FALSE(tvt::write_image(path("zero.png"), tvt::ImageRGBA8(0, 0)).ok());
  EXPECT_FALSE(tvt::write_image(path("names.exr"), tvt::ImageF(4, 4, 2), {"only-one"}).ok());
  auto folder = tvt::write_image(dir_.string(), pattern_rgba(4, 4));
  EXPECT_FALSE(folder.ok());
  EXPECT_EQ(files_in_dir(), 0u);
}

TEST_F(ImageIoTest, OverwriteReplacesTheWholeFile) {
  ASSERT_TRUE(tvt::write_image(path("o.png"), pattern_rgba(64, 64)).ok());
  ASSERT_TRUE(tvt::write_image(path("o.png"), pattern_rgba(3, 2)).ok());
  auto back = tvt::read_image_rgba8(path("o.png"));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->width, 3);
  EXPECT_EQ(back->texels, pattern_rgba(3, 2).texels);
  EXPECT_EQ(files_in_dir(), 1u);
}

}  // namespace
