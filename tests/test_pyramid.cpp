// The filtered pyramid (streaming/pyramid.h): the rounding of the box filter, every mip-m page
// of a filtered bake equal to the box filter of the finer mip (borders from the neighbours,
// clamped at the terrain edge), checked texel by texel against a direct reading of the rule;
// byte identity across batch sizes, resumes, shards, `finer` stores and region bakes; the
// pyramid in the header.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "support/temp_dir.h"
#include "streaming/bake.h"
#include "streaming/pyramid.h"
#include "streaming/store_format.h"
#include "streaming/synthetic_pages.h"

using namespace tvt;
namespace fs = std::filesystem;
namespace sf = tvt::store_format;

namespace {

class PyramidTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tvt::test::fresh_test_dir("tvt_pyramid");
    desc_.vt = VtConfig{10, 64, 4};  // mips 0..4: 256 + 64 + 16 + 4 + 1 pages
    desc_.producer = "pyramid test";
    desc_.pyramid = StorePyramid::filtered;
    plan_ = bake_plan(desc_.vt, BakeRegion{}, StorePyramid::filtered).value();
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static std::vector<uint8_t> read_bytes(const std::string& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
  }
  // The single uninterrupted filtered bake of the whole VT.
  const std::string& reference() {
    static const std::string name = "reference.tvt";
    if (!fs::exists(path(name))) {
      auto r = bake_store(path(name), desc_, plan_, synthetic_source(desc_), BakeOptions{});
      EXPECT_TRUE(r.ok()) << r.error().message;
    }
    reference_ = path(name);
    return reference_;
  }

  fs::path dir_;
  StoreDesc desc_;
  std::vector<PageId> plan_;
  std::string reference_;
};

// Every page of a store, decoded.
std::map<uint64_t, std::vector<uint8_t>> all_pages(const std::string& p) {
  auto reader = PageStoreReader::open(p);
  EXPECT_TRUE(reader.ok()) << reader.error().message;
  std::map<uint64_t, std::vector<uint8_t>> out;
  auto decoder = reader.value()->make_decoder();
  for (const StoreEntry& e : reader.value()->entries()) {
    std::vector<uint8_t> page(reader.value()->page_bytes());
    EXPECT_EQ(reader.value()->read_page(e.page, page, *decoder), PageError::none);
    out[e.page.pack()] = std::move(page);
  }
  return out;
}

}  // namespace

TEST(BoxFilter, AveragesFourTexelsPerChannelRoundingHalvesUp) {
  // Four 2x2 blocks side by side (8x2 texels) -> 4x1 texels; channel c of block k below.
  const uint8_t block[4][4][4] = {
      {{0, 0, 1, 255}, {0, 1, 1, 255}, {0, 0, 1, 255}, {1, 1, 0, 255}},  // sums 1, 2, 3, 1020
      {{0, 1, 2, 3}, {1, 2, 3, 4}, {2, 3, 4, 5}, {3, 4, 5, 6}},          // sums 6, 10, 14, 18
      {{255, 254, 0, 9}, {255, 255, 0, 9}, {255, 255, 0, 9}, {255, 255, 1, 10}},
      {{7, 7, 7, 7}, {7, 7, 7, 7}, {7, 7, 7, 7}, {7, 7, 7, 7}}};
  uint8_t src[2][8][4];
  for (int k = 0; k < 4; ++k)
    for (int t = 0; t < 4; ++t)
      for (int c = 0; c < 4; ++c) src[t / 2][2 * k + t % 2][c] = block[k][t][c];
  uint8_t dst[4][4] = {};
  box_filter_rgba8(&src[0][0][0], 8 * 4, 4, 1, &dst[0][0], 4 * 4);
  const uint8_t expected[4][4] = {{0, 1, 1, 255},      // 1/4 -> 0, 2/4 -> 1 (half up), 3/4 -> 1
                                  {2, 3, 4, 5},        // 1.5 -> 2, 2.5 -> 3, 3.5 -> 4, 4.5 -> 5
                                  {255, 255, 0, 9},    // 1019/4 = 254.75 -> 255, 1/4 -> 0, 37/4 -> 9
                                  {7, 7, 7, 7}};
  for (int k = 0; k < 4; ++k)
    for (int c = 0; c < 4; ++c) EXPECT_EQ(dst[k][c], expected[k][c]) << "texel " << k << " channel " << c;
}

TEST_F(PyramidTest, EveryCoarsePageIsTheBoxFilterOfTheFinerMipWithBordersFromItsNeighbours) {
  const auto pages = all_pages(reference());
  ASSERT_EQ(pages.size(), plan_.size());
  const int64_t P = desc_.vt.page_texels, B = desc_.vt.border_texels, slot = desc_.vt.slot_texels();
  // Texel (X, Y) of mip m as its page's payload holds it.
  auto texel = [&](uint32_t m, int64_t X, int64_t Y, int c) {
    const auto& page = pages.at(PageId{m, uint32_t(X / P), uint32_t(Y / P)}.pack());
    return int(page[size_t(((Y % P + B) * slot + X % P + B) * 4 + c)]);
  };
  uint64_t checked = 0;
  for (const PageId& id : plan_) {
    const auto& page = pages.at(id.pack());
    if (id.mip == 0) {
      EXPECT_EQ(page, synthetic_page(desc_, id)) << to_string(id) << ": level 0 is the source's page";
      continue;
    }
    const int64_t last = int64_t(desc_.vt.mip_texels(id.mip)) - 1;
    for (int64_t ty = 0; ty < slot; ++ty)
      for (int64_t tx = 0; tx < slot; ++tx) {
        const int64_t X = std::clamp<int64_t>(id.x * P - B + tx, 0, last), Y = std::clamp<int64_t>(id.y * P - B + ty, 0, last);
        for (int c = 0; c < 4; ++c) {
          const int sum = texel(id.mip - 1, 2 * X, 2 * Y, c) + texel(id.mip - 1, 2 * X + 1, 2 * Y, c) +
                          texel(id.mip - 1, 2 * X, 2 * Y + 1, c) + texel(id.mip - 1, 2 * X + 1, 2 * Y + 1, c);
          ASSERT_EQ(int(page[size_t((ty * slot + tx) * 4 + c)]), (sum + 2) >> 2)
              << to_string(id) << " slot texel (" << tx << "," << ty << ") channel " << c;
        }
        ++checked;
      }
  }
  EXPECT_EQ(checked, uint64_t(85) * uint64_t(slot * slot));
}

TEST_F(PyramidTest, FilteredBakeIsByteIdenticalWhateverTheBatchThreadsOrResumes) {
  const auto expected = read_bytes(reference());
  BakeOptions small;
  small.batch_pages = 3;
  small.threads = 1;
  auto r = bake_store(path("small.tvt"), desc_, plan_, synthetic_source(desc_), small);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(read_bytes(path("small.tvt")), expected);
  EXPECT_EQ(r->extra_composed, 0u) << "a whole-VT bake filters from its own pages only";
  EXPECT_GT(r->read_back, 0u);

  for (uint32_t stop : {1u, 37u, 90u, 110u}) {  // mid level 0, at and past the mip-1 start
    const std::string p = path("resumed" + std::to_string(stop) + ".tvt");
    BakeOptions o;
    o.batch_pages = 3;
    auto seen = std::make_shared<uint32_t>(0);
    o.progress = [seen](const BakeProgress&) { ++*seen; };
    o.cancelled = [seen, stop] { return *seen >= stop; };
    auto cancelled = bake_store(p, desc_, plan_, synthetic_source(desc_), o);
    ASSERT_FALSE(cancelled.ok());
    ASSERT_TRUE(fs::exists(p + ".partial"));
    auto resumed = bake_store(p, desc_, plan_, synthetic_source(desc_), BakeOptions{});
    ASSERT_TRUE(resumed.ok()) << resumed.error().message;
    EXPECT_GT(resumed->resumed_pages, 0u);
    EXPECT_EQ(read_bytes(p), expected) << "cancelled after " << stop << " batches";
  }
}

TEST_F(PyramidTest, ShardsMergeToTheSingleFilteredBakeAndFinerStoresSpareTheComposition) {
  const auto expected = read_bytes(reference());
  std::vector<std::string> parts;
  std::vector<BakeSummary> summaries;
  for (uint32_t i = 0; i < 3; ++i) {
    BakeOptions o;
    o.shard_index = i;
    o.shard_count = 3;
    parts.push_back(path("part" + std::to_string(i) + ".tvt"));
    auto r = bake_store(parts.back(), desc_, plan_, synthetic_source(desc_), o);
    ASSERT_TRUE(r.ok()) << r.error().message;
    summaries.push_back(r.value());
  }
  // 341 pages: shards 0 and 1 are level 0 only; shard 2 ends level 0 and holds every coarser
  // page, so alone it composes the level-0 pages of shards 0 and 1 again.
  EXPECT_EQ(summaries[0].extra_composed, 0u);
  EXPECT_EQ(summaries[2].extra_composed, 228u);
  auto merged = merge_stores(parts, path("merged.tvt"));
  ASSERT_TRUE(merged.ok()) << merged.error().message;
  EXPECT_EQ(read_bytes(path("merged.tvt")), expected);

  // Given the finished shards 0 and 1, shard 2 reads their pages instead: same bytes, nothing extra.
  BakeOptions o;
  o.shard_index = 2;
  o.shard_count = 3;
  o.finer = {parts[0], parts[1]};
  auto r = bake_store(path("part2b.tvt"), desc_, plan_, synthetic_source(desc_), o);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->extra_composed, 0u);
  EXPECT_EQ(read_bytes(path("part2b.tvt")), read_bytes(parts[2]));

  // A store of another pyramid is refused as a finer store, by name.
  StoreDesc composed = desc_;
  composed.pyramid = StorePyramid::composed;
  ASSERT_TRUE(bake_store(path("composed.tvt"), composed, bake_plan(desc_.vt, BakeRegion{}).value(), synthetic_source(composed),
                         BakeOptions{}).ok());
  o.finer = {path("composed.tvt")};
  auto refused = bake_store(path("part2c.tvt"), desc_, plan_, synthetic_source(desc_), o);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("composed.tvt holds pages of another bake: it differs in pyramid"), std::string::npos)
      << refused.error().message;
  EXPECT_FALSE(fs::exists(path("part2c.tvt")));
}

TEST_F(PyramidTest, RegionAndMipRangeBakesMakeTheFinerPagesTheyDoNotHoldAndMatchTheWholeBake) {
  const auto whole = all_pages(reference());
  BakeRegion region;
  region.x0 = 100;  // not page-aligned: its coarse pages need level-0 pages outside it
  region.y0 = 700;
  region.x1 = 300;
  region.y1 = 1024;  // touches the bottom edge (clamped borders)
  region.mip_lo = 2;
  const auto plan = bake_plan(desc_.vt, region, StorePyramid::filtered).value();
  ASSERT_EQ(plan.front().mip, 2u) << "finest first";
  auto r = bake_store(path("region.tvt"), desc_, plan, synthetic_source(desc_), BakeOptions{});
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_GT(r->extra_composed, 0u);
  const auto pages = all_pages(path("region.tvt"));
  ASSERT_EQ(pages.size(), plan.size());
  for (const auto& [id, page] : pages) EXPECT_EQ(page, whole.at(id)) << to_string(PageId::unpack(id));

  // The pyramid on its own (compare's and bench mips' truth) gives the same pages, with its
  // level-0 needs listed up front (prepare) or page by page, and composes each level-0 page once.
  FilteredPyramid pyramid(desc_, synthetic_source(desc_), PageLookup{}, FilteredPyramid::Options{});
  FilteredPyramid prepared(desc_, synthetic_source(desc_), PageLookup{}, FilteredPyramid::Options{});
  const std::vector<PageId> ids = {PageId{1, 7, 0}, PageId{2, 0, 2}, PageId{3, 0, 1}};
  prepared.prepare(ids, false);
  for (const PageId& id : ids) {
    auto a = prepared.payload(id);
    auto b = pyramid.payload(id);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a.value(), b.value()) << to_string(id);
  }
  EXPECT_EQ(prepared.composed_pages(), 4u + 16u + 64u - 16u) << "mip 3 (0,1) holds mip 2 (0,2)'s 16 level-0 pages";
  for (const PageId id : {PageId{3, 1, 1}, PageId{4, 0, 0}, PageId{1, 7, 0}}) {
    auto page = pyramid.page(id);
    ASSERT_TRUE(page.ok()) << page.error().message;
    EXPECT_EQ(page.value(), whole.at(id.pack())) << to_string(id);
    auto payload = pyramid.payload(id);
    ASSERT_TRUE(payload.ok());
    const uint32_t P = desc_.vt.page_texels, B = desc_.vt.border_texels, slot = desc_.vt.slot_texels();
    for (uint32_t y = 0; y < P; ++y)
      ASSERT_TRUE(std::equal(payload->begin() + y * P * 4, payload->begin() + (y + 1) * P * 4,
                             whole.at(id.pack()).begin() + ((y + B) * slot + B) * 4))
          << to_string(id) << " payload row " << y;
  }
}

TEST_F(PyramidTest, TheHeaderSaysWhichPyramidAndOlderStoresReadAsComposed) {
  auto filtered = PageStoreReader::open(reference());
  ASSERT_TRUE(filtered.ok());
  EXPECT_EQ(filtered.value()->desc().pyramid, StorePyramid::filtered);

  StoreDesc composed = desc_;
  composed.pyramid = StorePyramid::composed;
  const auto plan = bake_plan(desc_.vt, BakeRegion{0, 0, 64, 64, 3, 4}).value();
  const std::string p = path("composed.tvt");
  ASSERT_TRUE(bake_store(p, composed, plan, synthetic_source(composed), BakeOptions{}).ok());
  auto bytes = read_bytes(p);
  EXPECT_EQ(sf::get_u32(bytes.data() + sf::off::pyramid), 0u) << "the field stores written before it existed hold";
  auto reader = PageStoreReader::open(p);
  ASSERT_TRUE(reader.ok());
  EXPECT_EQ(reader.value()->desc().pyramid, StorePyramid::composed);

  // An unknown pyramid (header hash repaired) is refused by name.
  sf::put_u32(bytes.data() + sf::off::pyramid, 2);
  sf::put_u64(bytes.data() + sf::off::header_hash, sf::hash(std::span(bytes.data(), sf::off::header_hash)));
  {
    std::ofstream f(path("bad.tvt"), std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  }
  auto bad = PageStoreReader::open(path("bad.tvt"));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("header pyramid: must be 0 (composed) or 1 (filtered), got 2"), std::string::npos)
      << bad.error().message;

  // A composed bake's partial is not resumed as a filtered one: the difference is named.
  BakeOptions o;
  o.cancelled = [] { return true; };
  ASSERT_FALSE(bake_store(path("mixed.tvt"), composed, plan, synthetic_source(composed), o).ok());
  auto mixed = bake_store(path("mixed.tvt"), desc_, plan, synthetic_source(desc_), BakeOptions{});
  ASSERT_FALSE(mixed.ok());
  EXPECT_NE(mixed.error().message.find("it differs in pyramid"), std::string::npos) << mixed.error().message;
}

TEST_F(PyramidTest, VerifyChecksCoarsePagesAgainstTheFinerMipAndFindsShardsOfDifferentSources) {
  auto clean = verify_store(reference(), 2);
  ASSERT_TRUE(clean.ok());
  EXPECT_EQ(clean->pyramid, StorePyramid::filtered);
  EXPECT_EQ(clean->filter_checked, 85u) << "every coarse page: the store holds the whole pyramid";
  EXPECT_TRUE(clean->problems.empty()) << clean->problems.front();

  // Shards of one plan and desc, but shard 0 baked from other level-0 pages than the shard
  // that filtered the coarse mips: merge cannot tell, verify can.
  std::vector<std::string> parts;
  for (uint32_t i = 0; i < 3; ++i) {
    BakeOptions o;
    o.shard_index = i;
    o.shard_count = 3;
    parts.push_back(path("mixed" + std::to_string(i) + ".tvt"));
    const SyntheticPages params{i == 0 ? 7u : 1u, 2};
    ASSERT_TRUE(bake_store(parts.back(), desc_, plan_, synthetic_source(desc_, params), o).ok());
  }
  ASSERT_TRUE(merge_stores(parts, path("mixed.tvt")).ok());
  auto mixed = verify_store(path("mixed.tvt"), 2);
  ASSERT_TRUE(mixed.ok());
  EXPECT_EQ(mixed->filter_checked, 85u);
  ASSERT_FALSE(mixed->problems.empty());
  EXPECT_LT(mixed->problems.size(), 85u) << "coarse pages over shards 1 and 2 only are right";
  for (const std::string& p : mixed->problems)
    EXPECT_NE(p.find(": not the box filter of mip 0 (first difference at slot texel"), std::string::npos) << p;
  EXPECT_NE(mixed->problems.front().find("mixed.tvt: mip 1 page (0,0)"), std::string::npos) << mixed->problems.front();
}
