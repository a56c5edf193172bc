#include "compose/scene_identity.h"

#include <filesystem>
#include <string>
#include <string_view>

namespace tvt {
namespace {

// FNV-1a, 64 bit: the inputs are a few kilobytes of text, so its speed does not matter and it
// is fully specified (std::hash is not stable across implementations).
uint64_t fnv1a(uint64_t h, std::string_view bytes) {
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  return h;
}

// Paths in a parsed scene are already resolved against its folder.
std::string file_stamp(const std::string& path) {
  if (path.empty()) return "-";
  std::error_code ec;
  const std::filesystem::path p(path);
  const auto size = std::filesystem::file_size(p, ec);
  if (ec) return path + ":?";
  const auto time = std::filesystem::last_write_time(p, ec);
  return path + ":" + std::to_string(size) + ":" + std::to_string(ec ? 0 : time.time_since_epoch().count());
}

}  // namespace

uint64_t scene_identity(const SceneDesc& scene, Method method, MipStrategy strategy) {
  // Bump when the composition maths or the page layout changes what a page holds.
  constexpr std::string_view k_page_format = "terravt-page-v1";
  uint64_t h = 0xcbf29ce484222325ull;
  h = fnv1a(h, k_page_format);
  h = fnv1a(h, to_string(method));
  if (!strategy.direct()) h = fnv1a(h, to_string(strategy));
  // Bump when the prefiltered strategy's expectations change (direct and supersampled pages
  // keep their identity). 2: DPT's blend map over the patches' spread, not their mean.
  if (strategy.prefiltered) h = fnv1a(h, "prefiltered maths 2");
  h = fnv1a(h, scene_to_json(scene));
  h = fnv1a(h, file_stamp(scene.terrain.heightmap.image_path));
  for (const MaterialDesc& m : scene.materials) {
    h = fnv1a(h, file_stamp(m.albedo.image_path));
    h = fnv1a(h, file_stamp(m.albedo.height_path));
    h = fnv1a(h, file_stamp(m.weight.splat_path));
    h = fnv1a(h, file_stamp(m.fbpb.meta_path));
    h = fnv1a(h, file_stamp(m.fbpb.mask_path));
  }
  return h == 0 ? 1 : h;  // 0 means "unknown" in a store header
}

uint64_t store_scene_identity(const SceneDesc& scene, Method method, MipStrategy strategy, StorePyramid pyramid) {
  return scene_identity(scene, method, pyramid == StorePyramid::filtered ? MipStrategy{} : strategy);
}

}  // namespace tvt
