// Helpers of the CLI tests, which run the built terravt executable.
#pragma once
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace tvt::test {

// Runs `terravt <args>` with `prefix` before it (e.g. "timeout 120 ", "VAR=1 "), stdin from
// /dev/null; its stdout and stderr land in `output` (through a log file in `dir`). Returns the
// exit code.
inline int run_terravt(const std::filesystem::path& dir, const std::string& args, std::string& output,
                       const std::string& prefix = "") {
  const std::string log = (dir / "log.txt").string();
  const std::string cmd = prefix + std::string(TVT_TERRAVT_EXE) + " " + args + " >" + log + " 2>&1 </dev/null";
  const int status = std::system(cmd.c_str());
  std::ifstream in(log);
  output.assign(std::istreambuf_iterator<char>(in), {});
  std::filesystem::remove(log);
  return WEXITSTATUS(status);
}

// The built-in scene with its "vt" object replaced by `vt` (JSON), written as `dir`/`name`.
// Returns its path.
inline std::string write_default_scene_with_vt(const std::filesystem::path& dir, const std::string& vt,
                                               const std::string& name = "scene.json") {
  std::ifstream in(std::string(TVT_SOURCE_DIR) + "/docs/default-scene.json");
  std::string json((std::istreambuf_iterator<char>(in)), {});
  const std::string key = "\"vt\": ";
  const std::size_t at = json.find(key);
  EXPECT_NE(at, std::string::npos);
  if (at != std::string::npos) json.replace(at + key.size(), json.find('}', at) + 1 - at - key.size(), vt);
  const std::string scene = (dir / name).string();
  std::ofstream(scene) << json;
  return scene;
}

// The built-in scene at V = 2^10 (85 pages over mips 0..3 of 128-texel pages), what the CLI
// tests bake and render in seconds, written as `dir`/scene.json. Returns its path.
inline std::string write_small_default_scene(const std::filesystem::path& dir) {
  return write_default_scene_with_vt(dir, R"({"log2_size": 10, "page_texels": 128, "border_texels": 4})");
}

}  // namespace tvt::test
