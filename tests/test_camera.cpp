// Camera maths, frustum and camera paths (terrain/camera.h).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "terrain/camera.h"

namespace tvt {
namespace {

glm::dvec3 clip_to_ndc(const glm::dmat4& m, const glm::dvec3& rel) {
  const glm::dvec4 c = m * glm::dvec4(rel, 1.0);
  return glm::dvec3(c) / c.w;
}

TEST(CameraTest, ProjectionIsReverseZWithVulkanAxes) {
  Camera cam;
  cam.yaw_rad = 0.3;
  cam.pitch_rad = -0.2;
  cam.near_m = 0.5;
  cam.far_m = 1000.0;
  const glm::dmat4 m = cam.clip_from_relative(16.0 / 9.0);
  EXPECT_NEAR(clip_to_ndc(m, cam.forward() * cam.near_m).z, 1.0, 1e-12);  // near plane -> depth 1
  EXPECT_NEAR(clip_to_ndc(m, cam.forward() * cam.far_m).z, 0.0, 1e-12);   // far plane -> depth 0
  const glm::dvec3 mid = clip_to_ndc(m, cam.forward() * 10.0);
  EXPECT_NEAR(mid.x, 0.0, 1e-12);
  EXPECT_NEAR(mid.y, 0.0, 1e-12);
  // Right of the view axis -> +x; above it -> -y (Vulkan framebuffer y points down).
  EXPECT_GT(clip_to_ndc(m, cam.forward() * 10.0 + cam.right()).x, 0.0);
  EXPECT_LT(clip_to_ndc(m, cam.forward() * 10.0 + cam.up()).y, 0.0);
  // Depth decreases monotonically with distance.
  EXPECT_GT(clip_to_ndc(m, cam.forward() * 5.0).z, clip_to_ndc(m, cam.forward() * 50.0).z);
}

TEST(CameraTest, BasisIsOrthonormalLookingStraightDown) {
  Camera cam;
  cam.yaw_rad = 1.1;
  cam.pitch_rad = -std::numbers::pi / 2;
  EXPECT_NEAR(cam.forward().z, -1.0, 1e-12);
  EXPECT_NEAR(glm::length(cam.right()), 1.0, 1e-12);
  EXPECT_NEAR(glm::length(cam.up()), 1.0, 1e-12);
  EXPECT_NEAR(glm::dot(cam.right(), cam.forward()), 0.0, 1e-12);
  EXPECT_NEAR(glm::dot(cam.up(), cam.forward()), 0.0, 1e-12);
  // Right-handed view space: right x up = -forward.
  const glm::dvec3 back = glm::cross(cam.right(), cam.up());
  EXPECT_NEAR(glm::length(back + cam.forward()), 0.0, 1e-12);
}

TEST(CameraTest, FrustumCullsBoxesBehindBesideAndBeyondFar) {
  Camera cam;  // at the origin looking along +x
  cam.far_m = 1000.0;
  const Frustum f = Frustum::from_clip(cam.clip_from_relative(1.0));
  auto box = [&](glm::dvec3 c, double r) { return f.intersects_box(c - glm::dvec3(r), c + glm::dvec3(r)); };
  EXPECT_TRUE(box({100, 0, 0}, 1));
  EXPECT_FALSE(box({-100, 0, 0}, 1));    // behind
  EXPECT_FALSE(box({100, 200, 0}, 1));   // beside (60 degree fov, aspect 1)
  EXPECT_FALSE(box({100, 0, 200}, 1));   // above
  EXPECT_FALSE(box({2000, 0, 0}, 1));    // beyond far
  EXPECT_FALSE(box({0.1, 0, 0}, 0.05));  // before near
  EXPECT_TRUE(box({0, 0, 0}, 1));        // contains the camera
  EXPECT_TRUE(box({100, 200, 0}, 150));  // large box reaching into the view
}

// Rolling hills for path tests: up to 300 m.
double hills(double x, double y) { return 150.0 + 150.0 * std::sin(x * 0.002) * std::cos(y * 0.0015); }

TEST(CameraPathTest, KeysAreHitAndShotsHoldAtTheirEnds) {
  std::vector<CameraKey> keys = {
      {0.0, {0, 0, 10}, 0.0, 0.0},
      {1.0, {10, 0, 10}, 0.5, -0.1},
      {2.0, {20, 5, 12}, 1.0, -0.2},
      {5.0, {500, 500, 50}, 3.0, -0.3, true},
      {6.0, {510, 500, 50}, 3.2, -0.3},
  };
  const CameraPath path(keys);
  for (const CameraKey& k : keys) {
    const CameraPose p = path.sample(k.time_s);
    EXPECT_NEAR(glm::length(p.position_m - k.position_m), 0.0, 1e-9) << k.time_s;
    EXPECT_NEAR(p.yaw_rad, k.yaw_rad, 1e-9);
    EXPECT_NEAR(p.pitch_rad, k.pitch_rad, 1e-9);
  }
  // Between the first shot's end (t=2) and the cut (t=5) the camera holds.
  EXPECT_NEAR(glm::length(path.sample(4.999).position_m - keys[2].position_m), 0.0, 1e-9);
  EXPECT_EQ(path.cut_times(), std::vector<double>{5.0});
  // Before the start and after the end: held.
  EXPECT_NEAR(glm::length(path.sample(-1.0).position_m - keys[0].position_m), 0.0, 1e-9);
  EXPECT_NEAR(glm::length(path.sample(9.0).position_m - keys[4].position_m), 0.0, 1e-9);
}

TEST(CameraPathTest, YawTurnsTheShortWay) {
  const CameraPath path({{0.0, {0, 0, 0}, 3.0, 0.0}, {1.0, {1, 0, 0}, -3.0, 0.0}});
  // From 3 rad to -3 rad the short way passes through pi, not through 0.
  EXPECT_NEAR(std::cos(path.sample(0.5).yaw_rad), -1.0, 1e-3);
}

TEST(CameraPathTest, DefaultFlythroughIsContinuousExceptAtTheCutAndAboveGround) {
  const double extent = 16384.0, height = 300.0;
  const CameraPath path = CameraPath::default_flythrough(extent, height, hills);
  const std::vector<double> cuts = path.cut_times();
  ASSERT_EQ(cuts.size(), 1u);
  const double dt = 1.0 / 240.0;
  double max_step = 0.0, cut_step = 0.0, max_turn = 0.0;
  CameraPose prev = path.sample(path.start_time());
  double lowest_margin = 1e300;
  for (double t = path.start_time() + dt; t <= path.end_time() + 1e-9; t += dt) {
    const CameraPose p = path.sample(t);
    const double step = glm::length(p.position_m - prev.position_m);
    const bool crosses_cut = t - dt < cuts[0] && t >= cuts[0];
    if (crosses_cut) {
      cut_step = step;
    } else {
      max_step = std::max(max_step, step);
      max_turn = std::max({max_turn, std::abs(p.yaw_rad - prev.yaw_rad), std::abs(p.pitch_rad - prev.pitch_rad)});
    }
    lowest_margin = std::min(lowest_margin, p.position_m.z - (hills(p.position_m.x, p.position_m.y) + path.clearance_m()));
    ASSERT_TRUE(std::isfinite(p.position_m.x) && std::isfinite(p.position_m.y) && std::isfinite(p.position_m.z));
    prev = p;
  }
  EXPECT_GE(lowest_margin, -1e-9);
  // Continuous: no step faster than ~1.5 km/s (the climb is the fastest part).
  EXPECT_LT(max_step, 1500.0 * dt);
  EXPECT_LT(max_turn, 2.0 * dt);
  // The cut jumps by kilometres in one sample.
  EXPECT_GT(cut_step, 0.1 * extent);
  // It covers a low pass (near the ground) and a climb (high above the highest ground).
  double lowest = 1e300, highest = 0.0;
  for (double t = 0.0; t < cuts[0]; t += 0.1) {
    const CameraPose p = path.sample(t);
    const double agl = p.position_m.z - hills(p.position_m.x, p.position_m.y);
    lowest = std::min(lowest, agl);
    highest = std::max(highest, p.position_m.z);
  }
  EXPECT_LT(lowest, 0.01 * extent);
  EXPECT_GT(highest, height + 0.1 * extent);
}

}  // namespace
}  // namespace tvt
