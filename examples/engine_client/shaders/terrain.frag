#version 460
// Albedo through terravt's virtual texture (the GLSL contract, terravt/vt.glsl), and one page
// request per N x N pixel block into the engine's feedback buffer (compacted by terravt on the
// GPU, or read back on the CPU with --cpu-feedback).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "common.glsl"

#define TERRAVT_VT_SET 0
#define TERRAVT_VT_BINDING_INFO 5
#define TERRAVT_VT_BINDING_TABLE 6
#define TERRAVT_VT_BINDING_CACHE 7
#include "terravt/vt.glsl"

// The feedback store is a side effect, which would switch early depth tests off: hidden
// fragments would then report pages nobody sees.
layout(early_fragment_tests) in;
layout(std430, set = 0, binding = 1) writeonly buffer Feedback { uvec2 requests[]; };

layout(location = 0) in vec2 in_local;
layout(location = 0) out vec4 out_colour;

void main() {
  const vec2 whole = floor(in_local);
  const ivec2 texel = frame.anchor.xy + ivec2(whole);
  const vec2 frac = in_local - whole;
  const vec2 dx = dFdx(in_local), dy = dFdy(in_local);
  // Neutral lighting: the image is the albedo.
  out_colour = vec4(terravt_sample(texel, frac, dx, dy).rgb, 1.0);
  const uvec2 px = uvec2(gl_FragCoord.xy);
  const uint n = frame.feedback.x;
  if (px.x % n == frame.feedback.y && px.y % n == frame.feedback.z)
    requests[(px.y / n) * frame.feedback.w + px.x / n] = terravt_feedback(texel, dx, dy);
}
