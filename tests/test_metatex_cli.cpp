// `terravt metatex` end to end: runs the built executable (TVT_TERRAVT_EXE) on synthetic inputs.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "compose/image.h"
#include "compose/metatex.h"
#include "compose/scene_assets.h"
#include "support/bad_images.h"
#include "support/file_scene.h"

namespace fs = std::filesystem;

namespace {

constexpr int R = 64;

std::string read_bytes(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

class MetatexCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("tvt_metatex_cli_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // Albedo with three raised discs in the height (alpha); one crosses the corner.
    tvt::ImageRGBA8 albedo(R, R);
    tvt::ImageGray8 mask(R, R);
    const int discs[3][3] = {{0, 0, 6}, {32, 20, 5}, {50, 45, 7}};
    for (int y = 0; y < R; ++y)
      for (int x = 0; x < R; ++x) {
        bool f = false;
        for (const auto& d : discs) {
          int dx = ((x - d[0]) % R + R) % R, dy = ((y - d[1]) % R + R) % R;
          if (dx > R / 2) dx -= R;
          if (dy > R / 2) dy -= R;
          f = f || dx * dx + dy * dy <= d[2] * d[2];
        }
        uint8_t* t = albedo.at(x, y);
        t[0] = uint8_t(f ? 90 : 160);
        t[1] = uint8_t(f ? 80 : 150);
        t[2] = uint8_t(70 + (x + y) % 5);
        t[3] = uint8_t(f ? 210 : 40 + (x * 3 + y) % 7);
        mask.at(x, y) = f ? 255 : 0;
      }
    ASSERT_TRUE(tvt::write_image(path("albedo.png"), albedo).ok());
    ASSERT_TRUE(tvt::write_image(path("mask.png"), mask).ok());
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // Runs `terravt <args>`, returns the exit code; stdout+stderr in output_.
  int run(const std::string& args) {
    const std::string log = path("log.txt");
    const std::string command = std::string("\"") + TVT_TERRAVT_EXE + "\" " + args + " > \"" + log + "\" 2>&1";
    const int status = std::system(command.c_str());
    std::ifstream file(log);
    std::stringstream text;
    text << file.rdbuf();
    output_ = text.str();
    fs::remove(log);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  // Every field of every texel (the bytes the compositors read) and the count.
  static void expect_same_meta(const tvt::MetaTexture& from_scene, const std::string& cli_exr, const std::string& what) {
    auto from_cli = tvt::read_meta_texture(cli_exr);
    ASSERT_TRUE(from_cli.ok()) << from_cli.error().message;
    EXPECT_EQ(from_scene.feature_count, from_cli->feature_count) << what;
    ASSERT_EQ(from_scene.resolution, from_cli->resolution) << what;
    ASSERT_EQ(from_scene.texels.size(), from_cli->texels.size());
    for (size_t i = 0; i < from_scene.texels.size(); ++i) {
      const tvt::MetaTexel &a = from_scene.texels[i], &b = from_cli->texels[i];
      ASSERT_TRUE(a.dx == b.dx && a.dy == b.dy && a.d == b.d && a.f == b.f && a.variation == b.variation)
          << what << ": texel " << i;
    }
  }
  fs::path dir_;
  std::string output_;
};

TEST_F(MetatexCliTest, AutomaticIsolationWritesMetaAndDebug) {
  const std::string args = "metatex --input " + path("albedo.png") + " --out " + path("meta.exr") + " --debug " +
                           path("debug.png");
  ASSERT_EQ(run(args), 0) << output_;
  ASSERT_TRUE(fs::exists(path("meta.exr")));
  ASSERT_TRUE(fs::exists(path("debug.png")));
  EXPECT_NE(output_.find("features         3"), std::string::npos) << output_;
  EXPECT_NE(output_.find("64 x 64"), std::string::npos);
  auto meta = tvt::read_meta_texture(path("meta.exr"));
  ASSERT_TRUE(meta.ok()) << meta.error().message;
  EXPECT_EQ(meta->feature_count, 3u);
  // The printed sizes are the features' own (texels per centroid in the meta-texture):
  // smallest, median and largest, and the largest against the median.
  std::map<std::pair<int, int>, uint64_t> area;
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x)
      if (const tvt::MetaTexel& t = meta->at(x, y); t.d != 0) ++area[{((x + t.dx) % R + R) % R, ((y + t.dy) % R + R) % R}];
  ASSERT_EQ(area.size(), 3u);
  std::vector<uint64_t> sizes;
  for (const auto& [centroid, texels] : area) sizes.push_back(texels);
  std::sort(sizes.begin(), sizes.end());
  char line[160];
  std::snprintf(line, sizeof line, "feature size     smallest %llu, median %llu, largest %llu texels (largest / median %.2f)",
                (unsigned long long)sizes[0], (unsigned long long)sizes[1], (unsigned long long)sizes[2],
                double(sizes[2]) / double(sizes[1]));
  EXPECT_NE(output_.find(line), std::string::npos) << line << "\n" << output_;
  const tvt::MetaTexel& corner = meta->at(R - 1, R - 1);  // part of the corner disc
  EXPECT_EQ(corner.d, 1);
  EXPECT_EQ(corner.dx, 1);
  EXPECT_EQ(corner.dy, 1);
  auto debug = tvt::read_image_rgba8(path("debug.png"));
  ASSERT_TRUE(debug.ok());
  EXPECT_EQ(debug->width, R);
}

TEST_F(MetatexCliTest, HandMadeMaskAndSeparateHeight) {
  ASSERT_EQ(run("metatex --input " + path("albedo.png") + " --mask " + path("mask.png") + " --min-texels 20 --blur 0 --out " +
                path("m.exr")),
            0)
      << output_;
  auto meta = tvt::read_meta_texture(path("m.exr"));
  ASSERT_TRUE(meta.ok()) << meta.error().message;
  EXPECT_EQ(meta->feature_count, 3u);
  auto mask = tvt::read_image_rgba8(path("mask.png"));
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) EXPECT_EQ(meta->at(x, y).f, mask->at(x, y)[0]);  // blur 0: f = 255·d

  // --height: the mask's grey becomes the height, thresholded at 0.5.
  ASSERT_EQ(run("metatex --input " + path("albedo.png") + " --height " + path("mask.png") +
                " --threshold 0.5 --out " + path("h.exr")),
            0)
      << output_;
  auto from_height = tvt::read_meta_texture(path("h.exr"));
  ASSERT_TRUE(from_height.ok());
  EXPECT_EQ(from_height->feature_count, 3u);
}

TEST_F(MetatexCliTest, BadFlagsAndInputsExitTwoAndWriteNothing) {
  const std::string in = " --input " + path("albedo.png");
  const std::string out = " --out " + path("out.exr");
  struct Case {
    std::string args;
    std::string named;  // the flag or file the message must name
  };
  tvt::ImageRGBA8 oblong(64, 32);
  ASSERT_TRUE(tvt::write_image(path("oblong.png"), oblong).ok());
  {
    std::ofstream junk(path("junk.png"), std::ios::binary);
    junk << "definitely not a png";
  }
  std::vector<Case> cases = {
      {"metatex" + in + out + " --blur -1", "--blur"},
      {"metatex" + in + out + " --threshold 1.5", "--threshold"},
      {"metatex" + in + out + " --channel alpha", "--channel"},
      {"metatex" + in + out + " --bogus", "--bogus"},
      {"metatex" + in, "--out"},
      {"metatex" + out, "--input"},
      {"metatex --input " + path("nope.png") + out, path("nope.png")},
      {"metatex --input " + path("junk.png") + out, path("junk.png")},
      {"metatex" + in + out + " --resolution 100", "--resolution 100: must be a power of two"},
      {"metatex" + in + out + " --height-source file", "--height-source file needs --height"},
      {"metatex" + in + out + " --polarity sideways", "--polarity"},
      {"metatex" + in + out + " --mask " + path("oblong.png"), path("oblong.png")},
      {"metatex" + in + out + " --mask " + path("mask.png") + " --invert", "--invert"},
      {"metatex" + in + out + " --generator cobbles", "--generator"},
      {"metatex --generator no-such-generator" + out, "no-such-generator"},
      {"metatex" + in + " --out " + path("out.png"), "--out"},
      {"metatex" + in + " --out " + path("missing/out.exr"), "does not exist"},
      {"metatex" + in + out + " --debug " + path("missing/debug.png"), "--debug"},
      {"metatex" + in + out + " --debug " + path("debug.notanimage"), "--debug"},
      {"metatex" + in + out + " --mask-out " + path("missing/m.png"), "--mask-out"},
      // No output replaces an input, however spelt, or another output.
      {"metatex" + in + out + " --debug " + path("albedo.png"),
       "--debug " + path("albedo.png") + ": is the --input file; an output never replaces an input"},
      {"metatex" + in + out + " --debug " + path("x/../albedo.png"), "is the --input file"},
      {"metatex" + in + out + " --mask " + path("mask.png") + " --mask-out " + path("mask.png"), "is the --mask file"},
      {"metatex" + in + out + " --height " + path("mask.png") + " --debug " + path("mask.png"), "is the --height file"},
      {"metatex" + in + out + " --debug " + path("debug.png") + " --mask-out " + path("debug.png"),
       "--debug " + path("debug.png") + ": is also --mask-out; two outputs cannot share a file"},
  };
  fs::create_directories(path("x"));
  const std::string albedo_bytes = read_bytes(path("albedo.png")), mask_bytes = read_bytes(path("mask.png"));
  for (const auto& [name, why] : tvt::test::write_bad_images(dir_)) {
    cases.push_back({"metatex --input " + path(name) + out, "--input " + path(name) + ": "});
    cases.push_back({"metatex --input " + path(name) + out, why});
    cases.push_back({"metatex" + in + " --height " + path(name) + out, "--height " + path(name) + ": "});
  }
  for (const Case& c : cases) {
    EXPECT_EQ(run(c.args), 2) << c.args << "\n" << output_;
    EXPECT_NE(output_.find(c.named), std::string::npos) << c.args << "\n" << output_;
    EXPECT_FALSE(fs::exists(path("out.exr"))) << c.args;
    EXPECT_FALSE(fs::exists(path("debug.png"))) << c.args;
  }
  for (const auto& entry : fs::directory_iterator(dir_))
    EXPECT_EQ(entry.path().string().find(".tmp-"), std::string::npos) << entry.path();
  EXPECT_EQ(read_bytes(path("albedo.png")), albedo_bytes);
  EXPECT_EQ(read_bytes(path("mask.png")), mask_bytes);
}

TEST_F(MetatexCliTest, GeneratorWithExactLabels) {
  ASSERT_EQ(run("metatex --generator cobbles --resolution 64 --seed 3 --out " + path("g.exr") + " --debug " +
                path("g.png")),
            0)
      << output_;
  auto meta = tvt::read_meta_texture(path("g.exr"));
  ASSERT_TRUE(meta.ok()) << meta.error().message;
  EXPECT_GT(meta->feature_count, 0u);
  EXPECT_EQ(meta->resolution, 64);
  EXPECT_TRUE(fs::exists(path("g.png")));
}

// An automatic isolation that merged features or broke them into pieces says so: on the
// real tiles (dark grout, shaded tile edges) one feature is 21x the median and hundreds of
// specks are dropped; on the pavers, which it isolates right, neither line appears.
TEST_F(MetatexCliTest, ChecksFlagAnIsolationThatMergedOrBrokeFeatures) {
  const std::string textures = std::string(TVT_SOURCE_DIR) + "/tests/data/textures/";
  ASSERT_EQ(run("metatex --input " + textures + "tiles.png --out " + path("t.exr")), 0) << output_;
  EXPECT_NE(output_.find("check            the largest feature is 21.0x the median"), std::string::npos) << output_;
  EXPECT_NE(output_.find("specks dropped against 24 features"), std::string::npos) << output_;
  EXPECT_NE(output_.find("remedy           --joints may do better; or correct the features by hand: --mask-out writes "
                         "them as a mask to edit and give back with --mask"),
            std::string::npos)
      << output_;
  ASSERT_EQ(run("metatex --input " + textures + "tiles.png --joints --out " + path("t.exr")), 0) << output_;
  EXPECT_NE(output_.find("check            the largest feature is 10.1x the median"), std::string::npos) << output_;
  EXPECT_NE(output_.find("remedy           correct the features by hand: --mask-out"), std::string::npos) << output_;
  EXPECT_EQ(output_.find("--joints may"), std::string::npos) << output_;  // it is on already
  ASSERT_EQ(run("metatex --input " + textures + "pavers.png --out " + path("p.exr")), 0) << output_;
  EXPECT_NE(output_.find("features         64"), std::string::npos) << output_;
  EXPECT_EQ(output_.find("  check  "), std::string::npos) << output_;
  EXPECT_EQ(output_.find("  remedy  "), std::string::npos) << output_;
  // A hand-made mask is what the user drew: no check.
  ASSERT_EQ(run("metatex --input " + path("albedo.png") + " --mask " + path("mask.png") + " --out " + path("m.exr")), 0)
      << output_;
  EXPECT_EQ(output_.find("  check  "), std::string::npos) << output_;
}

// The issue's case: a greyscale image without alpha, of no power-of-two size, used with mode
// fbpb. Scene loading isolates with the defaults of `terravt metatex`, so both give the same
// meta-texture: every field of every texel (the bytes the compositors read) and the count.
// (The EXR files themselves differ in their header's capture date.)
TEST_F(MetatexCliTest, SceneLoadingAndTheCliGiveTheSameMetaTextureByteForByte) {
  tvt::ImageGray8 grey(100, 100);  // light mortar, dark 20 x 8 bricks in a running bond
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < 100; ++x) {
      const int row = y / 10, bx = (x + (row % 2) * 12) % 25, by = y % 10;
      grey.at(x, y) = uint8_t(bx < 22 && by < 8 ? 50 + (x * 7 + y * 3) % 20 : 200 + (x + y) % 9);
    }
  ASSERT_TRUE(tvt::write_image(path("grey.png"), grey).ok());
  const std::string real = std::string(TVT_SOURCE_DIR) + "/tests/data/textures/flagstones.png";
  for (const std::string& image : {path("grey.png"), real}) {
    ASSERT_EQ(run("metatex --input " + image + " --out " + path("cli.exr")), 0) << output_;
    const std::string scene = tvt::test::write_scene_json(dir_, "scene.json", R"(
      {"name": "ground", "albedo": {"generator": "sand", "resolution": 16}, "weight": "remainder"},
      {"name": "wall", "albedo": {"image": ")" + image + R"("}, "mode": "fbpb", "weight": {"rule": {"height": [0, 1]}}})");
    auto desc = tvt::load_scene_file(scene);
    ASSERT_TRUE(desc.ok()) << desc.error().message;
    auto assets = tvt::load_scene_assets(desc.value());
    ASSERT_TRUE(assets.ok()) << assets.error().message;
    // The loader says what it does with the file, from its header (the CLI prints it).
    const std::string note = assets->materials->info(1).image_note;
    const std::string isolation =
        ", FBPB features isolated automatically at first use (`terravt metatex --input " + image + " --debug <png>` shows them)";
    EXPECT_EQ(note, image + (image == real ? ": 256x256, 3 channel(s), used as it is, height from luminance"
                                           : ": 100x100, 1 channel(s), resampled to 128x128 (Lanczos-3, wrap), height "
                                             "from luminance") +
                        isolation);
    EXPECT_TRUE(assets->materials->info(0).image_note.empty());  // a generator's
    auto wall = assets->materials->get(1);
    ASSERT_TRUE(wall.ok()) << wall.error().message;
    ASSERT_TRUE(wall.value()->meta.has_value());
    const tvt::MetaTexture& from_scene = *wall.value()->meta;
    EXPECT_GT(from_scene.feature_count, 3u) << image;
    expect_same_meta(from_scene, path("cli.exr"), image);
  }
}

// `--mask-out` writes the features as a mask to edit by hand: drawn on the image as given (at
// the material's resolution where the image is smaller), white features, black background and
// split lines. Given back with `--mask`, or as a scene's `fbpb.mask`, it gives the same
// features, and the CLI and scene loading the same meta-texture.
TEST_F(MetatexCliTest, MaskOutReadsBackAsTheSameFeaturesInTheCliAndInAScene) {
  const std::string textures = std::string(TVT_SOURCE_DIR) + "/tests/data/textures/";
  // pavers: 256 x 256, 64 touching-free pavers; light_mortar_bricks: 96 x 96, resampled to 128.
  for (const auto& [name, side] : {std::pair<std::string, int>{"pavers.png", 256}, {"light_mortar_bricks.png", 128}}) {
    const std::string image = textures + name;
    ASSERT_EQ(run("metatex --input " + image + " --out " + path("auto.exr") + " --mask-out " + path("m.png")), 0) << output_;
    const size_t at = output_.find("features         ");
    ASSERT_NE(at, std::string::npos) << output_;
    const int features = std::atoi(output_.c_str() + at + 17);
    EXPECT_GT(features, 3) << name;
    EXPECT_NE(output_.find("wrote            " + path("auto.exr") + ", " + path("m.png")), std::string::npos) << output_;
    auto mask = tvt::read_image_rgba8(path("m.png"));
    ASSERT_TRUE(mask.ok()) << mask.error().message;
    EXPECT_EQ(mask->width, side) << name;
    EXPECT_EQ(mask->height, side) << name;
    size_t white = 0;
    for (int y = 0; y < mask->height; ++y)
      for (int x = 0; x < mask->width; ++x) {
        const uint8_t v = mask->at(x, y)[0];
        ASSERT_TRUE(v == 0 || v == 255) << name << " at " << x << ", " << y;
        white += v == 255;
      }
    EXPECT_GT(white, 0u);

    ASSERT_EQ(run("metatex --input " + image + " --mask " + path("m.png") + " --out " + path("cli.exr")), 0) << output_;
    EXPECT_NE(output_.find("features         " + std::to_string(features) + "\n"), std::string::npos) << output_;
    const std::string scene = tvt::test::write_scene_json(dir_, "scene.json", R"(
      {"name": "ground", "albedo": {"generator": "sand", "resolution": 16}, "weight": "remainder"},
      {"name": "wall", "albedo": {"image": ")" + image + R"("}, "mode": "fbpb", "weight": {"rule": {"height": [0, 1]}},
       "fbpb": {"mask": ")" + path("m.png") + R"("}})");
    auto desc = tvt::load_scene_file(scene);
    ASSERT_TRUE(desc.ok()) << desc.error().message;
    auto assets = tvt::load_scene_assets(desc.value());
    ASSERT_TRUE(assets.ok()) << assets.error().message;
    auto wall = assets->materials->get(1);
    ASSERT_TRUE(wall.ok()) << wall.error().message;
    ASSERT_TRUE(wall.value()->meta.has_value());
    EXPECT_EQ(wall.value()->meta->feature_count, uint32_t(features)) << name;
    expect_same_meta(*wall.value()->meta, path("cli.exr"), name);
  }
}

}  // namespace
