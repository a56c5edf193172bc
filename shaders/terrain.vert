#version 460
// Terrain chunk vertex (docs/renderer.md): grid vertex (i, j) of a chunk at one LOD. Integer
// texel arithmetic relative to the camera's anchor texel; heights fetched bilinearly from the
// heightfield with the fixed-point addressing of shared/terrain_types.h (mirrored on the CPU by
// TerrainMesh::height01_at_texel); normal from central differences one heightfield texel apart.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "shared/terrain_types.h"

layout(location = TVT_TERRAIN_ATTR_GRID) in uvec4 in_grid;  // i, j (LOD-0 quads), skirt flag

layout(std140, set = 0, binding = TVT_BIND_TERRAIN_FRAME) uniform FrameBuf { TvtTerrainFrame F; };
layout(std430, set = 0, binding = TVT_BIND_TERRAIN_HEIGHTS) readonly buffer HeightBuf { float heights[]; };
layout(push_constant) uniform DrawPush { TvtTerrainDraw D; };

layout(location = 0) out vec2 v_local_texel;  // level-0 VT texel coordinate minus the anchor
layout(location = 1) out vec3 v_normal;       // world, unnormalised
layout(location = 2) out vec3 v_rel_m;        // position minus camera, metres
layout(location = 3) out float v_height01;    // heightfield value in [0,1]

float texel(int x, int y) { return heights[y * int(F.hf.x) + x]; }

// Bilinear height at fixed-point heightfield coordinates (1/256 heightfield texels).
float height01_fp(int64_t ux, int64_t uy) {
  const int x0 = tvt_hf_tap0(ux, F.hf.x), x1 = tvt_hf_tap1(ux, F.hf.x);
  const int y0 = tvt_hf_tap0(uy, F.hf.y), y1 = tvt_hf_tap1(uy, F.hf.y);
  const float fx = tvt_hf_weight(ux), fy = tvt_hf_weight(uy);
  const float top = texel(x0, y0) + (texel(x1, y0) - texel(x0, y0)) * fx;
  const float bottom = texel(x0, y1) + (texel(x1, y1) - texel(x0, y1)) * fx;
  return top + (bottom - top) * fy;
}

void main() {
  const ivec2 rel = tvt_vertex_rel_texel(D.rel_texel, in_grid.x, in_grid.y, D.quad_texels);
  const int64_t x = F.anchor_x + int64_t(rel.x), y = F.anchor_y + int64_t(rel.y);
  const int64_t ux = tvt_hf_coord_fp(x, F.hf.x, F.hf.z), uy = tvt_hf_coord_fp(y, F.hf.y, F.hf.z);
  const float h = height01_fp(ux, uy);

  const int64_t one = int64_t(1) << int64_t(TVT_HF_FRAC_BITS);  // one heightfield texel
  const float dhdx = (height01_fp(ux + one, uy) - height01_fp(ux - one, uy)) * F.terrain.x / (2.0 * F.terrain.y);
  const float dhdy = (height01_fp(ux, uy + one) - height01_fp(ux, uy - one)) * F.terrain.x / (2.0 * F.terrain.z);

  const vec2 local = vec2(rel);
  vec3 rel_m = vec3((local - F.camera.xy) * F.camera.w, h * F.terrain.x - F.camera.z);
  if (in_grid.z != 0u) rel_m.z -= D.skirt_depth_m;

  v_local_texel = local;
  v_normal = vec3(-dhdx, -dhdy, 1.0);
  v_rel_m = rel_m;
  v_height01 = h;
  gl_Position = F.clip_from_relative * vec4(rel_m, 1.0);
}
