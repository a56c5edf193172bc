// Camera path files: the flythrough `terravt render --camera FILE` follows, and the file
// `--save-camera FILE` writes (the built-in flythrough as a template). Format and rules:
// docs/renderer.md §Camera path files. No Vulkan here.
//
//   {
//     "lens": {"vertical_fov_deg": 60, "near_m": 0.5, "far_m": 100000},
//     "clearance_m": 2,
//     "keys": [
//       {"time_s": 0,  "position_m": [1200, 900, 350], "yaw_deg": 30, "pitch_deg": -10},
//       {"time_s": 5,  "position_m": [2000, 1400], "above_ground_m": 40, "look_at_m": [2600, 1800, 200]},
//       {"time_s": 6,  "position_m": [9000, 500, 800], "yaw_deg": 135, "pitch_deg": -20, "cut": true}
//     ]
//   }
//
// A key's height is absolute (3 numbers) or above the ground (2 numbers + above_ground_m); its
// direction is yaw/pitch or a point to look at. Both may depend on the ground, so a file is
// parsed first (every field checked) and resolved against a terrain afterwards.
#pragma once
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "terrain/camera.h"
#include "vt/result.h"

namespace tvt {

struct CameraKeySpec {
  double time_s = 0.0;
  glm::dvec3 position_m{0.0};            // z unused when above_ground_m is set
  std::optional<double> above_ground_m;  // z = ground(x, y) + this
  double yaw_rad = 0.0, pitch_rad = 0.0;  // unused when look_at_m is set
  std::optional<glm::dvec3> look_at_m;
  bool cut = false;
};

struct CameraFile {
  std::string source_path;  // for error messages
  Camera lens;              // vertical FOV, near, far (position and angles unused)
  double clearance_m = 2.0;  // samples are lifted to at least ground + clearance
  std::vector<CameraKeySpec> keys;
};

// Limits (documented with the format): coordinates within 1e9 m of the origin (resolved
// heights too), yaw within 1e9 degrees, times within 1e9 s and keys of a shot at least 1e-6 s
// apart, at most 100000 keys.
inline constexpr double k_camera_max_coordinate_m = 1e9;
inline constexpr size_t k_camera_max_keys = 100000;

// Parses and checks a camera file's text; errors name source and field (JSON pointer).
Result<CameraFile> parse_camera_file(std::string_view json_text, const std::string& source_path);
Result<CameraFile> load_camera_file(const std::string& path);

// The path for a terrain whose ground height is `ground` (never null). Errors (a look-at point
// on its key's resolved position, a resolved height beyond the coordinate limit) name the file
// and the key's field.
Result<CameraPath> resolve_camera_path(const CameraFile& file, const GroundFn& ground);

// A camera file holding `path` with absolute positions and yaw/pitch, and `lens`: loading it
// gives the same path (angles are written rounded to 1e-9 degree).
std::string camera_file_json(const CameraPath& path, const Camera& lens);

}  // namespace tvt
