// The flat form of a scene that both compositors read: the std430 parameter block and the
// texel/meta/weight buffers uploaded to the GPU. The CPU reference reads exactly these bytes,
// so the two differ only in their arithmetic (double vs float), never in their inputs.
#pragma once
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "compose/scene.h"
#include "compose/scene_assets.h"
#include "shaders/shared/compose_types.h"

namespace tvt {

struct ComposeOptions {
  std::optional<Mode> method;     // replaces every material's mode but the base's
  uint32_t dpt_layer_limit = 0;   // 0: all DPT layers; n: at most n
  uint32_t supersample = 1;       // s: s*s sub-samples per texel; power of two, 1 ... 64
};

// The six methods the papers compare, as compose options.
enum class Method { Linear, BlendMap, Fbpb, Dpt1, Dpt2, FbpbDpt };
inline constexpr Method k_all_methods[] = {Method::Linear, Method::BlendMap, Method::Fbpb,
                                           Method::Dpt1,   Method::Dpt2,     Method::FbpbDpt};
std::string_view to_string(Method method);  // "linear", "blendmap", "fbpb", "dpt1", "dpt2", "fbpb+dpt2"
std::optional<Method> method_from_string(std::string_view text);
ComposeOptions options_for(Method method);

struct PackedScene {
  gpu::TvtComposeParams params{};
  std::vector<uint32_t> material_texels;  // RGBA8 words r | g<<8 | b<<16 | a<<24, all mips of all materials
  std::vector<uint32_t> meta_texels;      // two words per texel: (dx & 0xffff) | dy<<16, d | f<<8 | v<<16
  std::vector<float> weights;             // WeightGrid::data
  bool has_meta() const { return !meta_texels.empty(); }
};

// Resolves effective modes (an FBPB mode without features falls back to blend map / DPT, a
// DPT mode without layers to blend map / FBPB) and converts sizes to 1/256 fixed point.
Result<PackedScene> pack_scene(const SceneAssets& assets, const ComposeOptions& options);

}  // namespace tvt
