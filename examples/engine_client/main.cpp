// engine_client: a small engine that uses terravt as its virtual-texture backend through the
// installed package only (docs/engine-integration.md, "The example client"). It makes its own
// Vulkan device, its own render pass, mesh, descriptor layout and shaders; terravt records its
// page production into the engine's command buffers, the engine's fragment shader samples with
// terravt_sample() and writes requests with terravt_feedback() into a storage buffer, which
// terravt compacts on the GPU (record_feedback(); --cpu-feedback: the engine reads it back and
// turns it into terravt::PageRequest's). N frames offscreen; the last is saved as PNG.
#include <terravt/compose.h>  // the scene and its composer (component `compose`)
#include <terravt/terravt.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "device.h"
#include "png.h"
#include "terrain_pass.h"

namespace {

struct Args {
  std::string scene, method = "fbpb+dpt2", out = "engine_client.png", page_table;
  double extent_m = 8192;
  uint32_t width = 640, height = 360, frames = 60;
  double x = 4096, y = 4096, z = 120, yaw_deg = 30, pitch_deg = -35, fov_deg = 60, near_m = 0.5, far_m = 100000;
  uint32_t feedback_divisor = 8, cache_slots = 512, page_budget = 48, window = 64, chunks = 16, quads = 32;
  bool bench = false, validation = false, cpu_feedback = false;
};

constexpr const char* kUsage = R"(usage: engine_client [options]
  --scene FILE            terravt scene JSON (default: terravt's built-in scene)
  --extent-m M            the terrain's side in metres, as the scene says (default 8192)
  --method NAME           transition method (default fbpb+dpt2)
  --width W --height H    image size (default 640 x 360)
  --frames N              frames to render (default 60); the last is written
  --position X,Y,Z        camera position in metres (default 4096,4096,120); the terrain is flat at z = 0
  --yaw-deg D             heading: 0 looks along +x, 90 along +y (default 30)
  --pitch-deg D           elevation, -90 straight down (default -35)
  --fov-deg D             vertical field of view (default 60)
  --near M --far M        clip planes (default 0.5, 100000)
  --feedback-divisor N    one page request per N x N pixels, a rotating pixel per frame (default 8)
  --cpu-feedback          read the feedback back on the CPU and pass it to begin_frame() as
                          terravt::PageRequest's, instead of terravt's GPU compaction (record_feedback())
  --cache-slots N --page-budget N --window N   terravt's cache, pages per frame, page-table window (512, 48, 64)
  --chunks C --quads-per-chunk Q               the engine's grid: C x C chunks of Q x Q quads (16, 32)
  --out FILE.png          the last frame (default engine_client.png)
  --page-table FILE       also write terravt's page table after the last frame (raw little-endian uint32s)
  --bench                 print the steady frame time (mean and median over the last half of the frames)
  --validation            Vulkan validation layer with synchronisation validation; any message fails the run (exit 3)
)";

int usage_error(const std::string& what) {
  std::fprintf(stderr, "engine_client: %s\n%s", what.c_str(), kUsage);
  return 2;
}

bool parse_number(const char* text, double& out) {
  char* end = nullptr;
  out = std::strtod(text, &end);
  return end != text && *end == '\0' && std::isfinite(out);
}

bool parse_uint(const char* text, uint32_t& out) {
  char* end = nullptr;
  const unsigned long long v = std::strtoull(text, &end, 10);
  if (end == text || *end != '\0' || text[0] == '-' || v > UINT32_MAX) return false;
  out = uint32_t(v);
  return true;
}

// Returns 0 to run, or the exit status (2: a bad flag, named; 0 after --help).
int parse(int argc, char** argv, Args& a) {
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--help" || flag == "-h") {
      std::printf("%s", kUsage);
      return -1;
    }
    if (flag == "--bench") { a.bench = true; continue; }
    if (flag == "--validation") { a.validation = true; continue; }
    if (flag == "--cpu-feedback") { a.cpu_feedback = true; continue; }
    static const char* const kValueFlags[] = {
        "--scene", "--method", "--out", "--page-table", "--extent-m", "--width", "--height", "--frames",
        "--yaw-deg", "--pitch-deg", "--fov-deg", "--near", "--far", "--feedback-divisor", "--cache-slots",
        "--page-budget", "--window", "--chunks", "--quads-per-chunk", "--position"};
    if (std::find(std::begin(kValueFlags), std::end(kValueFlags), flag) == std::end(kValueFlags))
      return usage_error("unknown flag " + flag);
    if (i + 1 >= argc) return usage_error(flag + ": needs a value");
    const char* v = argv[++i];
    bool ok = true;
    if (flag == "--scene") a.scene = v;
    else if (flag == "--method") a.method = v;
    else if (flag == "--out") a.out = v;
    else if (flag == "--page-table") a.page_table = v;
    else if (flag == "--extent-m") ok = parse_number(v, a.extent_m) && a.extent_m > 0;
    else if (flag == "--width") ok = parse_uint(v, a.width) && a.width >= 16 && a.width <= 8192;
    else if (flag == "--height") ok = parse_uint(v, a.height) && a.height >= 16 && a.height <= 8192;
    else if (flag == "--frames") ok = parse_uint(v, a.frames) && a.frames >= 1 && a.frames <= 100000;
    else if (flag == "--yaw-deg") ok = parse_number(v, a.yaw_deg);
    else if (flag == "--pitch-deg") ok = parse_number(v, a.pitch_deg) && std::abs(a.pitch_deg) <= 90;
    else if (flag == "--fov-deg") ok = parse_number(v, a.fov_deg) && a.fov_deg >= 0.01 && a.fov_deg <= 179;
    else if (flag == "--near") ok = parse_number(v, a.near_m) && a.near_m > 0;
    else if (flag == "--far") ok = parse_number(v, a.far_m);
    else if (flag == "--feedback-divisor") ok = parse_uint(v, a.feedback_divisor) && a.feedback_divisor >= 1 && a.feedback_divisor <= 64;
    else if (flag == "--cache-slots") ok = parse_uint(v, a.cache_slots) && a.cache_slots >= 2;
    else if (flag == "--page-budget") ok = parse_uint(v, a.page_budget) && a.page_budget >= 1;
    else if (flag == "--window") ok = parse_uint(v, a.window) && a.window >= 4 && (a.window & (a.window - 1)) == 0;
    else if (flag == "--chunks") ok = parse_uint(v, a.chunks) && a.chunks >= 1 && a.chunks <= 1024 && (a.chunks & (a.chunks - 1)) == 0;
    else if (flag == "--quads-per-chunk") ok = parse_uint(v, a.quads) && a.quads >= 1 && a.quads <= 256 && (a.quads & (a.quads - 1)) == 0;
    else if (flag == "--position") {
      ok = std::sscanf(v, "%lf,%lf,%lf", &a.x, &a.y, &a.z) == 3 && std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z) && a.z > 0;
    } else return usage_error("unknown flag " + flag);
    if (!ok) return usage_error(flag + ": invalid value '" + v + "'");
  }
  if (!(a.far_m > a.near_m)) return usage_error("--far: must be larger than --near");
  if (a.page_budget > a.cache_slots) return usage_error("--page-budget: at most --cache-slots");
  if (a.feedback_divisor > std::min(a.width, a.height)) return usage_error("--feedback-divisor: at most the image's width and height");
  return 0;
}

int fail(const std::string& what, int code = 1) {
  std::fprintf(stderr, "engine_client: %s\n", what.c_str());
  return code;
}

// Prints every validation message; true when there were none.
bool clean(engine::Device& device) {
  const std::vector<std::string> lines = device.messages().take();
  for (const std::string& l : lines) std::fprintf(stderr, "  %s\n", l.c_str());
  if (!lines.empty()) std::fprintf(stderr, "engine_client: %zu validation message(s)\n", lines.size());
  return lines.empty();
}

int run(const Args& a) {
  std::string error;
  auto device = engine::Device::create(a.validation, error);
  if (!device) return fail(error);
  const terravt::DeviceHandles handles = device->handles();
  if (terravt::Status s = terravt::check_device(handles); !s.ok()) return fail("terravt::check_device: " + s.error().message);

  constexpr uint32_t kFramesInFlight = 2;
  terravt::VirtualTextureDesc vd;
  vd.scene_file = a.scene;
  vd.method = a.method;
  vd.cache_slots = a.cache_slots;
  vd.page_budget = a.page_budget;
  vd.window_pages = a.window;
  vd.frames_in_flight = kFramesInFlight;
  // The GPU route: terravt compacts the pass's feedback buffer (every texel of it) itself.
  if (!a.cpu_feedback) vd.feedback_texels = engine::feedback_texel_count(a.width, a.height, a.feedback_divisor);
  // Composed from the scene: the compose component. (An engine that streams baked stores only
  // calls terravt::VirtualTexture::create() with source = stored and links libterravt alone.)
  auto created = terravt::compose::create_virtual_texture(handles, vd);
  if (!created.ok()) return fail("terravt::compose::create_virtual_texture: " + created.error().message);
  std::unique_ptr<terravt::VirtualTexture> vt = std::move(created.value());
  const terravt::VirtualTextureInfo info = vt->info();

  engine::TerrainPassDesc pd;
  pd.width = a.width;
  pd.height = a.height;
  pd.log2_size = info.log2_size;
  pd.extent_m = a.extent_m;
  pd.chunks_per_side = a.chunks;
  pd.quads_per_chunk = a.quads;
  pd.feedback_divisor = a.feedback_divisor;
  pd.frames_in_flight = kFramesInFlight;
  pd.feedback_on_host = a.cpu_feedback;
  pd.vt = vt->bindings();
  auto pass = engine::TerrainPass::create(*device, pd, error);
  if (!pass) return fail(error);

  // The engine's frame ring: a command buffer and a fence per frame in flight.
  const VkDevice d = device->device();
  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = device->queue_family();
  VkCommandPool pool = VK_NULL_HANDLE;
  vkCreateCommandPool(d, &pci, nullptr, &pool);
  VkCommandBuffer cmds[kFramesInFlight];
  VkCommandBufferAllocateInfo cai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  cai.commandPool = pool;
  cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  cai.commandBufferCount = kFramesInFlight;
  vkAllocateCommandBuffers(d, &cai, cmds);
  VkFence fences[kFramesInFlight];
  for (VkFence& f : fences) {
    VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    fci.flags = VK_FENCE_CREATE_SIGNALED_BIT;
    vkCreateFence(d, &fci, nullptr, &f);
  }

  engine::Camera camera;
  camera.position_m = {a.x, a.y, a.z};
  constexpr double kRadiansPerDegree = std::numbers::pi / 180.0;
  camera.yaw_rad = a.yaw_deg * kRadiansPerDegree;
  camera.pitch_rad = a.pitch_deg * kRadiansPerDegree;
  camera.vertical_fov_rad = a.fov_deg * kRadiansPerDegree;
  camera.near_m = a.near_m;
  camera.far_m = a.far_m;
  const glm::dvec2 ct = pass->camera_texel(camera);

  std::printf("engine_client: terravt %s on %s, V = 2^%u, %ux%u, %u frames, feedback 1/%u on the %s\n",
              terravt::version_string(), device->name().c_str(), info.log2_size, a.width, a.height, a.frames,
              a.feedback_divisor, a.cpu_feedback ? "CPU" : "GPU");
  std::vector<terravt::PageRequest> requests;
  std::vector<double> frame_ms;
  uint64_t produced = 0;
  size_t requested = 0;  // distinct pages of the newest feedback that reached terravt
  std::optional<uint64_t> newest;  // the newest frame known complete
  int status = 0;
  for (uint64_t f = 0; f < a.frames && status == 0; ++f) {
    const auto t0 = std::chrono::steady_clock::now();
    const uint32_t slot = uint32_t(f % kFramesInFlight);
    vkWaitForFences(d, 1, &fences[slot], VK_TRUE, UINT64_MAX);  // back-pressure: frame f - 2 is done
    if (f >= kFramesInFlight) newest = f - kFramesInFlight;
    // The newest finished frame, never waiting: one frame late when the GPU kept up. Its
    // requests: read back here (CPU route), or its compaction, read by begin_frame() (GPU route).
    for (uint64_t late = 1; late < kFramesInFlight && late <= f; ++late)
      if (vkGetFenceStatus(d, fences[(f - late) % kFramesInFlight]) == VK_SUCCESS) {
        newest = f - late;
        break;
      }
    if (newest && a.cpu_feedback) {
      requests = pass->read_requests(uint32_t(*newest % kFramesInFlight));
      requested = requests.size();
    }
    vkResetFences(d, 1, &fences[slot]);
    VkCommandBuffer cmd = cmds[slot];
    vkResetCommandBuffer(cmd, 0);
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    vkBeginCommandBuffer(cmd, &bi);
    if (terravt::Status s = vt->begin_frame(f, newest, int64_t(std::floor(ct.x)), int64_t(std::floor(ct.y)), requests); !s.ok())
      status = fail("terravt begin_frame: " + s.error().message);
    else if (terravt::Status r = vt->record(cmd); !r.ok())
      status = fail("terravt record: " + r.error().message);  // the frame is still complete: finish it
    produced += vt->stats().produced;
    if (!a.cpu_feedback && vt->stats().feedback_pages > 0) requested = vt->stats().feedback_pages;
    pass->record(cmd, slot, f, camera);
    if (status == 0 && !a.cpu_feedback)
      if (terravt::Status s = vt->record_feedback(cmd, pass->feedback_buffer(slot)); !s.ok())
        status = fail("terravt record_feedback: " + s.error().message);
    if (f + 1 == a.frames) pass->record_readback(cmd, vt->bindings().table_buffer, vt->bindings().table_bytes);
    vkEndCommandBuffer(cmd);
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmd;
    if (VkResult r = vkQueueSubmit(device->queue(), 1, &si, fences[slot]); r != VK_SUCCESS)
      status = fail("vkQueueSubmit failed (VkResult " + std::to_string(int(r)) + ")");
    frame_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  vkDeviceWaitIdle(d);

  if (status == 0) {
    std::printf("%zu frames, %llu pages produced, %u resident, %zu pages requested by the last feedback read, %u chunks drawn\n",
                frame_ms.size(), (unsigned long long)produced, vt->stats().resident, requested, pass->drawn_chunks());
    if (a.bench) {
      std::vector<double> steady(frame_ms.end() - long(frame_ms.size() / 2), frame_ms.end());
      double sum = 0;
      for (double ms : steady) sum += ms;
      std::sort(steady.begin(), steady.end());
      std::printf("bench: steady frame %.2f ms mean, %.2f ms median over the last %zu frames (%ux%u)\n",
                  sum / double(steady.size()), steady[steady.size() / 2], steady.size(), a.width, a.height);
    }
    if (std::string e = engine::write_png(a.out, pass->colour_rgba(), a.width, a.height); !e.empty()) status = fail(e);
    else if (!a.page_table.empty())
      if (std::string t = engine::write_file(a.page_table, pass->table_bytes()); !t.empty()) status = fail(t);
    if (status == 0) std::printf("wrote %s%s%s\n", a.out.c_str(), a.page_table.empty() ? "" : " and ", a.page_table.c_str());
  }
  for (VkFence f : fences) vkDestroyFence(d, f, nullptr);
  vkDestroyCommandPool(d, pool, nullptr);
  pass.reset();
  vt.reset();  // the GPU finished every command buffer it recorded into (vkDeviceWaitIdle above)
  if (a.validation && !clean(*device) && status == 0) status = 3;
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  if (const int p = parse(argc, argv, a); p != 0) return p < 0 ? 0 : p;
  return run(a);
}
