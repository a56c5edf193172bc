#version 460
// Terrain colour pass sampling the virtual texture and writing, on colour attachment 1, the
// page every pixel's LOD wants; the renderer copies one rotating pixel per N x N block into the
// feedback buffer (FeedbackMode::Attachment, terrain_fragment.glsl).
#extension GL_GOOGLE_include_directive : require
#define TVT_TERRAIN_VT
#define TVT_TERRAIN_VT_FEEDBACK_ATTACHMENT
#include "terrain_fragment.glsl"
