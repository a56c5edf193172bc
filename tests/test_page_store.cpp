// Page store format and reader: round trips, determinism, and a reader that never trusts the
// file (every truncated prefix, every flipped byte, bad fields named in errors).
#include <gtest/gtest.h>

#include <random>
#include <sys/mman.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <thread>

#include "support/temp_dir.h"
#include "streaming/bake.h"
#include "streaming/page_store.h"
#include "streaming/store_format.h"
#include "streaming/synthetic_pages.h"

using namespace tvt;
namespace fs = std::filesystem;
namespace sf = tvt::store_format;

namespace {

class PageStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tvt::test::fresh_test_dir("tvt_page_store");
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

// V = 2^10, P = 64, B = 4: 5 mips, 341 pages of 72x72 RGBA8 (20736 bytes).
StoreDesc small_desc() {
  StoreDesc d;
  d.vt = VtConfig{10, 64, 4};
  d.producer = "synthetic test pages";
  d.scene_hash = 0x1234abcd;
  return d;
}

std::vector<uint8_t> read_bytes(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}
void write_bytes(const std::string& p, std::span<const uint8_t> bytes) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

BakeSummary bake_or_die(const std::string& p, const StoreDesc& desc, std::span<const PageId> plan,
                        const SyntheticPages& sp = {}, BakeOptions o = {}) {
  auto r = bake_store(p, desc, plan, synthetic_source(desc, sp), o);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
  return r.ok() ? r.value() : BakeSummary{};
}

// The top page and the first row of mip 3: 3 compressible pages, a store of about 5 KB.
std::vector<PageId> tiny_plan(const StoreDesc& desc) {
  BakeRegion region;
  region.y1 = 512;
  region.mip_lo = 3;
  return bake_plan(desc.vt, region).value();
}

// An in-memory file (memfd) with a path, so the byte-by-byte loops do not wait on a disk.
class MemFile {
 public:
  MemFile() : fd_(::memfd_create("tvt-test-store", MFD_CLOEXEC)) {}
  ~MemFile() { ::close(fd_); }
  std::string path() const { return "/proc/self/fd/" + std::to_string(fd_); }
  void set(std::span<const uint8_t> bytes) {
    ASSERT_EQ(::ftruncate(fd_, off_t(bytes.size())), 0);
    ASSERT_EQ(::pwrite(fd_, bytes.data(), bytes.size(), 0), ssize_t(bytes.size()));
  }

 private:
  int fd_;
};

}  // namespace

TEST(BakePlan, CoarsestMipFirstThenRowsThenColumns) {
  const VtConfig vt{10, 64, 4};
  auto plan = bake_plan(vt, BakeRegion{});
  ASSERT_TRUE(plan.ok());
  ASSERT_EQ(plan->size(), 1u + 4u + 16u + 64u + 256u);
  EXPECT_EQ(plan->front(), (PageId{4, 0, 0}));
  EXPECT_EQ((*plan)[1], (PageId{3, 0, 0}));
  EXPECT_EQ((*plan)[2], (PageId{3, 1, 0}));
  EXPECT_EQ((*plan)[3], (PageId{3, 0, 1}));
  EXPECT_EQ(plan->back(), (PageId{0, 15, 15}));
  // Level-0 rectangle [100, 300) x [0, 64) at mips 0..1: mip 0 pages x 1..4, y 0; mip 1 pages x 0..2, y 0.
  BakeRegion r{100, 0, 300, 64, 0, 1};
  auto part = bake_plan(vt, r);
  ASSERT_TRUE(part.ok());
  const std::vector<PageId> expected{{1, 0, 0}, {1, 1, 0}, {1, 2, 0}, {0, 1, 0}, {0, 2, 0}, {0, 3, 0}, {0, 4, 0}};
  EXPECT_EQ(part.value(), expected);
}

TEST(BakePlan, RejectsEmptyAndInvalidRegionsByField) {
  const VtConfig vt{10, 64, 4};
  auto empty = bake_plan(vt, BakeRegion{2000, 0, 3000, 10, 0, UINT32_MAX});
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error().message.find("region"), std::string::npos);
  auto mips = bake_plan(vt, BakeRegion{0, 0, UINT64_MAX, UINT64_MAX, 5, 9});
  ASSERT_FALSE(mips.ok());
  EXPECT_NE(mips.error().message.find("mip_lo"), std::string::npos);
  auto bad_vt = bake_plan(VtConfig{10, 100, 4}, BakeRegion{});
  ASSERT_FALSE(bad_vt.ok());
  EXPECT_NE(bad_vt.error().message.find("page_texels"), std::string::npos);
  // 2^30 texels with 16-texel pages would be 2^52 pages: refused before allocating.
  auto huge = bake_plan(VtConfig{30, 16, 4}, BakeRegion{});
  ASSERT_FALSE(huge.ok());
  EXPECT_NE(huge.error().message.find("smaller regions"), std::string::npos);
}

// bake_plan_pages counts what bake_plan enumerates, for seeded random regions and mip ranges
// (some empty or inverted: then both fail alike), and refuses the same oversized plans.
TEST(BakePlan, PageCountEqualsTheEnumeratedPlan) {
  std::mt19937_64 rng(20261127);
  for (const VtConfig vt : {VtConfig{10, 64, 4}, VtConfig{14, 128, 4}, VtConfig{12, 16, 2}}) {
    const uint64_t size = vt.size_texels();
    for (int i = 0; i < 300; ++i) {
      BakeRegion r;
      r.x0 = rng() % (size + 8);
      r.y0 = rng() % (size + 8);
      r.x1 = i % 7 == 0 ? UINT64_MAX : r.x0 + rng() % (size / 2 + 1);
      r.y1 = i % 5 == 0 ? UINT64_MAX : r.y0 + rng() % (size / 2 + 1);
      r.mip_lo = uint32_t(rng() % vt.mip_count());
      r.mip_hi = i % 3 == 0 ? UINT32_MAX : uint32_t(rng() % (vt.mip_count() + 2));
      for (const StorePyramid order : {StorePyramid::composed, StorePyramid::filtered}) {
        const auto plan = bake_plan(vt, r, order);
        const auto pages = bake_plan_pages(vt, r);
        ASSERT_EQ(plan.ok(), pages.ok()) << i;
        if (plan.ok()) {
          EXPECT_EQ(pages.value(), plan->size()) << i;
        } else {
          EXPECT_EQ(pages.error().message, plan.error().message) << i;
        }
      }
    }
  }
  const auto whole = bake_plan_pages(VtConfig{20, 128, 4}, BakeRegion{});  // the built-in scene
  ASSERT_TRUE(whole.ok());
  EXPECT_EQ(whole.value(), 89478485u);
  const auto huge = bake_plan_pages(VtConfig{30, 16, 4}, BakeRegion{});
  ASSERT_FALSE(huge.ok());
  EXPECT_NE(huge.error().message.find("smaller regions"), std::string::npos);
}

TEST(ShardRange, PartsTileThePlanAndDifferByAtMostOnePage) {
  for (uint64_t pages = 0; pages < 40; ++pages)
    for (uint32_t n = 1; n < 8; ++n) {
      uint64_t next = 0, lo = UINT64_MAX, hi = 0;
      for (uint32_t i = 0; i < n; ++i) {
        const ShardRange r = shard_range(pages, i, n);
        EXPECT_EQ(r.first, next);
        next += r.count;
        lo = std::min(lo, r.count);
        hi = std::max(hi, r.count);
      }
      EXPECT_EQ(next, pages);
      EXPECT_LE(hi - lo, 1u);
    }
  EXPECT_EQ(shard_range(10, 3, 3), ShardRange{});
  EXPECT_EQ(shard_range(10, 0, 0), ShardRange{});
  EXPECT_EQ(shard_range(UINT64_MAX, 1, 2).first + shard_range(UINT64_MAX, 1, 2).count, UINT64_MAX);
}

TEST_F(PageStoreTest, RoundTripEveryPageByteIdentical) {
  const StoreDesc desc = small_desc();
  const auto plan = bake_plan(desc.vt, BakeRegion{}).value();
  const BakeSummary s = bake_or_die(path("a.tvt"), desc, plan);
  EXPECT_EQ(s.pages, plan.size());
  EXPECT_EQ(s.raw_bytes, plan.size() * desc.page_bytes());
  EXPECT_EQ(s.file_bytes, fs::file_size(path("a.tvt")));
  EXPECT_LT(s.stored_bytes, s.raw_bytes);
  EXPECT_FALSE(fs::exists(path("a.tvt.partial")));

  auto reader = PageStoreReader::open(path("a.tvt"));
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  const PageStoreReader& r = *reader.value();
  EXPECT_TRUE(r.desc() == desc);
  EXPECT_EQ(r.file_bytes(), s.file_bytes);
  ASSERT_EQ(r.entries().size(), plan.size());
  auto decoder = r.make_decoder();
  std::vector<uint8_t> page(desc.page_bytes());
  for (size_t i = 0; i < plan.size(); ++i) {
    EXPECT_EQ(r.entries()[i].page, plan[i]);  // bake order
    ASSERT_EQ(r.find(plan[i]), &r.entries()[i]);
    std::string message;
    ASSERT_EQ(r.read_page(plan[i], page, *decoder, &message), PageError::none) << message;
    ASSERT_EQ(page, synthetic_page(desc, plan[i])) << to_string(plan[i]);
  }
  std::string message;
  EXPECT_FALSE(r.contains(PageId{0, 16, 0}));
  EXPECT_EQ(r.read_page(PageId{0, 16, 0}, page, *decoder, &message), PageError::missing);
  EXPECT_NE(message.find(path("a.tvt") + ": mip 0 page (16,0)"), std::string::npos) << message;
  std::vector<uint8_t> small(100);
  EXPECT_NE(r.read_page(plan[0], small, *decoder), PageError::none);
}

TEST_F(PageStoreTest, SameBytesWhateverTheThreadCountAndBatchSize) {
  const StoreDesc desc = small_desc();
  BakeRegion region;
  region.mip_lo = 1;  // 85 pages
  const auto plan = bake_plan(desc.vt, region).value();
  std::vector<uint8_t> first;
  for (const auto& [threads, batch] : {std::pair{1u, 32u}, {2u, 1u}, {5u, 7u}, {3u, 200u}}) {
    BakeOptions o;
    o.threads = threads;
    o.batch_pages = batch;
    const std::string p = path("t" + std::to_string(threads) + ".tvt");
    bake_or_die(p, desc, plan, {}, o);
    const auto bytes = read_bytes(p);
    if (first.empty()) first = bytes;
    EXPECT_EQ(bytes, first) << threads << " threads, batches of " << batch;
  }
}

TEST_F(PageStoreTest, DictionaryRoundTripAndNegativeLevel) {
  StoreDesc desc = small_desc();
  BakeRegion region;
  region.mip_lo = 1;
  const auto plan = bake_plan(desc.vt, region).value();
  std::vector<std::vector<uint8_t>> samples;
  for (size_t i = 0; i < plan.size(); i += 4) samples.push_back(synthetic_page(desc, plan[i]));
  auto dict = train_dictionary(samples, 4096);
  ASSERT_TRUE(dict.ok()) << dict.error().message;
  EXPECT_EQ(dict.value(), train_dictionary(samples, 4096).value());  // deterministic
  desc.dictionary = dict.value();
  for (int level : {-3, 3, 9}) {
    desc.zstd_level = level;
    const std::string p = path("d" + std::to_string(level + 10) + ".tvt");
    bake_or_die(p, desc, plan);
    auto reader = PageStoreReader::open(p);
    ASSERT_TRUE(reader.ok()) << reader.error().message;
    EXPECT_EQ(reader.value()->desc().dictionary, desc.dictionary);
    EXPECT_EQ(reader.value()->desc().zstd_level, level);
    auto decoder = reader.value()->make_decoder();
    std::vector<uint8_t> page(desc.page_bytes());
    for (const PageId& id : plan) {
      ASSERT_EQ(reader.value()->read_page(id, page, *decoder), PageError::none);
      ASSERT_EQ(page, synthetic_page(desc, id));
    }
  }
  EXPECT_FALSE(train_dictionary(std::span(samples).first(3), 4096).ok());
  EXPECT_FALSE(train_dictionary(samples, 10).ok());
}

TEST_F(PageStoreTest, ManyThreadsReadConcurrently) {
  const StoreDesc desc = small_desc();
  BakeRegion region;
  region.mip_lo = 1;
  const auto plan = bake_plan(desc.vt, region).value();
  bake_or_die(path("c.tvt"), desc, plan);
  auto reader = PageStoreReader::open(path("c.tvt"));
  ASSERT_TRUE(reader.ok());
  std::vector<int> bad(4, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      auto decoder = reader.value()->make_decoder();
      std::vector<uint8_t> page(desc.page_bytes());
      for (size_t k = 0; k < plan.size(); ++k) {
        const PageId& id = plan[(k * 7 + size_t(t) * 13) % plan.size()];
        if (reader.value()->read_page(id, page, *decoder) != PageError::none || page != synthetic_page(desc, id)) ++bad[t];
      }
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(bad, std::vector<int>(4, 0));
}

TEST_F(PageStoreTest, EveryTruncatedPrefixIsRejectedCleanly) {
  const StoreDesc desc = small_desc();
  const auto plan = tiny_plan(desc);
  bake_or_die(path("full.tvt"), desc, plan, SyntheticPages{1, 0});
  const auto bytes = read_bytes(path("full.tvt"));
  ASSERT_LT(bytes.size(), 8000u);
  MemFile cut;
  for (size_t n = 0; n < bytes.size(); ++n) {
    cut.set(std::span(bytes).first(n));
    auto r = PageStoreReader::open(cut.path());
    ASSERT_FALSE(r.ok()) << "prefix of " << n << " bytes was accepted";
    EXPECT_EQ(r.error().message.rfind(cut.path() + ": ", 0), 0u) << r.error().message;
  }
}

// Every byte of a store is covered by a check: a flip is rejected at open, or the pages it
// touches read as corrupt; a page that reads ok is always the right page.
TEST_F(PageStoreTest, EveryFlippedByteIsDetectedAndNoWrongPageIsOk) {
  StoreDesc desc = small_desc();
  desc.dictionary.assign(300, 0);
  for (size_t i = 0; i < desc.dictionary.size(); ++i) desc.dictionary[i] = uint8_t(i * 37 + 11);  // raw-content dictionary
  const auto plan = tiny_plan(desc);
  const SyntheticPages sp{1, 0};
  bake_or_die(path("full.tvt"), desc, plan, sp);
  const auto bytes = read_bytes(path("full.tvt"));
  ASSERT_LT(bytes.size(), 8000u);
  std::vector<std::vector<uint8_t>> truth;
  for (const PageId& id : plan) truth.push_back(synthetic_page(desc, id, sp));
  std::vector<uint8_t> page(desc.page_bytes());
  size_t rejected_at_open = 0, page_errors = 0;
  MemFile file;
  for (size_t at = 0; at < bytes.size(); ++at) {
    auto flipped = bytes;
    flipped[at] ^= uint8_t(1u << (at % 8));
    file.set(flipped);
    auto r = PageStoreReader::open(file.path());
    bool detected = !r.ok();
    if (r.ok()) {
      auto decoder = r.value()->make_decoder();
      for (size_t i = 0; i < plan.size(); ++i) {
        const PageError e = r.value()->read_page(plan[i], page, *decoder);
        if (e == PageError::none)
          ASSERT_EQ(page, truth[i]) << "byte " << at << ": wrong page " << to_string(plan[i]) << " returned as ok";
        else
          detected = true;
      }
      page_errors += detected;
    } else {
      ++rejected_at_open;
    }
    ASSERT_TRUE(detected) << "flipping byte " << at << " went unnoticed";
    {  // verify_store agrees
      auto v = verify_store(file.path(), 1);
      ASSERT_TRUE(v.ok());
      EXPECT_FALSE(v->problems.empty()) << "verify missed byte " << at;
    }
  }
  EXPECT_GT(rejected_at_open, 0u);
  EXPECT_GT(page_errors, 0u);
}

TEST_F(PageStoreTest, BadInputErrorsNameTheFileAndTheField) {
  const StoreDesc desc = small_desc();
  const auto plan = tiny_plan(desc);
  auto open_error = [](const std::string& p) {
    auto r = PageStoreReader::open(p);
    return r.ok() ? std::string("(opened)") : r.error().message;
  };
  EXPECT_NE(open_error(path("none.tvt")).find(path("none.tvt") + ": cannot open"), std::string::npos);
  write_bytes(path("empty.tvt"), {});
  EXPECT_NE(open_error(path("empty.tvt")).find("shorter than the 256-byte header"), std::string::npos);

  bake_or_die(path("ok.tvt"), desc, plan);
  const auto good = read_bytes(path("ok.tvt"));
  auto patched = [&](size_t offset, uint32_t value, bool fix_hash) {
    auto b = good;
    sf::put_u32(b.data() + offset, value);
    if (fix_hash) sf::put_u64(b.data() + sf::off::header_hash, sf::hash(std::span(b).first(sf::off::header_hash)));
    write_bytes(path("bad.tvt"), b);
    return open_error(path("bad.tvt"));
  };
  const std::string bad = path("bad.tvt") + ": header ";
  EXPECT_EQ(patched(sf::off::magic, 0x41414141, false), bad + "magic: not a terravt page store (expected \"TVTSTORE\")");
  EXPECT_NE(patched(sf::off::version, 2, false).find(bad + "version: unsupported version 2"), std::string::npos);
  EXPECT_NE(patched(sf::off::log2_size, 11, false).find(bad + "header_hash"), std::string::npos);
  EXPECT_NE(patched(sf::off::page_texels, 100, true).find(bad + "vt/page_texels"), std::string::npos);
  EXPECT_NE(patched(sf::off::page_texels, 32, true).find(bad + "page_bytes"), std::string::npos);
  EXPECT_NE(patched(sf::off::layer_count, 7, true).find(bad + "layer_count"), std::string::npos);
  EXPECT_NE(patched(sf::off::zstd_level, 0, true).find(bad + "zstd_level"), std::string::npos);
  EXPECT_NE(patched(sf::off::shard_index, 3, true).find(bad + "shard_index"), std::string::npos);
  EXPECT_NE(patched(sf::off::index_bytes, 40, true).find(bad + "index_bytes"), std::string::npos);
  EXPECT_NE(patched(sf::off::index_offset, 300, true).find(bad + "index_offset"), std::string::npos);
  EXPECT_NE(patched(sf::off::index_hash, 1, true).find(path("bad.tvt") + ": index: checksum mismatch"), std::string::npos);
  EXPECT_NE(patched(sf::off::producer + 60, 0x41414141, true).find(bad + "producer"), std::string::npos);

  // An index entry with a consistent index hash but a page outside the VT is named by entry.
  auto b = good;
  std::vector<std::string> ignored;
  const sf::Header h = *sf::decode_header(b, b.size(), "x", ignored);
  sf::put_u64(b.data() + h.index_offset + sf::idx::page, PageId{0, 99, 0}.pack());
  sf::put_u64(b.data() + sf::off::index_hash, sf::hash(std::span(b).subspan(size_t(h.index_offset))));
  sf::put_u64(b.data() + sf::off::header_hash, sf::hash(std::span(b).first(sf::off::header_hash)));
  write_bytes(path("bad.tvt"), b);
  EXPECT_NE(open_error(path("bad.tvt")).find(path("bad.tvt") + ": index entry 0 (mip 0 page (99,0)): page is outside"),
            std::string::npos)
      << open_error(path("bad.tvt"));

  // Bake-side validation: desc fields, plan entries, options.
  auto bake_error = [&](const StoreDesc& d, std::vector<PageId> p, BakeOptions o = {}) {
    auto r = bake_store(path("out.tvt"), d, p, synthetic_source(d), o);
    EXPECT_FALSE(fs::exists(path("out.tvt")));
    return r.ok() ? std::string("(baked)") : r.error().message;
  };
  StoreDesc d = desc;
  d.producer.assign(64, 'x');
  EXPECT_NE(bake_error(d, plan).find(path("out.tvt") + ": desc producer"), std::string::npos);
  d = desc;
  d.zstd_level = 0;
  EXPECT_NE(bake_error(d, plan).find(path("out.tvt") + ": desc zstd_level"), std::string::npos);
  d = desc;
  d.layers.assign(5, PageLayerFormat::rgba8_albedo_height);
  EXPECT_NE(bake_error(d, plan).find("desc layers"), std::string::npos);
  EXPECT_NE(bake_error(desc, {}).find(path("out.tvt") + ": plan: is empty"), std::string::npos);
  EXPECT_NE(bake_error(desc, {PageId{4, 0, 0}, PageId{4, 1, 0}}).find("plan entry 1 (mip 4, 1, 0): outside"), std::string::npos);
  EXPECT_NE(bake_error(desc, {PageId{4, 0, 0}, PageId{4, 0, 0}}).find("plan entry 1 (mip 4, 0, 0): duplicate"), std::string::npos);
  BakeOptions o;
  o.shard_index = 2;
  o.shard_count = 2;
  EXPECT_NE(bake_error(desc, plan, o).find("options shard_index"), std::string::npos);
  o = BakeOptions{};
  o.batch_pages = 0;
  EXPECT_NE(bake_error(desc, plan, o).find("options batch_pages"), std::string::npos);
  auto into_folder = bake_store(dir_.string(), desc, plan, synthetic_source(desc), BakeOptions{});
  ASSERT_FALSE(into_folder.ok());
  EXPECT_NE(into_folder.error().message.find(dir_.string() + ": is a folder"), std::string::npos);
  auto no_dir = bake_store(path("no/such/dir/x.tvt"), desc, plan, synthetic_source(desc), BakeOptions{});
  ASSERT_FALSE(no_dir.ok());
  EXPECT_NE(no_dir.error().message.find(path("no/such/dir/x.tvt.partial") + ": cannot create"), std::string::npos);
}

TEST_F(PageStoreTest, VerifyListsEveryBadPageOnOneLine) {
  const StoreDesc desc = small_desc();
  BakeRegion region;
  region.mip_lo = 2;  // 21 pages
  const auto plan = bake_plan(desc.vt, region).value();
  bake_or_die(path("v.tvt"), desc, plan);
  auto clean = verify_store(path("v.tvt"), 2);
  ASSERT_TRUE(clean.ok());
  EXPECT_EQ(clean->pages, plan.size());
  EXPECT_EQ(clean->ok, plan.size());
  EXPECT_TRUE(clean->problems.empty());

  std::vector<StoreEntry> entries;
  {
    auto r = PageStoreReader::open(path("v.tvt"));
    entries.assign(r.value()->entries().begin(), r.value()->entries().end());
  }
  auto b = read_bytes(path("v.tvt"));
  for (size_t i : {3u, 4u, 17u}) b[entries[i].offset + entries[i].stored_bytes / 2] ^= 0x40;  // three blobs
  b[entries[9].offset - sf::k_record_header_bytes + sf::rec::page_hash] ^= 1;               // one record header
  write_bytes(path("v.tvt"), b);
  auto report = verify_store(path("v.tvt"), 2);
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->pages, plan.size());
  EXPECT_EQ(report->ok, plan.size() - 4);
  ASSERT_EQ(report->problems.size(), 4u);
  EXPECT_NE(report->problems[0].find(sf::page_where(path("v.tvt"), entries[3].page) + ": blob checksum mismatch"), std::string::npos)
      << report->problems[0];
  EXPECT_NE(report->problems[2].find(sf::page_where(path("v.tvt"), entries[9].page) + ": record header"), std::string::npos)
      << report->problems[2];
  EXPECT_FALSE(verify_store(path("missing.tvt")).ok());

  // A damaged header is one problem line, not an error.
  b[sf::off::scene_hash] ^= 1;
  write_bytes(path("v.tvt"), b);
  auto broken = verify_store(path("v.tvt"));
  ASSERT_TRUE(broken.ok());
  ASSERT_EQ(broken->problems.size(), 1u);
  EXPECT_NE(broken->problems[0].find("header_hash"), std::string::npos);
}
