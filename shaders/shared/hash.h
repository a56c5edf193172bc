// Integer hashing for every random decision (docs/composition.md): a pure function of terrain-space
// integer coordinates and a salt, bit-identical in GLSL and C++, independent of page, mip
// and time. No float hashing, no noise textures.
#ifndef TVT_SHARED_HASH_H
#define TVT_SHARED_HASH_H
#include "bridge.h"

TVT_BEGIN

// "lowbias32" finaliser (C. Wellons, hash-prospector): full avalanche on 32-bit input.
TVT_FN uint tvt_mix32(uint x) {
  x ^= x >> 16u;
  x *= 0x7feb352du;
  x ^= x >> 15u;
  x *= 0x846ca68bu;
  x ^= x >> 16u;
  return x;
}

// Hash of a signed 64-bit coordinate pair and a salt. Every word of the input goes through
// its own mixing round, so (x, y) and (y, x) and neighbouring salts all decorrelate.
TVT_FN uint tvt_hash_coord(int64_t x, int64_t y, uint salt) {
  uint h = tvt_mix32(salt ^ 0x9e3779b9u);
  h = tvt_mix32(h ^ uint(x));
  h = tvt_mix32(h ^ uint(x >> 32));
  h = tvt_mix32(h ^ uint(y) ^ 0x85ebca6bu);
  h = tvt_mix32(h ^ uint(y >> 32));
  return h;
}

// r in (0, 1], exactly representable in fp32: r = ((h >> 8) + 1) * 2^-24 (docs/composition.md).
TVT_FN float tvt_rand01(uint h) { return float((h >> 8u) + 1u) * 5.9604644775390625e-8f; }

// Salts: derived from the scene seed and small integers (material index, layer, purpose).
TVT_FN uint tvt_salt(uint seed, uint material, uint layer, uint purpose) {
  return tvt_mix32(seed ^ tvt_mix32(material * 0x9e3779b1u + layer * 0x85ebca77u + purpose * 0xc2b2ae3du));
}

// floor(a / b) and the matching non-negative remainder for b > 0.
// One division: the remainder comes from a multiplication (a 64-bit division is a long
// software sequence on GPUs, and div and mod were two of them).
TVT_FN int64_t tvt_floor_div(int64_t a, int64_t b) {
  int64_t q = a / b;
  if (a - q * b < int64_t(0)) q -= int64_t(1);
  return q;
}
TVT_FN int64_t tvt_floor_mod(int64_t a, int64_t b) { return a - tvt_floor_div(a, b) * b; }
// The same in 32 bits, for operands known to fit (several times cheaper on GPUs).
TVT_FN int tvt_floor_div32(int a, int b) {
  int q = a / b;
  if (a - q * b < 0) q -= 1;
  return q;
}

TVT_END
#endif
