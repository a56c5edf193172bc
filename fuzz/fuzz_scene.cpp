// libFuzzer target: arbitrary bytes as a scene file -> tvt::parse_scene. Must never crash,
// throw, leak or hit UB; an accepted scene must satisfy the documented ranges, and writing it
// back with scene_to_json must give a scene the parser accepts again.
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "compose/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  // A folder that does not exist: image paths resolve against it and are reported missing.
  auto scene = tvt::parse_scene(text, "fuzz.json", "/nonexistent-terravt-fuzz");
  if (!scene) {
    if (scene.error().message.rfind("fuzz.json", 0) != 0) std::abort();  // errors name the file
    return 0;
  }
  const tvt::SceneDesc& s = scene.value();
  if (s.materials.empty() || s.materials.size() > 16) std::abort();
  if (!tvt::validate(s.vt, "fuzz").ok()) std::abort();
  auto again = tvt::parse_scene(tvt::scene_to_json(s), "fuzz-roundtrip.json", "/nonexistent-terravt-fuzz");
  if (!again) std::abort();
  return 0;
}
