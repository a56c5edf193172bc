// Each material's texture mip chain and FBPB meta-texture, produced on first use (docs/architecture.md:
// "nothing of a material is loaded that no visible page uses"). At scene load only the image
// headers are read (sizes, channels), so a scene whose files are missing or mis-sized still
// fails there, with the same messages; the texels are read (or generated, for built-in
// materials) by the first get() of the material. See docs/composition.md, "Lazy material loading".
//
// Thread-safety: get(), words(), load_all(), loaded() and stats() may be called from any number of
// threads; concurrent first calls of get() (or of words()) for one material read its files once;
// words() after get() packs get()'s images, a get() after words() reads the files again. A failed load is
// remembered: later calls return the same error without reading again. The in-memory editing
// calls (edit(), push_back()) are for tests and tools building scenes by hand, before any get().
#pragma once
#include <cstdint>
#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "compose/image.h"
#include "compose/metatex.h"
#include "compose/once_result.h"
#include "compose/scene.h"
#include "vt/result.h"

namespace tvt {

// Box-filtered mip chain of a square power-of-two tileable RGBA8 texture (wrap-around).
struct MipChain {
  int resolution = 0;
  std::vector<ImageRGBA8> mips;  // mips[0] is full resolution, last is 1x1
};
MipChain build_mip_chain(const ImageRGBA8& level0);

struct MaterialAssets {
  MipChain albedo;                 // RGB albedo, A height / blend map
  std::optional<MetaTexture> meta; // FBPB features, when the material has any
};

// A material in the flat form the compositors read (PackedScene): the albedo mips as RGBA8
// words r | g<<8 | b<<16 | a<<24, level 0 first, then the statistics block; the meta-texture as
// two words per texel, (dx & 0xffff) | dy<<16 and d | f<<8 | v<<16, then its feature statistics
// chain (tvt_meta_block_texels in all; empty without a meta-texture).
struct MaterialWords {
  int resolution = 0;
  int mip_count = 0;
  std::vector<uint32_t> texels;
  std::vector<uint32_t> meta;
  bool has_meta = false;
  uint32_t feature_count = 0;
};
MaterialWords pack_material(const MaterialAssets& assets);

// What is known of a material without reading its texels (the layout of the packed scene).
struct MaterialInfo {
  int resolution = 0;            // albedo texels per side, a power of two
  int mip_count = 0;             // levels of the mip chain (down to 1x1)
  bool meta = false;             // it has an FBPB meta-texture
  // Whether the meta-texture has features is only known once it is loaded (in-memory
  // materials: at once); until then a meta-texture counts as a promise of features.
  bool features_known = false;
  uint32_t feature_count = 0;    // meaningful when features_known
  // Image materials: what the loader does with the file, from its header, e.g.
  // "wall.jpg: 100x100, 3 channels, resampled to 128x128 (Lanczos-3, wrap), height from luminance".
  std::string image_note;
};

struct MaterialLoadStats {
  uint32_t loaded = 0;           // materials whose texels are in memory
  uint32_t failures = 0;         // materials whose first use failed
  uint64_t reads = 0;            // loads performed (each material at most once)
  double load_ms = 0.0;          // wall time spent reading/generating, summed over loads
};

class MaterialSource {
 public:
  // Checks every material's files by their headers: existence, format, size (any size up to
  // 16384 per side; resampled to a power-of-two square, compose/material_image.h), mask and
  // meta sizes. Errors name the scene file, the field
  // (e.g. /materials/2/albedo/image) and the image file, as the eager loader did.
  static Result<std::shared_ptr<MaterialSource>> open(const SceneDesc& desc);
  // Materials already in memory (synthetic scenes, tests): nothing to load.
  static std::shared_ptr<MaterialSource> in_memory(std::vector<MaterialAssets> materials = {});

  size_t size() const { return slots_.size(); }
  MaterialInfo info(size_t n) const;

  // Material n, loaded on the first call. The error names the scene file, the field and the file.
  Result<std::shared_ptr<const MaterialAssets>> get(size_t n) const;
  // Material n's words, made once and shared by every packing of the scene (one per method).
  // A file-backed source keeps only these: the images it read are dropped once packed (unless
  // get() kept them), so the host holds each material's texels once.
  Result<std::shared_ptr<const MaterialWords>> words(size_t n) const;
  // Loads every material's words (bake, compose panels, benchmarks); the first error.
  Status load_all() const;
  bool loaded(size_t n) const;
  MaterialLoadStats stats() const;

  // In-memory sources only, before any get(): material n's assets to edit, or a new one.
  MaterialAssets& edit(size_t n);
  void push_back(MaterialAssets assets);

 private:
  struct Slot {
    MaterialInfo info;
    mutable OnceResult<std::shared_ptr<const MaterialAssets>> assets;
    mutable OnceResult<std::shared_ptr<const MaterialWords>> words;
    mutable std::atomic<bool> assets_wanted{false};  // get() was called: words() packs its images
    MaterialAssets editable;  // in-memory sources before first use
  };
  MaterialSource() = default;
  Result<MaterialAssets> produce(size_t n) const;
  // produce(n) with the load counters (reads, load time, failures).
  Result<MaterialAssets> produce_counted(size_t n) const;

  std::optional<SceneDesc> desc_;  // empty: in memory
  std::vector<std::unique_ptr<Slot>> slots_;
  mutable std::mutex stats_mutex_;
  mutable MaterialLoadStats stats_;
};

// "<scene file>: <json pointer>", the prefix of every scene asset error.
std::string scene_field(const SceneDesc& desc, const std::string& pointer);

// How many times scene loading has run automatic feature isolation in this process (a cached
// meta-texture next to the scene, .terravt-cache/, spares it): for tests.
uint64_t automatic_isolation_runs();
// Seeds of derived assets: a pure function of the scene seed and small integers, so every
// asset is reproducible from the scene file alone.
uint32_t derived_asset_seed(uint32_t scene_seed, uint32_t index, uint32_t purpose);

}  // namespace tvt
