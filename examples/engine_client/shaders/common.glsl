// The example engine's own frame constants and bindings (set 0): terravt's three descriptors
// sit at bindings 5, 6 and 7, the engine's at 0 and 1. Shared by terrain.vert and terrain.frag.
layout(std140, set = 0, binding = 0) uniform Frame {
  mat4 clip_from_relative;  // camera-relative metres -> clip (reverse-Z, Vulkan y down)
  vec4 camera;              // xy: camera texel minus the anchor (in [0, 1)), z: camera height m, w: metres per texel
  ivec4 anchor;             // xy: the camera's level-0 texel (exact), z: texels per grid quad
  uvec4 feedback;           // x: divisor N, y, z: this frame's pixel of every N x N block, w: feedback row length
} frame;
