// Frames in flight: the VT frame loop records frame f while earlier frames still run, so every
// host-visible input of a frame (table updates, compose jobs, material staging, the VT info)
// lives in a ring. These tests let the GPU fall behind on purpose and check that nothing a
// frame still needs was overwritten: the final GPU page table, info block and every cache slot
// must be exactly what a correct pipeline gives. Validation is on; any message fails.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "app/flythrough.h"
#include "gpu/frame_ring.h"
#include "render/vt_info.h"
#include "composer/builtin_producers.h"
#include "render/vt_system.h"
#include "support/gpu_test.h"

using namespace tvt;

namespace {

std::vector<uint8_t> read_buffer(vk::Context& ctx, const vk::Buffer& device) {
  vk::Buffer host = ctx.create_buffer(device.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  ctx.run_commands([&](VkCommandBuffer cmd) {
    const VkBufferCopy copy{0, 0, device.size()};
    vkCmdCopyBuffer(cmd, device.handle(), host.handle(), 1, &copy);
  });
  const auto* p = static_cast<const uint8_t*>(host.mapped());
  return std::vector<uint8_t>(p, p + device.size());
}

// Every layer of the cache, layer-major.
std::vector<uint8_t> read_cache(vk::Context& ctx, const vk::Image& cache) {
  const VkDeviceSize layer = VkDeviceSize(cache.width()) * cache.height() * 4;
  vk::Buffer host = ctx.create_buffer(layer * cache.layers(), VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  ctx.run_commands([&](VkCommandBuffer cmd) {
    ctx.transition(cmd, cache, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, cache.layers()};
    region.imageExtent = {cache.width(), cache.height(), 1};
    vkCmdCopyImageToBuffer(cmd, cache.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host.handle(), 1, &region);
    ctx.transition(cmd, cache, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
  });
  const auto* p = static_cast<const uint8_t*>(host.mapped());
  return std::vector<uint8_t>(p, p + layer * cache.layers());
}

const SceneAssets& assets14() {
  static const SceneAssets a = [] {
    SceneDesc d = default_scene();
    d.vt.log2_size = 14;  // 128 x 128 pages at mip 0, 8 mips
    auto r = load_scene_assets(d);
    EXPECT_TRUE(r.ok());
    return std::move(r.value());
  }();
  return a;
}

}  // namespace

class GpuFramesInFlight : public GpuTest {};

// A random camera walk with random feedback, three frames in flight and a cache far smaller
// than what the stream asks for: pages are composed, evicted and recomposed into reused slots
// while the frames that sampled the old contents may still run.
TEST_F(GpuFramesInFlight, RingsKeepEveryFramesInputsUntilItCompletes) {
  auto packed = pack_scene(assets14(), options_for(Method::Linear));
  ASSERT_TRUE(packed.ok());
  SceneVtOptions o;
  o.cache_slots = 24;
  o.window_pages = 8;  // small windows: the walk recentres them often (bursts of table updates)
  o.page_budget = 6;
  o.frames_in_flight = 3;
  auto vt = create_vt_system(ctx(), packed.value(), o);
  ASSERT_TRUE(vt.ok()) << vt.error().message;
  VtSystem& s = *vt.value();
  auto ring = FrameRing::create(ctx(), o.frames_in_flight);
  ASSERT_TRUE(ring.ok()) << ring.error().message;

  std::mt19937 engine(7);
  auto rng = [&engine] { return uint32_t(engine()); };
  uint32_t cx = 3000, cy = 9000;
  double waited_ms = 0;
  uint64_t composed = 0, evicted = 0;
  for (uint64_t frame = 1; frame <= 40; ++frame) {
    VkCommandBuffer cmd = ring.value()->begin(frame);
    waited_ms += ring.value()->last_wait_ms();
    cx = std::min<uint32_t>(16383, cx + rng() % 700);
    cy -= std::min<uint32_t>(cy, rng() % 500);
    std::vector<PageFeedback> feedback;
    for (int i = 0; i < 8; ++i) {
      const uint32_t mip = rng() % 4;
      const uint32_t px = (cx >> (7 + mip)) + rng() % 3, py = (cy >> (7 + mip)) + rng() % 3;
      const uint32_t last = (1u << (7 - mip)) - 1;
      feedback.push_back({PageId{mip, std::min(px, last), std::min(py, last)}, 10 + rng() % 90});
    }
    s.begin_frame(frame, cx, cy, feedback);
    TVT_CHECK(s.record(cmd).ok());
    ring.value()->submit();
    s.end_frame();
    composed += s.stats().composed;
    evicted += s.residency().stats().evicted;
  }
  ring.value()->wait_idle();
  EXPECT_GT(composed, 60u);
  EXPECT_GT(evicted, 0u);
  // The GPU fell behind, so frames really overlapped (lavapipe composes far slower than the
  // CPU records).
  EXPECT_GT(waited_ms, 0.0);

  // The GPU table and info block equal what the CPU state says, bit for bit.
  const auto entries = read_buffer(ctx(), s.entry_buffer());
  const auto cpu_entries = s.residency().page_table().all_entries();
  ASSERT_EQ(entries.size(), cpu_entries.size_bytes());
  EXPECT_EQ(std::memcmp(entries.data(), cpu_entries.data(), entries.size()), 0);
  VtConfig cfg;
  cfg.log2_size = 14;
  cfg.page_texels = uint32_t(packed->params.page_texels);
  cfg.border_texels = uint32_t(packed->params.border_texels);
  const gpu::TvtVtInfo info = make_vt_info(cfg, s.residency().page_table(), float(s.residency().mip_bias()));
  const auto gpu_info = read_buffer(ctx(), s.info_buffer());
  ASSERT_EQ(gpu_info.size(), sizeof(info));
  EXPECT_EQ(std::memcmp(gpu_info.data(), &info, sizeof(info)), 0);

  // Every resident page's slot holds exactly that page.
  const auto cache = read_cache(ctx(), s.cache());
  const size_t slot_bytes = size_t(s.cache().width()) * s.cache().height() * 4;
  auto reference = GpuComposer::create(ctx(), packed.value(), 8);
  ASSERT_TRUE(reference.ok());
  const auto resident = s.residency().resident_pages();
  std::vector<PageId> pages;
  for (const PageRequest& r : resident) pages.push_back(r.page);
  const auto direct = reference.value()->compose_pages(pages).value();
  ASSERT_GE(resident.size(), 12u);
  for (size_t i = 0; i < resident.size(); ++i)
    EXPECT_EQ(std::memcmp(cache.data() + resident[i].slot * slot_bytes, direct[i].data(), slot_bytes), 0)
        << to_string(resident[i].page) << " in slot " << resident[i].slot;
}

// The same deterministic flythrough with 1 and 3 frames in flight shows the same frames.
TEST_F(GpuFramesInFlight, DeterministicFlythroughIsTheSameForAnyDepth) {
  std::vector<std::vector<ImageRGBA8>> runs;
  for (uint32_t depth : {1u, 3u}) {
    FlythroughOptions o;
    o.frames = 10;
    o.width = 96;
    o.height = 54;
    o.fps = 2.0;
    o.feedback_divisor = 4;
    o.vt.cache_slots = 64;
    o.vt.page_budget = 6;
    o.vt.window_pages = 16;
    o.deterministic = true;
    o.frames_in_flight = depth;
    std::vector<ImageRGBA8> frames;
    auto s = run_flythrough(ctx(), assets14(), o, [&](const FlythroughFrame& f, const FlythroughViews& views) {
      if (f.index > 0) {
        EXPECT_EQ(f.feedback_frames_late, 1u);  // deterministic: always the previous frame
      }
      frames.push_back(views.frame());
      return true;
    });
    ASSERT_TRUE(s.ok()) << s.error().message;
    runs.push_back(std::move(frames));
  }
  ASSERT_EQ(runs[0].size(), runs[1].size());
  for (size_t i = 0; i < runs[0].size(); ++i) EXPECT_EQ(runs[0][i].texels, runs[1][i].texels) << "frame " << i;
}

// Without determinism the loop never waits for feedback: with K frames in flight it reads the
// compaction of frame f - K (complete once begin(f) returned), never older than f - K - 1.
TEST_F(GpuFramesInFlight, FeedbackIsAsLateAsTheDepthAndNoLater) {
  for (uint32_t depth : {1u, 3u}) {
    FlythroughOptions o;
    o.frames = 14;
    o.width = 96;
    o.height = 54;
    o.feedback_divisor = 4;
    o.vt.cache_slots = 64;
    o.vt.page_budget = 4;
    o.vt.window_pages = 16;
    o.frames_in_flight = depth;
    uint32_t within_depth = 0, with_feedback = 0;
    auto s = run_flythrough(ctx(), assets14(), o, [&](const FlythroughFrame& f, const FlythroughViews&) {
      if (f.feedback_frames_late == 0) return true;
      ++with_feedback;
      EXPECT_LE(f.feedback_frames_late, depth + 1) << "frame " << f.index;
      within_depth += f.feedback_frames_late <= depth;
      return true;
    });
    ASSERT_TRUE(s.ok()) << s.error().message;
    EXPECT_GE(with_feedback, o.frames - depth - 1) << "depth " << depth;
    EXPECT_GE(within_depth + 1, with_feedback) << "depth " << depth;  // one frame's slot may be found busy
  }
}

TEST_F(GpuFramesInFlight, BadDepthIsAnErrorNamingTheField) {
  auto ring = FrameRing::create(ctx(), 0);
  ASSERT_FALSE(ring.ok());
  EXPECT_NE(ring.error().message.find("frames_in_flight"), std::string::npos);
  auto packed = pack_scene(assets14(), options_for(Method::Linear));
  ASSERT_TRUE(packed.ok());
  SceneVtOptions o;
  o.frames_in_flight = 9;
  auto vt = create_vt_system(ctx(), packed.value(), o);
  ASSERT_FALSE(vt.ok());
  EXPECT_NE(vt.error().message.find("frames_in_flight"), std::string::npos);
}

TEST_F(GpuFramesInFlight, RingReportsEveryFrameOnceWithItsStagesInOrder) {
  auto ring = FrameRing::create(ctx(), 2);
  ASSERT_TRUE(ring.ok());
  FrameRing& r = *ring.value();
  vk::Buffer scratch = ctx().create_buffer(1 << 20, VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
  std::vector<FrameTiming> seen;
  for (uint64_t f = 10; f < 16; ++f) {
    VkCommandBuffer cmd = r.begin(f);
    EXPECT_TRUE(f < 12 || r.completed(f - 2));  // begin(f) saw frame f - 2 complete
    EXPECT_FALSE(r.completed(f));
    vkCmdFillBuffer(cmd, scratch.handle(), 0, VK_WHOLE_SIZE, uint32_t(f));
    r.mark();
    ctx().memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                                VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
    vkCmdFillBuffer(cmd, scratch.handle(), 0, VK_WHOLE_SIZE, ~uint32_t(f));
    r.mark();
    r.submit();
    for (const FrameTiming& t : r.take_completed()) seen.push_back(t);
  }
  r.wait_idle();
  for (const FrameTiming& t : r.take_completed()) seen.push_back(t);
  EXPECT_TRUE(r.completed(15));
  EXPECT_TRUE(r.take_completed().empty());  // each frame once
  uint32_t valid_bits = 0;
  {
    uint32_t n = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(ctx().physical_device(), &n, nullptr);
    std::vector<VkQueueFamilyProperties> p(n);
    vkGetPhysicalDeviceQueueFamilyProperties(ctx().physical_device(), &n, p.data());
    valid_bits = p[ctx().queue_family()].timestampValidBits;
  }
  if (valid_bits == 0) GTEST_SKIP() << "no timestamps on this queue";
  ASSERT_EQ(seen.size(), 6u);
  for (size_t i = 0; i < seen.size(); ++i) {
    EXPECT_EQ(seen[i].frame, 10 + i);
    ASSERT_EQ(seen[i].stage_ms.size(), 3u);
    double sum = 0;
    for (double ms : seen[i].stage_ms) {
      EXPECT_GE(ms, 0.0);
      sum += ms;
    }
    EXPECT_NEAR(sum, seen[i].gpu_ms, 1e-6 + 1e-9 * seen[i].gpu_ms);
    EXPECT_GT(seen[i].gpu_ms, 0.0);
    EXPECT_LT(seen[i].gpu_ms, 10000.0);
  }
}
