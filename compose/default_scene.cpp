// The built-in default scene: five generated materials over an 8 km fBm terrain, one of each
// composition mode family, hex-tiling on the four whose tiling would show (the FBPB cobbles
// break their repetition by their own feature choice). The VT is 2^20 texels per side, 7.8 mm a
// texel: material tiles of 2-5 m and grass/mud patches of 1-8 m, ground-scale detail that only a
// virtual texture can hold (level 0 alone would be 4 TiB of RGBA8). The same text is in
// docs/default-scene.json (a test keeps the two identical), so users can copy it as a starting
// point.
#include "compose/scene.h"

namespace tvt {

namespace {
constexpr std::string_view k_default_scene = R"json({
  "seed": 1337,
  "terrain": {
    "extent_m": 8192,
    "height_m": 900,
    "heightmap": {"fbm": {"size": 512, "seed": 7, "octaves": 7, "frequency": 3, "gain": 0.5, "lacunarity": 2}}
  },
  "vt": {"log2_size": 20, "page_texels": 128, "border_texels": 4},
  "linear_boost": 1.5,
  "materials": [
    {
      "name": "sand",
      "albedo": {"generator": "sand", "resolution": 256},
      "period_texels": 512,
      "hex": true,
      "mode": "blendmap",
      "weight": "remainder"
    },
    {
      "name": "grass",
      "albedo": {"generator": "grass", "resolution": 256},
      "period_texels": 384,
      "hex": true,
      "mode": "dpt",
      "weight": {"rule": {"height": [0.30, 0.75], "height_fade": 0.08, "slope_deg": [0, 24], "slope_fade_deg": 6,
                          "noise": {"amplitude": 0.35, "frequency": 24}}},
      "dpt": {
        "layers": [
          {"patch_texels": 1024, "p": 1, "r": 1, "w": 1, "h": 0.6},
          {"patch_texels": 160, "p": 0.5, "r": 1.5, "w": 1, "h": 0.3}
        ],
        "fade_texels": [2, 8]
      }
    },
    {
      "name": "mud",
      "albedo": {"generator": "mud", "resolution": 256},
      "period_texels": 448,
      "hex": true,
      "mode": "dpt",
      "weight": {"rule": {"height": [0, 0.32], "height_fade": 0.06, "slope_deg": [0, 14], "slope_fade_deg": 4,
                          "noise": {"amplitude": 0.3, "frequency": 20}}},
      "dpt": {
        "layers": [
          {"patch_texels": 768, "p": 1, "r": 1, "w": 1, "h": 0.5}
        ]
      }
    },
    {
      "name": "rock",
      "albedo": {"generator": "rock", "resolution": 256},
      "period_texels": 640,
      "hex": true,
      "mode": "blendmap",
      "weight": {"rule": {"height": [0, 1], "height_fade": 0, "slope_deg": [26, 90], "slope_fade_deg": 8,
                          "noise": {"amplitude": 0.25, "frequency": 32}}}
    },
    {
      "name": "cobbles",
      "albedo": {"generator": "cobbles", "resolution": 512},
      "period_texels": 256,
      "mode": "fbpb+dpt",
      "weight": {"rule": {"height": [0.42, 0.62], "height_fade": 0.05, "slope_deg": [0, 18], "slope_fade_deg": 5,
                          "noise": {"amplitude": 0.4, "frequency": 28}}},
      "fbpb": {"cm": 1.5, "cf": 1, "cn": 1, "variation_threshold": 0.3, "colour_coeff": 0.75, "fade_lod": [2, 4]},
      "dpt": {
        "layers": [
          {"patch_texels": 96, "p": 1, "r": 1, "w": 1, "h": 0.5},
          {"patch_texels": 16, "p": 0.5, "r": 1.2, "w": 1, "h": 0.25}
        ]
      }
    }
  ]
}
)json";
}  // namespace

std::string_view default_scene_json() { return k_default_scene; }

SceneDesc default_scene() {
  Result<SceneDesc> scene = parse_scene(k_default_scene, "<built-in>", "");
  if (!scene) fatal(__FILE__, __LINE__, "parse_scene(default_scene_json())", scene.error().message.c_str());
  return std::move(scene).value();
}

}  // namespace tvt
