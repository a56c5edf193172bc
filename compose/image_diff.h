// Differences between two 8-bit images of the same size (RGB; alpha ignored): what tests and
// comparisons report about two renders of the same frame.
#pragma once
#include <cstdint>

#include "compose/image.h"

namespace tvt {

struct ImageDiff {
  double psnr_db = 0;         // over RGB; +infinity when identical (reported as 99 by printers)
  uint32_t max_abs = 0;       // largest channel difference, 0..255
  uint64_t pixels_differing = 0;
  uint64_t pixels = 0;
  bool identical() const { return max_abs == 0; }
};

// Fatal if the sizes differ (callers render both at one size).
ImageDiff compare_images(const ImageRGBA8& a, const ImageRGBA8& b);

}  // namespace tvt
