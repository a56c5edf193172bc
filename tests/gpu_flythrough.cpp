// The VT frame loop end to end (validation on: any message fails the test).
#include <gtest/gtest.h>

#include <cstdio>

#include "compose/image_diff.h"
#include "compose/scene.h"
#include "app/flythrough.h"
#include "support/gpu_test.h"

using namespace tvt;

namespace {
const SceneAssets& assets16() {
  static const SceneAssets a = [] {
    auto r = load_scene_assets(default_scene());
    EXPECT_TRUE(r.ok());
    return std::move(r.value());
  }();
  return a;
}
}  // namespace

class GpuFlythrough : public GpuTest {};

TEST_F(GpuFlythrough, HundredFramesStreamPagesWithValidationSilent) {
  FlythroughOptions o;
  o.frames = 100;
  o.width = 128;
  o.height = 72;
  o.fps = 4.0;  // covers the whole default path, camera cut included
  o.feedback_divisor = 4;
  o.vt.cache_slots = 128;
  o.vt.page_budget = 6;
  o.vt.window_pages = 32;
  uint32_t with_feedback = 0, max_resident = 0;
  ImageRGBA8 last;
  auto s = run_flythrough(ctx(), assets16(), o, [&](const FlythroughFrame& f, const FlythroughViews& views) {
    with_feedback += f.feedback_pages > 0;
    max_resident = std::max(max_resident, f.vt.residency.resident);
    EXPECT_LE(f.vt.composed, o.vt.page_budget);
    EXPECT_LE(f.feedback_frames_late, o.frames_in_flight + 1u);  // typically frames_in_flight
    if (f.index + 1 == o.frames) last = views.frame();
    return true;
  });
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(s->frames, 100u);
  EXPECT_GT(with_feedback, 80u);            // feedback arrives 1-2 frames late, every frame
  EXPECT_GT(s->pages_composed, 100u);
  EXPECT_EQ(max_resident, o.vt.cache_slots);  // the cache fills, then pages are evicted
  // The frame shows terrain texture: not all one colour.
  ASSERT_EQ(last.width, 128);
  uint8_t lo = 255, hi = 0;
  for (size_t i = 1; i < last.texels.size(); i += 4) lo = std::min(lo, last.texels[i]), hi = std::max(hi, last.texels[i]);
  EXPECT_GT(hi - lo, 30);
}

TEST_F(GpuFlythrough, OversubscribedCacheRaisesTheMipBiasAndFinishes) {
  FlythroughOptions o;
  o.frames = 30;
  o.width = 160;
  o.height = 90;
  o.feedback_divisor = 2;
  o.vt.cache_slots = 16;  // far below the working set of a 160x90 view
  o.vt.page_budget = 4;
  o.vt.window_pages = 16;
  auto s = run_flythrough(ctx(), assets16(), o, [](const FlythroughFrame&, const auto&) { return true; });
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(s->frames, 30u);
  EXPECT_GT(s->oversubscribed_frames, 0u);
  EXPECT_GT(s->max_mip_bias, 0u);
}

TEST_F(GpuFlythrough, BadOptionsAreErrorsNotCrashes) {
  FlythroughOptions o;
  o.frames = 2;
  o.width = 64;
  o.height = 64;
  o.vt.cache_slots = 8;
  o.vt.page_budget = 9;  // more than the cache
  auto s = run_flythrough(ctx(), assets16(), o, {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("page_budget"), std::string::npos);
  o.vt.page_budget = 4;
  o.feedback_divisor = 0;
  auto d = run_flythrough(ctx(), assets16(), o, {});
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find("feedback_divisor"), std::string::npos);
}

// Pages composed in a frame are mapped before that frame's terrain pass, so no frame, not
// even the first or the one after a cut, shows the "no data" colour (magenta albedo).
TEST_F(GpuFlythrough, PagesAreSampledInTheFrameThatComposesThem) {
  FlythroughOptions o;
  o.frames = 8;
  o.width = 96;
  o.height = 54;
  o.fps = 10.0;
  o.vt.cache_slots = 64;
  o.vt.page_budget = 8;
  o.vt.window_pages = 16;
  auto camera = parse_camera_file(R"({"keys": [
      {"time_s": 0, "position_m": [1500, 1500], "above_ground_m": 30, "look_at_m": [4000, 4000, 0]},
      {"time_s": 0.35, "position_m": [7000, 1200, 900], "yaw_deg": 150, "pitch_deg": -30, "cut": true},
      {"time_s": 1, "position_m": [7000, 1300, 900], "yaw_deg": 160, "pitch_deg": -30}]})",
                                  "test-camera.json");
  ASSERT_TRUE(camera.ok()) << camera.error().message;
  o.camera = camera.value();
  auto s = run_flythrough(ctx(), assets16(), o, [&](const FlythroughFrame& f, const FlythroughViews& views) {
    if (f.index == 0) {
      EXPECT_GT(f.vt.composed, 0u);
      EXPECT_EQ(f.completed.size(), f.vt.composed);  // resident the frame they were composed
      EXPECT_GT(f.vt.table_updates, 0u);
    }
    const ImageRGBA8 img = views.frame();
    uint32_t no_data = 0;
    for (size_t i = 0; i < img.texels.size(); i += 4) {
      const int r = img.texels[i], g = img.texels[i + 1], b = img.texels[i + 2];
      no_data += r > 2 * g + 40 && b > 2 * g + 40;
    }
    EXPECT_EQ(no_data, 0u) << "frame " << f.index << (f.cut ? " (cut)" : "");
    return true;
  });
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(s->frames, 8u);
}

// Every feedback writer drives the loop. In deterministic mode (feedback read exactly one frame
// late) attachment feedback and main-pass stores report the same texels, so the two runs
// request and compose the same pages at the same frames and show the same images; the separate
// pass differs in the mip near LOD boundaries but streams the same path to a sharp end.
TEST_F(GpuFlythrough, EveryFeedbackWriterDrivesTheLoopAndAttachmentEqualsStores) {
  struct Run {
    std::vector<std::vector<PageId>> completed;
    ImageRGBA8 last;
    uint64_t composed = 0;
  };
  auto fly = [&](FeedbackMode mode) {
    FlythroughOptions o;
    o.frames = 24;
    o.width = 96;
    o.height = 54;
    o.fps = 2.0;
    o.feedback_divisor = 4;
    o.feedback_mode = mode;
    o.deterministic = true;
    o.vt.cache_slots = 256;
    o.vt.page_budget = 12;
    Run r;
    auto s = run_flythrough(ctx(), assets16(), o, [&](const FlythroughFrame& f, const FlythroughViews& views) {
      r.completed.push_back(f.completed);
      if (f.index + 1 == o.frames) r.last = views.frame();
      return true;
    });
    EXPECT_TRUE(s.ok()) << s.error().message;
    if (s) r.composed = s->pages_composed;
    return r;
  };
  EXPECT_EQ(FlythroughOptions{}.feedback_mode, FeedbackMode::Attachment);
  const Run attachment = fly(FeedbackMode::Attachment), stores = fly(FeedbackMode::MainPass);
  const Run separate = fly(FeedbackMode::SeparatePass);
  std::fprintf(stderr, "pages composed: attachment %llu, stores %llu, separate %llu; last frame attachment vs separate %.1f dB\n",
               static_cast<unsigned long long>(attachment.composed), static_cast<unsigned long long>(stores.composed),
               static_cast<unsigned long long>(separate.composed), compare_images(attachment.last, separate.last).psnr_db);
  EXPECT_GT(attachment.composed, 50u);
  EXPECT_EQ(attachment.completed, stores.completed);
  EXPECT_EQ(compare_images(attachment.last, stores.last).max_abs, 0u);
  EXPECT_GT(separate.composed, 50u);
  // Same path, nearly the same pages: the separate pass's derivatives span 2N pixels.
  EXPECT_GE(compare_images(attachment.last, separate.last).psnr_db, 35.0);
}
