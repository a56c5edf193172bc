// Terrain raster pass (terrain.vert / terrain.frag, app/terrain_renderer.cpp): bindings,
// the frame uniform block, the per-chunk push constants and the heightfield addressing
// shared bit for bit by the vertex shader and the CPU (terrain/terrain_mesh.cpp).
// GLSL must enable GL_EXT_shader_explicit_arithmetic_types_int64 before including this.
#ifndef TVT_SHARED_TERRAIN_TYPES_H
#define TVT_SHARED_TERRAIN_TYPES_H
#include "bridge.h"

TVT_BEGIN

TVT_CONST uint TVT_BIND_TERRAIN_FRAME = 0u;    // uniform TvtTerrainFrame
TVT_CONST uint TVT_BIND_TERRAIN_HEIGHTS = 1u;  // storage float[hf_width * hf_height], row-major, in [0,1]
// Virtual-texture mode (terrain_vt.frag) adds, fragment stage:
TVT_CONST uint TVT_BIND_TERRAIN_VT_INFO = 2u;          // storage TvtVtInfo
TVT_CONST uint TVT_BIND_TERRAIN_VT_ENTRIES = 3u;       // storage uint[]: the page table
TVT_CONST uint TVT_BIND_TERRAIN_VT_CACHE = 4u;         // sampler2DArray: the physical cache
TVT_CONST uint TVT_BIND_TERRAIN_FEEDBACK = 5u;         // storage uvec2[]: feedback texels (feedback_types.h)
TVT_CONST uint TVT_BIND_TERRAIN_FEEDBACK_PARAMS = 6u;  // uniform TvtFeedbackWrite
// FeedbackMode::Attachment's pick pass (feedback_pick.comp; push constant TvtFeedbackWrite):
TVT_CONST uint TVT_BIND_FEEDBACK_PICK_IMAGE = 0u;   // uimage2DArray rg32ui: the colour pass's attachment 1 (GENERAL)
TVT_CONST uint TVT_BIND_FEEDBACK_PICK_TEXELS = 1u;  // storage uvec2[]: the feedback texels
// Direct-splat mode (terrain_direct.frag: the composition per pixel, as the papers did) adds,
// fragment stage, compose_sample.glsl's inputs:
TVT_CONST uint TVT_BIND_TERRAIN_COMPOSE_PARAMS = 7u;     // storage TvtComposeParams
TVT_CONST uint TVT_BIND_TERRAIN_MATERIAL_TEXELS = 8u;    // storage uint[]
TVT_CONST uint TVT_BIND_TERRAIN_META_TEXELS = 9u;        // storage uint[]
TVT_CONST uint TVT_BIND_TERRAIN_WEIGHTS = 10u;           // storage float[]
// Plain-texture mode (terrain_plain.frag: one ordinary mip-mapped texture over the whole
// terrain, the baseline a VT is measured against) adds, fragment stage:
TVT_CONST uint TVT_BIND_TERRAIN_PLAIN = 11u;             // sampler2DArray (layer 0), trilinear
// Fragment specialization constants (vk::GraphicsPipelineDesc::fragment_constants) of the VT
// passes: most anisotropic taps per mip, 1 = isotropic (a constant, so the isotropic pipeline
// carries no dead anisotropic branch: some devices, lavapipe among them, run both sides).
#define TVT_TERRAIN_SPEC_MAX_ANISOTROPY 0
// ... and of the main-pass feedback writer: the divisor N (a constant turns the per-pixel
// "x mod N" into a multiply and shift; lavapipe has no vector integer division).
#define TVT_TERRAIN_SPEC_FEEDBACK_DIVISOR 1
// ... and whether the detail normal is on (relief > 0 at pipeline creation): off, the VT
// passes drop the height-gradient gathers (one per mip lookup) altogether.
#define TVT_TERRAIN_SPEC_DETAIL_NORMAL 2
// ... and the filter between mips (all VT passes, the separate feedback pass and the
// matched-LOD direct pass), a float: the LOD band around each half-way point in which two mips
// blend (vt_lod.glsl tvt_filtered_lod): 1 trilinear, 0 bilinear from the nearest mip (one page
// lookup; feedback then asks for that mip), between: brilinear.
#define TVT_TERRAIN_SPEC_MIP_BAND 3
TVT_CONST uint TVT_TERRAIN_ATTR_GRID = 0u;     // vertex attribute: uvec4 (i, j, skirt, 0), R16G16B16A16_UINT
TVT_CONST uint TVT_HF_FRAC_BITS = 8u;          // heightfield coordinates in 1/256 heightfield texels

// One frame (std140; written with vkCmdUpdateBuffer by TerrainRenderer::record).
// Coordinates: the camera's level-0 VT texel `anchor` is the integer origin of everything
// the GPU sees; positions are camera-relative metres, texel coordinates anchor-relative floats.
struct TvtTerrainFrame {   // 208 bytes
  mat4 clip_from_relative; // reverse-Z projection * view rotation; input: camera-relative metres
  vec4 sun;                // xyz: unit direction toward the sun (world), w: sun intensity
  vec4 sun_color;          // rgb: sun colour (linear), a: ambient term
  vec4 sky;                // rgb: sky and fog colour (linear), a: fog density per metre
  vec4 albedo_override;    // a > 0: albedo is rgb instead of terrain_albedo() (tests, debugging)
  vec4 camera;             // xy: camera position minus anchor in texels ([0,1) over the terrain), z: camera z in metres, w: metres per texel
  vec4 terrain;            // x: height_m (metres at height 1), y, z: metres per heightfield texel in x, y, w: detail relief in metres (0: off)
  uvec4 hf;                // x, y: heightfield width, height; z: log2 V; w: 0
  int64_t anchor_x;        // camera's level-0 VT texel (floor of camera position / metres per texel)
  int64_t anchor_y;
  uvec4 sampling;          // plain mode: x: log2 of level-0 texels per plain texel; z: log2 of
                           // the plain texture's size in texels; y, w: 0
};

// Where the terrain pass writes feedback: one rotating pixel of every divisor x divisor block
// writes the page id its LOD wants into feedback texel (x / divisor, y / divisor). The separate
// feedback pass (terrain_feedback.frag) renders at 1/divisor resolution with its viewport
// shifted so that texel (x, y) sees the scene point of full-resolution pixel
// (x * divisor + offset_x, y * divisor + offset_y): both variants report the same pixels.
struct TvtFeedbackWrite {  // 32 bytes (std140)
  uint width;              // feedback texels per row (ceil(view width / divisor))
  uint height;
  uint divisor;            // N
  uint offset_x;           // the block's pixel that writes this frame, 0 .. N-1
  uint offset_y;
  uint pad0, pad1, pad2;
};

// Per draw (one chunk at one LOD).
struct TvtTerrainDraw {    // 16 bytes
  ivec2 rel_texel;         // chunk origin minus anchor, level-0 texels (exact int32: anchor is clamped to [-V/2, 3V/2])
  uint quad_texels;        // level-0 texels per LOD-0 grid quad of the chunk
  float skirt_depth_m;     // how far skirt vertices hang below their edge vertex
};

// Heightfield addressing. Heightfield texel i of n (per axis) is a cell centred at
// (i + 1/2) * V / n level-0 texels, so the continuous heightfield coordinate of level-0 texel
// position x is u = x * n / V - 1/2. Returned in 1/256 heightfield texels, exact for
// 0 <= x <= V <= 2^30, n <= 2^16.
TVT_FN int64_t tvt_hf_coord_fp(int64_t x_texel, uint n, uint log2_vt) {
  return (((x_texel * int64_t(n)) << int64_t(TVT_HF_FRAC_BITS)) >> int64_t(log2_vt)) -
         (int64_t(1) << int64_t(TVT_HF_FRAC_BITS - 1u));
}
// Lower bilinear tap (floor, clamped to [0, n-1]) and the tap one above it (clamped).
TVT_FN int tvt_hf_tap0(int64_t u_fp, uint n) {
  const int64_t i = u_fp >> int64_t(TVT_HF_FRAC_BITS);
  return int(i < int64_t(0) ? int64_t(0) : (i > int64_t(n - 1u) ? int64_t(n - 1u) : i));
}
TVT_FN int tvt_hf_tap1(int64_t u_fp, uint n) {
  const int64_t i = (u_fp >> int64_t(TVT_HF_FRAC_BITS)) + int64_t(1);
  return int(i < int64_t(0) ? int64_t(0) : (i > int64_t(n - 1u) ? int64_t(n - 1u) : i));
}
// Bilinear weight of tap1 (in [0,1), a multiple of 1/256: exact in fp32).
TVT_FN float tvt_hf_weight(int64_t u_fp) {
  return float(uint(u_fp & int64_t((1u << TVT_HF_FRAC_BITS) - 1u))) * (1.0f / float(1u << TVT_HF_FRAC_BITS));
}

// Anchor-relative texel position of a grid vertex: exact integer arithmetic, then one
// rounding to float (exact while |result| <= 2^24). The fragment's VT texel coordinate is
// anchor + (this value interpolated), so its error grows with distance from the camera and
// stays a fixed tiny fraction of the texel footprint.
TVT_FN ivec2 tvt_vertex_rel_texel(ivec2 rel_texel, uint i, uint j, uint quad_texels) {
  return rel_texel + ivec2(int(i * quad_texels), int(j * quad_texels));
}

TVT_END

#ifdef __cplusplus
static_assert(sizeof(tvt::gpu::TvtTerrainFrame) == 208);
static_assert(offsetof(tvt::gpu::TvtTerrainFrame, anchor_x) == 176);
static_assert(offsetof(tvt::gpu::TvtTerrainFrame, sampling) == 192);
static_assert(sizeof(tvt::gpu::TvtTerrainDraw) == 16);
#endif
#endif
