// Baking: resume after a kill (a real SIGKILL of a forked child) or a torn record, cancel,
// source errors, the lock against a second writer, and shards merged byte for byte.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include "support/temp_dir.h"
#include "streaming/bake.h"
#include "streaming/store_format.h"
#include "streaming/synthetic_pages.h"

using namespace tvt;
namespace fs = std::filesystem;
namespace sf = tvt::store_format;

namespace {

class BakeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tvt::test::fresh_test_dir("tvt_bake");
    desc_.vt = VtConfig{10, 64, 4};
    desc_.producer = "bake test";
    BakeRegion region;
    region.mip_lo = 1;
    plan_ = bake_plan(desc_.vt, region).value();  // 85 pages
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // The uninterrupted single bake every other result must equal.
  std::vector<uint8_t> reference() {
    const std::string p = path("reference.tvt");
    if (!fs::exists(p)) {
      auto r = bake_store(p, desc_, plan_, synthetic_source(desc_), BakeOptions{});
      EXPECT_TRUE(r.ok()) << r.error().message;
    }
    return read_bytes(p);
  }
  static std::vector<uint8_t> read_bytes(const std::string& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
  }
  static void write_bytes(const std::string& p, std::span<const uint8_t> bytes) {
    std::ofstream f(p, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  }

  fs::path dir_;
  StoreDesc desc_;
  std::vector<PageId> plan_;
};

// Cancels after `batches` batches.
BakeOptions cancel_after(uint32_t batches, uint32_t batch_pages) {
  BakeOptions o;
  o.batch_pages = batch_pages;
  o.threads = 2;
  auto seen = std::make_shared<uint32_t>(0);
  o.progress = [seen](const BakeProgress&) { ++*seen; };
  o.cancelled = [seen, batches] { return *seen >= batches; };
  return o;
}

}  // namespace

TEST_F(BakeTest, KilledMidwayThenResumedIsByteIdenticalAndOldStoreUntouched) {
  const auto expected = reference();
  const std::string p = path("store.tvt");
  const std::vector<uint8_t> old_store{'o', 'l', 'd', ' ', 's', 't', 'o', 'r', 'e'};
  write_bytes(p, old_store);

  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {  // the child bakes slowly until it is killed
    const PageSource fast = synthetic_source(desc_);
    const PageSource slow = [&fast](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) {
      std::this_thread::sleep_for(std::chrono::milliseconds(15) * pages.size());
      return fast(pages, out);
    };
    BakeOptions o;
    o.batch_pages = 4;
    o.threads = 2;
    auto r = bake_store(p, desc_, plan_, slow, o);
    ::_exit(r.ok() ? 0 : 1);
  }
  // Kill it once a few records are on disk, in the middle of whatever it is doing.
  const std::string partial = p + ".partial";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  std::error_code ec;
  while (std::chrono::steady_clock::now() < deadline) {
    const auto size = fs::file_size(partial, ec);
    if (!ec && size > 256 + 6 * 8000) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the child finished before it was killed";
  EXPECT_EQ(read_bytes(p), old_store) << "the old store changed before the final rename";
  ASSERT_TRUE(fs::exists(partial));

  uint64_t last_done = 0;
  BakeOptions o;
  o.progress = [&](const BakeProgress& pr) {
    EXPECT_GE(pr.done, last_done);
    EXPECT_GT(pr.resumed, 0u);
    EXPECT_TRUE(std::isfinite(pr.eta_seconds) && pr.eta_seconds >= 0);
    last_done = pr.done;
  };
  auto r = bake_store(p, desc_, plan_, synthetic_source(desc_), o);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_GT(r->resumed_pages, 0u);
  EXPECT_LT(r->resumed_pages, plan_.size());
  EXPECT_EQ(r->pages, plan_.size());
  EXPECT_EQ(last_done, plan_.size());
  EXPECT_EQ(read_bytes(p), expected);
  EXPECT_FALSE(fs::exists(partial));
}

TEST_F(BakeTest, TornPartialResumesFromItsCompletePrefix) {
  const auto expected = reference();
  const std::string p = path("torn.tvt");
  // Cancelled after the 5th batch: the 6th was already produced (the source runs one batch
  // ahead of the writer), so it is written too: 48 pages, nothing produced is thrown away.
  auto cancelled = bake_store(p, desc_, plan_, synthetic_source(desc_), cancel_after(5, 8));
  ASSERT_FALSE(cancelled.ok());
  EXPECT_NE(cancelled.error().message.find(p + ": bake cancelled; 48 of 85 pages are kept in " + p + ".partial"),
            std::string::npos)
      << cancelled.error().message;
  const auto partial = read_bytes(p + ".partial");
  ASSERT_GT(partial.size(), 256u);
  // Cut the partial at random points (inside headers, records, record headers) and resume.
  std::mt19937 rng(7);
  for (int round = 0; round < 12; ++round) {
    const size_t cut = round == 0 ? partial.size() : std::uniform_int_distribution<size_t>(0, partial.size())(rng);
    write_bytes(p + ".partial", std::span(partial).first(cut));
    BakeOptions o;
    o.threads = 1 + uint32_t(round % 3);
    auto r = bake_store(p, desc_, plan_, synthetic_source(desc_), o);
    ASSERT_TRUE(r.ok()) << r.error().message;
    if (round == 0) {
      EXPECT_EQ(r->resumed_pages, 48u);
    }
    EXPECT_LE(r->resumed_pages, 48u);
    ASSERT_EQ(read_bytes(p), expected) << "cut at " << cut;
  }
}

// A partial may hold hours of another bake's work: a bake with other settings, another plan or
// another shard refuses to touch it and says how the two differ; resume = false discards it.
TEST_F(BakeTest, PartialOfAnotherBakeIsRefusedAndKeptUnlessResumeIsOff) {
  const auto expected = reference();
  const std::string p = path("other.tvt");
  StoreDesc other = desc_;
  other.zstd_level = 5;
  ASSERT_FALSE(bake_store(p, other, plan_, synthetic_source(other), cancel_after(2, 8)).ok());
  const auto partial = read_bytes(p + ".partial");
  ASSERT_GT(partial.size(), sf::k_header_bytes);
  auto r = bake_store(p, desc_, plan_, synthetic_source(desc_), BakeOptions{});
  ASSERT_FALSE(r.ok());
  const std::string& m = r.error().message;
  EXPECT_EQ(m.rfind(p + ".partial: holds " + std::to_string(partial.size()) + " bytes of another bake", 0), 0u) << m;
  EXPECT_NE(m.find("it differs in zstd level"), std::string::npos) << m;
  EXPECT_NE(m.find("--restart"), std::string::npos) << m;
  EXPECT_EQ(read_bytes(p + ".partial"), partial);
  EXPECT_FALSE(fs::exists(p));

  // The same settings over a smaller plan (other mips): the plan is named, with both sizes.
  BakeRegion fewer;
  fewer.mip_lo = 2;
  const auto small_plan = bake_plan(desc_.vt, fewer).value();  // 21 pages
  auto planned = bake_store(p, other, small_plan, synthetic_source(other), BakeOptions{});
  ASSERT_FALSE(planned.ok());
  EXPECT_NE(planned.error().message.find("it differs in plan (the partial: V = 2^10, 64+4-texel pages, plan of 85 pages"),
            std::string::npos)
      << planned.error().message;
  EXPECT_NE(planned.error().message.find("this bake: V = 2^10, 64+4-texel pages, plan of 21 pages"), std::string::npos)
      << planned.error().message;
  EXPECT_EQ(read_bytes(p + ".partial"), partial);

  // The same bake resumes it.
  auto same = bake_store(p, other, plan_, synthetic_source(other), BakeOptions{});
  ASSERT_TRUE(same.ok()) << same.error().message;
  EXPECT_GT(same->resumed_pages, 0u);  // every page the cancelled run wrote
  EXPECT_LT(same->resumed_pages, plan_.size());

  // Another shard's partial is refused too; resume = false starts over.
  BakeOptions shard = cancel_after(1, 8);
  shard.shard_count = 2;
  ASSERT_FALSE(bake_store(path("s.tvt"), desc_, plan_, synthetic_source(desc_), shard).ok());
  auto again = bake_store(path("s.tvt"), desc_, plan_, synthetic_source(desc_), BakeOptions{});
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message.find("it differs in shard"), std::string::npos) << again.error().message;
  BakeOptions fresh;
  fresh.resume = false;
  auto restarted = bake_store(path("s.tvt"), desc_, plan_, synthetic_source(desc_), fresh);
  ASSERT_TRUE(restarted.ok()) << restarted.error().message;
  EXPECT_EQ(restarted->resumed_pages, 0u);
  EXPECT_EQ(read_bytes(path("s.tvt")), expected);
}

TEST_F(BakeTest, SourceErrorsKeepThePartialAndNeverWriteTheStore) {
  const auto expected = reference();
  const std::string p = path("err.tvt");
  int calls = 0;
  const PageSource good = synthetic_source(desc_);
  const PageSource failing = [&](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) -> Status {
    if (++calls == 4) return make_error("composer: device lost");
    return good(pages, out);
  };
  BakeOptions o;
  o.batch_pages = 10;
  auto r = bake_store(p, desc_, plan_, failing, o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find(p + ": page source failed at plan page 30 (mip 1, 1, 1): composer: device lost"),
            std::string::npos)
      << r.error().message;
  EXPECT_FALSE(fs::exists(p));
  ASSERT_TRUE(fs::exists(p + ".partial"));

  const PageSource short_page = [&](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) -> Status {
    for (size_t i = 0; i < pages.size(); ++i) out.emplace_back(100);
    return Ok{};
  };
  auto wrong = bake_store(p, desc_, plan_, short_page, o);  // resumes 30 pages, then fails
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.error().message.find("returned 100 bytes for page (mip 1, 1, 1), expected 20736"), std::string::npos)
      << wrong.error().message;
  const PageSource too_few = [&](std::span<const PageId>, std::vector<std::vector<uint8_t>>&) -> Status { return Ok{}; };
  auto few = bake_store(p, desc_, plan_, too_few, o);
  ASSERT_FALSE(few.ok());
  EXPECT_NE(few.error().message.find("returned 0 pages for a batch of 10"), std::string::npos);
  EXPECT_FALSE(fs::exists(p));

  auto resumed = bake_store(p, desc_, plan_, good, o);
  ASSERT_TRUE(resumed.ok());
  EXPECT_EQ(resumed->resumed_pages, 30u);
  EXPECT_EQ(read_bytes(p), expected);
}

TEST_F(BakeTest, SecondWriterOnTheSamePathIsRefused) {
  const std::string p = path("locked.tvt");
  std::string inner_error;
  bool asked = false;
  const PageSource good = synthetic_source(desc_);
  const PageSource nested = [&](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) -> Status {
    if (!asked) {  // while this bake holds the partial, another bake of the same path must fail
      asked = true;
      auto r = bake_store(p, desc_, plan_, good, BakeOptions{});
      inner_error = r.ok() ? "(baked)" : r.error().message;
    }
    return good(pages, out);
  };
  auto r = bake_store(p, desc_, plan_, nested, BakeOptions{});
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(inner_error, p + ".partial: another terravt process holds it (locked)");
  EXPECT_EQ(read_bytes(p), reference());
}

TEST_F(BakeTest, ThreeShardsMergeToTheSingleBakeInAnyOrder) {
  const auto expected = reference();
  std::vector<std::string> shards;
  uint64_t pages = 0;
  for (uint32_t i = 0; i < 3; ++i) {
    BakeOptions o;
    o.shard_index = i;
    o.shard_count = 3;
    o.threads = 1 + i;
    shards.push_back(path("shard" + std::to_string(i) + ".tvt"));
    auto r = bake_store(shards.back(), desc_, plan_, synthetic_source(desc_), o);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->pages, shard_range(plan_.size(), i, 3).count);
    pages += r->pages;
    auto reader = PageStoreReader::open(shards.back());  // a shard is a readable store of its own
    ASSERT_TRUE(reader.ok()) << reader.error().message;
    EXPECT_EQ(reader.value()->layout().shard_index, i);
    EXPECT_EQ(reader.value()->entries().front().page, plan_[shard_range(plan_.size(), i, 3).first]);
  }
  EXPECT_EQ(pages, plan_.size());

  const std::vector<std::string> shuffled{shards[2], shards[0], shards[1]};
  auto merged = merge_stores(shuffled, path("merged.tvt"));
  ASSERT_TRUE(merged.ok()) << merged.error().message;
  EXPECT_EQ(merged->pages, plan_.size());
  EXPECT_EQ(read_bytes(path("merged.tvt")), expected);

  const std::vector<std::string> missing{shards[2], shards[0]};
  auto m = merge_stores(missing, path("bad.tvt"));
  ASSERT_FALSE(m.ok());
  EXPECT_NE(m.error().message.find("shard 1 of 3 (plan pages [29, +28)) is missing"), std::string::npos) << m.error().message;
  const std::vector<std::string> twice{shards[0], shards[1], shards[1], shards[2]};
  auto d = merge_stores(twice, path("bad.tvt"));
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find(shards[1] + ": header shard_index: shard 1 of 3 is given twice (also " + shards[1] + ")"),
            std::string::npos)
      << d.error().message;
  EXPECT_FALSE(merge_stores(std::vector<std::string>{}, path("bad.tvt")).ok());

  // A shard of another bake (other producer) is refused by field.
  StoreDesc other = desc_;
  other.producer = "another producer";
  BakeOptions o;
  o.shard_index = 1;
  o.shard_count = 3;
  ASSERT_TRUE(bake_store(path("foreign.tvt"), other, plan_, synthetic_source(other), o).ok());
  const std::vector<std::string> foreign{shards[0], path("foreign.tvt"), shards[2]};
  auto f = merge_stores(foreign, path("bad.tvt"));
  ASSERT_FALSE(f.ok());
  EXPECT_NE(f.error().message.find(path("foreign.tvt") + ": header producer: differs from " + shards[0]), std::string::npos)
      << f.error().message;
  // A corrupt shard stops the merge; nothing is written.
  auto bytes = read_bytes(shards[1]);
  bytes[bytes.size() / 2] ^= 0x10;
  write_bytes(shards[1], bytes);
  auto c = merge_stores(shards, path("bad.tvt"));
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find(shards[1] + ": mip"), std::string::npos) << c.error().message;
  EXPECT_FALSE(fs::exists(path("bad.tvt")));
  EXPECT_FALSE(fs::exists(path("bad.tvt.partial")));
}

TEST_F(BakeTest, MorePartsThanPagesGivesEmptyShardsThatStillMerge) {
  const std::vector<PageId> plan(plan_.begin(), plan_.begin() + 2);
  const std::string single = path("single.tvt");
  ASSERT_TRUE(bake_store(single, desc_, plan, synthetic_source(desc_), BakeOptions{}).ok());
  std::vector<std::string> parts;
  for (uint32_t i = 0; i < 4; ++i) {
    BakeOptions o;
    o.shard_index = i;
    o.shard_count = 4;
    parts.push_back(path("p" + std::to_string(i) + ".tvt"));
    auto r = bake_store(parts.back(), desc_, plan, synthetic_source(desc_), o);
    ASSERT_TRUE(r.ok()) << r.error().message;
    auto reader = PageStoreReader::open(parts.back());
    ASSERT_TRUE(reader.ok()) << reader.error().message;
  }
  ASSERT_TRUE(merge_stores(parts, path("m.tvt")).ok());
  EXPECT_EQ(read_bytes(path("m.tvt")), read_bytes(single));
}
