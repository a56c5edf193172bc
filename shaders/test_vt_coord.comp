#version 460
// Samples the VT cache through vt_sample.glsl at a list of positions and also returns the exact
// texels the bilinear filter reads (tests/gpu_coord_vt.cpp decodes coordinate-pattern pages).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "shared/vt_types.h"
#include "shared/vt_test_types.h"
#include "shared/vt_coord_test_types.h"

layout(local_size_x = 64) in;
layout(std430, set = 0, binding = TVT_BIND_TEST_COORD_INFO) readonly buffer InfoBuf { TvtVtInfo tvt_vt; };
layout(std430, set = 0, binding = TVT_BIND_TEST_COORD_ENTRIES) readonly buffer EntryBuf { uint tvt_vt_entries[]; };
layout(set = 0, binding = TVT_BIND_TEST_COORD_CACHE) uniform sampler2DArray tvt_vt_cache;
layout(std430, set = 0, binding = TVT_BIND_TEST_COORD_QUERIES) readonly buffer QueryBuf { TvtVtQuery queries[]; };
layout(std430, set = 0, binding = TVT_BIND_TEST_COORD_ANSWERS) writeonly buffer AnswerBuf { TvtVtCoordAnswer answers[]; };
layout(push_constant) uniform Push { uint count; };

#include "vt_sample.glsl"

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= count) return;
  const TvtVtQuery q = queries[i];
  const i64vec2 ti = i64vec2(q.x, q.y);
  const TvtVtLookup l = tvt_vt_lookup(ti, q.frac, q.mip);
  TvtVtCoordAnswer a;
  a.valid = l.valid ? 1u : 0u;
  a.slot = l.slot;
  a.data_mip = l.data_mip;
  a.pad = 0;
  a.local = l.local;
  a.corner = ivec2(floor(l.local - 0.5));
  a.filtered = tvt_vt_sample_mip(ti, q.frac, q.mip);
  const int last = tvt_vt.slot_texels - 1;
  for (int k = 0; k < 4; ++k) {
    const ivec2 t = clamp(a.corner + ivec2(k & 1, k >> 1), ivec2(0), ivec2(last));
    a.quad[k] = packUnorm4x8(texelFetch(tvt_vt_cache, ivec3(t, int(l.slot)), 0));
  }
  answers[i] = a;
}
