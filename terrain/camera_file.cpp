// Camera path files (camera_file.h): JSON -> CameraFile (every field checked) -> CameraPath.
#include "terrain/camera_file.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "json/json_check.h"

namespace tvt {

namespace {

using namespace json_check;  // NOLINT: readers, bounds and json types

constexpr double k_deg = std::numbers::pi / 180.0;
constexpr double k_max_time_s = 1e9;
constexpr double k_min_key_spacing_s = 1e-6;

// Degrees as written: rounded to 1e-9 degree (60, not 59.99999999999999, for the default lens).
double written_degrees(double rad) { return std::round(rad / k_deg * 1e9) / 1e9; }

class Parser : public Reader {
 public:
  using Reader::Reader;

  CameraFile file(const json& root) const {
    const Ptr at;
    object(root, at, {"lens", "clearance_m", "keys"});
    CameraFile f;
    f.source_path = source_;
    if (const json* v = field(root, "lens")) f.lens = lens(*v, at / "lens");
    if (const json* v = field(root, "clearance_m")) f.clearance_m = real(*v, at / "clearance_m", closed(0, 1e6));
    const json& list = require(root, at, "keys");
    const Ptr list_at = at / "keys";
    const std::string count = "1 to " + std::to_string(k_camera_max_keys) + " keys";
    if (!list.is_array()) fail(list_at, "must be an array of " + count, list);
    if (list.empty() || list.size() > k_camera_max_keys)
      fail(list_at, "must hold " + count, std::to_string(list.size()) + " keys");
    for (size_t i = 0; i < list.size(); ++i) {
      f.keys.push_back(key(list[i], list_at / i));
      if (i == 0) continue;
      const CameraKeySpec &prev = f.keys[i - 1], &k = f.keys.back();
      if (k.time_s < prev.time_s)
        fail(list_at / i / "time_s", "keys must be in time order (the previous key is at " + show_number(prev.time_s) + " s)",
             show_number(k.time_s));
      // Inside a shot keys are at least a microsecond apart, so spline tangents stay finite.
      if (!k.cut && !(k.time_s - prev.time_s >= k_min_key_spacing_s))
        fail(list_at / i / "time_s",
             "must be at least 1e-06 s later than the previous key (" + show_number(prev.time_s) +
                 " s) inside a shot (\"cut\": true jumps to a new shot at any later or equal time)",
             show_number(k.time_s));
    }
    return f;
  }

 private:
  Camera lens(const json& v, const Ptr& at) const {
    object(v, at, {"vertical_fov_deg", "near_m", "far_m"});
    Camera c;
    if (const json* f = field(v, "vertical_fov_deg"))
      c.vertical_fov_rad = real(*f, at / "vertical_fov_deg", closed(0.01, 179)) * k_deg;
    if (const json* f = field(v, "near_m")) c.near_m = real(*f, at / "near_m", closed(1e-6, 1e6));
    if (const json* f = field(v, "far_m")) c.far_m = real(*f, at / "far_m", above(0, 1e12));
    if (!(c.far_m > c.near_m))
      fail(at / "far_m", "must be greater than near_m (" + show_number(c.near_m) + ")", show_number(c.far_m));
    return c;
  }

  glm::dvec3 point(const json& v, const Ptr& at, size_t n) const {
    double p[3] = {0.0, 0.0, 0.0};
    reals(v, at, n, closed(-k_camera_max_coordinate_m, k_camera_max_coordinate_m), p);
    return {p[0], p[1], p[2]};
  }

  CameraKeySpec key(const json& v, const Ptr& at) const {
    object(v, at, {"time_s", "position_m", "above_ground_m", "yaw_deg", "pitch_deg", "look_at_m", "cut"});
    CameraKeySpec k;
    k.time_s = real(require(v, at, "time_s"), at / "time_s", closed(-k_max_time_s, k_max_time_s));
    const json& position = require(v, at, "position_m");
    if (const json* f = field(v, "above_ground_m")) {
      k.above_ground_m = real(*f, at / "above_ground_m", closed(0, k_camera_max_coordinate_m));
      if (!position.is_array() || position.size() != 2)
        fail(at / "position_m", "must be [x, y] with \"above_ground_m\" (or [x, y, z] without it)", position);
      k.position_m = point(position, at / "position_m", 2);
    } else {
      if (!position.is_array() || position.size() != 3)
        fail(at / "position_m", "must be [x, y, z] (or [x, y] with \"above_ground_m\")", position);
      k.position_m = point(position, at / "position_m", 3);
    }
    const json* yaw = field(v, "yaw_deg");
    const json* pitch = field(v, "pitch_deg");
    if (const json* f = field(v, "look_at_m")) {
      if (yaw || pitch) fail(at / (yaw ? "yaw_deg" : "pitch_deg"), "not allowed with \"look_at_m\"", yaw ? *yaw : *pitch);
      if (!f->is_array() || f->size() != 3) fail(at / "look_at_m", "must be [x, y, z]", *f);
      k.look_at_m = point(*f, at / "look_at_m", 3);
      if (!k.above_ground_m && *k.look_at_m == k.position_m)
        fail(at / "look_at_m", "must differ from the camera position", *f);
    } else {
      if (!yaw) fail(at / "yaw_deg", "required field is missing (or give \"look_at_m\")");
      k.yaw_rad = real(*yaw, at / "yaw_deg", closed(-k_camera_max_coordinate_m, k_camera_max_coordinate_m)) * k_deg;
      if (pitch) k.pitch_rad = real(*pitch, at / "pitch_deg", closed(-90, 90)) * k_deg;
    }
    if (const json* f = field(v, "cut")) k.cut = boolean(*f, at / "cut");
    return k;
  }
};

}  // namespace

Result<CameraFile> parse_camera_file(std::string_view json_text, const std::string& source_path) {
  auto root = json_check::parse(json_text, source_path);
  if (!root) return root.error();
  return json_check::run<CameraFile>([&] { return Parser(source_path).file(root.value()); });
}

Result<CameraFile> load_camera_file(const std::string& path) {
  auto text = json_check::read_text_file(path, "camera");
  if (!text) return text.error();
  return parse_camera_file(text.value(), path);
}

Result<CameraPath> resolve_camera_path(const CameraFile& file, const GroundFn& ground) {
  std::vector<CameraKey> keys;
  keys.reserve(file.keys.size());
  for (size_t i = 0; i < file.keys.size(); ++i) {
    const CameraKeySpec& s = file.keys[i];
    CameraKey k{s.time_s, s.position_m, s.yaw_rad, s.pitch_rad, s.cut};
    const std::string key_at = file.source_path + ": /keys/" + std::to_string(i);
    if (s.above_ground_m) {
      k.position_m.z = ground(s.position_m.x, s.position_m.y) + *s.above_ground_m;
      if (!(std::abs(k.position_m.z) <= k_camera_max_coordinate_m))  // keeps a written path loadable
        return make_error(key_at + "/above_ground_m: puts the camera at z = " + show_number(k.position_m.z) +
                          " m, beyond the 1e9 m limit of coordinates");
    }
    if (s.look_at_m) {
      // Aim from where the camera will be: sample() lifts it to ground + clearance.
      glm::dvec3 from = k.position_m;
      from.z = std::max(from.z, ground(from.x, from.y) + file.clearance_m);
      const glm::dvec3 d = *s.look_at_m - from;
      const double horizontal = std::hypot(d.x, d.y);
      if (horizontal == 0.0 && d.z == 0.0)
        return make_error(key_at + "/look_at_m: must differ from the camera position (where its height and the clearance put it)");
      // Straight up or down: the heading is that of the previous key (any heading is right).
      k.yaw_rad = horizontal > 0.0 ? std::atan2(d.y, d.x) : (keys.empty() ? 0.0 : keys.back().yaw_rad);
      k.pitch_rad = std::atan2(d.z, horizontal);
    }
    keys.push_back(k);
  }
  return CameraPath(std::move(keys), ground, file.clearance_m);
}

std::string camera_file_json(const CameraPath& path, const Camera& lens) {
  using ojson = nlohmann::ordered_json;
  ojson root;
  root["lens"] = {{"vertical_fov_deg", written_degrees(lens.vertical_fov_rad)}, {"near_m", lens.near_m}, {"far_m", lens.far_m}};
  root["clearance_m"] = path.clearance_m();
  ojson keys = ojson::array();
  double turns = 0.0;  // whole turns taken off each shot's yaws (keeps them small; turning is relative)
  for (size_t i = 0; i < path.keys().size(); ++i) {
    const CameraKey& k = path.keys()[i];
    if (i == 0 || k.cut) turns = std::round(k.yaw_rad / (2.0 * std::numbers::pi));
    ojson j;
    j["time_s"] = k.time_s;
    j["position_m"] = {k.position_m.x, k.position_m.y, k.position_m.z};
    j["yaw_deg"] = written_degrees(k.yaw_rad - turns * 2.0 * std::numbers::pi);
    j["pitch_deg"] = std::clamp(written_degrees(k.pitch_rad), -90.0, 90.0);
    if (k.cut) j["cut"] = true;
    keys.push_back(j);
  }
  root["keys"] = keys;
  return root.dump(2) + "\n";
}

}  // namespace tvt
