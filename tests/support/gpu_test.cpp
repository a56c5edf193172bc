#include "support/gpu_test.h"

#include <cstdlib>
#include <memory>
#include <mutex>

#include "app/vt_frame_driver.h"

namespace tvt {
namespace {

struct Shared {
  std::once_flag once;
  std::unique_ptr<vk::Context> context;
  std::string error;
};

Shared& shared() {
  static Shared s;
  return s;
}

// Destroys the shared context after the last test, while the Vulkan loader and driver are
// still fully alive (static destruction order across libraries is unspecified).
class SharedContextEnvironment : public ::testing::Environment {
 public:
  void TearDown() override {
    if (shared().context) {
      expect_no_validation_messages(*shared().context);
      shared().context.reset();
    }
  }
};

[[maybe_unused]] ::testing::Environment* const g_environment =
    ::testing::AddGlobalTestEnvironment(new SharedContextEnvironment);

}  // namespace

vk::Context* shared_gpu_context() {
  Shared& s = shared();
  std::call_once(s.once, [&] {
    // terravt's library reads no environment variable; the tests honour TERRAVT_DEVICE as the
    // CLI does, so a machine with several devices can pick one.
    vk::ContextOptions options;
    options.validation = true;
    if (const char* device = std::getenv("TERRAVT_DEVICE")) options.device = device;
    options.device_source = "TERRAVT_DEVICE";
    auto created = vk::Context::create(options);
    if (created) {
      s.context = std::move(created).value();
    } else {
      s.error = created.error().message;
    }
  });
  return s.context.get();
}

const std::string& shared_gpu_context_error() {
  shared_gpu_context();
  return shared().error;
}

void expect_no_validation_messages(vk::Context& ctx) {
  const std::vector<std::string> messages = ctx.validation_messages();
  ctx.clear_validation_messages();
  if (messages.empty()) return;
  std::string all;
  for (const std::string& m : messages) all += "\n  " + m;
  ADD_FAILURE() << messages.size() << " Vulkan validation message(s):" << all;
}

void GpuTest::SetUp() {
  ctx_ = shared_gpu_context();
  if (!ctx_) GTEST_FAIL() << "no usable Vulkan context: " << shared_gpu_context_error();
}

void GpuTest::TearDown() {
  if (ctx_) expect_no_validation_messages(*ctx_);
}

std::unique_ptr<terravt::VirtualTexture> make_tool_vt(vk::Context& g, const SceneAssets& assets, Method method,
                                                      const SceneVtOptions& options, uint32_t feedback_texels) {
  terravt::detail::ToolVirtualTexture td;
  td.assets = &assets;
  td.method = method;
  td.runtime = options;
  td.feedback_texels = feedback_texels;
  auto vt = create_tool_vt(g, td);
  EXPECT_TRUE(vt.ok()) << vt.error().message;
  return vt ? std::move(vt.value()) : nullptr;
}

}  // namespace tvt
