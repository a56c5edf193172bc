// Camera path files (terrain/camera_file.h): every field parsed and resolved over the ground,
// the built-in flythrough written and read back to the same path, every bad field reported
// with file and JSON pointer, and extreme values giving finite cameras.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "terrain/camera_file.h"

namespace {

using tvt::Camera;
using tvt::CameraFile;
using tvt::CameraPath;

constexpr double k_deg = std::numbers::pi / 180.0;

double ground(double x, double y) { return 100.0 + 0.01 * x - 0.02 * y; }

CameraFile parse_ok(const std::string& text) {
  auto f = tvt::parse_camera_file(text, "cam.json");
  EXPECT_TRUE(f.ok()) << (f.ok() ? "" : f.error().message);
  return f.ok() ? f.value() : CameraFile{};
}

CameraPath resolve_ok(const CameraFile& f) {
  auto p = tvt::resolve_camera_path(f, ground);
  EXPECT_TRUE(p.ok()) << (p.ok() ? "" : p.error().message);
  return p.ok() ? p.value() : CameraPath({tvt::CameraKey{}});
}

bool finite(const glm::dmat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

TEST(CameraFile, ParsesEveryFieldAndResolvesOverTheGround) {
  const CameraFile f = parse_ok(R"({
    "lens": {"vertical_fov_deg": 40, "near_m": 0.25, "far_m": 5000},
    "clearance_m": 3,
    "keys": [
      {"time_s": 1, "position_m": [100, 200, 900], "yaw_deg": 90, "pitch_deg": -30},
      {"time_s": 3, "position_m": [300, 400], "above_ground_m": 50, "look_at_m": [300, 500, 250]},
      {"time_s": 3, "position_m": [1000, 1000, 2000], "yaw_deg": -45, "cut": true},
      {"time_s": 4, "position_m": [1000, 1000], "above_ground_m": 0, "look_at_m": [1000, 1000, 0]}
    ]})");
  EXPECT_EQ(f.source_path, "cam.json");
  EXPECT_DOUBLE_EQ(f.lens.vertical_fov_rad, 40 * k_deg);
  EXPECT_EQ(f.lens.near_m, 0.25);
  EXPECT_EQ(f.lens.far_m, 5000);
  EXPECT_EQ(f.clearance_m, 3);
  ASSERT_EQ(f.keys.size(), 4u);

  const CameraPath p = resolve_ok(f);
  ASSERT_EQ(p.keys().size(), 4u);
  EXPECT_EQ(p.clearance_m(), 3);
  EXPECT_EQ(p.start_time(), 1);
  EXPECT_EQ(p.end_time(), 4);
  ASSERT_EQ(p.cut_times(), std::vector<double>{3.0});
  const auto& k = p.keys();
  EXPECT_EQ(k[0].position_m, glm::dvec3(100, 200, 900));
  EXPECT_DOUBLE_EQ(k[0].yaw_rad, 90 * k_deg);
  EXPECT_DOUBLE_EQ(k[0].pitch_rad, -30 * k_deg);
  // Above the ground, looking at a point: z from the ground, yaw/pitch from the direction.
  const double z1 = ground(300, 400) + 50;
  EXPECT_DOUBLE_EQ(k[1].position_m.z, z1);
  EXPECT_NEAR(k[1].yaw_rad, 90 * k_deg, 1e-12);
  EXPECT_NEAR(k[1].pitch_rad, std::atan2(250 - z1, 100.0), 1e-12);
  EXPECT_EQ(k[2].pitch_rad, 0.0);  // pitch defaults to level
  EXPECT_TRUE(k[2].cut);
  // Straight down: pitch -90 degrees, the heading of the key before.
  EXPECT_NEAR(k[3].pitch_rad, -0.5 * std::numbers::pi, 1e-15);
  EXPECT_NEAR(k[3].yaw_rad, -45 * k_deg, 1e-12);
  // The path passes through its keys (lifted above ground + clearance where needed).
  EXPECT_EQ(p.sample(1).position_m, k[0].position_m);
  EXPECT_NEAR(p.sample(3).position_m.x, 1000, 1e-9);  // at the cut: the new shot
  EXPECT_GE(p.sample(4).position_m.z, ground(1000, 1000) + 3 - 1e-9);
}

// Forward direction of the sampled camera (yaw may differ by whole turns).
glm::dvec3 forward(const CameraPath& p, double t) {
  Camera c = p.camera_at(t);
  return c.forward();
}

TEST(CameraFile, TheBuiltInFlythroughWrittenAndReadBackIsTheSamePath) {
  const double extent = 8192, height = 600;
  const CameraPath original = CameraPath::default_flythrough(extent, height, ground);
  Camera lens;
  lens.far_m = 25000;
  const std::string text = tvt::camera_file_json(original, lens);
  const CameraFile f = parse_ok(text);
  const CameraPath back = resolve_ok(f);
  EXPECT_DOUBLE_EQ(f.lens.vertical_fov_rad, lens.vertical_fov_rad);
  EXPECT_EQ(f.lens.far_m, 25000);
  EXPECT_EQ(back.clearance_m(), original.clearance_m());
  EXPECT_EQ(back.cut_times(), original.cut_times());
  for (int i = 0; i <= 500; ++i) {
    const double t = original.start_time() + (original.end_time() - original.start_time()) * i / 500.0;
    const auto a = original.sample(t), b = back.sample(t);
    EXPECT_NEAR(glm::length(a.position_m - b.position_m), 0.0, 1e-6) << "t " << t;
    EXPECT_NEAR(glm::length(forward(original, t) - forward(back, t)), 0.0, 1e-9) << "t " << t;
  }
  // Writing the read-back path gives the same text (a stable template).
  EXPECT_EQ(tvt::camera_file_json(back, f.lens), text);
}

TEST(CameraFile, WholeTurnsAreTakenOffEachShotWithoutChangingTheTurns) {
  // Yaws of several turns and a half-turn step: written small, turning the same way.
  std::vector<tvt::CameraKey> keys = {
      {0.0, {0, 0, 500}, 1000 * k_deg, 0.0, false},  {1.0, {10, 0, 500}, 1180 * k_deg, 0.0, false},
      {2.0, {20, 0, 500}, 1300 * k_deg, 0.0, false}, {3.0, {0, 50, 500}, -4000 * k_deg, -0.3, true},
      {4.0, {0, 60, 500}, -3950 * k_deg, -0.3, false}};
  const CameraPath original(keys);
  const std::string text = tvt::camera_file_json(original, Camera{});
  const CameraPath back = resolve_ok(parse_ok(text));
  for (const tvt::CameraKey& k : back.keys()) EXPECT_LE(std::abs(k.yaw_rad), 2.0 * std::numbers::pi) << text;
  for (int i = 0; i <= 400; ++i) {
    const double t = 4.0 * i / 400.0;
    EXPECT_NEAR(glm::length(forward(original, t) - forward(back, t)), 0.0, 1e-9) << "t " << t;
  }
}

TEST(CameraFile, EveryBadFieldNamesFileAndPointer) {
  const std::string key0 = R"({"time_s": 0, "position_m": [0, 0, 10], "yaw_deg": 0})";
  auto with_keys = [](const std::string& keys) { return "{\"keys\": [" + keys + "]}"; };
  const std::pair<std::string, std::string> cases[] = {
      {"", "invalid JSON"},
      {"[1, 2]", "<root>: must be an object"},
      {"{\"keys\": [], \"speed\": 3}", "/speed: unknown field"},
      {"{}", "/keys: required field is missing"},
      {"{\"keys\": {}}", "/keys: must be an array"},
      {"{\"keys\": []}", "/keys: must hold 1 to 100000 keys"},
      {with_keys("3"), "/keys/0: must be an object"},
      {with_keys(R"({"position_m": [0, 0, 1], "yaw_deg": 0})"), "/keys/0/time_s: required field is missing"},
      {with_keys(R"({"time_s": "0", "position_m": [0, 0, 1], "yaw_deg": 0})"), "/keys/0/time_s: must be a finite number"},
      {with_keys(R"({"time_s": 2e9, "position_m": [0, 0, 1], "yaw_deg": 0})"), "/keys/0/time_s: must be a finite number in [-1e+09, 1e+09]"},
      {with_keys(R"({"time_s": 1e999, "position_m": [0, 0, 1], "yaw_deg": 0})"), "/keys/0/time_s: number is out of range"},
      {with_keys(R"({"time_s": 0, "yaw_deg": 0})"), "/keys/0/position_m: required field is missing"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0], "yaw_deg": 0})"), "/keys/0/position_m: must be [x, y, z]"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1], "above_ground_m": 5, "yaw_deg": 0})"), "/keys/0/position_m: must be [x, y]"},
      {with_keys(R"({"time_s": 0, "position_m": [0, "a", 1], "yaw_deg": 0})"), "/keys/0/position_m/1: must be a finite number"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 2e9], "yaw_deg": 0})"), "/keys/0/position_m/2: must be a finite number in"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0], "above_ground_m": -1, "yaw_deg": 0})"), "/keys/0/above_ground_m: must be a finite number in [0, "},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1]})"), "/keys/0/yaw_deg: required field is missing"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1], "yaw_deg": null})"), "/keys/0/yaw_deg: must be a finite number"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1], "yaw_deg": 0, "pitch_deg": -90.5})"), "/keys/0/pitch_deg: must be a finite number in [-90, 90]"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1], "yaw_deg": 0, "look_at_m": [1, 1, 1]})"), "/keys/0/yaw_deg: not allowed with \"look_at_m\""},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1], "pitch_deg": 0, "look_at_m": [1, 1, 1]})"), "/keys/0/pitch_deg: not allowed with \"look_at_m\""},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1], "look_at_m": [1, 1]})"), "/keys/0/look_at_m: must be [x, y, z]"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1], "look_at_m": [0, 0, 1]})"), "/keys/0/look_at_m: must differ from the camera position"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1], "yaw_deg": 0, "cut": 1})"), "/keys/0/cut: must be true or false"},
      {with_keys(R"({"time_s": 0, "position_m": [0, 0, 1], "yaw_deg": 0, "roll_deg": 0})"), "/keys/0/roll_deg: unknown field"},
      {with_keys(R"({"time_s": 0, "time_s": 1, "position_m": [0, 0, 1], "yaw_deg": 0})"), "/keys/0/time_s: duplicate field"},
      {with_keys(key0 + "," + R"({"time_s": -1, "position_m": [0, 0, 1], "yaw_deg": 0})"), "/keys/1/time_s: keys must be in time order"},
      {with_keys(key0 + "," + R"({"time_s": -1, "position_m": [0, 0, 1], "yaw_deg": 0, "cut": true})"), "/keys/1/time_s: keys must be in time order"},
      {with_keys(key0 + "," + R"({"time_s": 0, "position_m": [0, 0, 1], "yaw_deg": 0})"), "/keys/1/time_s: must be at least 1e-06 s later than the previous key (0 s) inside a shot"},
      {with_keys(key0 + "," + R"({"time_s": 1e-7, "position_m": [0, 0, 1], "yaw_deg": 0})"), "/keys/1/time_s: must be at least 1e-06 s later"},
      {"{\"lens\": 60, \"keys\": [" + key0 + "]}", "/lens: must be an object"},
      {"{\"lens\": {\"vertical_fov_deg\": 0}, \"keys\": [" + key0 + "]}", "/lens/vertical_fov_deg: must be a finite number in [0.01, 179]"},
      {"{\"lens\": {\"vertical_fov_deg\": 180}, \"keys\": [" + key0 + "]}", "/lens/vertical_fov_deg: must be a finite number in [0.01, 179]"},
      {"{\"lens\": {\"near_m\": 0}, \"keys\": [" + key0 + "]}", "/lens/near_m: must be a finite number in"},
      {"{\"lens\": {\"far_m\": 1e13}, \"keys\": [" + key0 + "]}", "/lens/far_m: must be a finite number <= 1e+12"},
      {"{\"lens\": {\"near_m\": 10, \"far_m\": 10}, \"keys\": [" + key0 + "]}", "/lens/far_m: must be greater than near_m (10)"},
      {"{\"lens\": {\"far_m\": 0.1}, \"keys\": [" + key0 + "]}", "/lens/far_m: must be greater than near_m (0.5)"},
      {"{\"clearance_m\": -1, \"keys\": [" + key0 + "]}", "/clearance_m: must be a finite number in [0, 1e+06]"},
  };
  for (const auto& [text, expect] : cases) {
    const auto r = tvt::parse_camera_file(text, "cam.json");
    ASSERT_FALSE(r.ok()) << text;
    const std::string& m = r.error().message;
    EXPECT_EQ(m.rfind("cam.json: ", 0), 0u) << m;
    EXPECT_NE(m.find(expect), std::string::npos) << "expected \"" << expect << "\" in: " << m;
  }
}

TEST(CameraFile, ALookAtKeyAimsFromWhereTheClearanceLiftsTheCamera) {
  const CameraFile f = parse_ok(R"({"clearance_m": 2, "keys": [
      {"time_s": 0, "position_m": [0, 0], "above_ground_m": 0, "look_at_m": [10, 0, 100.1]}]})");
  const CameraPath p = resolve_ok(f);  // camera at ground(0, 0) + 2 = 102; target 1.9 m below
  EXPECT_NEAR(p.keys()[0].pitch_rad, std::atan2(100.1 - 102.0, 10.0), 1e-12);
  EXPECT_NEAR(p.sample(0).position_m.z, 102.0, 1e-12);
}

TEST(CameraFile, ALookAtPointOnTheResolvedPositionIsAnErrorNamingTheKey) {
  const CameraFile f = parse_ok(R"({"keys": [
      {"time_s": 0, "position_m": [0, 0, 500], "yaw_deg": 0},
      {"time_s": 1, "position_m": [0, 0], "above_ground_m": 20, "look_at_m": [0, 0, 120]}]})");
  const auto p = tvt::resolve_camera_path(f, ground);  // ground(0, 0) + 20 = 120: the same point
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.error().message.rfind("cam.json: /keys/1/look_at_m: must differ from the camera position", 0), 0u)
      << p.error().message;
}

TEST(CameraFile, AHeightAboveGroundBeyondTheCoordinateLimitIsAnErrorNamingTheKey) {
  const CameraFile f = parse_ok(R"({"keys": [{"time_s": 0, "position_m": [0, 0], "above_ground_m": 1e9, "yaw_deg": 0}]})");
  const auto p = tvt::resolve_camera_path(f, ground);  // 100 m of ground below
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.error().message.rfind("cam.json: /keys/0/above_ground_m: puts the camera at z = 1000000100 m", 0), 0u)
      << p.error().message;
}

TEST(CameraFile, ExtremeValuesGiveFiniteCameras) {
  const CameraFile f = parse_ok(R"({
    "lens": {"vertical_fov_deg": 179, "near_m": 1e-6, "far_m": 1e12},
    "keys": [
      {"time_s": -1e9, "position_m": [-1e9, 1e9, 1e9], "yaw_deg": 1e9, "pitch_deg": 90},
      {"time_s": -999999999.99999, "position_m": [1e9, -1e9], "above_ground_m": 0, "look_at_m": [-1e9, -1e9, -1e9]},
      {"time_s": 1e9, "position_m": [1e9, 1e9, -1e9], "yaw_deg": 0, "pitch_deg": 0},
      {"time_s": 1e9, "position_m": [0, 0, 0], "yaw_deg": -1e9, "pitch_deg": -90, "cut": true}
    ]})");
  const CameraPath p = resolve_ok(f);
  for (const double t : {-2e9, -1e9, -1.0, 0.0, 5e8, 1e9, 3e9}) {
    for (const double fov : {0.01 * k_deg, 179 * k_deg}) {
      Camera lens = f.lens;
      lens.vertical_fov_rad = fov;
      const Camera c = p.camera_at(t, lens);
      EXPECT_TRUE(std::isfinite(c.position_m.x) && std::isfinite(c.position_m.y) && std::isfinite(c.position_m.z)) << t;
      EXPECT_TRUE(finite(c.clip_from_relative(16.0 / 9.0))) << "t " << t << " fov " << fov;
      EXPECT_NEAR(glm::length(c.forward()), 1.0, 1e-12);
    }
  }
}

TEST(CameraFile, TruncatedAndCorruptedTextNeverCrashes) {
  const std::string text = tvt::camera_file_json(CameraPath::default_flythrough(4096, 300, ground), Camera{});
  for (size_t n = 0; n < text.size(); n += 7) {
    const auto r = tvt::parse_camera_file(text.substr(0, n), "cut.json");
    EXPECT_FALSE(r.ok()) << n;
    if (!r.ok()) {
      EXPECT_EQ(r.error().message.rfind("cut.json: ", 0), 0u) << r.error().message;
    }
  }
  uint32_t state = 12345;
  for (int i = 0; i < 2000; ++i) {
    std::string t = text;
    state = state * 1664525u + 1013904223u;
    t[state % t.size()] = char(state >> 24);
    const auto r = tvt::parse_camera_file(t, "flip.json");
    if (r.ok()) {  // still a valid file: it resolves, or names the key it cannot
      const auto p = tvt::resolve_camera_path(r.value(), ground);
      if (!p.ok()) {
        EXPECT_EQ(p.error().message.rfind("flip.json: /keys/", 0), 0u) << p.error().message;
      }
    } else {
      EXPECT_EQ(r.error().message.rfind("flip.json: ", 0), 0u) << r.error().message;
    }
  }
}

TEST(CameraFile, MissingFileIsNamed) {
  const auto r = tvt::load_camera_file("/nonexistent/dir/cam.json");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message, "/nonexistent/dir/cam.json: cannot read camera file: file not found");
}

}  // namespace
