// Feedback texel format and the GPU feedback compactor's buffers (feedback_insert.comp,
// feedback_gather.comp), shared by GLSL, render/feedback_compactor.cpp and the CPU reference
// vt/feedback_analysis.cpp. See docs/feedback.md.
//
// Texel: two uint32 words (a uvec2 SSBO element, or an R32G32_UINT image texel):
//   word0 = page_x | mip << 27      page_x in bits 0..26, mip in bits 27..31
//   word1 = page_y                  page_y in bits 0..26; bits 27..31 reserved (ignored: masked off)
// page_x, page_y < 2^27 covers every VtConfig validate() accepts (V <= 2^30 and P >= 16 give at
// most 2^26 pages per side), with one bit to spare (P = 8 at V = 2^30 would still fit). A texel whose mip field is 31 is EMPTY (sky, no terrain): valid mips are
// <= 30 - log2(P) < 31. Writers clear to (~0u, ~0u).
#ifndef TVT_SHARED_FEEDBACK_TYPES_H
#define TVT_SHARED_FEEDBACK_TYPES_H
#include "bridge.h"
#include "hash.h"

TVT_BEGIN

TVT_CONST uint TVT_FEEDBACK_COORD_BITS = 27u;
TVT_CONST uint TVT_FEEDBACK_COORD_MASK = 0x07ffffffu;  // (1 << 27) - 1
TVT_CONST uint TVT_FEEDBACK_EMPTY_MIP = 31u;          // mip field value of an empty texel
TVT_CONST uint TVT_FEEDBACK_EMPTY_WORD = 0xffffffffu; // clear value of both words; also the
                                                      // "unclaimed" key word of a table entry
TVT_CONST uint TVT_FEEDBACK_GROUP = 64u;              // invocations per workgroup, both passes
// Consecutive texels one insert invocation reads; runs of equal texels among them are counted
// with one atomicAdd (feedback is spatially coherent). Also 8x fewer workgroups, which is what
// lavapipe pays for (docs/feedback.md).
TVT_CONST uint TVT_FEEDBACK_TEXELS_PER_INVOCATION = 8u;

// Descriptor bindings (set 0) of feedback_insert.comp and feedback_gather.comp.
#define TVT_BIND_FEEDBACK_TEXELS 0  // readonly uvec2[width * height], the feedback texels
#define TVT_BIND_FEEDBACK_TABLE 1   // TvtFeedbackEntry[capacity], the hash table
#define TVT_BIND_FEEDBACK_LIST 2    // TvtFeedbackListHeader + TvtFeedbackEntry[capacity]

// Hash table entry and output list entry (std430 stride 12). Key words are EMPTY until claimed.
struct TvtFeedbackEntry {
  uint key0;   // texel word0 (never EMPTY for a non-empty texel: its mip field is < 31)
  uint key1;   // texel word1 with the reserved bits masked off (so never EMPTY either)
  uint count;  // number of feedback texels naming this page
};

struct TvtFeedbackListHeader {  // 16 bytes, zeroed before the insert pass
  uint count;            // entries appended to the list by the gather pass
  uint overflow_texels;  // non-empty texels that found no table slot within max_probes
  uint pad0, pad1;
};

struct TvtFeedbackPush {  // 16 bytes
  uint texel_count;       // texels in the feedback buffer (width * height)
  uint capacity;          // table entries, a power of two
  uint max_probes;        // linear-probing limit per texel, 1 ... capacity
  uint pad0;
};

TVT_FN uint tvt_feedback_word0(uint mip, uint page_x) { return (mip << TVT_FEEDBACK_COORD_BITS) | page_x; }
TVT_FN uint tvt_feedback_word1(uint page_y) { return page_y; }
TVT_FN uint tvt_feedback_mip(uint word0) { return word0 >> TVT_FEEDBACK_COORD_BITS; }
TVT_FN uint tvt_feedback_x(uint word0) { return word0 & TVT_FEEDBACK_COORD_MASK; }
TVT_FN uint tvt_feedback_y(uint word1) { return word1 & TVT_FEEDBACK_COORD_MASK; }
TVT_FN bool tvt_feedback_is_empty(uint word0) { return tvt_feedback_mip(word0) == TVT_FEEDBACK_EMPTY_MIP; }

// Home slot of a key in a table of `capacity` (power of two) entries; probing goes on linearly.
TVT_FN uint tvt_feedback_home(uint key0, uint key1, uint capacity) {
  return tvt_mix32(key0 ^ tvt_mix32(key1 ^ 0x9e3779b9u)) & (capacity - 1u);
}

TVT_END

#ifdef __cplusplus
static_assert(sizeof(tvt::gpu::TvtFeedbackEntry) == 12);
static_assert(sizeof(tvt::gpu::TvtFeedbackListHeader) == 16);
static_assert(sizeof(tvt::gpu::TvtFeedbackPush) == 16);
#endif
#endif
