// Lazy material upload (render/material_uploader.h, issue 3 deliverable 3): a material's
// texels, meta-texture and weight layer reach the GPU with the first recorded page whose
// culling mask includes it, never before, never for pages that exclude it — and the composed
// pages are byte-identical to uploading everything at create(), for every method.
#include <gtest/gtest.h>

#include <bit>
#include <map>

#include "compose/material_culling.h"
#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "render/gpu_composer.h"
#include "support/gpu_test.h"

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

// What uploading material n copies, from the packed layout: its mip chain, its meta-texture
// (two words per texel) and its weight layer.
uint64_t material_bytes(const PackedScene& s, int n) {
  const gpu::TvtMaterial& m = s.params.materials[n];
  uint64_t bytes = 0;
  for (int l = 0; l < m.mip_count; ++l) bytes += 4ull * uint64_t(m.resolution >> l) * uint64_t(m.resolution >> l);
  if (m.meta_offset != gpu::TVT_NO_META) bytes += 8ull * uint64_t(m.resolution) * uint64_t(m.resolution);
  return bytes + 4ull * uint64_t(s.params.weight_width) * uint64_t(s.params.weight_height);
}

uint64_t bytes_of_mask(const PackedScene& s, uint32_t mask) {
  uint64_t b = 0;
  for (int n = 0; n < s.params.material_count; ++n)
    if (mask & (1u << n)) b += material_bytes(s, n);
  return b;
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

uint32_t union_mask(const PackedScene& s, const std::vector<PageId>& pages) {
  const MaterialCuller culler(s);
  uint32_t m = 0;
  for (const PageId& p : pages) m |= culler.mask(p);
  return m;
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

  auto created = GpuComposer::create(ctx(), s, 4);
  ASSERT_TRUE(created.ok());
  GpuComposer& c = *created.value();
  const uint32_t all = (1u << s.params.material_count) - 1u;
  EXPECT_EQ(c.upload_stats().resident, 0u) << "create() uploaded materials";
  EXPECT_EQ(c.upload_stats().bytes_uploaded, 0u);
  EXPECT_EQ(c.upload_stats().bytes_total, bytes_of_mask(s, all));

  c.compose_pages(sets.without);
  const uint32_t first = union_mask(s, sets.without);
  ASSERT_FALSE(first & (1u << k));
  EXPECT_EQ(c.upload_stats().resident_mask, first);
  EXPECT_EQ(c.upload_stats().resident, uint32_t(std::popcount(first)));
  EXPECT_EQ(c.upload_stats().bytes_uploaded, bytes_of_mask(s, first));
  EXPECT_EQ(c.upload_stats().last_bytes, bytes_of_mask(s, first));
  c.compose_pages(sets.without);  // again: nothing new
  EXPECT_EQ(c.upload_stats().last_materials, 0u);
  EXPECT_EQ(c.upload_stats().bytes_uploaded, bytes_of_mask(s, first));

  // One batch mixing pages with and without k: k arrives before that dispatch.
  std::vector<PageId> mixed = {sets.without[0], sets.with[0]};
  c.compose_pages(mixed);
  const uint32_t second = first | union_mask(s, mixed);
  EXPECT_TRUE(c.upload_stats().resident_mask & (1u << k));
  EXPECT_EQ(c.upload_stats().resident_mask, second);
  EXPECT_EQ(c.upload_stats().last_bytes, bytes_of_mask(s, second & ~first));
  EXPECT_EQ(c.upload_stats().bytes_uploaded, bytes_of_mask(s, second));
  RecordProperty("bytes_without_material", std::to_string(bytes_of_mask(s, first)));
  RecordProperty("bytes_total", std::to_string(c.upload_stats().bytes_total));

  // A per-pixel pass may read any material: the buffer accessors complete the upload.
  (void)c.material_buffer();
  EXPECT_EQ(c.upload_stats().resident_mask, all);
  EXPECT_EQ(c.upload_stats().bytes_uploaded, c.upload_stats().bytes_total);
}

TEST_F(GpuLazyMaterials, WithoutCullingTheFirstBatchUploadsEverything) {
  auto packed = pack_scene(default_assets(), options_for(Method::Linear));
  ASSERT_TRUE(packed.ok());
  auto created = GpuComposer::create(ctx(), packed.value(), 2);
  ASSERT_TRUE(created.ok());
  GpuComposer& c = *created.value();
  c.set_culling(false);
  const PageId page[] = {{3, 1, 1}};
  c.compose_pages(page);
  EXPECT_EQ(c.upload_stats().resident, uint32_t(packed->params.material_count));
  EXPECT_EQ(c.upload_stats().bytes_uploaded, c.upload_stats().bytes_total);
}

TEST_F(GpuLazyMaterials, EagerCreateUploadsEverythingAtOnce) {
  auto packed = pack_scene(default_assets(), options_for(Method::Linear));
  ASSERT_TRUE(packed.ok());
  GpuComposerOptions eager;
  eager.lazy_materials = false;
  auto created = GpuComposer::create(ctx(), packed.value(), 2, eager);
  ASSERT_TRUE(created.ok());
  EXPECT_EQ(created.value()->upload_stats().resident, uint32_t(packed->params.material_count));
  EXPECT_EQ(created.value()->upload_stats().bytes_uploaded, created.value()->upload_stats().bytes_total);
}

TEST_F(GpuLazyMaterials, ComposedPagesAreByteIdenticalToTheEagerUploadForEveryMethod) {
  const SceneAssets& assets = default_assets();
  for (Method method : k_all_methods) {
    auto packed = pack_scene(assets, options_for(method));
    ASSERT_TRUE(packed.ok());
    const PackedScene& s = packed.value();
    const PageSets sets = find_pages(s, assets.desc.vt, s.params.material_count - 1);
    ASSERT_FALSE(sets.without.empty());
    ASSERT_FALSE(sets.with.empty());
    GpuComposerOptions eager_options;
    eager_options.lazy_materials = false;
    auto eager = GpuComposer::create(ctx(), s, 2, eager_options);
    auto lazy = GpuComposer::create(ctx(), s, 2);
    ASSERT_TRUE(eager.ok() && lazy.ok());
    // Lazy: pages without the material first (it must stay absent), then those that bring it.
    std::vector<PageId> rest = sets.with;
    rest.push_back(PageId{4, 3, 5});  // a coarse page
    auto lazy_pages = lazy.value()->compose_pages(sets.without);
    EXPECT_FALSE(lazy.value()->upload_stats().resident_mask & (1u << sets.material)) << to_string(method);
    for (auto& page : lazy.value()->compose_pages(rest)) lazy_pages.push_back(std::move(page));
    std::vector<PageId> order = sets.without;
    order.insert(order.end(), rest.begin(), rest.end());
    const auto eager_pages = eager.value()->compose_pages(order);
    ASSERT_EQ(lazy_pages.size(), order.size());
    for (size_t i = 0; i < order.size(); ++i)
      EXPECT_EQ(lazy_pages[i], eager_pages[i]) << to_string(method) << " " << to_string(order[i]);
  }
}
