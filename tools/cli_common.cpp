#include "tools/cli_common.h"

#include "compose/scene.h"

namespace tvt::cli {

Result<SceneAssets> load_scene_and_assets(const std::string& path) {
  Result<SceneDesc> desc = path.empty() ? Result<SceneDesc>(default_scene()) : load_scene_file(path);
  if (!desc) return desc.error();
  return load_scene_assets(desc.value());
}

Result<std::unique_ptr<vk::Context>> gpu_context(const std::string& device) {
  vk::ContextOptions options;
  options.device = device;
  return vk::Context::create(options);
}

int fail(const char* command, const std::string& message, int code) {
  std::fprintf(stderr, "terravt %s: %s\n", command, message.c_str());
  return code;
}

}  // namespace tvt::cli
