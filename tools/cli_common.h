// Helpers shared by the subcommands.
#pragma once
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

#include "compose/scene_assets.h"
#include "render/vk_context.h"
#include "vt/result.h"

namespace tvt::cli {

// Loads a scene file, or the built-in default scene when `path` is empty, and its assets.
Result<SceneAssets> load_scene_and_assets(const std::string& path);

// The Vulkan context for a command: `device` (its --gpu flag) or TERRAVT_DEVICE / the best.
Result<std::unique_ptr<vk::Context>> gpu_context(const std::string& device);

// Prints "terravt <command>: <message>" to stderr and returns `code`.
int fail(const char* command, const std::string& message, int code);

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace tvt::cli
