#version 460
// FeedbackMode::Attachment, after the colour pass: copies the rotating pixel (x N + offset_x,
// y N + offset_y) of every N x N block from the pass's feedback attachment into feedback texel
// (x, y); texels whose pixel lies beyond the image are empty. One invocation per texel, every
// texel written (no clear needed). See terrain_renderer.h.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/feedback_types.h"
#include "shared/terrain_types.h"

layout(local_size_x = TVT_FEEDBACK_GROUP) in;
layout(set = 0, binding = TVT_BIND_FEEDBACK_PICK_IMAGE, rg32ui) uniform readonly uimage2DArray feedback_image;  // layer 0
layout(set = 0, binding = TVT_BIND_FEEDBACK_PICK_TEXELS, std430) writeonly buffer Texels { uvec2 feedback[]; };
layout(push_constant, std430) uniform Push { TvtFeedbackWrite FB; };

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= FB.width * FB.height) return;
  const uvec2 px = uvec2(i % FB.width, i / FB.width) * FB.divisor + uvec2(FB.offset_x, FB.offset_y);
  const uvec2 size = uvec2(imageSize(feedback_image).xy);
  feedback[i] = all(lessThan(px, size)) ? imageLoad(feedback_image, ivec3(px, 0)).xy : uvec2(TVT_FEEDBACK_EMPTY_WORD);
}
