// The virtual texture on the GPU: residency policy (vt/), one page producer writing into the
// physical cache (render/page_producer.h: stored pages (render/stored_pages.h), terravt's
// composer or its hybrid with stored pages (composer/builtin_producers.h), or a client's
// plug-in), page table (device buffer updated by a GPU scatter) and the state a sampling pass
// binds (TvtVtInfo, entries, cache image + sampler). The runtime does not know which producer
// it drives, and knows nothing of scenes: it links no composer, image or scene library.
//
// Frame protocol (single queue). Up to frames_in_flight frames may be on the GPU at once: the
// caller guarantees (gpu/frame_ring.h) that frame f - frames_in_flight has completed before
// begin_frame(f); everything a frame's commands read from host memory (table updates, compose
// jobs, material and stored-page staging) lives in rings of that depth. GPU-side ordering
// (cache writes after earlier frames' reads, table updates after the composition they map)
// comes from queue order and barriers, not from waits.
//   begin_frame(frame, camera texel, feedback)  — CPU: LRU, requests within the budgets
//   record(cmd)                                 — compose requested pages, land loaded pages,
//                                                 mark them resident and scatter the table
//                                                 updates (evictions, recentring, the new
//                                                 pages) after their texels: the passes
//                                                 recorded next sample them this frame
//   ... the caller records passes that sample (bind info_buffer/entry_buffer/cache/sampler) ...
//   end_frame()                                 — once `cmd` is recorded: frame statistics
// Stored pages load on the loader's threads across frames: one requested in frame f lands in
// the first frame after it finished (or, with sync_loads, in frame f itself, which makes a
// stored run request and show exactly what a procedural run does).
#pragma once
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string_view>
#include <unordered_set>
#include <span>
#include <string>
#include <vector>

#include "gpu/context.h"
#include "render/page_producer.h"
#include "shaders/shared/vt_types.h"
#include "vt/residency.h"
#include "vt/vt_config.h"

namespace tvt {

struct VtSystemOptions {
  uint32_t cache_slots = 256;          // physical cache pages ((P+2B)^2 RGBA8 each)
  uint32_t window_pages = 64;          // page-table window W per mip
  uint32_t page_budget = 32;           // pages composed per frame at most
  double time_budget_ms = 1e9;         // CPU time for request selection per frame
  uint32_t pinned_mips = 1;            // coarsest mips kept resident
  uint32_t cancel_after_frames = 4;    // loads no frame has needed for this long are cancelled
  bool sync_loads = false;             // finish() the producer every frame: this frame's loads land in it
  uint32_t frames_in_flight = 2;       // frames the caller may have on the GPU at once (1 ... 8)
  // The producer of every page (its requests_per_frame() caps the requests a frame; page_budget
  // only checks it against the cache): `producer`, or
  // else the one `make_producer` makes once the cache exists (`cache`: the VT's cache image,
  // its layers the slots, owned by the VtSystem and outliving the producer). One is required.
  std::shared_ptr<PageProducer> producer;
  using ProducerFactory = std::function<Result<std::shared_ptr<PageProducer>>(vk::Context& context, vk::Image& cache)>;
  ProducerFactory make_producer;
};

class VtSystem {
 public:
  // `vt`: the geometry (log2_size, page_texels, border_texels).
  static Result<std::unique_ptr<VtSystem>> create(vk::Context& context, const VtConfig& vt,
                                                  const VtSystemOptions& options);
  ~VtSystem();

  void begin_frame(uint64_t frame, uint32_t camera_x, uint32_t camera_y, std::span<const PageFeedback> feedback);
  // Always records a complete frame. A material load error (first use of a material whose
  // file went missing or bad) fails this frame's compositions: their pages are marked failed
  // in the residency (their ancestors stand in), and the error (scene file, field, image file)
  // is returned so the caller can stop.
  Status record(VkCommandBuffer cmd);
  void end_frame();

  const VtFrameStats& stats() const { return stats_; }
  // Pages that became resident in the last record() (composed or landed), in that order.
  const std::vector<PageId>& last_completed() const { return completed_; }
  // Debug view for sampling passes (TVT_VT_VIEW_*), applied from the next begin_frame().
  void set_debug_view(int view) { debug_view_ = view; }
  const Residency& residency() const { return residency_; }
  const vk::Buffer& info_buffer() const { return info_buffer_; }
  const vk::Buffer& entry_buffer() const { return entry_buffer_; }
  const vk::Image& cache() const { return *cache_; }
  VkSampler sampler() const { return sampler_; }
  PageProducer& producer() { return *producer_; }
  // Bytes of GPU memory: page table + info + cache + what the producer holds besides.
  uint64_t gpu_bytes() const;

 private:
  VtSystem(const VtConfig& vt, const ResidencyOptions& residency) : residency_(vt, residency) {}
  vk::Context* context_ = nullptr;
  VtConfig vt_;
  VtSystemOptions options_;
  Residency residency_;
  std::unique_ptr<vk::Image> cache_;          // the producers write into it: created first
  std::shared_ptr<PageProducer> producer_;
  ProducerOutcome outcome_;
  std::unordered_set<uint64_t> outstanding_;  // accepted, not yet written, failed or cancelled
  void take_outcome();
  vk::Buffer info_buffer_, entry_buffer_, update_buffer_;
  gpu::TvtVtInfo info_{};              // written into info_buffer_ by record()
  uint32_t update_capacity_ = 0;       // entries per ring part of update_buffer_
  uint64_t records_ = 0;               // record() calls (ring position)
  vk::ComputePipeline scatter_;
  vk::DescriptorSet scatter_set_;
  VkSampler sampler_ = VK_NULL_HANDLE;
  std::vector<PageId> completed_;
  std::vector<PageTableUpdate> pending_updates_;
  VtFrameStats stats_;
  int debug_view_ = 0;
};

}  // namespace tvt
