#version 460
// Terrain colour pass sampling the virtual texture, plus a probe attachment (LOD, data mips,
// distance to the page payload edge) for tests (terrain_fragment.glsl).
#extension GL_GOOGLE_include_directive : require
#define TVT_TERRAIN_VT
#define TVT_TERRAIN_VT_PROBE
#include "terrain_fragment.glsl"
