// Internal to compose/: float images with channel names and string metadata, for files whose
// channels are read by name (the FBPB meta-texture). Same checks as compose/image.h readers
// (file named in every error, size limits, non-finite texels rejected) and the same atomic
// write (temporary file in the target folder, then rename).
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "compose/image.h"
#include "vt/result.h"

namespace tvt::detail {

using StringMetadata = std::vector<std::pair<std::string, std::string>>;

struct NamedFloatImage {
  ImageF image;
  std::vector<std::string> channel_names;  // one per channel, in the order the file reports them
  StringMetadata metadata;                 // every string attribute of the file
};

// Largest accepted width or height of any image file, texels.
inline constexpr int k_max_image_side = 16384;
// Most channels of any image file (terravt's own meta-textures have 8; a header may claim
// thousands), and most bytes its texels take as float: a 16384^2 RGBA image, 4 GiB. A file
// beyond either is refused from its header, before anything is allocated.
inline constexpr int k_max_image_channels = 64;
inline constexpr uint64_t k_max_image_float_bytes = 16384ull * 16384ull * 4ull * sizeof(float);

Result<NamedFloatImage> read_named_float_image(const std::string& path);

// channel_names: empty (format defaults) or one per channel. The format comes from the
// extension of `path`.
Status write_named_float_image(const std::string& path, const ImageF& image,
                               const std::vector<std::string>& channel_names, const StringMetadata& metadata);

}  // namespace tvt::detail
