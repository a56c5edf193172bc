// The terrain pass's test probe attachment (TerrainRenderer with a probe): per pixel the VT
// LOD, the fine and coarse mips sampled and the distance to the nearest page edge.
#pragma once
#include <cstring>
#include <vector>

#include "app/terrain_renderer.h"

namespace tvt::test {

struct Probe {
  float lod, fine_mip, coarse_mip, edge;
};

inline std::vector<Probe> read_probe(const TerrainRenderer& r) {
  const std::vector<uint8_t> bytes = r.target().read_color(1);
  std::vector<Probe> p(bytes.size() / sizeof(Probe));
  std::memcpy(p.data(), bytes.data(), p.size() * sizeof(Probe));
  return p;
}

}  // namespace tvt::test
