// Test kernel for the Vulkan context: writes test_image_texel() into every texel of an RGBA8
// 2D-array storage image (tests/gpu_vk_context.cpp compares each byte).
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/test_types.h"

layout(local_size_x = TVT_TEST_IMAGE_GROUP, local_size_y = TVT_TEST_IMAGE_GROUP) in;
layout(set = 0, binding = 0, rgba8) writeonly uniform image2DArray image;
layout(push_constant, std430) uniform Push { TvtTestImagePush pc; };

void main() {
  uvec3 p = gl_GlobalInvocationID;
  if (p.x >= pc.width || p.y >= pc.height || p.z >= pc.layers) return;
  // Bytes k/255 are exact in fp32 and round back to k on the UNORM store.
  vec4 texel = unpackUnorm4x8(test_image_texel(p.x, p.y, p.z, pc.salt));
  imageStore(image, ivec3(p), texel);
}
