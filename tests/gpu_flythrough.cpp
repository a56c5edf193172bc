// The VT frame loop end to end (validation on: any message fails the test).
#include <gtest/gtest.h>

#include "compose/scene.h"
#include "render/flythrough.h"
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
