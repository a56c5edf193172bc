// Query/answer records of test_vt_lookup.comp, which runs vt_lookup.glsl on a list of
// positions so tests can compare the GLSL decoder with vt/page_table.h bit for bit.
#ifndef TVT_SHARED_VT_TEST_TYPES_H
#define TVT_SHARED_VT_TEST_TYPES_H
#include "bridge.h"

TVT_BEGIN

struct TvtVtQuery {   // 32 bytes
  int64_t x;          // level-0 texel, integer part
  int64_t y;
  vec2 frac;          // fraction inside the texel
  int mip;            // requested mip
  int pad;
};

struct TvtVtAnswer {  // 32 bytes
  uint valid;
  uint slot;
  int data_mip;
  int pad;
  vec2 local;         // texel coordinate inside the slot, border included
  vec2 pad2;
};

#define TVT_BIND_TEST_VT_INFO 0
#define TVT_BIND_TEST_VT_ENTRIES 1
#define TVT_BIND_TEST_VT_QUERIES 2
#define TVT_BIND_TEST_VT_ANSWERS 3

TVT_END

#ifdef __cplusplus
static_assert(sizeof(tvt::gpu::TvtVtQuery) == 32);
static_assert(sizeof(tvt::gpu::TvtVtAnswer) == 32);
#endif
#endif
