// Terrain-pass sampling options (app/terrain_renderer.h): the plain pre-composed texture,
// anisotropic VT sampling, the separate feedback pass, and all of them at the far corner of
// V = 2^24. Validation is on: any message fails a test.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <numbers>

#include "support/terrain_probe.h"
#include "compose/image_diff.h"
#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "app/flythrough.h"
#include "app/plain_texture.h"
#include "app/terrain_renderer.h"
#include "app/vt_frame_driver.h"
#include "shaders/shared/feedback_types.h"
#include "support/gpu_test.h"

namespace tvt {
namespace {

using test::Probe;
using test::read_probe;

// Blocking copy of a device buffer (TRANSFER_SRC usage) to the host.
std::vector<uint32_t> read_buffer(vk::Context& g, const vk::Buffer& src) {
  vk::Buffer staging = g.create_buffer(src.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  g.run_commands([&](VkCommandBuffer cmd) {
    const VkBufferCopy region{0, 0, src.size()};
    vkCmdCopyBuffer(cmd, src.handle(), staging.handle(), 1, &region);
    g.memory_barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                                VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
  });
  std::vector<uint32_t> out(size_t(src.size() / 4));
  std::memcpy(out.data(), staging.mapped(), out.size() * 4);
  return out;
}

// Blocking readback of one mip level of a sampled RGBA8 image (SHADER_READ_ONLY_OPTIMAL).
std::vector<uint8_t> read_level(vk::Context& g, const vk::Image& image, uint32_t level) {
  const uint32_t w = image.width() >> level, h = image.height() >> level;
  vk::Buffer staging = g.create_buffer(VkDeviceSize(w) * h * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  g.run_commands([&](VkCommandBuffer cmd) {
    g.transition(cmd, image, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, level, 0, 1};
    region.imageExtent = {w, h, 1};
    vkCmdCopyImageToBuffer(cmd, image.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, staging.handle(), 1, &region);
    g.transition(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  });
  std::vector<uint8_t> out(size_t(w) * h * 4);
  std::memcpy(out.data(), staging.mapped(), out.size());
  return out;
}

bool has_magenta(const ImageRGBA8& img) {
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const uint8_t* p = img.at(x, y);
      if (p[0] == 255 && p[1] == 0 && p[2] == 255) return true;
    }
  return false;
}

const SceneAssets& default_assets() {
  static const SceneAssets a = [] {
    auto r = load_scene_assets(default_scene());
    EXPECT_TRUE(r.ok());
    return std::move(r.value());
  }();
  return a;
}

TerrainVtInputs vt_inputs(terravt::VirtualTexture& v, uint32_t divisor, FeedbackMode mode, uint32_t aniso = 1) {
  return terrain_vt_inputs(v, divisor, mode, aniso);
}

// The feedback tests' VT: the default scene in blend-map form, 256 cache pages, 64 per frame,
// compacting the feedback of a 320 x 180 pass at N = 4. Frame 0 has run (nothing requested), so
// its set-up is done and passes may sample it; a driver continues with frame 1.
struct FeedbackVt {
  std::unique_ptr<terravt::VirtualTexture> vt;
};
void make_feedback_vt(vk::Context& g, FeedbackVt& out) {
  SceneVtOptions vo;
  vo.cache_slots = 256;
  vo.page_budget = 64;
  out.vt = make_tool_vt(g, default_assets(), Method::BlendMap, vo, vt_feedback_texels(320, 180, 4));
  ASSERT_TRUE(out.vt);
  ASSERT_TRUE(out.vt->begin_frame(0, std::nullopt, 0, 0, {}).ok());
  terravt::Status recorded = terravt::Ok{};
  g.run_commands([&](VkCommandBuffer cmd) { recorded = out.vt->record(cmd); });
  ASSERT_TRUE(recorded.ok()) << recorded.error().message;
}

using TerrainSamplingTest = GpuTest;

TEST_F(TerrainSamplingTest, PlainTextureLevelZeroIsTheComposedPagesAndTheChainIsBoxFiltered) {
  const SceneAssets& assets = default_assets();
  auto packed = pack_scene(assets, options_for(Method::FbpbDpt));
  ASSERT_TRUE(packed.ok());
  PlainTextureOptions po;
  po.log2_size = 9;  // VT mip log2(V) - 9: 4 x 4 pages
  po.batch_pages = 5;  // batches that do not divide the page count
  auto plain = PlainTexture::create(ctx(), packed.value(), po);
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  const PlainTexture& p = *plain.value();
  const uint32_t mip = assets.desc.vt.log2_size - 9;
  EXPECT_EQ(p.vt_mip(), mip);
  EXPECT_EQ(p.pages_composed(), 16u);
  EXPECT_EQ(p.image().mip_levels(), 10u);

  const std::vector<uint8_t> l0 = read_level(ctx(), p.image(), 0), l1 = read_level(ctx(), p.image(), 1);
  auto composer = GpuComposer::create(ctx(), packed.value(), 4);
  ASSERT_TRUE(composer.ok());
  const std::vector<PageId> pages = {{mip, 0, 0}, {mip, 3, 1}, {mip, 2, 3}};
  const auto composed = composer.value()->compose_pages(pages).value();
  const uint32_t P = 128, B = 4, S = P + 2 * B, size = 512;
  for (size_t i = 0; i < pages.size(); ++i)
    for (uint32_t y = 0; y < P; ++y)
      ASSERT_EQ(std::memcmp(&composed[i][((y + B) * S + B) * 4], &l0[((pages[i].y * P + y) * size + pages[i].x * P) * 4], P * 4),
                0)
          << "page " << i << " row " << y;
  int worst = 0;
  for (uint32_t y = 0; y < size / 2; ++y)
    for (uint32_t x = 0; x < size / 2; ++x)
      for (uint32_t c = 0; c < 4; ++c) {
        int sum = 0;
        for (uint32_t k = 0; k < 4; ++k) sum += l0[((2 * y + k / 2) * size + 2 * x + k % 2) * 4 + c];
        worst = std::max(worst, std::abs(4 * int(l1[(y * size / 2 + x) * 4 + c]) - sum));
      }
  EXPECT_LE(worst, 4) << "level 1 is not the 2x2 box filter of level 0 (4 x difference " << worst << ")";

  TerrainRendererOptions o;
  o.width = 160;
  o.height = 90;
  o.plain = TerrainPlainInputs{&p};
  auto r = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_TRUE(r.ok()) << r.error().message;
  const CameraPath path = flythrough_path(assets, r.value()->mesh());
  const ImageRGBA8 img = r.value()->render(path.camera_at(path.start_time() + 2.0));
  EXPECT_FALSE(has_magenta(img));
  uint8_t lo = 255, hi = 0;
  for (int x = 0; x < 160; ++x) lo = std::min(lo, img.at(x, 80)[1]), hi = std::max(hi, img.at(x, 80)[1]);
  EXPECT_GT(hi - lo, 20) << "terrain rows should carry texture";
}

// A low grazing view: anisotropic sampling picks finer mips (LOD from major axis / taps, at
// most log2(4) = 2 finer), the feedback asks for them, and distant texture keeps more detail.
TEST_F(TerrainSamplingTest, AnisotropicSamplingReadsFinerMipsAlongGrazingViewsAndKeepsDetail) {
  const SceneAssets& assets = default_assets();
  SceneVtOptions vo;
  vo.cache_slots = 512;
  vo.page_budget = 64;
  const uint32_t w = 192, h = 108;
  auto vt = make_tool_vt(ctx(), assets, Method::BlendMap, vo, vt_feedback_texels(w, h, 2));
  ASSERT_TRUE(vt);
  terravt::VirtualTexture& v = *vt;
  TerrainRendererOptions o;
  o.width = w;
  o.height = h;
  o.vt = vt_inputs(v, 2, FeedbackMode::MainPass, 4);
  auto writer = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  o.vt = vt_inputs(v, 2, FeedbackMode::None, 4);
  o.vt->probe_output = true;
  auto aniso = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_TRUE(aniso.ok());
  o.vt->max_anisotropy = 1;
  auto iso = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_TRUE(iso.ok());
  o.vt->max_anisotropy = 5;  // beyond the border B = 4: taps would leave the slot
  EXPECT_FALSE(TerrainRenderer::create(ctx(), assets, o).ok());

  const CameraPath path = flythrough_path(assets, writer.value()->mesh());
  const Camera cam = path.camera_at(path.start_time() + 0.5);
  auto driver = VtFrameDriver::create(ctx(), v, *writer.value());
  ASSERT_TRUE(driver.ok());
  const auto conv = driver.value()->converge(cam, 60);
  ASSERT_TRUE(conv.ok()) << conv.error().message;
  ASSERT_TRUE(conv->converged);

  const ImageRGBA8 a_img = aniso.value()->render(cam);
  const std::vector<Probe> a = read_probe(*aniso.value());
  const ImageRGBA8 i_img = iso.value()->render(cam);
  const std::vector<Probe> i = read_probe(*iso.value());
  EXPECT_FALSE(has_magenta(a_img));
  const int top = int(assets.desc.vt.mip_count()) - 1;
  size_t terrain = 0, finer = 0, unmatched = 0;
  double detail_a = 0, detail_i = 0;
  for (uint32_t y = 0; y + 1 < h; ++y)
    for (uint32_t x = 0; x + 1 < w; ++x) {
      const size_t k = y * w + x;
      if (i[k].lod < 0.0f) continue;
      ++terrain;
      ASSERT_GE(a[k].lod, 0.0f);
      EXPECT_LE(a[k].lod, i[k].lod + 1e-4f) << x << "," << y;
      EXPECT_GE(a[k].lod, i[k].lod - 2.0f - 1e-3f) << x << "," << y;
      // The converged cache holds what the anisotropic LOD wants (its feedback asked for it).
      unmatched += int(a[k].fine_mip) != std::min(int(std::floor(a[k].lod)), top);
      if (i[k].lod - a[k].lod < 0.75f || i[k].lod < 1.0f || i[k + 1].lod < 0.0f || i[k + w].lod < 0.0f) continue;
      ++finer;
      for (int c = 0; c < 3; ++c) {
        const double dai = double(a_img.at(int(x) + 1, int(y))[c]) - a_img.at(int(x), int(y))[c];
        const double daj = double(a_img.at(int(x), int(y) + 1)[c]) - a_img.at(int(x), int(y))[c];
        const double dii = double(i_img.at(int(x) + 1, int(y))[c]) - i_img.at(int(x), int(y))[c];
        const double dij = double(i_img.at(int(x), int(y) + 1)[c]) - i_img.at(int(x), int(y))[c];
        detail_a += dai * dai + daj * daj;
        detail_i += dii * dii + dij * dij;
      }
    }
  std::fprintf(stderr, "aniso: %zu of %zu terrain px at least 0.75 mip finer; gradient energy %.0f vs iso %.0f (%.2fx)\n",
               finer, terrain, detail_a, detail_i, detail_a / std::max(detail_i, 1.0));
  EXPECT_EQ(unmatched, 0u);
  EXPECT_GT(finer, terrain / 10);
  EXPECT_GT(detail_a, 1.2 * detail_i);
}

// The separate 1/N-resolution pass reports, texel for texel, the page the main pass reports for
// the same rotating pixel (its viewport is shifted onto that pixel), up to the mip: its screen
// derivatives span 2N pixels instead of 2.
TEST_F(TerrainSamplingTest, SeparateFeedbackPassReportsThePagesTheMainPassReports) {
  const SceneAssets& assets = default_assets();
  FeedbackVt fv;
  ASSERT_NO_FATAL_FAILURE(make_feedback_vt(ctx(), fv));
  terravt::VirtualTexture& v = *fv.vt;
  TerrainRendererOptions o;
  o.width = 320;
  o.height = 180;
  o.vt = vt_inputs(v, 4, FeedbackMode::MainPass);
  auto main_pass = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_TRUE(main_pass.ok());
  o.vt = vt_inputs(v, 4, FeedbackMode::SeparatePass);
  auto separate = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_TRUE(separate.ok()) << separate.error().message;
  ASSERT_EQ(separate.value()->feedback_width(), 80u);

  const CameraPath path = flythrough_path(assets, main_pass.value()->mesh());
  size_t texels = 0, same = 0, terrain = 0, silhouette = 0, adjacent_mip = 0, separate_coarser = 0, other = 0;
  for (int frame = 0; frame < 3; ++frame) {  // three rotation offsets
    const Camera cam = path.camera_at(path.start_time() + 1.0 + 3.0 * frame);
    (void)main_pass.value()->render(cam);
    (void)separate.value()->render(cam);
    const auto a = read_buffer(ctx(), main_pass.value()->feedback_buffer());
    const auto b = read_buffer(ctx(), separate.value()->feedback_buffer());
    ASSERT_EQ(a.size(), b.size());
    for (size_t k = 0; k < a.size(); k += 2) {
      ++texels;
      terrain += a[k] != gpu::TVT_FEEDBACK_EMPTY_WORD;
      if (a[k] == b[k] && a[k + 1] == b[k + 1]) {
        ++same;
        continue;
      }
      if (a[k] == gpu::TVT_FEEDBACK_EMPTY_WORD || b[k] == gpu::TVT_FEEDBACK_EMPTY_WORD) {
        ++silhouette;
        continue;
      }
      // Otherwise the same place at an adjacent mip: one page is the other's parent.
      const uint32_t ma = gpu::tvt_feedback_mip(a[k]), mb = gpu::tvt_feedback_mip(b[k]);
      const uint32_t xa = gpu::tvt_feedback_x(a[k]), ya = gpu::tvt_feedback_y(a[k + 1]);
      const uint32_t xb = gpu::tvt_feedback_x(b[k]), yb = gpu::tvt_feedback_y(b[k + 1]);
      const bool parent = (ma + 1 == mb && (xa >> 1) == xb && (ya >> 1) == yb) ||
                          (mb + 1 == ma && (xb >> 1) == xa && (yb >> 1) == ya);
      adjacent_mip += parent;
      separate_coarser += parent && mb > ma;
      other += !parent;
    }
  }
  std::fprintf(stderr,
               "separate vs main-pass feedback: %zu of %zu texels equal (%zu terrain); differing: %zu terrain/sky, "
               "%zu parent/child page (separate pass coarser in %zu), %zu other\n",
               same, texels, terrain, silhouette, adjacent_mip, separate_coarser, other);
  // Measured 92 % equal; nearly all the others name the parent or child page: the separate pass
  // takes derivatives over 2N pixels instead of 2, which moves floor(LOD) near mip boundaries.
  EXPECT_GT(terrain, texels / 2);
  EXPECT_GE(double(same), 0.88 * double(texels));
  EXPECT_LE(double(silhouette), 0.01 * double(texels));
  EXPECT_LE(double(other), 0.005 * double(texels));

  // And it drives residency: a static view converges with only the separate pass reporting.
  auto driver = VtFrameDriver::create(ctx(), v, *separate.value(), 1);
  ASSERT_TRUE(driver.ok());
  const auto c = driver.value()->converge(path.camera_at(path.start_time() + 4.0), 60);
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_TRUE(c->converged) << c->frames << " frames";
  EXPECT_GT(terravt::detail::runtime(v).stats().residency.resident, 20u);
}

// Attachment feedback (the default) reports exactly what main-pass stores report: the same
// rotating pixel of every N x N block, the same LOD, copied from the second attachment instead
// of stored by the shader. A size that N does not divide leaves blocks whose rotating pixel
// lies beyond the image: those texels stay empty in both.
TEST_F(TerrainSamplingTest, AttachmentFeedbackEqualsMainPassStoresTexelForTexel) {
  const SceneAssets& assets = default_assets();
  FeedbackVt fv;
  ASSERT_NO_FATAL_FAILURE(make_feedback_vt(ctx(), fv));
  terravt::VirtualTexture& v = *fv.vt;
  TerrainRendererOptions o;
  o.width = 251;  // 32 blocks of 8, the last one 3 pixels wide
  o.height = 139;
  ASSERT_EQ(TerrainVtInputs{}.feedback, FeedbackMode::Attachment);
  // The CLI's --feedback auto: the attachment on a CPU device, main-pass stores on a GPU.
  EXPECT_EQ(default_feedback_mode(VK_PHYSICAL_DEVICE_TYPE_CPU), FeedbackMode::Attachment);
  EXPECT_EQ(default_feedback_mode(VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU), FeedbackMode::MainPass);
  EXPECT_EQ(default_feedback_mode(VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU), FeedbackMode::MainPass);
  o.vt = vt_inputs(v, 8, FeedbackMode::Attachment);
  auto attachment = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_TRUE(attachment.ok()) << attachment.error().message;
  o.vt = vt_inputs(v, 8, FeedbackMode::MainPass);
  auto stores = TerrainRenderer::create(ctx(), assets, o);
  ASSERT_TRUE(stores.ok());
  ASSERT_EQ(attachment.value()->feedback_width(), 32u);

  const CameraPath path = flythrough_path(assets, stores.value()->mesh());
  size_t terrain = 0, empty_edge = 0;
  for (int frame = 0; frame < 64; ++frame) {  // every rotation offset of the 8 x 8 block
    const Camera cam = path.camera_at(path.start_time() + 0.25 * frame);
    const ImageRGBA8 ia = attachment.value()->render(cam), ib = stores.value()->render(cam);
    const auto a = read_buffer(ctx(), attachment.value()->feedback_buffer());
    const auto b = read_buffer(ctx(), stores.value()->feedback_buffer());
    ASSERT_EQ(a, b) << "frame " << frame;
    ASSERT_EQ(compare_images(ia, ib).max_abs, 0u) << "frame " << frame;  // the colour is untouched
    for (size_t k = 0; k < a.size(); k += 2) terrain += a[k] != gpu::TVT_FEEDBACK_EMPTY_WORD;
    empty_edge += a[2 * (15 * 32 + 31)] == gpu::TVT_FEEDBACK_EMPTY_WORD;  // row 15 (terrain), last column
  }
  EXPECT_GT(terrain, 64u * 32u * 18u / 2u);
  EXPECT_EQ(empty_edge, 40u);  // the last column's rotating pixel is inside for 3 of the 8 x offsets
}

// V = 2^24 (0.5 mm texels), camera 1 m above the far corner looking along the edge at a grazing
// angle: the anisotropic VT pass, the separate feedback pass, the matched direct pass and the
// plain texture produce no NaN (the shaders paint non-finite colours magenta) and no
// validation message.
TEST_F(TerrainSamplingTest, ExtremeCoordinatesAtTheFarCornerOfTwoPow24) {
  SceneDesc desc = default_scene();
  desc.vt.log2_size = 24;
  auto assets = load_scene_assets(desc);
  ASSERT_TRUE(assets.ok()) << assets.error().message;
  SceneVtOptions vo;
  vo.cache_slots = 384;
  vo.page_budget = 64;
  auto vt = make_tool_vt(ctx(), assets.value(), Method::FbpbDpt, vo, vt_feedback_texels(128, 72, 4));
  auto packed = pack_scene(assets.value(), options_for(Method::FbpbDpt));  // the direct and plain passes'
  ASSERT_TRUE(packed.ok());
  ASSERT_TRUE(vt);
  terravt::VirtualTexture& v = *vt;
  TerrainRendererOptions o;
  o.width = 128;
  o.height = 72;
  o.vt = vt_inputs(v, 4, FeedbackMode::SeparatePass, 4);
  auto writer = TerrainRenderer::create(ctx(), assets.value(), o);
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  const double extent = desc.terrain.extent_m;
  Camera cam;
  cam.position_m = {extent - 0.37, extent - 0.61, writer.value()->mesh().height_m_at(extent - 0.37, extent - 0.61) + 1.0};
  cam.yaw_rad = std::numbers::pi * 1.25;  // back across the terrain, along the diagonal
  cam.pitch_rad = -0.12;
  cam.near_m = 0.05;
  auto driver = VtFrameDriver::create(ctx(), v, *writer.value());
  ASSERT_TRUE(driver.ok());
  const auto c = driver.value()->converge(cam, 40);
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_TRUE(c->converged) << c->frames << " frames";
  const ImageRGBA8 vt_img = writer.value()->target().read_rgba8(0);
  EXPECT_FALSE(has_magenta(vt_img));

  auto composer = GpuComposer::create(ctx(), packed.value(), 1);
  ASSERT_TRUE(composer.ok());
  TerrainRendererOptions d = o;
  d.vt.reset();
  d.direct = TerrainDirectInputs{composer.value().get(), true};
  auto matched = TerrainRenderer::create(ctx(), assets.value(), d);
  ASSERT_TRUE(matched.ok());
  EXPECT_FALSE(has_magenta(matched.value()->render(cam)));

  PlainTextureOptions po;
  po.log2_size = 9;
  auto plain = PlainTexture::create(ctx(), packed.value(), po);
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  TerrainRendererOptions p = o;
  p.vt.reset();
  p.plain = TerrainPlainInputs{plain.value().get()};
  auto plain_r = TerrainRenderer::create(ctx(), assets.value(), p);
  ASSERT_TRUE(plain_r.ok());
  EXPECT_FALSE(has_magenta(plain_r.value()->render(cam)));
}

}  // namespace
}  // namespace tvt
