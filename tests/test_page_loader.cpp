// PageLoader: bounded staging ring, every request reported exactly once under concurrent
// request/cancel/poll from several threads, bad pages failed (never ok) and reported once.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <thread>

#include "support/temp_dir.h"
#include "streaming/bake.h"
#include "streaming/page_loader.h"
#include "streaming/synthetic_pages.h"

using namespace tvt;
namespace fs = std::filesystem;

namespace {

class PageLoaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tvt::test::fresh_test_dir("tvt_page_loader");
    desc_.vt = VtConfig{10, 64, 4};
    BakeRegion region;
    region.mip_lo = 1;
    plan_ = bake_plan(desc_.vt, region).value();  // 85 pages
    store_path_ = (dir_ / "s.tvt").string();
    auto r = bake_store(store_path_, desc_, plan_, synthetic_source(desc_), BakeOptions{});
    ASSERT_TRUE(r.ok()) << r.error().message;
    for (const PageId& id : plan_) truth_[id.pack()] = synthetic_page(desc_, id);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::shared_ptr<const PageStoreReader> open_store() {
    auto r = PageStoreReader::open(store_path_);
    EXPECT_TRUE(r.ok()) << r.error().message;
    return r.ok() ? std::shared_ptr<const PageStoreReader>(std::move(r.value())) : nullptr;
  }

  fs::path dir_;
  StoreDesc desc_;
  std::vector<PageId> plan_;
  std::string store_path_;
  std::map<uint64_t, std::vector<uint8_t>> truth_;
};

// Polls until `n` results arrived or 10 s passed.
std::vector<LoadedPage> poll_n(PageLoader& loader, size_t n) {
  std::vector<LoadedPage> out;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (out.size() < n && std::chrono::steady_clock::now() < deadline) {
    loader.poll(out);
    if (out.size() < n) std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  return out;
}

}  // namespace

TEST_F(PageLoaderTest, DecodesIntoCallerStagingMemory) {
  auto store = open_store();
  ASSERT_TRUE(store);
  PageLoaderOptions o;
  o.threads = 2;
  o.staging_slots = 8;
  std::vector<uint8_t> memory(8 * desc_.page_bytes() + 5, 0xee);  // a mapped Vulkan buffer, say
  PageLoader loader(store, o, memory);
  for (size_t begin = 0; begin < plan_.size(); begin += 8) {
    const size_t end = std::min(plan_.size(), begin + 8);
    for (size_t i = begin; i < end; ++i) ASSERT_TRUE(loader.request(plan_[i], 1000 + i));
    const auto done = poll_n(loader, end - begin);
    ASSERT_EQ(done.size(), end - begin);
    for (const LoadedPage& p : done) {
      ASSERT_EQ(p.status, LoadStatus::ok);
      EXPECT_EQ(p.page, plan_[p.tag - 1000]);
      EXPECT_GE(p.read_ms, 0.0);
      EXPECT_GE(p.decode_ms, 0.0);
      const uint64_t at = loader.staging_offset(p.staging);
      EXPECT_EQ(at, p.staging * desc_.page_bytes());
      const std::span<const uint8_t> staged = loader.staged(p.staging);
      ASSERT_EQ(staged.data(), memory.data() + at);  // decoded straight into the caller's memory
      ASSERT_TRUE(std::equal(staged.begin(), staged.end(), truth_[p.page.pack()].begin(), truth_[p.page.pack()].end()));
      loader.release(p.staging);
      EXPECT_TRUE(loader.staged(p.staging).empty());  // released slots expose nothing
    }
  }
  EXPECT_EQ(memory.back(), 0xee);  // nothing written past staging_slots * page_bytes
  const PageLoaderStats s = loader.stats();
  EXPECT_EQ(s.requested, plan_.size());
  EXPECT_EQ(s.loaded, plan_.size());
  EXPECT_EQ(s.bytes_decoded, plan_.size() * desc_.page_bytes());
  EXPECT_GT(s.bytes_read, 0u);
  EXPECT_LT(s.bytes_read, s.bytes_decoded);
  EXPECT_EQ(s.outstanding, 0u);
  EXPECT_EQ(s.staging_in_use, 0u);
}

TEST_F(PageLoaderTest, RingBoundsOutstandingPlusStagedPages) {
  auto store = open_store();
  ASSERT_TRUE(store);
  PageLoader loader(store, PageLoaderOptions{1, 4});
  for (uint64_t i = 0; i < 4; ++i) EXPECT_TRUE(loader.request(plan_[i], i));
  EXPECT_FALSE(loader.request(plan_[4], 4));
  EXPECT_EQ(loader.stats().requested, 4u);
  loader.wait_idle();
  EXPECT_FALSE(loader.request(plan_[4], 4)) << "finished but unpolled pages still hold their slots";
  auto done = poll_n(loader, 4);
  ASSERT_EQ(done.size(), 4u);
  EXPECT_FALSE(loader.request(plan_[4], 4)) << "staged pages hold their slots until release";
  loader.release(done[0].staging);
  loader.release(done[0].staging);  // a second release is ignored
  EXPECT_EQ(loader.stats().staging_in_use, 3u);
  EXPECT_TRUE(loader.request(plan_[4], 4));
  EXPECT_FALSE(loader.request(plan_[5], 5));
  const PageLoaderStats s = loader.stats();
  EXPECT_EQ(s.staging_in_use, 3u);  // polled, not released
  EXPECT_EQ(s.outstanding, 1u);     // plan_[4], not yet polled
  EXPECT_EQ(s.outstanding + s.staging_in_use, 4u);
}

TEST_F(PageLoaderTest, ManyThreadsWithRandomCancelReportEveryRequestExactlyOnce) {
  auto store = open_store();
  ASSERT_TRUE(store);
  PageLoader loader(store, PageLoaderOptions{3, 16});
  constexpr uint64_t k_requests_per_thread = 600;
  std::atomic<uint64_t> accepted{0};
  std::atomic<bool> requesters_done{false};
  std::mutex mutex;
  std::map<uint64_t, PageId> requested;  // tag -> page
  std::map<uint64_t, int> reports;       // tag -> times reported
  std::atomic<int> mismatches{0}, bad_status{0};

  auto requester = [&](uint64_t thread) {
    std::mt19937 rng(uint32_t(thread + 1));
    for (uint64_t k = 0; k < k_requests_per_thread;) {
      const PageId page = plan_[rng() % plan_.size()];
      const uint64_t tag = thread << 32 | k;
      {
        std::lock_guard lock(mutex);  // recorded before the request, so a fast result finds it
        requested[tag] = page;
      }
      if (loader.request(page, tag)) {
        ++accepted;
        ++k;
      } else {
        std::lock_guard lock(mutex);
        requested.erase(tag);
        std::this_thread::yield();
      }
      if (rng() % 4 == 0) loader.cancel(plan_[rng() % plan_.size()]);
    }
  };
  auto poller = [&] {
    std::vector<LoadedPage> out;
    for (;;) {
      const bool last = requesters_done.load();
      out.clear();
      loader.poll(out);
      for (const LoadedPage& p : out) {
        std::lock_guard lock(mutex);
        ++reports[p.tag];
        if (requested.count(p.tag) == 0 || requested[p.tag] != p.page) ++mismatches;
        if (p.status == LoadStatus::ok) {
          const auto staged = loader.staged(p.staging);
          const auto& truth = truth_[p.page.pack()];
          if (!std::equal(staged.begin(), staged.end(), truth.begin(), truth.end())) ++mismatches;
          loader.release(p.staging);
        } else if (p.status == LoadStatus::failed || p.staging != UINT32_MAX) {
          ++bad_status;
        }
      }
      if (last && loader.stats().outstanding == 0) return;
      std::this_thread::yield();
    }
  };
  std::thread poll_thread(poller);
  std::vector<std::thread> requesters;
  for (uint64_t t = 0; t < 3; ++t) requesters.emplace_back(requester, t);
  for (auto& t : requesters) t.join();
  requesters_done = true;
  poll_thread.join();

  EXPECT_EQ(accepted.load(), 3 * k_requests_per_thread);
  EXPECT_EQ(mismatches.load(), 0);
  EXPECT_EQ(bad_status.load(), 0);
  EXPECT_EQ(reports.size(), requested.size()) << "lost requests";
  for (const auto& [tag, n] : reports) ASSERT_EQ(n, 1) << "tag " << tag << " reported " << n << " times";
  const PageLoaderStats s = loader.stats();
  EXPECT_EQ(s.requested, 3 * k_requests_per_thread);
  EXPECT_EQ(s.loaded + s.cancelled, s.requested);
  EXPECT_GT(s.cancelled, 0u);
  EXPECT_GT(s.loaded, 0u);
  EXPECT_EQ(s.staging_in_use, 0u);
  EXPECT_TRUE(loader.take_error_messages().empty());
}

TEST_F(PageLoaderTest, CorruptAndMissingPagesFailAndAreReportedOnce) {
  auto store = open_store();
  ASSERT_TRUE(store);
  // Damage two pages after the store was opened (the reader checks every read, not only open).
  const StoreEntry a = *store->find(plan_[10]), b = *store->find(plan_[20]);
  {
    std::fstream f(store_path_, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(a.offset + 3));
    f.put('\x55');
    f.seekp(std::streamoff(b.offset - 20));  // inside b's record header
    f.put('\x55');
  }
  PageLoader loader(store, PageLoaderOptions{2, 8});
  const PageId absent{0, 3, 3};  // mip 0 is not in this store
  for (int round = 0; round < 3; ++round) {
    ASSERT_TRUE(loader.request(plan_[10], 1));
    ASSERT_TRUE(loader.request(plan_[20], 2));
    ASSERT_TRUE(loader.request(plan_[30], 3));
    ASSERT_TRUE(loader.request(absent, 4));
    auto done = poll_n(loader, 4);
    ASSERT_EQ(done.size(), 4u);
    for (const LoadedPage& p : done) {
      if (p.tag == 3) {
        EXPECT_EQ(p.status, LoadStatus::ok);
        loader.release(p.staging);
        continue;
      }
      EXPECT_EQ(p.status, LoadStatus::failed) << p.tag;
      EXPECT_EQ(p.staging, UINT32_MAX);
      EXPECT_EQ(p.error, p.tag == 4 ? PageError::missing : PageError::corrupt);
    }
    const auto messages = loader.take_error_messages();
    if (round == 0) {
      ASSERT_EQ(messages.size(), 3u);
      std::set<std::string> got(messages.begin(), messages.end());
      EXPECT_EQ(got.count(store_path_ + ": mip 0 page (3,3): not in the store"), 1u);
      const std::string pa = store_path_ + ": mip " + std::to_string(plan_[10].mip) + " page (" +
                             std::to_string(plan_[10].x) + "," + std::to_string(plan_[10].y) + "): blob checksum mismatch";
      EXPECT_TRUE(std::any_of(messages.begin(), messages.end(), [&](const std::string& m) { return m.find(pa) == 0; }))
          << messages[0] << " | " << messages[1] << " | " << messages[2];
    } else {
      EXPECT_TRUE(messages.empty()) << "a bad page was reported twice: " << messages[0];
    }
  }
  const PageLoaderStats s = loader.stats();
  EXPECT_EQ(s.failed, 9u);
  EXPECT_EQ(s.loaded, 3u);
  EXPECT_EQ(s.staging_in_use, 0u);
}

TEST_F(PageLoaderTest, AFailedLoadCancelledBeforeItIsPolledIsReportedCancelled) {
  auto store = open_store();
  ASSERT_TRUE(store);
  PageLoader loader(store, PageLoaderOptions{2, 8});
  const PageId absent{0, 3, 3};  // mip 0 is not in this store: the load fails
  ASSERT_TRUE(loader.request(absent, 7));
  ASSERT_TRUE(loader.request(plan_[3], 8));
  loader.wait_idle();       // both finished, neither polled
  loader.cancel(absent);    // the caller no longer wants it: "failed" would come for a page it gave up
  std::vector<LoadedPage> done;
  loader.poll(done);
  ASSERT_EQ(done.size(), 2u);
  for (const LoadedPage& p : done) {
    if (p.tag == 8) {
      EXPECT_EQ(p.status, LoadStatus::ok);
      loader.release(p.staging);
      continue;
    }
    EXPECT_EQ(p.status, LoadStatus::cancelled);
    EXPECT_EQ(p.error, PageError::none);
    EXPECT_EQ(p.staging, UINT32_MAX);
  }
  EXPECT_EQ(loader.stats().failed, 0u);
  EXPECT_EQ(loader.stats().cancelled, 1u);
}

TEST_F(PageLoaderTest, DestructionWithQueuedWorkDoesNotHang) {
  auto store = open_store();
  ASSERT_TRUE(store);
  for (int round = 0; round < 20; ++round) {
    PageLoader loader(store, PageLoaderOptions{2, 64});
    for (uint64_t i = 0; i < 64; ++i) ASSERT_TRUE(loader.request(plan_[i], i));
    if (round % 2) loader.cancel(plan_[5]);
  }
}
