// Built only in the sanitized build (TERRAVT_SANITIZE): the check that tests/lsan.supp hides
// dependencies' leaks and nothing of terravt's. It makes terravt's own Vulkan context with the
// validation layer on, a compute pipeline and one submitted command buffer (the layer then
// leaks six blocks of its own state, about 3.4 KB, suppressed), destroys them, then leaks one
// 4242-byte block from terravt code. The CTest test sanitized_run_reports_a_leak_in_terravt_code
// passes only when LeakSanitizer reports that block, and only that block, by its function.
#include <cstdio>
#include <cstring>
#include <memory>

#include <embedded_shaders.h>

#include "gpu/context.h"
#include "shaders/shared/feedback_types.h"

namespace {

// Not inlined, so the leak's stack names this function. The volatile store keeps the allocation;
// overwriting it leaves no pointer to the block.
char* volatile last_block = nullptr;
[[gnu::noinline]] void leak_a_block_from_terravt_code() {
  last_block = new char[4242];
  std::memset(last_block, 1, 4242);
  last_block = nullptr;
}

}  // namespace

int main() {
  tvt::vk::ContextOptions options;
  options.validation = true;
  auto context = tvt::vk::Context::create(options);
  if (!context) {
    std::fprintf(stderr, "leak_probe: %s\n", context.error().message.c_str());
    return 1;
  }
  {
    const tvt::vk::ComputeBinding bindings[] = {{TVT_BIND_FEEDBACK_TABLE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                                {TVT_BIND_FEEDBACK_LIST, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
    tvt::vk::ComputePipeline pipeline = context.value()->create_compute_pipeline(
        tvt::shaders::feedback_gather_comp(), bindings, sizeof(tvt::gpu::TvtFeedbackPush));
    context.value()->run_commands([&](VkCommandBuffer cmd) {
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.handle());
    });
  }
  context.value().reset();
  leak_a_block_from_terravt_code();
  return 0;
}
