// Camera, frustum and camera paths for the terrain renderer (see docs/renderer.md).
//
// World space: metres, right-handed, z up. The terrain covers [0, extent_m]^2 in x and y;
// heightfield column i grows with x, row j with y. The camera position is double precision;
// matrices here are *camera-relative*: they transform (p - camera position), computed in
// double on the CPU, so the GPU only ever sees small float offsets (precision holds for
// terrains of hundreds of km).
//
// Projection: reverse-Z with a finite far plane (depth 1 at near, 0 at far; clear depth to 0,
// compare GREATER_OR_EQUAL), Vulkan clip space (y down in the framebuffer, z in [0, 1]).
#pragma once
#include <array>
#include <functional>
#include <vector>

#include <glm/glm.hpp>

namespace tvt {

struct Camera {
  glm::dvec3 position_m{0.0};
  double yaw_rad = 0.0;    // heading: 0 looks along +x, pi/2 along +y
  double pitch_rad = 0.0;  // elevation: > 0 looks up, -pi/2 straight down
  double vertical_fov_rad = 1.0471975511965976;  // 60 degrees
  double near_m = 0.5;
  double far_m = 100000.0;

  glm::dvec3 forward() const;  // unit view direction
  glm::dvec3 right() const;    // unit, horizontal (independent of pitch: no singularity looking down)
  glm::dvec3 up() const;       // cross(right, forward)
  // View matrix without translation: camera-relative world offsets -> view space
  // (x right, y up, looking down -z).
  glm::dmat4 view_rotation() const;
  // Reverse-Z perspective for width/height `aspect`.
  glm::dmat4 projection(double aspect) const;
  // projection * view_rotation: clip position of a camera-relative world offset.
  glm::dmat4 clip_from_relative(double aspect) const { return projection(aspect) * view_rotation(); }
};

// Six planes (inside: dot(plane.xyz, p) + plane.w >= 0) in camera-relative world space.
struct Frustum {
  std::array<glm::dvec4, 6> planes{};  // left, right, bottom, top, far, near

  static Frustum from_clip(const glm::dmat4& clip_from_relative);
  // Conservative: false only when the box is entirely outside one plane. Box corners are
  // camera-relative world offsets in metres.
  bool intersects_box(const glm::dvec3& min_rel, const glm::dvec3& max_rel) const;
};

// Ground height in metres at a world position (x_m, y_m).
using GroundFn = std::function<double(double x_m, double y_m)>;

struct CameraKey {
  double time_s = 0.0;
  glm::dvec3 position_m{0.0};
  double yaw_rad = 0.0;
  double pitch_rad = 0.0;
  bool cut = false;  // a camera cut: the path jumps to this key at time_s (no interpolation into it)
};

struct CameraPose {
  glm::dvec3 position_m{0.0};
  double yaw_rad = 0.0;
  double pitch_rad = 0.0;
};

// Keyframed path. Keys between cuts form a shot; inside a shot position, yaw and pitch follow
// a non-uniform Catmull-Rom spline (cubic Hermite with tangents (p[k+1]-p[k-1])/(t[k+1]-t[k-1]),
// one-sided at shot ends): C1-continuous. Before a cut key the camera holds the previous
// shot's last key. Yaw is unwrapped inside a shot (turns by the short way). With a ground
// function, every sample is lifted to at least ground + clearance_m.
class CameraPath {
 public:
  // keys: sorted by time (fatal otherwise), at least one; the first key's cut flag is ignored.
  explicit CameraPath(std::vector<CameraKey> keys, GroundFn ground = {}, double clearance_m = 2.0);

  CameraPose sample(double time_s) const;
  // The camera at time_s with lens (fov, near, far) taken from `lens`.
  Camera camera_at(double time_s, const Camera& lens = {}) const;
  double start_time() const { return keys_.front().time_s; }
  double end_time() const { return keys_.back().time_s; }
  std::vector<double> cut_times() const;
  const std::vector<CameraKey>& keys() const { return keys_; }
  double clearance_m() const { return clearance_m_; }

  // Built-in flythrough for a square terrain of extent_m with heights up to height_m: a low
  // pass, a climb, a cut to a different area and a slow pan. ~24 s.
  static CameraPath default_flythrough(double extent_m, double height_m, GroundFn ground);

 private:
  std::vector<CameraKey> keys_;
  GroundFn ground_;
  double clearance_m_ = 2.0;
};

}  // namespace tvt
