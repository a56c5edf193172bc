// Lazy CPU material loading (compose/material_source.h): scene load reads image headers only;
// a material's texels are read by the first page that uses it, once, even from many threads;
// a file broken after load fails that page with the file and the field, and only that page;
// composed pages equal those of materials loaded up front.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "compose/reference_compositor.h"
#include "compose/scene_assets.h"
#include "support/file_scene.h"
#include "support/temp_dir.h"

using namespace tvt;
namespace fs = std::filesystem;

namespace {

class LazyMaterials : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = test::fresh_test_dir("tvt_lazy_materials");
    scene = test::write_split_scene(dir);
  }
  void TearDown() override { fs::remove_all(dir); }

  SceneAssets load() { return test::load_split_scene(dir, &scene); }

  fs::path dir;
  std::string scene;
  const PageId left{0, 0, 0};    // material 1's half: reads materials 0 and 1
  const PageId right{0, 15, 0};  // material 2's half: reads materials 0 and 2
};

TEST_F(LazyMaterials, SceneLoadReadsHeadersOnly) {
  const SceneAssets a = load();
  EXPECT_EQ(a.materials->stats().reads, 0u);
  EXPECT_EQ(a.materials->info(2).resolution, 16);
  EXPECT_EQ(a.materials->info(2).mip_count, 5);
  auto packed = pack_scene(a, {});
  ASSERT_TRUE(packed.ok());
  EXPECT_EQ(packed->loaded_mask(), 0u);
  // Texels of every level, A's spread chain (a word per texel of levels >= 1), statistics.
  EXPECT_EQ(packed->texel_words, size_t(2 * (1024 + 256 + 64 + 16 + 4 + 1) + (256 + 64 + 16 + 4 + 1)) +
                                     size_t(2 * (256 + 64 + 16 + 4 + 1) + (64 + 16 + 4 + 1)) +
                                     3 * size_t(gpu::TVT_MATERIAL_STATS_WORDS));
  EXPECT_EQ(a.materials->stats().reads, 0u);
}

TEST_F(LazyMaterials, PagesReadOnlyTheMaterialsTheyUse) {
  const SceneAssets a = load();
  auto packed = pack_scene(a, {});
  ASSERT_TRUE(packed.ok());
  auto page = compose_page_reference(packed.value(), left);
  ASSERT_TRUE(page.ok()) << page.error().message;
  EXPECT_EQ(a.materials->stats().reads, 2u);
  EXPECT_TRUE(a.materials->loaded(0));
  EXPECT_TRUE(a.materials->loaded(1));
  EXPECT_FALSE(a.materials->loaded(2));  // never read
  EXPECT_EQ(packed->loaded_mask(), 3u);
  ASSERT_TRUE(compose_page_reference(packed.value(), left).ok());
  EXPECT_EQ(a.materials->stats().reads, 2u);  // cached
}

TEST_F(LazyMaterials, FileDeletedAfterLoadFailsOnlyThePagesThatUseIt) {
  const SceneAssets a = load();
  fs::remove(dir / "c.png");
  auto packed = pack_scene(a, {});
  ASSERT_TRUE(packed.ok());
  ASSERT_TRUE(compose_page_reference(packed.value(), left).ok());
  auto bad = compose_page_reference(packed.value(), right);
  ASSERT_FALSE(bad.ok());
  const std::string& msg = bad.error().message;
  EXPECT_NE(msg.find(scene + ": /materials/2/albedo/image: "), std::string::npos) << msg;
  EXPECT_NE(msg.find((dir / "c.png").string() + ": file not found"), std::string::npos) << msg;
  EXPECT_EQ(a.materials->stats().failures, 1u);
  // The failure is remembered (no second read) and other pages still compose.
  EXPECT_FALSE(compose_page_reference(packed.value(), right).ok());
  EXPECT_EQ(a.materials->stats().reads, 3u);
  EXPECT_TRUE(compose_page_reference(packed.value(), PageId{0, 1, 1}).ok());
  EXPECT_FALSE(a.materials->load_all().ok());
}

TEST_F(LazyMaterials, FileCorruptedAfterLoadNamesTheFileAndField) {
  const SceneAssets a = load();
  std::ofstream(dir / "b.png", std::ios::binary | std::ios::trunc) << "not a png at all";
  auto packed = pack_scene(a, {});
  ASSERT_TRUE(packed.ok());
  ASSERT_TRUE(compose_page_reference(packed.value(), right).ok());
  auto bad = compose_page_reference(packed.value(), left);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find(scene + ": /materials/1/albedo/image: " + (dir / "b.png").string()),
            std::string::npos)
      << bad.error().message;
}

TEST_F(LazyMaterials, BadFilesStillFailAtSceneLoad) {
  auto desc = load_scene_file(scene);  // the parser checks that files exist; remove one after it
  ASSERT_TRUE(desc.ok());
  fs::remove(dir / "c.png");
  auto missing = load_scene_assets(desc.value());
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("/materials/2/albedo/image: " + (dir / "c.png").string() + ": file not found"),
            std::string::npos)
      << missing.error().message;
  ASSERT_TRUE(write_image((dir / "c.png").string(), ImageRGBA8(16, 1)).ok());  // oblong is fine, one row is not
  auto thin = load_scene_assets(desc.value());
  ASSERT_FALSE(thin.ok());
  EXPECT_NE(thin.error().message.find("/materials/2/albedo/image: " + (dir / "c.png").string() +
                                      ": image is 16 x 1 texels; a material image needs at least 2 x 2"),
            std::string::npos)
      << thin.error().message;
}

TEST_F(LazyMaterials, PagesEqualThoseOfMaterialsLoadedUpFront) {
  const SceneAssets lazy = load();
  SceneAssets eager = load();
  ASSERT_TRUE(eager.materials->load_all().ok());
  std::vector<MaterialAssets> copies;
  for (size_t n = 0; n < 3; ++n) copies.push_back(*eager.materials->get(n).value());
  eager.materials = MaterialSource::in_memory(std::move(copies));
  for (Method m : {Method::BlendMap, Method::Dpt2}) {
    auto a = pack_scene(lazy, options_for(m));
    auto b = pack_scene(eager, options_for(m));
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(std::memcmp(&a->params, &b->params, sizeof(a->params)), 0);
    EXPECT_EQ(a->texel_words, b->texel_words);
    for (const PageId& p : {left, right, PageId{0, 7, 3}, PageId{3, 0, 0}, PageId{4, 0, 0}})
      EXPECT_EQ(compose_page_reference(a.value(), p).value(), compose_page_reference(b.value(), p).value());
    for (size_t n = 0; n < 3; ++n) {
      const auto ta = a->texels(n), tb = b->texels(n);
      EXPECT_TRUE(std::equal(ta.begin(), ta.end(), tb.begin(), tb.end())) << n;
    }
  }
}

// The host holds each material's texels once: every packing of the scene (one per method)
// reads the source's words, and the source keeps no images once it has packed them.
TEST_F(LazyMaterials, PackingsOfOneSceneShareTheMaterialWordsAndReadEachFileOnce) {
  const SceneAssets a = load();
  auto blend = pack_scene(a, options_for(Method::BlendMap));
  auto fbpb = pack_scene(a, options_for(Method::FbpbDpt));
  ASSERT_TRUE(blend.ok() && fbpb.ok());
  ASSERT_TRUE(blend->load_all().ok());
  ASSERT_TRUE(fbpb->load_all().ok());
  EXPECT_EQ(a.materials->stats().reads, 3u);
  for (size_t n = 0; n < 3; ++n) {
    EXPECT_TRUE(a.materials->loaded(n));
    EXPECT_EQ(blend->texels(n).data(), fbpb->texels(n).data()) << n;  // one copy
    EXPECT_EQ(blend->texels(n).data(), a.materials->words(n).value()->texels.data()) << n;
  }
}

TEST_F(LazyMaterials, ConcurrentFirstUseLoadsOnce) {
  const SceneAssets a = load();
  auto packed = pack_scene(a, {});
  ASSERT_TRUE(packed.ok());
  std::atomic<int> ok{0};
  std::vector<const MaterialAssets*> seen(8, nullptr);
  {
    std::vector<std::jthread> threads;
    for (int t = 0; t < 8; ++t)
      threads.emplace_back([&, t] {
        auto r = a.materials->get(1);
        if (r) seen[size_t(t)] = r.value().get();
        if (packed->load(0b110).ok() && packed->texels(1).size() == 1365u + 341u + size_t(gpu::TVT_MATERIAL_STATS_WORDS)) ++ok;
      });
  }
  EXPECT_EQ(ok.load(), 8);
  EXPECT_EQ(a.materials->stats().reads, 2u);  // materials 1 and 2, once each
  for (const MaterialAssets* p : seen) EXPECT_EQ(p, seen[0]);
}

}  // namespace

namespace {

// An "fbpb" block promises features (the packer cannot see them without reading texels); a
// mask without any fails the first FBPB page that reads the material, naming /materials/1/fbpb.
TEST(LazyMaterialsFbpb, AFeaturelessMetaTextureFailsItsFirstFbpbPage) {
  const fs::path dir = test::fresh_test_dir("tvt_lazy_fbpb");
  test::write_split_scene(dir);
  ASSERT_TRUE(write_image((dir / "m.png").string(), ImageRGBA8(32, 32)).ok());  // all zero: no features
  const std::string scene = test::write_scene_json(dir, "fbpb.json", R"(
    {"name": "a", "albedo": {"image": "a.png"}, "period_texels": 128, "weight": "remainder"},
    {"name": "b", "albedo": {"image": "b.png"}, "period_texels": 96, "mode": "fbpb",
     "weight": {"splat": {"image": "s.png", "channel": "r"}}, "fbpb": {"mask": "m.png"}})");
  auto desc = load_scene_file(scene);
  ASSERT_TRUE(desc.ok()) << desc.error().message;
  auto assets = load_scene_assets(desc.value());
  ASSERT_TRUE(assets.ok()) << assets.error().message;
  auto fbpb = pack_scene(assets.value(), {});
  ASSERT_TRUE(fbpb.ok());
  EXPECT_EQ(fbpb->params.materials[1].mode, gpu::TVT_MODE_FBPB);  // laid out on the promise
  auto page = compose_page_reference(fbpb.value(), PageId{0, 0, 0});
  ASSERT_FALSE(page.ok());
  EXPECT_NE(page.error().message.find(scene + ": /materials/1/fbpb: "), std::string::npos) << page.error().message;
  // Modes that do not read features are unaffected.
  auto blend = pack_scene(assets.value(), options_for(Method::BlendMap));
  ASSERT_TRUE(blend.ok());
  EXPECT_TRUE(compose_page_reference(blend.value(), PageId{0, 0, 0}).ok());
  fs::remove_all(dir);
}

}  // namespace
