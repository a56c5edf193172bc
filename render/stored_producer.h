// Stored-page producer of the VT (docs/virtual-texture.md, docs/page-store.md): pages of a baked store are read,
// verified and decompressed by streaming/'s PageLoader on its own threads, straight into a
// host-visible staging ring; the frame loop only polls finished pages and records their copy
// into the cache slots. Nothing here ever waits for I/O.
//
// Per frame, on the frame thread (VtSystem drives it):
//   begin_frame()                    resets the frame's counters; releases the staging of the
//                                    frame frames_in_flight frames ago (completed by then)
//   poll(ready, failed, cancelled)   finished loads; ready ones are copied by the next record()
//   request(page, slot) / cancel()    while can_accept()
//   record(cmd, cache)               copy ready pages from staging into their cache layers
//   end_frame()                      once `cmd` is submitted
// A page that fails verification is reported once, remembered as bad and never requested
// again: has() turns false, so the caller falls back (coarser mip or procedural page).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

#include "gpu/context.h"
#include "streaming/page_loader.h"
#include "streaming/page_store.h"
#include "vt/residency.h"

namespace tvt {

struct StoredProducerOptions {
  uint32_t threads = 2;          // loader I/O + decode threads
  uint32_t staging_slots = 32;   // pages staged at once (also the most loads outstanding)
  uint32_t frames_in_flight = 1; // frames whose copies may still run when a frame begins
};

struct StoredFrameStats {
  uint32_t requested = 0;        // loads started this frame
  uint32_t landed = 0;           // pages copied into the cache this frame
  uint32_t failed = 0;           // loads that failed (missing, truncated, corrupt, I/O)
  uint32_t cancelled = 0;        // loads withdrawn
  uint32_t outstanding = 0;      // loads queued or running after this frame's requests
  uint32_t staging_in_use = 0;
  double read_ms = 0, decode_ms = 0;  // summed over the pages that landed (loader threads)
};

class StoredProducer {
 public:
  // Whether `store` holds this VT's pages: the same geometry, RGBA8 albedo+height in layer 0,
  // and `scene_hash` (0: unchecked) equal to the store's. The error names the store and field.
  static Status matches(const PageStoreReader& store, const VtConfig& vt, uint64_t scene_hash);
  // The store must match (matches()).
  static Result<std::unique_ptr<StoredProducer>> create(vk::Context& context, std::shared_ptr<const PageStoreReader> store,
                                                        const VtConfig& vt, uint64_t scene_hash,
                                                        const StoredProducerOptions& options);
  ~StoredProducer();

  // The store holds `page` and it has not failed.
  bool has(const PageId& page) const;
  // A request would be accepted now (staging ring not full).
  bool can_accept() const;
  // Starts loading `page` for cache slot `slot`; false if the ring is full (nothing started).
  bool request(const PageRequest& request);
  void cancel(const PageId& page);
  // Collects finished loads. `ready` pages are copied by the next record(); `failed` and
  // `cancelled` are for the caller to hand back to the residency (or to a fallback producer).
  void poll(std::vector<PageRequest>& ready, std::vector<PageRequest>& failed, std::vector<PageRequest>& cancelled);
  void begin_frame();
  void record(VkCommandBuffer cmd, const vk::Image& cache);
  void end_frame();

  const StoredFrameStats& stats() const { return stats_; }
  PageLoaderStats loader_stats() const { return loader_->stats(); }
  // Each bad page once, e.g. "store.tvt: mip 3 page (5,2): checksum mismatch".
  std::vector<std::string> take_error_messages() { return loader_->take_error_messages(); }
  const PageStoreReader& store() const { return *store_; }
  uint64_t gpu_bytes() const { return staging_.size(); }
  // Tests and benchmarks: blocks until no load is outstanding.
  void wait_idle() { loader_->wait_idle(); }

 private:
  StoredProducer() = default;
  struct Copy {
    PageRequest request;
    uint32_t staging = 0;
  };
  vk::Context* context_ = nullptr;
  std::shared_ptr<const PageStoreReader> store_;
  vk::Buffer staging_;
  std::unique_ptr<PageLoader> loader_;
  uint32_t staging_slots_ = 0;
  uint32_t slot_texels_ = 0;
  std::vector<Copy> to_copy_;      // recorded by the next record()
  // Staging slots copied by each of the last frames_in_flight frames, by frame modulo that.
  std::vector<std::vector<uint32_t>> to_release_;
  uint64_t frames_ = 0;
  std::unordered_set<uint64_t> bad_;  // pages that failed: never requested again
  std::vector<LoadedPage> polled_;
  StoredFrameStats stats_;
};

}  // namespace tvt
