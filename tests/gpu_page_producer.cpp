// A client's own page producer plugged into terravt::VirtualTexture (terravt/page_producer.h):
// the client's compute shader writes a checkerboard into the slots terravt hands it, terravt
// maps them. Checked slot by slot on read-back, with the page table; a producer's failures and
// contract breaches are errors that leave the frame usable and the ancestors standing in.
#include <gtest/gtest.h>

#include <embedded_shaders.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <functional>
#include <map>
#include <set>
#include <vector>

#include "gpu/context.h"
#include "shared/feedback_types.h"
#include "shared/page_table_entry.h"
#include "support/vt_client.h"
#include "terravt/terravt.h"

namespace tvt {
namespace {

using terravt::PageTask;

struct CheckerPush {
  uint32_t mip, x, y, slot, page_texels, border_texels;
};

// What shaders/test_checker_producer.comp writes at texel (i, j) of `t`'s layer.
std::array<uint8_t, 4> checker_texel(const PageTask& t, uint32_t page, uint32_t border, uint32_t i, uint32_t j) {
  const int64_t gx = int64_t(t.x) * page + i - border, gy = int64_t(t.y) * page + j - border;
  if ((((gx >> 3) ^ (gy >> 3)) & 1) != 0) return {0, 0, 0, 255};
  return {uint8_t(16 * t.mip), 255, uint8_t(t.slot % 256), 128};
}

// The client's producer: accepts up to `per_frame` pages a frame and writes each `delay`
// frames after it was accepted (0: in the same frame), with its own compute pipeline.
class CheckerProducer final : public terravt::PageProducer {
 public:
  explicit CheckerProducer(VkDevice device) : device_(device) {}
  ~CheckerProducer() override {
    vkDestroyPipeline(device_, pipeline_, nullptr);
    vkDestroyPipelineLayout(device_, layout_, nullptr);
    vkDestroyDescriptorPool(device_, pool_, nullptr);
    vkDestroyDescriptorSetLayout(device_, set_layout_, nullptr);
  }

  uint32_t per_frame = 1000, delay = 0;
  uint32_t wants_per_frame = 0;  // requests_per_frame(): 0, the VT's page budget
  terravt::Error failure{terravt::ErrorKind::io, "the checkerboard disk is on fire"};  // record()'s, with failed pages
  uint32_t most_offered = 0;     // the most request() calls in one frame
  std::function<bool(const PageTask&)> fails;        // these are reported failed
  std::function<bool(const PageTask&)> unavailable;  // these are refused for good
  std::vector<PageTask> extra_written;               // reported written without a request (contract breach)
  std::map<uint32_t, PageTask> in_slot;              // what each slot holds now
  uint32_t cancelled = 0;
  terravt::ProducerTarget target;
  std::function<void(VkCommandBuffer)> on_record;    // called first thing in record()
  std::vector<PageTask> pending_tasks() const {
    std::vector<PageTask> out;
    for (const Pending& p : pending_) out.push_back(p.task);
    return out;
  }

  terravt::Status attach(const terravt::ProducerTarget& t) override {
    target = t;
    const VkDescriptorSetLayoutBinding b{0, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
    VkDescriptorSetLayoutCreateInfo dli{};
    dli.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
    dli.bindingCount = 1;
    dli.pBindings = &b;
    vkCreateDescriptorSetLayout(device_, &dli, nullptr, &set_layout_);
    const VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(CheckerPush)};
    VkPipelineLayoutCreateInfo pli{};
    pli.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
    pli.setLayoutCount = 1;
    pli.pSetLayouts = &set_layout_;
    pli.pushConstantRangeCount = 1;
    pli.pPushConstantRanges = &range;
    vkCreatePipelineLayout(device_, &pli, nullptr, &layout_);
    const std::span<const uint32_t> spirv = shaders::test_checker_producer_comp();
    VkShaderModuleCreateInfo mi{};
    mi.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
    mi.codeSize = spirv.size_bytes();
    mi.pCode = spirv.data();
    VkShaderModule module = VK_NULL_HANDLE;
    vkCreateShaderModule(device_, &mi, nullptr, &module);
    VkComputePipelineCreateInfo ci{};
    ci.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
    ci.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    ci.stage.module = module;
    ci.stage.pName = "main";
    ci.layout = layout_;
    const VkResult made = vkCreateComputePipelines(device_, VK_NULL_HANDLE, 1, &ci, nullptr, &pipeline_);
    vkDestroyShaderModule(device_, module, nullptr);
    if (made != VK_SUCCESS) return terravt::Error{terravt::ErrorKind::vulkan, "checker pipeline", int32_t(made)};
    const VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1};
    VkDescriptorPoolCreateInfo pi{};
    pi.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
    pi.maxSets = 1;
    pi.poolSizeCount = 1;
    pi.pPoolSizes = &size;
    vkCreateDescriptorPool(device_, &pi, nullptr, &pool_);
    VkDescriptorSetAllocateInfo ai{};
    ai.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
    ai.descriptorPool = pool_;
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &set_layout_;
    vkAllocateDescriptorSets(device_, &ai, &set_);
    const VkDescriptorImageInfo image{VK_NULL_HANDLE, t.cache_view, VK_IMAGE_LAYOUT_GENERAL};
    VkWriteDescriptorSet w{};
    w.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
    w.dstSet = set_;
    w.descriptorCount = 1;
    w.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
    w.pImageInfo = &image;
    vkUpdateDescriptorSets(device_, 1, &w, 0, nullptr);
    return terravt::Ok{};
  }
  uint32_t requests_per_frame() const override { return wants_per_frame; }
  void begin_frame(uint64_t frame) override {
    frame_ = frame;
    accepted_ = offered_ = 0;
  }
  terravt::ProducerAccept request(const PageTask& t) override {
    most_offered = std::max(most_offered, ++offered_);
    if (unavailable && unavailable(t)) return terravt::ProducerAccept::unavailable;
    if (accepted_ >= per_frame) return terravt::ProducerAccept::busy;
    ++accepted_;
    pending_.push_back({t, frame_ + delay});
    return terravt::ProducerAccept::accepted;
  }
  void cancel(const PageTask& t) override {
    std::erase_if(pending_, [&](const Pending& p) { return p.task == t; });
    ++cancelled;
  }
  void finish() override {
    for (Pending& p : pending_) p.due = frame_;
  }
  terravt::Status record(VkCommandBuffer cmd, std::vector<PageTask>& written, std::vector<PageTask>& failed) override {
    if (on_record) on_record(cmd);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_, 0, 1, &set_, 0, nullptr);
    std::vector<Pending> later;
    for (const Pending& p : pending_) {
      if (p.due > frame_) {
        later.push_back(p);
      } else if (fails && fails(p.task)) {
        failed.push_back(p.task);
      } else {
        const CheckerPush push{p.task.mip, p.task.x, p.task.y, p.task.slot, target.page_texels, target.border_texels};
        vkCmdPushConstants(cmd, layout_, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
        const uint32_t groups = (target.slot_texels + 7) / 8;
        vkCmdDispatch(cmd, groups, groups, 1);
        written.push_back(p.task);
        in_slot[p.task.slot] = p.task;
      }
    }
    pending_ = std::move(later);
    written.insert(written.end(), extra_written.begin(), extra_written.end());
    extra_written.clear();
    if (!failed.empty()) return failure;
    return terravt::Ok{};
  }

 private:
  struct Pending {
    PageTask task;
    uint64_t due = 0;
  };
  VkDevice device_;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  std::vector<Pending> pending_;
  uint64_t frame_ = 0;
  uint32_t accepted_ = 0, offered_ = 0;
};

terravt::VirtualTextureDesc producer_desc(std::shared_ptr<CheckerProducer> producer) {
  terravt::VirtualTextureDesc d;  // no scene: libterravt alone, the geometry given
  d.layout = {16, 128, 4};
  d.cache_slots = 48;
  d.page_budget = 16;
  d.window_pages = 16;
  d.frames_in_flight = 2;
  d.producer = std::move(producer);
  return d;
}

// A 3x3 block of mip-0 pages at the centre and the mip-2 page above it.
std::vector<terravt::PageRequest> centre_requests(const terravt::VirtualTextureInfo& info, int64_t centre) {
  const uint32_t px = uint32_t(centre / info.page_texels);
  std::vector<terravt::PageRequest> r;
  for (uint32_t dy = 0; dy < 3; ++dy)
    for (uint32_t dx = 0; dx < 3; ++dx) r.push_back({0, px - 1 + dx, px - 1 + dy, 4});
  r.push_back({2, px >> 2, px >> 2, 1});
  return r;
}

struct Frames {
  std::vector<terravt::Status> records;
  uint32_t produced = 0, failed = 0;
};

Frames run_frames(Client& client, terravt::VirtualTexture& vt, std::span<const terravt::PageRequest> wanted, uint64_t frames,
               uint64_t first = 0) {
  Frames run;
  const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
  for (uint64_t f = first; f < first + frames; ++f) {
    VkCommandBuffer cmd = client.begin(f);
    const terravt::Status begun =
        vt.begin_frame(f, f >= 2 ? std::optional<uint64_t>(f - 2) : std::nullopt, centre, centre, wanted);
    EXPECT_TRUE(begun.ok()) << begun.error().message;
    run.records.push_back(vt.record(cmd));
    client.submit(f);
    run.produced += vt.stats().produced;
    run.failed += vt.stats().failed;
  }
  vkDeviceWaitIdle(client.h.device);
  return run;
}

TEST(PageProducer, TheClientsComputeShaderFillsEveryPageTheViewAsksForSlotBySlot) {
  Client client(2);
  ASSERT_TRUE(client.device);
  auto producer = std::make_shared<CheckerProducer>(client.h.device);
  producer->delay = 1;     // asynchronous: a page lands the frame after it was accepted ...
  producer->per_frame = 4; // ... and only four are taken a frame (busy beyond)
  auto created = terravt::VirtualTexture::create(client.h, producer_desc(producer));
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  const terravt::ProducerTarget& t = producer->target;
  ASSERT_NE(t.cache, VK_NULL_HANDLE);
  EXPECT_EQ(t.slots, 48u);
  EXPECT_EQ(t.slot_texels, t.page_texels + 2 * t.border_texels);

  const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
  const std::vector<terravt::PageRequest> wanted = centre_requests(vt.info(), centre);
  const Frames run = run_frames(client, vt, wanted, 16);
  for (const terravt::Status& s : run.records) EXPECT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(run.failed, 0u);
  EXPECT_EQ(run.produced, producer->in_slot.size());  // no slot was reused: the cache is big enough

  const Readback r = read_back(client, vt, t);
  // Every slot the producer wrote holds exactly its checkerboard, borders included.
  for (const auto& [slot, task] : producer->in_slot) {
    const uint8_t* layer = r.cache.data() + size_t(slot) * t.slot_texels * t.slot_texels * 4;
    size_t wrong = 0;
    for (uint32_t j = 0; j < t.slot_texels; ++j)
      for (uint32_t i = 0; i < t.slot_texels; ++i) {
        const auto want = checker_texel(task, t.page_texels, t.border_texels, i, j);
        wrong += std::memcmp(layer + (size_t(j) * t.slot_texels + i) * 4, want.data(), 4) != 0;
      }
    EXPECT_EQ(wrong, 0u) << "slot " << slot << " (mip " << task.mip << " page " << task.x << ", " << task.y << ")";
  }
  // Every mapped entry points at a slot holding data of the mip it says; every requested page
  // (and the ancestors terravt added) was produced and is mapped.
  std::set<std::pair<uint32_t, uint32_t>> mapped;  // (slot, mip)
  for (uint32_t e : r.entries) {
    if (!gpu::tvt_pte_valid(e)) continue;
    const auto it = producer->in_slot.find(gpu::tvt_pte_slot(e));
    ASSERT_NE(it, producer->in_slot.end()) << "an entry maps slot " << gpu::tvt_pte_slot(e) << ", never written";
    EXPECT_EQ(it->second.mip, gpu::tvt_pte_mip(e));
    mapped.insert({it->first, it->second.mip});
  }
  for (const terravt::PageRequest& w : wanted) {
    const auto it = std::find_if(producer->in_slot.begin(), producer->in_slot.end(), [&](const auto& s) {
      return s.second.mip == w.mip && s.second.x == w.x && s.second.y == w.y;
    });
    ASSERT_NE(it, producer->in_slot.end()) << "mip " << w.mip << " page " << w.x << ", " << w.y << " never produced";
    EXPECT_TRUE(mapped.contains({it->first, w.mip})) << "mip " << w.mip << " page " << w.x << ", " << w.y << " not mapped";
  }
}

TEST(PageProducer, AProducerSaysHowManyPagesItWantsOfferedAFrame) {
  for (const uint32_t wants : {0u, 3u, 40u, 1000u}) {
    Client client(2);
    ASSERT_TRUE(client.device);
    auto producer = std::make_shared<CheckerProducer>(client.h.device);
    producer->wants_per_frame = wants;
    producer->delay = 2;  // pages stay outstanding: the residency keeps offering more
    auto created = terravt::VirtualTexture::create(client.h, producer_desc(producer));
    ASSERT_TRUE(created.ok()) << created.error().message;
    terravt::VirtualTexture& vt = **created;
    // Every mip-0 page of a 16 x 16 block: far more than any frame's offer.
    const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
    const uint32_t px = uint32_t(centre / vt.info().page_texels);
    std::vector<terravt::PageRequest> wanted;
    for (uint32_t dy = 0; dy < 16; ++dy)
      for (uint32_t dx = 0; dx < 16; ++dx) wanted.push_back({0, px - 8 + dx, px - 8 + dy, 1});
    const Frames run = run_frames(client, vt, wanted, 6);
    for (const terravt::Status& s : run.records) EXPECT_TRUE(s.ok()) << s.error().message;
    // 0: the page budget (16); otherwise what it asked for, at most the cache's 48 slots.
    const uint32_t expected = wants == 0 ? 16u : std::min(wants, 48u);
    EXPECT_EQ(producer->most_offered, expected) << "requests_per_frame() " << wants;
  }
}

TEST(PageProducer, AFailingProducerLeavesTheAncestorsStandingInAndTheFramesGoOn) {
  Client client(2);
  ASSERT_TRUE(client.device);
  auto producer = std::make_shared<CheckerProducer>(client.h.device);
  producer->fails = [](const PageTask& t) { return t.mip == 0; };        // reported failed, with an error
  producer->unavailable = [](const PageTask& t) { return t.mip == 1; };  // refused outright
  auto created = terravt::VirtualTexture::create(client.h, producer_desc(producer));
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
  const std::vector<terravt::PageRequest> wanted = centre_requests(vt.info(), centre);
  const Frames run = run_frames(client, vt, wanted, 8);

  // The frames whose pages failed hand back the producer's error; every frame is complete.
  const auto failing = std::find_if(run.records.begin(), run.records.end(), [](const terravt::Status& s) { return !s.ok(); });
  ASSERT_NE(failing, run.records.end());
  EXPECT_EQ(failing->error().kind, terravt::ErrorKind::producer_failed);
  EXPECT_NE(failing->error().message.find("the checkerboard disk is on fire"), std::string::npos);
  EXPECT_GE(run.failed, 9u + 1u);  // the nine mip-0 pages, and at least one refused mip-1 page
  EXPECT_GT(run.produced, 0u);     // mip 2 and above

  const Readback r = read_back(client, vt, producer->target);
  size_t valid = 0;
  for (uint32_t e : r.entries) {
    if (!gpu::tvt_pte_valid(e)) continue;
    ++valid;
    EXPECT_GE(gpu::tvt_pte_mip(e), 2u) << "an entry maps data of a mip the producer never made";
  }
  EXPECT_GT(valid, 0u);
}

TEST(PageProducer, OnlyAFailedVulkanCallOfTheProducerStaysLatched) {
  // Host memory running out (no VkResult) is the producer's failure of those pages: the next
  // frames go on. A failed Vulkan call of the producer's is the device's: it stays.
  for (const bool vulkan : {false, true}) {
    Client client(2);
    ASSERT_TRUE(client.device);
    auto producer = std::make_shared<CheckerProducer>(client.h.device);
    producer->fails = [](const PageTask& t) { return t.mip == 0; };
    producer->failure = vulkan ? terravt::Error{terravt::ErrorKind::out_of_memory, "vkAllocateMemory",
                                                int32_t(VK_ERROR_OUT_OF_DEVICE_MEMORY)}
                               : terravt::Error{terravt::ErrorKind::out_of_memory, "std::bad_alloc reading a page"};
    auto created = terravt::VirtualTexture::create(client.h, producer_desc(producer));
    ASSERT_TRUE(created.ok()) << created.error().message;
    terravt::VirtualTexture& vt = **created;
    const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
    const std::vector<terravt::PageRequest> wanted = centre_requests(vt.info(), centre);
    if (vulkan) {
      // Frames until record() fails; from then on every call returns the same error.
      std::optional<terravt::Error> latched;
      for (uint64_t f = 0; f < 6; ++f) {
        VkCommandBuffer cmd = client.begin(f);
        const terravt::Status begun =
            vt.begin_frame(f, f >= 2 ? std::optional<uint64_t>(f - 2) : std::nullopt, centre, centre, wanted);
        const terravt::Status recorded = begun.ok() ? vt.record(cmd) : begun;
        client.submit(f);
        if (latched) {
          EXPECT_FALSE(begun.ok()) << "frame " << f << " began after the producer's Vulkan failure";
          EXPECT_EQ(recorded.error().message, latched->message);
        } else if (!recorded.ok()) {
          latched = recorded.error();
        }
      }
      ASSERT_TRUE(latched);
      EXPECT_EQ(latched->kind, terravt::ErrorKind::out_of_memory);
      EXPECT_EQ(latched->vk_result, int32_t(VK_ERROR_OUT_OF_DEVICE_MEMORY));
    } else {
      const Frames run = run_frames(client, vt, wanted, 6);
      const auto first = std::find_if(run.records.begin(), run.records.end(), [](const terravt::Status& s) { return !s.ok(); });
      ASSERT_NE(first, run.records.end());
      EXPECT_EQ(first->error().kind, terravt::ErrorKind::producer_failed) << first->error().message;
      EXPECT_NE(first->error().message.find("std::bad_alloc"), std::string::npos);
      // Frames after it still record (the failed mip-0 pages are retried after a back-off).
      EXPECT_TRUE(std::any_of(first + 1, run.records.end(), [](const terravt::Status& s) { return s.ok(); }));
    }
    vkDeviceWaitIdle(client.h.device);
  }
}

TEST(PageProducer, AReportOfAPageItWasNotHandedIsMisuseAndIgnored) {
  Client client(2);
  ASSERT_TRUE(client.device);
  auto producer = std::make_shared<CheckerProducer>(client.h.device);
  auto created = terravt::VirtualTexture::create(client.h, producer_desc(producer));
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
  const std::vector<terravt::PageRequest> wanted = centre_requests(vt.info(), centre);
  run_frames(client, vt, wanted, 2);
  // A page nobody asked for, in a slot that is not free: reported as written.
  producer->extra_written.push_back(PageTask{0, 1, 1, 0});
  const Frames run = run_frames(client, vt, {}, 1, 2);
  ASSERT_FALSE(run.records[0].ok());
  EXPECT_EQ(run.records[0].error().kind, terravt::ErrorKind::misuse);
  EXPECT_NE(run.records[0].error().message.find("mip 0 page (1, 1) slot 0"), std::string::npos)
      << run.records[0].error().message;
}

// A report that aliases a page the producer accepted (the same packed id, another mip) is
// caught field by field: misuse, ignored, and the real page still lands when it is done.
TEST(PageProducer, AReportAliasingAnAcceptedPageIsMisuseAndTheRealPageStillLands) {
  Client client(2);
  ASSERT_TRUE(client.device);
  auto producer = std::make_shared<CheckerProducer>(client.h.device);
  auto created = terravt::VirtualTexture::create(client.h, producer_desc(producer));
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
  const std::vector<terravt::PageRequest> wanted = centre_requests(vt.info(), centre);
  run_frames(client, vt, {}, 2);  // the pinned pages
  producer->delay = 3;            // accepted now, written three frames later
  run_frames(client, vt, wanted, 1, 2);
  const std::vector<PageTask> pending = producer->pending_tasks();
  ASSERT_FALSE(pending.empty());
  for (uint32_t mip_shift : {64u, 128u}) {
    PageTask alias = pending[0];
    alias.mip += mip_shift;  // PageId::pack() keeps 6 bits of mip: this packs like pending[0]
    producer->extra_written.push_back(alias);
  }
  const Frames run = run_frames(client, vt, wanted, 1, 3);
  ASSERT_FALSE(run.records[0].ok());
  EXPECT_EQ(run.records[0].error().kind, terravt::ErrorKind::misuse) << run.records[0].error().message;
  const Frames rest = run_frames(client, vt, wanted, 4, 4);
  for (const terravt::Status& s : rest.records) EXPECT_TRUE(s.ok()) << s.error().message;
  const bool landed = std::any_of(producer->in_slot.begin(), producer->in_slot.end(), [&](const auto& s) {
    return s.second == pending[0];
  });
  EXPECT_TRUE(landed);
}

// A producer's callback may not call back into the VirtualTexture: misuse, and the outer call
// completes as usual.
TEST(PageProducer, AProducerCallingBackIntoTheVirtualTextureIsMisuse) {
  Client client(2);
  ASSERT_TRUE(client.device);
  auto producer = std::make_shared<CheckerProducer>(client.h.device);
  auto created = terravt::VirtualTexture::create(client.h, producer_desc(producer));
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  std::vector<terravt::Status> inner;
  producer->on_record = [&](VkCommandBuffer cmd) {
    inner.push_back(vt.record(cmd));
    inner.push_back(vt.begin_frame(100, std::nullopt, 0, 0, {}));
  };
  const Frames run = run_frames(client, vt, {}, 2);
  for (const terravt::Status& s : run.records) EXPECT_TRUE(s.ok()) << s.error().message;
  ASSERT_EQ(inner.size(), 4u);
  for (const terravt::Status& s : inner) {
    ASSERT_FALSE(s.ok());
    EXPECT_EQ(s.error().kind, terravt::ErrorKind::misuse);
    EXPECT_NE(s.error().message.find("inside another VirtualTexture call"), std::string::npos) << s.error().message;
  }
  EXPECT_GE(run.produced, 1u);
}

TEST(PageProducer, FeedbackWrittenOnTheGpuIsCompactedThereAndAsksForItsPages) {
  Client client(2);
  ASSERT_TRUE(client.device);
  auto producer = std::make_shared<CheckerProducer>(client.h.device);
  terravt::VirtualTextureDesc d = producer_desc(producer);
  d.feedback_texels = 256;
  auto created = terravt::VirtualTexture::create(client.h, d);
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  const terravt::VirtualTextureInfo info = vt.info();
  const int64_t centre = int64_t(1) << (info.log2_size - 1);
  const uint32_t px = uint32_t(centre / info.page_texels);
  // What the client's pass would have written with terravt_feedback(): 100 texels want the
  // mip-0 page at the centre, 50 a mip-3 page elsewhere, the rest nothing.
  const PageTask a{0, px, px, 0}, b{3, (px >> 3) + 1, px >> 3, 0};
  auto ctx = vk::Context::adopt(client.h);
  ASSERT_TRUE(ctx.ok()) << ctx.error().message;
  vk::Buffer feedback = (*ctx)->create_buffer(256 * 8, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  auto* words = static_cast<uint32_t*>(feedback.mapped());
  for (uint32_t i = 0; i < 256; ++i) {
    const PageTask* t = i < 100 ? &a : i < 150 ? &b : nullptr;
    words[2 * i] = t ? gpu::tvt_feedback_word0(t->mip, t->x) : gpu::TVT_FEEDBACK_EMPTY_WORD;
    words[2 * i + 1] = t ? gpu::tvt_feedback_word1(t->y) : gpu::TVT_FEEDBACK_EMPTY_WORD;
  }

  uint32_t most_feedback_pages = 0;
  for (uint64_t f = 0; f < 10; ++f) {
    VkCommandBuffer cmd = client.begin(f);
    // Even frames find the previous frame complete (the queue drained); odd ones know only
    // f - 2, the frame the even one before them knew already: no newer compaction.
    if (f % 2 == 0) vkQueueWaitIdle(client.h.queue);
    const std::optional<uint64_t> completed =
        f < 2 ? std::nullopt : std::optional<uint64_t>(f % 2 == 0 ? f - 1 : f - 2);
    ASSERT_TRUE(vt.begin_frame(f, completed, centre, centre, {}).ok());
    most_feedback_pages = std::max(most_feedback_pages, vt.stats().feedback_pages);
    EXPECT_EQ(vt.stats().gpu_feedback, f >= 2) << "frame " << f;
    if (f >= 2) {
      // The newest completed frame's feedback; an odd frame reuses its even predecessor's
      // (the same frame's compaction), so the view's pages are asked for at every frame.
      EXPECT_EQ(vt.stats().feedback_frame, *completed) << "frame " << f;
      EXPECT_EQ(vt.stats().feedback_pages, 2u) << "frame " << f;
    }
    ASSERT_TRUE(vt.record(cmd).ok());
    // An offset the device cannot bind a storage buffer at is refused; nothing is recorded.
    if (const VkDeviceSize align = (*ctx)->properties().limits.minStorageBufferOffsetAlignment; align > 1) {
      const terravt::Status misaligned = vt.record_feedback(cmd, feedback.handle(), align / 2);
      ASSERT_FALSE(misaligned.ok());
      EXPECT_EQ(misaligned.error().kind, terravt::ErrorKind::invalid_argument);
      EXPECT_NE(misaligned.error().message.find("minStorageBufferOffsetAlignment"), std::string::npos)
          << misaligned.error().message;
    }
    const terravt::Status fed = vt.record_feedback(cmd, feedback.handle());
    ASSERT_TRUE(fed.ok()) << fed.error().message;
    const terravt::Status twice = vt.record_feedback(cmd, feedback.handle());
    ASSERT_FALSE(twice.ok());
    EXPECT_EQ(twice.error().kind, terravt::ErrorKind::misuse);
    client.submit(f);
  }
  vkDeviceWaitIdle(client.h.device);
  EXPECT_EQ(most_feedback_pages, 2u);
  for (const PageTask& want : {a, b}) {
    const bool made = std::any_of(producer->in_slot.begin(), producer->in_slot.end(), [&](const auto& s) {
      return s.second.mip == want.mip && s.second.x == want.x && s.second.y == want.y;
    });
    EXPECT_TRUE(made) << "mip " << want.mip << " page " << want.x << ", " << want.y << " asked for by GPU feedback";
  }
}

TEST(PageProducer, GpuFeedbackNeedsFeedbackTexelsAtCreate) {
  Client client(2);
  ASSERT_TRUE(client.device);
  auto created = terravt::VirtualTexture::create(client.h, producer_desc(std::make_shared<CheckerProducer>(client.h.device)));
  ASSERT_TRUE(created.ok()) << created.error().message;
  const terravt::Status s = (*created)->record_feedback(VK_NULL_HANDLE, VK_NULL_HANDLE);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().kind, terravt::ErrorKind::misuse);
  EXPECT_NE(s.error().message.find("feedback_texels"), std::string::npos) << s.error().message;
}

}  // namespace
}  // namespace tvt
