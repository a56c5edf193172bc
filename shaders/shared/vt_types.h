// Virtual-texture sampling state shared by the sampling GLSL (vt_sample.glsl) and the host.
#ifndef TVT_SHARED_VT_TYPES_H
#define TVT_SHARED_VT_TYPES_H
#include "bridge.h"

TVT_BEGIN

TVT_CONST int TVT_MAX_VT_MIPS = 32;
TVT_CONST int TVT_VT_VIEW_ALBEDO = 0;     // normal sampling
TVT_CONST int TVT_VT_VIEW_DATA_MIP = 1;   // colour = mip of the page the data came from

// Colour of a mip level in debug views: mip 0 red, 1 green, 2 yellow, 3 blue, 4 magenta,
// 5 cyan, 6 white, then again.
TVT_FN vec4 tvt_mip_colour(int mip) {
  const uint c = uint(mip % 7) + 1u;
  return vec4(float(c & 1u), float((c >> 1u) & 1u), float((c >> 2u) & 1u), 1.0f);
}

struct TvtVtMip {    // one mip's page-table window, in pages of that mip (vt/page_table.h)
  int origin_x;      // first page covered
  int origin_y;
  int size;          // entries per side (power of two)
  uint offset;       // first entry of this mip in the flat entry buffer
};

// TvtVtInfo::mips[m] read as one ivec4 (origin x, y, size, offset): vt_lookup.glsl loads
// word TVT_VT_INFO_MIP_WORD + m of the same buffer viewed as ivec4[].
TVT_CONST int TVT_VT_INFO_MIP_WORD = 2;

struct TvtVtInfo {
  int log2_vt;       // V = 2^log2_vt level-0 texels
  int log2_page;     // P = 2^log2_page payload texels per page
  int border_texels; // B
  int slot_texels;   // P + 2B: edge of a cache slot
  int mip_count;
  float mip_bias;    // added to every LOD (residency raises it when oversubscribed)
  int debug_view;    // TVT_VT_VIEW_*
  int pad1;
  TvtVtMip mips[TVT_MAX_VT_MIPS];
};

TVT_END

#ifdef __cplusplus
static_assert(sizeof(tvt::gpu::TvtVtMip) == 16);
static_assert(offsetof(tvt::gpu::TvtVtInfo, mips) == 32);
static_assert(offsetof(tvt::gpu::TvtVtInfo, mips) == 16 * tvt::gpu::TVT_VT_INFO_MIP_WORD);
static_assert(sizeof(tvt::gpu::TvtVtInfo) == 32 + 32 * 16);
#endif
#endif
