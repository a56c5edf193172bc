#version 460
// Page composition (docs/composition.md): one invocation per texel of a (P+2B)^2 page, one workgroup z
// slice per page job; the per-sample maths is in compose_sample.glsl.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "shared/compose_types.h"
#include "shared/hash.h"
#include "shared/compose_bindings.h"
#include "shared/compose_coord.h"

layout(local_size_x = TVT_COMPOSE_GROUP, local_size_y = TVT_COMPOSE_GROUP, local_size_z = 1) in;

layout(std430, set = 0, binding = TVT_BIND_COMPOSE_PARAMS) readonly buffer ParamsBuf { TvtComposeParams P; };
layout(std430, set = 0, binding = TVT_BIND_MATERIAL_TEXELS) readonly buffer MaterialBuf { uint material_texels[]; };
layout(std430, set = 0, binding = TVT_BIND_META_TEXELS) readonly buffer MetaBuf { uint meta_texels[]; };
layout(std430, set = 0, binding = TVT_BIND_WEIGHTS) readonly buffer WeightBuf { float weights[]; };
layout(std430, set = 0, binding = TVT_BIND_PAGE_JOBS) readonly buffer JobBuf { TvtPageJob jobs[]; };
layout(set = 0, binding = TVT_BIND_PAGE_OUTPUT, rgba8) uniform writeonly image2DArray page_out;

layout(push_constant) uniform Push { TvtComposePush push; };

#include "compose_sample.glsl"

void main() {
  const uint job_index = gl_GlobalInvocationID.z + push.job_offset;
  const int size = P.page_texels + 2 * P.border_texels;
  const ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  if (t.x >= size || t.y >= size || gl_GlobalInvocationID.z >= push.job_count) return;
  const TvtPageJob job = jobs[job_index];
  const int mip = int(job.mip);
  const int64_t last = (int64_t(1) << (P.log2_vt - mip)) - 1;
  const int64_t x = clamp(int64_t(job.page_x) * int64_t(P.page_texels) - int64_t(P.border_texels) + int64_t(t.x), int64_t(0), last);
  const int64_t y = clamp(int64_t(job.page_y) * int64_t(P.page_texels) - int64_t(P.border_texels) + int64_t(t.y), int64_t(0), last);
  if (P.pattern == TVT_COMPOSE_PATTERN_COORDS) {  // tests: every texel names itself
    imageStore(page_out, ivec3(t, int(job.slot)), unpackUnorm4x8(tvt_coord_word(mip, x, y)));
    return;
  }
  // Never more samples per side than the 2^mip level-0 texels the texel covers: mip 0 is direct.
  const int64_t s = min(int64_t(P.supersample), int64_t(1) << mip);
  const int sub_shift = mip + TVT_FIXED_BITS;
  // 2^mip / s, exactly for a power-of-two s (every validated one): the host decides from it
  // which prefiltered parts a mip's pages reach (prefiltered_parts()).
  const int log2_s = findMSB(int(s));
  const float footprint = s == (int64_t(1) << log2_s) ? ldexp(1.0, mip - log2_s) : exp2(float(mip)) / float(s);
  // Mip 0 is direct under every strategy (compose_sample() applies the variant's constants).
  const bool prefiltered = P.prefiltered != 0 && mip > 0;
  vec4 sum = vec4(0.0);
  for (int64_t sy = 0; sy < s; ++sy)
    for (int64_t sx = 0; sx < s; ++sx) {
      const int64_t xf = (x << sub_shift) + (((2 * sx + 1) << sub_shift) / (2 * s));
      const int64_t yf = (y << sub_shift) + (((2 * sy + 1) << sub_shift) / (2 * s));
      sum += compose_sample(xf, yf, footprint, job.material_mask, prefiltered);
    }
  imageStore(page_out, ivec3(t, int(job.slot)), sum / float(s * s));
}
