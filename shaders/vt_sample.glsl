// Sampling through the virtual texture (DESIGN §5): vt_lookup.glsl plus the physical cache.
// The includer also declares sampler2DArray vt_cache (bilinear, clamp to edge).
#ifndef TVT_VT_SAMPLE_GLSL
#define TVT_VT_SAMPLE_GLSL
#include "vt_lookup.glsl"

vec4 vt_sample_mip(i64vec2 ti, vec2 tf, int mip) {
  const VtLookup l = vt_lookup(ti, tf, mip);
  if (!l.valid) return vec4(1.0, 0.0, 1.0, 1.0);  // no data at all: visible, never NaN
  if (VT.debug_view == TVT_VT_VIEW_DATA_MIP) return tvt_mip_colour(l.data_mip);
  return textureLod(vt_cache, vec3(l.local / float(VT.slot_texels), float(l.slot)), 0.0);
}

// LOD from the footprint in level-0 texels per pixel (max of the two derivative lengths).
float vt_lod(vec2 dx, vec2 dy) {
  const float rho = max(length(dx), length(dy));
  return max(log2(max(rho, 1e-8)) + VT.mip_bias, 0.0);
}

// Trilinear: bilinear inside the border of two pages, blended across mips (two lookups).
vec4 vt_sample(i64vec2 ti, vec2 tf, float lod) {
  const float l = clamp(lod, 0.0, float(VT.mip_count - 1));
  const int m0 = int(floor(l));
  const float t = l - float(m0);
  const vec4 a = vt_sample_mip(ti, tf, m0);
  if (t <= 0.0 || m0 + 1 >= VT.mip_count) return a;
  return mix(a, vt_sample_mip(ti, tf, m0 + 1), t);
}

#endif
