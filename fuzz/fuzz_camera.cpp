// libFuzzer target: arbitrary bytes as a camera path file -> tvt::parse_camera_file. Must never
// crash, throw, leak or hit UB; an accepted file must resolve over a ground (or name its key),
// give finite cameras and projections at any time, and write back to a file that parses and
// resolves again.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "terrain/camera_file.h"

namespace {

double ground(double x, double y) { return 500.0 + 400.0 * std::sin(x * 1e-3) * std::cos(y * 1e-3); }

bool finite_camera(const tvt::Camera& c) {
  const glm::dmat4 m = c.clip_from_relative(16.0 / 9.0);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      if (!std::isfinite(m[i][j])) return false;
  return std::isfinite(c.position_m.x) && std::isfinite(c.position_m.y) && std::isfinite(c.position_m.z);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto file = tvt::parse_camera_file(text, "fuzz.json");
  if (!file) {
    if (file.error().message.rfind("fuzz.json: ", 0) != 0) std::abort();  // errors name the file
    return 0;
  }
  auto path = tvt::resolve_camera_path(file.value(), ground);
  if (!path) {
    if (path.error().message.rfind("fuzz.json: /keys/", 0) != 0) std::abort();  // and the key
    return 0;
  }
  const tvt::CameraPath& p = path.value();
  const double t0 = p.start_time(), t1 = p.end_time();
  for (int i = -1; i <= 9; ++i) {
    if (!finite_camera(p.camera_at(t0 + (t1 - t0) * i / 8.0, file.value().lens))) std::abort();
  }
  for (const tvt::CameraKey& k : p.keys()) {
    if (!finite_camera(p.camera_at(k.time_s, file.value().lens))) std::abort();
  }
  auto again = tvt::parse_camera_file(tvt::camera_file_json(p, file.value().lens), "fuzz-roundtrip.json");
  if (!again || !tvt::resolve_camera_path(again.value(), ground)) std::abort();
  return 0;
}
