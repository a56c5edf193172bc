// Camera maths and keyframed camera paths (see camera.h).
#include "terrain/camera.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "vt/result.h"

namespace tvt {

glm::dvec3 Camera::forward() const {
  return {std::cos(pitch_rad) * std::cos(yaw_rad), std::cos(pitch_rad) * std::sin(yaw_rad), std::sin(pitch_rad)};
}

glm::dvec3 Camera::right() const { return {std::sin(yaw_rad), -std::cos(yaw_rad), 0.0}; }

glm::dvec3 Camera::up() const { return glm::cross(right(), forward()); }

glm::dmat4 Camera::view_rotation() const {
  const glm::dvec3 r = right(), u = up(), f = forward();
  glm::dmat4 m(1.0);  // m[col][row]
  for (int c = 0; c < 3; ++c) {
    m[c][0] = r[c];
    m[c][1] = u[c];
    m[c][2] = -f[c];
  }
  return m;
}

glm::dmat4 Camera::projection(double aspect) const {
  TVT_CHECK(aspect > 0.0 && near_m > 0.0 && far_m > near_m);
  const double f = 1.0 / std::tan(vertical_fov_rad * 0.5);
  glm::dmat4 p(0.0);
  p[0][0] = f / aspect;
  p[1][1] = -f;  // Vulkan: framebuffer y points down
  p[2][2] = near_m / (far_m - near_m);
  p[3][2] = near_m * far_m / (far_m - near_m);
  p[2][3] = -1.0;  // w = -z_view
  return p;
}

Frustum Frustum::from_clip(const glm::dmat4& m) {
  auto row = [&](int i) { return glm::dvec4(m[0][i], m[1][i], m[2][i], m[3][i]); };
  // Vulkan clip volume: -w <= x <= w, -w <= y <= w, 0 <= z <= w (z = 0 is far with reverse-Z).
  Frustum fr;
  fr.planes = {row(3) + row(0), row(3) - row(0), row(3) + row(1), row(3) - row(1), row(2), row(3) - row(2)};
  for (glm::dvec4& p : fr.planes) p /= glm::length(glm::dvec3(p));
  return fr;
}

bool Frustum::intersects_box(const glm::dvec3& lo, const glm::dvec3& hi) const {
  for (const glm::dvec4& p : planes) {
    const glm::dvec3 v(p.x >= 0 ? hi.x : lo.x, p.y >= 0 ? hi.y : lo.y, p.z >= 0 ? hi.z : lo.z);  // most inside corner
    if (glm::dot(glm::dvec3(p), v) + p.w < 0.0) return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------
// Camera paths

CameraPath::CameraPath(std::vector<CameraKey> keys, GroundFn ground, double clearance_m)
    : keys_(std::move(keys)), ground_(std::move(ground)), clearance_m_(clearance_m) {
  TVT_CHECK(!keys_.empty());
  keys_.front().cut = false;
  for (size_t i = 1; i < keys_.size(); ++i) {
    TVT_CHECK(keys_[i].time_s >= keys_[i - 1].time_s);
    if (keys_[i].cut) continue;
    TVT_CHECK(keys_[i].time_s > keys_[i - 1].time_s);  // inside a shot times strictly increase
    // Unwrap yaw so the camera turns the short way.
    double d = keys_[i].yaw_rad - keys_[i - 1].yaw_rad;
    d = std::remainder(d, 2.0 * std::numbers::pi);
    keys_[i].yaw_rad = keys_[i - 1].yaw_rad + d;
  }
}

std::vector<double> CameraPath::cut_times() const {
  std::vector<double> t;
  for (size_t i = 1; i < keys_.size(); ++i)
    if (keys_[i].cut) t.push_back(keys_[i].time_s);
  return t;
}

namespace {

struct Values {
  glm::dvec3 p;
  double yaw, pitch;
};

Values values(const CameraKey& k) { return {k.position_m, k.yaw_rad, k.pitch_rad}; }
Values operator-(const Values& a, const Values& b) { return {a.p - b.p, a.yaw - b.yaw, a.pitch - b.pitch}; }
Values operator*(const Values& a, double s) { return {a.p * s, a.yaw * s, a.pitch * s}; }
Values operator+(const Values& a, const Values& b) { return {a.p + b.p, a.yaw + b.yaw, a.pitch + b.pitch}; }

}  // namespace

CameraPose CameraPath::sample(double time_s) const {
  // The shot containing time_s: keys [first, last].
  size_t first = 0;
  for (size_t i = 1; i < keys_.size(); ++i)
    if (keys_[i].cut && keys_[i].time_s <= time_s) first = i;
  size_t last = first;
  while (last + 1 < keys_.size() && !keys_[last + 1].cut) ++last;

  Values v{};
  if (time_s <= keys_[first].time_s || first == last) {
    v = values(keys_[first]);
  } else if (time_s >= keys_[last].time_s) {
    v = values(keys_[last]);
  } else {
    size_t k = first;
    while (keys_[k + 1].time_s < time_s) ++k;
    const CameraKey &a = keys_[k], &b = keys_[k + 1];
    // Tangents in units per second (non-uniform Catmull-Rom; one-sided at shot ends).
    auto tangent = [&](size_t i) {
      const size_t lo = i > first ? i - 1 : i, hi = i < last ? i + 1 : i;
      return (values(keys_[hi]) - values(keys_[lo])) * (1.0 / (keys_[hi].time_s - keys_[lo].time_s));
    };
    const double h = b.time_s - a.time_s, s = (time_s - a.time_s) / h;
    const double s2 = s * s, s3 = s2 * s;
    const double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2, h11 = s3 - s2;
    v = values(a) * h00 + tangent(k) * (h10 * h) + values(b) * h01 + tangent(k + 1) * (h11 * h);
  }
  CameraPose pose{v.p, v.yaw, std::clamp(v.pitch, -0.5 * std::numbers::pi, 0.5 * std::numbers::pi)};
  if (ground_) pose.position_m.z = std::max(pose.position_m.z, ground_(v.p.x, v.p.y) + clearance_m_);
  return pose;
}

Camera CameraPath::camera_at(double time_s, const Camera& lens) const {
  const CameraPose pose = sample(time_s);
  Camera c = lens;
  c.position_m = pose.position_m;
  c.yaw_rad = pose.yaw_rad;
  c.pitch_rad = pose.pitch_rad;
  return c;
}

CameraPath CameraPath::default_flythrough(double extent_m, double height_m, GroundFn ground) {
  const double e = extent_m;
  const double low = std::max(20.0, 0.004 * e);  // low pass: metres above the ground
  auto ground_at = [&](double x, double y) { return ground ? ground(x, y) : 0.0; };
  auto key = [&](double t, double x, double y, double agl, double yaw, double pitch, bool cut = false) {
    return CameraKey{t, {x * e, y * e, ground_at(x * e, y * e) + agl}, yaw, pitch, cut};
  };
  const double heading = std::atan2(0.20, 0.30);  // direction of the low pass
  std::vector<CameraKey> keys = {
      // Low pass along a diagonal.
      key(0.0, 0.20, 0.25, low, heading, -0.12),
      key(4.0, 0.35, 0.35, low, heading + 0.10, -0.10),
      key(8.0, 0.50, 0.45, low, heading - 0.05, -0.12),
      // Climb: up to well above the highest possible ground, looking down over the terrain.
      key(12.0, 0.60, 0.52, 0.0, heading + 0.30, -0.45),
      // Cut to a different area, then a slow pan.
      key(13.0, 0.80, 0.22, 0.02 * e + 0.2 * height_m, 0.75 * std::numbers::pi, -0.22, true),
      key(18.0, 0.79, 0.23, 0.02 * e + 0.2 * height_m, 0.90 * std::numbers::pi, -0.22),
      key(24.0, 0.78, 0.24, 0.02 * e + 0.2 * height_m, 1.05 * std::numbers::pi, -0.20),
  };
  keys[3].position_m.z = height_m + 0.12 * e;  // absolute altitude of the climb's top
  return CameraPath(std::move(keys), std::move(ground), std::max(2.0, 1e-4 * e));
}

}  // namespace tvt
