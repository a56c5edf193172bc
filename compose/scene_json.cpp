// Scene files: JSON -> SceneDesc (fully validated) and back. The format is documented in
// docs/scene-format.md; every rule there is enforced here.
//
// Errors: the first problem found is reported as
//   "<source_path>: <json pointer>: <what is wrong>, got <value>"
// The field readers are json/json_check.h's; a failed check throws there and parse_scene
// turns it into a Result; nothing escapes. The parser never writes anything; it only checks
// that referenced files exist.
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "json/json_check.h"
#include "compose/procedural.h"
#include "compose/scene.h"

namespace tvt {

namespace {

namespace fs = std::filesystem;
using namespace json_check;  // NOLINT: the readers, bounds and json types of this file
using ojson = nlohmann::ordered_json;

constexpr uint32_t k_u32_max = std::numeric_limits<uint32_t>::max();
constexpr std::array<char, 4> k_channels{'r', 'g', 'b', 'a'};
constexpr size_t k_max_materials = 16;
constexpr size_t k_max_dpt_layers = 4;

class Parser : public json_check::Reader {
 public:
  using Reader::Reader;

  SceneDesc scene(const json& root) const {
    const Ptr at;
    object(root, at, {"seed", "terrain", "vt", "linear_boost", "materials"});
    SceneDesc s;
    s.source_path = source_;
    s.base_dir = base_dir_;
    if (const json* f = field(root, "seed")) s.seed = uint(*f, at / "seed", 0, k_u32_max);
    if (const json* f = field(root, "terrain")) s.terrain = terrain(*f, at / "terrain");
    if (const json* f = field(root, "vt")) s.vt = vt(*f, at / "vt");
    const Status vt_ok = validate(s.vt, source_ + ": /vt");
    if (!vt_ok) throw Failure{vt_ok.error().message};
    if (const json* f = field(root, "linear_boost")) s.linear_boost = real(*f, at / "linear_boost", closed(1, 4));

    const json& list = require(root, at, "materials");
    const Ptr list_at = at / "materials";
    if (!list.is_array()) fail(list_at, "must be an array of 1 to 16 materials", list);
    if (list.empty() || list.size() > k_max_materials)
      fail(list_at, "must hold 1 to 16 materials", std::to_string(list.size()) + " materials");
    for (size_t i = 0; i < list.size(); ++i) {
      s.materials.push_back(material(list[i], list_at / i, i));
      for (size_t j = 0; j < i; ++j)
        if (s.materials[j].name == s.materials[i].name)
          fail(list_at / i / "name", "duplicate material name (also at /materials/" + std::to_string(j) + "/name)",
               list[i]["name"]);
    }
    return s;
  }

 private:
  HeightmapDesc heightmap(const json& v, const Ptr& at) const {
    object(v, at, {"image", "fbm"});
    const json* image = field(v, "image");
    const json* fbm = field(v, "fbm");
    if ((image != nullptr) == (fbm != nullptr)) fail(at, "needs exactly one of \"image\" or \"fbm\"", v);
    HeightmapDesc h;
    if (image) {
      h.image_path = file(*image, at / "image");
      return h;
    }
    const Ptr f_at = at / "fbm";
    object(*fbm, f_at, {"size", "seed", "octaves", "frequency", "gain", "lacunarity"});
    if (const json* f = field(*fbm, "size")) h.size = uint(*f, f_at / "size", 16, 8192);
    if (const json* f = field(*fbm, "seed")) h.seed = uint(*f, f_at / "seed", 0, k_u32_max);
    if (const json* f = field(*fbm, "octaves")) h.octaves = uint(*f, f_at / "octaves", 1, 16);
    if (const json* f = field(*fbm, "frequency")) h.frequency = real(*f, f_at / "frequency", above(0, 1e6));
    if (const json* f = field(*fbm, "gain")) h.gain = real(*f, f_at / "gain", open(0, 1));
    if (const json* f = field(*fbm, "lacunarity")) h.lacunarity = real(*f, f_at / "lacunarity", open_closed(1, 4));
    return h;
  }

  TerrainDesc terrain(const json& v, const Ptr& at) const {
    object(v, at, {"extent_m", "height_m", "heightmap"});
    TerrainDesc t;
    if (const json* f = field(v, "extent_m")) t.extent_m = real(*f, at / "extent_m", above(0, 1e9));  // the camera file's coordinate limit
    if (const json* f = field(v, "height_m")) t.height_m = real(*f, at / "height_m", at_least(0, 1e6));
    if (const json* f = field(v, "heightmap")) t.heightmap = heightmap(*f, at / "heightmap");
    return t;
  }

  VtConfig vt(const json& v, const Ptr& at) const {
    object(v, at, {"log2_size", "page_texels", "border_texels"});
    // Each field's own range (validate(VtConfig)'s), so a wrong value is told the range it
    // must be in; how the fields relate (border vs page, page vs size) is validate()'s.
    VtConfig c;
    if (const json* f = field(v, "log2_size")) c.log2_size = uint(*f, at / "log2_size", 10, 30);
    if (const json* f = field(v, "page_texels")) c.page_texels = uint(*f, at / "page_texels", 16, 1024, true);
    if (const json* f = field(v, "border_texels")) c.border_texels = uint(*f, at / "border_texels", 0, 512);
    return c;
  }

  TextureDesc texture(const json& v, const Ptr& at) const {
    object(v, at, {"generator", "resolution", "seed", "image", "height", "height_source", "height_invert"});
    const json* generator = field(v, "generator");
    const json* image = field(v, "image");
    if ((generator != nullptr) == (image != nullptr)) fail(at, "needs exactly one of \"generator\" or \"image\"", v);
    TextureDesc t;
    if (generator) {
      for (const char* key : {"height", "height_source", "height_invert"})
        if (const json* f = field(v, key)) fail(at / key, "only allowed with \"image\"", *f);
      t.generator = text(*generator, at / "generator");
      if (!is_known_generator(t.generator)) fail(at / "generator", "must be one of sand, grass, rock, mud, cobbles, bricks", *generator);
      if (const json* f = field(v, "resolution")) t.resolution = uint(*f, at / "resolution", 16, 4096, true);
      if (const json* f = field(v, "seed")) t.seed = uint(*f, at / "seed", 0, k_u32_max);
      return t;
    }
    if (const json* f = field(v, "resolution"))
      t.image_resolution = uint(*f, at / "resolution", k_min_material_resolution, k_max_material_resolution, true);
    if (const json* f = field(v, "seed")) fail(at / "seed", "only allowed with \"generator\"", *f);
    t.image_path = file(*image, at / "image");
    if (const json* f = field(v, "height")) t.height_path = file(*f, at / "height");
    if (const json* f = field(v, "height_source")) {
      const auto source = f->is_string() ? height_source_from_string(f->get_ref<const std::string&>()) : std::nullopt;
      if (!source) fail(at / "height_source", "must be one of auto, alpha, luminance, file, none", *f);
      t.height_source = *source;
    }
    if (t.height_source == HeightSource::File && t.height_path.empty())
      fail(at / "height_source", "\"file\" needs \"height\" (the height image)", *field(v, "height_source"));
    if (!t.height_path.empty() && t.height_source != HeightSource::Auto && t.height_source != HeightSource::File)
      fail(at / "height_source", "must be auto or file when \"height\" names a height image", *field(v, "height_source"));
    if (const json* f = field(v, "height_invert")) t.height_invert = boolean(*f, at / "height_invert");
    return t;
  }

  WeightDesc weight(const json& v, const Ptr& at) const {
    WeightDesc w;
    if (v.is_string() && v.get_ref<const std::string&>() == "remainder") return w;
    if (!v.is_object()) fail(at, "must be \"remainder\" or an object with \"rule\" or \"splat\"", v);
    object(v, at, {"rule", "splat"});
    const json* rule = field(v, "rule");
    const json* splat = field(v, "splat");
    if ((rule != nullptr) == (splat != nullptr)) fail(at, "needs exactly one of \"rule\" or \"splat\"", v);
    if (rule) {
      const Ptr r_at = at / "rule";
      object(*rule, r_at, {"height", "height_fade", "slope_deg", "slope_fade_deg", "noise"});
      w.kind = WeightDesc::Kind::Rule;
      if (const json* f = field(*rule, "height"))
        std::tie(w.height_lo, w.height_hi) = window(*f, r_at / "height", closed(0, 1));
      if (const json* f = field(*rule, "height_fade")) w.height_fade = real(*f, r_at / "height_fade", at_least(0, 1e6));
      if (const json* f = field(*rule, "slope_deg"))
        std::tie(w.slope_lo_deg, w.slope_hi_deg) = window(*f, r_at / "slope_deg", closed(0, 90));
      if (const json* f = field(*rule, "slope_fade_deg"))
        w.slope_fade_deg = real(*f, r_at / "slope_fade_deg", at_least(0, 1e6));
      if (const json* noise = field(*rule, "noise")) {
        const Ptr n_at = r_at / "noise";
        object(*noise, n_at, {"amplitude", "frequency"});
        if (const json* f = field(*noise, "amplitude")) w.noise_amplitude = real(*f, n_at / "amplitude", closed(0, 4));
        if (const json* f = field(*noise, "frequency")) w.noise_frequency = real(*f, n_at / "frequency", above(0, 1e6));
      }
      return w;
    }
    const Ptr s_at = at / "splat";
    object(*splat, s_at, {"image", "channel"});
    w.kind = WeightDesc::Kind::Splat;
    w.splat_path = file(require(*splat, s_at, "image"), s_at / "image");
    if (const json* f = field(*splat, "channel")) {
      const std::string c = f->is_string() ? f->get<std::string>() : std::string();
      bool found = false;
      for (size_t i = 0; i < k_channels.size(); ++i) {
        if (c.size() == 1 && c[0] == k_channels[i]) {
          w.splat_channel = uint32_t(i);
          found = true;
        }
      }
      if (!found) fail(s_at / "channel", "must be one of r, g, b, a", *f);
    }
    return w;
  }

  FbpbDesc fbpb(const json& v, const Ptr& at) const {
    object(v, at, {"cm", "cf", "cn", "variation_threshold", "colour_coeff", "fade_lod", "meta", "mask"});
    FbpbDesc b;
    if (const json* f = field(v, "cm")) b.cm = real(*f, at / "cm", at_least(0, 1e6));
    if (const json* f = field(v, "cf")) b.cf = real(*f, at / "cf", at_least(0, 1e6));
    if (const json* f = field(v, "cn")) b.cn = real(*f, at / "cn", at_least(0, 1e6));
    if (const json* f = field(v, "variation_threshold"))
      b.variation_threshold = real(*f, at / "variation_threshold", closed(0, 1));
    if (const json* f = field(v, "colour_coeff")) b.colour_coeff = real(*f, at / "colour_coeff", closed(0, 1));
    if (const json* f = field(v, "fade_lod"))
      std::tie(b.fade_lod_lo, b.fade_lod_hi) = window(*f, at / "fade_lod", any_finite());
    const json* meta = field(v, "meta");
    const json* mask = field(v, "mask");
    if (meta && mask) fail(at / "mask", "\"meta\" and \"mask\" are mutually exclusive", *mask);
    if (meta) b.meta_path = file(*meta, at / "meta");
    if (mask) b.mask_path = file(*mask, at / "mask");
    return b;
  }

  DptDesc dpt(const json& v, const Ptr& at) const {
    object(v, at, {"layers", "fade_texels"});
    DptDesc d;
    if (const json* layers = field(v, "layers")) {
      const Ptr l_at = at / "layers";
      if (!layers->is_array() || layers->size() > k_max_dpt_layers)
        fail(l_at, "must be an array of 0 to 4 layers", *layers);
      for (size_t k = 0; k < layers->size(); ++k) {
        const json& layer = (*layers)[k];
        const Ptr k_at = l_at / k;
        object(layer, k_at, {"patch_texels", "p", "r", "w", "h"});
        DptLayerDesc L;
        if (const json* f = field(layer, "patch_texels"))
          L.patch_texels = real(*f, k_at / "patch_texels", above(0, 0x1p31));
        if (const json* f = field(layer, "p")) L.p = real(*f, k_at / "p", above(0, 1e6));
        if (const json* f = field(layer, "r")) L.r = real(*f, k_at / "r", above(0, 1e6));
        if (const json* f = field(layer, "w")) L.w = real(*f, k_at / "w", above(0, 1e6));
        if (const json* f = field(layer, "h")) L.h = real(*f, k_at / "h", at_least(0, 1e6));
        d.layers.push_back(L);
      }
    }
    if (const json* f = field(v, "fade_texels"))
      std::tie(d.fade_lo_texels, d.fade_hi_texels) = window(*f, at / "fade_texels", at_least(0, 0x1p30));
    return d;
  }

  // "hex": true | false | {"edge": L, "sharpness": gamma, "preserve": 0 ... 1}
  HexDesc hex(const json& v, const Ptr& at) const {
    HexDesc h;
    if (v.is_boolean()) {
      h.enabled = v.get<bool>();
      return h;
    }
    if (!v.is_object()) fail(at, "must be true, false or an object with edge, sharpness, preserve", v);
    object(v, at, {"edge", "sharpness", "preserve"});
    h.enabled = true;
    if (const json* f = field(v, "edge")) h.edge = real(*f, at / "edge", closed(2, 65536));
    if (const json* f = field(v, "sharpness")) h.sharpness = real(*f, at / "sharpness", closed(1, 64));
    if (const json* f = field(v, "preserve")) h.preserve = real(*f, at / "preserve", closed(0, 1));
    return h;
  }

  MaterialDesc material(const json& v, const Ptr& at, size_t index) const {
    object(v, at, {"name", "albedo", "normal", "period_texels", "mode", "blend_sharpness", "weight", "fbpb", "dpt", "hex"});
    MaterialDesc m;
    m.name = text(require(v, at, "name"), at / "name");
    m.albedo = texture(require(v, at, "albedo"), at / "albedo");
    if (const json* f = field(v, "normal")) m.normal_path = file(*f, at / "normal");
    if (const json* f = field(v, "period_texels"))
      m.period_texels = real(*f, at / "period_texels", at_least(1, 0x1p30));
    if (const json* f = field(v, "mode")) {
      const auto mode = f->is_string() ? mode_from_string(f->get<std::string>()) : std::nullopt;
      if (!mode) fail(at / "mode", "must be one of linear, blendmap, fbpb, dpt, fbpb+dpt", *f);
      m.mode = *mode;
    }
    if (const json* f = field(v, "blend_sharpness"))
      m.blend_sharpness = real(*f, at / "blend_sharpness", open_closed(0, 0.5));
    if (const json* f = field(v, "weight")) {
      m.weight = weight(*f, at / "weight");
      if (index != 0 && m.weight.kind == WeightDesc::Kind::Remainder)
        fail(at / "weight", "only the first material (/materials/0) may be \"remainder\"", *f);
    } else if (index != 0) {
      throw Failure{source_ + ": " + show_pointer(at / "weight") +
                    ": required field is missing (only the first material defaults to \"remainder\")"};
    }
    if (const json* f = field(v, "fbpb")) {
      m.fbpb = fbpb(*f, at / "fbpb");
      m.has_fbpb = true;
    }
    if (m.mode == Mode::Fbpb || m.mode == Mode::FbpbDpt) m.has_fbpb = true;
    const json* dpt_block = field(v, "dpt");
    if (dpt_block) m.dpt = dpt(*dpt_block, at / "dpt");
    if (const json* f = field(v, "hex")) m.hex = hex(*f, at / "hex");
    if ((m.mode == Mode::Dpt || m.mode == Mode::FbpbDpt) && m.dpt.layers.empty()) {
      const json* layers = dpt_block ? field(*dpt_block, "layers") : nullptr;
      fail(at / "dpt" / "layers", "mode \"" + std::string(to_string(m.mode)) + "\" needs at least one DPT layer",
           layers ? show_value(*layers) : std::string("nothing"));
    }
    return m;
  }
};

// Writes `path` relative to the scene's base_dir where that re-resolves to the same path,
// so a serialised scene stays portable together with its assets.
std::string portable_path(const std::string& path, const std::string& base_dir) {
  if (base_dir.empty()) return path;
  const fs::path p(path), base(base_dir);
  if (p.is_absolute() != base.is_absolute()) return path;
  const fs::path rel = p.lexically_relative(base);
  if (rel.empty()) return path;
  if (p.is_absolute() && *rel.begin() == "..") return path;  // outside: keep absolute
  return rel.generic_string();
}

ojson pair(double lo, double hi) { return ojson::array({lo, hi}); }

}  // namespace

Result<SceneDesc> parse_scene(std::string_view json_text, const std::string& source_path, const std::string& base_dir) {
  auto root = json_check::parse(json_text, source_path);
  if (!root) return root.error();
  return json_check::run<SceneDesc>([&] { return Parser(source_path, base_dir).scene(root.value()); });
}

Result<SceneDesc> load_scene_file(const std::string& path) {
  auto text = json_check::read_text_file(path, "scene");
  if (!text) return text.error();
  std::string base = fs::path(path).parent_path().string();
  if (base.empty()) base = ".";
  return parse_scene(text.value(), path, base);
}

std::vector<std::pair<std::string, std::string>> scene_files(const SceneDesc& s) {
  std::vector<std::pair<std::string, std::string>> files;
  auto add = [&files](std::string field, const std::string& path) {
    if (!path.empty()) files.emplace_back(std::move(field), path);
  };
  add("/terrain/heightmap/image", s.terrain.heightmap.image_path);
  for (size_t i = 0; i < s.materials.size(); ++i) {
    const MaterialDesc& m = s.materials[i];
    const std::string at = "/materials/" + std::to_string(i) + "/";
    add(at + "albedo/image", m.albedo.image_path);
    add(at + "albedo/height", m.albedo.height_path);
    add(at + "normal", m.normal_path);
    add(at + "weight/splat/image", m.weight.splat_path);
    add(at + "fbpb/meta", m.fbpb.meta_path);
    add(at + "fbpb/mask", m.fbpb.mask_path);
  }
  return files;
}

std::string scene_to_json(const SceneDesc& s) {
  const auto path = [&](const std::string& p) { return portable_path(p, s.base_dir); };
  ojson root;
  root["seed"] = s.seed;

  ojson terrain;
  terrain["extent_m"] = s.terrain.extent_m;
  terrain["height_m"] = s.terrain.height_m;
  const HeightmapDesc& h = s.terrain.heightmap;
  if (!h.image_path.empty()) {
    terrain["heightmap"] = {{"image", path(h.image_path)}};
  } else {
    ojson fbm;
    fbm["size"] = h.size;
    fbm["seed"] = h.seed;
    fbm["octaves"] = h.octaves;
    fbm["frequency"] = h.frequency;
    fbm["gain"] = h.gain;
    fbm["lacunarity"] = h.lacunarity;
    terrain["heightmap"]["fbm"] = fbm;
  }
  root["terrain"] = terrain;

  ojson vt;
  vt["log2_size"] = s.vt.log2_size;
  vt["page_texels"] = s.vt.page_texels;
  vt["border_texels"] = s.vt.border_texels;
  root["vt"] = vt;
  root["linear_boost"] = s.linear_boost;

  ojson materials = ojson::array();
  for (const MaterialDesc& m : s.materials) {
    ojson j;
    j["name"] = m.name;
    ojson albedo;
    if (!m.albedo.image_path.empty()) {
      albedo["image"] = path(m.albedo.image_path);
      if (!m.albedo.height_path.empty()) albedo["height"] = path(m.albedo.height_path);
      albedo["height_source"] = std::string(to_string(m.albedo.height_source));
      if (m.albedo.height_invert) albedo["height_invert"] = true;
      if (m.albedo.image_resolution) albedo["resolution"] = m.albedo.image_resolution;
    } else {
      albedo["generator"] = m.albedo.generator;
      albedo["resolution"] = m.albedo.resolution;
      albedo["seed"] = m.albedo.seed;
    }
    j["albedo"] = albedo;
    if (!m.normal_path.empty()) j["normal"] = path(m.normal_path);
    j["period_texels"] = m.period_texels;
    j["mode"] = std::string(to_string(m.mode));
    j["blend_sharpness"] = m.blend_sharpness;

    const WeightDesc& w = m.weight;
    if (w.kind == WeightDesc::Kind::Remainder) {
      j["weight"] = "remainder";
    } else if (w.kind == WeightDesc::Kind::Rule) {
      ojson rule;
      rule["height"] = pair(w.height_lo, w.height_hi);
      rule["height_fade"] = w.height_fade;
      rule["slope_deg"] = pair(w.slope_lo_deg, w.slope_hi_deg);
      rule["slope_fade_deg"] = w.slope_fade_deg;
      ojson noise;
      noise["amplitude"] = w.noise_amplitude;
      noise["frequency"] = w.noise_frequency;
      rule["noise"] = noise;
      j["weight"]["rule"] = rule;
    } else {
      ojson splat;
      splat["image"] = path(w.splat_path);
      splat["channel"] = std::string(1, k_channels[w.splat_channel & 3u]);
      j["weight"]["splat"] = splat;
    }

    if (m.has_fbpb) {
      const FbpbDesc& b = m.fbpb;
      ojson fb;
      fb["cm"] = b.cm;
      fb["cf"] = b.cf;
      fb["cn"] = b.cn;
      fb["variation_threshold"] = b.variation_threshold;
      fb["colour_coeff"] = b.colour_coeff;
      fb["fade_lod"] = pair(b.fade_lod_lo, b.fade_lod_hi);
      if (!b.meta_path.empty()) fb["meta"] = path(b.meta_path);
      if (!b.mask_path.empty()) fb["mask"] = path(b.mask_path);
      j["fbpb"] = fb;
    }

    const DptDesc defaults;
    if (!m.dpt.layers.empty() || m.dpt.fade_lo_texels != defaults.fade_lo_texels ||
        m.dpt.fade_hi_texels != defaults.fade_hi_texels) {
      ojson layers = ojson::array();
      for (const DptLayerDesc& L : m.dpt.layers) {
        ojson l;
        l["patch_texels"] = L.patch_texels;
        l["p"] = L.p;
        l["r"] = L.r;
        l["w"] = L.w;
        l["h"] = L.h;
        layers.push_back(l);
      }
      j["dpt"]["layers"] = layers;
      j["dpt"]["fade_texels"] = pair(m.dpt.fade_lo_texels, m.dpt.fade_hi_texels);
    }
    if (m.hex.enabled) {  // written only when on: scenes without it keep their identity
      ojson hex;
      if (m.hex.edge > 0) hex["edge"] = m.hex.edge;
      hex["sharpness"] = m.hex.sharpness;
      hex["preserve"] = m.hex.preserve;
      j["hex"] = hex;
    }
    materials.push_back(j);
  }
  root["materials"] = materials;
  // Paths keep their bytes; one that is not UTF-8 (a Latin-1 folder name) is written with
  // U+FFFD in place of the bad bytes rather than thrown over.
  return root.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

}  // namespace tvt
