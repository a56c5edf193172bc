// Push constants of the Vulkan-context test kernels (test_fill.comp, test_image_pattern.comp),
// shared by GLSL and tests/gpu_vk_context.cpp. The CPU references live in that test file.
#ifndef TVT_SHARED_TEST_TYPES_H
#define TVT_SHARED_TEST_TYPES_H
#include "bridge.h"

TVT_BEGIN

TVT_CONST uint TVT_TEST_FILL_GROUP = 64u;   // test_fill.comp workgroup size (invocations)
TVT_CONST uint TVT_TEST_IMAGE_GROUP = 8u;   // test_image_pattern.comp workgroup edge (texels)

struct TvtTestFillPush {   // 8 bytes
  uint count;              // number of uints to write
  uint xor_value;          // values[i] = i * i ^ xor_value (mod 2^32)
};

struct TvtTestImagePush {  // 16 bytes
  uint width;              // image size in texels
  uint height;
  uint layers;
  uint salt;               // mixed into every texel (see test_image_texel)
};

// Texel (x, y, layer) of the test image as RGBA8 bytes packed little-endian (R in bits 0..7).
TVT_FN uint test_image_texel(uint x, uint y, uint layer, uint salt) {
  uint r = (x * 7u + salt) & 255u;
  uint g = (y * 13u + layer * 101u) & 255u;
  uint b = (x ^ y ^ salt) & 255u;
  uint a = (layer * 85u + x + y) & 255u;
  return r | (g << 8) | (b << 16) | (a << 24);
}

TVT_END

#ifdef __cplusplus
static_assert(sizeof(tvt::gpu::TvtTestFillPush) == 8);
static_assert(sizeof(tvt::gpu::TvtTestImagePush) == 16);
#endif
#endif
