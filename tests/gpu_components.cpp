// terravt's two components on a client's device: libterravt alone streams a baked store (no
// scene, no composer: terravt::VirtualTexture::create) and refuses what needs a scene; the
// compose component (terravt::compose::create_virtual_texture) composes through the public
// producer interface, streams a store checked against its scene, and mixes both. Pages are
// compared byte for byte, read back from the cache slots the page table names.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "api/tool_access.h"
#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "compose/scene_assets.h"
#include "compose/scene_identity.h"
#include "composer/gpu_composer.h"
#include "streaming/bake.h"
#include "streaming/synthetic_pages.h"
#include "support/gpu_test.h"
#include "support/temp_dir.h"
#include "support/vt_client.h"
#include "terravt/compose.h"
#include "terravt/terravt.h"

namespace tvt {
namespace {

terravt::VirtualTextureDesc small_desc() {
  terravt::VirtualTextureDesc d;
  d.cache_slots = 64;
  d.page_budget = 16;
  d.window_pages = 16;
  d.frames_in_flight = 2;
  return d;
}

// The 3x3 mip-0 pages around the centre and the mip-2 page above them.
std::vector<PageId> centre_pages(const terravt::VirtualTextureInfo& info) {
  const uint32_t c = (1u << (info.log2_size - 1)) / info.page_texels;
  std::vector<PageId> pages;
  for (uint32_t dy = 0; dy < 3; ++dy)
    for (uint32_t dx = 0; dx < 3; ++dx) pages.push_back(PageId{0, c - 1 + dx, c - 1 + dy});
  pages.push_back(PageId{2, c >> 2, c >> 2});
  return pages;
}

// Runs `frames` frames asking for `pages` (two in flight); returns the first error of record().
std::optional<terravt::Error> run(Client& client, terravt::VirtualTexture& vt, const std::vector<PageId>& pages,
                                  uint64_t frames) {
  std::vector<terravt::PageRequest> wanted;
  for (const PageId& p : pages) wanted.push_back({p.mip, p.x, p.y, 1});
  const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
  std::optional<terravt::Error> error;
  for (uint64_t f = 0; f < frames; ++f) {
    VkCommandBuffer cmd = client.begin(f);
    const auto done = f >= 2 ? std::optional<uint64_t>(f - 2) : std::nullopt;
    if (auto s = vt.begin_frame(f, done, centre, centre, wanted); !s && !error) error = s.error();
    if (auto s = vt.record(cmd); !s && !error) error = s.error();
    client.submit(f);
  }
  vkDeviceWaitIdle(client.h.device);
  return error;
}

// Each page's cache layer (its slot from the runtime's page table), read back; empty when
// the page is not resident.
std::vector<std::vector<uint8_t>> resident_layers(Client& client, terravt::VirtualTexture& vt,
                                                  const std::vector<PageId>& pages) {
  const VtSystem& runtime = terravt::detail::runtime(vt);
  terravt::ProducerTarget t;
  t.cache = runtime.cache().handle();
  t.slots = runtime.cache().layers();
  t.slot_texels = runtime.cache().width();
  const Readback r = read_back(client, vt, t);
  const size_t layer = size_t(t.slot_texels) * t.slot_texels * 4;
  std::vector<std::vector<uint8_t>> out;
  for (const PageId& p : pages) {
    const auto slot = runtime.residency().page_table().slot_of(p);
    out.push_back(slot ? std::vector<uint8_t>(r.cache.begin() + std::ptrdiff_t(*slot * layer),
                                              r.cache.begin() + std::ptrdiff_t((*slot + 1) * layer))
                       : std::vector<uint8_t>{});
  }
  return out;
}

TEST(Components, LibterravtAloneStreamsABakedStoreIntoTheCacheByteForByte) {
  const auto dir = test::fresh_test_dir("terravt_components");
  // A store of synthetic pages: nothing of a scene or a composer is involved.
  StoreDesc sd;
  sd.vt = VtConfig{10, 128, 4};
  sd.producer = "synthetic";
  const std::string path = (dir / "synthetic.tvt").string();
  auto plan = bake_plan(sd.vt, BakeRegion{});
  ASSERT_TRUE(plan.ok());
  BakeOptions bo;
  bo.resume = false;
  ASSERT_TRUE(bake_store(path, sd, plan.value(), synthetic_source(sd), bo).ok());

  Client client(2);
  ASSERT_TRUE(client.device);
  terravt::VirtualTextureDesc d = small_desc();
  d.source = terravt::PageSource::stored;
  d.store_file = path;
  auto created = terravt::VirtualTexture::create(client.h, d);
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  // The geometry is the store's.
  EXPECT_EQ(vt.info().log2_size, 10u);
  EXPECT_EQ(vt.info().page_texels, 128u);
  EXPECT_EQ(vt.info().border_texels, 4u);
  const std::vector<PageId> pages = centre_pages(vt.info());
  const auto error = run(client, vt, pages, 8);
  ASSERT_FALSE(error) << error->message;
  const auto layers = resident_layers(client, vt, pages);
  for (size_t i = 0; i < pages.size(); ++i) {
    ASSERT_FALSE(layers[i].empty()) << to_string(pages[i]) << " is not resident";
    const std::vector<uint8_t> expected = synthetic_page(sd, pages[i]);
    ASSERT_EQ(layers[i].size(), expected.size());
    EXPECT_TRUE(layers[i] == expected) << to_string(pages[i]) << ": the cache slot differs from the stored page";
  }

  // Set, the layout must be the store's.
  d.layout = {11, 128, 4};
  auto other = terravt::VirtualTexture::create(client.h, d);
  ASSERT_FALSE(other.ok());
  EXPECT_EQ(other.error().kind, terravt::ErrorKind::invalid_argument);
  EXPECT_NE(other.error().message.find("VirtualTextureDesc::layout"), std::string::npos) << other.error().message;
  EXPECT_NE(other.error().message.find(path), std::string::npos) << other.error().message;
}

TEST(Components, LibterravtAloneRefusesWhatNeedsTheComposeComponentNamingIt) {
  Client client(2);
  ASSERT_TRUE(client.device);
  const auto refused = [&](const terravt::VirtualTextureDesc& d, const std::string& field) {
    auto vt = terravt::VirtualTexture::create(client.h, d);
    ASSERT_FALSE(vt.ok()) << field;
    EXPECT_EQ(vt.error().kind, terravt::ErrorKind::invalid_argument) << vt.error().message;
    EXPECT_NE(vt.error().message.find("VirtualTextureDesc::" + field), std::string::npos) << vt.error().message;
    if (field != "layout") {
      EXPECT_NE(vt.error().message.find("terravt::compose::create_virtual_texture"), std::string::npos)
          << vt.error().message;
    }
  };
  refused(small_desc(), "source");  // composed, the default
  terravt::VirtualTextureDesc d = small_desc();
  d.source = terravt::PageSource::hybrid;
  d.store_file = "any.tvt";
  refused(d, "source");
  d = small_desc();
  d.scene_file = "scene.json";
  refused(d, "scene_file");
  // A producer needs the geometry when no scene gives it.
  struct Nothing final : terravt::PageProducer {
    terravt::ProducerAccept request(const terravt::PageTask&) override { return terravt::ProducerAccept::unavailable; }
    terravt::Status record(VkCommandBuffer, std::vector<terravt::PageTask>&, std::vector<terravt::PageTask>&) override {
      return terravt::Ok{};
    }
  };
  d = small_desc();
  d.producer = std::make_shared<Nothing>();
  refused(d, "layout");
  d.layout = {9, 128, 4};  // below the smallest VT
  refused(d, "layout");
}

class ComposeComponent : public GpuTest {
 protected:
  // The built-in scene on a 2^10 VT, as a file, and stores of it baked with fbpb+dpt2: whole,
  // and without the centre's mip-0 pages (which the hybrid then composes). Made once for the
  // suite (the bakes dominate its time), removed after it.
  struct Files {
    std::filesystem::path dir;
    std::string scene, store, partial_store;
  };
  static std::optional<Files>& files() {
    static std::optional<Files> f;
    return f;
  }
  static void TearDownTestSuite() {
    if (files()) std::filesystem::remove_all(files()->dir);
    files().reset();
  }
  void SetUp() override {
    GpuTest::SetUp();
    if (!files()) {
      Files f;
      f.dir = test::fresh_test_dir("terravt_compose_component");
      make_files(f);
      if (HasFatalFailure()) return;
      files() = f;
    }
    scene_file_ = files()->scene;
    store_ = files()->store;
    partial_store_ = files()->partial_store;
  }
  void make_files(Files& f) {
    SceneDesc scene = default_scene();
    scene.vt.log2_size = 10;
    f.scene = (f.dir / "scene.json").string();
    std::ofstream(f.scene) << scene_to_json(scene);
    auto loaded = load_scene_file(f.scene);
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    auto assets = load_scene_assets(loaded.value());
    ASSERT_TRUE(assets.ok()) << assets.error().message;
    // The API's default mip strategy, as the VTs below use it.
    const MipStrategy strategy = mip_strategy_from_string(terravt::VirtualTextureDesc{}.mip_strategy).value();
    auto packed = pack_scene(assets.value(), options_for(Method::FbpbDpt, strategy));
    ASSERT_TRUE(packed.ok());
    auto composer = GpuComposer::create(ctx(), packed.value(), 16);
    ASSERT_TRUE(composer.ok()) << composer.error().message;
    StoreDesc sd;
    sd.vt = assets->desc.vt;
    sd.scene_hash = store_scene_identity(assets->desc, Method::FbpbDpt, strategy, StorePyramid::composed);
    sd.producer = "gpu fbpb+dpt2";
    f.store = (f.dir / "scene.tvt").string();
    auto plan = bake_plan(sd.vt, BakeRegion{});
    ASSERT_TRUE(plan.ok());
    const std::vector<PageId> centre = centre_pages(terravt::VirtualTextureInfo{10, 128, 4, 4, 0});
    std::vector<PageId> kept;
    for (const PageId& p : plan.value())
      if (p.mip != 0 || std::find(centre.begin(), centre.end(), p) == centre.end()) kept.push_back(p);
    f.partial_store = (f.dir / "partial.tvt").string();
    BakeOptions bo;
    bo.resume = false;
    const PageSource source = [&](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) -> Status {
      auto composed = composer.value()->compose_pages(pages);
      if (!composed) return composed.error();
      out = std::move(composed.value());
      return Ok{};
    };
    ASSERT_TRUE(bake_store(f.store, sd, plan.value(), source, bo).ok());
    // The partial store's pages come from the whole one (read, not composed again).
    auto whole = PageStoreReader::open(f.store);
    ASSERT_TRUE(whole.ok()) << whole.error().message;
    const PageSource copy = [&](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) -> Status {
      auto decoder = whole.value()->make_decoder();
      out.assign(pages.size(), std::vector<uint8_t>(size_t(sd.page_bytes())));
      for (size_t i = 0; i < pages.size(); ++i)
        if (whole.value()->read_page(pages[i], out[i], *decoder) != PageError::none)
          return make_error("cannot read " + to_string(pages[i]));
      return Ok{};
    };
    ASSERT_TRUE(bake_store(f.partial_store, sd, kept, copy, bo).ok());
  }

  terravt::VirtualTextureDesc desc(terravt::PageSource source, const std::string& store) const {
    terravt::VirtualTextureDesc d = small_desc();
    d.scene_file = scene_file_;
    d.source = source;
    d.store_file = store;
    return d;
  }
  // The centre pages of a VT made by the compose component from `d`, after eight frames.
  std::vector<std::vector<uint8_t>> centre_layers(const terravt::VirtualTextureDesc& d) {
    Client client(2);
    EXPECT_TRUE(client.device);
    if (!client.device) return {};
    auto created = terravt::compose::create_virtual_texture(client.h, d);
    EXPECT_TRUE(created.ok()) << created.error().message;
    if (!created) return {};
    const std::vector<PageId> pages = centre_pages(created.value()->info());
    const auto error = run(client, *created.value(), pages, 8);
    EXPECT_FALSE(error) << error->message;
    return resident_layers(client, *created.value(), pages);
  }

  std::string scene_file_, store_, partial_store_;
};

TEST_F(ComposeComponent, ComposedStoredAndHybridPagesAreTheSameBytes) {
  const auto composed = centre_layers(desc(terravt::PageSource::composed, ""));
  const auto stored = centre_layers(desc(terravt::PageSource::stored, store_));
  const auto hybrid = centre_layers(desc(terravt::PageSource::hybrid, partial_store_));
  ASSERT_EQ(composed.size(), 10u);
  ASSERT_EQ(stored.size(), composed.size());
  ASSERT_EQ(hybrid.size(), composed.size());
  for (size_t i = 0; i < composed.size(); ++i) {
    ASSERT_FALSE(composed[i].empty()) << "page " << i << " not composed";
    EXPECT_TRUE(stored[i] == composed[i]) << "page " << i << ": stored differs from composed";
    EXPECT_TRUE(hybrid[i] == composed[i]) << "page " << i << ": hybrid differs from composed";
  }
}

TEST_F(ComposeComponent, AStoreOfAnotherMethodOrGeometryIsRefusedNamingTheField) {
  Client client(2);
  ASSERT_TRUE(client.device);
  terravt::VirtualTextureDesc d = desc(terravt::PageSource::stored, store_);
  d.method = "linear";  // the store holds fbpb+dpt2 pages
  auto other_method = terravt::compose::create_virtual_texture(client.h, d);
  ASSERT_FALSE(other_method.ok());
  EXPECT_EQ(other_method.error().kind, terravt::ErrorKind::invalid_argument);
  EXPECT_NE(other_method.error().message.find("scene_hash"), std::string::npos) << other_method.error().message;
  EXPECT_NE(other_method.error().message.find(store_), std::string::npos) << other_method.error().message;
  // libterravt alone reads the same store without a scene to check it against.
  terravt::VirtualTextureDesc bare = small_desc();
  bare.source = terravt::PageSource::stored;
  bare.store_file = store_;
  EXPECT_TRUE(terravt::VirtualTexture::create(client.h, bare).ok());
  // A layout that is not the scene's.
  d = desc(terravt::PageSource::composed, "");
  d.layout = {12, 128, 4};
  auto other_layout = terravt::compose::create_virtual_texture(client.h, d);
  ASSERT_FALSE(other_layout.ok());
  EXPECT_NE(other_layout.error().message.find("VirtualTextureDesc::layout"), std::string::npos)
      << other_layout.error().message;
}

TEST_F(ComposeComponent, APageComposerComposesTheVtsBytesIntoHostMemory) {
  const terravt::VirtualTextureDesc d = desc(terravt::PageSource::composed, "");
  const auto in_vt = centre_layers(d);
  Client client(1);
  ASSERT_TRUE(client.device);
  auto made = terravt::compose::PageComposer::create(client.h, d, 4);  // batches of 4: three submissions
  ASSERT_TRUE(made.ok()) << made.error().message;
  terravt::compose::PageComposer& composer = *made.value();
  EXPECT_EQ(composer.info().log2_size, 10u);
  EXPECT_EQ(composer.page_bytes(), uint64_t(136) * 136 * 4);
  std::vector<terravt::PageRequest> requests;
  for (const PageId& p : centre_pages(composer.info())) requests.push_back({p.mip, p.x, p.y, 1});
  std::vector<std::vector<uint8_t>> pages;
  const terravt::Status s = composer.compose(requests, pages);
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_EQ(pages.size(), in_vt.size());
  for (size_t i = 0; i < pages.size(); ++i)
    EXPECT_TRUE(pages[i] == in_vt[i]) << "page " << i << ": not the bytes the VT's cache slot holds";

  // A page outside the VT is refused by index, before anything is composed.
  requests[1] = {0, 8, 0, 1};  // mip 0 has 8 pages a side
  pages.clear();
  const terravt::Status bad = composer.compose(requests, pages);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().kind, terravt::ErrorKind::invalid_argument);
  EXPECT_NE(bad.error().message.find("pages[1]"), std::string::npos) << bad.error().message;
  EXPECT_TRUE(pages.empty());
  // Bad descriptions and batches name what is wrong.
  auto no_batch = terravt::compose::PageComposer::create(client.h, d, 0);
  ASSERT_FALSE(no_batch.ok());
  EXPECT_NE(no_batch.error().message.find("batch"), std::string::npos);
  terravt::VirtualTextureDesc bad_method = d;
  bad_method.method = "nonsense";
  auto refused = terravt::compose::PageComposer::create(client.h, bad_method);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("VirtualTextureDesc::method"), std::string::npos);
}

}  // namespace
}  // namespace tvt
