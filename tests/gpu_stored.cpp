// Stored megatexture through the real pipeline (validation on): pages baked with the GPU
// compositor read back byte-identical; a flythrough from the store shows exactly the frames
// the procedural flythrough shows; corrupt pages are reported once and never land, and the
// hybrid source composes them instead.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>

#include "compose/image_diff.h"
#include "compose/scene.h"
#include "compose/scene_identity.h"
#include "app/flythrough.h"
#include "composer/gpu_composer.h"
#include "streaming/bake.h"
#include "streaming/page_store.h"
#include "support/gpu_test.h"

using namespace tvt;

namespace {

// The default scene on a 2^10 VT: 85 pages of 136^2 texels, cheap enough to bake in a test.
const SceneAssets& small_assets() {
  static const SceneAssets a = [] {
    SceneDesc d = default_scene();
    d.vt.log2_size = 10;
    auto r = load_scene_assets(d);
    EXPECT_TRUE(r.ok()) << r.error().message;
    return std::move(r.value());
  }();
  return a;
}

std::string temp_path(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("terravt_gpu_stored_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

StoreDesc desc_for(const SceneAssets& assets, Method method) {
  StoreDesc d;
  d.vt = assets.desc.vt;
  d.scene_hash = scene_identity(assets.desc, method);
  d.producer = "gpu test";
  return d;
}

// Bakes `plan` with a GPU composer of `method`; returns the store path.
std::string bake(vk::Context& g, const SceneAssets& assets, Method method, const std::vector<PageId>& plan,
                 const std::string& name) {
  auto packed = pack_scene(assets, options_for(method));
  EXPECT_TRUE(packed.ok());
  auto composer = GpuComposer::create(g, packed.value(), 16);
  EXPECT_TRUE(composer.ok());
  const std::string path = temp_path(name);
  BakeOptions bo;
  bo.resume = false;
  bo.threads = 2;
  auto s = bake_store(path, desc_for(assets, method), plan,
                      [&](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) -> Status {
                        out = composer.value()->compose_pages(pages).value();
                        return Ok{};
                      },
                      bo);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  return path;
}

FlythroughOptions small_flythrough() {
  FlythroughOptions o;
  o.method = Method::Linear;
  o.frames = 14;
  o.width = 96;
  o.height = 54;
  o.fps = 1.0;  // crosses the whole path, camera cut included
  o.feedback_divisor = 2;
  o.vt.cache_slots = 64;
  o.vt.page_budget = 8;
  o.vt.window_pages = 8;
  o.deterministic = true;
  return o;
}

struct FlyResult {
  FlythroughSummary summary;
  std::vector<ImageRGBA8> frames;
  std::set<std::string> errors;
  uint32_t error_lines = 0, fallback = 0, missing = 0;
};

FlyResult fly(vk::Context& g, const FlythroughOptions& o) {
  FlyResult r;
  auto s = run_flythrough(g, small_assets(), o, [&](const FlythroughFrame& f, const FlythroughViews& views) {
    r.frames.push_back(views.frame());
    for (const std::string& e : f.store_errors) r.errors.insert(e);
    r.error_lines += uint32_t(f.store_errors.size());
    r.fallback += f.vt.fallback_composed;
    r.missing += f.vt.missing;
    return true;
  });
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  if (s.ok()) r.summary = s.value();
  return r;
}

void expect_same_frames(const FlyResult& a, const FlyResult& b) {
  ASSERT_EQ(a.frames.size(), b.frames.size());
  for (size_t i = 0; i < a.frames.size(); ++i) {
    const ImageDiff d = compare_images(a.frames[i], b.frames[i]);
    EXPECT_TRUE(d.identical()) << "frame " << i << ": " << d.pixels_differing << " pixels differ, max " << d.max_abs;
  }
}

// Flips one byte in the middle of the blobs of `pages` in a copy of `path`.
std::string corrupt_copy(const std::string& path, const std::vector<PageId>& pages, const std::string& name) {
  const std::string out = temp_path(name);
  std::filesystem::copy_file(path, out, std::filesystem::copy_options::overwrite_existing);
  auto r = PageStoreReader::open(path);
  EXPECT_TRUE(r.ok());
  std::fstream f(out, std::ios::in | std::ios::out | std::ios::binary);
  for (const PageId& p : pages) {
    const StoreEntry* e = r.value()->find(p);
    EXPECT_NE(e, nullptr);
    f.seekg(std::streamoff(e->offset + e->stored_bytes / 2));
    char c = 0;
    f.read(&c, 1);
    c = char(c ^ 0x5a);
    f.seekp(std::streamoff(e->offset + e->stored_bytes / 2));
    f.write(&c, 1);
  }
  return out;
}

}  // namespace

class GpuStored : public GpuTest {};

TEST_F(GpuStored, BakedPagesReadBackByteIdenticalToFreshlyComposed) {
  const SceneAssets& assets = small_assets();
  BakeRegion region;
  region.mip_lo = 0;
  auto plan = bake_plan(assets.desc.vt, region);
  ASSERT_TRUE(plan.ok());
  plan.value().resize(24);  // the three coarsest mips and a few mip-0 pages
  const std::string path = bake(ctx(), assets, Method::FbpbDpt, plan.value(), "fbpb.tvt");
  auto store = PageStoreReader::open(path);
  ASSERT_TRUE(store.ok()) << store.error().message;
  ASSERT_EQ(store.value()->entries().size(), plan->size());

  auto packed = pack_scene(assets, options_for(Method::FbpbDpt));
  ASSERT_TRUE(packed.ok());
  auto composer = GpuComposer::create(ctx(), packed.value(), 8);  // another batch size: same bytes
  ASSERT_TRUE(composer.ok());
  const auto fresh = composer.value()->compose_pages(plan.value()).value();
  auto decoder = store.value()->make_decoder();
  std::vector<uint8_t> page(store.value()->page_bytes());
  for (size_t i = 0; i < plan->size(); ++i) {
    ASSERT_EQ(store.value()->read_page(plan.value()[i], page, *decoder), PageError::none);
    EXPECT_EQ(page, fresh[i]) << to_string(plan.value()[i]);
  }
}

TEST_F(GpuStored, StoredFlythroughShowsTheProceduralFramesExactly) {
  auto plan = bake_plan(small_assets().desc.vt, BakeRegion{});
  ASSERT_TRUE(plan.ok());
  const std::string path = bake(ctx(), small_assets(), Method::Linear, plan.value(), "linear.tvt");
  auto store = PageStoreReader::open(path);
  ASSERT_TRUE(store.ok());

  FlythroughOptions o = small_flythrough();
  const FlyResult procedural = fly(ctx(), o);
  o.vt.source = VtSource::stored;
  o.vt.store = std::move(store.value());
  o.vt.sync_loads = true;
  const FlyResult stored = fly(ctx(), o);
  EXPECT_EQ(stored.summary.pages_composed, 0u);
  EXPECT_EQ(stored.summary.pages_loaded, procedural.summary.pages_composed);
  EXPECT_EQ(stored.summary.load_failures, 0u);
  expect_same_frames(procedural, stored);

  // Asynchronous loads, as an engine runs them: nothing fails, pages land.
  o.vt.sync_loads = false;
  o.deterministic = false;
  const FlyResult async = fly(ctx(), o);
  EXPECT_GT(async.summary.pages_loaded, procedural.summary.pages_composed / 2);
  EXPECT_EQ(async.summary.load_failures, 0u);
}

TEST_F(GpuStored, CorruptPagesAreReportedOnceNeverLandAndHybridComposesThem) {
  auto plan = bake_plan(small_assets().desc.vt, BakeRegion{});
  ASSERT_TRUE(plan.ok());
  const std::string good = bake(ctx(), small_assets(), Method::Linear, plan.value(), "linear2.tvt");
  // Mip-1 pages: every view needs some of them (the coarsest mip is pinned, never missing).
  const std::vector<PageId> bad{{1, 0, 0}, {1, 1, 0}, {1, 0, 1}, {1, 1, 1}, {1, 2, 2}, {1, 3, 3}};
  const std::string path = corrupt_copy(good, bad, "corrupt.tvt");
  auto store = PageStoreReader::open(path);
  ASSERT_TRUE(store.ok()) << store.error().message;  // the index is intact: pages fail one by one

  FlythroughOptions o = small_flythrough();
  const FlyResult procedural = fly(ctx(), o);
  o.vt.source = VtSource::stored;
  o.vt.store = std::shared_ptr<const PageStoreReader>(std::move(store.value()));
  o.vt.sync_loads = true;
  const FlyResult stored = fly(ctx(), o);
  EXPECT_GT(stored.summary.load_failures, 0u);
  EXPECT_LE(stored.summary.load_failures, bad.size());      // never asked again after failing
  EXPECT_EQ(stored.error_lines, stored.summary.load_failures);  // each reported once
  EXPECT_EQ(stored.errors.size(), stored.error_lines);
  for (const std::string& e : stored.errors) EXPECT_NE(e.find("corrupt.tvt"), std::string::npos) << e;

  o.vt.source = VtSource::hybrid;
  const FlyResult hybrid = fly(ctx(), o);
  EXPECT_EQ(hybrid.fallback, hybrid.summary.load_failures);
  EXPECT_GT(hybrid.fallback, 0u);
  expect_same_frames(procedural, hybrid);  // composed instead: no bad texel, no hole
}

TEST_F(GpuStored, StoreOfAnotherSceneIsRefused) {
  auto plan = bake_plan(small_assets().desc.vt, BakeRegion{0, 0, 1, 1, 3, 3});
  ASSERT_TRUE(plan.ok());
  const std::string path = bake(ctx(), small_assets(), Method::Linear, plan.value(), "top.tvt");
  auto store = PageStoreReader::open(path);
  ASSERT_TRUE(store.ok());
  FlythroughOptions o = small_flythrough();
  o.method = Method::Fbpb;  // the store holds linear pages
  o.frames = 1;
  o.vt.source = VtSource::stored;
  o.vt.store = std::move(store.value());
  auto s = run_flythrough(ctx(), small_assets(), o, {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("scene_hash"), std::string::npos) << s.error().message;
  EXPECT_NE(s.error().message.find("top.tvt"), std::string::npos) << s.error().message;
}

namespace {
// Pixels in the "no data" colour (magenta albedo): drawn where no ancestor page is resident.
uint32_t no_data_pixels(const ImageRGBA8& img) {
  uint32_t n = 0;
  for (size_t i = 0; i < img.texels.size(); i += 4) {
    const int r = img.texels[i], g = img.texels[i + 1], b = img.texels[i + 2];
    n += r > 2 * g + 40 && b > 2 * g + 40;
  }
  return n;
}
}  // namespace

// The pinned (coarsest) pages are resident before the first frame is drawn, whatever the
// source: composed in the first frame's record (procedural; hybrid where the store lacks
// them) or loaded before it is drawn (stored, hybrid), even with asynchronous loads. So frame
// 0 shows the terrain at a coarse mip at worst, never the "no data" colour.
TEST_F(GpuStored, TheFirstFrameOfEverySourceHasNoNoDataPixel) {
  auto plan = bake_plan(small_assets().desc.vt, BakeRegion{});
  ASSERT_TRUE(plan.ok());
  const std::string path = bake(ctx(), small_assets(), Method::Linear, plan.value(), "first-frame.tvt");
  auto opened = PageStoreReader::open(path);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  const std::shared_ptr<const PageStoreReader> store(std::move(opened.value()));
  for (VtSource source : {VtSource::procedural, VtSource::stored, VtSource::hybrid}) {
    SCOPED_TRACE(std::string(to_string(source)));
    FlythroughOptions o = small_flythrough();
    o.frames = 2;
    o.deterministic = false;
    o.vt.sync_loads = false;  // the default: loads land frames later, except the pinned pages
    o.vt.source = source;
    if (source != VtSource::procedural) o.vt.store = store;
    const FlyResult r = fly(ctx(), o);
    ASSERT_EQ(r.frames.size(), 2u);
    const ImageRGBA8& first = r.frames[0];
    EXPECT_EQ(no_data_pixels(first), 0u) << "of " << first.width * first.height;
    if (source != VtSource::procedural) {
      EXPECT_GT(r.summary.pages_loaded, 0u);
    }
    EXPECT_EQ(r.summary.load_failures, 0u);
  }
}
