#include "tools/cli_common.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "compose/scene.h"
#include "render/flythrough.h"
#include "streaming/file_io.h"

namespace tvt::cli {

Result<SceneAssets> load_scene_and_assets(const std::string& path) {
  Result<SceneDesc> desc = path.empty() ? Result<SceneDesc>(default_scene()) : load_scene_file(path);
  if (!desc) return desc.error();
  return load_scene_assets(desc.value());
}

Result<CameraChoice> choose_camera(const std::string& camera_file, const SceneAssets& assets) {
  std::optional<CameraFile> file;
  if (!camera_file.empty()) {
    auto loaded = load_camera_file(camera_file);
    if (!loaded) return make_error("--camera: " + loaded.error().message);
    file = std::move(loaded.value());
  }
  // The renderer's heights, on the CPU.
  const TerrainDesc& terrain = assets.desc.terrain;
  auto mesh = TerrainMesh::create(assets.heightfield, terrain.extent_m, terrain.height_m, assets.desc.vt);
  if (!mesh) return mesh.error();
  auto ground = std::make_unique<TerrainMesh>(std::move(mesh.value()));
  auto path = flythrough_path(assets, *ground, file ? &*file : nullptr);  // holds a pointer to *ground
  if (!path) return make_error("--camera: " + path.error().message);
  const Camera lens = file ? file->lens : Camera{};
  return CameraChoice{std::move(file), std::move(ground), std::move(path.value()), lens};
}

std::string CameraChoice::describe() const {
  const size_t keys = path.keys().size(), cuts = path.cut_times().size();
  char text[96];
  std::snprintf(text, sizeof(text), " (%zu key%s, %.1f s, %zu cut%s)", keys, keys == 1 ? "" : "s",
                path.end_time() - path.start_time(), cuts, cuts == 1 ? "" : "s");
  return (file ? file->source_path : std::string("built-in flythrough")) + text;
}

Result<std::unique_ptr<vk::Context>> gpu_context(const std::string& device) {
  // The library reads no environment variable: the CLI turns TERRAVT_DEVICE and
  // TERRAVT_VALIDATION into options, and prints what the device reports.
  vk::ContextOptions options;
  const char* env_device = std::getenv("TERRAVT_DEVICE");
  options.device = !device.empty() ? device : (env_device ? env_device : "");
  options.device_source = !device.empty() ? "--gpu" : "TERRAVT_DEVICE";
  const char* env_validation = std::getenv("TERRAVT_VALIDATION");
  options.validation = env_validation && *env_validation && std::strcmp(env_validation, "0") != 0;
  options.validation_source = "TERRAVT_VALIDATION=1";
  options.log = [](terravt::LogLevel, std::string_view message) {
    std::fprintf(stderr, "terravt: %.*s\n", int(message.size()), message.data());
  };
  return vk::Context::create(options);
}

Status write_text_file(const std::string& path, const std::string& text) {
  return fileio::write_file_durable(path, text.data(), text.size());
}

int fail(const char* command, const std::string& message, int code) {
  std::fprintf(stderr, "terravt %s: %s\n", command, message.c_str());
  return code;
}

}  // namespace tvt::cli
