// Hostile input to the libraries: JSON nested deeper than the parsers' limit (refused in linear
// time), files that are not regular files (FIFOs, directories) where a file is read, a heightmap
// too small for a terrain, and field ranges quoted the way the format defines them. Nothing here
// may block, abort or run long.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include "compose/image.h"
#include "json/json_check.h"
#include "compose/scene.h"
#include "compose/scene_assets.h"
#include "terrain/camera_file.h"
#include "streaming/bake.h"
#include "streaming/page_store.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using namespace tvt;

namespace {

class HostileInput : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::fresh_test_dir("tvt_hostile"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string fifo(const std::string& name) const {
    const std::string p = path(name);
    EXPECT_EQ(::mkfifo(p.c_str(), 0644), 0);
    return p;
  }
  fs::path dir_;
};

bool contains(const std::string& haystack, const std::string& needle) { return haystack.find(needle) != std::string::npos; }

std::string nested_arrays(size_t depth) { return std::string(depth, '[') + std::string(depth, ']'); }

double seconds_of(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

TEST_F(HostileInput, JsonAtTheDepthLimitParsesAndOneLevelMoreIsRefusedNamingTheLimit) {
  ASSERT_EQ(json_check::k_max_depth, 64u);
  auto at_limit = json_check::parse(nested_arrays(64), "ok.json");
  ASSERT_TRUE(at_limit.ok()) << at_limit.error().message;
  auto past = json_check::parse(nested_arrays(65), "deep.json");
  ASSERT_FALSE(past.ok());
  EXPECT_EQ(past.error().message.rfind("deep.json: /0/0/", 0), 0u) << past.error().message;
  EXPECT_TRUE(contains(past.error().message, "nested deeper than 64 arrays/objects")) << past.error().message;
  // Objects count the same as arrays.
  std::string objects;
  for (int i = 0; i < 65; ++i) objects += "{\"k\":";
  objects += "1" + std::string(65, '}');
  auto deep_objects = json_check::parse(objects, "objects.json");
  ASSERT_FALSE(deep_objects.ok());
  EXPECT_TRUE(contains(deep_objects.error().message, "objects.json: /k/k/k/")) << deep_objects.error().message;
  EXPECT_TRUE(contains(deep_objects.error().message, "deeper than 64")) << deep_objects.error().message;
}

// 200 KB of brackets took minutes before (the pointer of every value was copied whole: O(depth)
// per value). Refused at the limit, it costs no more than a flat file of the same size; the
// time bound is generous so that a loaded machine does not fail it.
TEST_F(HostileInput, TwoHundredKilobytesOfNestedBracketsAreRefusedQuicklyAsSceneAndCameraFile) {
  const std::string deep = nested_arrays(100000);
  const std::string scene_file = path("d.json"), camera_file = path("c.json");
  std::ofstream(scene_file) << deep;
  std::ofstream(camera_file) << deep;
  Result<SceneDesc> scene = make_error("not run");
  Result<CameraFile> camera = make_error("not run");
  const double s = seconds_of([&] {
    scene = load_scene_file(scene_file);
    camera = load_camera_file(camera_file);
  });
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.error().message.rfind(scene_file + ": ", 0), 0u) << scene.error().message;
  EXPECT_TRUE(contains(scene.error().message, "deeper than 64")) << scene.error().message;
  ASSERT_FALSE(camera.ok());
  EXPECT_EQ(camera.error().message.rfind(camera_file + ": ", 0), 0u) << camera.error().message;
  EXPECT_TRUE(contains(camera.error().message, "deeper than 64")) << camera.error().message;
  EXPECT_LT(s, 5.0);
}

// Within the limit, nesting is linear too: 64 levels repeated side by side over 400 KB parse
// in about the time of a flat array of the same size (before, each value paid for its depth).
TEST_F(HostileInput, DeepButAllowedNestingCostsNoMoreThanFlatInput) {
  std::string nested = "[", flat = "[";
  while (nested.size() < 400000) nested += nested_arrays(60) + ",";
  nested.back() = ']';
  while (flat.size() < nested.size()) flat += "[],";
  flat.back() = ']';
  double t_nested = 1e9, t_flat = 1e9;
  for (int round = 0; round < 3; ++round) {  // fastest of three: scheduling noise only adds time
    t_nested = std::min(t_nested, seconds_of([&] { ASSERT_TRUE(json_check::parse(nested, "n.json").ok()); }));
    t_flat = std::min(t_flat, seconds_of([&] { ASSERT_TRUE(json_check::parse(flat, "f.json").ok()); }));
  }
  EXPECT_LT(t_nested, 10.0 * t_flat + 0.05) << "nested " << t_nested << " s, flat " << t_flat << " s";
}

TEST_F(HostileInput, SceneAndCameraFilesThatAreFifosOrDirectoriesAreRefusedWithoutBlocking) {
  const std::string f = fifo("scene.fifo");  // no writer: opening it for reading would block
  auto scene = load_scene_file(f);
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.error().message, f + ": cannot read scene file: it is not a regular file (a FIFO)");
  auto camera = load_camera_file(f);
  ASSERT_FALSE(camera.ok());
  EXPECT_EQ(camera.error().message, f + ": cannot read camera file: it is not a regular file (a FIFO)");
  fs::create_directories(path("folder"));
  auto folder = load_scene_file(path("folder"));
  ASSERT_FALSE(folder.ok());
  EXPECT_EQ(folder.error().message, path("folder") + ": cannot read scene file: it is a directory");
}

TEST_F(HostileInput, AnImagePathThatIsADirectoryOrFifoSaysSo) {
  fs::create_directories(path("tex"));
  const std::string f = fifo("tex.fifo");
  for (const auto& [image, kind] : {std::pair{path("tex"), std::string("is a directory")}, {f, "is a FIFO"}}) {
    const std::string scene = R"({"terrain": {"heightmap": {"image": ")" + image + R"("}}, "materials": [{"name": "a", "albedo": {"generator": "sand"}}]})";
    auto r = parse_scene(scene, "s.json", "");
    ASSERT_FALSE(r.ok()) << image;
    EXPECT_EQ(r.error().message, "s.json: /terrain/heightmap/image: not a regular file: " + image + " " + kind +
                                     ", got \"" + image + "\"");
  }
  // The image reader itself never opens a FIFO either.
  auto read = read_image_rgba8(f);
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.error().message, f + ": is not a regular file, not an image file");
  auto folder = read_image_rgba8(path("tex"));
  ASSERT_FALSE(folder.ok());
  EXPECT_EQ(folder.error().message, path("tex") + ": is a directory, not an image file");
}

TEST_F(HostileInput, AOneTexelHeightmapNamesTheSceneFieldAndTheImage) {
  const std::string image = path("h.png");
  ImageRGBA8 one(1, 1);
  ASSERT_TRUE(write_image(image, one).ok());
  std::ofstream(path("s.json")) << R"({"terrain": {"heightmap": {"image": "h.png"}}, "vt": {"log2_size": 10},
    "materials": [{"name": "a", "albedo": {"generator": "sand", "resolution": 64}}]})";
  auto desc = load_scene_file(path("s.json"));
  ASSERT_TRUE(desc.ok()) << desc.error().message;
  auto assets = load_scene_assets(desc.value());
  ASSERT_FALSE(assets.ok());
  EXPECT_TRUE(contains(assets.error().message, "/terrain/heightmap/image")) << assets.error().message;
  EXPECT_TRUE(contains(assets.error().message, image + ": heightmap is 1 x 1 texels; it needs at least 2 x 2"))
      << assets.error().message;
}

TEST_F(HostileInput, VtFieldsOutOfRangeQuoteTheirOwnRange) {
  const std::pair<std::string, std::string> cases[] = {
      {R"({"log2_size": -1})", "/vt/log2_size: must be an integer in [10, 30], got -1"},
      {R"({"log2_size": 4294967296})", "/vt/log2_size: must be an integer in [10, 30], got 4294967296"},
      {R"({"page_texels": 100})", "/vt/page_texels: must be a power of two in [16, 1024], got 100"},
      {R"({"border_texels": -4})", "/vt/border_texels: must be an integer in [0, 512], got -4"},
  };
  for (const auto& [vt, message] : cases) {
    auto r = parse_scene(R"({"vt": )" + vt + R"(, "materials": [{"name": "a", "albedo": {"generator": "sand"}}]})", "v.json", "");
    ASSERT_FALSE(r.ok()) << vt;
    EXPECT_EQ(r.error().message, "v.json: " + message) << vt;
  }
}

TEST_F(HostileInput, PageStoreReaderAndVerifyRefuseAFifoAndADirectoryWithoutBlocking) {
  const std::string f = fifo("store.fifo");
  auto opened = PageStoreReader::open(f);
  ASSERT_FALSE(opened.ok());
  EXPECT_EQ(opened.error().message, f + ": not a regular file");
  auto verified = verify_store(f);
  ASSERT_FALSE(verified.ok());
  EXPECT_EQ(verified.error().message, f + ": not a regular file");
  fs::create_directories(path("folder.tvt"));
  auto folder = PageStoreReader::open(path("folder.tvt"));
  ASSERT_FALSE(folder.ok());
  EXPECT_EQ(folder.error().message, path("folder.tvt") + ": not a regular file");
}
