#version 460
// Terrain colour pass (body in terrain_fragment.glsl).
#extension GL_GOOGLE_include_directive : require
#include "terrain_fragment.glsl"
