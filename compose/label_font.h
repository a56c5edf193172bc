// A tiny 5x7 bitmap font for labelling comparison images (lower-case letters, digits, a few
// symbols); unknown characters draw as a box.
#pragma once
#include <string_view>

#include "compose/image.h"

namespace tvt {

// Draws `text` with its top-left corner at (x, y), each font pixel `scale` image pixels,
// in colour rgb, on a dark backing box. Clipped to the image.
void draw_label(ImageRGBA8& image, int x, int y, std::string_view text, int scale = 2);

}  // namespace tvt
