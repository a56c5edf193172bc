// Page-table lookup (docs/virtual-texture.md). The includer declares
//   TvtVtInfo tvt_vt;  uint tvt_vt_entries[];
// and enables GL_EXT_shader_explicit_arithmetic_types_int64. Optionally it also declares, as a
// second block on VT's binding, `ivec4 tvt_vt_info_words[]` and defines TVT_VT_INFO_WORDS: the same
// bytes, so mip m's window (TvtVtMip) is one 16-byte load, word TVT_VT_INFO_MIP_WORD + m
// (vt_types.h), instead of four 4-byte loads (-15 % of the VT pass on lavapipe, where every
// buffer load is a per-lane gather).
// Positions are level-0 texels as an exact integer part `ti` plus a float fraction `tf`
// (|tf| small): no whole-terrain float coordinate anywhere (docs/composition.md).
#ifndef TVT_VT_LOOKUP_GLSL
#define TVT_VT_LOOKUP_GLSL
#include "shared/page_table_entry.h"

struct TvtVtLookup {
  bool valid;
  uint slot;     // cache slot (array layer)
  int data_mip;  // mip of the page the data comes from (>= the requested mip)
  vec2 local;    // texel coordinate inside the slot, border included ([B, B+P) for the payload)
};

// Window of mip m: origin x, y (pages), size (entries per side, a power of two), first entry.
ivec4 tvt_vt_window(int m) {
#ifdef TVT_VT_INFO_WORDS
  return tvt_vt_info_words[TVT_VT_INFO_MIP_WORD + m];
#else
  return ivec4(tvt_vt.mips[m].origin_x, tvt_vt.mips[m].origin_y, tvt_vt.mips[m].size, int(tvt_vt.mips[m].offset));
#endif
}

bool tvt_vt_outside(ivec2 page, ivec4 w) { return any(lessThan(page, w.xy)) || any(greaterThanEqual(page, w.xy + w.z)); }

// The first mip >= `mip` whose window holds the position's page; one entry fetch. Integer
// arithmetic in 32 bits: texel coordinates of positions on the terrain (0 <= ti <= V <= 2^30)
// fit int32, and 64-bit shifts and conversions are slow on some devices (lavapipe emulates them).
TvtVtLookup tvt_vt_lookup32(ivec2 ti, vec2 tf, int mip) {
  TvtVtLookup r;
  r.valid = false;
  r.slot = 0u;
  r.data_mip = 0;
  r.local = vec2(0.0);
  int m = clamp(mip, 0, tvt_vt.mip_count - 1);
  ivec4 w = tvt_vt_window(m);
  ivec2 page = ti >> (tvt_vt.log2_page + m);
  // Up to the first mip whose window holds the page. Usually none: windows are centred on the
  // camera. (One entry fetch after the walk, not inside it: on SIMD devices that run loops under
  // a mask, only the lanes outside their window pay for the walk.)
  while (m + 1 < tvt_vt.mip_count && tvt_vt_outside(page, w)) {
    ++m;
    w = tvt_vt_window(m);
    page = ti >> (tvt_vt.log2_page + m);
  }
  if (tvt_vt_outside(page, w)) return r;
  const int size = w.z;
  const uint e = tvt_vt_entries[uint(w.w) + uint((page.y & (size - 1)) * size + (page.x & (size - 1)))];
  if (!tvt_pte_valid(e)) return r;
  const int d = int(tvt_pte_mip(e));
  const ivec2 xi = ti >> d;                                      // texel at the data mip
  const vec2 f = (vec2(ti - (xi << d)) + tf) * exp2(-float(d));  // remainder, < 1 texel + tf
  r.valid = true;
  r.slot = tvt_pte_slot(e);
  r.data_mip = d;
  r.local = vec2(xi & ((1 << tvt_vt.log2_page) - 1)) + f + float(tvt_vt.border_texels);
  return r;
}

// A 64-bit texel coordinate as int32: positions beyond [-2^31, 2^31) clamp (they lie outside
// every terrain V <= 2^30 allows).
ivec2 tvt_vt_texel32(i64vec2 ti) {
  const i64vec2 lim = i64vec2(0x7fffffff);
  return ivec2(clamp(ti, -lim - int64_t(1), lim));
}

TvtVtLookup tvt_vt_lookup(i64vec2 ti, vec2 tf, int mip) { return tvt_vt_lookup32(tvt_vt_texel32(ti), tf, mip); }

#endif
