// Vulkan context: creation, device choice, buffers, images, compute, uploads, RAII and the
// validation-message sink. Runs on lavapipe in CI with VK_LAYER_KHRONOS_validation on.
#include <gtest/gtest.h>

#include <embedded_shaders.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "shared/test_types.h"
#include "support/gpu_test.h"

using namespace tvt;
using tvt::gpu::TvtTestFillPush;
using tvt::gpu::TvtTestImagePush;

namespace {

// Sets an environment variable for one scope and restores the previous value.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value) {
      ::setenv(name, value, 1);
    } else {
      ::unsetenv(name);
    }
  }
  ~ScopedEnv() {
    if (old_) {
      ::setenv(name_, old_->c_str(), 1);
    } else {
      ::unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};


// Copies a whole device buffer into a new host-visible buffer and returns its bytes.
std::vector<unsigned char> read_back(vk::Context& ctx, const vk::Buffer& src) {
  vk::Buffer host = ctx.create_buffer(src.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  ctx.run_commands([&](VkCommandBuffer cmd) {
    ctx.memory_barrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_ACCESS_MEMORY_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
            VK_ACCESS_TRANSFER_READ_BIT);
    const VkBufferCopy region{0, 0, src.size()};
    vkCmdCopyBuffer(cmd, src.handle(), host.handle(), 1, &region);
    ctx.memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
            VK_ACCESS_HOST_READ_BIT);
  });
  const auto* p = static_cast<const unsigned char*>(host.mapped());
  return {p, p + src.size()};
}

// splitmix64: seeded, reproducible test bytes.
uint64_t splitmix64(uint64_t& state) {
  uint64_t z = (state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

std::string upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::toupper(c)); });
  return s;
}

std::string physical_device_name(VkPhysicalDevice pd) {
  VkPhysicalDeviceProperties p{};
  vkGetPhysicalDeviceProperties(pd, &p);
  return p.deviceName;
}

}  // namespace

TEST_F(GpuTest, CreatesAVulkan13ContextWithValidationAndReportsTheDevice) {
  EXPECT_TRUE(ctx().validation_enabled());
  EXPECT_FALSE(ctx().device_name().empty());
  EXPECT_GE(ctx().properties().apiVersion, uint32_t(VK_API_VERSION_1_3));
  EXPECT_NE(ctx().device(), VK_NULL_HANDLE);
  EXPECT_NE(ctx().queue(), VK_NULL_HANDLE);
  EXPECT_TRUE(ctx().features().shader_int64);
  EXPECT_TRUE(ctx().features().maintenance4);
  RecordProperty("vulkan_device", ctx().device_name());
  std::printf("Vulkan device: %s (synchronization2 %d, dynamicRendering %d, scalarBlockLayout %d)\n",
              ctx().device_name().c_str(), ctx().features().synchronization2, ctx().features().dynamic_rendering,
              ctx().features().scalar_block_layout);

  // The enabled features really are on: the device reports them when queried.
  VkPhysicalDeviceVulkan13Features f13{};
  f13.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES;
  VkPhysicalDeviceFeatures2 f2{};
  f2.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
  f2.pNext = &f13;
  vkGetPhysicalDeviceFeatures2(ctx().physical_device(), &f2);
  EXPECT_EQ(ctx().features().synchronization2, f13.synchronization2 == VK_TRUE);
  EXPECT_EQ(ctx().features().dynamic_rendering, f13.dynamicRendering == VK_TRUE);
}

namespace {

// test_fill.comp over `count` values: values[i] = i * i ^ xor_value (mod 2^32).
struct FillJob {
  FillJob(vk::Context& c, uint32_t n, uint32_t xor_value)
      : count(n), push{n, xor_value}, pipeline(c.create_compute_pipeline(shaders::test_fill_comp(), bindings, sizeof(push))),
        values(c.create_buffer(VkDeviceSize(n) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, false)),
        set(c.allocate_descriptor_set(pipeline)) {
    set.write_buffer(0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, values);
  }
  // Records the fill `dispatches` times over.
  void record(VkCommandBuffer cmd, uint32_t dispatches = 1) const {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.handle());
    const VkDescriptorSet s = set.handle();
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout(), 0, 1, &s, 0, nullptr);
    vkCmdPushConstants(cmd, pipeline.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
    for (uint32_t r = 0; r < dispatches; ++r)
      vkCmdDispatch(cmd, (count + gpu::TVT_TEST_FILL_GROUP - 1) / gpu::TVT_TEST_FILL_GROUP, 1, 1);
  }
  // Reads the values back; the number that differ from i * i ^ xor_value (the first few are
  // reported as failures).
  size_t wrong_values(vk::Context& c) const {
    const std::vector<unsigned char> bytes = read_back(c, values);
    EXPECT_EQ(bytes.size(), size_t(count) * 4);
    if (bytes.size() != size_t(count) * 4) return count;
    size_t wrong = 0;
    for (uint32_t i = 0; i < count; ++i) {
      uint32_t got = 0;
      std::memcpy(&got, bytes.data() + size_t(i) * 4, 4);
      const uint32_t want = (i * i) ^ push.xor_value;  // mod 2^32, as in GLSL
      if (got != want && ++wrong <= 5) ADD_FAILURE() << "values[" << i << "] = " << got << ", want " << want;
    }
    return wrong;
  }

  static constexpr vk::ComputeBinding bindings[] = {{0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
  uint32_t count;
  TvtTestFillPush push;
  vk::ComputePipeline pipeline;
  vk::Buffer values;
  vk::DescriptorSet set;
};

}  // namespace

TEST_F(GpuTest, ComputeFillRoundTripsEveryValue) {
  const FillJob fill(ctx(), 100003, 0x9e3779b9u);  // not a multiple of the workgroup size
  ctx().run_commands([&](VkCommandBuffer cmd) { fill.record(cmd); });
  EXPECT_EQ(fill.wrong_values(ctx()), 0u);
}

// Benchmarks time device work with run_commands_timed(): timestamps around the commands where
// the queue counts them. It must do exactly what run_commands() does, without a validation
// message (the query reset is recorded in the same command buffer), and more work takes longer.
TEST_F(GpuTest, TimedCommandsDoTheSameWorkAndMoreWorkTakesLonger) {
  const FillJob fill(ctx(), 1u << 20, 0x5a5a5a5au);
  // Fastest of five: other jobs share the machine and can stretch any single run; 64 times the
  // work must then still time well above the single dispatch (asked: 4 times).
  double one = 1e300, many = 1e300;
  for (int round = 0; round < 5; ++round) {
    one = std::min(one, ctx().run_commands_timed([&](VkCommandBuffer cmd) { fill.record(cmd, 1); }));
    many = std::min(many, ctx().run_commands_timed([&](VkCommandBuffer cmd) { fill.record(cmd, 64); }));
  }
  ASSERT_TRUE(ctx().status());
  EXPECT_GT(one, 0.0);
  EXPECT_GT(many, 4.0 * one) << "64 dispatches timed " << many << " s, one " << one << " s";
  EXPECT_EQ(fill.wrong_values(ctx()), 0u);
}

TEST_F(GpuTest, StorageImageArrayRoundTripsEveryTexelOfEveryLayer) {
  const uint32_t w = 67, h = 45, layers = 3;  // edges not multiples of the workgroup
  vk::Image image = ctx().create_image(VK_FORMAT_R8G8B8A8_UNORM, w, h, layers,
                                       VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT);
  ASSERT_TRUE(image);
  ASSERT_NE(image.view(), VK_NULL_HANDLE);
  EXPECT_EQ(image.layers(), layers);
  const vk::ComputeBinding bindings[] = {{0, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE}};
  vk::ComputePipeline pipeline =
      ctx().create_compute_pipeline(shaders::test_image_pattern_comp(), bindings, sizeof(TvtTestImagePush));
  vk::DescriptorSet set = ctx().allocate_descriptor_set(pipeline);
  set.write_storage_image(0, image);
  const VkDeviceSize bytes = VkDeviceSize(w) * h * layers * 4;
  vk::Buffer host = ctx().create_buffer(bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);

  const TvtTestImagePush push{w, h, layers, 0x5au};
  ctx().run_commands([&](VkCommandBuffer cmd) {
    ctx().transition(cmd, image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.handle());
    const VkDescriptorSet s = set.handle();
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout(), 0, 1, &s, 0, nullptr);
    vkCmdPushConstants(cmd, pipeline.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
    const uint32_t g = gpu::TVT_TEST_IMAGE_GROUP;
    vkCmdDispatch(cmd, (w + g - 1) / g, (h + g - 1) / g, layers);
    ctx().transition(cmd, image, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, layers};
    region.imageExtent = {w, h, 1};
    vkCmdCopyImageToBuffer(cmd, image.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host.handle(), 1, &region);
    ctx().memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
            VK_ACCESS_HOST_READ_BIT);
  });

  // Layers are packed one after another, rows tightly (bufferRowLength 0).
  const auto* p = static_cast<const unsigned char*>(host.mapped());
  size_t wrong = 0;
  for (uint32_t l = 0; l < layers; ++l) {
    for (uint32_t y = 0; y < h; ++y) {
      for (uint32_t x = 0; x < w; ++x) {
        const uint32_t want = gpu::test_image_texel(x, y, l, push.salt);
        const unsigned char* texel = p + ((size_t(l) * h + y) * w + x) * 4;
        for (uint32_t c = 0; c < 4; ++c) {
          const unsigned want_c = (want >> (8 * c)) & 255u;
          if (texel[c] != want_c && ++wrong <= 5) {
            ADD_FAILURE() << "texel (" << x << ", " << y << ", layer " << l << ") channel " << c << " = "
                          << unsigned(texel[c]) << ", want " << want_c;
          }
        }
      }
    }
  }
  EXPECT_EQ(wrong, 0u);
}

TEST_F(GpuTest, UploadOfManyMegabytesIsByteExactAndStaysInsideItsRange) {
  // 37 MB spans several staging chunks; the odd offset and size check the copy arithmetic.
  const VkDeviceSize payload = 37u * 1000u * 1000u + 3u;
  const VkDeviceSize offset = 255;
  const VkDeviceSize size = (offset + payload + 300) & ~VkDeviceSize(3);  // vkCmdFillBuffer wants a multiple of 4
  vk::Buffer dst = ctx().create_buffer(
      size, VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
      false);
  EXPECT_EQ(dst.mapped(), nullptr);
  ctx().run_commands([&](VkCommandBuffer cmd) {
    vkCmdFillBuffer(cmd, dst.handle(), 0, VK_WHOLE_SIZE, 0xabababab);
    ctx().memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
            VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT);
  });

  std::vector<unsigned char> data(static_cast<size_t>(payload));
  uint64_t state = 12345;
  for (size_t i = 0; i < data.size(); i += 8) {
    const uint64_t r = splitmix64(state);
    std::memcpy(data.data() + i, &r, std::min<size_t>(8, data.size() - i));
  }
  ctx().upload(dst, data.data(), payload, offset);

  const std::vector<unsigned char> got = read_back(ctx(), dst);
  ASSERT_EQ(got.size(), size_t(size));
  EXPECT_TRUE(std::all_of(got.begin(), got.begin() + long(offset), [](unsigned char c) { return c == 0xab; }))
      << "bytes before dst_offset were overwritten";
  EXPECT_TRUE(std::all_of(got.begin() + long(offset + payload), got.end(), [](unsigned char c) { return c == 0xab; }))
      << "bytes after the uploaded range were overwritten";
  const auto mismatch = std::mismatch(data.begin(), data.end(), got.begin() + long(offset));
  EXPECT_TRUE(mismatch.first == data.end()) << "first differing byte at " << (mismatch.first - data.begin());
}

TEST_F(GpuTest, MovedFromHandlesOwnNothingAndMovedToHandlesStillWork) {
  vk::Buffer a = ctx().create_buffer(4096, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  const VkBuffer handle = a.handle();
  void* const mapped = a.mapped();
  ASSERT_NE(handle, VK_NULL_HANDLE);
  ASSERT_NE(mapped, nullptr);

  vk::Buffer b(std::move(a));
  EXPECT_FALSE(a);  // NOLINT(bugprone-use-after-move): checking the moved-from state is the point
  EXPECT_EQ(a.handle(), VK_NULL_HANDLE);
  EXPECT_EQ(a.mapped(), nullptr);
  EXPECT_EQ(a.size(), 0u);
  EXPECT_EQ(b.handle(), handle);
  EXPECT_EQ(b.mapped(), mapped);
  EXPECT_EQ(b.size(), 4096u);

  // Move-assignment over a live buffer frees the old one and takes the new one.
  vk::Buffer c = ctx().create_buffer(64, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  c = std::move(b);
  EXPECT_EQ(b.handle(), VK_NULL_HANDLE);  // NOLINT(bugprone-use-after-move)
  EXPECT_EQ(c.handle(), handle);
  std::memset(c.mapped(), 0x5a, 4096);  // the mapping survived the moves
  EXPECT_EQ(static_cast<unsigned char*>(c.mapped())[4095], 0x5a);
  a = std::move(c);  // back into the moved-from object
  EXPECT_EQ(a.handle(), handle);

  vk::Image i1 = ctx().create_image(VK_FORMAT_R8G8B8A8_UNORM, 16, 16, 2, VK_IMAGE_USAGE_STORAGE_BIT);
  const VkImage image_handle = i1.handle();
  const VkImageView view_handle = i1.view();
  vk::Image i2(std::move(i1));
  EXPECT_FALSE(i1);  // NOLINT(bugprone-use-after-move)
  EXPECT_EQ(i1.view(), VK_NULL_HANDLE);
  EXPECT_EQ(i1.layers(), 0u);
  EXPECT_EQ(i2.handle(), image_handle);
  EXPECT_EQ(i2.view(), view_handle);
  EXPECT_EQ(i2.layers(), 2u);
  vk::Image i3 = ctx().create_image(VK_FORMAT_R8G8B8A8_UNORM, 8, 8, 1, VK_IMAGE_USAGE_TRANSFER_DST_BIT);
  EXPECT_EQ(i3.view(), VK_NULL_HANDLE);  // transfer-only usage: no view
  i3 = std::move(i2);
  EXPECT_EQ(i3.handle(), image_handle);

  const vk::ComputeBinding bindings[] = {{0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
  vk::ComputePipeline p1 = ctx().create_compute_pipeline(shaders::test_fill_comp(), bindings, sizeof(TvtTestFillPush));
  const VkPipeline pipeline_handle = p1.handle();
  vk::ComputePipeline p2(std::move(p1));
  EXPECT_EQ(p1.handle(), VK_NULL_HANDLE);  // NOLINT(bugprone-use-after-move)
  EXPECT_EQ(p1.layout(), VK_NULL_HANDLE);
  EXPECT_EQ(p1.set_layout(), VK_NULL_HANDLE);
  EXPECT_EQ(p2.handle(), pipeline_handle);

  vk::DescriptorSet s1 = ctx().allocate_descriptor_set(p2);
  const VkDescriptorSet set_handle = s1.handle();
  vk::DescriptorSet s2;
  s2 = std::move(s1);
  EXPECT_EQ(s1.handle(), VK_NULL_HANDLE);  // NOLINT(bugprone-use-after-move)
  EXPECT_EQ(s2.handle(), set_handle);
  vk::Buffer storage = ctx().create_buffer(256, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  s2.write_buffer(0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, storage);  // still a valid set
  // Destructors run here; a double destroy or a destroy of a moved-from handle would be
  // reported by the validation layer's object tracker and fail TearDown.
}

TEST_F(GpuTest, UnknownDeviceNameIsAnErrorNamingItsSourceAndListingTheAvailableDevices) {
  vk::ContextOptions options;
  options.validation = true;
  options.device = "nonexistent-device";
  options.device_source = "--gpu";
  auto created = vk::Context::create(options);
  ASSERT_FALSE(created.ok());
  const std::string& message = created.error().message;
  EXPECT_NE(message.find("--gpu"), std::string::npos) << message;
  EXPECT_NE(message.find("nonexistent-device"), std::string::npos) << message;
  EXPECT_NE(message.find("available devices"), std::string::npos) << message;
  EXPECT_NE(message.find(ctx().device_name()), std::string::npos) << message;

  options.device = "99";
  auto by_bad_index = vk::Context::create(options);
  ASSERT_FALSE(by_bad_index.ok());
  EXPECT_NE(by_bad_index.error().message.find(ctx().device_name()), std::string::npos)
      << by_bad_index.error().message;
}

TEST_F(GpuTest, DeviceIsChosenByCaseInsensitiveSubstringOrByIndex) {
  vk::ContextOptions options;
  options.validation = true;
  {
    // A case-changed piece of the shared device's name picks the same device.
    const std::string name = ctx().device_name();
    options.device = upper(name.substr(0, std::min<size_t>(name.size(), 5)));
    auto created = vk::Context::create(options);
    ASSERT_TRUE(created.ok()) << created.error().message;
    EXPECT_EQ((*created)->device_name().substr(0, options.device.size()), name.substr(0, options.device.size()));
    expect_no_validation_messages(**created);
  }
  {
    uint32_t n = 0;
    vkEnumeratePhysicalDevices(ctx().instance(), &n, nullptr);
    std::vector<VkPhysicalDevice> devices(n);
    vkEnumeratePhysicalDevices(ctx().instance(), &n, devices.data());
    ASSERT_GE(n, 1u);
    options.device = "0";
    auto created = vk::Context::create(options);
    ASSERT_TRUE(created.ok()) << created.error().message;
    EXPECT_EQ((*created)->device_name(), physical_device_name(devices[0]));
    expect_no_validation_messages(**created);
  }
}

TEST_F(GpuTest, TheLibraryReadsNoEnvironmentVariableAndAMissingLayerNamesThePackage) {
  vk::ContextOptions options;  // validation off, best device
  {
    // The CLI honours these; the library must not (an engine's environment is its own).
    ScopedEnv validation("TERRAVT_VALIDATION", "1");
    ScopedEnv device("TERRAVT_DEVICE", "nonexistent-device");
    auto created = vk::Context::create(options);
    ASSERT_TRUE(created.ok()) << created.error().message;
    EXPECT_FALSE((*created)->validation_enabled());
  }
  {
    // The loader searches only VK_LAYER_PATH for explicit layers: the layer looks uninstalled.
    ScopedEnv env("VK_LAYER_PATH", "/nonexistent-terravt-layer-dir");
    options.validation = true;
    options.validation_source = "TERRAVT_VALIDATION=1";
    auto created = vk::Context::create(options);
    ASSERT_FALSE(created.ok());
    EXPECT_NE(created.error().message.find("vulkan-validationlayers"), std::string::npos) << created.error().message;
    EXPECT_NE(created.error().message.find("VK_LAYER_KHRONOS_validation"), std::string::npos)
        << created.error().message;
    EXPECT_NE(created.error().message.find("TERRAVT_VALIDATION=1"), std::string::npos) << created.error().message;
  }
}

TEST_F(GpuTest, ADeliberateValidationErrorIsRecordedThenCleared) {
  ASSERT_TRUE(ctx().validation_messages().empty());
  VkBufferCreateInfo info{};
  info.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
  info.size = 0;  // VUID-VkBufferCreateInfo-size-00912: size must be greater than 0
  info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  std::fprintf(stderr, "(the next Vulkan validation error is deliberate)\n");
  VkBuffer buffer = VK_NULL_HANDLE;
  if (vkCreateBuffer(ctx().device(), &info, nullptr, &buffer) == VK_SUCCESS && buffer != VK_NULL_HANDLE) {
    vkDestroyBuffer(ctx().device(), buffer, nullptr);
  }
  const std::vector<std::string> messages = ctx().validation_messages();
  ASSERT_FALSE(messages.empty()) << "the debug-utils callback recorded nothing";
  EXPECT_TRUE(std::any_of(messages.begin(), messages.end(), [](const std::string& m) {
    return m.find("VUID-VkBufferCreateInfo-size-00912") != std::string::npos;
  })) << messages.front();
  ctx().clear_validation_messages();
  EXPECT_TRUE(ctx().validation_messages().empty());
}
