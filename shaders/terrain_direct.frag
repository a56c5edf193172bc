#version 460
// Terrain colour pass with the composition evaluated per pixel (direct-splat baseline).
#extension GL_GOOGLE_include_directive : require
#define TVT_TERRAIN_DIRECT
#include "terrain_fragment.glsl"
