// `terravt render` (the main job) through the executable: a short flythrough with validation
// on writes frames and a stats line per frame; every bad flag or input exits 2 naming its
// field and writes nothing.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "support/temp_dir.h"

namespace fs = std::filesystem;

namespace {

class RenderCli : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = tvt::test::fresh_test_dir("tvt_render_cli"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  // Runs terravt with the validation layer on; stdout+stderr land in `output_`.
  int run(const std::string& args) {
    const std::string log = path("log.txt");
    const std::string cmd = "TERRAVT_VALIDATION=1 " + std::string(TVT_TERRAVT_EXE) + " " + args + " >" + log + " 2>&1";
    const int status = std::system(cmd.c_str());
    std::ifstream in(log);
    output_.assign(std::istreambuf_iterator<char>(in), {});
    fs::remove(log);
    return WEXITSTATUS(status);
  }
  fs::path dir_;
  std::string output_;
};

TEST_F(RenderCli, ShortFlythroughWritesFramesAndOneStatsLinePerFrame) {
  const std::string out = path("out");
  ASSERT_EQ(run("render --quiet --frames 6 --every 2 --width 64 --height 36 --cache-slots 64 --page-budget 8 "
                "--frames-in-flight 3 --method linear --out " + out),
            0)
      << output_;
  EXPECT_EQ(output_.find("vulkan"), std::string::npos) << output_;  // no validation message
  EXPECT_NE(output_.find("6 frames in"), std::string::npos) << output_;
  for (const char* f : {"frame_00000.png", "frame_00002.png", "frame_00004.png", "frame_00005.png"})
    EXPECT_TRUE(fs::exists(fs::path(out) / f)) << f;
  EXPECT_FALSE(fs::exists(fs::path(out) / "frame_00001.png"));
  std::ifstream stats(fs::path(out) / "stats.jsonl");
  std::string line;
  int lines = 0;
  uint64_t produced = 0;
  while (std::getline(stats, line)) {
    const auto j = nlohmann::json::parse(line);
    EXPECT_EQ(j["frame"].get<int>(), lines);
    for (const char* key : {"requested", "produced", "evicted", "occupancy", "mip_bias", "feedback_pages", "ms"})
      EXPECT_TRUE(j.contains(key)) << key << " in " << line;
    for (const char* key : {"cpu", "wait", "total", "residency", "select"}) EXPECT_TRUE(j["ms"].contains(key)) << key;
    EXPECT_LE(j["feedback_frames_late"].get<int>(), 4);  // at most frames_in_flight + 1
    produced += j["produced"].get<uint64_t>();
    ++lines;
  }
  EXPECT_EQ(lines, 6);
  EXPECT_GT(produced, 0u);
}

TEST_F(RenderCli, BadFlagsExitWithTheirNameAndWriteNothing) {
  const std::string out = path("out");
  const std::string missing = path("missing.tvt");
  std::ofstream(path("bad.json")) << "{ \"vt\": { \"log2_size\": \"sixteen\" } }";
  const std::pair<std::string, std::string> cases[] = {
      {"--method bogus", "--method"},
      {"--frames 0", "--frames"},
      {"--frames-in-flight 0", "--frames-in-flight"},
      {"--frames-in-flight 9", "--frames-in-flight"},
      {"--detail-relief -1", "--detail-relief"},
      {"--detail-relief nan", "--detail-relief"},
      {"--detail-relief 2000", "--detail-relief"},
      {"--every 0", "--every"},
      {"--width 8", "--width"},
      {"--fps 0", "--fps"},
      {"--format tif", "--format"},
      {"--source bogus", "--source"},
      {"--source stored", "--store"},
      {"--source stored --store " + missing, "missing.tvt"},
      {"--store " + missing, "--store"},
      {"--feedback sideways", "--feedback"},
      {"--loader-threads 0", "--loader-threads"},
      {"--scene " + path("bad.json"), "log2_size"},
  };
  for (const auto& [args, field] : cases) {
    const int code = run("render --quiet --frames 2 --width 64 --height 36 --out " + out + " " + args);
    EXPECT_NE(code, 0) << args;
    EXPECT_NE(output_.find(field), std::string::npos) << args << ": " << output_;
    EXPECT_FALSE(fs::exists(out)) << args << " created the output folder";
  }
}

}  // namespace
