// GPU feedback compaction (render/feedback_compactor.h) against the CPU reference
// compact_feedback(): bit for bit after sorting, overflow reporting, and the readback ring.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <thread>

#include "render/feedback_compactor.h"
#include "support/feedback_images.h"
#include "support/gpu_test.h"
#include "vt/feedback_analysis.h"

using namespace tvt;

namespace {

VtConfig vt_config(uint32_t log2_size, uint32_t page_texels) {
  VtConfig c;
  c.log2_size = log2_size;
  c.page_texels = page_texels;
  c.border_texels = 4;
  return c;
}

class GpuFeedback : public GpuTest {
 protected:
  vk::Buffer upload_feedback(const std::vector<uint32_t>& words) {
    vk::Buffer b = ctx().create_buffer(words.size() * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                                             VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
    ctx().upload(b, words.data(), words.size() * 4);
    return b;
  }

  std::unique_ptr<FeedbackCompactor> make(const FeedbackCompactor::Options& o) {
    auto c = FeedbackCompactor::create(ctx(), o);
    EXPECT_TRUE(c.ok()) << (c.ok() ? "" : c.error().message);
    return c.ok() ? std::move(c.value()) : nullptr;
  }

  // Compacts `words` as frame `frame` on the GPU and checks the result against the CPU.
  void expect_matches_cpu(FeedbackCompactor& compactor, const std::vector<uint32_t>& words, uint64_t frame,
                          const std::string& what) {
    const vk::Buffer feedback = upload_feedback(words);
    ASSERT_TRUE(compactor.submit(feedback, frame)) << what;
    const std::optional<FeedbackResult> got = compactor.read_blocking(frame);
    ASSERT_TRUE(got.has_value()) << what;
    FeedbackStats stats;
    const auto want = compact_feedback(words, &stats);
    EXPECT_EQ(got->frame, frame) << what;
    EXPECT_FALSE(got->overflow) << what;
    EXPECT_EQ(got->overflow_texels, 0u) << what;
    EXPECT_EQ(got->pages.size(), want.size()) << what;
    EXPECT_TRUE(got->pages == want) << what;
    uint64_t sum = 0;
    for (const auto& p : got->pages) sum += p.second;
    EXPECT_EQ(sum, stats.texels - stats.empty_texels) << what;
  }
};

TEST_F(GpuFeedback, MatchesCpuOnRandomImages) {
  struct Case {
    uint32_t width, height, distinct, run, capacity;
    VtConfig vt;
  };
  const Case cases[] = {
      {160, 90, 37, 1, 256, vt_config(24, 16)},         // small page set, incoherent
      {320, 180, 37, 6, 256, vt_config(24, 16)},        // small page set, runs
      {160, 90, 0, 1, 32768, vt_config(24, 16)},        // any page of V = 2^24: ~all distinct
      {320, 180, 0, 1, 131072, vt_config(24, 16)},
      {320, 180, 0, 12, 16384, vt_config(24, 128)},     // any page, spatially coherent
      {320, 180, 2000, 1, 4096, vt_config(30, 16)},
      {161, 91, 37, 3, 256, vt_config(24, 16)},         // texel count not a multiple of 8 or 64      // widest valid VT: 2^26 pages per side
  };
  for (const Case& c : cases) {
    FeedbackCompactor::Options o;
    o.feedback_width = c.width;
    o.feedback_height = c.height;
    o.table_capacity = c.capacity;
    auto compactor = make(o);
    ASSERT_TRUE(compactor);
    for (uint64_t seed = 1; seed <= 3; ++seed) {
      test::FeedbackImageSpec spec;
      spec.width = c.width;
      spec.height = c.height;
      spec.vt = c.vt;
      spec.distinct = c.distinct;
      spec.run = c.run;
      spec.empty_fraction = 0.1 * double(seed);
      spec.seed = seed * 1000 + c.width + c.distinct;
      const std::string what = std::to_string(c.width) + "x" + std::to_string(c.height) + " distinct " +
                                std::to_string(c.distinct) + " run " + std::to_string(c.run) + " seed " +
                                std::to_string(seed);
      // Frames run through the ring and reuse one table: the gather pass must leave it empty.
      expect_matches_cpu(*compactor, test::random_feedback_image(spec), seed - 1, what);
    }
  }
}

TEST_F(GpuFeedback, AllEmptyAndSinglePageImages) {
  FeedbackCompactor::Options o;
  o.feedback_width = 64;
  o.feedback_height = 32;
  o.table_capacity = 64;
  o.max_probes = 64;
  auto compactor = make(o);
  ASSERT_TRUE(compactor);
  std::vector<uint32_t> sky(64 * 32 * 2, 0xffffffffu);
  expect_matches_cpu(*compactor, sky, 0, "sky");
  const auto t = feedback_texel(PageId{7, (1u << 27) - 1, 0});
  std::vector<uint32_t> one(64 * 32 * 2);
  for (size_t i = 0; i < one.size(); i += 2) {
    one[i] = t[0];
    one[i + 1] = t[1];
  }
  expect_matches_cpu(*compactor, one, 1, "single page");
}

// Adversarial for the two-word claim: many pages share word0 (same mip and x) and race for the
// same slots, differing only in word1; also the converse (same y, different x).
TEST_F(GpuFeedback, PagesSharingOneKeyWordStayDistinct) {
  FeedbackCompactor::Options o;
  o.feedback_width = 320;
  o.feedback_height = 180;
  o.table_capacity = 512;
  auto compactor = make(o);
  ASSERT_TRUE(compactor);
  for (uint64_t frame = 0; frame < 4; ++frame) {
    std::vector<uint32_t> words(size_t(o.feedback_width) * o.feedback_height * 2);
    uint32_t state = uint32_t(frame) * 7919u + 1u;
    for (size_t i = 0; i < words.size(); i += 2) {
      state = state * 1664525u + 1013904223u;
      const uint32_t v = (state >> 8) % 200u;
      const PageId p = frame % 2 ? PageId{3, 5, v} : PageId{3, v, 77};
      const auto t = v == 199u ? k_feedback_empty_texel : feedback_texel(p);
      words[i] = t[0];
      words[i + 1] = t[1];
    }
    expect_matches_cpu(*compactor, words, frame, "shared word, frame " + std::to_string(frame));
  }
}

TEST_F(GpuFeedback, ReportsOverflowWhenTheTableIsTooSmallAndRecovers) {
  FeedbackCompactor::Options o;
  o.feedback_width = 160;
  o.feedback_height = 90;
  o.table_capacity = 64;
  o.max_probes = 64;
  auto compactor = make(o);
  ASSERT_TRUE(compactor);
  test::FeedbackImageSpec spec;
  spec.width = 160;
  spec.height = 90;
  spec.vt = vt_config(24, 16);
  spec.distinct = 500;
  spec.seed = 77;
  const auto words = test::random_feedback_image(spec);
  const vk::Buffer feedback = upload_feedback(words);
  ASSERT_TRUE(compactor->submit(feedback, 0));
  const auto got = compactor->read_blocking(0);
  ASSERT_TRUE(got.has_value());
  FeedbackStats stats;
  const auto want = compact_feedback(words, &stats);
  ASSERT_GT(want.size(), 64u);
  EXPECT_TRUE(got->overflow);
  EXPECT_GT(got->overflow_texels, 0u);
  // The table is full; every page that got an entry has its exact count (all texels of a page
  // take the same probing decisions), and no texel is lost: stored + overflow = non-empty.
  EXPECT_EQ(got->pages.size(), 64u);
  uint64_t sum = got->overflow_texels;
  for (const auto& p : got->pages) {
    sum += p.second;
    const auto it = std::lower_bound(want.begin(), want.end(), p);
    ASSERT_TRUE(it != want.end() && *it == p) << to_string(p.first) << " count " << p.second;
  }
  EXPECT_EQ(sum, stats.texels - stats.empty_texels);

  // A bounded probe also overflows before the table is full.
  o.table_capacity = 1024;
  o.max_probes = 1;
  auto short_probes = make(o);
  ASSERT_TRUE(short_probes);
  ASSERT_TRUE(short_probes->submit(feedback, 0));
  const auto bounded = short_probes->read_blocking(0);
  ASSERT_TRUE(bounded.has_value());
  EXPECT_TRUE(bounded->overflow);
  EXPECT_LT(bounded->pages.size(), want.size());

  // The next frame on the overflowed compactor (table reset by the gather pass) is exact.
  spec.distinct = 40;
  spec.seed = 78;
  expect_matches_cpu(*compactor, test::random_feedback_image(spec), 1, "after overflow");
}

TEST_F(GpuFeedback, RejectsBadOptionsByName) {
  FeedbackCompactor::Options o;
  o.table_capacity = 1000;
  auto c = FeedbackCompactor::create(ctx(), o);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find("table_capacity"), std::string::npos);
  o = FeedbackCompactor::Options{};
  o.max_probes = 0;
  EXPECT_NE(FeedbackCompactor::create(ctx(), o).error().message.find("max_probes"), std::string::npos);
  o = FeedbackCompactor::Options{};
  o.ring_size = 0;
  EXPECT_NE(FeedbackCompactor::create(ctx(), o).error().message.find("ring_size"), std::string::npos);
  o = FeedbackCompactor::Options{};
  o.feedback_height = 0;
  EXPECT_NE(FeedbackCompactor::create(ctx(), o).error().message.find("feedback_width"), std::string::npos);
}

// The GPU is held back by an event only the host sets: until then the ring must report nothing
// for the frame, and must refuse (not wait) to reuse the frame's slot.
TEST_F(GpuFeedback, RingNeverReturnsAResultBeforeItsFenceSignalled) {
  FeedbackCompactor::Options o;
  o.feedback_width = 160;
  o.feedback_height = 90;
  o.table_capacity = 1024;
  o.ring_size = 3;
  auto compactor = make(o);
  ASSERT_TRUE(compactor);
  test::FeedbackImageSpec spec;
  spec.distinct = 100;
  spec.vt = vt_config(24, 128);
  spec.seed = 5;
  const auto words0 = test::random_feedback_image(spec);
  spec.seed = 6;
  const auto words1 = test::random_feedback_image(spec);
  const vk::Buffer feedback0 = upload_feedback(words0);
  const vk::Buffer feedback1 = upload_feedback(words1);
  const VkDevice device = ctx().device();

  VkEventCreateInfo eci{};
  eci.sType = VK_STRUCTURE_TYPE_EVENT_CREATE_INFO;
  VkEvent event = VK_NULL_HANDLE;
  ASSERT_EQ(vkCreateEvent(device, &eci, nullptr, &event), VK_SUCCESS);
  VkCommandPoolCreateInfo pci{};
  pci.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
  pci.queueFamilyIndex = ctx().queue_family();
  VkCommandPool pool = VK_NULL_HANDLE;
  ASSERT_EQ(vkCreateCommandPool(device, &pci, nullptr, &pool), VK_SUCCESS);
  VkCommandBufferAllocateInfo cai{};
  cai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
  cai.commandPool = pool;
  cai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  cai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  ASSERT_EQ(vkAllocateCommandBuffers(device, &cai, &cmd), VK_SUCCESS);

  VkCommandBufferBeginInfo bi{};
  bi.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  ASSERT_EQ(vkBeginCommandBuffer(cmd, &bi), VK_SUCCESS);
  vkCmdWaitEvents(cmd, 1, &event, VK_PIPELINE_STAGE_HOST_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, nullptr, 0, nullptr,
                  0, nullptr);
  const VkFence fence = compactor->record(cmd, feedback0, 0);
  ASSERT_NE(fence, VK_NULL_HANDLE);
  ASSERT_EQ(vkEndCommandBuffer(cmd), VK_SUCCESS);
  VkSubmitInfo si{};
  si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  ASSERT_EQ(vkQueueSubmit(ctx().queue(), 1, &si, fence), VK_SUCCESS);
  // Frame 1 queues behind frame 0 on the same queue, in the compactor's own command buffer.
  ASSERT_TRUE(compactor->submit(feedback1, 1));

  for (int i = 0; i < 20; ++i) {
    EXPECT_FALSE(compactor->try_read(0).has_value());
    EXPECT_FALSE(compactor->try_read(1).has_value());
    EXPECT_EQ(vkGetFenceStatus(device, fence), VK_NOT_READY);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_FALSE(compactor->try_read(2).has_value());  // never recorded
  // Frame 3 maps to frame 0's slot, which is in flight: skipped, nothing recorded, no wait.
  const auto before = std::chrono::steady_clock::now();
  EXPECT_FALSE(compactor->submit(feedback1, 3));
  EXPECT_LT(std::chrono::steady_clock::now() - before, std::chrono::milliseconds(500));

  ASSERT_EQ(vkSetEvent(device, event), VK_SUCCESS);
  const auto r1 = compactor->read_blocking(1);
  ASSERT_TRUE(r1.has_value());
  EXPECT_EQ(vkGetFenceStatus(device, fence), VK_SUCCESS);  // same queue: frame 0 finished first
  const auto r0 = compactor->try_read(0);
  ASSERT_TRUE(r0.has_value());
  EXPECT_EQ(r0->frame, 0u);
  EXPECT_EQ(r1->frame, 1u);
  EXPECT_TRUE(r0->pages == compact_feedback(words0));
  EXPECT_TRUE(r1->pages == compact_feedback(words1));
  EXPECT_TRUE(compactor->try_read(0).has_value());  // readable until the slot is reused

  // Frame 3 may now reuse slot 0; afterwards frame 0 is gone and frame 3 is there.
  ASSERT_TRUE(compactor->submit(feedback1, 3));
  const auto r3 = compactor->read_blocking(3);
  ASSERT_TRUE(r3.has_value());
  EXPECT_TRUE(r3->pages == r1->pages);
  EXPECT_FALSE(compactor->try_read(0).has_value());

  vkDestroyCommandPool(device, pool, nullptr);
  vkDestroyEvent(device, event, nullptr);
}

// A frame loop that never waits: submit every frame, read frame - (R - 1) when ready. How many
// results arrive inside the loop depends on the device's speed, so the loop only checks that
// every result that does arrive is correct for its frame. What does not depend on speed is
// checked after it: the first R submissions find free slots, and the last R frames submitted
// are still in the ring, each readable once its own fence signalled, with its own pages.
TEST_F(GpuFeedback, FrameLoopReadsResultsLateWithoutWaiting) {
  FeedbackCompactor::Options o;
  o.feedback_width = 160;
  o.feedback_height = 90;
  o.table_capacity = 1024;
  auto compactor = make(o);
  ASSERT_TRUE(compactor);
  std::vector<std::vector<uint32_t>> images;
  std::vector<vk::Buffer> buffers;
  for (uint64_t f = 0; f < 4; ++f) {
    test::FeedbackImageSpec spec;
    spec.distinct = 30 + uint32_t(f) * 40;
    spec.run = 4;
    spec.vt = vt_config(20, 128);
    spec.seed = 100 + f;
    images.push_back(test::random_feedback_image(spec));
    buffers.push_back(upload_feedback(images.back()));
  }
  const uint64_t frames = 24;
  const uint64_t late = o.ring_size - 1;
  std::vector<uint64_t> submitted;
  for (uint64_t f = 0; f < frames + late; ++f) {
    if (f < frames && compactor->submit(buffers[f % 4], f)) submitted.push_back(f);
    if (f < late) continue;
    if (auto r = compactor->try_read(f - late)) {
      EXPECT_EQ(r->frame, f - late);
      EXPECT_TRUE(r->pages == compact_feedback(images[(f - late) % 4])) << "frame " << f - late;
    }
  }
  ASSERT_GE(submitted.size(), size_t(o.ring_size));
  for (uint64_t f = 0; f < o.ring_size; ++f) EXPECT_EQ(submitted[f], f);  // free slots never refuse
  // The last ring_size submissions occupy distinct slots (consecutive frames would; skipped
  // frames may share one: then only the later is kept).
  for (size_t i = submitted.size() - o.ring_size; i < submitted.size(); ++i) {
    const uint64_t f = submitted[i];
    const bool overwritten = std::any_of(submitted.begin() + long(i) + 1, submitted.end(),
                                         [&](uint64_t later) { return later % o.ring_size == f % o.ring_size; });
    if (overwritten) continue;
    const auto r = compactor->read_blocking(f);
    ASSERT_TRUE(r.has_value()) << "frame " << f;
    EXPECT_EQ(r->frame, f);
    EXPECT_TRUE(r->pages == compact_feedback(images[f % 4])) << "frame " << f;
    EXPECT_TRUE(compactor->try_read(f).has_value()) << "frame " << f;  // complete now: no wait needed
  }
  ctx().wait_idle();
}

// Cost of one 320x180 compaction on this device; recorded as a test property (no output).
TEST_F(GpuFeedback, TimesA320x180Compaction) {
  FeedbackCompactor::Options o;
  auto compactor = make(o);
  ASSERT_TRUE(compactor);
  test::FeedbackImageSpec spec;
  spec.width = 320;
  spec.height = 180;
  spec.vt = vt_config(24, 128);
  spec.distinct = 600;
  spec.run = 8;
  spec.seed = 9;
  const auto words = test::random_feedback_image(spec);
  const vk::Buffer feedback = upload_feedback(words);
  const double seconds = compactor->time_compaction(feedback, 20);
  EXPECT_GT(seconds, 0.0);
  RecordProperty("compaction_320x180_us", std::to_string(int(seconds * 1e6)));
  const auto start = std::chrono::steady_clock::now();
  FeedbackStats stats;
  const auto want = compact_feedback(words, &stats);
  const double cpu = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  RecordProperty("cpu_reference_320x180_us", std::to_string(int(cpu * 1e6)));
  expect_matches_cpu(*compactor, words, 1000, "timed image");
}

}  // namespace
