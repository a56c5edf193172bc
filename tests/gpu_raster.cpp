// Graphics pipelines and render targets of the Vulkan context: vertex input, two colour
// attachments (RGBA8 + R32G32_UINT), reverse-Z depth testing, back-face culling, readback.
#include <gtest/gtest.h>

#include <cstring>
#include <embedded_shaders.h>

#include "app/render_target.h"
#include "support/gpu_test.h"

namespace tvt {
namespace {

struct Vertex {
  float x, y, z, w;
  uint32_t id;
};

using RasterTest = GpuTest;

TEST_F(RasterTest, TwoAttachmentsReverseZDepthAndCulling) {
  const uint32_t w = 64, h = 32;
  vk::RenderTarget target(ctx(), {w, h, {VK_FORMAT_R8G8B8A8_UNORM, VK_FORMAT_R32G32_UINT}, true});
  vk::GraphicsPipelineDesc pd;
  pd.vertex_spirv = shaders::test_raster_vert();
  pd.fragment_spirv = shaders::test_raster_frag();
  pd.vertex_bindings = {{0, sizeof(Vertex), VK_VERTEX_INPUT_RATE_VERTEX}};
  pd.vertex_attributes = {{0, 0, VK_FORMAT_R32G32B32A32_SFLOAT, 0}, {1, 0, VK_FORMAT_R32_UINT, 16}};
  pd.color_formats = target.color_formats();
  pd.depth_format = target.depth_format();
  pd.cull_mode = VK_CULL_MODE_BACK_BIT;
  pd.front_face = VK_FRONT_FACE_COUNTER_CLOCKWISE;
  vk::GraphicsPipeline pipeline = ctx().create_graphics_pipeline(pd);

  // Left half: a far (z = 0.2) quad drawn before a near (z = 0.8) one: the near one wins with
  // reverse-Z. Right half: the near quad again but wound the other way: culled, far stays.
  auto quad = [](float x0, float x1, float z, uint32_t id, bool flip) {
    std::vector<Vertex> v = {{x0, -1, z, 1, id}, {x0, 1, z, 1, id}, {x1, 1, z, 1, id},
                             {x0, -1, z, 1, id}, {x1, 1, z, 1, id}, {x1, -1, z, 1, id}};
    if (flip) {
      std::swap(v[1], v[2]);
      std::swap(v[4], v[5]);
    }
    return v;
  };
  std::vector<Vertex> verts;
  for (auto part : {quad(-1, 1, 0.2f, 10, false), quad(-1, 0, 0.8f, 20, false), quad(0, 1, 0.8f, 30, true)})
    verts.insert(verts.end(), part.begin(), part.end());
  vk::Buffer vb = ctx().create_buffer(verts.size() * sizeof(Vertex), VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, true);
  std::memcpy(vb.mapped(), verts.data(), verts.size() * sizeof(Vertex));

  ctx().run_commands([&](VkCommandBuffer cmd) {
    VkClearColorValue c0{}, c1{};
    c1.uint32[0] = 7;
    target.begin(cmd, {c0, c1}, 0.0f);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline.handle());
    const VkDeviceSize offset = 0;
    const VkBuffer b = vb.handle();
    vkCmdBindVertexBuffers(cmd, 0, 1, &b, &offset);
    vkCmdDraw(cmd, uint32_t(verts.size()), 1, 0, 0);
    target.end(cmd);
  });
  const ImageRGBA8 colour = target.read_rgba8(0);
  const std::vector<uint8_t> ids = target.read_color(1);
  ASSERT_EQ(ids.size(), size_t(w) * h * 8);
  int front_faces_seen = 0;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      uint32_t id[2];
      std::memcpy(id, &ids[(size_t(y) * w + x) * 8], 8);
      const uint32_t want = x < w / 2 ? 20u : 10u;
      front_faces_seen += id[0] == want ? 1 : 0;
      ASSERT_EQ(id[0], want) << x << "," << y;
      EXPECT_EQ(id[1], x);
      EXPECT_EQ(colour.at(int(x), int(y))[0], want);
      EXPECT_EQ(colour.at(int(x), int(y))[2], 255);
    }
  EXPECT_EQ(front_faces_seen, int(w * h));
}

}  // namespace
}  // namespace tvt
