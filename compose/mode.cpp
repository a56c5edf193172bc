#include <array>

#include "compose/material_image.h"
#include "compose/scene.h"

namespace tvt {

namespace {
constexpr std::array<std::pair<Mode, std::string_view>, 5> k_modes{{
    {Mode::Linear, "linear"},
    {Mode::BlendMap, "blendmap"},
    {Mode::Fbpb, "fbpb"},
    {Mode::Dpt, "dpt"},
    {Mode::FbpbDpt, "fbpb+dpt"},
}};
}  // namespace

std::string_view to_string(Mode mode) {
  for (const auto& [m, name] : k_modes)
    if (m == mode) return name;
  return "?";
}

std::optional<Mode> mode_from_string(std::string_view text) {
  for (const auto& [m, name] : k_modes)
    if (name == text) return m;
  return std::nullopt;
}

// Here, not in material_image.cpp, so that the scene parser needs no image library.
std::string_view to_string(HeightSource source) {
  switch (source) {
    case HeightSource::Auto: return "auto";
    case HeightSource::Alpha: return "alpha";
    case HeightSource::Luminance: return "luminance";
    case HeightSource::File: return "file";
    case HeightSource::None: return "none";
  }
  return "?";
}

std::optional<HeightSource> height_source_from_string(std::string_view text) {
  for (HeightSource s : {HeightSource::Auto, HeightSource::Alpha, HeightSource::Luminance, HeightSource::File,
                         HeightSource::None})
    if (text == to_string(s)) return s;
  return std::nullopt;
}

}  // namespace tvt
