// Test kernel: a client's page producer (tests/gpu_page_producer.cpp) writes a checkerboard of
// 8-texel squares in level-`mip` texel coordinates into cache layer `slot`, borders included.
// Colours are k/255 so the RGBA8 stores are exact: dark (0, 0, 0, 255); light (16 mip, 255,
// slot mod 256, 128).
#version 460
layout(local_size_x = 8, local_size_y = 8) in;
layout(set = 0, binding = 0, rgba8) uniform writeonly image2DArray cache;
layout(push_constant, std430) uniform Push {
  uint mip, x, y, slot, page_texels, border_texels;
} pc;

void main() {
  const uvec2 ij = gl_GlobalInvocationID.xy;
  const uint side = pc.page_texels + 2u * pc.border_texels;
  if (ij.x >= side || ij.y >= side) return;
  const ivec2 g = ivec2(uvec2(pc.x, pc.y) * pc.page_texels + ij) - int(pc.border_texels);
  const bool dark = (((g.x >> 3) ^ (g.y >> 3)) & 1) != 0;
  const vec4 light = vec4(float(16u * pc.mip), 255.0, float(pc.slot % 256u), 128.0) / 255.0;
  imageStore(cache, ivec3(ij, pc.slot), dark ? vec4(0.0, 0.0, 0.0, 1.0) : light);
}
