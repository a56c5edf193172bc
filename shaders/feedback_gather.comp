// Feedback compaction, pass 2 of 2: appends every occupied hash-table entry to the output list
// (atomic counter; the list has the table's capacity, so it cannot overflow) and resets the entry
// to EMPTY, leaving the table clean for the next compaction without a separate clear pass.
// Runs after feedback_insert.comp (barrier in between). See docs/feedback.md.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/feedback_types.h"

layout(local_size_x = TVT_FEEDBACK_GROUP) in;
layout(set = 0, binding = TVT_BIND_FEEDBACK_TABLE, std430) buffer Table { TvtFeedbackEntry table[]; };
layout(set = 0, binding = TVT_BIND_FEEDBACK_LIST, std430) buffer List {
  TvtFeedbackListHeader header;
  TvtFeedbackEntry list[];
};
layout(push_constant, std430) uniform Push { TvtFeedbackPush pc; };

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= pc.capacity) return;
  const TvtFeedbackEntry e = table[i];
  if (e.key0 == TVT_FEEDBACK_EMPTY_WORD) return;
  // Both words are set once insertion is complete (the invocation that set key0 also set or
  // matched key1), and such an entry has count >= 1.
  list[atomicAdd(header.count, 1u)] = e;
  table[i] = TvtFeedbackEntry(TVT_FEEDBACK_EMPTY_WORD, TVT_FEEDBACK_EMPTY_WORD, 0u);
}
