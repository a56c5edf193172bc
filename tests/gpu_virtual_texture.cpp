// terravt::VirtualTexture on a client's device, driven as an engine drives it: the client's
// command pool, command buffers and fences; terravt only records. The frame protocol's misuse
// cases are errors that change nothing.
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <vector>

#include "gpu/context.h"
#include "gpu/device_setup.h"
#include "shared/page_table_entry.h"
#include "terravt/compose.h"
#include "terravt/terravt.h"
#include "support/vt_client.h"

namespace tvt {
namespace {

terravt::VirtualTextureDesc small_desc() {
  terravt::VirtualTextureDesc d;  // the built-in scene
  d.cache_slots = 64;
  d.page_budget = 8;
  d.window_pages = 16;
  d.frames_in_flight = 2;
  return d;
}

TEST(VirtualTexture, ComposesTheRequestedPagesIntoTheClientsCommandBuffersAndMapsThem) {
  Client client(2);
  ASSERT_TRUE(client.device);
  auto created = terravt::compose::create_virtual_texture(client.h, small_desc());
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  const terravt::VirtualTextureInfo info = vt.info();
  ASSERT_GE(info.mip_count, 3u);
  const terravt::VirtualTextureBindings b = vt.bindings();
  EXPECT_NE(b.info_buffer, VK_NULL_HANDLE);
  EXPECT_NE(b.table_buffer, VK_NULL_HANDLE);
  EXPECT_NE(b.cache_view, VK_NULL_HANDLE);
  EXPECT_NE(b.cache_sampler, VK_NULL_HANDLE);

  // The camera at the centre asks for the mip-0 page there and one two mips up.
  const int64_t centre = int64_t(1) << (info.log2_size - 1);
  const uint32_t px = uint32_t(centre / info.page_texels);
  const std::vector<terravt::PageRequest> wanted = {{0, px, px, 10}, {2, px >> 2, px >> 2, 5}};
  uint32_t produced = 0;
  for (uint64_t f = 0; f < 6; ++f) {
    VkCommandBuffer cmd = client.begin(f);
    const std::optional<uint64_t> done = f >= 2 ? std::optional<uint64_t>(f - 2) : std::nullopt;
    ASSERT_TRUE(vt.begin_frame(f, done, centre, centre, wanted).ok());
    const terravt::Status s = vt.record(cmd);
    ASSERT_TRUE(s.ok()) << s.error().message;
    client.submit(f);
    produced += vt.stats().produced;
  }
  vkDeviceWaitIdle(client.h.device);
  EXPECT_GE(produced, 3u);  // the pinned top page, the two requested pages and their ancestors
  EXPECT_EQ(vt.stats().failed, 0u);

  // Read the page table back through a context of terravt's own on the same device.
  auto ctx = vk::Context::adopt(client.h);
  ASSERT_TRUE(ctx.ok()) << ctx.error().message;
  vk::Buffer readback = (*ctx)->create_buffer(b.table_bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  (*ctx)->run_commands([&](VkCommandBuffer cmd) {
    const VkBufferCopy region{0, 0, b.table_bytes};
    vkCmdCopyBuffer(cmd, b.table_buffer, readback.handle(), 1, &region);
    (*ctx)->memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                                VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
  });
  const auto* entries = static_cast<const uint32_t*>(readback.mapped());
  const size_t count = size_t(b.table_bytes / 4);
  // Every requested mip has at least one entry mapped to data of that very mip.
  for (const terravt::PageRequest& r : wanted) {
    size_t exact = 0;
    for (size_t i = 0; i < count; ++i)
      if (gpu::tvt_pte_valid(entries[i]) && gpu::tvt_pte_mip(entries[i]) == r.mip) ++exact;
    EXPECT_GE(exact, 1u) << "no page-table entry maps mip " << r.mip << " data";
  }
}

TEST(VirtualTexture, ARenderGraphPlacesTheHandedBackDependenciesItself) {
  Client client(2);
  ASSERT_TRUE(client.device);
  terravt::VirtualTextureDesc d = small_desc();
  d.consumer_stages = VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;
  d.record_barriers = false;
  auto created = terravt::compose::create_virtual_texture(client.h, d);
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  const terravt::VirtualTextureDependencies& dep = vt.dependencies();
  ASSERT_EQ(dep.before.sType, VK_STRUCTURE_TYPE_DEPENDENCY_INFO);
  ASSERT_EQ(dep.before.memoryBarrierCount, 1u);
  ASSERT_EQ(dep.after.memoryBarrierCount, 1u);
  const VkMemoryBarrier2& before = dep.before.pMemoryBarriers[0];
  const VkMemoryBarrier2& after = dep.after.pMemoryBarriers[0];
  // before: the consumers' earlier reads, then terravt's writes (execution only).
  EXPECT_EQ(before.srcStageMask, VkPipelineStageFlags2(d.consumer_stages));
  EXPECT_EQ(before.dstStageMask, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_TRANSFER_BIT);
  // after: terravt's writes made visible to the consumers' shader reads.
  EXPECT_EQ(after.srcStageMask, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_TRANSFER_BIT);
  EXPECT_EQ(after.srcAccessMask, VK_ACCESS_2_SHADER_WRITE_BIT | VK_ACCESS_2_TRANSFER_WRITE_BIT);
  EXPECT_EQ(after.dstStageMask, VkPipelineStageFlags2(d.consumer_stages));
  EXPECT_EQ(after.dstAccessMask, VkAccessFlags2(VK_ACCESS_2_SHADER_READ_BIT));

  // The graph places them around record(); frames run clean under synchronisation validation.
  const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
  const uint32_t px = uint32_t(centre / vt.info().page_texels);
  const terravt::PageRequest wanted[] = {{0, px, px, 1}};
  uint32_t produced = 0;
  for (uint64_t f = 0; f < 4; ++f) {
    VkCommandBuffer cmd = client.begin(f);
    ASSERT_TRUE(vt.begin_frame(f, f >= 2 ? std::optional<uint64_t>(f - 2) : std::nullopt, centre, centre, wanted).ok());
    vkCmdPipelineBarrier2(cmd, &dep.before);
    ASSERT_TRUE(vt.record(cmd).ok());
    vkCmdPipelineBarrier2(cmd, &dep.after);
    client.submit(f);
    produced += vt.stats().produced;
  }
  vkDeviceWaitIdle(client.h.device);
  EXPECT_GE(produced, 2u);
}

TEST(VirtualTexture, MisuseOfTheFrameProtocolIsAnErrorAndChangesNothing) {
  Client client(3);
  ASSERT_TRUE(client.device);
  auto created = terravt::compose::create_virtual_texture(client.h, small_desc());
  ASSERT_TRUE(created.ok()) << created.error().message;
  terravt::VirtualTexture& vt = **created;
  const auto expect_misuse = [](const terravt::Status& s, const char* piece) {
    ASSERT_FALSE(s.ok()) << piece;
    EXPECT_EQ(s.error().kind, terravt::ErrorKind::misuse) << s.error().message;
    EXPECT_NE(s.error().message.find(piece), std::string::npos) << s.error().message;
  };
  VkCommandBuffer cmd = client.begin(0);
  expect_misuse(vt.record(cmd), "no frame begun");
  ASSERT_TRUE(vt.begin_frame(0, std::nullopt, 0, 0, {}).ok());
  expect_misuse(vt.begin_frame(1, std::nullopt, 0, 0, {}), "record() did not follow");
  ASSERT_TRUE(vt.record(cmd).ok());
  expect_misuse(vt.record(cmd), "recorded already");
  client.submit(0);
  expect_misuse(vt.begin_frame(0, std::nullopt, 0, 0, {}), "frames must increase");
  expect_misuse(vt.begin_frame(1, 7, 0, 0, {}), "never begun");

  cmd = client.begin(1);
  ASSERT_TRUE(vt.begin_frame(1, std::nullopt, 0, 0, {}).ok());
  ASSERT_TRUE(vt.record(cmd).ok());
  client.submit(1);
  // Two frames begun, none known complete: a third would exceed frames_in_flight = 2.
  expect_misuse(vt.begin_frame(2, std::nullopt, 0, 0, {}), "at most 2 may be in flight");
  vkWaitForFences(client.h.device, 1, &client.fences[1], VK_TRUE, UINT64_MAX);
  cmd = client.begin(2);
  ASSERT_TRUE(vt.begin_frame(2, 1, 0, 0, {}).ok());
  ASSERT_TRUE(vt.record(cmd).ok());
  client.submit(2);
  expect_misuse(vt.begin_frame(3, 0, 0, 0, {}), "went backwards");

  // A request outside the VT names its index; camera positions beyond the terrain clamp.
  const terravt::PageRequest bad[] = {{0, 0, 0, 1}, {40, 0, 0, 1}};
  const terravt::Status s = vt.begin_frame(3, 2, -5, int64_t(1) << 40, bad);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().kind, terravt::ErrorKind::invalid_argument);
  EXPECT_NE(s.error().message.find("requests[1]"), std::string::npos) << s.error().message;
  cmd = client.begin(3);
  ASSERT_TRUE(vt.begin_frame(3, 2, -5, int64_t(1) << 40, {}).ok());
  ASSERT_TRUE(vt.record(cmd).ok());
  client.submit(3);
  vkDeviceWaitIdle(client.h.device);  // the contract: the GPU is done before the VT goes
}

TEST(VirtualTexture, CreateRefusesADeviceWithoutARequiredFeatureAndBadDescriptions) {
  Client client(1);
  ASSERT_TRUE(client.device);
  terravt::DeviceHandles h = client.h;
  VkPhysicalDeviceFeatures2 no_int64 = *h.enabled_features;
  no_int64.features.shaderInt64 = VK_FALSE;  // the same chain otherwise
  h.enabled_features = &no_int64;
  auto refused = terravt::compose::create_virtual_texture(h, small_desc());
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().kind, terravt::ErrorKind::unsupported_device);
  EXPECT_NE(refused.error().message.find("shaderInt64"), std::string::npos) << refused.error().message;

  terravt::VirtualTextureDesc d = small_desc();
  d.method = "nonsense";
  auto bad_method = terravt::compose::create_virtual_texture(client.h, d);
  ASSERT_FALSE(bad_method.ok());
  EXPECT_NE(bad_method.error().message.find("method"), std::string::npos) << bad_method.error().message;
  d = small_desc();
  d.mip_strategy = "supersample:3";
  auto bad_strategy = terravt::compose::create_virtual_texture(client.h, d);
  ASSERT_FALSE(bad_strategy.ok());
  EXPECT_EQ(bad_strategy.error().kind, terravt::ErrorKind::invalid_argument);
  EXPECT_NE(bad_strategy.error().message.find("VirtualTextureDesc::mip_strategy"), std::string::npos)
      << bad_strategy.error().message;
  d.mip_strategy = "supersample:4";  // a valid one is accepted
  EXPECT_TRUE(terravt::compose::create_virtual_texture(client.h, d).ok());
  d = small_desc();
  d.source = terravt::PageSource::stored;
  auto no_store = terravt::compose::create_virtual_texture(client.h, d);
  ASSERT_FALSE(no_store.ok());
  EXPECT_NE(no_store.error().message.find("store_file"), std::string::npos) << no_store.error().message;
  d.store_file = "/nonexistent/terravt.tvt";
  auto missing = terravt::compose::create_virtual_texture(client.h, d);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().kind, terravt::ErrorKind::io);
  d = small_desc();
  d.scene_file = "/nonexistent/scene.json";
  auto no_scene = terravt::compose::create_virtual_texture(client.h, d);
  ASSERT_FALSE(no_scene.ok());
  EXPECT_NE(no_scene.error().message.find("/nonexistent/scene.json"), std::string::npos) << no_scene.error().message;
}

}  // namespace
}  // namespace tvt
