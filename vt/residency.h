// LRU residency policy for the VT page cache (docs/virtual-texture.md), plain CPU
// like Granite's AssetManager + LRUCache: it decides which pages live in which slots; the
// GPU side (composer, stored-page loader) only fills the slots it is told to fill.
//
// One frame, on one thread:
//   residency.set_centre(camera_x, camera_y);             // level-0 texels
//   residency.begin_frame(frame, feedback);                // compacted GPU feedback
//   std::vector<PageRequest> batch;                        // producer interface:
//   while (clock() < deadline)                             //   the caller enforces its
//     if (auto r = residency.next_request()) batch.push_back(*r); else break;  // ms budget
//   producer.produce(batch);                               // list of (page id, slot)
//   ... later, possibly in another frame: residency.complete(page) or residency.failed(page)
//   upload(residency.take_table_updates());                // GPU scatter of changed entries
//
// Policy:
// - The working set of a frame is every feedback page, all its ancestors, and the pinned
//   pages (all pages of the `pinned_mips` coarsest mips). Resident pages of the working set
//   are touched (last frame seen = this frame); missing ones are queued.
// - Queue order: coarse mips first, then pixel coverage (a page's own count plus its
//   descendants' in the feedback), then age (frames it has been waiting), then page id.
// - next_request() hands out the next queued page with a slot: a free slot, or the slot of
//   the least recently seen resident page, which is evicted (unmapped). Pages of the working
//   set of the current frame, pinned pages and pages in flight are never evicted. When no
//   slot can be had, or the per-frame page budget is used, it returns std::nullopt; it never
//   blocks and never loops, so a frame always finishes.
// - Mip bias: when the working set (minus the pinned pages) exceeds the unpinned slots by
//   `raise_bias_above`, the frame is oversubscribed and the bias rises by one (the renderer
//   adds it to its LOD, which quarters the fine pages it asks for); it falls by one after
//   `calm_frames` frames below `lower_bias_below`. At most one change per
//   `bias_settle_frames`, which covers the feedback latency; the gap between the two
//   thresholds (one step down quadruples the fine pages) is the hysteresis.
// - A page that failed is not queued again for `retry_after_frames` frames (pinned pages are
//   retried next frame); meanwhile its entries fall back to its nearest resident ancestor.
// Not thread-safe: one owner thread; producers report completion through that thread.
#pragma once
#include <cstdint>
#include <list>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "vt/page_table.h"
#include "vt/result.h"
#include "vt/slot_allocator.h"
#include "vt/vt_config.h"

namespace tvt {

// One entry of the compacted GPU feedback: a page sampled this frame and how many feedback
// pixels (at 1/N resolution) asked for it.
struct PageFeedback {
  PageId page;
  uint32_t pixels = 0;
};

// What a producer is asked to do: fill `slot` of the physical cache with `page`.
struct PageRequest {
  PageId page;
  uint32_t slot = 0;
  friend bool operator==(const PageRequest&, const PageRequest&) = default;
};

struct ResidencyOptions {
  uint32_t slot_count = 1024;            // physical cache slots; < 2^20
  uint32_t pinned_mips = 1;              // coarsest mips kept fully resident; >= 1
  uint32_t window_pages = 128;           // page-table window W (PageTableOptions)
  uint32_t max_requests_per_frame = 64;  // page budget of next_request() per frame; >= 1
  uint32_t retry_after_frames = 30;      // frames before a failed page is queued again
  double raise_bias_above = 1.0;         // working set / unpinned slots: oversubscribed above
  double lower_bias_below = 0.2;         // ... bias may fall below this ratio
  uint32_t bias_settle_frames = 3;       // frames between two bias changes; >= 1
  uint32_t calm_frames = 8;              // frames below lower_bias_below before lowering
  uint32_t max_mip_bias = 0;             // 0: up to mip_count - 1
};

// Counters of the current frame (reset by begin_frame) and the state after it.
struct ResidencyStats {
  uint64_t frame = 0;
  uint32_t working_set = 0;       // distinct pages needed this frame (feedback, ancestors, pinned)
  uint32_t requested = 0;         // of those, missing and queued
  uint32_t issued = 0;            // (page, slot) pairs handed out by next_request()
  uint32_t produced = 0;          // complete() calls since begin_frame
  uint32_t failed = 0;            // failed() calls since begin_frame
  uint32_t cancelled = 0;         // cancelled() calls since begin_frame
  uint32_t evicted = 0;           // pages unmapped to free their slot
  uint32_t invalid_feedback = 0;  // feedback entries naming no page of this VT (ignored)
  uint32_t resident = 0;          // mapped pages
  uint32_t in_flight = 0;         // handed out, not yet completed or failed
  double occupancy = 0.0;         // (resident + in_flight) / slot_count
  uint32_t mip_bias = 0;          // levels the renderer adds to its LOD
  bool oversubscribed = false;    // working set exceeded the cache this frame
};

class Residency {
 public:
  // Checks the options against `config`; messages start with `where` + "/<field>".
  static Status validate(const VtConfig& config, const ResidencyOptions& options, const std::string& where);

  // Both must be valid (fatal otherwise). Starts with nothing resident; the pinned pages are
  // queued by the first begin_frame, coarsest first.
  Residency(const VtConfig& config, const ResidencyOptions& options);

  void set_centre(uint32_t x, uint32_t y) { table_.set_centre(x, y); }  // level-0 texels

  // Starts frame `frame` (strictly increasing) with this frame's feedback (any order; a page
  // may repeat, its pixels add up). Touches, queues and updates the mip bias.
  void begin_frame(uint64_t frame, std::span<const PageFeedback> feedback);

  // The next (page, slot) to produce, or std::nullopt if the queue is empty, the page budget
  // of this frame is spent or no slot can be freed. The page is in flight until complete()
  // or failed(). O(1) amortised.
  std::optional<PageRequest> next_request();
  // Up to `max` calls of next_request(), for callers without a time budget.
  std::vector<PageRequest> take_requests(uint32_t max = UINT32_MAX);

  // The producer filled the slot: the page is mapped. Fatal if `page` is not in flight.
  void complete(const PageId& page);
  // The producer could not make the page: its slot is freed; its entries keep pointing at the
  // nearest resident ancestor. Fatal if `page` is not in flight.
  void failed(const PageId& page);
  // The request was withdrawn (no longer wanted, or the producer had no room): the slot is
  // freed and the page may be queued again next frame, without the failure back-off.
  // Fatal if `page` is not in flight.
  void cancelled(const PageId& page);
  // Pages in flight that no frame has needed for more than `frames` frames (a camera cut left
  // them behind): candidates for cancellation by producers that can still withdraw them.
  std::vector<PageId> stale_in_flight(uint64_t frames) const;

  const ResidencyStats& stats() const;
  uint32_t mip_bias() const { return bias_; }

  bool is_resident(const PageId& page) const;
  bool is_in_flight(const PageId& page) const;
  bool is_pinned(const PageId& page) const { return page.mip + options_.pinned_mips >= mip_count_; }
  uint32_t pinned_page_count() const { return pinned_count_; }
  std::vector<PageRequest> resident_pages() const;   // unordered; for tools and tests
  std::vector<PageRequest> in_flight_pages() const;  // unordered

  const PageTable& page_table() const { return table_; }
  const SlotAllocator& slots() const { return slots_; }
  std::vector<PageTableUpdate> take_table_updates() { return table_.take_updates(); }

 private:
  enum class State : uint8_t { in_flight, resident };
  struct Record {
    uint32_t slot = 0;
    State state = State::in_flight;
    uint64_t last_seen = 0;           // frame
    std::list<uint64_t>::iterator lru;  // valid if resident and not pinned
  };
  struct Candidate {
    PageId page;
    uint64_t pixels = 0;
    uint64_t age = 0;  // frames waiting
  };

  std::optional<uint32_t> evict_least_recent();
  void update_bias(uint32_t working_set);

  VtConfig config_;
  ResidencyOptions options_;
  uint32_t mip_count_ = 0;
  uint32_t pinned_count_ = 0;
  uint32_t max_bias_ = 0;
  PageTable table_;
  SlotAllocator slots_;
  std::unordered_map<uint64_t, Record> pages_;          // resident or in flight, by PageId::pack()
  std::list<uint64_t> lru_;                             // unpinned resident; front = least recent
  std::unordered_map<uint64_t, uint64_t> waiting_since_;  // queued page -> first frame queued
  std::unordered_map<uint64_t, uint64_t> retry_at_;       // failed page -> first frame to retry
  std::vector<Candidate> queue_;
  size_t cursor_ = 0;
  uint64_t frame_ = 0;
  bool started_ = false;
  uint32_t bias_ = 0;
  uint32_t frames_since_bias_change_ = UINT32_MAX / 2;
  uint32_t calm_ = 0;
  mutable ResidencyStats stats_;
};

}  // namespace tvt
