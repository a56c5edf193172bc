#version 460
// Runs tvt_vt_lookup() on a list of queries (tests/gpu_vt_lookup.cpp compares with the CPU table).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "shared/vt_types.h"
#include "shared/vt_test_types.h"

layout(local_size_x = 64) in;
layout(std430, set = 0, binding = TVT_BIND_TEST_VT_INFO) readonly buffer InfoBuf { TvtVtInfo tvt_vt; };
layout(std430, set = 0, binding = TVT_BIND_TEST_VT_INFO) readonly buffer InfoWords { ivec4 tvt_vt_info_words[]; };
#define TVT_VT_INFO_WORDS
layout(std430, set = 0, binding = TVT_BIND_TEST_VT_ENTRIES) readonly buffer EntryBuf { uint tvt_vt_entries[]; };
layout(std430, set = 0, binding = TVT_BIND_TEST_VT_QUERIES) readonly buffer QueryBuf { TvtVtQuery queries[]; };
layout(std430, set = 0, binding = TVT_BIND_TEST_VT_ANSWERS) writeonly buffer AnswerBuf { TvtVtAnswer answers[]; };
layout(push_constant) uniform Push { uint count; };

#include "vt_lookup.glsl"

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= count) return;
  const TvtVtQuery q = queries[i];
  const TvtVtLookup l = tvt_vt_lookup(i64vec2(q.x, q.y), q.frac, q.mip);
  answers[i].valid = l.valid ? 1u : 0u;
  answers[i].slot = l.slot;
  answers[i].data_mip = l.data_mip;
  answers[i].pad = 0;
  answers[i].local = l.local;
  answers[i].pad2 = vec2(0.0);
}
