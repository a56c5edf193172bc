// A failed Vulkan call is an error, never an abort. terravt::VirtualTexture runs on a client's
// device whose allocation callbacks refuse one host allocation, at points spread over create()
// and the first frames: the refused call fails with VK_ERROR_OUT_OF_HOST_MEMORY, and terravt
// returns that as ErrorKind::out_of_memory, keeps returning it, records nothing more and frees
// everything it allocated. A lost device is latched and returned the same way.
#include <gtest/gtest.h>

#include <optional>
#include <set>
#include <string>
#include <vector>

#include "compose/packed_scene.h"
#include "compose/scene_assets.h"
#include "gpu/context.h"
#include "composer/builtin_producers.h"
#include "render/vt_system.h"
#include "support/counting_allocator.h"
#include "support/vt_client.h"
#include "terravt/compose.h"
#include "terravt/terravt.h"

namespace tvt {
namespace {

terravt::VirtualTextureDesc small_desc() {
  terravt::VirtualTextureDesc d;  // the built-in scene, composed
  d.cache_slots = 32;
  d.page_budget = 8;
  d.window_pages = 8;
  d.frames_in_flight = 2;
  return d;
}

// What one run of create() + `frames` frames returned.
struct RunResult {
  std::optional<terravt::Error> first_error;  // the first error any call returned
  std::string where;                          // which call
  bool sticky = true;                         // every call after it returned the same error
  uint32_t produced = 0;
};

RunResult drive(Client& client, const terravt::DeviceHandles& h, uint64_t frames) {
  RunResult run;
  const auto note = [&](const terravt::Status& s, const std::string& call) {
    if (s.ok()) {
      if (run.first_error) {
        run.sticky = false;
        run.where += "; then " + call + " ok";
      }
      return;
    }
    if (!run.first_error) {
      run.first_error = s.error();
      run.where = call;
    } else if (s.error().message != run.first_error->message) {
      run.sticky = false;
      run.where += "; then " + call + ": " + s.error().message;
    }
  };
  auto created = terravt::compose::create_virtual_texture(h, small_desc());
  if (!created) {
    run.first_error = created.error();
    run.where = "create()";
    return run;
  }
  terravt::VirtualTexture& vt = **created;
  const int64_t centre = int64_t(1) << (vt.info().log2_size - 1);
  const uint32_t px = uint32_t(centre / vt.info().page_texels);
  const terravt::PageRequest wanted[] = {{0, px, px, 4}, {1, px / 2, px / 2, 2}, {3, px / 8, px / 8, 1}};
  for (uint64_t f = 0; f < frames; ++f) {
    VkCommandBuffer cmd = client.begin(f);
    note(vt.begin_frame(f, f >= 2 ? std::optional<uint64_t>(f - 2) : std::nullopt, centre, centre, wanted),
         "begin_frame(" + std::to_string(f) + ")");
    note(vt.record(cmd), "record(" + std::to_string(f) + ")");
    client.submit(f);  // also after an error: what was recorded is complete and valid
    run.produced += vt.stats().produced;
  }
  vkDeviceWaitIdle(h.device);
  return run;
}

// The validation layer reports each call that returned an error code (a short message naming
// the code); anything else it says is a real finding and stays for the Client to fail on.
void take_refusal_reports(vk::OwnedDevice& device, const std::string& what) {
  std::vector<std::string> others;
  for (const std::string& m : device.messages())
    if (m.find("VK_ERROR_OUT_OF_HOST_MEMORY") == std::string::npos || m.size() > 80) others.push_back(m);
  device.clear_messages();
  for (const std::string& m : others) ADD_FAILURE() << what << ": validation: " << m;
}

TEST(VulkanFailures, AHostAllocationRefusedAnywhereIsAnOutOfMemoryErrorThatStaysAndLeaksNothing) {
  Client client(2);
  ASSERT_TRUE(client.device);
  CountingAllocator counter;
  const VkAllocationCallbacks callbacks = counter.callbacks();
  terravt::DeviceHandles h = client.h;
  h.allocation_callbacks = &callbacks;

  // Unrefused, to count the allocations a run makes.
  counter.restart(0);
  const RunResult clean = drive(client, h, 4);
  ASSERT_FALSE(clean.first_error) << clean.where << ": " << clean.first_error->message;
  EXPECT_GE(clean.produced, 3u);
  const size_t total = counter.allocations;
  ASSERT_GE(total, 20u) << "terravt should allocate through the client's callbacks";
  EXPECT_EQ(counter.outstanding(), 0u);

  // The first few allocations one by one (the context, pools, the first buffers), then points
  // spread evenly up to the last.
  std::set<size_t> points;
  for (size_t n = 1; n <= 8; ++n) points.insert(n);
  for (size_t i = 1; i <= 24; ++i) points.insert(1 + (total - 1) * i / 24);
  size_t failed_runs = 0;
  std::set<std::string> places;
  for (size_t at : points) {
    counter.restart(at);
    const RunResult run = drive(client, h, 4);
    const std::string what = "allocation " + std::to_string(at) + " of " + std::to_string(total) + " refused";
    EXPECT_EQ(counter.outstanding(), 0u) << what << ": terravt leaked through the client's callbacks";
    take_refusal_reports(*client.device, what);
    if (counter.refused == 0) continue;  // the run took another path and made fewer allocations
    if (!run.first_error) continue;      // the driver absorbed the refusal (a cache, a retry)
    ++failed_runs;
    places.insert(run.where.substr(0, run.where.find('(')));
    EXPECT_EQ(run.first_error->kind, terravt::ErrorKind::out_of_memory) << what << ": " << run.first_error->message;
    EXPECT_EQ(run.first_error->vk_result, int32_t(VK_ERROR_OUT_OF_HOST_MEMORY)) << what;
    EXPECT_NE(run.first_error->message.find("VK_ERROR_OUT_OF_HOST_MEMORY"), std::string::npos)
        << what << ": " << run.first_error->message;
    EXPECT_TRUE(run.sticky) << what << ": a later call did not return the same error (" << run.where << "): "
                               << run.first_error->message;
  }
  RecordProperty("allocations_per_run", std::to_string(total));
  RecordProperty("runs_that_failed", std::to_string(failed_runs));
  EXPECT_GE(failed_runs, points.size() / 2) << "most refused allocations must surface as errors";
  EXPECT_TRUE(places.contains("create")) << "no refusal was reported by create()";

  // The client's device is untouched: the same VT runs clean on it afterwards.
  counter.restart(0);
  const RunResult after = drive(client, h, 3);
  EXPECT_FALSE(after.first_error) << after.where << ": " << after.first_error->message;
}

TEST(VulkanFailures, ALostDeviceIsLatchedAndReturnedByEveryLaterCall) {
  Client client(2);
  ASSERT_TRUE(client.device);
  auto adopted = vk::Context::adopt(client.h);
  ASSERT_TRUE(adopted.ok()) << adopted.error().message;
  vk::Context& ctx = **adopted;
  ASSERT_TRUE(ctx.status().ok());
  auto assets = load_scene_assets(default_scene());
  ASSERT_TRUE(assets.ok());
  auto packed = pack_scene(assets.value(), options_for(Method::FbpbDpt));
  ASSERT_TRUE(packed.ok());
  SceneVtOptions o;
  o.cache_slots = 32;
  o.page_budget = 8;
  o.window_pages = 8;
  ctx.defer_setup();
  auto vt = create_vt_system(ctx, packed.value(), o);
  ASSERT_TRUE(vt.ok()) << vt.error().message;

  // What a queue submission or a fence wait returns when the device is lost.
  EXPECT_FALSE(ctx.ok(VK_ERROR_DEVICE_LOST, "vkQueueSubmit(queue, 1, &si, fence)"));
  const Status s = ctx.status();
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().kind, terravt::ErrorKind::device_lost);
  EXPECT_EQ(s.error().vk_result, int32_t(VK_ERROR_DEVICE_LOST));
  EXPECT_EQ(s.error().message, "Vulkan: vkQueueSubmit failed with VK_ERROR_DEVICE_LOST");
  // The first failure stays; a later one does not replace it.
  EXPECT_FALSE(ctx.ok(VK_ERROR_OUT_OF_DEVICE_MEMORY, "vkAllocateMemory(...)"));
  EXPECT_EQ(ctx.status().error().kind, terravt::ErrorKind::device_lost);

  // Creation hands back empty handles, and the runtime records nothing and returns the error.
  EXPECT_FALSE(ctx.create_buffer(256, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true));
  EXPECT_FALSE(ctx.create_image(VK_FORMAT_R8G8B8A8_UNORM, 8, 8, 1, VK_IMAGE_USAGE_SAMPLED_BIT));
  VkCommandBuffer cmd = client.begin(0);
  (*vt)->begin_frame(1, 0, 0, {});
  const Status recorded = (*vt)->record(cmd);
  ASSERT_FALSE(recorded.ok());
  EXPECT_EQ(recorded.error().kind, terravt::ErrorKind::device_lost);
  client.submit(0);  // empty: nothing of terravt's was recorded
  EXPECT_FALSE(create_vt_system(ctx, packed.value(), o).ok());
  vkDeviceWaitIdle(client.h.device);
}

}  // namespace
}  // namespace tvt
