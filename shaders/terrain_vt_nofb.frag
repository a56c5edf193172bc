#version 460
// Terrain colour pass sampling the virtual texture without writing feedback (the separate
// feedback pass writes it, or nothing does) (terrain_fragment.glsl).
#extension GL_GOOGLE_include_directive : require
#define TVT_TERRAIN_VT
#include "terrain_fragment.glsl"
