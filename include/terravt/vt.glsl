// terravt's GLSL contract: sampling the virtual texture and writing page requests from a
// client's own shader. Include it after choosing where the VT's three descriptors live:
//
//   #extension GL_GOOGLE_include_directive : require
//   #extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
//   #define TERRAVT_VT_SET 1             // descriptor set (default 0)
//   #define TERRAVT_VT_BINDING_INFO 0    // storage buffer: the VT description (TvtVtInfo, readonly)
//   #define TERRAVT_VT_BINDING_TABLE 1   // storage buffer: the page-table entries (uint[], readonly)
//   #define TERRAVT_VT_BINDING_CACHE 2   // combined image sampler: the page cache (sampler2DArray)
//   #include "terravt/vt.glsl"           // compile with -I <prefix>/include
//
// Every name it declares starts with tvt_/Tvt/TVT_ (internal) or terravt_ (the calls below).
// The cache is an RGBA8_UNORM 2D array, one layer per cache slot of (P + 2B)^2 texels: rgb the
// composed albedo, a the material height. Its sampler must be bilinear (min and mag LINEAR),
// CLAMP_TO_EDGE, mipmapMode NEAREST and maxLod 0: mips are separate pages, filtered here.
//
// Positions (precision rule): a level-0 texel `texel` as exact integers plus a small float
// `frac` (|frac| < a few texels), never one float over the whole terrain: fp32 cannot name a
// texel of a 2^24-texel terrain. Derivatives are in level-0 texels per pixel.
#ifndef TERRAVT_VT_GLSL
#define TERRAVT_VT_GLSL

#ifndef TERRAVT_VT_SET
#define TERRAVT_VT_SET 0
#endif
#if !defined(TERRAVT_VT_BINDING_INFO) || !defined(TERRAVT_VT_BINDING_TABLE) || !defined(TERRAVT_VT_BINDING_CACHE)
#error "terravt/vt.glsl: define TERRAVT_VT_BINDING_INFO, TERRAVT_VT_BINDING_TABLE and TERRAVT_VT_BINDING_CACHE first"
#endif

#include "glsl/shared/vt_types.h"

layout(std430, set = TERRAVT_VT_SET, binding = TERRAVT_VT_BINDING_INFO) readonly buffer TvtVtInfoBuf { TvtVtInfo tvt_vt; };
// The same bytes as 16-byte words: a mip's window in one load.
layout(std430, set = TERRAVT_VT_SET, binding = TERRAVT_VT_BINDING_INFO) readonly buffer TvtVtInfoWords { ivec4 tvt_vt_info_words[]; };
#define TVT_VT_INFO_WORDS
layout(std430, set = TERRAVT_VT_SET, binding = TERRAVT_VT_BINDING_TABLE) readonly buffer TvtVtEntryBuf { uint tvt_vt_entries[]; };
layout(set = TERRAVT_VT_SET, binding = TERRAVT_VT_BINDING_CACHE) uniform sampler2DArray tvt_vt_cache;

#include "glsl/vt_sample.glsl"

// The LOD a footprint asks for (mips; the VT's mip bias included).
float terravt_lod(vec2 dx, vec2 dy) { return tvt_vt_lod(dx, dy); }

// Trilinear sample of the VT: rgb albedo, a height. Where no page of any mip is resident the
// result is magenta (1, 0, 1, 1), never NaN (terravt keeps the coarsest mips resident).
vec4 terravt_sample(ivec2 texel, vec2 frac, vec2 dx, vec2 dy) {
  vec2 dh;
  return tvt_vt_sample_dh(texel, frac, terravt_lod(dx, dy), dh);
}

// The page request to write for this pixel: two words (a uvec2 in a storage buffer, or an
// R32G32_UINT attachment texel) naming the page terravt_sample() reads most from. Clear the
// feedback target to uvec2(0xffffffff) (no request) before the pass.
uvec2 terravt_feedback(ivec2 texel, vec2 dx, vec2 dy) { return tvt_vt_feedback_texel(texel, terravt_lod(dx, dy)); }

#endif
