// Bindings of the VT passes (page-table scatter; sampling descriptors used by render passes).
#ifndef TVT_SHARED_VT_BINDINGS_H
#define TVT_SHARED_VT_BINDINGS_H
#include "bridge.h"

TVT_BEGIN

#define TVT_BIND_SCATTER_ENTRIES 0  // uint entries[] (the flat page table)
#define TVT_BIND_SCATTER_UPDATES 1  // uvec2 updates[]: (flat index, value)

TVT_CONST uint TVT_SCATTER_GROUP = 64u;

struct TvtScatterPush {
  uint first;  // first update of this dispatch in the buffer (ring part)
  uint count;  // updates from `first` on
};

TVT_END
#endif
