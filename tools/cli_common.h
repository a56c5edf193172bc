// Helpers shared by the subcommands.
#pragma once
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "compose/packed_scene.h"
#include "compose/scene_assets.h"
#include "terrain/camera_file.h"
#include "terrain/terrain_mesh.h"
#include "gpu/context.h"
#include "streaming/file_io.h"
#include "vt/result.h"

namespace tvt::cli {

// Loads a scene file, or the built-in default scene when `path` is empty, and its assets.
// `hex`: a value add_hex_option() accepted, applied to every material before the assets load
// ("scene" leaves the scene's choices; a store baked or compared so records it in its scene
// identity).
Result<SceneAssets> load_scene_and_assets(const std::string& path, const std::string& hex = "scene");

// The camera path a flythrough command follows: a --camera file, checked and resolved over
// the scene's terrain (so a bad file fails before anything is written), or the built-in
// flythrough.
struct CameraChoice {
  std::optional<CameraFile> file;       // none: the built-in flythrough
  std::unique_ptr<TerrainMesh> ground;  // the terrain `path` stands on (CPU)
  CameraPath path;
  Camera lens;
  std::string describe() const;  // "mine.json (4 keys, 3.0 s, 1 cut)"
};
// Errors start with "--camera: " and name the file and field.
Result<CameraChoice> choose_camera(const std::string& camera_file, const SceneAssets& assets);

// The Vulkan context for a command: `device` (its --gpu flag) or TERRAVT_DEVICE / the best.
Result<std::unique_ptr<vk::Context>> gpu_context(const std::string& device);

// Writes `text` to `path` durably (fileio::write_file_durable): a failed write leaves any
// earlier file untouched. Errors name the path.
Status write_text_file(const std::string& path, const std::string& text);

// CLI11 checks, so every command refuses a bad value up front under the flag's name
// ("--blur: ..."). finite_range: a real number in [lo, hi]; NaN and infinities are refused
// (CLI::Range lets NaN through). regular_file: an existing regular file (CLI::ExistingFile
// also passes FIFOs, devices and sockets, on which a reader blocks or never ends).
CLI::Validator finite_range(double lo, double hi);
CLI::Validator regular_file();
// --mip-strategy (render, bake, compare, compose): direct | prefiltered | supersample:S (compose/packed_scene.h).
void add_mip_strategy_option(CLI::App& app, std::string& text);
// The strategy of a value add_mip_strategy_option() accepted.
MipStrategy parsed_mip_strategy(const std::string& text);
// --hex scene|on|off: hex-tiling (the anti-repetition mode) as each material of the scene
// says, on every material (its scene parameters, else the defaults), or off everywhere.
void add_hex_option(CLI::App& app, std::string& text);

// Why `path` cannot be read as a regular input file ("is a directory", "is a FIFO", ...),
// or nullopt when it can be. Follows symbolic links.
std::optional<std::string> not_a_regular_file(const std::string& path);

// Checked before a command writes the file `path` for `flag`: its folder exists; an existing
// directory, FIFO, socket or device is refused even with --overwrite (a file is never put in
// its place); an existing file (or link) is replaced only with `overwrite`.
Status check_output_file(const std::string& flag, const std::string& path, bool overwrite);
// The same without the flag ("x.json is a FIFO; ..."), or nullopt when `path` may be written.
std::optional<std::string> output_file_problem(const std::string& path, bool overwrite);
// CLI11 check for an output file that is simply replaced (bench --json): output_file_problem()
// with overwrite, so a bad path fails before the run instead of after it.
CLI::Validator output_file();

// A run's files by flag, ("--input", path); empty paths are skipped.
using FlaggedPaths = std::vector<std::pair<std::string, std::string>>;
// Whether one of a run's `outputs` is one of its `inputs` or another of its outputs (under
// another flag), the same file however it is spelt (another path to it, a symbolic or hard
// link; a file not written yet by its normalised absolute path): the run would destroy what it
// reads, or write one output over another. The files a run writes beside an output and removes
// again, `<output>.lock` and `<output>.partial`, are checked against the inputs too. Checked
// before any work; returns the first problem, in the order of `outputs`, naming both flags
// ("--debug a.png: is the --input file; an output never replaces an input"), or nullopt.
std::optional<std::string> output_collision(const FlaggedPaths& outputs, const FlaggedPaths& inputs);

// The same for the files a loaded scene names (its images, maps, meta-textures and masks:
// "--out rock.png: is the scene's /materials/2/albedo/image file; ..."), checked once the scene
// is loaded and before anything is written.
std::optional<std::string> output_in_scene(const FlaggedPaths& outputs, const SceneDesc& scene);
// The files a loaded scene names as inputs, by field ("scene's /materials/2/albedo/image").
FlaggedPaths scene_inputs(const SceneDesc& scene);

// Whether `path` names a file in `folder` (however either is spelt; the folder need not exist
// yet) under a name `written` accepts: one a run writes into its output folder.
bool written_into_folder(const std::string& path, const std::string& folder, bool (*written)(const std::filesystem::path&));
// Whether one of `inputs` is a file the run removes or replaces in its output folder `folder`
// (those `written` accepts by name: an earlier run's frames and stats): the input's own name
// lies there (a file, or a link the scene would lose), or the input is a symbolic link to a
// file there (its data would go). A hard link elsewhere keeps its data and passes. Returns the
// problem naming `flag`, the file and the input's flag, or nullopt.
std::optional<std::string> input_in_output_folder(const std::string& flag, const std::string& folder,
                                                  bool (*written)(const std::filesystem::path&), const FlaggedPaths& inputs);

// An image output for `flag`, checked before any work: its folder exists, it is not a folder
// or any other non-regular file, and OIIO has a writer for its extension (`must_be_exr`: .exr
// only). Returns the problem ("--out x.png: folder 'y' does not exist") or "" when usable.
std::string check_image_output(const std::string& flag, const std::string& path, bool must_be_exr = false);

// Ownership of an output (a folder or a file) by one terravt process at a time: an exclusive
// flock on "<output>.lock" beside it (fileio::lock_exclusive, the lock a bake takes on its
// .partial), held until the object dies, which removes the lock file. Folders above the output
// are created if missing (the lock file needs one) and removed with the lock when the run left
// them empty (a run that failed leaves no trace); an existing output folder whose parent is
// read-only holds its lock inside, as .terravt.lock. A second run on the same output is refused:
// "<flag>: <output> is in use: <output>.lock: another terravt process holds it (locked) ...".
class OutputLock {
 public:
  static Result<OutputLock> acquire(const std::string& flag, const std::string& output);
  OutputLock(OutputLock&&) noexcept = default;
  OutputLock& operator=(OutputLock&&) = delete;
  ~OutputLock();
  const std::string& path() const { return path_; }

 private:
  OutputLock(std::string path, fileio::UniqueFd fd, std::vector<std::string> made)
      : path_(std::move(path)), fd_(std::move(fd)), made_(std::move(made)) {}
  std::string path_;
  fileio::UniqueFd fd_;
  std::vector<std::string> made_;  // folders acquire() created, deepest first; removed if left empty
};

// Prints "terravt <command>: <message>" to stderr and returns `code`.
int fail(const char* command, const std::string& message, int code);

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace tvt::cli
