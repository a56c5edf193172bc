#version 460
// The engine's terrain: a flat grid (z = 0) of chunks. Integer texel arithmetic relative to
// the camera's anchor texel, converted to float once: the level-0 texel coordinate the
// fragment samples terravt with is anchor (exact) + a small float.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(location = 0) in uvec2 in_grid;     // vertex of the chunk grid, in quads
layout(location = 1) in ivec2 in_origin;   // per instance: chunk origin minus the anchor, level-0 texels

layout(location = 0) out vec2 out_local;   // level-0 texel coordinate minus the anchor

void main() {
  const ivec2 rel = in_origin + ivec2(in_grid) * frame.anchor.z;
  const vec2 local = vec2(rel);
  const vec3 rel_m = vec3((local - frame.camera.xy) * frame.camera.w, -frame.camera.z);
  out_local = local;
  gl_Position = frame.clip_from_relative * vec4(rel_m, 1.0);
}
