#include "vt/feedback_analysis.h"

#include <algorithm>

#include "shaders/shared/feedback_types.h"

namespace tvt {

std::array<uint32_t, 2> feedback_texel(const PageId& page) {
  TVT_CHECK(page.mip <= k_feedback_max_mip);
  TVT_CHECK(page.x <= k_feedback_max_coord && page.y <= k_feedback_max_coord);
  return {gpu::tvt_feedback_word0(page.mip, page.x), gpu::tvt_feedback_word1(page.y)};
}

bool feedback_texel_empty(uint32_t word0) { return gpu::tvt_feedback_is_empty(word0); }

PageId feedback_texel_page(uint32_t word0, uint32_t word1) {
  return PageId{gpu::tvt_feedback_mip(word0), gpu::tvt_feedback_x(word0), gpu::tvt_feedback_y(word1)};
}

std::vector<std::pair<PageId, uint32_t>> compact_feedback(std::span<const uint32_t> words, FeedbackStats* stats) {
  TVT_CHECK(words.size() % 2 == 0);
  // Key = (word0, masked word1) as one uint64: its order is PageId order (mip, then x, then y),
  // because word0 = x | mip << 27 with x < 2^27.
  std::vector<uint64_t> keys;
  keys.reserve(words.size() / 2);
  for (size_t i = 0; i < words.size(); i += 2) {
    if (feedback_texel_empty(words[i])) continue;
    keys.push_back(uint64_t(words[i]) << 32 | (words[i + 1] & gpu::TVT_FEEDBACK_COORD_MASK));
  }
  if (stats) {
    stats->texels = words.size() / 2;
    stats->empty_texels = stats->texels - keys.size();
  }
  std::sort(keys.begin(), keys.end());
  std::vector<std::pair<PageId, uint32_t>> out;
  for (size_t i = 0; i < keys.size();) {
    size_t j = i + 1;
    while (j < keys.size() && keys[j] == keys[i]) ++j;
    out.emplace_back(feedback_texel_page(uint32_t(keys[i] >> 32), uint32_t(keys[i])), uint32_t(j - i));
    i = j;
  }
  return out;
}

}  // namespace tvt
