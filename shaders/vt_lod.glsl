// Texel footprint -> LOD (and anisotropic tap line) for virtual-texture sampling. Pure
// functions of the screen derivatives, with no bindings, so that every pass choosing a VT mip
// (the VT sampler, the feedback writers, the matched-LOD direct-splat mode) uses exactly the
// same numbers. Units: derivatives in level-0 VT texels per pixel; LOD in mips.
#ifndef TVT_VT_LOD_GLSL
#define TVT_VT_LOD_GLSL
#include "shared/feedback_types.h"

// Lengths beyond this (or NaN) are treated as this: the LOD then clamps to the top mip.
const float TVT_MAX_FOOTPRINT = 1e30;

float tvt_safe_length(vec2 d) {
  const float l = length(d);
  return l < TVT_MAX_FOOTPRINT ? l : TVT_MAX_FOOTPRINT;  // NaN fails the comparison too
}

struct TvtVtFootprint {
  float lod;   // mip level to sample (>= 0, not yet clamped to the top mip)
  vec2 axis;   // major axis of the footprint, level-0 texels (the longer derivative)
  int taps;    // samples along `axis` (1: isotropic)
};

// Isotropic: LOD from the longer derivative (OpenGL's rho = max of the two lengths).
float tvt_vt_lod_iso(vec2 dx, vec2 dy, float bias) {
  const float rho = max(tvt_safe_length(dx), tvt_safe_length(dy));
  return max(log2(max(rho, 1e-8)) + bias, 0.0);
}

// Anisotropic footprint (the EXT_texture_filter_anisotropic recipe): N = ceil(major / minor)
// taps, at most max_taps, spread along the major axis; the LOD comes from major / N, which
// equals the minor axis when the ratio is within the limit (never coarser than it otherwise).
// With max_taps = 1 this is exactly tvt_vt_lod_iso().
TvtVtFootprint tvt_vt_footprint(vec2 dx, vec2 dy, float bias, int max_taps) {
  const float lx = tvt_safe_length(dx), ly = tvt_safe_length(dy);
  const float major = max(lx, ly), minor = min(lx, ly);
  TvtVtFootprint fp;
  fp.axis = lx >= ly ? dx : dy;
  if (!(major < TVT_MAX_FOOTPRINT)) fp.axis = vec2(0.0);
  // 1e-3: a ratio a rounding error above an integer does not buy another tap.
  const float ratio = major / max(minor, 1e-8);
  fp.taps = max_taps <= 1 ? 1 : int(clamp(ceil(ratio - 1e-3), 1.0, float(max_taps)));
  fp.lod = max(log2(max(major / float(fp.taps), 1e-8)) + bias, 0.0);
  return fp;
}

// The LOD a sample actually uses under the mip filter (app/terrain_renderer.h VtMipFilter):
// the two mips around `lod` blend only while its fraction f lies within band / 2 of 1/2, the
// weight of the coarser one ramping linearly from 0 to 1 across the band; elsewhere the result
// is a whole number, the nearer mip, so one page lookup serves the sample and feedback asks for
// exactly that page. band >= 1: trilinear (lod itself); band <= 0: the nearest mip as
// GL_LINEAR_MIPMAP_NEAREST picks it (ties go to the finer mip). lod >= 0 and finite.
float tvt_filtered_lod(float lod, float band) {
  if (band >= 1.0) return lod;
  const float m = floor(lod), f = lod - m;
  if (!(band > 0.0)) return f > 0.5 ? m + 1.0 : m;
  return m + clamp((f - 0.5) / band + 0.5, 0.0, 1.0);
}

// Feedback texel (feedback_types.h) naming the page that a sample at `lod` wants: the finer
// of its two mips, before any fallback to a resident ancestor. Positions outside the terrain
// clamp to its edge. 32-bit: texel coordinates on a terrain of V <= 2^30 fit int32.
uvec2 tvt_feedback_page(ivec2 ti, float lod, int mip_count, int log2_vt, int log2_page) {
  const int m = clamp(int(floor(lod)), 0, mip_count - 1);
  const ivec2 clamped = clamp(ti, ivec2(0), ivec2((1 << log2_vt) - 1));
  const uvec2 page = uvec2(clamped >> (log2_page + m));
  return uvec2(tvt_feedback_word0(uint(m), page.x), tvt_feedback_word1(page.y));
}

#endif
