// Feedback compaction, pass 1 of 2: counts every non-empty feedback texel into an open-addressing
// hash table (linear probing) keyed by the two texel words. See docs/feedback.md.
//
// Lock-free two-word claim without spinning: an entry's key words start EMPTY and are each set
// once, in order, by atomicCompSwap(EMPTY -> own word). An invocation moves on to the next slot as
// soon as one word holds a different (final) value; once both words equal its key it atomicAdds
// its count. Every word is written once and never changes, so all invocations of one key take the
// same decision at every slot: each key ends in exactly one entry (or overflows as a whole), and
// an entry's key is the key of the invocation that wrote its second word, which has counted.
//
// Each invocation reads TVT_FEEDBACK_TEXELS_PER_INVOCATION consecutive texels and inserts each
// run of equal keys once, with the run's length (empty texels inside a run do not break it).
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/feedback_types.h"

layout(local_size_x = TVT_FEEDBACK_GROUP) in;
layout(set = 0, binding = TVT_BIND_FEEDBACK_TEXELS, std430) readonly buffer Texels { uvec2 texels[]; };
layout(set = 0, binding = TVT_BIND_FEEDBACK_TABLE, std430) buffer Table { TvtFeedbackEntry table[]; };
layout(set = 0, binding = TVT_BIND_FEEDBACK_LIST, std430) buffer List {
  TvtFeedbackListHeader header;
  TvtFeedbackEntry list[];
};
layout(push_constant, std430) uniform Push { TvtFeedbackPush pc; };

// Adds `n` texels of key (k0, k1) to the table, or to the overflow count.
void insert(uint k0, uint k1, uint n) {
  const uint mask = pc.capacity - 1u;
  uint slot = tvt_feedback_home(k0, k1, pc.capacity);
  for (uint probe = 0u; probe < pc.max_probes; ++probe, slot = (slot + 1u) & mask) {
    const uint w0 = atomicCompSwap(table[slot].key0, TVT_FEEDBACK_EMPTY_WORD, k0);
    if (w0 != TVT_FEEDBACK_EMPTY_WORD && w0 != k0) continue;
    const uint w1 = atomicCompSwap(table[slot].key1, TVT_FEEDBACK_EMPTY_WORD, k1);
    if (w1 != TVT_FEEDBACK_EMPTY_WORD && w1 != k1) continue;
    atomicAdd(table[slot].count, n);
    return;
  }
  atomicAdd(header.overflow_texels, n);
}

void main() {
  const uint first = gl_GlobalInvocationID.x * TVT_FEEDBACK_TEXELS_PER_INVOCATION;
  if (first >= pc.texel_count) return;
  const uint end = min(first + TVT_FEEDBACK_TEXELS_PER_INVOCATION, pc.texel_count);
  uint k0 = 0u, k1 = 0u, n = 0u;
  for (uint i = first; i < end; ++i) {
    const uvec2 t = texels[i];
    if (tvt_feedback_is_empty(t.x)) continue;
    const uint c1 = t.y & TVT_FEEDBACK_COORD_MASK;
    if (n != 0u && t.x == k0 && c1 == k1) {
      ++n;
      continue;
    }
    if (n != 0u) insert(k0, k1, n);
    k0 = t.x;
    k1 = c1;
    n = 1u;
  }
  if (n != 0u) insert(k0, k1, n);
}
