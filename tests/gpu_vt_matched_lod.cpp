// The VT image against direct splatting at matched LOD (issue: PSNR >= 45 dB, no pixel along
// page borders off by more than 8/255): the cache converges for one camera, then the same
// frame is rendered through the VT (with a probe attachment: LOD, data mips, distance to the
// page payload edge) and through the direct-splat pass that composes the texel centres of the
// mips the VT LOD selects and filters them as the VT sampler does.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "support/terrain_probe.h"
#include "compose/packed_scene.h"
#include "compose/scene.h"
#include "app/flythrough.h"
#include "app/terrain_renderer.h"
#include "app/vt_frame_driver.h"
#include "support/gpu_test.h"

using namespace tvt;

namespace {

using test::Probe;
using test::read_probe;

struct Diff {
  double se = 0;
  size_t channels = 0;
  int worst = 0;
  void add(const uint8_t* a, const uint8_t* b) {
    for (int c = 0; c < 3; ++c) {
      const int d = int(a[c]) - int(b[c]);
      se += double(d * d);
      worst = std::max(worst, std::abs(d));
      ++channels;
    }
  }
  double psnr() const { return se == 0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 * double(channels) / se); }
};

// One camera over varied terrain, the cache converged for it by a VT writer with the given mip
// filter, then the same frame through the VT (probe attachment), the direct pass at matched
// LOD (same filter) and the continuous direct pass.
class GpuVtMatchedLod : public GpuTest {
 protected:
  static constexpr uint32_t w = 256, h = 144;

  // Each call starts from a new, empty VT; the scene is loaded and packed once.
  void converge_and_render(VtMipFilter filter) {
    if (!scene_ready) {
      auto loaded = load_scene_assets(default_scene());
      ASSERT_TRUE(loaded.ok());
      assets = std::move(loaded.value());
      auto packing = pack_scene(assets, options_for(Method::FbpbDpt));
      ASSERT_TRUE(packing.ok());
      packed = std::move(packing.value());
      scene_ready = true;
    }
    vt.reset();
    SceneVtOptions vo;
    vo.cache_slots = 512;
    vo.page_budget = 64;
    vt = make_tool_vt(ctx(), assets, Method::FbpbDpt, vo, vt_feedback_texels(w, h, 2));
    ASSERT_TRUE(vt);
    const VtSystem& v = terravt::detail::runtime(*vt);

    base.width = w;
    base.height = h;
    TerrainVtInputs vi = terrain_vt_inputs(*vt, 2, FeedbackMode::Attachment);
    vi.mip_filter = filter;
    TerrainRendererOptions writer_o = base;
    writer_o.vt = vi;
    auto writer = TerrainRenderer::create(ctx(), assets, writer_o);
    ASSERT_TRUE(writer.ok()) << writer.error().message;
    probe_o = base;
    probe_o.vt = vi;
    probe_o.vt->feedback = FeedbackMode::None;
    probe_o.vt->probe_output = true;
    auto probe = TerrainRenderer::create(ctx(), assets, probe_o);
    ASSERT_TRUE(probe.ok()) << probe.error().message;
    auto made_composer = GpuComposer::create(ctx(), packed, 1);
    ASSERT_TRUE(made_composer.ok());
    composer = std::move(made_composer.value());
    direct_o = base;
    direct_o.direct = TerrainDirectInputs{composer.get(), true, filter};
    auto matched = TerrainRenderer::create(ctx(), assets, direct_o);
    ASSERT_TRUE(matched.ok()) << matched.error().message;
    TerrainRendererOptions continuous_o = direct_o;
    continuous_o.direct->matched_lod = false;
    auto continuous = TerrainRenderer::create(ctx(), assets, continuous_o);
    ASSERT_TRUE(continuous.ok());

    // A low pass over varied terrain: mips 0 ... 6 on screen, many page borders.
    const CameraPath path = flythrough_path(assets, writer.value()->mesh());
    cam = path.camera_at(path.start_time() + 0.5);
    auto driver = VtFrameDriver::create(ctx(), *vt, *writer.value());
    ASSERT_TRUE(driver.ok()) << driver.error().message;
    const auto conv = driver.value()->converge(cam, 60);
    ASSERT_TRUE(conv.ok()) << conv.error().message;
    ASSERT_TRUE(conv->converged) << "no convergence in " << conv->frames << " frames";
    EXPECT_EQ(v.stats().residency.mip_bias, 0u);  // the matched pass assumes no bias
    resident = v.stats().residency.resident;

    vt_img = probe.value()->render(cam);
    pr = read_probe(*probe.value());
    direct_img = matched.value()->render(cam);
    continuous_img = continuous.value()->render(cam);
  }

  bool scene_ready = false;
  SceneAssets assets;
  PackedScene packed;
  std::unique_ptr<terravt::VirtualTexture> vt;
  std::unique_ptr<GpuComposer> composer;
  TerrainRendererOptions base, probe_o, direct_o;
  Camera cam;
  uint32_t resident = 0;  // pages resident once converged
  ImageRGBA8 vt_img, direct_img, continuous_img;
  std::vector<Probe> pr;
};

}  // namespace

TEST_F(GpuVtMatchedLod, VtEqualsDirectSplattingAtMatchedLod) {
  ASSERT_NO_FATAL_FAILURE(converge_and_render(VtMipFilter::Trilinear));
  Diff frame, terrain, border, cont;
  size_t terrain_px = 0, mismatched_mips = 0;
  int mip_lo = 99, mip_hi = -1;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const Probe& p = pr[y * w + x];
      const uint8_t* a = vt_img.at(int(x), int(y));
      const uint8_t* b = direct_img.at(int(x), int(y));
      frame.add(a, b);
      cont.add(a, continuous_img.at(int(x), int(y)));
      if (p.lod < 0.0f) continue;  // sky
      ++terrain_px;
      terrain.add(a, b);
      // Matched: the VT read the mips its LOD wants (no fallback to an ancestor).
      const int want = std::min(int(std::floor(p.lod)), int(assets.desc.vt.mip_count()) - 1);
      mismatched_mips += int(p.fine_mip) != want;
      mip_lo = std::min(mip_lo, want);
      mip_hi = std::max(mip_hi, want);
      if (p.edge < 1.0f) border.add(a, b);  // within a texel of the payload edge: taps read the border or next to it
    }
  std::fprintf(stderr,
               "VT vs matched direct: %.2f dB frame, %.2f dB terrain (%zu px, mips %d..%d), worst %d/255; border: %zu px, "
               "worst %d/255, %.2f dB; VT vs continuous direct %.2f dB\n",
               frame.psnr(), terrain.psnr(), terrain_px, mip_lo, mip_hi, terrain.worst, border.channels / 3, border.worst,
               border.psnr(), cont.psnr());
  RecordProperty("vt_vs_matched_direct_psnr_db", std::to_string(terrain.psnr()));
  RecordProperty("border_worst", std::to_string(border.worst));
  ASSERT_GT(terrain_px, size_t(w * h / 2));
  EXPECT_EQ(mismatched_mips, 0u);
  EXPECT_GE(mip_hi - mip_lo, 3);  // the frame spans several mips (trilinear between them)
  ASSERT_GT(border.channels / 3, 300u);
  EXPECT_GE(frame.psnr(), 45.0);
  EXPECT_GE(terrain.psnr(), 45.0);
  EXPECT_LE(border.worst, 8);

  // The comparison above includes the detail normal (lighting.detail_relief_m, default on):
  // the VT's per-lane height gradient (textureGather of the cache) against the matched pass's
  // analytic one. It matters: without relief the VT image differs visibly, and the two paths
  // still agree.
  ASSERT_GT(base.lighting.detail_relief_m, 0.0);
  TerrainRendererOptions flat_vt_o = probe_o, flat_direct_o = direct_o;
  flat_vt_o.lighting.detail_relief_m = 0.0;
  flat_direct_o.lighting.detail_relief_m = 0.0;
  flat_direct_o.direct->matched_lod = true;
  auto flat_vt = TerrainRenderer::create(ctx(), assets, flat_vt_o);
  auto flat_direct = TerrainRenderer::create(ctx(), assets, flat_direct_o);
  ASSERT_TRUE(flat_vt.ok() && flat_direct.ok());
  const ImageRGBA8 flat_vt_img = flat_vt.value()->render(cam), flat_direct_img = flat_direct.value()->render(cam);
  Diff relief, flat;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      if (pr[y * w + x].lod < 0.0f) continue;
      relief.add(vt_img.at(int(x), int(y)), flat_vt_img.at(int(x), int(y)));
      flat.add(flat_vt_img.at(int(x), int(y)), flat_direct_img.at(int(x), int(y)));
    }
  std::fprintf(stderr, "detail normal: relief on vs off %.2f dB (worst %d/255); VT vs matched without relief %.2f dB\n",
               relief.psnr(), relief.worst, flat.psnr());
  EXPECT_LT(relief.psnr(), 48.0);  // measured 42.7 dB with 1 m of relief
  EXPECT_GE(relief.worst, 8);      // measured 22/255
  EXPECT_GE(flat.psnr(), 45.0);
}

// The bilinear mip filter (--vt-filter bilinear): one page lookup from the nearest mip. The VT
// still equals direct splatting at matched LOD with the same filter; its feedback asked for
// exactly the mip it samples (no pixel falls back to an ancestor, none reads a second mip);
// and the view needs fewer resident pages than trilinear, whose finer mip is wanted wherever
// the LOD is past a half.
TEST_F(GpuVtMatchedLod, BilinearVtEqualsDirectSplattingAndNeedsFewerPages) {
  ASSERT_NO_FATAL_FAILURE(converge_and_render(VtMipFilter::Trilinear));
  const uint32_t trilinear_resident = resident;
  const ImageRGBA8 trilinear_img = vt_img;
  ASSERT_NO_FATAL_FAILURE(converge_and_render(VtMipFilter::Bilinear));

  Diff terrain, border, against_trilinear;
  size_t terrain_px = 0, mismatched_mips = 0, second_mip = 0, fractional_lod = 0;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const Probe& p = pr[y * w + x];
      if (p.lod < 0.0f) continue;  // sky
      const uint8_t* a = vt_img.at(int(x), int(y));
      ++terrain_px;
      terrain.add(a, direct_img.at(int(x), int(y)));
      against_trilinear.add(a, trilinear_img.at(int(x), int(y)));
      fractional_lod += p.lod != std::floor(p.lod);
      const int want = std::min(int(p.lod), int(assets.desc.vt.mip_count()) - 1);
      mismatched_mips += int(p.fine_mip) != want;
      second_mip += p.coarse_mip != -1.0f;
      if (p.edge < 1.0f) border.add(a, direct_img.at(int(x), int(y)));
    }
  std::fprintf(stderr,
               "bilinear VT vs matched direct: %.2f dB terrain (%zu px), worst %d/255; border %zu px worst %d/255; "
               "vs trilinear VT %.2f dB; resident pages %u (trilinear %u)\n",
               terrain.psnr(), terrain_px, terrain.worst, border.channels / 3, border.worst, against_trilinear.psnr(),
               resident, trilinear_resident);
  ASSERT_GT(terrain_px, size_t(w * h / 2));
  EXPECT_EQ(fractional_lod, 0u);
  EXPECT_EQ(mismatched_mips, 0u);
  EXPECT_EQ(second_mip, 0u);
  ASSERT_GT(border.channels / 3, 300u);
  EXPECT_GE(terrain.psnr(), 45.0);
  EXPECT_LE(border.worst, 8);
  EXPECT_LT(against_trilinear.psnr(), 45.0);  // the filter changes the picture: mip bands
  EXPECT_LT(resident, trilinear_resident);
}

// CPU reference of tvt_filtered_lod (vt_lod.glsl) for 0 < band < 1.
float brilinear_lod(float lod, float band) {
  const float m = std::floor(lod), f = lod - m;
  return m + std::clamp((f - 0.5f) / band + 0.5f, 0.0f, 1.0f);
}

// Brilinear (--vt-filter brilinear:W): two mips blend only where the LOD's fraction is within
// W/2 of a half. Per pixel, the LOD the VT samples is the trilinear LOD remapped by that band
// (checked against a CPU reference of the remap); only pixels inside the band read a second
// mip; the VT still equals direct splatting at matched LOD; and it sits between the other two
// filters: closer to the trilinear picture than bilinear is, with resident pages between
// theirs (outside the band feedback asks for the one mip sampled).
TEST_F(GpuVtMatchedLod, BrilinearBlendsOnlyInsideItsBandAndSitsBetweenBilinearAndTrilinear) {
  constexpr float band = kDefaultBrilinearBand;
  ASSERT_NO_FATAL_FAILURE(converge_and_render(VtMipFilter::Bilinear));
  const uint32_t bilinear_resident = resident;
  const ImageRGBA8 bilinear_img = vt_img;
  ASSERT_NO_FATAL_FAILURE(converge_and_render(VtMipFilter::Trilinear));
  const uint32_t trilinear_resident = resident;
  const ImageRGBA8 trilinear_img = vt_img;
  const std::vector<Probe> trilinear_pr = pr;
  ASSERT_NO_FATAL_FAILURE(converge_and_render(VtMipFilter{band}));
  EXPECT_EQ(mip_filter_name(VtMipFilter{band}), "brilinear:0.25");

  const int top = int(assets.desc.vt.mip_count()) - 1;
  Diff terrain, border, vs_trilinear, bilinear_vs_trilinear;
  size_t terrain_px = 0, lod_off = 0, mismatched_mips = 0, two_mips = 0, trilinear_two_mips = 0, outside_band = 0;
  float worst_lod = 0.f;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const Probe& p = pr[y * w + x];
      const Probe& t = trilinear_pr[y * w + x];
      ASSERT_EQ(p.lod < 0.0f, t.lod < 0.0f) << x << "," << y;  // same sky
      if (p.lod < 0.0f) continue;
      const uint8_t* a = vt_img.at(int(x), int(y));
      ++terrain_px;
      terrain.add(a, direct_img.at(int(x), int(y)));
      vs_trilinear.add(a, trilinear_img.at(int(x), int(y)));
      bilinear_vs_trilinear.add(bilinear_img.at(int(x), int(y)), trilinear_img.at(int(x), int(y)));
      const float d = std::abs(p.lod - brilinear_lod(t.lod, band));
      worst_lod = std::max(worst_lod, d);
      lod_off += d > 1e-4f;
      mismatched_mips += int(p.fine_mip) != std::min(int(std::floor(p.lod)), top);
      const bool blends = p.coarse_mip != -1.0f;
      two_mips += blends;
      trilinear_two_mips += t.coarse_mip != -1.0f;
      const float f = t.lod - std::floor(t.lod);
      // Reads a second mip only inside the band (1e-4: rounding at its edges).
      outside_band += blends && std::abs(f - 0.5f) > band / 2 + 1e-4f;
      if (p.edge < 1.0f) border.add(a, direct_img.at(int(x), int(y)));
    }
  std::fprintf(stderr,
               "brilinear %.2f: vs matched direct %.2f dB (%zu px), border %zu px worst %d/255; vs trilinear %.2f dB "
               "(bilinear vs trilinear %.2f dB); two-mip pixels %zu (trilinear %zu); resident pages %u (bilinear %u, "
               "trilinear %u); worst LOD remap error %g\n",
               band, terrain.psnr(), terrain_px, border.channels / 3, border.worst, vs_trilinear.psnr(),
               bilinear_vs_trilinear.psnr(), two_mips, trilinear_two_mips, resident, bilinear_resident,
               trilinear_resident, double(worst_lod));
  ASSERT_GT(terrain_px, size_t(w * h / 2));
  EXPECT_EQ(lod_off, 0u);
  EXPECT_EQ(mismatched_mips, 0u);
  EXPECT_EQ(outside_band, 0u);
  EXPECT_GT(two_mips, 0u);
  EXPECT_LT(two_mips, trilinear_two_mips / 2);
  ASSERT_GT(border.channels / 3, 300u);
  EXPECT_GE(terrain.psnr(), 45.0);
  EXPECT_LE(border.worst, 8);
  EXPECT_GT(vs_trilinear.psnr(), bilinear_vs_trilinear.psnr());
  EXPECT_LE(bilinear_resident, resident);
  EXPECT_LE(resident, trilinear_resident);
}
