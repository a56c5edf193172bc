#include "support/feedback_images.h"


#include "vt/feedback_analysis.h"

namespace tvt::test {

namespace {
uint64_t next(uint64_t& state) {  // splitmix64
  uint64_t z = (state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
}  // namespace

PageId random_page(const VtConfig& vt, uint64_t& state) {
  const uint32_t mip = uint32_t(next(state) % vt.mip_count());
  const uint64_t n = vt.pages_per_side(mip);
  if (next(state) % 10 == 0) return PageId{mip, uint32_t(n - 1), uint32_t(n - 1)};
  return PageId{mip, uint32_t(next(state) % n), uint32_t(next(state) % n)};
}

std::vector<uint32_t> random_feedback_image(const FeedbackImageSpec& spec) {
  uint64_t state = spec.seed * 0x2545f4914f6cdd1dull + 7;
  std::vector<PageId> pool;
  for (uint32_t i = 0; i < spec.distinct; ++i) pool.push_back(random_page(spec.vt, state));
  const auto uniform = [&] { return double(next(state) >> 11) * 0x1.0p-53; };

  const size_t texels = size_t(spec.width) * spec.height;
  std::vector<uint32_t> words(texels * 2);
  uint32_t w0 = 0, w1 = 0;
  for (size_t t = 0; t < texels; ++t) {
    if (t == 0 || spec.run <= 1 || next(state) % spec.run == 0) {
      if (uniform() < spec.empty_fraction) {
        // Empty: mip field 31; the other bits are junk when garbage is on.
        const uint32_t junk = spec.garbage ? uint32_t(next(state)) : 0xffffffffu;
        w0 = junk | 0xf8000000u;
        w1 = spec.garbage ? uint32_t(next(state)) : 0xffffffffu;
      } else {
        const PageId p = pool.empty() ? random_page(spec.vt, state) : pool[next(state) % pool.size()];
        const auto texel = feedback_texel(p);
        w0 = texel[0];
        w1 = texel[1] | (spec.garbage ? uint32_t(next(state)) & 0xf8000000u : 0u);
      }
    }
    words[2 * t] = w0;
    words[2 * t + 1] = w1;
  }
  return words;
}

}  // namespace tvt::test
