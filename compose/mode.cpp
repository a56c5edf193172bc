#include <array>

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

}  // namespace tvt
