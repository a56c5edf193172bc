#version 460
// Terrain colour pass that also writes the VT texel coordinate (attachment 1, R32G32B32A32_UINT):
// for precision tests and debugging. Body in terrain_fragment.glsl.
#extension GL_GOOGLE_include_directive : require
#define TVT_TERRAIN_TEXEL_OUTPUT 1
#include "terrain_fragment.glsl"
