#version 460
// Vulkan-context raster test: colour from the primitive id, and (id, pixel x) as integers in a
// second attachment.
layout(location = 0) flat in uint v_id;
layout(location = 0) out vec4 out_color;
layout(location = 1) out uvec2 out_id;
void main() {
  out_color = vec4(float(v_id) / 255.0, 0.0, 1.0, 1.0);
  out_id = uvec2(v_id, uint(gl_FragCoord.x));
}
