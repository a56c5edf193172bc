// What the VT runtime (render/vt_system.h) asks of anything that makes pages: the compute
// composer, the stored-megatexture loader, their hybrid, or a client's plug-in (the public
// terravt::PageProducer is adapted to this interface in api/).
//
// A request names a page and the cache slot (layer of the cache image, (P+2B)^2 RGBA8 texels,
// layout GENERAL) it must land in. Per frame, on the frame thread:
//   begin_frame(frame)    the frame `frames_in_flight` earlier has completed: what it read from
//                         host memory (staging, job lists) may be reused
//   request(r) ...        accepted (written by this or a later record()), busy (not now: the
//                         residency asks again next frame) or unavailable (never: the page's
//                         nearest resident ancestor stands in)
//   cancel(page)          withdraw an accepted request that has not been written
//   finish()              block until every accepted request can be written or has failed
//                         (frame-exact runs; the pinned pages of the first frame)
//   record(cmd, outcome)  record the writes of the pages ready now, with compute or transfer
//                         stages (the runtime's barriers cover exactly those), and report what
//                         happened to requests since the last call
//   end_frame()           once `cmd` is recorded
// Every accepted request is reported exactly once: written, failed or cancelled.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <string>
#include <vector>

#include "render/stored_producer.h"
#include "vt/residency.h"
#include "vt/result.h"

namespace tvt {

// A composing producer's lazy material upload (composer/material_uploader.h): what is on the
// GPU. Bytes count texture levels + meta-texture + weight layer.
struct MaterialUploadStats {
  uint32_t materials = 0;           // in the scene
  uint32_t resident = 0;            // materials with anything on the GPU
  uint32_t resident_mask = 0;       // bit n: material n's weight layer (and some levels) are there
  uint32_t complete_mask = 0;       // bit n: all of material n is there
  uint64_t bytes_total = 0;         // what uploading everything copies
  uint64_t bytes_uploaded = 0;      // copied so far (each byte once)
  uint32_t last_materials = 0;      // materials that got data from the latest record() / upload_all()
  uint64_t last_bytes = 0;          // bytes the latest record() / upload_all() copied
  // CPU side (compose/material_source.h): materials read from disk or generated on first use.
  uint32_t cpu_loaded = 0;          // materials whose texels are in host memory
  uint32_t last_cpu_loaded = 0;     // materials the latest record() / upload_all() loaded
  double cpu_load_ms = 0.0;         // wall time of those loads, summed over all calls
  double last_cpu_load_ms = 0.0;    // ... of the latest record() / upload_all()
  uint32_t load_failures = 0;       // record() / upload_all() calls that met a load error
};

struct VtFrameStats {
  ResidencyStats residency;
  uint32_t composed = 0;               // pages composed this frame (incl. fallbacks)
  uint32_t fallback_composed = 0;      // ... of which instead of a bad stored page (hybrid)
  uint32_t missing = 0;                // requests no producer could serve (their ancestors stand in)
  uint32_t compose_failed = 0;         // pages not composed because a material failed to load
  uint32_t produce_failed = 0;         // pages a producer reported failed this frame (all kinds)
  StoredFrameStats stored;             // loader activity (stored and hybrid sources)
  MaterialUploadStats materials;       // lazy material upload (what this frame's pages needed first)
  uint32_t table_updates = 0;          // entries scattered this frame
  double select_ms = 0;                // CPU time spent choosing requests
};

enum class ProducerAccept { accepted, busy, unavailable };

struct ProducerOutcome {
  std::vector<PageRequest> written;    // recorded into their slots: resident once `cmd` runs
  std::vector<PageRequest> failed;     // will not be produced: their ancestors stand in
  std::vector<PageRequest> cancelled;  // withdrawn: may be asked for again
  void clear() {
    written.clear();
    failed.clear();
    cancelled.clear();
  }
};

class PageProducer {
 public:
  virtual ~PageProducer() = default;
  // The most requests it may accept in one frame (sizes the residency's request list).
  virtual uint32_t requests_per_frame() const = 0;
  virtual void begin_frame(uint64_t /*frame*/) {}
  virtual ProducerAccept request(const PageRequest& request) = 0;
  virtual void cancel(const PageId& /*page*/) {}
  virtual void finish() {}
  // An error (a material file that cannot be loaded, a plug-in's failure) comes with its pages
  // in outcome.failed; what was recorded is still a complete frame.
  virtual Status record(VkCommandBuffer cmd, ProducerOutcome& outcome) = 0;
  virtual void end_frame() {}
  // Adds this frame's counters (composed, stored, materials...).
  virtual void add_stats(VtFrameStats& /*stats*/) const {}
  // Diagnostics about bad pages since the last call (each once).
  virtual std::vector<std::string> take_error_messages() { return {}; }
  // GPU memory it holds besides the cache (staging, scene buffers).
  virtual uint64_t gpu_bytes() const { return 0; }
};

}  // namespace tvt
