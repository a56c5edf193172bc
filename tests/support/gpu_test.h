// GoogleTest support for GPU tests: one Vulkan context (validation on) shared by every test of
// the binary, and a fixture that fails a test when validation recorded anything during it.
// GPU tests are never skipped: CI runs them on lavapipe (mesa-vulkan-drivers).
#pragma once
#include <gtest/gtest.h>

#include <string>

#include "api/compose/tool_vt.h"
#include "gpu/context.h"

namespace tvt {

// The shared context: created on first call with ContextOptions::validation = true, destroyed
// by a global test environment after the last test (so before static destructors run).
// nullptr when creation failed; shared_gpu_context_error() then says why.
vk::Context* shared_gpu_context();
const std::string& shared_gpu_context_error();

// Adds a test failure listing every message `ctx` recorded, then clears them, so one bad test
// does not fail the next. Use it for extra contexts a test creates itself.
void expect_no_validation_messages(vk::Context& ctx);

// A VT on `g`'s device made the way terravt's tools make theirs (the public API through
// api/tool_access.h): for tests that converge a view with VtFrameDriver. Fails the test (ASSERT)
// when creation fails; `feedback_texels` is the writer's (vt_feedback_texels()).
std::unique_ptr<terravt::VirtualTexture> make_tool_vt(vk::Context& g, const SceneAssets& assets, Method method,
                                                      const SceneVtOptions& options, uint32_t feedback_texels);

// Fixture for GPU tests. SetUp fails the test (GTEST_FAIL, not skip) when there is no usable
// Vulkan device; TearDown calls expect_no_validation_messages() on the shared context.
// Every Buffer/Image/pipeline a test creates must be destroyed before the test ends.
class GpuTest : public ::testing::Test {
 protected:
  void SetUp() override;
  void TearDown() override;
  vk::Context& ctx() { return *ctx_; }

 private:
  vk::Context* ctx_ = nullptr;
};

}  // namespace tvt
