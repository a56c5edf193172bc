#include "compose/image_diff.h"

#include <cmath>
#include <cstdlib>
#include <limits>

#include "vt/result.h"

namespace tvt {

ImageDiff compare_images(const ImageRGBA8& a, const ImageRGBA8& b) {
  TVT_CHECK(a.width == b.width && a.height == b.height);
  ImageDiff d;
  d.pixels = uint64_t(a.width) * uint64_t(a.height);
  double se = 0;
  for (uint64_t i = 0; i < d.pixels; ++i) {
    bool differs = false;
    for (int c = 0; c < 3; ++c) {
      const int e = std::abs(int(a.texels[i * 4 + c]) - int(b.texels[i * 4 + c]));
      se += double(e) * e;
      d.max_abs = std::max(d.max_abs, uint32_t(e));
      differs = differs || e != 0;
    }
    d.pixels_differing += differs ? 1 : 0;
  }
  d.psnr_db = se == 0 ? std::numeric_limits<double>::infinity()
                      : 10.0 * std::log10(255.0 * 255.0 * 3.0 * double(d.pixels) / se);
  return d;
}

}  // namespace tvt
