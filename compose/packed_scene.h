// The flat form of a scene that both compositors read: the std430 parameter block and the
// texel/meta/weight buffers uploaded to the GPU. The CPU reference reads exactly these bytes,
// so the two differ only in their arithmetic (double vs float), never in their inputs.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "compose/scene.h"
#include "compose/scene_assets.h"
#include "shaders/shared/compose_types.h"

namespace tvt {

struct ComposeOptions {
  std::optional<Mode> method;     // replaces every material's mode but the base's
  uint32_t dpt_layer_limit = 0;   // 0: all DPT layers; n: at most n
  // s: up to s*s sub-samples per texel, power of two 1 ... 64; a texel of mip m takes
  // min(s, 2^m)^2, never more samples than the level-0 texels it covers (mip 0 is direct).
  uint32_t supersample = 1;
  // Mips >= 1 composed with the expected coverage of what is smaller than their footprint
  // (MipStrategy::prefiltered); one sample per texel, supersample must be 1.
  bool prefiltered = false;
  // Hex-tiling: unset follows each material's "hex"; true turns it on for every material it
  // applies to (with the scene's parameters where given, else the defaults); false turns it off.
  std::optional<bool> hex;
};

// How pages of mip m >= 1 are composed, the user's accuracy/speed knob ("mip strategy"):
//   direct          one sample per texel, materials read at the footprint's LOD;
//   supersample:S   the average of min(S, 2^m)^2 samples per texel (S a power of two, 2 ... 64),
//                   each a direct composition of its share of the footprint;
//   prefiltered     one sample per texel, with the expected coverage of the DPT patches, FBPB
//                   features and blend-map heights that are smaller than the footprint, from the
//                   statistics of the material's texels (docs/composition.md, "Prefiltered mips").
// Mip 0 is the same under every strategy. Cost and error per mip: docs/benchmarks.md
// ("bench mips").
struct MipStrategy {
  uint32_t supersample = 1;  // 1: direct or prefiltered
  bool prefiltered = false;
  bool direct() const { return supersample <= 1 && !prefiltered; }
  friend bool operator==(const MipStrategy&, const MipStrategy&) = default;
};
std::string to_string(MipStrategy strategy);  // "direct", "supersample:4", "prefiltered"
// `text` as written above; the error lists the accepted forms.
Result<MipStrategy> mip_strategy_from_string(std::string_view text);

// The six methods the papers compare, as compose options.
enum class Method { Linear, BlendMap, Fbpb, Dpt1, Dpt2, FbpbDpt };
inline constexpr Method k_all_methods[] = {Method::Linear, Method::BlendMap, Method::Fbpb,
                                           Method::Dpt1,   Method::Dpt2,     Method::FbpbDpt};
std::string_view to_string(Method method);  // "linear", "blendmap", "fbpb", "dpt1", "dpt2", "fbpb+dpt2"
std::optional<Method> method_from_string(std::string_view text);
ComposeOptions options_for(Method method, MipStrategy strategy = {});

// The flat material buffers are laid out at pack time from what is known without texels
// (MaterialInfo); material n's words are produced on first use (load()) and cached, shared by
// every copy of the PackedScene. Thread-safe: load(), texels() and meta() may be called
// concurrently; one material is packed once.
struct PackedScene {
  gpu::TvtComposeParams params{};
  std::vector<float> weights;   // WeightGrid::data
  size_t texel_words = 0;       // size of the flat texel buffer, uint32 words (all mips of all materials)
  size_t meta_words = 0;        // size of the flat meta buffer, uint32 words
  bool has_meta() const { return meta_words > 0; }

  // Reads (or generates) and packs the materials of `mask` (bit n: material n) that are not yet
  // packed. An error names the scene file, the field and the file; an FBPB material whose
  // meta-texture turns out to have no features fails with /materials/n/fbpb (see pack_scene).
  Status load(uint32_t mask) const;
  Status load_all() const { return load(~0u); }
  // Bit n: material n is packed.
  uint32_t loaded_mask() const;
  // Material n's words, at params.materials[n].texel_offset of the flat buffer: RGBA8 words
  // r | g<<8 | b<<16 | a<<24, all mips. Loads on first use; a load error is fatal here, so
  // callers that can meet one call load() first.
  std::span<const uint32_t> texels(size_t n) const;
  // Word i of material n's statistics block (TVT_MATERIAL_STATS_WORDS, after its 1x1 mip), as
  // the float it holds; loads as texels() does.
  float stat(size_t n, int i) const;
  // Material n's meta words at 2 * meta_offset, two per texel: (dx & 0xffff) | dy<<16,
  // d | f<<8 | v<<16; empty when meta_offset is TVT_NO_META.
  std::span<const uint32_t> meta(size_t n) const;
  // The materials' source (load counters).
  const MaterialSource& source() const;
  // A copy that shares the material cache and parameters but not the weights (for holders of
  // the materials' words and statistics alone).
  PackedScene materials_only() const;

  struct Cache;  // per material: once flag, packed words or error
  std::shared_ptr<Cache> cache_;
};

// Resolves effective modes (an FBPB mode without features falls back to blend map / DPT, a
// DPT mode without layers to blend map / FBPB) and converts sizes to 1/256 fixed point.
// Features: a material whose meta-texture is not loaded yet is taken to have features (an
// "fbpb" block is a promise); if its meta-texture then has none, load() of it fails naming
// /materials/n/fbpb, at the first page that reads it. Nothing of the texels is read here.
Result<PackedScene> pack_scene(const SceneAssets& assets, const ComposeOptions& options);

}  // namespace tvt
