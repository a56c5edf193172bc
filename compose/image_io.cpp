// Image files through OpenImageIO 2.4 (compose/image.h). Every error starts with the file name.
// Colour values are taken as stored: no colour-space conversion, and alpha is never
// (un)premultiplied, because for materials A is the height / blend map, not coverage.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <new>
#include <string>
#include <system_error>
#include <vector>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/lsan_interface.h>
#endif

#include "compose/image.h"
#include "compose/image_io_detail.h"
#include "streaming/file_io.h"

namespace tvt {

namespace fs = std::filesystem;

namespace {

// OIIO messages may span lines; keep error text on one line.
std::string one_line(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text.empty() ? std::string("no detail from OpenImageIO") : text;
}

std::string texel_text(int x, int y, int c) {
  return "texel (" + std::to_string(x) + ", " + std::to_string(y) + ") channel " + std::to_string(c);
}

// Around OpenImageIO's decoding only, in sanitized builds (scripts/test-sanitized.sh): LeakSanitizer
// ignores what is allocated in the scope. OpenImageIO 2.4's PNG reader leaks one error string per
// truncated or corrupt file (PNGInput::PngReadCallback copies the message, then libpng longjmps
// past its destructor), and no tests/lsan.supp entry can match that leak: the sanitizer's fast
// unwinder stops in libstdc++, before OpenImageIO's frames. Only OpenImageIO code runs inside (the
// ImageInput that open() returns is exempt too; terravt holds it in a unique_ptr).
struct DependencyLeaksIgnored {
#if defined(__SANITIZE_ADDRESS__)
  __lsan::ScopedDisabler disabler;
#endif
};

// Opens `path` for reading and checks what every reader needs: exists, readable, a supported
// format, flat 2D, non-zero and not too large.
Result<std::unique_ptr<OIIO::ImageInput>> open_input(const std::string& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) return make_error(path + ": file not found");
  if (fs::is_directory(status)) return make_error(path + ": is a directory, not an image file");
  // Checked before anything opens it: a FIFO would block the reader, a device never end.
  if (!fs::is_regular_file(status)) return make_error(path + ": is not a regular file, not an image file");
  if (!std::ifstream(path, std::ios::binary)) return make_error(path + ": cannot be opened for reading");

  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);  // keep colour and alpha exactly as stored
  std::unique_ptr<OIIO::ImageInput> in;
  {
    [[maybe_unused]] DependencyLeaksIgnored scope;
    in = OIIO::ImageInput::open(path, &config);
  }
  if (!in) return make_error(path + ": not an image in a supported format (" + one_line(OIIO::geterror()) + ")");

  const OIIO::ImageSpec& spec = in->spec();
  if (spec.deep) return make_error(path + ": deep images are not supported");
  if (spec.depth > 1) return make_error(path + ": volume images are not supported");
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
    return make_error(path + ": zero-size image (" + std::to_string(spec.width) + " x " + std::to_string(spec.height) +
                      " texels, " + std::to_string(spec.nchannels) + " channels)");
  if (spec.width > detail::k_max_image_side || spec.height > detail::k_max_image_side)
    return make_error(path + ": image too large (" + std::to_string(spec.width) + " x " + std::to_string(spec.height) +
                      " texels; at most " + std::to_string(detail::k_max_image_side) + " per side)");
  if (spec.nchannels > detail::k_max_image_channels)
    return make_error(path + ": " + std::to_string(spec.nchannels) + " channels; at most " +
                      std::to_string(detail::k_max_image_channels) + " are accepted");
  if (const uint64_t bytes = uint64_t(spec.width) * uint64_t(spec.height) * uint64_t(spec.nchannels) * sizeof(float);
      bytes > detail::k_max_image_float_bytes)
    return make_error(path + ": image too large (" + std::to_string(spec.width) + " x " + std::to_string(spec.height) +
                      " texels x " + std::to_string(spec.nchannels) + " channels = " + std::to_string(bytes >> 20) +
                      " MiB as float; at most " + std::to_string(detail::k_max_image_float_bytes >> 20) + " MiB)");
  return in;
}

// Reads every channel of subimage 0, mip 0 as float and rejects non-finite texels.
Result<ImageF> read_all_channels(const std::string& path, OIIO::ImageInput& in) {
  const OIIO::ImageSpec& spec = in.spec();
  ImageF image;
  try {
    image = ImageF(spec.width, spec.height, spec.nchannels);
  } catch (const std::bad_alloc&) {
    return Error{ErrorKind::out_of_memory, path + ": not enough memory for its " + std::to_string(spec.width) + " x " +
                                               std::to_string(spec.height) + " x " + std::to_string(spec.nchannels) +
                                               " texels as float"};
  }
  bool read = false;
  {
    [[maybe_unused]] DependencyLeaksIgnored scope;
    read = in.read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.data.data());
  }
  if (!read)
    return make_error(path + ": truncated or corrupt image data (" + one_line(in.geterror()) + ")");
  for (size_t i = 0; i < image.data.size(); ++i) {
    if (std::isfinite(image.data[i])) continue;
    const size_t texel = i / size_t(image.channels);
    const int x = int(texel % size_t(image.width));
    const int y = int(texel / size_t(image.width));
    const int c = int(i % size_t(image.channels));
    return make_error(path + ": non-finite value (" + std::string(std::isnan(image.data[i]) ? "NaN" : "Inf") +
                      ") at " + texel_text(x, y, c) + "; float images must be finite");
  }
  return image;
}

uint8_t unorm8(float value) {
  const float clamped = std::clamp(value, 0.0f, 1.0f);
  return uint8_t(std::lround(clamped * 255.0f));
}

// Writes `data` (described by `spec`, texel type `data_type`) to `path`: OpenImageIO encodes
// the file in memory (its own file writes go through stdio, whose errors it does not always
// see, so a full disk left 0-byte "written" files), then fileio::write_file_durable writes it
// under a temporary name with every write checked, fsyncs and renames it over `path`. A
// failure names the file and the OS error and leaves any earlier file untouched.
Status write_atomically(const std::string& path, OIIO::ImageSpec spec, OIIO::TypeDesc data_type, const void* data) {
  if (path.empty()) return make_error("(empty path): no output file name given");
  const fs::path target(path);
  if (!target.has_extension())
    return make_error(path + ": no file extension, cannot tell which image format to write (use .png, .exr, .tif ...)");
  const fs::path folder = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(folder, ec))
    return make_error(path + ": folder '" + folder.string() + "' does not exist");
  if (fs::is_directory(target, ec)) return make_error(path + ": is a directory, cannot write an image over it");
  // The rename below would replace a FIFO, socket or device node (as root: /dev/null) with a file.
  if (const fs::file_status st = fs::symlink_status(target, ec); fs::exists(st) && !fs::is_regular_file(st) &&
                                                                 !fs::is_symlink(st))
    return make_error(path + ": is not a regular file, cannot write an image over it");

  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(path);
  if (!out)
    return make_error(path + ": unsupported image format '" + target.extension().string() + "' (" +
                      one_line(OIIO::geterror()) + ")");
  if (!out->supports("ioproxy"))
    return make_error(path + ": the '" + target.extension().string() +
                      "' writer cannot encode to memory, so its writes cannot be checked (use .png, .exr, .tif ...)");

  spec.attribute("oiio:UnassociatedAlpha", 1);  // write alpha as given, never un-premultiply
  std::vector<unsigned char> encoded;
  OIIO::Filesystem::IOVecOutput proxy(encoded);
  if (!out->set_ioproxy(&proxy)) return make_error(path + ": cannot encode to memory (" + one_line(out->geterror()) + ")");
  if (!out->open(path, spec)) return make_error(path + ": cannot encode (" + one_line(out->geterror()) + ")");
  if (!out->write_image(data_type, data)) return make_error(path + ": cannot encode texels (" + one_line(out->geterror()) + ")");
  if (!out->close()) return make_error(path + ": cannot finish encoding (" + one_line(out->geterror()) + ")");
  out.reset();
  if (encoded.empty()) return make_error(path + ": OpenImageIO encoded no bytes");
  return fileio::write_file_durable(path, encoded.data(), encoded.size());
}

Status check_size(const std::string& path, int width, int height, size_t values, size_t per_texel) {
  if (width <= 0 || height <= 0)
    return make_error(path + ": refusing to write a zero-size image (" + std::to_string(width) + " x " +
                      std::to_string(height) + ")");
  if (width > detail::k_max_image_side || height > detail::k_max_image_side)
    return make_error(path + ": image too large to write (" + std::to_string(width) + " x " + std::to_string(height) +
                      "; at most " + std::to_string(detail::k_max_image_side) + " per side)");
  if (values != size_t(width) * size_t(height) * per_texel)
    return make_error(path + ": image buffer holds " + std::to_string(values) + " values, expected " +
                      std::to_string(size_t(width) * size_t(height) * per_texel));
  return Ok{};
}

}  // namespace

Result<ImageRGBA8> read_image_rgba8(const std::string& path) {
  auto in = open_input(path);
  if (!in) return in.error();
  auto all = read_all_channels(path, **in);
  if (!all) return all.error();
  const ImageF& src = *all;
  ImageRGBA8 image(src.width, src.height);
  for (int y = 0; y < src.height; ++y) {
    for (int x = 0; x < src.width; ++x) {
      uint8_t* dst = image.at(x, y);
      switch (src.channels) {
        case 1:  // grey
          dst[0] = dst[1] = dst[2] = unorm8(src.at(x, y, 0));
          dst[3] = 255;
          break;
        case 2:  // grey + alpha
          dst[0] = dst[1] = dst[2] = unorm8(src.at(x, y, 0));
          dst[3] = unorm8(src.at(x, y, 1));
          break;
        case 3:
          for (int c = 0; c < 3; ++c) dst[c] = unorm8(src.at(x, y, c));
          dst[3] = 255;
          break;
        default:  // 4 or more: the first four
          for (int c = 0; c < 4; ++c) dst[c] = unorm8(src.at(x, y, c));
          break;
      }
    }
  }
  return image;
}

Result<ImageHeader> read_image_header(const std::string& path) {
  auto in = open_input(path);
  if (!in) return in.error();
  const OIIO::ImageSpec& spec = in.value()->spec();
  return ImageHeader{spec.width, spec.height, spec.nchannels};
}

Result<ImageF> read_image_float(const std::string& path) {
  auto in = open_input(path);
  if (!in) return in.error();
  return read_all_channels(path, **in);
}

Status write_image(const std::string& path, const ImageRGBA8& image) {
  if (auto ok = check_size(path, image.width, image.height, image.texels.size(), 4); !ok) return ok;
  return write_atomically(path, OIIO::ImageSpec(image.width, image.height, 4, OIIO::TypeDesc::UINT8),
                          OIIO::TypeDesc::UINT8, image.texels.data());
}

Status write_image(const std::string& path, const ImageGray8& image) {
  if (auto ok = check_size(path, image.width, image.height, image.texels.size(), 1); !ok) return ok;
  return write_atomically(path, OIIO::ImageSpec(image.width, image.height, 1, OIIO::TypeDesc::UINT8),
                          OIIO::TypeDesc::UINT8, image.texels.data());
}

Status write_image(const std::string& path, const ImageF& image, const std::vector<std::string>& channel_names) {
  return detail::write_named_float_image(path, image, channel_names, {});
}

namespace detail {

Result<NamedFloatImage> read_named_float_image(const std::string& path) {
  auto in = open_input(path);
  if (!in) return in.error();
  auto all = read_all_channels(path, **in);
  if (!all) return all.error();
  NamedFloatImage named;
  named.image = std::move(*all);
  const OIIO::ImageSpec& spec = (*in)->spec();
  named.channel_names.assign(spec.channelnames.begin(), spec.channelnames.end());
  named.channel_names.resize(size_t(spec.nchannels));
  for (const OIIO::ParamValue& attribute : spec.extra_attribs)
    if (attribute.type() == OIIO::TypeDesc::STRING)
      named.metadata.emplace_back(attribute.name().string(), attribute.get_string());
  return named;
}

Status write_named_float_image(const std::string& path, const ImageF& image,
                               const std::vector<std::string>& channel_names, const StringMetadata& metadata) {
  if (image.channels <= 0) return make_error(path + ": image has " + std::to_string(image.channels) + " channels");
  if (auto ok = check_size(path, image.width, image.height, image.data.size(), size_t(image.channels)); !ok) return ok;
  if (!channel_names.empty() && channel_names.size() != size_t(image.channels))
    return make_error(path + ": " + std::to_string(channel_names.size()) + " channel names given for an image with " +
                      std::to_string(image.channels) + " channels");
  OIIO::ImageSpec spec(image.width, image.height, image.channels, OIIO::TypeDesc::FLOAT);
  if (!channel_names.empty()) {
    spec.channelnames = channel_names;
    spec.alpha_channel = -1;  // named channels are data, never coverage
    for (size_t c = 0; c < channel_names.size(); ++c)
      if (channel_names[c] == "A") spec.alpha_channel = int(c);
  }
  for (const auto& [name, value] : metadata) spec.attribute(name, value);
  return write_atomically(path, spec, OIIO::TypeDesc::FLOAT, image.data.data());
}

}  // namespace detail

}  // namespace tvt
