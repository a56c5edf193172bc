// Feedback analysis, CPU side (pure C++, no Vulkan): the feedback texel format of
// shaders/shared/feedback_types.h in PageId terms, the CPU reference of the GPU compaction
// (render/feedback_compactor.h), and the result type residency consumes. See docs/feedback.md.
#pragma once
#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "vt/vt_config.h"

namespace tvt {

// Largest page coordinate a feedback texel holds: 2^27 - 1 (every valid VtConfig has <= 2^26
// pages per side).
inline constexpr uint32_t k_feedback_max_coord = (1u << 27) - 1u;
// Largest mip a feedback texel holds; mip field 31 marks an empty texel.
inline constexpr uint32_t k_feedback_max_mip = 30;
// Both words of an empty texel (sky, no terrain): the clear value of feedback targets.
inline constexpr std::array<uint32_t, 2> k_feedback_empty_texel = {0xffffffffu, 0xffffffffu};

// The two words of the feedback texel naming `page`. Fatal if page.mip > 30 or a coordinate
// exceeds k_feedback_max_coord (is_valid(config, page) implies neither).
std::array<uint32_t, 2> feedback_texel(const PageId& page);
// True when the texel is empty (its mip field is 31).
bool feedback_texel_empty(uint32_t word0);
// The page a non-empty texel names (reserved bits 27..31 of word1 are ignored).
PageId feedback_texel_page(uint32_t word0, uint32_t word1);

// Counts over one feedback image.
struct FeedbackStats {
  uint64_t texels = 0;        // all texels
  uint64_t empty_texels = 0;  // texels naming no page
};

// CPU reference of the GPU compaction: every distinct page named by the texels of `words`
// (two words per texel, so words.size() must be even) with the number of texels naming it,
// sorted by PageId. Counts sum to the number of non-empty texels.
std::vector<std::pair<PageId, uint32_t>> compact_feedback(std::span<const uint32_t> words,
                                                          FeedbackStats* stats = nullptr);

// One frame's compacted feedback as the residency code sees it (render/feedback_compactor.h
// produces it from the GPU, compact_feedback() from the CPU).
struct FeedbackResult {
  uint64_t frame = 0;                             // frame number the feedback was rendered in
  std::vector<std::pair<PageId, uint32_t>> pages; // distinct pages with texel counts, sorted by PageId
  bool overflow = false;                          // some texels found no table slot (pages incomplete)
  uint32_t overflow_texels = 0;                   // non-empty texels not counted in `pages`
};

}  // namespace tvt
