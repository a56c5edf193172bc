// Asynchronous page loader (docs/architecture.md). Workers pread and decompress pages of a PageStoreReader straight into a
// bounded ring of staging slots; the caller polls finished pages, copies them out (e.g. into
// the GPU cache) and releases the slot.
//
// Threading: every public member may be called from any thread. request, cancel, poll,
// release and stats only take a mutex for a few bookkeeping steps and never wait for I/O;
// workers do all reads and decompression outside it.
//
// Every request is reported by poll() exactly once: ok (data in a staging slot until
// release()), failed (a PageError; the slot, if any, was recycled and its bytes are never
// exposed) or cancelled. Each bad page's message is queued once for take_error_messages().
#pragma once
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <unordered_set>
#include <vector>

#include "streaming/page_store.h"

namespace tvt {

struct PageLoaderOptions {
  uint32_t threads = 2;         // I/O + decode workers (1..64)
  uint32_t staging_slots = 32;  // bounded ring; also the cap on outstanding requests (>= 1)
};
enum class LoadStatus : uint8_t { ok, failed, cancelled };
struct LoadedPage {
  PageId page;
  uint64_t tag = 0;  // the caller's (e.g. the cache slot)
  LoadStatus status = LoadStatus::ok;
  PageError error = PageError::none;
  uint32_t staging = UINT32_MAX;  // ok: staging slot holding the page until release()
  double read_ms = 0, decode_ms = 0;
};
struct PageLoaderStats {
  uint64_t requested = 0, loaded = 0, failed = 0, cancelled = 0;  // loaded/failed/cancelled: as reported by poll()
  uint64_t bytes_read = 0, bytes_decoded = 0;                       // compressed bytes read, page bytes decoded
  uint32_t outstanding = 0;     // accepted requests not yet reported by poll() (queued, loading, finished)
  uint32_t staging_in_use = 0;  // ok pages polled but not yet released
  // Disjoint, so request() succeeds when outstanding + staging_in_use < staging_slots (it may
  // also succeed at equality while unpolled failed/cancelled results, which hold no slot, count).
};

class PageLoader {
 public:
  // `staging`: caller-provided memory of staging_slots * page_bytes (e.g. a mapped host-visible
  // Vulkan buffer), or empty to allocate it. Workers decompress straight into it. Too small
  // caller memory is a programming error (fatal check).
  PageLoader(std::shared_ptr<const PageStoreReader> store, PageLoaderOptions options, std::span<uint8_t> staging = {});
  ~PageLoader();  // cancels everything, joins
  PageLoader(const PageLoader&) = delete;
  PageLoader& operator=(const PageLoader&) = delete;

  // Queues a page; false (nothing queued) when outstanding requests + staged pages reach
  // staging_slots. Never blocks on I/O. A page the store does not hold is accepted and
  // reported as failed (PageError::missing) by the next poll().
  bool request(const PageId& page, uint64_t tag);
  // Every unpolled request of `page`: queued ones are dropped, in-progress results discarded,
  // finished-but-unpolled ones dropped (their slot freed). Reported as cancelled by poll().
  void cancel(const PageId& page);
  void poll(std::vector<LoadedPage>& out);  // appends every finished request, never blocks
  std::span<const uint8_t> staged(uint32_t staging) const;
  uint64_t staging_offset(uint32_t staging) const;  // byte offset in the staging memory
  void release(uint32_t staging);                   // the caller copied it out; ignored unless staged
  PageLoaderStats stats() const;
  // Each bad page is reported once: messages not yet taken ("store.tvt: mip 3 page (5,2): ...").
  std::vector<std::string> take_error_messages();
  void wait_idle();  // tests/benchmarks only: blocks until every request is finished (not necessarily polled)

  uint32_t staging_slots() const { return slots_count_; }
  uint64_t page_bytes() const { return page_bytes_; }

 private:
  enum class SlotState : uint8_t { free, queued, loading, ready, staged };
  struct Slot {
    SlotState state = SlotState::free;
    bool cancel = false;  // loading: discard the result
    PageId page;
    uint64_t tag = 0;
  };
  void worker();
  void free_slot(uint32_t slot);  // mutex held

  std::shared_ptr<const PageStoreReader> store_;
  uint64_t page_bytes_ = 0;
  uint32_t slots_count_ = 0;
  std::vector<uint8_t> own_staging_;
  std::span<uint8_t> staging_;

  mutable std::mutex mutex_;
  std::condition_variable work_cv_, idle_cv_;
  std::vector<Slot> slots_;
  std::vector<uint32_t> free_slots_;  // stack
  std::deque<uint32_t> queue_;        // queued slots, FIFO
  std::vector<LoadedPage> finished_;  // not yet polled
  uint32_t loading_ = 0;
  std::unordered_set<uint64_t> reported_;  // packed ids whose error message was queued
  std::vector<std::string> messages_;
  PageLoaderStats stats_;
  bool stop_ = false;
  std::vector<std::thread> workers_;
};

}  // namespace tvt
