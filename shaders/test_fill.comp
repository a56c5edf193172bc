// Test kernel for the Vulkan context: values[i] = i * i ^ xor_value (tests/gpu_vk_context.cpp).
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/test_types.h"

layout(local_size_x = TVT_TEST_FILL_GROUP) in;
layout(set = 0, binding = 0, std430) writeonly buffer Values { uint values[]; };
layout(push_constant, std430) uniform Push { TvtTestFillPush pc; };

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= pc.count) return;
  values[i] = (i * i) ^ pc.xor_value;
}
