#version 460
// Terrain colour pass sampling the virtual texture and writing feedback for one rotating pixel
// per N x N block (terrain_fragment.glsl).
#extension GL_GOOGLE_include_directive : require
#define TVT_TERRAIN_VT
#define TVT_TERRAIN_VT_FEEDBACK
#include "terrain_fragment.glsl"
