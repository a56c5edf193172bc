// Virtual-texture sampling state shared by the sampling GLSL (vt_sample.glsl) and the host.
#ifndef TVT_SHARED_VT_TYPES_H
#define TVT_SHARED_VT_TYPES_H
#include "bridge.h"

TVT_BEGIN

TVT_CONST int TVT_MAX_VT_MIPS = 32;

struct TvtVtMip {    // one mip's page-table window, in pages of that mip (vt/page_table.h)
  int origin_x;      // first page covered
  int origin_y;
  int size;          // entries per side (power of two)
  uint offset;       // first entry of this mip in the flat entry buffer
};

struct TvtVtInfo {
  int log2_vt;       // V = 2^log2_vt level-0 texels
  int log2_page;     // P = 2^log2_page payload texels per page
  int border_texels; // B
  int slot_texels;   // P + 2B: edge of a cache slot
  int mip_count;
  float mip_bias;    // added to every LOD (residency raises it when oversubscribed)
  int pad0, pad1;
  TvtVtMip mips[TVT_MAX_VT_MIPS];
};

TVT_END

#ifdef __cplusplus
static_assert(sizeof(tvt::gpu::TvtVtMip) == 16);
static_assert(offsetof(tvt::gpu::TvtVtInfo, mips) == 32);
static_assert(sizeof(tvt::gpu::TvtVtInfo) == 32 + 32 * 16);
#endif
#endif
