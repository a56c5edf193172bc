// vt_lookup.glsl against vt/page_table.h: same entry, same data mip, and the texel position
// inside the slot within 1/256 texel — at the origin and at the far corner of V = 2^24.
#include <gtest/gtest.h>

#include <embedded_shaders.h>

#include <cmath>
#include <cstring>
#include <ostream>
#include <string>
#include <random>

#include "render/vt_info.h"
#include "shaders/shared/vt_test_types.h"
#include "support/gpu_test.h"
#include "vt/page_table.h"

using namespace tvt;

namespace {

struct Case {
  uint32_t log2_vt;
  uint32_t window;
  uint32_t centre_x, centre_y;
};
void PrintTo(const Case& c, std::ostream* os) {
  *os << "V 2^" << c.log2_vt << ", window " << c.window << ", centre (" << c.centre_x << ", " << c.centre_y << ")";
}

class GpuVtLookup : public GpuTest, public ::testing::WithParamInterface<Case> {};

}  // namespace

TEST_P(GpuVtLookup, MatchesThePageTable) {
  const Case c = GetParam();
  VtConfig vt;
  vt.log2_size = c.log2_vt;
  PageTable table(vt, PageTableOptions{c.window});
  table.set_centre(c.centre_x, c.centre_y);
  std::mt19937 rng(c.log2_vt * 31 + c.centre_x);
  // The top page always; then random pages near the centre at every mip.
  uint32_t slot = 0;
  table.map(PageId{vt.mip_count() - 1, 0, 0}, slot++);
  for (int i = 0; i < 400; ++i) {
    const uint32_t mip = uint32_t(rng() % vt.mip_count());
    const int64_t n = int64_t(vt.pages_per_side(mip));
    const int64_t cx = int64_t(c.centre_x >> (vt.log2_page() + mip)), cy = int64_t(c.centre_y >> (vt.log2_page() + mip));
    const PageId p{mip, uint32_t(std::clamp<int64_t>(cx + int64_t(rng() % 9) - 4, 0, n - 1)),
                   uint32_t(std::clamp<int64_t>(cy + int64_t(rng() % 9) - 4, 0, n - 1))};
    if (!table.is_mapped(p)) table.map(p, slot++);
  }
  const gpu::TvtVtInfo info = make_vt_info(vt, table, 0.f);

  std::vector<gpu::TvtVtQuery> queries;
  std::uniform_real_distribution<float> frac(0.f, 0.999f);
  const int64_t V = int64_t(vt.size_texels());
  for (int i = 0; i < 4000; ++i) {
    const int64_t spread = int64_t(1) << (rng() % 20);
    gpu::TvtVtQuery q{};
    q.x = std::clamp<int64_t>(int64_t(c.centre_x) + int64_t(rng() % uint32_t(2 * spread)) - spread, 0, V - 1);
    q.y = std::clamp<int64_t>(int64_t(c.centre_y) + int64_t(rng() % uint32_t(2 * spread)) - spread, 0, V - 1);
    q.frac = {frac(rng), frac(rng)};
    q.mip = int(rng() % vt.mip_count());
    queries.push_back(q);
  }

  vk::Context& g = ctx();
  vk::Buffer info_buf = g.create_buffer(sizeof(info), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  std::memcpy(info_buf.mapped(), &info, sizeof(info));
  const auto entries = table.all_entries();
  vk::Buffer entry_buf = g.create_buffer(entries.size_bytes(), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  std::memcpy(entry_buf.mapped(), entries.data(), entries.size_bytes());
  vk::Buffer query_buf = g.create_buffer(queries.size() * sizeof(gpu::TvtVtQuery), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  std::memcpy(query_buf.mapped(), queries.data(), queries.size() * sizeof(gpu::TvtVtQuery));
  vk::Buffer answer_buf = g.create_buffer(queries.size() * sizeof(gpu::TvtVtAnswer), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  const vk::ComputeBinding bindings[] = {{TVT_BIND_TEST_VT_INFO, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                         {TVT_BIND_TEST_VT_ENTRIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                         {TVT_BIND_TEST_VT_QUERIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                         {TVT_BIND_TEST_VT_ANSWERS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
  vk::ComputePipeline pipeline = g.create_compute_pipeline(shaders::test_vt_lookup_comp(), bindings, sizeof(uint32_t));
  vk::DescriptorSet set = g.allocate_descriptor_set(pipeline);
  set.write_buffer(TVT_BIND_TEST_VT_INFO, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, info_buf);
  set.write_buffer(TVT_BIND_TEST_VT_ENTRIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, entry_buf);
  set.write_buffer(TVT_BIND_TEST_VT_QUERIES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, query_buf);
  set.write_buffer(TVT_BIND_TEST_VT_ANSWERS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, answer_buf);
  const uint32_t count = uint32_t(queries.size());
  g.run_commands([&](VkCommandBuffer cmd) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.handle());
    const VkDescriptorSet s = set.handle();
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout(), 0, 1, &s, 0, nullptr);
    vkCmdPushConstants(cmd, pipeline.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(count), &count);
    vkCmdDispatch(cmd, (count + 63) / 64, 1, 1);
  });

  const auto* answers = static_cast<const gpu::TvtVtAnswer*>(answer_buf.mapped());
  double worst = 0;
  size_t valid = 0;
  for (size_t i = 0; i < queries.size(); ++i) {
    const gpu::TvtVtQuery& q = queries[i];
    const uint32_t e = table.lookup(uint32_t(q.x), uint32_t(q.y), uint32_t(q.mip));
    ASSERT_EQ(answers[i].valid != 0, entry_valid(e)) << i;
    if (!entry_valid(e)) continue;
    ++valid;
    ASSERT_EQ(answers[i].slot, entry_slot(e)) << i;
    const int d = int(entry_mip(e));
    ASSERT_EQ(answers[i].data_mip, d) << i;
    // Analytic texel position inside the data page, in double.
    for (int axis = 0; axis < 2; ++axis) {
      const int64_t t = axis == 0 ? q.x : q.y;
      const double at_mip = (double(t) + double(axis == 0 ? q.frac.x : q.frac.y)) / std::ldexp(1.0, d);
      const double page = std::floor(double(t >> d) / double(vt.page_texels));
      const double local = at_mip - page * vt.page_texels + vt.border_texels;
      const double got = axis == 0 ? answers[i].local.x : answers[i].local.y;
      worst = std::max(worst, std::abs(got - local));
    }
  }
  EXPECT_GT(valid, queries.size() / 2);
  EXPECT_LE(worst, 1.0 / 256.0) << "worst texel error " << worst;
}

INSTANTIATE_TEST_SUITE_P(Sizes, GpuVtLookup,
                         ::testing::Values(Case{16, 32, 30000, 20000}, Case{24, 32, 100, 50},
                                           Case{24, 32, (1u << 24) - 3, (1u << 24) - 7}, Case{24, 8, 1u << 23, 77}),
                         [](const auto& p) {
                           const Case& c = p.param;
                           return "V" + std::to_string(c.log2_vt) + "Window" + std::to_string(c.window) + "At" +
                                  std::to_string(c.centre_x) + "x" + std::to_string(c.centre_y);
                         });
