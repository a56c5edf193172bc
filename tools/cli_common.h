// Helpers shared by the subcommands.
#pragma once
#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "compose/scene_assets.h"
#include "render/camera_file.h"
#include "render/terrain_mesh.h"
#include "gpu/context.h"
#include "vt/result.h"

namespace tvt::cli {

// Loads a scene file, or the built-in default scene when `path` is empty, and its assets.
Result<SceneAssets> load_scene_and_assets(const std::string& path);

// The camera path a flythrough command follows: a --camera file, checked and resolved over
// the scene's terrain (so a bad file fails before anything is written), or the built-in
// flythrough.
struct CameraChoice {
  std::optional<CameraFile> file;       // none: the built-in flythrough
  std::unique_ptr<TerrainMesh> ground;  // the terrain `path` stands on (CPU)
  CameraPath path;
  Camera lens;
  std::string describe() const;  // "mine.json (4 keys, 3.0 s, 1 cut)"
};
// Errors start with "--camera: " and name the file and field.
Result<CameraChoice> choose_camera(const std::string& camera_file, const SceneAssets& assets);

// The Vulkan context for a command: `device` (its --gpu flag) or TERRAVT_DEVICE / the best.
Result<std::unique_ptr<vk::Context>> gpu_context(const std::string& device);

// Writes `text` to `path` durably (fileio::write_file_durable): a failed write leaves any
// earlier file untouched. Errors name the path.
Status write_text_file(const std::string& path, const std::string& text);

// Prints "terravt <command>: <message>" to stderr and returns `code`.
int fail(const char* command, const std::string& message, int code);

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace tvt::cli
