#include "tools/cli_common.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "json/json_check.h"
#include "compose/scene.h"
#include "app/flythrough.h"
#include "streaming/file_io.h"

namespace tvt::cli {

Result<SceneAssets> load_scene_and_assets(const std::string& path, const std::string& hex) {
  Result<SceneDesc> desc = path.empty() ? Result<SceneDesc>(default_scene()) : load_scene_file(path);
  if (!desc) return desc.error();
  if (hex != "scene")
    for (MaterialDesc& m : desc.value().materials) m.hex.enabled = hex == "on";
  return load_scene_assets(desc.value());
}

Result<CameraChoice> choose_camera(const std::string& camera_file, const SceneAssets& assets) {
  std::optional<CameraFile> file;
  if (!camera_file.empty()) {
    auto loaded = load_camera_file(camera_file);
    if (!loaded) return make_error("--camera: " + loaded.error().message);
    file = std::move(loaded.value());
  }
  // The renderer's heights, on the CPU.
  const TerrainDesc& terrain = assets.desc.terrain;
  auto mesh = TerrainMesh::create(assets.heightfield, terrain.extent_m, terrain.height_m, assets.desc.vt);
  if (!mesh) return mesh.error();
  auto ground = std::make_unique<TerrainMesh>(std::move(mesh.value()));
  auto path = flythrough_path(assets, *ground, file ? &*file : nullptr);  // holds a pointer to *ground
  if (!path) return make_error("--camera: " + path.error().message);
  const Camera lens = file ? file->lens : Camera{};
  return CameraChoice{std::move(file), std::move(ground), std::move(path.value()), lens};
}

std::string CameraChoice::describe() const {
  const size_t keys = path.keys().size(), cuts = path.cut_times().size();
  char text[96];
  std::snprintf(text, sizeof(text), " (%zu key%s, %.1f s, %zu cut%s)", keys, keys == 1 ? "" : "s",
                path.end_time() - path.start_time(), cuts, cuts == 1 ? "" : "s");
  return (file ? file->source_path : std::string("built-in flythrough")) + text;
}

Result<std::unique_ptr<vk::Context>> gpu_context(const std::string& device) {
  // The library reads no environment variable: the CLI turns TERRAVT_DEVICE and
  // TERRAVT_VALIDATION into options, and prints what the device reports.
  vk::ContextOptions options;
  const char* env_device = std::getenv("TERRAVT_DEVICE");
  options.device = !device.empty() ? device : (env_device ? env_device : "");
  options.device_source = !device.empty() ? "--gpu" : "TERRAVT_DEVICE";
  const char* env_validation = std::getenv("TERRAVT_VALIDATION");
  options.validation = env_validation && *env_validation && std::strcmp(env_validation, "0") != 0;
  options.validation_source = "TERRAVT_VALIDATION=1";
  options.log = [](terravt::LogLevel, std::string_view message) {
    std::fprintf(stderr, "terravt: %.*s\n", int(message.size()), message.data());
  };
  return vk::Context::create(options);
}

Status write_text_file(const std::string& path, const std::string& text) {
  return fileio::write_file_durable(path, text.data(), text.size());
}

CLI::Validator finite_range(double lo, double hi) {
  const std::string range = "[" + json_check::show_number(lo) + ", " + json_check::show_number(hi) + "]";
  return CLI::Validator(
      [lo, hi, range](std::string& text) -> std::string {
        double v = 0;
        if (!CLI::detail::lexical_cast(text, v)) return "must be a number in " + range + ", got '" + text + "'";
        if (!std::isfinite(v) || v < lo || v > hi) return "must be a finite number in " + range + ", got " + text;
        return {};
      },
      "FLOAT in " + range);
}

void add_mip_strategy_option(CLI::App& app, std::string& text) {
  app.add_option("--mip-strategy", text,
                 "How pages of mip >= 1 are composed: direct (one sample per texel), prefiltered (one sample per "
                 "texel with the expected coverage of patches, features and blend-map heights smaller than it) or "
                 "supersample:S (up to SxS samples per texel, S = 2..64, a power of two; never more than the "
                 "level-0 texels covered)")
      ->check(CLI::Validator(
          [](std::string& value) -> std::string {
            auto s = mip_strategy_from_string(value);
            return s ? std::string() : s.error().message;
          },
          "direct|prefiltered|supersample:S"))
      ->capture_default_str();
}

MipStrategy parsed_mip_strategy(const std::string& text) {
  auto s = mip_strategy_from_string(text);
  return s ? s.value() : MipStrategy{};  // the option's check refused anything else
}

void add_hex_option(CLI::App& app, std::string& text) {
  app.add_option("--hex", text,
                 "Hex-tiling, the anti-repetition mode: scene (as each material says), on (every material but FBPB "
                 "layers above the base) or off")
      ->check(CLI::IsMember({"scene", "on", "off"}))
      ->capture_default_str();
}

std::optional<std::string> not_a_regular_file(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return path + ": " + (errno == ENOENT || errno == ENOTDIR ? "file not found" : fileio::errno_text(errno));
  if (!S_ISREG(st.st_mode)) return path + ": is " + json_check::file_kind(st.st_mode) + ", not a regular file";
  return std::nullopt;
}

CLI::Validator regular_file() {
  return CLI::Validator([](std::string& path) { return not_a_regular_file(path).value_or(std::string()); }, "FILE");
}

std::optional<std::string> output_file_problem(const std::string& path, bool overwrite) {
  namespace fs = std::filesystem;
  if (path.empty()) return "empty path";
  std::error_code ec;
  const fs::path p(path);
  const fs::path folder = p.has_parent_path() ? p.parent_path() : fs::path(".");
  if (!fs::is_directory(folder, ec)) return "folder does not exist: " + folder.string();
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return std::nullopt;  // nothing there: a new file
  struct stat target {};
  const bool followed = ::stat(path.c_str(), &target) == 0;  // a dangling link is replaced like a file
  if (!S_ISLNK(st.st_mode) || followed) {
    const unsigned mode = S_ISLNK(st.st_mode) ? target.st_mode : st.st_mode;
    if (!S_ISREG(mode))
      return path + " is " + json_check::file_kind(mode) + "; terravt writes only regular files and never replaces anything else";
  }
  if (!overwrite) return path + " exists; pass --overwrite to replace it";
  return std::nullopt;
}

Status check_output_file(const std::string& flag, const std::string& path, bool overwrite) {
  if (auto why = output_file_problem(path, overwrite)) return make_error(flag + ": " + *why);
  return Ok{};
}

CLI::Validator output_file() {
  return CLI::Validator([](std::string& path) { return output_file_problem(path, true).value_or(std::string()); }, "FILE");
}

namespace {

// The same file: one device and inode where both exist, else the same normalised absolute path.
bool same_file(const std::string& a, const std::string& b) {
  namespace fs = std::filesystem;
  struct stat sa {}, sb {};
  const bool a_exists = ::stat(a.c_str(), &sa) == 0, b_exists = ::stat(b.c_str(), &sb) == 0;
  if (a_exists && b_exists) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
  if (a_exists != b_exists) return false;
  std::error_code ea, eb;
  const fs::path pa = fs::weakly_canonical(fs::absolute(fs::path(a), ea), ea);
  const fs::path pb = fs::weakly_canonical(fs::absolute(fs::path(b), eb), eb);
  return !ea && !eb && pa == pb;
}

}  // namespace

std::optional<std::string> output_collision(const FlaggedPaths& outputs, const FlaggedPaths& inputs) {
  for (const auto& [flag, output] : outputs) {
    if (output.empty()) continue;
    // The files a run writes beside an output and removes again (its lock, a bake's .partial)
    // would take an input with them too.
    for (const std::string& written : {output, output + ".lock", output + ".partial"})
      for (const auto& [input_flag, input] : inputs)
        if (!input.empty() && same_file(written, input))
          return flag + " " + output + ": " +
                 (written == output ? "is" : "its " + written + " (written and removed by the run) is") + " the " +
                 input_flag + " file; an output never replaces an input";
    for (const auto& [other_flag, other] : outputs)
      if (!other.empty() && other_flag != flag && same_file(output, other))
        return flag + " " + output + ": is also " + other_flag + "; two outputs cannot share a file";
  }
  return std::nullopt;
}

FlaggedPaths scene_inputs(const SceneDesc& scene) {
  FlaggedPaths inputs;
  for (const auto& [field, path] : scene_files(scene)) inputs.emplace_back("scene's " + field, path);
  return inputs;
}

std::optional<std::string> output_in_scene(const FlaggedPaths& outputs, const SceneDesc& scene) {
  return output_collision(outputs, scene_inputs(scene));
}

namespace {

// The normalised absolute path of a folder, links resolved (it need not exist).
std::filesystem::path folder_place(const std::filesystem::path& folder) {
  std::error_code ec;
  return std::filesystem::weakly_canonical(std::filesystem::absolute(folder, ec), ec);
}

// `path` in its folder's place with its own last name, unresolved: where the name itself lies,
// a link or not.
std::filesystem::path own_place(const std::filesystem::path& path) {
  std::error_code ec;
  const std::filesystem::path absolute = std::filesystem::absolute(path, ec);
  return folder_place(absolute.parent_path()) / absolute.filename();
}

// Whether `place` (normalised) lies directly in `folder` (normalised) under a name `written` accepts.
bool written_at(const std::filesystem::path& place, const std::filesystem::path& folder,
                bool (*written)(const std::filesystem::path&)) {
  return place.parent_path() == folder && written(place.filename());
}

}  // namespace

bool written_into_folder(const std::string& path, const std::string& folder, bool (*written)(const std::filesystem::path&)) {
  return written_at(own_place(path), folder_place(folder), written);
}

std::optional<std::string> input_in_output_folder(const std::string& flag, const std::string& folder,
                                                  bool (*written)(const std::filesystem::path&), const FlaggedPaths& inputs) {
  const std::filesystem::path place = folder_place(folder);
  for (const auto& [input_flag, input] : inputs) {
    if (input.empty()) continue;
    // The input's own name in the folder (a file or a link: the scene would lose its name), or
    // the file it finally resolves to there (removing that loses the data). A hard link
    // elsewhere to a file in the folder keeps its data and is not refused.
    std::error_code ec;
    const std::filesystem::path own = own_place(input), resolved = std::filesystem::canonical(input, ec);
    std::filesystem::path name;
    if (written_at(own, place, written)) name = own.filename();
    else if (!ec && written_at(resolved, place, written)) name = resolved.filename();
    else continue;
    return flag + " " + folder + ": its " + name.string() + " (an earlier run's output, which this run removes or replaces) is the " +
           input_flag + " file; an output never replaces an input";
  }
  return std::nullopt;
}

std::string check_image_output(const std::string& flag, const std::string& path, bool must_be_exr) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  const fs::path folder = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) return flag + " " + path + ": folder '" + folder.string() + "' does not exist";
  if (fs::is_directory(p, ec)) return flag + " " + path + ": is a folder";
  // Never replaced by a file: a FIFO, socket or device node (as root, /dev/null) stays what it is.
  if (struct stat st {}; ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    return flag + " " + path + ": is " + json_check::file_kind(st.st_mode) + "; terravt writes only regular files";
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (must_be_exr && ext != ".exr") return flag + " " + path + ": the meta-texture is an OpenEXR file; use .exr";
  if (!must_be_exr && (ext.empty() || !OIIO::ImageOutput::create(path)))
    return flag + " " + path + ": no image writer for extension '" + ext + "' (use .png, .exr, .tif ...)";
  return {};
}

Result<OutputLock> OutputLock::acquire(const std::string& flag, const std::string& output) {
  namespace fs = std::filesystem;
  std::error_code ec;
  // One lock per output however it is spelt ("out", "./out/", a link to it).
  fs::path target = fs::absolute(fs::path(output), ec).lexically_normal();
  if (!target.has_filename()) target = target.parent_path();
  target = fs::weakly_canonical(target, ec);
  if (ec || target == target.root_path()) return make_error(flag + ": cannot use " + output + " as an output");
  // The folders made for the output, deepest first: removed again when the run leaves them empty.
  std::vector<std::string> made;
  for (fs::path p = target.parent_path(); !p.empty() && p != p.root_path() && !fs::exists(p, ec); p = p.parent_path())
    made.push_back(p.string());
  fs::create_directories(target.parent_path(), ec);
  if (ec) return make_error(flag + ": cannot create folder " + target.parent_path().string() + " (" + ec.message() + ")");
  std::string lock_path = target.string() + ".lock";
  for (int attempt = 0; attempt < 16; ++attempt) {
    fileio::UniqueFd fd(::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644));
    // An existing folder whose parent is not writable (`--out .` in a read-only parent): the
    // lock goes inside it. Every run on it meets the same permissions, so they agree on the file.
    if (fd.get() < 0 && (errno == EACCES || errno == EROFS || errno == EPERM) && attempt == 0 &&
        fs::is_directory(target, ec)) {
      lock_path = (target / ".terravt.lock").string();
      fd = fileio::UniqueFd(::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644));
    }
    if (fd.get() < 0) return make_error(flag + ": cannot create lock file " + lock_path + ": " + fileio::errno_text(errno));
    if (auto s = fileio::lock_exclusive(fd.get(), lock_path); !s)
      return make_error(flag + ": " + output + " is in use: " + s.error().message +
                        "; wait for that run to finish or choose another " + flag);
    // The previous holder removes the file as it lets go: if that happened after open(), this
    // lock is on a removed file and a third run could lock a new one; take the new one instead.
    struct stat held {}, named {};
    if (::fstat(fd.get(), &held) == 0 && ::lstat(lock_path.c_str(), &named) == 0 && held.st_dev == named.st_dev &&
        held.st_ino == named.st_ino)
      return OutputLock(lock_path, std::move(fd), std::move(made));
  }
  return make_error(flag + ": cannot lock " + lock_path + ": it keeps being replaced");
}

OutputLock::~OutputLock() {
  if (fd_.get() < 0) return;  // moved from
  ::unlink(path_.c_str());  // before unlocking, so no later holder's file is removed
  // rmdir removes only empty folders: those the run wrote into (or another run uses) stay.
  for (const std::string& dir : made_) ::rmdir(dir.c_str());
}

int fail(const char* command, const std::string& message, int code) {
  std::fprintf(stderr, "terravt %s: %s\n", command, message.c_str());
  return code;
}

}  // namespace tvt::cli
