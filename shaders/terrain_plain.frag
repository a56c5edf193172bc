#version 460
// Terrain colour pass sampling one plain mip-mapped texture (the baseline for the VT's
// sampling cost) (terrain_fragment.glsl).
#extension GL_GOOGLE_include_directive : require
#define TVT_TERRAIN_PLAIN
#include "terrain_fragment.glsl"
