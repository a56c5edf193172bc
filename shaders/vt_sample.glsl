// Sampling through the virtual texture (docs/virtual-texture.md): vt_lookup.glsl plus the physical cache.
// The includer also declares sampler2DArray tvt_vt_cache (bilinear, clamp to edge, no mips).
// Positions: level-0 texel `ti` (int32: positions on a terrain of V <= 2^30 texels fit, see
// tvt_vt_lookup32; i64vec2 overloads clamp) plus the fraction `tf` in [0, 1).
#ifndef TVT_VT_SAMPLE_GLSL
#define TVT_VT_SAMPLE_GLSL
#include "vt_lookup.glsl"
#include "vt_lod.glsl"

// Bilinear sample at a position inside a slot (border included), in slot texels.
vec4 tvt_vt_fetch(uint slot, vec2 local) {
  return textureLod(tvt_vt_cache, vec3(local / float(tvt_vt.slot_texels), float(slot)), 0.0);
}

// Gradient of the bilinearly filtered alpha (the material height) at a position inside a slot,
// in slot texels: the derivative of the bilinear interpolation of the 2x2 texels a fetch there
// reads (textureGather of alpha picks exactly those). Per lane, no screen derivatives, so it
// holds at triangle edges whatever helper invocations read.
vec2 tvt_vt_height_gradient(uint slot, vec2 local) {
  const vec4 a = textureGather(tvt_vt_cache, vec3(local / float(tvt_vt.slot_texels), float(slot)), 3);
  // a: x (i0,j1), y (i1,j1), z (i1,j0), w (i0,j0)
  const vec2 f = fract(local - 0.5);
  return vec2(mix(a.z - a.w, a.y - a.x, f.y), mix(a.x - a.w, a.y - a.z, f.x));
}

// One mip: page lookup, then the bilinear fetch and the height gradient in level-0 texels (0
// without data or in the debug view).
vec4 tvt_vt_sample_mip_dh(ivec2 ti, vec2 tf, int mip, out vec2 dh) {
  dh = vec2(0.0);
  const TvtVtLookup l = tvt_vt_lookup32(ti, tf, mip);
  if (!l.valid) return vec4(1.0, 0.0, 1.0, 1.0);  // no data at all: visible, never NaN
  if (tvt_vt.debug_view == TVT_VT_VIEW_DATA_MIP) return tvt_mip_colour(l.data_mip);
  dh = tvt_vt_height_gradient(l.slot, l.local) * exp2(-float(l.data_mip));
  return tvt_vt_fetch(l.slot, l.local);
}

// Without the gradient (the driver's compiler drops the unused gather after inlining).
vec4 tvt_vt_sample_mip(ivec2 ti, vec2 tf, int mip) {
  vec2 unused;
  return tvt_vt_sample_mip_dh(ti, tf, mip, unused);
}

vec4 tvt_vt_sample_mip(i64vec2 ti, vec2 tf, int mip) { return tvt_vt_sample_mip(tvt_vt_texel32(ti), tf, mip); }

// LOD from the footprint in level-0 texels per pixel (max of the two derivative lengths).
float tvt_vt_lod(vec2 dx, vec2 dy) { return tvt_vt_lod_iso(dx, dy, tvt_vt.mip_bias); }

// The two mips a (trilinear) sample at `lod` reads and the weight of the coarser one.
void tvt_vt_mip_pair(float lod, out int m0, out float t) {
  const float l = clamp(lod, 0.0, float(tvt_vt.mip_count - 1));
  m0 = int(floor(l));
  t = m0 + 1 >= tvt_vt.mip_count ? 0.0 : l - float(m0);
}

// Trilinear: bilinear inside the border of two pages, blended across mips (two lookups), with
// the gradient of the filtered height in level-0 texels (blended like the colour).
vec4 tvt_vt_sample_dh(ivec2 ti, vec2 tf, float lod, out vec2 dh) {
  int m0;
  float t;
  tvt_vt_mip_pair(lod, m0, t);
  const vec4 a = tvt_vt_sample_mip_dh(ti, tf, m0, dh);
  if (t <= 0.0) return a;
  vec2 dh1;
  const vec4 b = tvt_vt_sample_mip_dh(ti, tf, m0 + 1, dh1);
  dh = mix(dh, dh1, t);
  return mix(a, b, t);
}

// Anisotropic, one mip: one page lookup, then `taps` bilinear taps inside that slot along
// `axis` (level-0 texels; the taps sit at (i + 1/2)/taps - 1/2 of it, i = 0 .. taps-1). The tap
// line is clamped to reach at most B - 1/2 data-mip texels from the centre, so every bilinear
// tap stays inside the slot's border: the footprint never crosses into a page it did not look
// up. tvt_vt_footprint() with taps <= B never needs the clamp at the wanted mip (docs/renderer.md).
// dh: the height gradient at the footprint's centre, level-0 texels.
vec4 tvt_vt_sample_aniso_mip(ivec2 ti, vec2 tf, int mip, vec2 axis, int taps, out vec2 dh) {
  dh = vec2(0.0);
  const TvtVtLookup l = tvt_vt_lookup32(ti, tf, mip);
  if (!l.valid) return vec4(1.0, 0.0, 1.0, 1.0);
  if (tvt_vt.debug_view == TVT_VT_VIEW_DATA_MIP) return tvt_mip_colour(l.data_mip);
  dh = tvt_vt_height_gradient(l.slot, l.local) * exp2(-float(l.data_mip));
  if (taps <= 1) return tvt_vt_fetch(l.slot, l.local);
  vec2 a = axis * exp2(-float(l.data_mip));  // data-mip texels
  const float reach = length(a) * float(taps - 1) / float(2 * taps);  // farthest tap from the centre
  const float limit = float(tvt_vt.border_texels) - 0.5;
  if (reach > limit) a *= limit / reach;
  vec4 sum = vec4(0.0);
  for (int i = 0; i < taps; ++i) sum += tvt_vt_fetch(l.slot, l.local + a * ((float(i) + 0.5) / float(taps) - 0.5));
  return sum / float(taps);
}

// Anisotropic trilinear: tvt_vt_sample_aniso_mip() on the two mips of fp.lod, blended.
vec4 tvt_vt_sample_aniso(ivec2 ti, vec2 tf, TvtVtFootprint fp, out vec2 dh) {
  int m0;
  float t;
  tvt_vt_mip_pair(fp.lod, m0, t);
  const vec4 a = tvt_vt_sample_aniso_mip(ti, tf, m0, fp.axis, fp.taps, dh);
  if (t <= 0.0) return a;
  vec2 dh1;
  const vec4 b = tvt_vt_sample_aniso_mip(ti, tf, m0 + 1, fp.axis, fp.taps, dh1);
  dh = mix(dh, dh1, t);
  return mix(a, b, t);
}

// Feedback texel naming the page a sample at `lod` wants (vt_lod.glsl).
uvec2 tvt_vt_feedback_texel(ivec2 ti, float lod) {
  return tvt_feedback_page(ti, lod, tvt_vt.mip_count, tvt_vt.log2_vt, tvt_vt.log2_page);
}

#endif
