// Scene loading caches the meta-texture of automatic feature isolation next to the scene
// (.terravt-cache/), keyed by what it is made from: a second load of the same scene does not
// isolate again and gets the same meta-texture; another image, or a damaged cache file, is
// isolated afresh.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "compose/image.h"
#include "compose/material_source.h"
#include "compose/metatex.h"
#include "compose/scene.h"
#include "compose/scene_assets.h"
#include "support/file_scene.h"
#include "support/temp_dir.h"

namespace tvt {
namespace {

namespace fs = std::filesystem;

// Light mortar, dark bricks in a running bond (100 x 100: resampled to 128^2 on load).
ImageGray8 bricks(uint8_t shade) {
  ImageGray8 grey(100, 100);
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < 100; ++x) {
      const int row = y / 10, bx = (x + (row % 2) * 12) % 25, by = y % 10;
      grey.at(x, y) = uint8_t(bx < 22 && by < 8 ? shade + (x * 7 + y * 3) % 20 : 200 + (x + y) % 9);
    }
  return grey;
}

struct Loaded {
  MetaTexture meta;
  uint64_t isolations = 0;  // automatic isolations the load ran
};

Loaded load_wall(const std::string& scene) {
  const uint64_t before = automatic_isolation_runs();
  auto desc = load_scene_file(scene);
  EXPECT_TRUE(desc.ok()) << desc.error().message;
  auto assets = load_scene_assets(desc.value());
  EXPECT_TRUE(assets.ok()) << assets.error().message;
  auto wall = assets->materials->get(1);
  EXPECT_TRUE(wall.ok()) << wall.error().message;
  EXPECT_TRUE(wall.value()->meta.has_value());
  return Loaded{*wall.value()->meta, automatic_isolation_runs() - before};
}

bool same(const MetaTexture& a, const MetaTexture& b) {
  if (a.resolution != b.resolution || a.feature_count != b.feature_count || a.texels.size() != b.texels.size())
    return false;
  for (size_t i = 0; i < a.texels.size(); ++i) {
    const MetaTexel &p = a.texels[i], &q = b.texels[i];
    if (p.dx != q.dx || p.dy != q.dy || p.d != q.d || p.f != q.f || p.variation != q.variation) return false;
  }
  return true;
}

std::vector<fs::path> cache_files(const fs::path& dir) {
  std::vector<fs::path> out;
  if (fs::is_directory(dir / ".terravt-cache"))
    for (const auto& e : fs::directory_iterator(dir / ".terravt-cache")) out.push_back(e.path());
  return out;
}

TEST(MetaTextureCache, ASecondLoadOfTheSameImageReusesTheIsolationAndAnotherImageOrADamagedFileDoesNot) {
  const fs::path dir = test::fresh_test_dir("terravt_meta_cache");
  ASSERT_TRUE(write_image((dir / "wall.png").string(), bricks(50)).ok());
  const std::string scene = test::write_scene_json(dir, "scene.json", R"(
    {"name": "ground", "albedo": {"generator": "sand", "resolution": 16}, "weight": "remainder"},
    {"name": "wall", "albedo": {"image": "wall.png"}, "mode": "fbpb", "weight": {"rule": {"height": [0, 1]}}})");

  const Loaded first = load_wall(scene);
  EXPECT_EQ(first.isolations, 1u);
  EXPECT_GT(first.meta.feature_count, 20u);
  ASSERT_EQ(cache_files(dir).size(), 1u);

  const Loaded again = load_wall(scene);
  EXPECT_EQ(again.isolations, 0u) << "the cached meta-texture was not used";
  EXPECT_TRUE(same(again.meta, first.meta));

  // Other bricks: another key, isolated afresh; the first image's entry stays.
  ASSERT_TRUE(write_image((dir / "wall.png").string(), bricks(60)).ok());
  const Loaded other = load_wall(scene);
  EXPECT_EQ(other.isolations, 1u);
  EXPECT_EQ(cache_files(dir).size(), 2u);

  // A damaged cache file is rebuilt, to the same meta-texture.
  ASSERT_TRUE(write_image((dir / "wall.png").string(), bricks(50)).ok());
  for (const fs::path& f : cache_files(dir)) std::ofstream(f, std::ios::trunc) << "not an EXR";
  const Loaded rebuilt = load_wall(scene);
  EXPECT_EQ(rebuilt.isolations, 1u);
  EXPECT_TRUE(same(rebuilt.meta, first.meta));
  EXPECT_EQ(load_wall(scene).isolations, 0u) << "the rebuilt entry was not written back";

  // A folder the cache cannot be made in costs only the time.
  fs::remove_all(dir / ".terravt-cache");
  std::ofstream(dir / ".terravt-cache") << "a file where the cache folder would be";
  const Loaded uncached = load_wall(scene);
  EXPECT_EQ(uncached.isolations, 1u);
  EXPECT_TRUE(same(uncached.meta, first.meta));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace tvt
