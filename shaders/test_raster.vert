#version 460
// Vulkan-context raster test (tests/gpu_raster.cpp): positions are already in clip space.
layout(location = 0) in vec4 in_position;  // clip space
layout(location = 1) in uint in_id;
layout(location = 0) flat out uint v_id;
void main() {
  v_id = in_id;
  gl_Position = in_position;
}
