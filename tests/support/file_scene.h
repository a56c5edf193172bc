// A scene on disk with three image materials split across the terrain (lazy-loading tests):
// a.png (32^2, base), b.png (32^2) on the left half, c.png (16^2) on the right half, by a
// splat image. VT 2^10 texels, 64-texel pages: mip-0 page (0, 0) reads materials 0 and 1,
// page (15, 0) materials 0 and 2. Returns the scene file's path.
#pragma once
#include <filesystem>
#include <fstream>
#include <string>

#include "compose/image.h"
#include "compose/scene_assets.h"
#include "vt/result.h"

namespace tvt::test {

inline ImageRGBA8 gradient_image(int size, uint8_t r, uint8_t g, uint8_t b) {
  ImageRGBA8 img(size, size);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      uint8_t* t = img.at(x, y);
      t[0] = uint8_t(r + x), t[1] = uint8_t(g + y), t[2] = b, t[3] = uint8_t(16 * (x % 16));
    }
  return img;
}

// Writes `name` in `dir`: the split scene's terrain and VT with the given materials (JSON
// array items). Returns the file's path.
inline std::string write_scene_json(const std::filesystem::path& dir, const std::string& name,
                                    const std::string& materials) {
  const std::string scene = (dir / name).string();
  std::ofstream(scene) << R"({"seed": 5, "terrain": {"heightmap": {"fbm": {"size": 16, "seed": 3}}},
    "vt": {"log2_size": 10, "page_texels": 64, "border_texels": 4}, "materials": [)"
                       << materials << "]}";
  return scene;
}

inline std::string write_split_scene(const std::filesystem::path& dir) {
  TVT_CHECK(write_image((dir / "a.png").string(), gradient_image(32, 10, 20, 30)).ok());
  TVT_CHECK(write_image((dir / "b.png").string(), gradient_image(32, 100, 50, 0)).ok());
  TVT_CHECK(write_image((dir / "c.png").string(), gradient_image(16, 0, 150, 200)).ok());
  ImageRGBA8 splat(16, 16);  // r: material 1 on the left half, g: material 2 on the right half
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) splat.at(x, y)[x < 8 ? 0 : 1] = 255, splat.at(x, y)[3] = 255;
  TVT_CHECK(write_image((dir / "s.png").string(), splat).ok());
  return write_scene_json(dir, "scene.json", R"(
    {"name": "a", "albedo": {"image": "a.png"}, "period_texels": 128, "weight": "remainder"},
    {"name": "b", "albedo": {"image": "b.png"}, "period_texels": 96, "mode": "blendmap",
     "weight": {"splat": {"image": "s.png", "channel": "r"}}},
    {"name": "c", "albedo": {"image": "c.png"}, "period_texels": 64, "mode": "blendmap",
     "weight": {"splat": {"image": "s.png", "channel": "g"}}})");
}

// write_split_scene() then load_scene_assets() (fatal on error); `scene_path` gets the file.
inline SceneAssets load_split_scene(const std::filesystem::path& dir, std::string* scene_path) {
  *scene_path = write_split_scene(dir);
  auto desc = load_scene_file(*scene_path);
  TVT_CHECK(desc.ok());
  auto assets = load_scene_assets(desc.value());
  TVT_CHECK(assets.ok());
  return std::move(assets.value());
}

}  // namespace tvt::test
