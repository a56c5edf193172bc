#version 460
// Separate feedback pass (terrain_renderer.h, FeedbackMode::SeparatePass): the terrain drawn at
// 1/N of the view resolution with its own depth; every texel writes the page its LOD wants
// (the same LOD as the colour pass: derivatives are rescaled to full-resolution pixels).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "shared/terrain_types.h"
#include "shared/vt_types.h"
#include "vt_lod.glsl"

layout(std140, set = 0, binding = TVT_BIND_TERRAIN_FRAME) uniform FrameBuf { TvtTerrainFrame F; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_VT_INFO) readonly buffer VtInfoBuf { TvtVtInfo tvt_vt; };
layout(std140, set = 0, binding = TVT_BIND_TERRAIN_FEEDBACK_PARAMS) uniform FeedbackParams { TvtFeedbackWrite FB; };

layout(constant_id = TVT_TERRAIN_SPEC_MAX_ANISOTROPY) const int k_max_anisotropy = 1;
layout(constant_id = TVT_TERRAIN_SPEC_MIP_BAND) const float k_mip_band = 1.0;

layout(location = 0) in vec2 v_local_texel;
layout(location = 0) out uvec2 out_page;  // feedback texel (feedback_types.h), R32G32_UINT

void main() {
  // One texel here spans N full-resolution pixels (the viewport is scaled by exactly 1/N).
  const float to_full = 1.0 / float(FB.divisor);
  const TvtVtFootprint fp = tvt_vt_footprint(dFdx(v_local_texel) * to_full, dFdy(v_local_texel) * to_full, tvt_vt.mip_bias,
                                      k_max_anisotropy);
  const vec2 whole = floor(v_local_texel);
  const ivec2 ti = ivec2(int(F.anchor_x), int(F.anchor_y)) + ivec2(whole);  // fits: see terrain_fragment.glsl
  out_page = tvt_feedback_page(ti, tvt_filtered_lod(fp.lod, k_mip_band), tvt_vt.mip_count, tvt_vt.log2_vt, tvt_vt.log2_page);
}
