// The coordinate pattern: cache pages whose texels encode their own address, written by
// compose.comp instead of the composition when TvtComposeParams::pattern is
// TVT_COMPOSE_PATTERN_COORDS (tests/gpu_coord_vt.cpp; a debugging aid). One definition for the
// GLSL writer and the C++ decoder.
//
// Texel X, Y of mip m (texels of that mip, after the VT-edge clamp compose.comp applies to
// border texels), as one RGBA8 word:
//   R = 255 * (X & 1)            phase of X: a square wave, so a bilinear sample between two
//   G = 255 * (Y & 1)            neighbours is 255 * (their weight), the sub-texel position
//   B = ((X >> 1) ^ h) & 255     bits 1..8 of X and of Y, scrambled with a hash of the mip and
//   A = ((Y >> 1) ^ h >> 8) & 255  of the 512-texel block (X >> 9, Y >> 9)
// A reader that knows the address to within a few texels recovers it exactly; a texel from the
// wrong mip or the wrong block decodes to noise, one from the wrong place to the wrong address.
#ifndef TVT_SHARED_COMPOSE_COORD_H
#define TVT_SHARED_COMPOSE_COORD_H
#include "bridge.h"
#include "hash.h"

TVT_BEGIN

TVT_CONST int TVT_COMPOSE_PATTERN_NONE = 0;    // the composition (docs/composition.md)
TVT_CONST int TVT_COMPOSE_PATTERN_COORDS = 1;  // tvt_coord_word() of every texel
TVT_CONST int TVT_COORD_BLOCK_SHIFT = 9;       // X >> 9: the block the hash scrambles with

TVT_FN uint tvt_coord_scramble(int mip, int64_t x, int64_t y) {
  return tvt_hash_coord(x >> TVT_COORD_BLOCK_SHIFT, y >> TVT_COORD_BLOCK_SHIFT, 0xc00dbeefu ^ uint(mip));
}

TVT_FN uint tvt_coord_word(int mip, int64_t x, int64_t y) {
  const uint h = tvt_coord_scramble(mip, x, y);
  const uint r = (uint(x) & 1u) * 255u;
  const uint g = (uint(y) & 1u) * 255u;
  const uint b = (uint(x >> 1) ^ h) & 255u;
  const uint a = (uint(y >> 1) ^ (h >> 8u)) & 255u;
  return r | (g << 8u) | (b << 16u) | (a << 24u);
}

TVT_END
#endif
