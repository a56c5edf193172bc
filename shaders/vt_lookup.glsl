// Page-table lookup (DESIGN §5). The includer declares
//   TvtVtInfo VT;  uint pt_entries[];
// and enables GL_EXT_shader_explicit_arithmetic_types_int64.
// Positions are level-0 texels as an exact integer part `ti` plus a float fraction `tf`
// (|tf| small): no whole-terrain float coordinate anywhere (DESIGN §3).
#ifndef TVT_VT_LOOKUP_GLSL
#define TVT_VT_LOOKUP_GLSL
#include "shared/page_table_entry.h"

struct VtLookup {
  bool valid;
  uint slot;     // cache slot (array layer)
  int data_mip;  // mip of the page the data comes from (>= the requested mip)
  vec2 local;    // texel coordinate inside the slot, border included ([B, B+P) for the payload)
};

// The first mip >= `mip` whose window holds the position's page; one entry fetch.
VtLookup vt_lookup(i64vec2 ti, vec2 tf, int mip) {
  VtLookup r;
  r.valid = false;
  r.slot = 0u;
  r.data_mip = 0;
  r.local = vec2(0.0);
  mip = clamp(mip, 0, VT.mip_count - 1);
  for (int m = mip; m < VT.mip_count; ++m) {
    const ivec2 page = ivec2(ti >> int64_t(VT.log2_page + m));
    const ivec2 origin = ivec2(VT.mips[m].origin_x, VT.mips[m].origin_y);
    const int size = VT.mips[m].size;
    if (any(lessThan(page, origin)) || any(greaterThanEqual(page, origin + size))) continue;
    const uint e = pt_entries[VT.mips[m].offset + uint((page.y & (size - 1)) * size + (page.x & (size - 1)))];
    if (!tvt_pte_valid(e)) return r;
    const int d = int(tvt_pte_mip(e));
    const i64vec2 xi = ti >> int64_t(d);                               // texel at the data mip
    const vec2 f = (vec2(ti - (xi << int64_t(d))) + tf) * exp2(-float(d));  // remainder, < 1 texel + tf
    const i64vec2 pd = xi >> int64_t(VT.log2_page);
    r.valid = true;
    r.slot = tvt_pte_slot(e);
    r.data_mip = d;
    r.local = vec2(xi - (pd << int64_t(VT.log2_page))) + f + float(VT.border_texels);
    return r;
  }
  return r;
}

#endif
