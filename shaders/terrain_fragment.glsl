// Terrain fragment stage, included by one small .frag per variant that defines what the albedo
// comes from:
//   (nothing)                  height/slope colour ramp (terrain.frag); with
//                              TVT_TERRAIN_TEXEL_OUTPUT also the VT texel coordinate on a
//                              second attachment (terrain_texel.frag)
//   TVT_TERRAIN_VT             the virtual texture (terrain_vt_nofb.frag); plus
//                              TVT_TERRAIN_VT_FEEDBACK: main-pass feedback stores (terrain_vt.frag),
//                              TVT_TERRAIN_VT_FEEDBACK_ATTACHMENT: every pixel's page on
//                              attachment 1 (terrain_vt_attach.frag),
//                              TVT_TERRAIN_VT_PROBE: a probe attachment (terrain_vt_probe.frag)
//   TVT_TERRAIN_DIRECT         the composition per pixel (terrain_direct.frag); plus
//                              TVT_TERRAIN_DIRECT_MATCHED: at the VT's texel centres and mips
//                              (terrain_direct_matched.frag)
//   TVT_TERRAIN_PLAIN          one mip-mapped texture (terrain_plain.frag)
//
// Albedo comes from terrain_albedo(TerrainFragment): the single place where virtual-texture
// sampling plugs in. Everything it may need is in TerrainFragment; the level-0 VT texel
// coordinate is anchor_texel + local_texel with anchor_texel an exact int64 pair and
// local_texel a small float (camera-relative), never a whole-terrain float UV (docs/composition.md).
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
#ifdef TVT_TERRAIN_VT_PROBE
layout(location = 1) out vec4 out_probe;   // vt_probe(); -1 everywhere when the albedo is overridden
vec4 g_probe = vec4(-1.0);
#endif
// Set by terrain_albedo(): gradient of the albedo's alpha (the material height, 0 ... 1) per
// level-0 texel, for the detail normal. Zero: flat.
vec2 g_height_gradient = vec2(0.0);

// Height gradient per level-0 texel from screen derivatives of `h` (for albedo sources without
// a per-lane form): solves g . dtexel_dx = dFdx(h), g . dtexel_dy = dFdy(h). Call in uniform
// control flow. Degenerate (edge-on) footprints give 0.
vec2 screen_height_gradient(float h, vec2 dtx, vec2 dty) {
  const float hx = dFdx(h), hy = dFdy(h);
  const float det = dtx.x * dty.y - dtx.y * dty.x;
  if (!(abs(det) > 1e-20)) return vec2(0.0);
  return vec2(dty.y * hx - dtx.y * hy, dtx.x * hy - dty.x * hx) / det;
}

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
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_VT_INFO) readonly buffer VtInfoBuf { TvtVtInfo tvt_vt; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_VT_INFO) readonly buffer VtInfoWords { ivec4 tvt_vt_info_words[]; };
#define TVT_VT_INFO_WORDS
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_VT_ENTRIES) readonly buffer VtEntryBuf { uint tvt_vt_entries[]; };
layout(set = 0, binding = TVT_BIND_TERRAIN_VT_CACHE) uniform sampler2DArray tvt_vt_cache;
#ifdef TVT_TERRAIN_VT_FEEDBACK
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_FEEDBACK) writeonly buffer FeedbackBuf { uvec2 feedback[]; };
layout(std140, set = 0, binding = TVT_BIND_TERRAIN_FEEDBACK_PARAMS) uniform FeedbackParams { TvtFeedbackWrite FB; };
#endif
#include "vt_sample.glsl"
#ifdef TVT_TERRAIN_VT_FEEDBACK_ATTACHMENT
// R32G32_UINT, cleared to TVT_FEEDBACK_EMPTY_WORD: the page this pixel's LOD wants. A colour
// output is not a storage write: on lavapipe a pipeline writing a storage buffer makes the
// driver flush its scene on every draw, which about doubled the cost of the whole pass.
layout(location = 1) out uvec2 out_feedback;
uvec2 g_feedback = uvec2(TVT_FEEDBACK_EMPTY_WORD);  // stays empty under an albedo override
#endif
layout(constant_id = TVT_TERRAIN_SPEC_MAX_ANISOTROPY) const int k_max_anisotropy = 1;
layout(constant_id = TVT_TERRAIN_SPEC_FEEDBACK_DIVISOR) const uint k_feedback_divisor = 8u;  // = FB.divisor
layout(constant_id = TVT_TERRAIN_SPEC_DETAIL_NORMAL) const bool k_detail_normal = true;
layout(constant_id = TVT_TERRAIN_SPEC_MIP_BAND) const float k_mip_band = 1.0;

#ifdef TVT_TERRAIN_VT_PROBE
// Distance in data-mip texels from the lookup's sample point to the nearest edge of the page
// payload: below 1/2 the bilinear taps read border texels. -1 without data.
float vt_edge_distance(TvtVtLookup l) {
  if (!l.valid) return -1.0;
  const float b = float(tvt_vt.border_texels), e = float(tvt_vt.slot_texels - tvt_vt.border_texels);
  return min(min(l.local.x - b, l.local.y - b), min(e - l.local.x, e - l.local.y));
}

// Test probe (attachment 1): LOD, the data mips of the (one or two) lookups, and how close
// their sample points come to a payload edge.
vec4 vt_probe(ivec2 ti, vec2 tf, float lod) {
  int m0;
  float t;
  tvt_vt_mip_pair(lod, m0, t);
  const TvtVtLookup a = tvt_vt_lookup32(ti, tf, m0);
  float edge = vt_edge_distance(a), coarse_mip = -1.0;
  if (t > 0.0) {
    const TvtVtLookup b = tvt_vt_lookup32(ti, tf, m0 + 1);
    edge = min(edge, vt_edge_distance(b));
    coarse_mip = b.valid ? float(b.data_mip) : -2.0;
  }
  return vec4(lod, a.valid ? float(a.data_mip) : -2.0, coarse_mip, edge);
}
#endif

// Albedo through the virtual texture. With main-pass feedback, one rotating pixel per N x N
// block also reports the page its LOD wants (before any fallback to a resident ancestor).
vec4 terrain_albedo(TerrainFragment f) {
  // 32-bit texel: the anchor is clamped to [-V/2, 3V/2] and fragments lie on the terrain, so
  // for V <= 2^30 both fit int32 (64-bit integer work is emulated on some devices).
  const vec2 whole = floor(f.local_texel);
  const ivec2 ti = ivec2(f.anchor_texel) + ivec2(whole);
  const vec2 tf = f.local_texel - whole;
  TvtVtFootprint fp = tvt_vt_footprint(f.dtexel_dx, f.dtexel_dy, tvt_vt.mip_bias, k_max_anisotropy);
  fp.lod = tvt_filtered_lod(fp.lod, k_mip_band);  // outside the band: one mip, which feedback then asks for
#ifdef TVT_TERRAIN_VT_FEEDBACK
  const uvec2 px = uvec2(gl_FragCoord.xy);
  if (px.x % k_feedback_divisor == FB.offset_x && px.y % k_feedback_divisor == FB.offset_y) {
    const uvec2 fb = px / k_feedback_divisor;
    if (fb.x < FB.width && fb.y < FB.height) feedback[fb.y * FB.width + fb.x] = tvt_vt_feedback_texel(ti, fp.lod);
  }
#endif
#ifdef TVT_TERRAIN_VT_FEEDBACK_ATTACHMENT
  g_feedback = tvt_vt_feedback_texel(ti, fp.lod);
#endif
#ifdef TVT_TERRAIN_VT_PROBE
  g_probe = vt_probe(ti, tf, fp.lod);
#endif
  return k_max_anisotropy > 1 ? tvt_vt_sample_aniso(ti, tf, fp, g_height_gradient) : tvt_vt_sample_dh(ti, tf, fp.lod, g_height_gradient);
}
#elif defined(TVT_TERRAIN_DIRECT)
#include "shared/compose_types.h"
#include "shared/hash.h"
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_COMPOSE_PARAMS) readonly buffer ParamsBuf { TvtComposeParams P; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_MATERIAL_TEXELS) readonly buffer MaterialBuf { uint material_texels[]; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_META_TEXELS) readonly buffer MetaBuf { uint meta_texels[]; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_WEIGHTS) readonly buffer WeightBuf { float weights[]; };
#include "compose_sample.glsl"

#ifdef TVT_TERRAIN_DIRECT_MATCHED
#include "vt_lod.glsl"
layout(constant_id = TVT_TERRAIN_SPEC_MIP_BAND) const float k_mip_band = 1.0;
// Texel i of VT mip `mip` exactly as compose.comp writes it into a page: the composition at
// the texel's centre with a footprint of 2^mip level-0 texels, edge texels repeated beyond
// the terrain.
vec4 direct_texel(i64vec2 i, int mip) {
  const int64_t last = (int64_t(1) << int64_t(P.log2_vt - mip)) - int64_t(1);
  const i64vec2 c = clamp(i, i64vec2(0), i64vec2(last));
  const int64_t sub = int64_t(mip + TVT_FIXED_BITS);
  const i64vec2 pos = (c << sub) + (int64_t(1) << (sub - int64_t(1)));
  return compose_sample(pos.x, pos.y, exp2(float(mip)), 0xffffffffu, false);
}

// Bilinear between the four texel centres around the position, weighted as the VT's
// hardware bilinear fetch weights them (tvt_vt_lookup's in-page coordinate minus 1/2).
// dh: the gradient of the filtered alpha per level-0 texel, as tvt_vt_height_gradient() gives it.
vec4 direct_bilinear(i64vec2 ti, vec2 tf, int mip, out vec2 dh) {
  const int64_t m = int64_t(mip);
  const i64vec2 xi = ti >> m;
  const vec2 u = (vec2(ti - (xi << m)) + tf) * exp2(-float(mip)) - 0.5;
  const vec2 fu = floor(u);
  const vec2 w = u - fu;
  const i64vec2 i0 = xi + i64vec2(fu);
  const vec4 c00 = direct_texel(i0, mip), c10 = direct_texel(i0 + i64vec2(1, 0), mip);
  const vec4 c01 = direct_texel(i0 + i64vec2(0, 1), mip), c11 = direct_texel(i0 + i64vec2(1, 1), mip);
  dh = vec2(mix(c10.a - c00.a, c11.a - c01.a, w.y), mix(c01.a - c00.a, c11.a - c10.a, w.x)) * exp2(-float(mip));
  return mix(mix(c00, c10, w.x), mix(c01, c11, w.x), w.y);
}

// Direct splatting at matched LOD: the composition evaluated at the texel centres of the
// mip(s) the VT's LOD selects (tvt_vt_lod_iso, no bias, the same mip filter) and filtered as
// tvt_vt_sample_dh() filters the cache: bilinear within a mip, linear across two (trilinear). The
// VT image without the cache.
vec4 terrain_albedo(TerrainFragment f) {
  const vec2 whole = floor(f.local_texel);
  const i64vec2 ti = f.anchor_texel + i64vec2(whole);
  const vec2 tf = f.local_texel - whole;
  const int mip_count = P.log2_vt - findMSB(uint(P.page_texels)) + 1;
  const float lod = tvt_filtered_lod(tvt_vt_lod_iso(f.dtexel_dx, f.dtexel_dy, 0.0), k_mip_band);
  const float l = clamp(lod, 0.0, float(mip_count - 1));
  const int m0 = int(floor(l));
  const float t = m0 + 1 >= mip_count ? 0.0 : l - float(m0);
  const vec4 a = direct_bilinear(ti, tf, m0, g_height_gradient);
  if (t <= 0.0) return a;
  vec2 dh1;
  const vec4 b = direct_bilinear(ti, tf, m0 + 1, dh1);
  g_height_gradient = mix(g_height_gradient, dh1, t);
  return mix(a, b, t);
}
#else
// Direct splatting: the whole composition evaluated per pixel at the pixel's footprint (the
// papers' fragment-shader form) — the baseline the VT path is measured against.
vec4 terrain_albedo(TerrainFragment f) {
  const vec2 whole = floor(f.local_texel);
  const i64vec2 ti = f.anchor_texel + i64vec2(whole);
  const i64vec2 sub = i64vec2(floor((f.local_texel - whole) * float(1 << TVT_FIXED_BITS)));
  const i64vec2 pos = (ti << int64_t(TVT_FIXED_BITS)) + sub;
  const float footprint = max(length(f.dtexel_dx), length(f.dtexel_dy));
  const vec4 c = compose_sample(pos.x, pos.y, max(footprint, 1.0), 0xffffffffu, false);
  g_height_gradient = screen_height_gradient(c.a, f.dtexel_dx, f.dtexel_dy);
  return c;
}
#endif
#elif defined(TVT_TERRAIN_PLAIN)
layout(set = 0, binding = TVT_BIND_TERRAIN_PLAIN) uniform sampler2DArray plain_texture;

// One ordinary mip-mapped texture over the whole terrain, hardware trilinear (the baseline a
// VT is measured against). Its texel coordinate is built like the VT's: the anchor's integer
// plain texel plus a small float, so only the final [0,1] UV is a whole-terrain float; at
// 2^12 plain texels its rounding is 2^-12 texel.
vec4 terrain_albedo(TerrainFragment f) {
  const int64_t s = int64_t(F.sampling.x);
  const i64vec2 hi = f.anchor_texel >> s;
  const vec2 lo = vec2(f.anchor_texel - (hi << s));
  const float to_plain = exp2(-float(F.sampling.x)), to_uv = exp2(-float(F.sampling.z));
  const vec2 uv = (vec2(hi) + (lo + f.local_texel) * to_plain) * to_uv;
  const float d = to_plain * to_uv;
  const vec4 c = textureGrad(plain_texture, vec3(uv, 0.0), f.dtexel_dx * d, f.dtexel_dy * d);
  g_height_gradient = screen_height_gradient(c.a, f.dtexel_dx, f.dtexel_dy);
  return c;
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
  return vec4(c, 1.0);  // no detail height: flat
}
#endif

// Detail normal from the material height the albedo carries in alpha (docs/architecture.md), relief
// F.terrain.w metres from 0 to 1: g_height_gradient (per level-0 texel) over metres per texel
// is the slope added to the heightfield's, n ~ (-Hx - hx, -Hy - hy, 1) = n / n.z - (hx, hy, 0).
// The gradient is that of the filtered (mip-mapped) height, so detail fades with distance as
// the mips average it out. Slopes are clamped to 4 (76 degrees); non-finite ones keep `n`.
vec3 detail_normal(vec3 n, vec2 g) {
  const float relief = F.terrain.w;
  if (!(relief > 0.0)) return n;
  vec2 slope = g * (relief / F.camera.w);  // metres per metre
  const float len = length(slope);
  if (!(len < 1e30)) return n;
  if (len > 4.0) slope *= 4.0 / len;
  return normalize(n - n.z * vec3(slope, 0.0));
}

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
#ifdef TVT_TERRAIN_VT
  // Off (a specialization constant), g_height_gradient is dead and the gathers go with it.
  const bool detail = k_detail_normal && !(F.albedo_override.a > 0.0);
#else
  const bool detail = !(F.albedo_override.a > 0.0);
#endif
  const vec3 n = detail ? detail_normal(f.normal, g_height_gradient) : f.normal;
  const float lambert = max(dot(n, F.sun.xyz), 0.0);
  const vec3 lit = albedo.rgb * (F.sun_color.rgb * (F.sun.w * lambert) + vec3(F.sun_color.a));
  const float fog = 1.0 - exp(-F.sky.a * f.distance_m);
  vec3 c = mix(lit, F.sky.rgb, fog);
  // A non-finite colour must never pass silently: paint it magenta (tests look for it).
  if (any(isnan(c)) || any(isinf(c))) c = vec3(1.0, 0.0, 1.0);
  out_color = vec4(c, 1.0);
#ifdef TVT_TERRAIN_VT_PROBE
  out_probe = g_probe;
#endif
#ifdef TVT_TERRAIN_VT_FEEDBACK_ATTACHMENT
  out_feedback = g_feedback;
#endif
#ifdef TVT_TERRAIN_TEXEL_OUTPUT
  const vec2 whole = floor(v_local_texel);
  const i64vec2 t = f.anchor_texel + i64vec2(whole);
  out_texel = uvec4(uint(t.x), uint(t.y), floatBitsToUint(v_local_texel - whole));
#endif
}
