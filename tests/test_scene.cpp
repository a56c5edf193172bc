// Scene files: the default scene, full round trips, and one rejected case per validation rule
// (each error must name the source file and the exact JSON pointer of the bad field).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "compose/scene.h"

namespace fs = std::filesystem;
using json = nlohmann::json;
using namespace tvt;

namespace {

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_text(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream out(p, std::ios::binary);
  out << text;
}

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// Every field of the format, with values away from the defaults and at the accepted extremes.
json full_scene_json() {
  return json::parse(R"({
    "seed": 42,
    "terrain": {"extent_m": 4096.5, "height_m": 321.25, "heightmap": {"image": "h.png"}},
    "vt": {"log2_size": 20, "page_texels": 256, "border_texels": 8},
    "linear_boost": 2.5,
    "materials": [
      {"name": "base", "albedo": {"image": "tex/a.png", "height": "tex/ah.png"}, "normal": "tex/n.png",
       "period_texels": 300.5, "mode": "linear", "blend_sharpness": 0.5, "weight": "remainder"},
      {"name": "splatted", "albedo": {"generator": "bricks", "resolution": 4096, "seed": 99},
       "period_texels": 1, "mode": "blendmap", "blend_sharpness": 0.01,
       "weight": {"splat": {"image": "s.png", "channel": "a"}}},
      {"name": "ruled", "albedo": {"generator": "rock", "resolution": 16, "seed": 4294967295},
       "period_texels": 1073741824, "mode": "dpt",
       "weight": {"rule": {"height": [0.1, 0.9], "height_fade": 0, "slope_deg": [0, 90], "slope_fade_deg": 2.5,
                           "noise": {"amplitude": 4, "frequency": 0.5}}},
       "dpt": {"layers": [{"patch_texels": 2147483648, "p": 0.001, "r": 1000, "w": 1000000, "h": 0},
                          {"patch_texels": 0.5, "p": 1000, "r": 0.001, "w": 0.001, "h": 1000000},
                          {"patch_texels": 64, "p": 2, "r": 3, "w": 4, "h": 5},
                          {"patch_texels": 12.75}],
               "fade_texels": [0, 0]}},
      {"name": "features", "albedo": {"generator": "cobbles"}, "mode": "fbpb", "weight": {"rule": {}},
       "fbpb": {"cm": 0, "cf": 1000000, "cn": 0.5, "variation_threshold": 0, "colour_coeff": 1,
                "fade_lod": [-1, -1], "meta": "x.exr"}},
      {"name": "masked", "albedo": {"generator": "grass"}, "mode": "fbpb+dpt",
       "weight": {"rule": {"height": [0.5, 0.5]}}, "fbpb": {"mask": "m.png"}, "dpt": {"layers": [{}]}},
      {"name": "implicit-fbpb", "albedo": {"generator": "mud"}, "mode": "fbpb",
       "weight": {"splat": {"image": "s.png"}}},
      {"name": "blend-with-fbpb", "albedo": {"generator": "sand"}, "weight": {"rule": {"slope_deg": [10, 20]}},
       "fbpb": {}}
    ]
  })");
}

// A temporary folder holding tiny stand-ins for every asset the full scene names (the parser
// only checks that they exist).
class SceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("terravt_scene_" + std::to_string(::getpid()) + "_" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    for (const char* name : {"h.png", "tex/a.png", "tex/ah.png", "tex/n.png", "s.png", "x.exr", "m.png"})
      write_text(dir / name, "\x89PNG");
  }
  void TearDown() override { fs::remove_all(dir); }

  std::set<std::string> listing() const {
    std::set<std::string> names;
    for (const auto& e : fs::recursive_directory_iterator(dir))
      names.insert(e.path().string() + ":" + std::to_string(e.is_regular_file() ? e.file_size() : 0));
    return names;
  }

  Result<SceneDesc> parse(const json& j) const { return parse_scene(j.dump(), "bad.json", dir.string()); }
  std::string in_dir(const std::string& rel) const { return (dir / rel).lexically_normal().string(); }

  fs::path dir;
};

// ---- the built-in default scene ------------------------------------------------------------

TEST(DefaultScene, HasTheDocumentedContent) {
  const SceneDesc s = default_scene();
  EXPECT_EQ(s.source_path, "<built-in>");
  EXPECT_EQ(s.seed, 1337u);
  EXPECT_TRUE(s.terrain.heightmap.image_path.empty());
  EXPECT_EQ(s.terrain.heightmap.size, 512u);
  EXPECT_EQ(s.terrain.heightmap.seed, 7u);
  EXPECT_EQ(s.terrain.heightmap.octaves, 7u);
  EXPECT_DOUBLE_EQ(s.terrain.heightmap.frequency, 3.0);
  EXPECT_DOUBLE_EQ(s.terrain.heightmap.gain, 0.5);
  EXPECT_DOUBLE_EQ(s.terrain.heightmap.lacunarity, 2.0);
  EXPECT_DOUBLE_EQ(s.terrain.extent_m, 8192.0);
  EXPECT_DOUBLE_EQ(s.terrain.height_m, 900.0);
  EXPECT_EQ(s.vt.log2_size, 20u);
  EXPECT_EQ(s.vt.page_texels, 128u);
  EXPECT_EQ(s.vt.border_texels, 4u);
  EXPECT_DOUBLE_EQ(s.linear_boost, 1.5);
  ASSERT_EQ(s.materials.size(), 5u);

  const MaterialDesc& sand = s.materials[0];
  EXPECT_EQ(sand.name, "sand");
  EXPECT_EQ(sand.albedo.generator, "sand");
  EXPECT_TRUE(sand.albedo.image_path.empty());
  EXPECT_EQ(sand.albedo.resolution, 256u);
  EXPECT_EQ(sand.albedo.seed, 0u);
  EXPECT_DOUBLE_EQ(sand.period_texels, 512.0);
  EXPECT_EQ(sand.mode, Mode::BlendMap);
  EXPECT_EQ(sand.weight.kind, WeightDesc::Kind::Remainder);
  // Hex-tiling on every material but the FBPB cobbles, with the defaults.
  for (size_t n = 0; n < 4; ++n) {
    EXPECT_TRUE(s.materials[n].hex.enabled) << n;
    EXPECT_EQ(s.materials[n].hex.edge, 0.0) << n;
    EXPECT_EQ(s.materials[n].hex.sharpness, 7.0) << n;
    EXPECT_EQ(s.materials[n].hex.preserve, 1.0) << n;
  }
  EXPECT_FALSE(s.materials[4].hex.enabled);
  EXPECT_FALSE(sand.has_fbpb);
  EXPECT_TRUE(sand.dpt.layers.empty());

  const MaterialDesc& grass = s.materials[1];
  EXPECT_EQ(grass.name, "grass");
  EXPECT_EQ(grass.albedo.generator, "grass");
  EXPECT_EQ(grass.albedo.resolution, 256u);
  EXPECT_DOUBLE_EQ(grass.period_texels, 384.0);
  EXPECT_EQ(grass.mode, Mode::Dpt);
  EXPECT_FALSE(grass.has_fbpb);
  EXPECT_EQ(grass.weight.kind, WeightDesc::Kind::Rule);
  EXPECT_DOUBLE_EQ(grass.weight.height_lo, 0.30);
  EXPECT_DOUBLE_EQ(grass.weight.height_hi, 0.75);
  EXPECT_DOUBLE_EQ(grass.weight.height_fade, 0.08);
  EXPECT_DOUBLE_EQ(grass.weight.slope_lo_deg, 0.0);
  EXPECT_DOUBLE_EQ(grass.weight.slope_hi_deg, 24.0);
  EXPECT_DOUBLE_EQ(grass.weight.slope_fade_deg, 6.0);
  EXPECT_DOUBLE_EQ(grass.weight.noise_amplitude, 0.35);
  EXPECT_DOUBLE_EQ(grass.weight.noise_frequency, 24.0);
  ASSERT_EQ(grass.dpt.layers.size(), 2u);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[0].patch_texels, 1024.0);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[0].p, 1.0);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[0].r, 1.0);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[0].w, 1.0);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[0].h, 0.6);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[1].patch_texels, 160.0);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[1].p, 0.5);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[1].r, 1.5);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[1].w, 1.0);
  EXPECT_DOUBLE_EQ(grass.dpt.layers[1].h, 0.3);
  EXPECT_DOUBLE_EQ(grass.dpt.fade_lo_texels, 2.0);
  EXPECT_DOUBLE_EQ(grass.dpt.fade_hi_texels, 8.0);

  const MaterialDesc& mud = s.materials[2];
  EXPECT_EQ(mud.name, "mud");
  EXPECT_EQ(mud.albedo.generator, "mud");
  EXPECT_EQ(mud.albedo.resolution, 256u);
  EXPECT_DOUBLE_EQ(mud.period_texels, 448.0);
  EXPECT_EQ(mud.mode, Mode::Dpt);
  EXPECT_EQ(mud.weight.kind, WeightDesc::Kind::Rule);
  EXPECT_DOUBLE_EQ(mud.weight.height_lo, 0.0);
  EXPECT_DOUBLE_EQ(mud.weight.height_hi, 0.32);
  EXPECT_DOUBLE_EQ(mud.weight.height_fade, 0.06);
  EXPECT_DOUBLE_EQ(mud.weight.slope_lo_deg, 0.0);
  EXPECT_DOUBLE_EQ(mud.weight.slope_hi_deg, 14.0);
  EXPECT_DOUBLE_EQ(mud.weight.slope_fade_deg, 4.0);
  EXPECT_DOUBLE_EQ(mud.weight.noise_amplitude, 0.3);
  EXPECT_DOUBLE_EQ(mud.weight.noise_frequency, 20.0);
  ASSERT_EQ(mud.dpt.layers.size(), 1u);
  EXPECT_DOUBLE_EQ(mud.dpt.layers[0].patch_texels, 768.0);
  EXPECT_DOUBLE_EQ(mud.dpt.layers[0].h, 0.5);

  const MaterialDesc& rock = s.materials[3];
  EXPECT_EQ(rock.name, "rock");
  EXPECT_EQ(rock.albedo.generator, "rock");
  EXPECT_EQ(rock.albedo.resolution, 256u);
  EXPECT_DOUBLE_EQ(rock.period_texels, 640.0);
  EXPECT_EQ(rock.mode, Mode::BlendMap);
  EXPECT_DOUBLE_EQ(rock.weight.height_lo, 0.0);
  EXPECT_DOUBLE_EQ(rock.weight.height_hi, 1.0);
  EXPECT_DOUBLE_EQ(rock.weight.height_fade, 0.0);
  EXPECT_DOUBLE_EQ(rock.weight.slope_lo_deg, 26.0);
  EXPECT_DOUBLE_EQ(rock.weight.slope_hi_deg, 90.0);
  EXPECT_DOUBLE_EQ(rock.weight.slope_fade_deg, 8.0);
  EXPECT_DOUBLE_EQ(rock.weight.noise_amplitude, 0.25);
  EXPECT_DOUBLE_EQ(rock.weight.noise_frequency, 32.0);
  EXPECT_TRUE(rock.dpt.layers.empty());

  const MaterialDesc& cobbles = s.materials[4];
  EXPECT_EQ(cobbles.name, "cobbles");
  EXPECT_EQ(cobbles.albedo.generator, "cobbles");
  EXPECT_EQ(cobbles.albedo.resolution, 512u);
  EXPECT_DOUBLE_EQ(cobbles.period_texels, 256.0);
  EXPECT_EQ(cobbles.mode, Mode::FbpbDpt);
  EXPECT_DOUBLE_EQ(cobbles.weight.height_lo, 0.42);
  EXPECT_DOUBLE_EQ(cobbles.weight.height_hi, 0.62);
  EXPECT_DOUBLE_EQ(cobbles.weight.height_fade, 0.05);
  EXPECT_DOUBLE_EQ(cobbles.weight.slope_hi_deg, 18.0);
  EXPECT_DOUBLE_EQ(cobbles.weight.slope_fade_deg, 5.0);
  EXPECT_DOUBLE_EQ(cobbles.weight.noise_amplitude, 0.4);
  EXPECT_DOUBLE_EQ(cobbles.weight.noise_frequency, 28.0);
  EXPECT_TRUE(cobbles.has_fbpb);
  EXPECT_DOUBLE_EQ(cobbles.fbpb.cm, 1.5);
  EXPECT_DOUBLE_EQ(cobbles.fbpb.cf, 1.0);
  EXPECT_DOUBLE_EQ(cobbles.fbpb.cn, 1.0);
  EXPECT_DOUBLE_EQ(cobbles.fbpb.variation_threshold, 0.3);
  EXPECT_DOUBLE_EQ(cobbles.fbpb.colour_coeff, 0.75);
  EXPECT_DOUBLE_EQ(cobbles.fbpb.fade_lod_lo, 2.0);
  EXPECT_DOUBLE_EQ(cobbles.fbpb.fade_lod_hi, 4.0);
  EXPECT_TRUE(cobbles.fbpb.meta_path.empty());
  EXPECT_TRUE(cobbles.fbpb.mask_path.empty());
  ASSERT_EQ(cobbles.dpt.layers.size(), 2u);
  EXPECT_DOUBLE_EQ(cobbles.dpt.layers[0].patch_texels, 96.0);
  EXPECT_DOUBLE_EQ(cobbles.dpt.layers[1].patch_texels, 16.0);
  EXPECT_DOUBLE_EQ(cobbles.dpt.layers[1].p, 0.5);
  EXPECT_DOUBLE_EQ(cobbles.dpt.layers[1].r, 1.2);
  EXPECT_DOUBLE_EQ(cobbles.dpt.layers[1].w, 1.0);
  EXPECT_DOUBLE_EQ(cobbles.dpt.layers[1].h, 0.25);
}

TEST(DefaultScene, CompiledTextIsIdenticalToDocsCopy) {
  const fs::path docs = fs::path(TVT_SOURCE_DIR) / "docs" / "default-scene.json";
  ASSERT_TRUE(fs::exists(docs)) << docs;
  EXPECT_EQ(read_text(docs), std::string(default_scene_json()));
}

// The built-in scene before it grew to V = 2^20, kept so that the figures measured on it
// (docs/benchmarks.md, docs/stored-megatexture.md) can be reproduced: it must keep loading, and
// differ from today's scene in the VT size and the DPT patch sizes only.
TEST(DefaultScene, EarlierBuiltInSceneLoadsAndDiffersOnlyInScale) {
  const fs::path file = fs::path(TVT_SOURCE_DIR) / "examples" / "scenes" / "builtin-v16.json";
  ASSERT_TRUE(fs::exists(file)) << file;
  Result<SceneDesc> old = parse_scene(read_text(file), file.string(), file.parent_path().string());
  ASSERT_TRUE(old.ok()) << old.error().message;
  EXPECT_EQ(old->vt.log2_size, 16u);
  EXPECT_EQ(old->materials[1].dpt.layers[0].patch_texels, 160.0);
  EXPECT_EQ(old->materials[1].dpt.layers[1].patch_texels, 20.0);
  EXPECT_EQ(old->materials[2].dpt.layers[0].patch_texels, 128.0);
  SceneDesc now = default_scene();
  now.vt.log2_size = 16;
  now.materials[1].dpt.layers[0].patch_texels = 160.0;
  now.materials[1].dpt.layers[1].patch_texels = 20.0;
  now.materials[2].dpt.layers[0].patch_texels = 128.0;
  EXPECT_EQ(scene_to_json(*old), scene_to_json(now));
}

TEST(DefaultScene, RoundTripsThroughJson) {
  const SceneDesc s = default_scene();
  const std::string text = scene_to_json(s);
  const Result<SceneDesc> again = parse_scene(text, "<built-in>", "");
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(scene_to_json(*again), text);
  EXPECT_EQ(again->materials[4].dpt.layers[1].r, s.materials[4].dpt.layers[1].r);
  EXPECT_EQ(again->materials[1].weight.noise_amplitude, s.materials[1].weight.noise_amplitude);
  EXPECT_EQ(again->materials[0].weight.kind, WeightDesc::Kind::Remainder);
  EXPECT_FALSE(again->materials[0].has_fbpb);
  EXPECT_TRUE(again->materials[2].dpt.layers.size() == 1);
}

// Every truncated prefix of a valid scene is rejected cleanly with the source named; flipped
// bytes never crash the parser.
TEST(DefaultScene, TruncatedAndCorruptedTextNeverCrashes) {
  const std::string text(default_scene_json());
  const size_t closing = text.rfind('}');
  for (size_t n = 0; n <= closing; ++n) {
    const Result<SceneDesc> r = parse_scene(std::string_view(text).substr(0, n), "cut.json", "");
    ASSERT_FALSE(r.ok()) << n;
    ASSERT_EQ(r.error().message.rfind("cut.json: ", 0), 0u) << r.error().message;
  }
  for (size_t i = 0; i < text.size(); i += 3) {
    std::string bad = text;
    bad[i] = char(bad[i] ^ (1 << (i % 8)));
    const Result<SceneDesc> r = parse_scene(bad, "flip.json", "");
    if (!r.ok()) {
      ASSERT_EQ(r.error().message.rfind("flip.json: ", 0), 0u) << r.error().message;
    }
  }
}

// ---- a scene using every option ------------------------------------------------------------

TEST_F(SceneTest, FullSceneParsesEveryField) {
  const Result<SceneDesc> r = parse(full_scene_json());
  ASSERT_TRUE(r.ok()) << r.error().message;
  const SceneDesc& s = *r;
  EXPECT_EQ(s.source_path, "bad.json");
  EXPECT_EQ(s.base_dir, dir.string());
  EXPECT_EQ(s.seed, 42u);
  EXPECT_EQ(s.terrain.heightmap.image_path, in_dir("h.png"));
  EXPECT_DOUBLE_EQ(s.terrain.extent_m, 4096.5);
  EXPECT_DOUBLE_EQ(s.terrain.height_m, 321.25);
  EXPECT_EQ(s.vt.log2_size, 20u);
  EXPECT_EQ(s.vt.page_texels, 256u);
  EXPECT_EQ(s.vt.border_texels, 8u);
  EXPECT_DOUBLE_EQ(s.linear_boost, 2.5);
  ASSERT_EQ(s.materials.size(), 7u);

  const MaterialDesc& base = s.materials[0];
  EXPECT_EQ(base.albedo.image_path, in_dir("tex/a.png"));
  EXPECT_EQ(base.albedo.height_path, in_dir("tex/ah.png"));
  EXPECT_TRUE(base.albedo.generator.empty());
  EXPECT_EQ(base.normal_path, in_dir("tex/n.png"));
  EXPECT_DOUBLE_EQ(base.period_texels, 300.5);
  EXPECT_EQ(base.mode, Mode::Linear);
  EXPECT_DOUBLE_EQ(base.blend_sharpness, 0.5);
  EXPECT_EQ(base.weight.kind, WeightDesc::Kind::Remainder);

  const MaterialDesc& splatted = s.materials[1];
  EXPECT_EQ(splatted.albedo.generator, "bricks");
  EXPECT_EQ(splatted.albedo.resolution, 4096u);
  EXPECT_EQ(splatted.albedo.seed, 99u);
  EXPECT_DOUBLE_EQ(splatted.period_texels, 1.0);
  EXPECT_DOUBLE_EQ(splatted.blend_sharpness, 0.01);
  EXPECT_EQ(splatted.weight.kind, WeightDesc::Kind::Splat);
  EXPECT_EQ(splatted.weight.splat_path, in_dir("s.png"));
  EXPECT_EQ(splatted.weight.splat_channel, 3u);

  const MaterialDesc& ruled = s.materials[2];
  EXPECT_EQ(ruled.albedo.resolution, 16u);
  EXPECT_EQ(ruled.albedo.seed, 4294967295u);
  EXPECT_DOUBLE_EQ(ruled.period_texels, 1073741824.0);
  EXPECT_EQ(ruled.mode, Mode::Dpt);
  EXPECT_EQ(ruled.weight.kind, WeightDesc::Kind::Rule);
  EXPECT_DOUBLE_EQ(ruled.weight.height_lo, 0.1);
  EXPECT_DOUBLE_EQ(ruled.weight.height_hi, 0.9);
  EXPECT_DOUBLE_EQ(ruled.weight.height_fade, 0.0);
  EXPECT_DOUBLE_EQ(ruled.weight.slope_hi_deg, 90.0);
  EXPECT_DOUBLE_EQ(ruled.weight.slope_fade_deg, 2.5);
  EXPECT_DOUBLE_EQ(ruled.weight.noise_amplitude, 4.0);
  EXPECT_DOUBLE_EQ(ruled.weight.noise_frequency, 0.5);
  ASSERT_EQ(ruled.dpt.layers.size(), 4u);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[0].patch_texels, 2147483648.0);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[0].p, 1e-3);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[0].r, 1e3);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[0].w, 1e6);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[0].h, 0.0);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[1].p, 1e3);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[1].r, 1e-3);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[1].h, 1e6);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[3].patch_texels, 12.75);
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[3].p, 1.0);  // defaults fill omitted layer fields
  EXPECT_DOUBLE_EQ(ruled.dpt.layers[3].h, 0.5);
  EXPECT_DOUBLE_EQ(ruled.dpt.fade_lo_texels, 0.0);
  EXPECT_DOUBLE_EQ(ruled.dpt.fade_hi_texels, 0.0);
  EXPECT_FALSE(ruled.has_fbpb);

  const MaterialDesc& features = s.materials[3];
  EXPECT_EQ(features.albedo.resolution, 256u);  // default
  EXPECT_EQ(features.albedo.seed, 0u);
  EXPECT_DOUBLE_EQ(features.period_texels, 512.0);
  EXPECT_DOUBLE_EQ(features.blend_sharpness, 0.1);
  EXPECT_EQ(features.weight.kind, WeightDesc::Kind::Rule);
  EXPECT_DOUBLE_EQ(features.weight.height_fade, 0.05);  // rule defaults
  EXPECT_DOUBLE_EQ(features.weight.slope_fade_deg, 5.0);
  EXPECT_DOUBLE_EQ(features.weight.noise_amplitude, 0.0);
  EXPECT_DOUBLE_EQ(features.weight.noise_frequency, 16.0);
  EXPECT_TRUE(features.has_fbpb);
  EXPECT_DOUBLE_EQ(features.fbpb.cm, 0.0);
  EXPECT_DOUBLE_EQ(features.fbpb.cf, 1e6);
  EXPECT_DOUBLE_EQ(features.fbpb.cn, 0.5);
  EXPECT_DOUBLE_EQ(features.fbpb.variation_threshold, 0.0);
  EXPECT_DOUBLE_EQ(features.fbpb.colour_coeff, 1.0);
  EXPECT_DOUBLE_EQ(features.fbpb.fade_lod_lo, -1.0);
  EXPECT_DOUBLE_EQ(features.fbpb.fade_lod_hi, -1.0);
  EXPECT_EQ(features.fbpb.meta_path, in_dir("x.exr"));
  EXPECT_TRUE(features.fbpb.mask_path.empty());

  const MaterialDesc& masked = s.materials[4];
  EXPECT_EQ(masked.mode, Mode::FbpbDpt);
  EXPECT_TRUE(masked.has_fbpb);
  EXPECT_EQ(masked.fbpb.mask_path, in_dir("m.png"));
  EXPECT_TRUE(masked.fbpb.meta_path.empty());
  EXPECT_DOUBLE_EQ(masked.fbpb.cm, 1.5);
  ASSERT_EQ(masked.dpt.layers.size(), 1u);
  EXPECT_DOUBLE_EQ(masked.dpt.layers[0].patch_texels, 256.0);
  EXPECT_DOUBLE_EQ(masked.weight.height_lo, 0.5);
  EXPECT_DOUBLE_EQ(masked.weight.height_hi, 0.5);

  EXPECT_TRUE(s.materials[5].has_fbpb);                // implied by mode "fbpb" without a block
  EXPECT_EQ(s.materials[5].weight.splat_channel, 0u);  // channel defaults to "r"
  EXPECT_EQ(s.materials[6].mode, Mode::BlendMap);
  EXPECT_TRUE(s.materials[6].has_fbpb);  // a block given in blendmap mode
  EXPECT_DOUBLE_EQ(s.materials[6].weight.slope_lo_deg, 10.0);
  EXPECT_DOUBLE_EQ(s.materials[6].weight.slope_hi_deg, 20.0);
}

TEST_F(SceneTest, FullSceneRoundTrips) {
  const Result<SceneDesc> first = parse(full_scene_json());
  ASSERT_TRUE(first.ok()) << first.error().message;
  const std::string text = scene_to_json(*first);
  const Result<SceneDesc> second = parse_scene(text, "bad.json", dir.string());
  ASSERT_TRUE(second.ok()) << second.error().message << "\n" << text;
  EXPECT_EQ(scene_to_json(*second), text);

  // The serialised text is itself the full scene, field for field.
  const json written = json::parse(text);
  EXPECT_EQ(written["materials"][0]["albedo"]["image"], "tex/a.png");  // relative to base_dir again
  EXPECT_EQ(written["materials"][2]["albedo"]["seed"], 4294967295u);
  EXPECT_EQ(written["materials"][3]["fbpb"]["meta"], "x.exr");
  EXPECT_FALSE(written["materials"][0].contains("fbpb"));
  EXPECT_FALSE(written["materials"][0].contains("dpt"));

  const SceneDesc& a = *first;
  const SceneDesc& b = *second;
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.terrain.heightmap.image_path, b.terrain.heightmap.image_path);
  EXPECT_EQ(a.vt.page_texels, b.vt.page_texels);
  ASSERT_EQ(a.materials.size(), b.materials.size());
  for (size_t i = 0; i < a.materials.size(); ++i) {
    SCOPED_TRACE(a.materials[i].name);
    const MaterialDesc& x = a.materials[i];
    const MaterialDesc& y = b.materials[i];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.albedo.image_path, y.albedo.image_path);
    EXPECT_EQ(x.albedo.height_path, y.albedo.height_path);
    EXPECT_EQ(x.albedo.generator, y.albedo.generator);
    EXPECT_EQ(x.albedo.resolution, y.albedo.resolution);
    EXPECT_EQ(x.albedo.seed, y.albedo.seed);
    EXPECT_EQ(x.normal_path, y.normal_path);
    EXPECT_EQ(x.period_texels, y.period_texels);
    EXPECT_EQ(x.mode, y.mode);
    EXPECT_EQ(x.blend_sharpness, y.blend_sharpness);
    EXPECT_EQ(x.weight.kind, y.weight.kind);
    EXPECT_EQ(x.weight.splat_path, y.weight.splat_path);
    EXPECT_EQ(x.weight.splat_channel, y.weight.splat_channel);
    EXPECT_EQ(x.weight.height_lo, y.weight.height_lo);
    EXPECT_EQ(x.weight.slope_hi_deg, y.weight.slope_hi_deg);
    EXPECT_EQ(x.weight.noise_frequency, y.weight.noise_frequency);
    EXPECT_EQ(x.has_fbpb, y.has_fbpb);
    EXPECT_EQ(x.fbpb.meta_path, y.fbpb.meta_path);
    EXPECT_EQ(x.fbpb.mask_path, y.fbpb.mask_path);
    EXPECT_EQ(x.fbpb.fade_lod_lo, y.fbpb.fade_lod_lo);
    EXPECT_EQ(x.fbpb.cf, y.fbpb.cf);
    ASSERT_EQ(x.dpt.layers.size(), y.dpt.layers.size());
    for (size_t k = 0; k < x.dpt.layers.size(); ++k) {
      EXPECT_EQ(x.dpt.layers[k].patch_texels, y.dpt.layers[k].patch_texels);
      EXPECT_EQ(x.dpt.layers[k].p, y.dpt.layers[k].p);
      EXPECT_EQ(x.dpt.layers[k].r, y.dpt.layers[k].r);
      EXPECT_EQ(x.dpt.layers[k].w, y.dpt.layers[k].w);
      EXPECT_EQ(x.dpt.layers[k].h, y.dpt.layers[k].h);
    }
    EXPECT_EQ(x.dpt.fade_lo_texels, y.dpt.fade_lo_texels);
    EXPECT_EQ(x.dpt.fade_hi_texels, y.dpt.fade_hi_texels);
  }
}

TEST_F(SceneTest, RoundTripKeepsAwkwardDoublesExact) {
  json j = full_scene_json();
  j["terrain"]["extent_m"] = 0.1 + 0.2;
  j["materials"][2]["dpt"]["layers"][0]["p"] = 1.0 / 3.0;
  const Result<SceneDesc> a = parse(j);
  ASSERT_TRUE(a.ok()) << a.error().message;
  const Result<SceneDesc> b = parse_scene(scene_to_json(*a), "x.json", dir.string());
  ASSERT_TRUE(b.ok()) << b.error().message;
  EXPECT_EQ(b->terrain.extent_m, 0.1 + 0.2);
  EXPECT_EQ(b->materials[2].dpt.layers[0].p, 1.0 / 3.0);
}

// ---- one rejected case per rule ------------------------------------------------------------

struct BadCase {
  std::string set;     // JSON pointer to replace (or remove)
  json value;          // new value
  std::string expect;  // pointer the error must name; empty: same as `set`
  bool remove = false;
};

BadCase Set(std::string ptr, json value, std::string expect = {}) {
  return {std::move(ptr), std::move(value), std::move(expect), false};
}
BadCase Remove(std::string ptr, std::string expect = {}) { return {std::move(ptr), nullptr, std::move(expect), true}; }

TEST_F(SceneTest, EveryRuleViolationNamesFileAndPointer) {
  const auto fbm = [](json fields) { return json{{"fbm", std::move(fields)}}; };
  json seventeen = json::array();
  for (int i = 0; i < 17; ++i) seventeen.push_back(full_scene_json()["materials"][1]);
  const json five_layers =
      json::array({json::object(), json::object(), json::object(), json::object(), json::object()});

  const std::vector<BadCase> cases = {
      // seeds: uint32 only
      Set("/seed", -1),
      Set("/seed", 4294967296ull),
      Set("/seed", 1.5),
      Set("/seed", "1"),
      Set("/seed", json::parse("123456789012345678901234567890")),
      // terrain
      Set("/terrain", "flat"),
      Set("/terrain/extent_m", 0),
      Set("/terrain/extent_m", -5),
      Set("/terrain/extent_m", 1.5e9),  // beyond the camera's coordinate limit
      Set("/terrain/height_m", 2e6),
      Set("/terrain/extent_m", "big"),
      Set("/terrain/height_m", -0.1),
      Set("/terrain/colour", 1),
      Set("/terrain/heightmap", json::object()),
      Set("/terrain/heightmap", {{"image", "h.png"}, {"fbm", json::object()}}),
      Set("/terrain/heightmap/image", "nope.png"),
      Set("/terrain/heightmap/image", ""),
      Set("/terrain/heightmap/image", 3),
      Set("/terrain/heightmap/colour", 1),
      Set("/terrain/heightmap", fbm({{"size", 15}}), "/terrain/heightmap/fbm/size"),
      Set("/terrain/heightmap", fbm({{"size", 8193}}), "/terrain/heightmap/fbm/size"),
      Set("/terrain/heightmap", fbm({{"seed", -3}}), "/terrain/heightmap/fbm/seed"),
      Set("/terrain/heightmap", fbm({{"octaves", 0}}), "/terrain/heightmap/fbm/octaves"),
      Set("/terrain/heightmap", fbm({{"octaves", 17}}), "/terrain/heightmap/fbm/octaves"),
      Set("/terrain/heightmap", fbm({{"frequency", 0}}), "/terrain/heightmap/fbm/frequency"),
      Set("/terrain/heightmap", fbm({{"frequency", 2e6}}), "/terrain/heightmap/fbm/frequency"),
      Set("/terrain/heightmap", fbm({{"gain", 0}}), "/terrain/heightmap/fbm/gain"),
      Set("/terrain/heightmap", fbm({{"gain", 1}}), "/terrain/heightmap/fbm/gain"),
      Set("/terrain/heightmap", fbm({{"lacunarity", 1}}), "/terrain/heightmap/fbm/lacunarity"),
      Set("/terrain/heightmap", fbm({{"lacunarity", 4.5}}), "/terrain/heightmap/fbm/lacunarity"),
      Set("/terrain/heightmap", fbm({{"colour", 1}}), "/terrain/heightmap/fbm/colour"),
      Set("/terrain/heightmap", {{"fbm", 7}}, "/terrain/heightmap/fbm"),
      // vt (ranges from validate(VtConfig))
      Set("/vt", 16),
      Set("/vt/log2_size", 9),
      Set("/vt/log2_size", 31),
      Set("/vt/log2_size", -1),
      Set("/vt/page_texels", 100),
      Set("/vt/border_texels", 200),
      Set("/vt/colour", 1),
      // linear boost
      Set("/linear_boost", 0.5),
      Set("/linear_boost", 4.5),
      Set("/linear_boost", nullptr),
      // materials list
      Set("/materials", json::array()),
      Set("/materials", seventeen),
      Set("/materials", "sand"),
      Remove("/materials"),
      Set("/materials/0", 3),
      Set("/colour", 1),
      // name
      Set("/materials/0/name", ""),
      Set("/materials/0/name", 5),
      Set("/materials/2/name", "base"),
      Remove("/materials/0/name"),
      // albedo
      Remove("/materials/1/albedo"),
      Set("/materials/1/albedo", "bricks"),
      Set("/materials/1/albedo/generator", "marble"),
      Set("/materials/1/albedo/generator", ""),
      Set("/materials/1/albedo/resolution", 300),
      Set("/materials/1/albedo/resolution", 8),
      Set("/materials/1/albedo/resolution", 8192),
      Set("/materials/1/albedo/resolution", 256.5),
      Set("/materials/1/albedo/seed", -1),
      Set("/materials/1/albedo/seed", 4294967296ull),
      Set("/materials/1/albedo/image", "tex/a.png", "/materials/1/albedo"),
      Set("/materials/1/albedo/height", "tex/ah.png"),
      Set("/materials/1/albedo/colour", 1),
      Set("/materials/0/albedo", json::object()),
      Set("/materials/0/albedo/image", "missing.png"),
      Set("/materials/0/albedo/height", "missing.png"),
      Set("/materials/0/albedo/resolution", 100),
      Set("/materials/0/albedo/height_source", "sideways"),
      Set("/materials/0/albedo/height_source", "none"),  // with a "height" image
      Set("/materials/0/albedo/height_invert", 1),
      Set("/materials/1/albedo/height_source", "luminance"),  // material 1 is a generator
      Set("/materials/0/albedo/seed", 1),
      Set("/materials/0/normal", "missing.png"),
      Set("/materials/0/normal", 7),
      Set("/materials/0/normal", "tex"),  // a directory is not a file
      // period, mode, sharpness
      Set("/materials/0/period_texels", 0.5),
      Set("/materials/0/period_texels", 1073741825.0),
      Set("/materials/0/period_texels", true),
      Set("/materials/0/mode", "cubic"),
      Set("/materials/0/mode", 3),
      Set("/materials/0/blend_sharpness", 0),
      Set("/materials/0/blend_sharpness", 0.51),
      Set("/materials/0/colour", 1),
      // weight
      Set("/materials/1/weight", "remainder"),
      Remove("/materials/1/weight"),
      Set("/materials/1/weight", "other"),
      Set("/materials/1/weight", 1),
      Set("/materials/1/weight", json::object()),
      Set("/materials/1/weight", {{"rule", json::object()}, {"splat", {{"image", "s.png"}}}}),
      Set("/materials/1/weight/colour", 1),
      Set("/materials/1/weight/splat/channel", "x"),
      Set("/materials/1/weight/splat/channel", 0),
      Set("/materials/1/weight/splat/image", "nope.png"),
      Remove("/materials/1/weight/splat/image"),
      Set("/materials/1/weight/splat/colour", 1),
      Set("/materials/2/weight/rule", 0.5),
      Set("/materials/2/weight/rule/height", json::array({0.9, 0.1})),
      Set("/materials/2/weight/rule/height", json::array({-0.1, 0.5}), "/materials/2/weight/rule/height/0"),
      Set("/materials/2/weight/rule/height", json::array({0.5, 1.1}), "/materials/2/weight/rule/height/1"),
      Set("/materials/2/weight/rule/height", json::array({0.5})),
      Set("/materials/2/weight/rule/height", "low"),
      Set("/materials/2/weight/rule/height_fade", -1),
      Set("/materials/2/weight/rule/height_fade", 2e6),
      Set("/materials/2/weight/rule/slope_deg", json::array({0, 91}), "/materials/2/weight/rule/slope_deg/1"),
      Set("/materials/2/weight/rule/slope_deg", json::array({-1, 20}), "/materials/2/weight/rule/slope_deg/0"),
      Set("/materials/2/weight/rule/slope_deg", json::array({30, 20})),
      Set("/materials/2/weight/rule/slope_fade_deg", -1),
      Set("/materials/2/weight/rule/slope_fade_deg", 2e6),
      Set("/materials/2/weight/rule/noise/amplitude", 4.5),
      Set("/materials/2/weight/rule/noise/amplitude", -0.1),
      Set("/materials/2/weight/rule/noise/frequency", 0),
      Set("/materials/2/weight/rule/noise/frequency", 2e6),
      Set("/materials/2/weight/rule/noise/colour", 1),
      Set("/materials/2/weight/rule/colour", 1),
      // fbpb
      Set("/materials/3/fbpb", "on"),
      Set("/materials/3/fbpb/cm", -1),
      Set("/materials/3/fbpb/cm", 2e6),
      Set("/materials/3/fbpb/cf", -1),
      Set("/materials/3/fbpb/cn", 1e7),
      Set("/materials/3/fbpb/variation_threshold", 1.5),
      Set("/materials/3/fbpb/colour_coeff", -0.1),
      Set("/materials/3/fbpb/fade_lod", json::array({4, 2})),
      Set("/materials/3/fbpb/mask", "m.png"),
      Set("/materials/3/fbpb/meta", "nope.exr"),
      Set("/materials/4/fbpb/mask", "nope.png"),
      Set("/materials/3/fbpb/colour", 1),
      // dpt
      Set("/materials/2/dpt", "x"),
      Set("/materials/2/dpt/layers", json::object()),
      Set("/materials/2/dpt/layers", five_layers),
      Set("/materials/2/dpt/layers", json::array()),
      Remove("/materials/2/dpt", "/materials/2/dpt/layers"),
      Set("/materials/4/dpt/layers", json::array()),
      Remove("/materials/4/dpt", "/materials/4/dpt/layers"),
      Set("/materials/2/dpt/layers/0", 1),
      Set("/materials/2/dpt/layers/0/p", -1),
      Set("/materials/2/dpt/layers/0/p", 0),
      Set("/materials/2/dpt/layers/0/p", 2e6),
      Set("/materials/2/dpt/layers/0/p", "1"),
      Set("/materials/2/dpt/layers/1/r", 0),
      Set("/materials/2/dpt/layers/1/r", 1e6 + 1),
      Set("/materials/2/dpt/layers/2/w", 0),
      Set("/materials/2/dpt/layers/2/w", 1e7),
      Set("/materials/2/dpt/layers/3/h", -1),
      Set("/materials/2/dpt/layers/3/h", 2e6),
      Set("/materials/2/dpt/layers/0/patch_texels", 0),
      Set("/materials/2/dpt/layers/0/patch_texels", 2147483649.0),
      Set("/materials/2/dpt/layers/0/colour", 1),
      Set("/materials/2/dpt/fade_texels", json::array({-1, 2}), "/materials/2/dpt/fade_texels/0"),
      Set("/materials/2/dpt/fade_texels", json::array({8, 2})),
      Set("/materials/2/dpt/fade_texels", json::array({2, 3e9}), "/materials/2/dpt/fade_texels/1"),
      Set("/materials/2/dpt/fade_texels", 4),
      Set("/materials/2/dpt/colour", 1),
      // hex
      Set("/materials/1/hex", 3),
      Set("/materials/1/hex", "yes"),
      Set("/materials/1/hex", json::array()),
      Set("/materials/1/hex", {{"edge", 1}}, "/materials/1/hex/edge"),
      Set("/materials/1/hex", {{"edge", 70000}}, "/materials/1/hex/edge"),
      Set("/materials/1/hex", {{"edge", "wide"}}, "/materials/1/hex/edge"),
      Set("/materials/1/hex", {{"sharpness", 0.5}}, "/materials/1/hex/sharpness"),
      Set("/materials/1/hex", {{"sharpness", 65}}, "/materials/1/hex/sharpness"),
      Set("/materials/1/hex", {{"preserve", -0.1}}, "/materials/1/hex/preserve"),
      Set("/materials/1/hex", {{"preserve", 1.5}}, "/materials/1/hex/preserve"),
      Set("/materials/1/hex", {{"rotation", 1}}, "/materials/1/hex/rotation"),
  };

  ASSERT_TRUE(parse(full_scene_json()).ok());
  for (const BadCase& c : cases) {
    json j = full_scene_json();
    const json::json_pointer ptr(c.set);
    if (c.remove) {
      j.at(ptr.parent_pointer()).erase(ptr.back());
    } else {
      j[ptr] = c.value;
    }
    const std::string expect = c.expect.empty() ? c.set : c.expect;
    SCOPED_TRACE(c.set + " = " + (c.remove ? std::string("<removed>") : c.value.dump()));
    const Result<SceneDesc> r = parse(j);
    ASSERT_FALSE(r.ok());
    const std::string& m = r.error().message;
    EXPECT_EQ(m.rfind("bad.json: " + expect + ": ", 0), 0u) << m;
  }
  // Nothing is ever written by the parser.
  EXPECT_EQ(listing().size(), 7u + 1u);  // seven files and the "tex" folder
}

TEST_F(SceneTest, MessagesFollowTheDocumentedForm) {
  json j = full_scene_json();
  j["materials"][2]["dpt"]["layers"][0]["p"] = -1;
  Result<SceneDesc> r = parse_scene(j.dump(), "my.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message, "my.json: /materials/2/dpt/layers/0/p: must be a finite number > 0, got -1");

  j = full_scene_json();
  j["materials"][0]["blend_sharpness"] = 0.75;
  r = parse_scene(j.dump(), "my.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message, "my.json: /materials/0/blend_sharpness: must be a finite number in (0, 0.5], got 0.75");

  j = full_scene_json();
  j["seed"] = -7;
  r = parse_scene(j.dump(), "my.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message, "my.json: /seed: must be an integer in [0, 4294967295], got -7");

  j = full_scene_json();
  j["materials"][1]["albedo"]["resolution"] = 300;
  r = parse_scene(j.dump(), "my.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message,
            "my.json: /materials/1/albedo/resolution: must be a power of two in [16, 4096], got 300");
}

TEST_F(SceneTest, UnknownFieldIsNamed) {
  json j = full_scene_json();
  j["materials"][3]["fbpb"]["colur_coeff"] = 0.5;
  const Result<SceneDesc> r = parse(j);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "bad.json: /materials/3/fbpb/colur_coeff: unknown field \"colur_coeff\""))
      << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "colour_coeff")) << "lists the allowed names";
}

TEST_F(SceneTest, WrongTypeIsRejected) {
  json j = full_scene_json();
  j["materials"][2]["weight"]["rule"]["height"] = {{"lo", 0}, {"hi", 1}};
  Result<SceneDesc> r = parse(j);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "bad.json: /materials/2/weight/rule/height: must be an array"))
      << r.error().message;

  j = full_scene_json();
  j["vt"]["page_texels"] = "128";
  r = parse(j);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "bad.json: /vt/page_texels: must be a power of two in [16, 1024]")) << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "got \"128\"")) << r.error().message;

  r = parse_scene("[1, 2]", "bad.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "bad.json: <root>: must be an object")) << r.error().message;
}

TEST_F(SceneTest, IntegralFloatsAreAcceptedForIntegerFields) {
  json j = full_scene_json();
  j["seed"] = 7.0;
  j["materials"][1]["albedo"]["resolution"] = 512.0;
  const Result<SceneDesc> r = parse(j);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->seed, 7u);
  EXPECT_EQ(r->materials[1].albedo.resolution, 512u);
}

TEST_F(SceneTest, OnlyTheFirstMaterialDefaultsToRemainder) {
  json j = full_scene_json();
  j["materials"][0].erase("weight");
  Result<SceneDesc> r = parse(j);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->materials[0].weight.kind, WeightDesc::Kind::Remainder);

  j["materials"][0]["weight"] = {{"splat", {{"image", "s.png"}, {"channel", "g"}}}};  // may also be explicit
  r = parse(j);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->materials[0].weight.kind, WeightDesc::Kind::Splat);
  EXPECT_EQ(r->materials[0].weight.splat_channel, 1u);
}

TEST_F(SceneTest, HexTilingIsOffUnlessAskedAndRoundTrips) {
  json j = full_scene_json();
  j["materials"][1]["hex"] = true;
  j["materials"][2]["hex"] = {{"edge", 96}, {"sharpness", 12}, {"preserve", 0.25}};
  j["materials"][3]["hex"] = false;
  const Result<SceneDesc> r = parse(j);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(r->materials[0].hex.enabled);
  EXPECT_TRUE(r->materials[1].hex.enabled);
  EXPECT_EQ(r->materials[1].hex.edge, 0.0);  // half the material's resolution, at pack time
  EXPECT_EQ(r->materials[1].hex.sharpness, 7.0);
  EXPECT_EQ(r->materials[1].hex.preserve, 1.0);
  EXPECT_TRUE(r->materials[2].hex.enabled);
  EXPECT_EQ(r->materials[2].hex.edge, 96.0);
  EXPECT_EQ(r->materials[2].hex.sharpness, 12.0);
  EXPECT_EQ(r->materials[2].hex.preserve, 0.25);
  EXPECT_FALSE(r->materials[3].hex.enabled);
  const std::string text = scene_to_json(r.value());
  const Result<SceneDesc> again = parse_scene(text, "again.json", dir.string());
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(scene_to_json(again.value()), text);
  EXPECT_TRUE(again->materials[1].hex.enabled);
  EXPECT_EQ(again->materials[2].hex.edge, 96.0);
  // A scene without hex-tiling serialises without the field (its identity is unchanged).
  const Result<SceneDesc> none = parse(full_scene_json());
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(scene_to_json(none.value()).find("\"hex\""), std::string::npos);
}

TEST_F(SceneTest, DptModesNeedALayer) {
  json j = full_scene_json();
  j["materials"][4]["dpt"]["layers"] = json::array();
  const Result<SceneDesc> r = parse(j);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "bad.json: /materials/4/dpt/layers: mode \"fbpb+dpt\" needs at least one"))
      << r.error().message;
}

// ---- malformed text, numbers that do not fit -----------------------------------------------

TEST_F(SceneTest, MalformedJsonNamesFileAndPosition) {
  Result<SceneDesc> r = parse_scene("{\n  \"seed\": 1,\n  \"materials\": [}\n", "broken.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message.rfind("broken.json: ", 0), 0u) << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "line 3")) << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "invalid JSON")) << r.error().message;

  for (const char* text : {"", "{", "{\"seed\": 1,}", "{} trailing", "{\"seed\": tru}", "{\"a\" 1}"}) {
    r = parse_scene(text, "broken.json", dir.string());
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_EQ(r.error().message.rfind("broken.json: ", 0), 0u) << r.error().message;
  }
}

TEST_F(SceneTest, DuplicateKeysAreRejected) {
  const Result<SceneDesc> r = parse_scene(R"({"seed": 1, "terrain": {"extent_m": 1, "extent_m": 2}})", "dup.json", "");
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "dup.json: /terrain/extent_m: duplicate field")) << r.error().message;
}

TEST_F(SceneTest, OverflowingNumbersGiveACleanError) {
  std::string text = full_scene_json().dump();
  const auto replace = [](std::string s, const std::string& from, const std::string& to) {
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  Result<SceneDesc> r =
      parse_scene(replace(text, "\"extent_m\":4096.5", "\"extent_m\":1e999"), "big.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "big.json: /terrain/extent_m: number is out of range")) << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "got 1e999")) << r.error().message;

  r = parse_scene(replace(text, "\"p\":0.001", "\"p\":-1e999"), "big.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "big.json: /materials/2/dpt/layers/0/p: number is out of range"))
      << r.error().message;

  r = parse_scene(replace(text, "\"seed\":42,", "\"seed\":1e999,"), "big.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "big.json: /seed:")) << r.error().message;

  // Integers beyond 64 bits are read as doubles and then fail the field's range.
  r = parse_scene(replace(text, "\"seed\":42,", "\"seed\":99999999999999999999999999,"), "big.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "big.json: /seed: must be an integer")) << r.error().message;
  r = parse_scene(replace(text, "\"period_texels\":300.5", "\"period_texels\":99999999999999999999999999"), "big.json",
                  dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "big.json: /materials/0/period_texels: must be a finite number <= "))
      << r.error().message;
  r = parse_scene(replace(text, "\"log2_size\":20", "\"log2_size\":18446744073709551615"), "big.json", dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "big.json: /vt/log2_size:")) << r.error().message;
}

// ---- files -------------------------------------------------------------------------------

TEST_F(SceneTest, MissingOrUnreadableSceneFileIsNamed) {
  const std::string missing = (dir / "no-such-scene.json").string();
  Result<SceneDesc> r = load_scene_file(missing);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message.rfind(missing + ": ", 0), 0u) << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "not found")) << r.error().message;

  r = load_scene_file((dir / "tex").string());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message.rfind((dir / "tex").string() + ": ", 0), 0u) << r.error().message;
}

TEST_F(SceneTest, MissingReferencedImageNamesTheResolvedPath) {
  json j = full_scene_json();
  j["materials"][1]["weight"]["splat"]["image"] = "maps/splat.png";
  const Result<SceneDesc> r = parse(j);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message, "bad.json: /materials/1/weight/splat/image: file not found: " +
                                   in_dir("maps/splat.png") + ", got \"maps/splat.png\"");
}

TEST_F(SceneTest, RelativePathsResolveAgainstTheSceneFolder) {
  // Assets next to the scene, one level up, and at an absolute path.
  write_text(dir / "scenes" / "local.png", "x");
  json j = full_scene_json();
  j["terrain"]["heightmap"]["image"] = "../h.png";
  j["materials"][0]["albedo"] = {{"image", "local.png"}, {"height", (dir / "tex" / "ah.png").string()}};
  j["materials"][0].erase("normal");
  j["materials"][1]["weight"]["splat"]["image"] = "./../s.png";
  j["materials"][3]["fbpb"]["meta"] = "../x.exr";
  j["materials"][4]["fbpb"]["mask"] = "../m.png";
  j["materials"][5]["weight"]["splat"]["image"] = "../s.png";
  const fs::path scene = dir / "scenes" / "terrain.json";
  write_text(scene, j.dump(2));

  const Result<SceneDesc> r = load_scene_file(scene.string());
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->source_path, scene.string());
  EXPECT_EQ(r->base_dir, (dir / "scenes").string());
  EXPECT_EQ(r->terrain.heightmap.image_path, in_dir("h.png"));
  EXPECT_EQ(r->materials[0].albedo.image_path, in_dir("scenes/local.png"));
  EXPECT_EQ(r->materials[0].albedo.height_path, in_dir("tex/ah.png"));
  EXPECT_EQ(r->materials[1].weight.splat_path, in_dir("s.png"));
  EXPECT_TRUE(fs::exists(r->materials[0].albedo.image_path));

  // The same text parsed against another folder does not find "local.png".
  const Result<SceneDesc> elsewhere = parse_scene(j.dump(), "t.json", dir.string());
  ASSERT_FALSE(elsewhere.ok());
  EXPECT_TRUE(contains(elsewhere.error().message, "t.json: /terrain/heightmap/image: file not found"))
      << elsewhere.error().message;

  // Serialising writes paths relative to the scene folder where they are inside it, absolute
  // otherwise, and re-parsing gives the same resolved paths.
  const std::string text = scene_to_json(*r);
  const json written = json::parse(text);
  EXPECT_EQ(written["materials"][0]["albedo"]["image"], "local.png");
  EXPECT_EQ(written["terrain"]["heightmap"]["image"], in_dir("h.png"));
  const Result<SceneDesc> again = parse_scene(text, scene.string(), r->base_dir);
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(scene_to_json(*again), text);
  EXPECT_EQ(again->materials[0].albedo.image_path, r->materials[0].albedo.image_path);
  EXPECT_EQ(again->terrain.heightmap.image_path, r->terrain.heightmap.image_path);
}

TEST_F(SceneTest, SceneFileErrorsNameTheFile) {
  const fs::path scene = dir / "broken scene.json";
  write_text(scene, R"({"materials": [{"name": "a", "albedo": {"generator": "sand"}, "period_texels": -1}]})");
  const std::set<std::string> before = listing();
  const Result<SceneDesc> r = load_scene_file(scene.string());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message, scene.string() + ": /materials/0/period_texels: must be a finite number >= 1, got -1");
  EXPECT_EQ(listing(), before);  // the parser wrote nothing
}

}  // namespace
