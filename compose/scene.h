// Scene description: what a scene file (JSON) says, fully validated, before any asset is
// loaded. Paths are resolved relative to the scene file's folder. See docs/scene-format.md.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "compose/material_image.h"
#include "vt/result.h"
#include "vt/vt_config.h"

namespace tvt {

enum class Mode { Linear, BlendMap, Fbpb, Dpt, FbpbDpt };
std::string_view to_string(Mode mode);                   // "linear", "blendmap", "fbpb", "dpt", "fbpb+dpt"
std::optional<Mode> mode_from_string(std::string_view);  // inverse of to_string

// Terrain height field: an image (any size, first channel, normalised to [0,1]) or fBm noise.
struct HeightmapDesc {
  std::string image_path;      // empty: procedural fBm below
  uint32_t size = 512;         // fBm grid texels per side (16 ... 8192)
  uint32_t seed = 1;
  uint32_t octaves = 6;        // 1 ... 16
  double frequency = 3.0;      // base frequency, cycles across the terrain (> 0)
  double gain = 0.5;           // amplitude ratio between octaves (0, 1)
  double lacunarity = 2.0;     // frequency ratio between octaves (1, 4]
};

struct TerrainDesc {
  HeightmapDesc heightmap;
  double extent_m = 8192.0;    // terrain edge length in metres (> 0)
  double height_m = 900.0;     // height of a heightmap value of 1 in metres (>= 0)
};

// A material texture: an image file of any size (resampled to a power-of-two square, see
// compose/material_image.h), or one of the built-in generators ("sand", "grass", "rock",
// "mud", "cobbles", "bricks") at a power-of-two resolution.
struct TextureDesc {
  std::string image_path;      // albedo RGB (and alpha, see height_source)
  std::string height_path;     // optional separate height/blend map (first channel)
  HeightSource height_source = HeightSource::Auto;  // where A comes from (material_image.h)
  bool height_invert = false;  // luminance height: the lightest pixel is the deepest
  uint32_t image_resolution = 0;  // images: texels per side after resampling, 0 = the size rule
  std::string generator;       // used when image_path is empty
  uint32_t resolution = 256;   // generator output size, power of two 16 ... 4096
  uint32_t seed = 0;           // generator seed (0: derived from scene seed and material index)
};

// Where a material's weight p in [0,1] comes from. Heights are normalised heightmap values
// in [0,1]; slopes are in degrees computed from the heightmap with extent_m and height_m.
struct WeightDesc {
  enum class Kind { Remainder, Rule, Splat };
  Kind kind = Kind::Remainder;  // Remainder: 1 - sum of the other weights, clamped (base only)
  // Rule: smoothstep windows on height and slope, multiplied, plus optional fBm noise.
  double height_lo = 0.0, height_hi = 1.0, height_fade = 0.05;
  double slope_lo_deg = 0.0, slope_hi_deg = 90.0, slope_fade_deg = 5.0;
  double noise_amplitude = 0.0;  // adds amplitude * (fbm - 0.5) * 4p(1-p): perturbs the transition band only
  double noise_frequency = 16.0; // cycles across the terrain
  // Splat: one channel of an RGBA image covering the whole terrain.
  std::string splat_path;
  uint32_t splat_channel = 0;    // 0..3 = r, g, b, a
};

struct FbpbDesc {
  double cm = 1.5;                  // Cm, eq 3.1: opacity boost of visible features
  double cf = 1.0;                  // Cf, eq 3.1: feature visibility probability scale
  double cn = 1.0;                  // Cn, eq 3.1: non-feature opacity scale
  double variation_threshold = 0.3; // Algorithm 1
  double colour_coeff = 0.75;       // Cc, Algorithm 1
  double fade_lod_lo = 2.0;         // material LOD (log2 material texels per VT texel) where
  double fade_lod_hi = 4.0;         // features start / finish fading to the blend map
  // Feature source: a meta-texture file written by `terravt metatex`, a hand-made mask image
  // (non-zero = feature), or automatic isolation (the default; built-in generators give
  // their exact mask instead).
  std::string meta_path;
  std::string mask_path;
};

struct DptLayerDesc {
  double patch_texels = 256.0;  // S_k in level-0 VT texels (> 0)
  double p = 1.0;               // P_k, eq 4.1
  double r = 1.0;               // R_k, eq 4.2
  double w = 1.0;               // W_k, eq 4.3
  double h = 0.5;               // H_k, Algorithm 3
};

struct DptDesc {
  std::vector<DptLayerDesc> layers;  // 0 ... 4 layers
  double fade_lo_texels = 2.0;       // eq 4.4 in texel terms: a layer whose patch spans fewer
  double fade_hi_texels = 8.0;       // texels than fade_lo at the composed mip is gone, above fade_hi fully present
};

// Hex-tiling, the anti-repetition mode (docs/composition.md): the material is sampled by three
// tiles of a triangle lattice, each shifted by its own random whole-texel offset, blended by
// sharpened barycentric weights about the material's mean so the contrast of one tile is kept.
// Not used by FBPB modes above the base (their features are tied to the unshifted texture).
struct HexDesc {
  bool enabled = false;
  double edge = 0.0;       // lattice edge in material texels, rounded to even; 0: half the resolution
  double sharpness = 7.0;  // gamma: barycentric weights raised to this power, [1, 64]
  double preserve = 1.0;   // 0: linear blend of the tiles; 1: variance-preserving about the mean
};

struct MaterialDesc {
  std::string name;
  TextureDesc albedo;
  std::string normal_path;       // optional; carried for renderers, not used by composition
  double period_texels = 512.0;  // T_n: level-0 VT texels per texture repeat (>= 1)
  Mode mode = Mode::BlendMap;
  WeightDesc weight;
  bool has_fbpb = false;         // an "fbpb" block was given (needed for fbpb modes)
  FbpbDesc fbpb;
  DptDesc dpt;
  double blend_sharpness = 0.1;  // s of BlendMap, (0, 0.5]
  HexDesc hex;
};

struct SceneDesc {
  std::string source_path;       // file it came from, "<built-in>" for the default scene
  std::string base_dir;          // folder relative paths were resolved against
  uint32_t seed = 1;
  TerrainDesc terrain;
  VtConfig vt;
  std::vector<MaterialDesc> materials;  // precedence order, base first; 1 ... 16
  double linear_boost = 1.0;            // Bloom splatting boost, [1, 4]
};

// Parses and validates a scene. Every error names the file and the field as a JSON pointer,
// e.g. "my.json: /materials/2/dpt/layers/0/p: must be a finite number > 0, got -1".
Result<SceneDesc> parse_scene(std::string_view json_text, const std::string& source_path,
                              const std::string& base_dir);
Result<SceneDesc> load_scene_file(const std::string& path);

// The built-in default scene (compiled in; the same JSON is in docs/default-scene.json).
std::string_view default_scene_json();
SceneDesc default_scene();

// Serialises a scene back to JSON (round-trips through parse_scene).
std::string scene_to_json(const SceneDesc& scene);

// Every file the scene names (images, height and splat maps, normal maps, meta-textures and
// masks) as (its field, a JSON pointer such as "/materials/2/albedo/image"; its path), in the
// order of the scene: what a run that loads the scene reads, and must not write over.
std::vector<std::pair<std::string, std::string>> scene_files(const SceneDesc& scene);

}  // namespace tvt
