#version 460
// Page-table updates on the GPU: entries[flat index] = value for every (index, value) pair the
// residency policy produced this frame (vt/page_table.h take_updates(); each index once).
#extension GL_GOOGLE_include_directive : require
#include "shared/vt_bindings.h"

layout(local_size_x = TVT_SCATTER_GROUP) in;
layout(std430, set = 0, binding = TVT_BIND_SCATTER_ENTRIES) buffer EntryBuf { uint entries[]; };
layout(std430, set = 0, binding = TVT_BIND_SCATTER_UPDATES) readonly buffer UpdateBuf { uvec2 updates[]; };
layout(push_constant) uniform Push { TvtScatterPush push; };

void main() {
  if (gl_GlobalInvocationID.x >= push.count) return;
  const uvec2 u = updates[push.first + gl_GlobalInvocationID.x];
  entries[u.x] = u.y;
}
