// Bring your own device: terravt's requirements, the check of a client's device, adopting it
// (allocation callbacks, nothing of the client's destroyed), and the errors that name what is
// missing. The "client" here is an OwnedDevice, exactly what terravt's own tools adopt.
#include <gtest/gtest.h>

#include <embedded_shaders.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <unordered_map>

#include "gpu/device_setup.h"
#include "shared/test_types.h"
#include "support/counting_allocator.h"
#include "support/gpu_test.h"
#include "terravt/terravt.h"

namespace tvt {
namespace {

// A client's device with validation on; handles() are what the client hands terravt.
std::unique_ptr<vk::OwnedDevice> client_device() {
  vk::ContextOptions options;
  options.validation = true;
  if (const char* device = std::getenv("TERRAVT_DEVICE")) options.device = device;
  auto owned = vk::OwnedDevice::create(options);
  EXPECT_TRUE(owned.ok()) << owned.error().message;
  return owned ? std::move(owned).value() : nullptr;
}

void expect_no_messages(vk::OwnedDevice& device) {
  const std::vector<std::string> messages = device.messages();
  device.clear_messages();
  std::string all;
  for (const std::string& m : messages) all += "\n  " + m;
  EXPECT_TRUE(messages.empty()) << messages.size() << " Vulkan validation message(s):" << all;
}

// A copy of a feature chain (features2 -> 1.2 -> 1.3) that a test may change.
struct FeatureChain {
  VkPhysicalDeviceFeatures2 f2{};
  VkPhysicalDeviceVulkan12Features f12{};
  VkPhysicalDeviceVulkan13Features f13{};
  explicit FeatureChain(const VkPhysicalDeviceFeatures2* from = nullptr) {
    f2.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
    f12.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES;
    f13.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES;
    if (from) {
      f2.features = from->features;
      for (auto* s = static_cast<const VkBaseInStructure*>(from->pNext); s; s = s->pNext) {
        if (s->sType == f12.sType) f12 = *reinterpret_cast<const VkPhysicalDeviceVulkan12Features*>(s);
        if (s->sType == f13.sType) f13 = *reinterpret_cast<const VkPhysicalDeviceVulkan13Features*>(s);
      }
    }
    f2.pNext = &f12;
    f12.pNext = &f13;
    f13.pNext = nullptr;
  }
  FeatureChain(const FeatureChain&) = delete;
};

bool contains(const std::string& text, const std::string& piece) { return text.find(piece) != std::string::npos; }

TEST(DeviceRequirements, NameShaderInt64AndMaintenance4AsRequiredAndSayWhyForEveryFeature) {
  const terravt::DeviceRequirements r = terravt::device_requirements();
  EXPECT_EQ(r.min_api_version, uint32_t(VK_API_VERSION_1_3));
  EXPECT_TRUE(r.queue_flags & VK_QUEUE_COMPUTE_BIT);
  std::vector<std::string> required;
  for (const terravt::FeatureRequirement& f : r.features) {
    EXPECT_GT(std::strlen(f.why), 10u) << f.name;
    EXPECT_TRUE(std::strncmp(f.structure, "VkPhysicalDevice", 16) == 0) << f.name;
    if (f.required) required.push_back(f.name);
  }
  EXPECT_EQ(required, (std::vector<std::string>{"shaderInt64", "maintenance4"}));
}

TEST(DeviceRequirements, TheVersionMacrosMatchTheLibrary) {
  const terravt::Version v = terravt::version();
  EXPECT_EQ(v.major, TERRAVT_VERSION_MAJOR);
  EXPECT_EQ(v.minor, TERRAVT_VERSION_MINOR);
  EXPECT_EQ(v.patch, TERRAVT_VERSION_PATCH);
  EXPECT_STREQ(terravt::version_string(), TERRAVT_VERSION_STRING);
}

TEST(AdoptDevice, EnableDeviceFeaturesSwitchesOnWhatTerravtNeedsAndKeepsTheClientsOwn) {
  auto device = client_device();
  ASSERT_TRUE(device);
  const terravt::DeviceHandles h = device->handles();
  FeatureChain chain;
  chain.f12.hostQueryReset = VK_TRUE;  // the engine's own choice, supported everywhere in 1.2
  ASSERT_TRUE(terravt::enable_device_features(h.get_instance_proc_addr, h.instance, h.physical_device, chain.f2).ok());
  EXPECT_TRUE(chain.f2.features.shaderInt64);
  EXPECT_TRUE(chain.f13.maintenance4);
  EXPECT_TRUE(chain.f12.hostQueryReset);

  // A chain without the 1.3 struct cannot receive maintenance4: the error says what to add.
  VkPhysicalDeviceVulkan12Features only12{};
  only12.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES;
  VkPhysicalDeviceFeatures2 short_chain{};
  short_chain.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
  short_chain.pNext = &only12;
  auto refused = terravt::enable_device_features(h.get_instance_proc_addr, h.instance, h.physical_device, short_chain);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().kind, terravt::ErrorKind::invalid_argument);
  EXPECT_TRUE(contains(refused.error().message, "VkPhysicalDeviceVulkan13Features")) << refused.error().message;
}

TEST(AdoptDevice, ADeviceWithoutARequiredFeatureIsRefusedNamingTheFeature) {
  auto device = client_device();
  ASSERT_TRUE(device);
  terravt::DeviceHandles h = device->handles();
  ASSERT_TRUE(terravt::check_device(h).ok());
  {
    FeatureChain chain(h.enabled_features);
    chain.f2.features.shaderInt64 = VK_FALSE;
    h.enabled_features = &chain.f2;
    auto s = terravt::check_device(h);
    ASSERT_FALSE(s.ok());
    EXPECT_EQ(s.error().kind, terravt::ErrorKind::unsupported_device);
    EXPECT_TRUE(contains(s.error().message, "VkPhysicalDeviceFeatures::shaderInt64")) << s.error().message;
    auto adopted = vk::Context::adopt(h);
    ASSERT_FALSE(adopted.ok());
    EXPECT_TRUE(contains(adopted.error().message, "shaderInt64")) << adopted.error().message;
  }
  {
    FeatureChain chain(device->handles().enabled_features);
    chain.f12.pNext = nullptr;  // no VkPhysicalDeviceVulkan13Features at all
    h.enabled_features = &chain.f2;
    auto s = terravt::check_device(h);
    ASSERT_FALSE(s.ok());
    EXPECT_TRUE(contains(s.error().message, "VkPhysicalDeviceVulkan13Features::maintenance4")) << s.error().message;
  }
  expect_no_messages(*device);
}

TEST(AdoptDevice, MissingOrWrongHandlesAreNamed) {
  auto device = client_device();
  ASSERT_TRUE(device);
  struct Case {
    const char* what;
    void (*mutate)(terravt::DeviceHandles&);
    terravt::ErrorKind kind;
    const char* expected;
  };
  const Case cases[] = {
      {"no queue", [](terravt::DeviceHandles& h) { h.queue = VK_NULL_HANDLE; }, terravt::ErrorKind::invalid_argument,
       "DeviceHandles::queue"},
      {"no device", [](terravt::DeviceHandles& h) { h.device = VK_NULL_HANDLE; }, terravt::ErrorKind::invalid_argument,
       "DeviceHandles::device"},
      {"no entry point", [](terravt::DeviceHandles& h) { h.get_instance_proc_addr = nullptr; },
       terravt::ErrorKind::invalid_argument, "get_instance_proc_addr"},
      {"no feature chain", [](terravt::DeviceHandles& h) { h.enabled_features = nullptr; },
       terravt::ErrorKind::invalid_argument, "enabled_features"},
      {"bad queue family", [](terravt::DeviceHandles& h) { h.queue_family = 999; }, terravt::ErrorKind::invalid_argument,
       "queue_family 999"},
      {"old instance", [](terravt::DeviceHandles& h) { h.instance_api_version = VK_API_VERSION_1_2; },
       terravt::ErrorKind::unsupported_device, "Vulkan 1.2"},
  };
  for (const Case& c : cases) {
    terravt::DeviceHandles h = device->handles();
    c.mutate(h);
    auto s = terravt::check_device(h);
    ASSERT_FALSE(s.ok()) << c.what;
    EXPECT_EQ(s.error().kind, c.kind) << c.what;
    EXPECT_TRUE(contains(s.error().message, c.expected)) << c.what << ": " << s.error().message;
    EXPECT_FALSE(vk::Context::adopt(h).ok()) << c.what;
  }
}

TEST(AdoptDevice, AnAdoptedContextAllocatesThroughTheClientsCallbacksAndLeavesTheDeviceAlive) {
  auto device = client_device();
  ASSERT_TRUE(device);
  CountingAllocator counter;
  const VkAllocationCallbacks callbacks = counter.callbacks();
  terravt::DeviceHandles h = device->handles();
  h.allocation_callbacks = &callbacks;
  std::vector<std::string> logged;
  h.log = [&](terravt::LogLevel, std::string_view m) { logged.emplace_back(m); };
  {
    auto adopted = vk::Context::adopt(h);
    ASSERT_TRUE(adopted.ok()) << adopted.error().message;
    vk::Context& ctx = **adopted;
    EXPECT_EQ(ctx.device(), h.device);
    EXPECT_EQ(ctx.allocation_callbacks(), &callbacks);
    EXPECT_TRUE(ctx.features().shader_int64);
    EXPECT_FALSE(ctx.validation_enabled());  // the client's device: its messages are the client's

    // Every kind of object terravt makes, then a round trip on the client's queue.
    const uint32_t count = 4099;
    const vk::ComputeBinding bindings[] = {{0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
    vk::ComputePipeline pipeline =
        ctx.create_compute_pipeline(shaders::test_fill_comp(), bindings, sizeof(gpu::TvtTestFillPush));
    vk::DescriptorSet set = ctx.allocate_descriptor_set(pipeline);
    vk::Buffer values = ctx.create_buffer(VkDeviceSize(count) * 4,
                                          VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, false);
    vk::Buffer readback = ctx.create_buffer(VkDeviceSize(count) * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
    vk::Image image = ctx.create_image(VK_FORMAT_R8G8B8A8_UNORM, 64, 64, 2, VK_IMAGE_USAGE_SAMPLED_BIT);
    VkSamplerCreateInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO;
    const VkSampler sampler = ctx.create_sampler(si);
    set.write_buffer(0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, values);
    const gpu::TvtTestFillPush push{count, 12345u};
    ctx.run_commands([&](VkCommandBuffer cmd) {
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.handle());
      const VkDescriptorSet s = set.handle();
      vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout(), 0, 1, &s, 0, nullptr);
      vkCmdPushConstants(cmd, pipeline.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
      vkCmdDispatch(cmd, (count + gpu::TVT_TEST_FILL_GROUP - 1) / gpu::TVT_TEST_FILL_GROUP, 1, 1);
      ctx.memory_barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                                  VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
      const VkBufferCopy region{0, 0, VkDeviceSize(count) * 4};
      vkCmdCopyBuffer(cmd, values.handle(), readback.handle(), 1, &region);
      ctx.memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                                  VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
    });
    const auto* got = static_cast<const uint32_t*>(readback.mapped());
    EXPECT_NE(got[0], 0u);  // the fill shader wrote through the client's device
    ctx.destroy_sampler(sampler);
    EXPECT_GT(counter.allocations, 0u) << "nothing was allocated through the client's callbacks";
  }
  // Everything terravt allocated through the callbacks was freed through them...
  {
    std::lock_guard lock(counter.mutex);
    EXPECT_TRUE(counter.live.empty()) << counter.live.size() << " block(s) still allocated";
  }
  // ...and the client's device is untouched: still usable after the Context is gone.
  EXPECT_EQ(vkDeviceWaitIdle(h.device), VK_SUCCESS);
  VkBufferCreateInfo bci{};
  bci.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
  bci.size = 256;
  bci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  VkBuffer buffer = VK_NULL_HANDLE;
  EXPECT_EQ(vkCreateBuffer(h.device, &bci, nullptr, &buffer), VK_SUCCESS);
  vkDestroyBuffer(h.device, buffer, nullptr);
  EXPECT_TRUE(logged.empty());
  expect_no_messages(*device);
}

// The client's own Vulkan dispatch: a vkGetInstanceProcAddr that hands out the loader's
// functions, except that vkGetDeviceProcAddr is the client's, which wraps vkCreateBuffer,
// vkCmdDispatch and vkQueueSubmit in counters and can withhold one function by name. terravt
// must call Vulkan only through what this returns (its private table), never the loader's
// exports.
struct ClientDispatch {
  static inline int buffers = 0, dispatches = 0, submits = 0;
  static inline std::string withheld;

  // Each wrapper counts, then calls the loader's own export (the test links the loader).
  static VKAPI_ATTR VkResult VKAPI_CALL create_buffer(VkDevice d, const VkBufferCreateInfo* i,
                                                      const VkAllocationCallbacks* a, VkBuffer* b) {
    ++buffers;
    return vkCreateBuffer(d, i, a, b);
  }
  static VKAPI_ATTR void VKAPI_CALL dispatch(VkCommandBuffer c, uint32_t x, uint32_t y, uint32_t z) {
    ++dispatches;
    vkCmdDispatch(c, x, y, z);
  }
  static VKAPI_ATTR VkResult VKAPI_CALL submit(VkQueue q, uint32_t n, const VkSubmitInfo* s, VkFence f) {
    ++submits;
    return vkQueueSubmit(q, n, s, f);
  }
  static VKAPI_ATTR PFN_vkVoidFunction VKAPI_CALL gdpa(VkDevice device, const char* name) {
    const std::string n = name;
    if (n == withheld) return nullptr;
    if (n == "vkCreateBuffer") return reinterpret_cast<PFN_vkVoidFunction>(&create_buffer);
    if (n == "vkCmdDispatch") return reinterpret_cast<PFN_vkVoidFunction>(&dispatch);
    if (n == "vkQueueSubmit") return reinterpret_cast<PFN_vkVoidFunction>(&submit);
    return vkGetDeviceProcAddr(device, name);
  }
  static VKAPI_ATTR PFN_vkVoidFunction VKAPI_CALL gipa(VkInstance instance, const char* name) {
    const std::string n = name;
    if (n == withheld) return nullptr;
    if (n == "vkGetDeviceProcAddr") return reinterpret_cast<PFN_vkVoidFunction>(&gdpa);
    return vkGetInstanceProcAddr(instance, name);
  }
};

TEST(AdoptDevice, EveryVulkanCallGoesThroughTheClientsGetInstanceProcAddr) {
  auto device = client_device();
  ASSERT_TRUE(device);
  terravt::DeviceHandles h = device->handles();
  h.get_instance_proc_addr = &ClientDispatch::gipa;
  ClientDispatch::buffers = ClientDispatch::dispatches = ClientDispatch::submits = 0;
  ClientDispatch::withheld.clear();
  {
    auto adopted = vk::Context::adopt(h);
    ASSERT_TRUE(adopted.ok()) << adopted.error().message;
    vk::Context& ctx = **adopted;
    const uint32_t count = 1000;
    const vk::ComputeBinding bindings[] = {{0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
    vk::ComputePipeline pipeline =
        ctx.create_compute_pipeline(shaders::test_fill_comp(), bindings, sizeof(gpu::TvtTestFillPush));
    vk::DescriptorSet set = ctx.allocate_descriptor_set(pipeline);
    vk::Buffer values = ctx.create_buffer(VkDeviceSize(count) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    vk::Buffer more = ctx.create_buffer(256, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    EXPECT_EQ(ClientDispatch::buffers, 2);
    set.write_buffer(0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, values);
    const gpu::TvtTestFillPush push{count, 777u};
    // terravt's own recording helper (a barrier through its table) inside its own submission.
    ctx.run_commands([&](VkCommandBuffer cmd) {
      const auto& fn = ctx.fn();
      fn.vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.handle());
      const VkDescriptorSet s = set.handle();
      fn.vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout(), 0, 1, &s, 0, nullptr);
      fn.vkCmdPushConstants(cmd, pipeline.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
      fn.vkCmdDispatch(cmd, (count + gpu::TVT_TEST_FILL_GROUP - 1) / gpu::TVT_TEST_FILL_GROUP, 1, 1);
      ctx.memory_barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                         VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
    });
    EXPECT_EQ(ClientDispatch::dispatches, 1);
    EXPECT_EQ(ClientDispatch::submits, 1);
    EXPECT_NE(static_cast<const uint32_t*>(values.mapped())[0], 0u);
    EXPECT_TRUE(ctx.status().ok());
  }
  expect_no_messages(*device);

  // A function the client's dispatch does not provide is named, and nothing is adopted.
  for (const char* name : {"vkCmdDispatch", "vkGetPhysicalDeviceProperties2", "vkGetDeviceProcAddr"}) {
    ClientDispatch::withheld = name;
    auto refused = vk::Context::adopt(h);
    ASSERT_FALSE(refused.ok()) << name;
    EXPECT_EQ(refused.error().kind, terravt::ErrorKind::unsupported_device) << name;
    EXPECT_TRUE(contains(refused.error().message, name)) << refused.error().message;
  }
  ClientDispatch::withheld.clear();
}

}  // namespace
}  // namespace tvt
