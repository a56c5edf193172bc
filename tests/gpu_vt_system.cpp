// VtSystem end to end without a renderer: feedback in, pages composed into cache slots, the
// GPU page table scattered — checked against the CPU table and against directly composed pages.
#include <gtest/gtest.h>

#include <cstring>
#include <map>

#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "composer/builtin_producers.h"
#include "render/vt_system.h"
#include "support/gpu_test.h"

using namespace tvt;

namespace {

std::vector<uint32_t> read_entries(vk::Context& ctx, const vk::Buffer& entries) {
  vk::Buffer host = ctx.create_buffer(entries.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  ctx.run_commands([&](VkCommandBuffer cmd) {
    const VkBufferCopy copy{0, 0, entries.size()};
    vkCmdCopyBuffer(cmd, entries.handle(), host.handle(), 1, &copy);
  });
  std::vector<uint32_t> out(entries.size() / 4);
  std::memcpy(out.data(), host.mapped(), entries.size());
  return out;
}

std::vector<uint8_t> read_slot(vk::Context& ctx, const vk::Image& cache, uint32_t slot) {
  const VkDeviceSize bytes = VkDeviceSize(cache.width()) * cache.height() * 4;
  vk::Buffer host = ctx.create_buffer(bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  ctx.run_commands([&](VkCommandBuffer cmd) {
    ctx.transition(cmd, cache, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, slot, 1};
    region.imageExtent = {cache.width(), cache.height(), 1};
    vkCmdCopyImageToBuffer(cmd, cache.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host.handle(), 1, &region);
    ctx.transition(cmd, cache, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL);
  });
  const auto* p = static_cast<const uint8_t*>(host.mapped());
  return std::vector<uint8_t>(p, p + bytes);
}

}  // namespace

class GpuVtSystem : public GpuTest {};

TEST_F(GpuVtSystem, FeedbackBecomesResidentComposedPagesAndAMatchingGpuTable) {
  SceneDesc d = default_scene();
  d.vt.log2_size = 14;  // 128 x 128 pages at mip 0, 8 mips
  auto assets = load_scene_assets(d);
  ASSERT_TRUE(assets.ok()) << assets.error().message;
  auto packed = pack_scene(assets.value(), options_for(Method::FbpbDpt));
  ASSERT_TRUE(packed.ok());
  SceneVtOptions o;
  o.cache_slots = 48;
  o.window_pages = 16;
  o.page_budget = 12;
  auto vt = create_vt_system(ctx(), packed.value(), o);
  ASSERT_TRUE(vt.ok()) << vt.error().message;
  VtSystem& s = *vt.value();

  // A camera near texel (5000, 7000) asking for a 3x3 block of mip-0 pages and one mip-2 page.
  std::vector<PageFeedback> feedback;
  for (uint32_t j = 0; j < 3; ++j)
    for (uint32_t i = 0; i < 3; ++i) feedback.push_back({PageId{0, 38 + i, 54 + j}, 100});
  feedback.push_back({PageId{2, 3, 4}, 50});
  uint64_t composed = 0;
  for (uint64_t frame = 1; frame <= 6; ++frame) {
    s.begin_frame(frame, 5000, 7000, feedback);
    ctx().run_commands([&](VkCommandBuffer cmd) { TVT_CHECK(s.record(cmd).ok()); });
    s.end_frame();
    composed += s.stats().composed;
    EXPECT_LE(s.stats().composed, o.page_budget);
  }
  // Every requested page and its ancestors are resident: 9 + 4 (mip 1) + ... pages.
  for (const PageFeedback& f : feedback) {
    for (PageId p = f.page; p.mip < 8; p = p.parent()) EXPECT_TRUE(s.residency().is_resident(p)) << to_string(p);
  }
  EXPECT_GT(composed, 9u);
  // The GPU table equals the CPU table bit for bit.
  const auto gpu_entries = read_entries(ctx(), s.entry_buffer());
  const auto cpu_entries = s.residency().page_table().all_entries();
  ASSERT_EQ(gpu_entries.size(), cpu_entries.size());
  EXPECT_TRUE(std::equal(cpu_entries.begin(), cpu_entries.end(), gpu_entries.begin()));
  // Each resident page's slot holds exactly what composing that page directly gives.
  auto reference = GpuComposer::create(ctx(), packed.value(), 4);
  ASSERT_TRUE(reference.ok());
  int checked = 0;
  for (const PageRequest& r : s.residency().resident_pages()) {
    if (r.page.mip > 1 && checked > 4) continue;
    const PageId pages[] = {r.page};
    const auto direct = reference.value()->compose_pages(pages).value();
    EXPECT_EQ(read_slot(ctx(), s.cache(), r.slot), direct[0]) << to_string(r.page);
    ++checked;
  }
  EXPECT_GE(checked, 9);
}
