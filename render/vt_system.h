// The virtual texture on the GPU: residency policy (vt/), procedural producer (GpuComposer
// into the physical cache), page table (device buffer updated by a GPU scatter) and the
// state a sampling pass binds (TvtVtInfo, entries, cache image + sampler).
//
// Frame protocol (single queue; the caller waits for a frame's fence before the next
// begin_frame, so host-visible buffers are never written while the GPU reads them):
//   begin_frame(frame, camera texel, feedback)  — CPU: LRU, requests within the budgets
//   record(cmd)                                 — compose requested pages, scatter table updates
//   ... the caller records passes that sample (bind info_buffer/entry_buffer/cache/sampler) ...
//   end_frame()                                 — after the fence: requested pages become
//                                                 resident (visible from the next frame on)
#pragma once
#include <chrono>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "compose/packed_scene.h"
#include "render/gpu_composer.h"
#include "render/vk_context.h"
#include "shaders/shared/vt_types.h"
#include "vt/residency.h"

namespace tvt {

struct VtSystemOptions {
  uint32_t cache_slots = 256;          // physical cache pages ((P+2B)^2 RGBA8 each)
  uint32_t window_pages = 64;          // page-table window W per mip
  uint32_t page_budget = 32;           // pages composed per frame at most
  double time_budget_ms = 1e9;         // CPU time for request selection per frame
  uint32_t pinned_mips = 1;            // coarsest mips kept resident
};

struct VtFrameStats {
  ResidencyStats residency;
  uint32_t composed = 0;               // pages composed this frame
  uint32_t table_updates = 0;          // entries scattered this frame
  double select_ms = 0;                // CPU time spent choosing requests
};

class VtSystem {
 public:
  static Result<std::unique_ptr<VtSystem>> create(vk::Context& context, const PackedScene& scene,
                                                  const VtSystemOptions& options);
  ~VtSystem();

  void begin_frame(uint64_t frame, uint32_t camera_x, uint32_t camera_y, std::span<const PageFeedback> feedback);
  void record(VkCommandBuffer cmd);
  void end_frame();

  const VtFrameStats& stats() const { return stats_; }
  // Debug view for sampling passes (TVT_VT_VIEW_*), applied from the next begin_frame().
  void set_debug_view(int view) { debug_view_ = view; }
  const Residency& residency() const { return residency_; }
  const vk::Buffer& info_buffer() const { return info_buffer_; }
  const vk::Buffer& entry_buffer() const { return entry_buffer_; }
  const vk::Image& cache() const { return composer_->output(); }
  VkSampler sampler() const { return sampler_; }
  GpuComposer& composer() { return *composer_; }
  // Bytes of GPU memory: page table + info + cache.
  uint64_t gpu_bytes() const;

 private:
  VtSystem(const VtConfig& vt, const ResidencyOptions& residency) : residency_(vt, residency) {}
  vk::Context* context_ = nullptr;
  VtConfig vt_;
  VtSystemOptions options_;
  Residency residency_;
  std::unique_ptr<GpuComposer> composer_;
  vk::Buffer info_buffer_, entry_buffer_, update_buffer_;
  uint32_t update_capacity_ = 0;
  vk::ComputePipeline scatter_;
  vk::DescriptorSet scatter_set_;
  VkSampler sampler_ = VK_NULL_HANDLE;
  std::vector<PageJob> jobs_;
  std::vector<PageTableUpdate> pending_updates_;
  VtFrameStats stats_;
  int debug_view_ = 0;
};

}  // namespace tvt
