// Lazy material upload (composer/material_uploader.h, issue 3 deliverable 3): a material's
// weight layer, texture levels and meta-texture reach the GPU with the first recorded page
// that reads them (compose/material_culling.h MaterialNeeds), never for pages that exclude the
// material — and the composed pages are byte-identical to uploading everything at create(),
// for every method. The lazy composers run with poisoned buffers, so a read of anything not
// uploaded yet would show.
#include <gtest/gtest.h>

#include <bit>
#include <filesystem>
#include <map>

#include "compose/material_culling.h"
#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "app/flythrough.h"
#include "composer/gpu_composer.h"
#include "app/terrain_renderer.h"
#include "app/vt_frame_driver.h"
#include "composer/builtin_producers.h"
#include "render/vt_system.h"
#include "compose/reference_compositor.h"
#include "support/file_scene.h"
#include "support/gpu_test.h"
#include "support/temp_dir.h"

using namespace tvt;

namespace {

const SceneAssets& default_assets() {
  static const SceneAssets assets = [] {
    SceneDesc d = default_scene();
    auto a = load_scene_assets(d);
    TVT_CHECK(a.ok());
    return std::move(a.value());
  }();
  return assets;
}

// Bytes the uploader copies for `needs`, from the packed layout: the texture levels from the
// finest needed to the coarsest, each with A's spread chain, the meta block (two words per texel of the meta-texture and
// of its feature statistics chain), the weight layer.
uint64_t bytes_of(const PackedScene& s, const MaterialNeeds& needs) {
  uint64_t bytes = 0;
  for (int n = 0; n < s.params.material_count; ++n) {
    if (!(needs.mask & (1u << n))) continue;
    const gpu::TvtMaterial& m = s.params.materials[n];
    for (int l = needs.finest_level[size_t(n)]; l < m.mip_count; ++l) {
      const uint64_t texels = uint64_t(m.resolution >> l) * uint64_t(m.resolution >> l);
      bytes += 4ull * (l >= 1 ? 2 * texels : texels);  // and the level's spread chain
    }
    bytes += 4ull * uint64_t(gpu::TVT_MATERIAL_STATS_WORDS);  // the statistics, with the 1x1 level
    if ((needs.meta_mask & (1u << n)) && m.meta_offset != gpu::TVT_NO_META)
      bytes += 8ull * uint64_t(gpu::tvt_meta_block_texels(uint32_t(m.resolution)));
    bytes += 4ull * uint64_t(s.params.weight_width) * uint64_t(s.params.weight_height);
  }
  return bytes;
}

MaterialNeeds needs_of(const PackedScene& s, const std::vector<PageId>& pages) {
  const MaterialCuller culler(s);
  MaterialNeeds needs;
  for (const PageId& p : pages) needs.merge(culler.needs(p, culler.mask(p)));
  return needs;
}

std::vector<PageId> concat(std::vector<PageId> a, const std::vector<PageId>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

GpuComposerOptions lazy_poisoned() {
  GpuComposerOptions o;
  o.poison_materials = true;
  return o;
}

struct PageSets {
  std::vector<PageId> without;  // pages whose masks all exclude `material`, in transitions of others
  std::vector<PageId> with;     // pages in a transition that includes `material`
  int material = 0;
};

// Scans mip-0 and mip-1 pages for the feature material (it has a meta-texture) absent from
// transition pages of at least two other materials, and present in transitions of three.
PageSets find_pages(const PackedScene& s, const VtConfig& vt, int material) {
  const MaterialCuller culler(s);
  PageSets sets;
  sets.material = material;
  const uint32_t bit = 1u << material;
  for (uint32_t mip = 0; mip < 2; ++mip) {
    const uint32_t n = uint32_t(vt.pages_per_side(mip));
    for (uint32_t y = 3; y < n; y += 29)
      for (uint32_t x = 5; x < n; x += 31) {
        const PageId p{mip, x, y};
        const uint32_t mask = culler.mask(p);
        if (!(mask & bit) && std::popcount(mask) >= 3 && sets.without.size() < 3) sets.without.push_back(p);
        if ((mask & bit) && std::popcount(mask) >= 3 && sets.with.size() < 2) sets.with.push_back(p);
      }
  }
  return sets;
}

class GpuLazyMaterials : public GpuTest {};

}  // namespace

TEST_F(GpuLazyMaterials, PagesThatExcludeAMaterialNeverUploadItAndItComesWithTheFirstPageThatNeedsIt) {
  const SceneAssets& assets = default_assets();
  auto packed = pack_scene(assets, options_for(Method::FbpbDpt));
  ASSERT_TRUE(packed.ok());
  const PackedScene& s = packed.value();
  const int k = s.params.material_count - 1;  // cobbles: FBPB features, so a meta-texture too
  ASSERT_NE(s.params.materials[k].meta_offset, gpu::TVT_NO_META);
  const PageSets sets = find_pages(s, assets.desc.vt, k);
  ASSERT_EQ(sets.without.size(), 3u);
  ASSERT_EQ(sets.with.size(), 2u);

  auto created = GpuComposer::create(ctx(), s, 4, lazy_poisoned());
  ASSERT_TRUE(created.ok());
  GpuComposer& c = *created.value();
  const uint32_t all = (1u << s.params.material_count) - 1u;
  MaterialNeeds everything;
  everything.mask = everything.meta_mask = all;
  EXPECT_EQ(c.upload_stats().resident, 0u) << "create() uploaded materials";
  EXPECT_EQ(c.upload_stats().bytes_uploaded, 0u);
  EXPECT_EQ(c.upload_stats().bytes_total, bytes_of(s, everything));

  c.compose_pages(sets.without).value();
  const MaterialNeeds first = needs_of(s, sets.without);
  ASSERT_FALSE(first.mask & (1u << k));
  EXPECT_EQ(c.upload_stats().resident_mask, first.mask);
  EXPECT_EQ(c.upload_stats().resident, uint32_t(std::popcount(first.mask)));
  EXPECT_EQ(c.upload_stats().bytes_uploaded, bytes_of(s, first));
  EXPECT_EQ(c.upload_stats().last_bytes, bytes_of(s, first));
  c.compose_pages(sets.without).value();  // again: nothing new
  EXPECT_EQ(c.upload_stats().last_materials, 0u);
  EXPECT_EQ(c.upload_stats().bytes_uploaded, bytes_of(s, first));

  // One batch mixing pages with and without k: k, its meta-texture included, arrives first.
  const std::vector<PageId> mixed = {sets.without[0], sets.with[0]};
  c.compose_pages(mixed).value();
  const MaterialNeeds second = needs_of(s, concat(sets.without, mixed));
  ASSERT_TRUE(second.meta_mask & (1u << k));
  EXPECT_EQ(c.upload_stats().resident_mask, second.mask);
  EXPECT_EQ(c.upload_stats().bytes_uploaded, bytes_of(s, second));
  EXPECT_EQ(c.upload_stats().last_bytes, bytes_of(s, second) - bytes_of(s, first));
  RecordProperty("bytes_without_material", std::to_string(bytes_of(s, first)));
  RecordProperty("bytes_total", std::to_string(c.upload_stats().bytes_total));

  // A per-pixel pass may read any material: it completes the upload first.
  ASSERT_TRUE(c.upload_all_materials().ok());
  EXPECT_EQ(c.upload_stats().complete_mask, all);
  EXPECT_EQ(c.upload_stats().bytes_uploaded, c.upload_stats().bytes_total);
}

TEST_F(GpuLazyMaterials, TheTopPageUploadsOnlyCoarseLevelsAndNoMetaTexture) {
  const SceneAssets& assets = default_assets();
  auto packed = pack_scene(assets, options_for(Method::FbpbDpt));
  ASSERT_TRUE(packed.ok());
  const PackedScene& s = packed.value();
  auto created = GpuComposer::create(ctx(), s, 2, lazy_poisoned());
  ASSERT_TRUE(created.ok());
  GpuComposer& c = *created.value();
  const uint32_t top = assets.desc.vt.mip_count() - 1;
  const std::vector<PageId> pages = {{top, 0, 0}};
  c.compose_pages(pages).value();
  const MaterialNeeds needs = needs_of(s, pages);
  const uint32_t all = (1u << s.params.material_count) - 1u;
  EXPECT_EQ(needs.mask, all) << "the top page covers the terrain: every material is in it";
  EXPECT_EQ(needs.meta_mask, 0u);
  EXPECT_EQ(c.upload_stats().complete_mask, 0u);
  EXPECT_EQ(c.upload_stats().bytes_uploaded, bytes_of(s, needs));
  // Beyond the weight layers, a sliver of the textures.
  const uint64_t weights = 4ull * uint64_t(s.params.weight_width) * uint64_t(s.params.weight_height) *
                           uint64_t(s.params.material_count);
  EXPECT_LT(c.upload_stats().bytes_uploaded - weights, (c.upload_stats().bytes_total - weights) / 64);
  for (int n = 0; n < s.params.material_count; ++n) EXPECT_GE(int(needs.finest_level[size_t(n)]), 5) << n;
}

TEST_F(GpuLazyMaterials, WithoutCullingEveryMaterialComesWithTheFirstBatch) {
  auto packed = pack_scene(default_assets(), options_for(Method::Linear));
  ASSERT_TRUE(packed.ok());
  auto created = GpuComposer::create(ctx(), packed.value(), 2, lazy_poisoned());
  ASSERT_TRUE(created.ok());
  GpuComposer& c = *created.value();
  c.set_culling(false);
  const PageId page[] = {{3, 1, 1}};
  c.compose_pages(page).value();
  const MaterialCuller culler(packed.value());
  EXPECT_EQ(c.upload_stats().resident, uint32_t(packed->params.material_count));
  EXPECT_EQ(c.upload_stats().bytes_uploaded, bytes_of(packed.value(), culler.needs(page[0], ~0u)));
}

TEST_F(GpuLazyMaterials, EagerCreateUploadsEverythingAtOnce) {
  auto packed = pack_scene(default_assets(), options_for(Method::Linear));
  ASSERT_TRUE(packed.ok());
  GpuComposerOptions eager;
  eager.lazy_materials = false;
  auto created = GpuComposer::create(ctx(), packed.value(), 2, eager);
  ASSERT_TRUE(created.ok());
  const uint32_t all = (1u << packed->params.material_count) - 1u;
  EXPECT_EQ(created.value()->upload_stats().complete_mask, all);
  EXPECT_EQ(created.value()->upload_stats().bytes_uploaded, created.value()->upload_stats().bytes_total);
}

// Coarse to fine, as a VT requests them: the top page, an ancestor of a transition page, a page
// without the feature material, then pages with it; each call is one upload + dispatch.
// Direct and prefiltered (whose FBPB expectation reads the meta block's feature statistics at
// every mip, so the meta block must arrive with coarse pages too).
TEST_F(GpuLazyMaterials, ComposedPagesAreByteIdenticalToTheEagerUploadForEveryMethod) {
  const SceneAssets& assets = default_assets();
  const uint32_t top = assets.desc.vt.mip_count() - 1;
  for (const MipStrategy strategy : {MipStrategy{}, MipStrategy{1, true}})
  for (Method method : k_all_methods) {
    SCOPED_TRACE(to_string(strategy));
    auto packed = pack_scene(assets, options_for(method, strategy));
    ASSERT_TRUE(packed.ok());
    const PackedScene& s = packed.value();
    const PageSets sets = find_pages(s, assets.desc.vt, s.params.material_count - 1);
    ASSERT_FALSE(sets.without.empty());
    ASSERT_FALSE(sets.with.empty());
    const PageId w = sets.with[0];
    const std::vector<std::vector<PageId>> calls = {
        {{top, 0, 0}}, {{w.mip + 2, w.x >> 2, w.y >> 2}}, {sets.without[0]}, sets.with};
    GpuComposerOptions eager_options;
    eager_options.lazy_materials = false;
    auto eager = GpuComposer::create(ctx(), s, 2, eager_options);
    auto lazy = GpuComposer::create(ctx(), s, 2, lazy_poisoned());
    ASSERT_TRUE(eager.ok() && lazy.ok());
    std::vector<PageId> order;
    std::vector<std::vector<uint8_t>> lazy_pages;
    for (const auto& call : calls) {
      auto composed = lazy.value()->compose_pages(call);
      ASSERT_TRUE(composed.ok()) << composed.error().message;
      for (auto& page : composed.value()) lazy_pages.push_back(std::move(page));
      order = concat(order, call);
      if (order.size() <= 3) {  // before the pages with it, the feature material is incomplete
        EXPECT_FALSE(lazy.value()->upload_stats().complete_mask & (1u << sets.material)) << to_string(method);
      }
    }
    const auto eager_pages = eager.value()->compose_pages(order).value();
    ASSERT_EQ(lazy_pages.size(), order.size());
    for (size_t i = 0; i < order.size(); ++i)
      EXPECT_EQ(lazy_pages[i], eager_pages[i]) << to_string(method) << " " << to_string(order[i]);
  }
}

// CPU side of the lazy path (compose/material_source.h): a material file deleted after the
// scene loaded fails the first GPU batch that needs it, naming the file and the field; batches
// of other pages compose; the uploader counts what was read from disk.
// The split scene on disk with c.png (material 2) deleted after the scene loaded; the folder
// goes with the object.
struct SceneWithDeletedMaterial {
  explicit SceneWithDeletedMaterial(const char* name)
      : dir(test::fresh_test_dir(name)), assets(test::load_split_scene(dir, &scene)) {
    std::filesystem::remove(dir / "c.png");
  }
  ~SceneWithDeletedMaterial() { std::filesystem::remove_all(dir); }
  // What every use of material 2 reports: scene file, field, image file.
  std::string error() const { return scene + ": /materials/2/albedo/image: " + (dir / "c.png").string(); }

  std::filesystem::path dir;
  std::string scene;
  SceneAssets assets;
};

TEST_F(GpuLazyMaterials, AMaterialFileBrokenAfterLoadFailsOnlyTheBatchesThatNeedIt) {
  const SceneWithDeletedMaterial broken("tvt_gpu_lazy_files");
  const SceneAssets& assets = broken.assets;
  auto packed = pack_scene(assets, {});
  ASSERT_TRUE(packed.ok());
  {
    auto created = GpuComposer::create(ctx(), packed.value(), 2, lazy_poisoned());
    ASSERT_TRUE(created.ok());
    GpuComposer& c = *created.value();
    EXPECT_EQ(c.upload_stats().cpu_loaded, 0u);
    const PageId left{0, 0, 0}, right{0, 15, 0};
    auto ok = c.compose_pages(std::vector<PageId>{left});
    ASSERT_TRUE(ok.ok()) << ok.error().message;
    EXPECT_EQ(c.upload_stats().cpu_loaded, 2u);
    EXPECT_EQ(c.upload_stats().last_cpu_loaded, 2u);
    auto bad = c.compose_pages(std::vector<PageId>{right});
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.error().message.find(broken.error()),
              std::string::npos)
        << bad.error().message;
    EXPECT_EQ(c.upload_stats().load_failures, 1u);
    EXPECT_FALSE(assets.materials->loaded(2));
    EXPECT_TRUE(c.compose_pages(std::vector<PageId>{PageId{0, 2, 5}}).ok());
  }
}

// The render loop: frame 0 composes the top page, which reads every material; a material file
// deleted after the scene loaded stops the flythrough with the file and the field, before the
// frame is reported (nothing is written), and no page of that batch becomes resident.
TEST_F(GpuLazyMaterials, AFlythroughStopsWithTheFileAndFieldWhenAMaterialCannotBeLoaded) {
  const SceneWithDeletedMaterial broken("tvt_gpu_lazy_fly");
  const SceneAssets& assets = broken.assets;
  FlythroughOptions o;
  o.frames = 4;
  o.width = 64;
  o.height = 64;
  o.vt.cache_slots = 64;
  uint32_t reported = 0;
  auto s = run_flythrough(ctx(), assets, o, [&](const FlythroughFrame&, const FlythroughViews&) {
    ++reported;
    return true;
  });
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find(broken.error()),
            std::string::npos)
      << s.error().message;
  EXPECT_EQ(reported, 0u);
}

// A direct-splat pass reads every material: one that cannot be loaded fails the renderer's
// creation with the file and the field (the buffer accessors would otherwise stop the process).
TEST_F(GpuLazyMaterials, ADirectSplatRendererReportsAMaterialThatCannotBeLoaded) {
  const SceneWithDeletedMaterial broken("tvt_gpu_lazy_direct");
  const SceneAssets& assets = broken.assets;
  auto packed = pack_scene(assets, {});
  ASSERT_TRUE(packed.ok());
  auto composer = GpuComposer::create(ctx(), packed.value(), 1, lazy_poisoned());
  ASSERT_TRUE(composer.ok());
  TerrainRendererOptions o;
  o.width = 64;
  o.height = 64;
  o.direct = TerrainDirectInputs{composer.value().get(), false};
  auto r = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find(broken.error()),
            std::string::npos)
      << r.error().message;
}

// The blocking frame driver (tests' and bench frame's convergence loop) reports the same error
// instead of stopping the process, after finishing the frame; the driver stays usable.
TEST_F(GpuLazyMaterials, TheFrameDriverReportsAMaterialThatCannotBeLoaded) {
  const SceneWithDeletedMaterial broken("tvt_gpu_lazy_driver");
  const SceneAssets& assets = broken.assets;
  SceneVtOptions vo;
  vo.cache_slots = 64;
  auto vt = make_tool_vt(ctx(), assets, Method::FbpbDpt, vo, vt_feedback_texels(64, 64, 4));
  ASSERT_TRUE(vt);
  TerrainRendererOptions o;
  o.width = 64;
  o.height = 64;
  o.vt = terrain_vt_inputs(*vt, 4, FeedbackMode::Attachment);
  auto writer = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  auto driver = VtFrameDriver::create(ctx(), *vt, *writer.value());
  ASSERT_TRUE(driver.ok());
  const Camera cam = flythrough_path(assets, writer.value()->mesh()).camera_at(1.0);
  auto c = driver.value()->converge(cam, 10);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find(broken.error()), std::string::npos) << c.error().message;
  // The next frame retries the pages and fails the same way rather than crashing.
  auto f = driver.value()->frame(cam);
  ASSERT_FALSE(f.ok());
  EXPECT_NE(f.error().message.find(broken.error()), std::string::npos) << f.error().message;
}
