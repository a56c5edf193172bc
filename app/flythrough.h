// The VT frame loop (the main job of `terravt render`), as a library function so tests and
// benchmarks drive exactly what the CLI runs: camera path -> terrain pass sampling the VT and
// writing feedback -> GPU feedback compaction -> residency -> compute composition into the
// cache -> GPU page-table scatter. The VT runs through the public API (terravt::VirtualTexture
// on the device's handles: begin_frame, record, record_feedback), as in an engine; the loop
// is terravt's own client of it, with its own frame ring, terrain pass and feedback buffer.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "compose/image.h"
#include "compose/packed_scene.h"
#include "terrain/camera.h"
#include "terrain/camera_file.h"
#include "terrain/terrain_mesh.h"
#include "app/terrain_renderer.h"
#include "gpu/context.h"
#include "composer/builtin_producers.h"
#include "render/vt_system.h"

namespace tvt {

struct FlythroughOptions {
  Method method = Method::FbpbDpt;
  MipStrategy mip_strategy;  // how pages of mip >= 1 are composed
  uint32_t frames = 120;
  uint32_t width = 640, height = 360;   // pixels
  double fps = 10.0;                    // camera-path frames per second
  uint32_t feedback_divisor = 8;        // N
  FeedbackMode feedback_mode = FeedbackMode::Attachment;  // who writes feedback (not None)
  uint32_t max_anisotropy = 1;          // VT taps per mip along the footprint (1: isotropic; <= B)
  VtMipFilter mip_filter = VtMipFilter::Trilinear;  // between mips: trilinear, brilinear band or nearest only
  SceneVtOptions vt;
  int debug_view = 0;                   // TVT_VT_VIEW_*: 1 colours every texel by its data mip
  TerrainLighting lighting;             // sun, ambient, sky/fog, detail relief
  // Reads each frame's feedback exactly one frame late, waiting for it if needed, so two runs
  // of one path request the same pages at the same frames (comparisons, tests). Off: the
  // newest ready feedback, never a wait (what an engine does).
  bool deterministic = false;
  // Frames recorded ahead of the GPU (gpu/frame_ring.h): the loop blocks only when the GPU
  // is this many frames behind. 1: every frame waits for the previous one.
  uint32_t frames_in_flight = 2;
  // The camera path and lens (terrain/camera_file.h); none: the scene's built-in flythrough with
  // the default lens.
  std::optional<CameraFile> camera;
};

struct FlythroughFrame {
  uint32_t index = 0;
  double time_s = 0;
  Camera camera;
  bool cut = false;                     // the camera path cut to a new shot at this frame
  size_t feedback_pages = 0;
  uint64_t feedback_frames_late = 0;    // 0: no feedback yet
  VtFrameStats vt;
  std::vector<std::string> store_errors;  // bad stored pages first seen this frame (each once)
  std::vector<PageId> completed;          // pages that became resident this frame
  uint64_t triangles = 0;
  // total: the loop iteration (frame begin to submit and bookkeeping; not the callback);
  // wait: blocked on the GPU being frames_in_flight frames behind (and, deterministic, on
  // feedback); cpu: total - wait. gpu: GPU time of frame gpu_ms_frame, the newest frame seen
  // complete at the start of this iteration (timestamps; 0 when none or no timestamp support).
  // residency: CPU time of the feedback read-back parse and VtSystem::begin_frame (LRU,
  // recentring, request selection: vt.select_ms of it).
  double cpu_ms = 0, wait_ms = 0, gpu_ms = 0, total_ms = 0, residency_ms = 0;
  uint64_t gpu_ms_frame = 0;
  // gpu_ms by stage: VT (uploads, composition, stored copies, table scatter), terrain pass
  // (with the separate feedback pass), feedback compaction.
  std::array<double, 3> gpu_stage_ms{};
};

struct FlythroughSummary {
  uint32_t frames = 0;
  uint64_t pages_composed = 0;
  uint64_t pages_loaded = 0;            // stored pages copied into the cache
  uint64_t load_failures = 0;           // stored pages that failed reading or verification
  uint64_t pages_missing = 0;           // requests the store had no page for
  uint32_t oversubscribed_frames = 0;
  uint32_t max_mip_bias = 0;
  uint64_t gpu_bytes = 0;
  double seconds = 0;
};

// Read-backs a frame callback may ask for (each blocks until the frame has completed; call only
// what is needed). The callback runs before the next frame is recorded, so they show this frame.
struct FlythroughViews {
  std::function<ImageRGBA8()> frame;       // the rendered colour
  std::function<ImageRGBA8()> atlas;       // every cache slot (vt_debug.h)
  std::function<ImageRGBA8()> page_table;  // every mip window, coloured by data mip
  std::function<ImageRGBA8()> feedback;    // this frame's feedback texels, coloured by mip
  // The GPU page table after this frame, read back as it is bound (every mip's window, uint32
  // entries of shared/page_table_entry.h, little-endian): what a client of the installed API
  // reads from VirtualTextureBindings::table_buffer.
  std::function<std::vector<uint8_t>()> page_table_bytes;
};

// Called after every frame. Returning false stops the loop early.
using FrameCallback = std::function<bool(const FlythroughFrame& frame, const FlythroughViews& views)>;

// The scene's built-in flythrough (CameraPath::default_flythrough over the mesh's ground).
CameraPath flythrough_path(const SceneAssets& assets, const TerrainMesh& mesh);
// The path run_flythrough() follows: `file` resolved over the mesh's ground, or the built-in
// flythrough when `file` is null. Errors name the camera file and key.
Result<CameraPath> flythrough_path(const SceneAssets& assets, const TerrainMesh& mesh, const CameraFile* file);

// Runs the loop on options.camera (default: the scene's built-in flythrough). Errors name the
// option at fault.
Result<FlythroughSummary> run_flythrough(vk::Context& context, const SceneAssets& assets, const FlythroughOptions& options,
                                         const FrameCallback& on_frame);

}  // namespace tvt
