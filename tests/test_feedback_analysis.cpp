// CPU side of feedback: texel format round trips, and compact_feedback() against a naive count.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "support/feedback_images.h"
#include "vt/feedback_analysis.h"

using namespace tvt;

namespace {

VtConfig vt_config(uint32_t log2_size, uint32_t page_texels) {
  VtConfig c;
  c.log2_size = log2_size;
  c.page_texels = page_texels;
  c.border_texels = std::min(4u, page_texels / 4);
  return c;
}

// Naive reference of the reference: a std::map over decoded pages.
std::vector<std::pair<PageId, uint32_t>> naive_count(const std::vector<uint32_t>& words) {
  std::map<PageId, uint32_t> counts;
  for (size_t i = 0; i < words.size(); i += 2) {
    if ((words[i] >> 27) == 31u) continue;
    ++counts[PageId{words[i] >> 27, words[i] & 0x07ffffffu, words[i + 1] & 0x07ffffffu}];
  }
  return {counts.begin(), counts.end()};
}

}  // namespace

TEST(FeedbackTexel, RoundTripsEveryMipAtTheFarCornerUpTo2To30) {
  for (const VtConfig& c : {vt_config(24, 16), vt_config(24, 128), vt_config(30, 16), vt_config(10, 128)}) {
    ASSERT_TRUE(validate(c, "t").ok());
    for (uint32_t mip = 0; mip < c.mip_count(); ++mip) {
      const uint32_t last = uint32_t(c.pages_per_side(mip) - 1);
      for (const PageId id : {PageId{mip, last, last}, PageId{mip, 0, last}, PageId{mip, last, 0}, PageId{mip, 0, 0}}) {
        ASSERT_TRUE(is_valid(c, id));
        const auto t = feedback_texel(id);
        EXPECT_FALSE(feedback_texel_empty(t[0])) << to_string(id);
        EXPECT_EQ(feedback_texel_page(t[0], t[1]), id);
        // No valid page's texel collides with the empty clear value or the table's EMPTY word.
        EXPECT_NE(t[0], 0xffffffffu);
        EXPECT_NE(t[1], 0xffffffffu);
      }
    }
  }
  EXPECT_TRUE(feedback_texel_empty(k_feedback_empty_texel[0]));
  const auto widest = feedback_texel(PageId{k_feedback_max_mip, k_feedback_max_coord, k_feedback_max_coord});
  EXPECT_FALSE(feedback_texel_empty(widest[0]));
  EXPECT_EQ(feedback_texel_page(widest[0], widest[1]), (PageId{30, k_feedback_max_coord, k_feedback_max_coord}));
}

TEST(FeedbackTexel, ReservedBitsOfWordOneAreIgnored) {
  const PageId id{3, 12345, 67890};
  const auto t = feedback_texel(id);
  EXPECT_EQ(feedback_texel_page(t[0], t[1] | 0xf8000000u), id);
}

TEST(CompactFeedback, CountsAHandMadeImage) {
  const auto a = feedback_texel(PageId{0, 5, 7});
  const auto b = feedback_texel(PageId{2, 1, 1});
  const auto c = feedback_texel(PageId{0, 5, 6});
  const auto e = k_feedback_empty_texel;
  // a a e b c a e e b(with reserved junk) e-with-junk
  const std::vector<uint32_t> words = {a[0], a[1], a[0], a[1], e[0], e[1], b[0], b[1], c[0], c[1],
                                       a[0], a[1], e[0], e[1], e[0], e[1], b[0], b[1] | 0x40000000u,
                                       0xf8000123u, 0x12345678u};
  FeedbackStats stats;
  const auto got = compact_feedback(words, &stats);
  const std::vector<std::pair<PageId, uint32_t>> want = {
      {PageId{0, 5, 6}, 1}, {PageId{0, 5, 7}, 3}, {PageId{2, 1, 1}, 2}};
  EXPECT_EQ(got, want);
  EXPECT_EQ(stats.texels, 10u);
  EXPECT_EQ(stats.empty_texels, 4u);
}

TEST(CompactFeedback, EmptyImagesGiveNoPages) {
  FeedbackStats stats;
  EXPECT_TRUE(compact_feedback({}, &stats).empty());
  EXPECT_EQ(stats.texels, 0u);
  const std::vector<uint32_t> sky(2 * 64, 0xffffffffu);
  EXPECT_TRUE(compact_feedback(sky, &stats).empty());
  EXPECT_EQ(stats.empty_texels, 64u);
}

TEST(CompactFeedback, MatchesANaiveCountOnRandomImages) {
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    test::FeedbackImageSpec spec;
    spec.width = 320;
    spec.height = 180;
    spec.vt = vt_config(24, 16);
    spec.distinct = seed % 2 ? 50 : 0;
    spec.run = seed % 3 == 0 ? 8 : 1;
    spec.seed = seed;
    const auto words = test::random_feedback_image(spec);
    FeedbackStats stats;
    const auto got = compact_feedback(words, &stats);
    EXPECT_EQ(got, naive_count(words)) << "seed " << seed;
    uint64_t sum = 0;
    for (size_t i = 0; i < got.size(); ++i) {
      sum += got[i].second;
      EXPECT_GT(got[i].second, 0u);
      if (i > 0) {
        EXPECT_LT(got[i - 1].first, got[i].first);  // sorted and unique
      }
    }
    EXPECT_EQ(sum, stats.texels - stats.empty_texels);
    EXPECT_GT(stats.empty_texels, 0u);
    EXPECT_GT(sum, 0u);
  }
}
