#version 460
// Terrain colour pass with the composition evaluated at the texel centres of the mips the VT
// would sample, filtered like the VT sampler (direct splatting at matched LOD; tests).
#extension GL_GOOGLE_include_directive : require
#define TVT_TERRAIN_DIRECT
#define TVT_TERRAIN_DIRECT_MATCHED
#include "terrain_fragment.glsl"
