// Seeded random feedback images for the feedback-compaction tests (CPU and GPU): two uint32
// words per texel (shaders/shared/feedback_types.h), row-major.
#pragma once
#include <cstdint>
#include <vector>

#include "vt/vt_config.h"

namespace tvt::test {

struct FeedbackImageSpec {
  uint32_t width = 160;
  uint32_t height = 90;
  VtConfig vt{};                 // pages are drawn from every mip of this VT, uniformly per mip
  uint32_t distinct = 0;         // > 0: texels use a pool of this many random pages; 0: any page
  double empty_fraction = 0.25;  // share of empty texels (sky)
  uint32_t run = 1;              // texels repeat the previous one with probability 1 - 1/run
                                 // (the spatial coherence of real feedback)
  bool garbage = true;           // empty texels and reserved word1 bits carry random junk
  uint64_t seed = 1;
};

// A random page of `vt`; every tenth is at the far corner of its mip (largest x and y).
PageId random_page(const VtConfig& vt, uint64_t& state);
std::vector<uint32_t> random_feedback_image(const FeedbackImageSpec& spec);

}  // namespace tvt::test
