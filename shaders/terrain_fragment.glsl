// Terrain fragment stage, included by terrain.frag and terrain_texel.frag (the latter defines
// TVT_TERRAIN_TEXEL_OUTPUT and writes the VT texel coordinate to a second attachment).
//
// Albedo comes from terrain_albedo(TerrainFragment): the single place where virtual-texture
// sampling plugs in. Everything it may need is in TerrainFragment; the level-0 VT texel
// coordinate is anchor_texel + local_texel with anchor_texel an exact int64 pair and
// local_texel a small float (camera-relative), never a whole-terrain float UV (DESIGN §3).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "shared/terrain_types.h"

layout(std140, set = 0, binding = TVT_BIND_TERRAIN_FRAME) uniform FrameBuf { TvtTerrainFrame F; };

layout(location = 0) in vec2 v_local_texel;
layout(location = 1) in vec3 v_normal;
layout(location = 2) in vec3 v_rel_m;
layout(location = 3) in float v_height01;

layout(location = 0) out vec4 out_color;
#ifdef TVT_TERRAIN_TEXEL_OUTPUT
layout(location = 1) out uvec4 out_texel;  // x, y: floor of the texel coordinate (low 32 bits); z, w: fraction bits
#endif

struct TerrainFragment {
  i64vec2 anchor_texel;  // level-0 VT texel of the camera (exact integers)
  vec2 local_texel;      // level-0 texel coordinate minus anchor_texel (error ~ |local| * 2^-23)
  vec2 dtexel_dx;        // screen-space derivatives of the texel coordinate (level-0 texels per pixel)
  vec2 dtexel_dy;
  vec3 normal;           // world, unit
  float height01;        // heightfield value in [0,1]
  vec3 rel_m;            // position minus camera, metres
  float distance_m;      // length(rel_m)
};

#ifdef TVT_TERRAIN_VT
// The feedback store is a side effect, which would otherwise switch early depth testing off:
// hidden fragments would sample the VT for nothing and report pages nobody sees.
layout(early_fragment_tests) in;
#include "shared/vt_types.h"
#include "shared/feedback_types.h"
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_VT_INFO) readonly buffer VtInfoBuf { TvtVtInfo VT; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_VT_ENTRIES) readonly buffer VtEntryBuf { uint pt_entries[]; };
layout(set = 0, binding = TVT_BIND_TERRAIN_VT_CACHE) uniform sampler2DArray vt_cache;
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_FEEDBACK) writeonly buffer FeedbackBuf { uvec2 feedback[]; };
layout(std140, set = 0, binding = TVT_BIND_TERRAIN_FEEDBACK_PARAMS) uniform FeedbackParams { TvtFeedbackWrite FB; };
#include "vt_sample.glsl"

// Albedo through the virtual texture; one rotating pixel per N x N block also reports the
// page its LOD wants (before any fallback to a resident ancestor).
vec4 terrain_albedo(TerrainFragment f) {
  const vec2 whole = floor(f.local_texel);
  const i64vec2 ti = f.anchor_texel + i64vec2(whole);
  const vec2 tf = f.local_texel - whole;
  const float lod = vt_lod(f.dtexel_dx, f.dtexel_dy);
  const uvec2 px = uvec2(gl_FragCoord.xy);
  if (px.x % FB.divisor == FB.offset_x && px.y % FB.divisor == FB.offset_y) {
    const int m = clamp(int(floor(lod)), 0, VT.mip_count - 1);
    const i64vec2 clamped = clamp(ti, i64vec2(0), i64vec2((int64_t(1) << VT.log2_vt) - 1));
    const uvec2 page = uvec2(clamped >> int64_t(VT.log2_page + m));
    const uvec2 fb = px / FB.divisor;
    if (fb.x < FB.width && fb.y < FB.height)
      feedback[fb.y * FB.width + fb.x] = uvec2(tvt_feedback_word0(uint(m), page.x), tvt_feedback_word1(page.y));
  }
  return vec4(vt_sample(ti, tf, lod).rgb, 1.0);
}
#elif defined(TVT_TERRAIN_DIRECT)
#include "shared/compose_types.h"
#include "shared/hash.h"
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_COMPOSE_PARAMS) readonly buffer ParamsBuf { TvtComposeParams P; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_MATERIAL_TEXELS) readonly buffer MaterialBuf { uint material_texels[]; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_META_TEXELS) readonly buffer MetaBuf { uint meta_texels[]; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_WEIGHTS) readonly buffer WeightBuf { float weights[]; };
#include "compose_sample.glsl"

// Direct splatting: the whole composition evaluated per pixel at the pixel's footprint (the
// papers' fragment-shader form) — the baseline the VT path is measured against.
vec4 terrain_albedo(TerrainFragment f) {
  const vec2 whole = floor(f.local_texel);
  const i64vec2 ti = f.anchor_texel + i64vec2(whole);
  const i64vec2 sub = i64vec2(floor((f.local_texel - whole) * float(1 << TVT_FIXED_BITS)));
  const i64vec2 pos = (ti << int64_t(TVT_FIXED_BITS)) + sub;
  const float footprint = max(length(f.dtexel_dx), length(f.dtexel_dy));
  return vec4(compose_sample(pos.x, pos.y, max(footprint, 1.0), 0xffffffffu).rgb, 1.0);
}
#else
// Without a virtual texture (tests of the raster pass): a height/slope colour ramp (linear RGB).
vec4 terrain_albedo(TerrainFragment f) {
  const vec3 sand = vec3(0.62, 0.55, 0.38), grass = vec3(0.20, 0.36, 0.12);
  const vec3 rock = vec3(0.38, 0.35, 0.33), snow = vec3(0.92, 0.93, 0.95);
  const float slope = 1.0 - f.normal.z;  // 0 flat, 1 vertical
  vec3 c = mix(sand, grass, smoothstep(0.18, 0.28, f.height01));
  c = mix(c, rock, smoothstep(0.55, 0.70, f.height01));
  c = mix(c, rock, smoothstep(0.12, 0.25, slope));
  c = mix(c, snow, smoothstep(0.78, 0.86, f.height01) * (1.0 - smoothstep(0.20, 0.35, slope)));
  return vec4(c, 1.0);
}
#endif

void main() {
  TerrainFragment f;
  f.anchor_texel = i64vec2(F.anchor_x, F.anchor_y);
  f.local_texel = v_local_texel;
  f.dtexel_dx = dFdx(v_local_texel);
  f.dtexel_dy = dFdy(v_local_texel);
  f.normal = normalize(v_normal);
  f.height01 = v_height01;
  f.rel_m = v_rel_m;
  f.distance_m = length(v_rel_m);

  const vec4 albedo = F.albedo_override.a > 0.0 ? F.albedo_override : terrain_albedo(f);
  const float lambert = max(dot(f.normal, F.sun.xyz), 0.0);
  const vec3 lit = albedo.rgb * (F.sun_color.rgb * (F.sun.w * lambert) + vec3(F.sun_color.a));
  const float fog = 1.0 - exp(-F.sky.a * f.distance_m);
  vec3 c = mix(lit, F.sky.rgb, fog);
  // A non-finite colour must never pass silently: paint it magenta (tests look for it).
  if (any(isnan(c)) || any(isinf(c))) c = vec3(1.0, 0.0, 1.0);
  out_color = vec4(c, 1.0);
#ifdef TVT_TERRAIN_TEXEL_OUTPUT
  const vec2 whole = floor(v_local_texel);
  const i64vec2 t = f.anchor_texel + i64vec2(whole);
  out_texel = uvec4(uint(t.x), uint(t.y), floatBitsToUint(v_local_texel - whole));
#endif
}
