// Descriptor bindings and push constants of compose.comp (set 0), shared with the host.
#ifndef TVT_SHARED_COMPOSE_BINDINGS_H
#define TVT_SHARED_COMPOSE_BINDINGS_H
#include "bridge.h"

TVT_BEGIN

#define TVT_BIND_COMPOSE_PARAMS 0
#define TVT_BIND_MATERIAL_TEXELS 1
#define TVT_BIND_META_TEXELS 2
#define TVT_BIND_WEIGHTS 3
#define TVT_BIND_PAGE_JOBS 4
#define TVT_BIND_PAGE_OUTPUT 5

struct TvtComposePush {
  uint job_offset;  // first job of this dispatch
  uint job_count;   // jobs in the buffer from job_offset on
};

TVT_END

#ifdef __cplusplus
static_assert(sizeof(tvt::gpu::TvtComposePush) == 8);
#endif
#endif
