// Answers of test_vt_coord.comp, which samples coordinate-pattern pages (compose_coord.h)
// through vt_sample.glsl at a list of positions (queries: TvtVtQuery, vt_test_types.h).
#ifndef TVT_SHARED_VT_COORD_TEST_TYPES_H
#define TVT_SHARED_VT_COORD_TEST_TYPES_H
#include "bridge.h"

TVT_BEGIN

struct TvtVtCoordAnswer {  // 64 bytes
  uint valid;              // vt_lookup() found an entry
  uint slot;
  int data_mip;
  int pad;
  vec2 local;              // vt_lookup(): texel coordinate inside the slot, border included
  ivec2 corner;            // floor(local - 0.5): the slot texel bilinear filtering starts at
  vec4 filtered;           // vt_sample_mip(): bilinear sample of the cache (the real path)
  uvec4 quad;              // exact words of the 2x2 texels at corner + (0,0), (1,0), (0,1), (1,1)
};

#define TVT_BIND_TEST_COORD_INFO 0
#define TVT_BIND_TEST_COORD_ENTRIES 1
#define TVT_BIND_TEST_COORD_CACHE 2
#define TVT_BIND_TEST_COORD_QUERIES 3
#define TVT_BIND_TEST_COORD_ANSWERS 4

TVT_END

#ifdef __cplusplus
static_assert(sizeof(tvt::gpu::TvtVtCoordAnswer) == 64);
static_assert(offsetof(tvt::gpu::TvtVtCoordAnswer, filtered) == 32);
static_assert(offsetof(tvt::gpu::TvtVtCoordAnswer, quad) == 48);
#endif
#endif
