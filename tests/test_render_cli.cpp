// `terravt render` (the main job) through the executable: a short flythrough with validation
// on writes frames and a stats line per frame; every bad flag or input exits 2 naming its
// field and writes nothing.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "app/terrain_renderer.h"
#include "support/small_tmpfs.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;

namespace {

class RenderCli : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = tvt::test::fresh_test_dir("tvt_render_cli"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  // Runs terravt with the validation layer on (and `env`, "NAME=value ...", set); stdout+stderr
  // land in `output_`.
  int run(const std::string& args, const std::string& env = "") {
    const std::string log = path("log.txt");
    const std::string cmd = "TERRAVT_VALIDATION=1 " + env + " " + std::string(TVT_TERRAVT_EXE) + " " + args + " >" + log + " 2>&1";
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
                "--frames-in-flight 3 --method linear --vt-filter brilinear:0.5 --out " + out),
            0)
      << output_;
  EXPECT_EQ(output_.find("vulkan"), std::string::npos) << output_;  // no validation message
  EXPECT_NE(output_.find("brilinear:0.5 filter"), std::string::npos) << output_;
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
  std::ofstream(path("bad-camera.json")) << R"({"keys": [{"time_s": 0, "position_m": [1, 2, 3]}]})";
  {
    // Within the scene format's limits, but 512 slots of 2048^2 texels (8 GB) exceed what one image may hold.
    std::ifstream in(std::string(TVT_SOURCE_DIR) + "/docs/default-scene.json");
    auto scene = nlohmann::json::parse(in);
    scene["vt"]["page_texels"] = 1024;
    scene["vt"]["border_texels"] = 512;
    std::ofstream(path("huge-pages.json")) << scene.dump();
  }
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
      {"--feedback none", "--feedback"},
      {"--fps 1e-310", "--fps"},
      {"--cache-slots 0", "--cache-slots"},
      {"--cache-slots 100000", "--cache-slots"},
      {"--page-budget 0", "--page-budget"},
      {"--cache-slots 64 --page-budget 65", "--page-budget"},
      {"--window 3", "--window"},
      {"--window 8192", "--window"},
      {"--feedback-divisor 0", "--feedback-divisor"},
      {"--feedback-divisor 37", "--feedback-divisor"},  // more than the 36-pixel height
      {"--anisotropy 0", "--anisotropy"},
      {"--anisotropy 5", "--anisotropy"},  // the built-in scene's border is 4
      {"--camera ''", "--camera: empty path"},
      {"--save-camera ''", "--save-camera: empty path"},
      {"--gpu ''", "--gpu: empty"},
      {"--scene " + path("huge-pages.json"), "vt cache (cache_slots pages of vt.page_texels"},
      {"--vt-filter nearest", "--vt-filter"},
      {"--vt-filter brilinear:", "--vt-filter"},
      {"--vt-filter brilinear:1.5", "--vt-filter"},
      {"--vt-filter brilinear:-0.25", "--vt-filter"},
      {"--vt-filter brilinear:nan", "--vt-filter"},
      {"--vt-filter brilinear:0.3x", "--vt-filter"},
      {"--loader-threads 0", "--loader-threads"},
      {"--scene " + path("bad.json"), "log2_size"},
      {"--camera " + path("missing-camera.json"), "missing-camera.json: cannot read camera file"},
      {"--camera " + path("bad-camera.json"), "bad-camera.json: /keys/0/yaw_deg: required field is missing"},
      {"--save-camera " + path("no/such/folder/cam.json"), "--save-camera"},
      {"--lighting dim", "--lighting"},
      {"--page-table " + path("bad.json"), "--page-table"},  // exists: replaced only with --overwrite
  };
  for (const auto& [args, field] : cases) {
    const int code = run("render --quiet --frames 2 --width 64 --height 36 --out " + out + " " + args);
    EXPECT_NE(code, 0) << args;
    EXPECT_NE(output_.find(field), std::string::npos) << args << ": " << output_;
    EXPECT_FALSE(fs::exists(out)) << args << " created the output folder";
  }
}

// stats.jsonl lines of a finished run.
std::vector<nlohmann::json> stats_lines(const std::string& out) {
  std::vector<nlohmann::json> lines;
  std::ifstream in(fs::path(out) / "stats.jsonl");
  for (std::string line; std::getline(in, line);) lines.push_back(nlohmann::json::parse(line));
  return lines;
}

std::string file_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// --lighting none renders the albedo alone, and --page-table writes the GPU page table after
// the last frame: uint32 entries of every mip's window, the coarsest page mapped everywhere.
TEST_F(RenderCli, LightingNoneChangesTheFrameAndThePageTableIsWrittenAfterTheLastFrame) {
  // A still camera and every pixel reporting: each frame's feedback is the same, so both runs
  // end with the same residency whichever frame their first feedback arrived in.
  std::ofstream(path("still.json")) << R"({"keys": [{"time_s": 0, "position_m": [3000, 3000, 900], "yaw_deg": 20, "pitch_deg": -30}]})";
  const std::string args = "render --quiet --frames 3 --every 2 --width 64 --height 36 --cache-slots 64 --method linear "
                           "--feedback-divisor 1 --camera " + path("still.json") + " ";
  ASSERT_EQ(run(args + "--out " + path("sun") + " --page-table " + path("sun.bin")), 0) << output_;
  ASSERT_EQ(run(args + "--lighting none --out " + path("albedo") + " --page-table " + path("albedo.bin")), 0) << output_;
  EXPECT_EQ(output_.find("vulkan"), std::string::npos) << output_;  // no validation message
  const std::string table = file_text(path("albedo.bin"));
  ASSERT_GT(table.size(), 0u);
  ASSERT_EQ(table.size() % 4, 0u);
  std::vector<uint32_t> entries(table.size() / 4);
  std::memcpy(entries.data(), table.data(), table.size());
  EXPECT_TRUE(std::all_of(entries.begin(), entries.end(), [](uint32_t e) { return (e & 0x80000000u) != 0; }))
      << "an entry without data: the coarsest mip is always resident";
  // The lighting does not change what is resident, only the frame.
  EXPECT_EQ(file_text(path("sun.bin")), table);
  EXPECT_NE(file_text(fs::path(path("sun")) / "frame_00002.png"), file_text(fs::path(path("albedo")) / "frame_00002.png"));
}

// An earlier run's output is never replaced or emptied without --overwrite: not by a second run,
// not by a run whose flags are bad, not through a stats.jsonl that links elsewhere. With
// --overwrite the earlier frames go (none of them mixes with the new run) and the user's other
// files stay; --save-camera follows the same rule.
TEST_F(RenderCli, AnEarlierRunIsReplacedOnlyWithOverwrite) {
  const std::string out = path("run");
  const std::string common = "render --quiet --width 64 --height 36 --cache-slots 64 --method linear --every 2 ";
  ASSERT_EQ(run(common + "--frames 5 --out " + out), 0) << output_;
  std::ofstream(fs::path(out) / "notes.txt") << "mine";
  const std::string stats = file_text(fs::path(out) / "stats.jsonl");
  ASSERT_FALSE(stats.empty());
  ASSERT_TRUE(fs::exists(fs::path(out) / "frame_00004.png"));

  EXPECT_EQ(run(common + "--frames 2 --out " + out), 2);
  EXPECT_NE(output_.find("--out: " + out + " holds the output of an earlier run"), std::string::npos) << output_;
  EXPECT_NE(output_.find("--overwrite"), std::string::npos) << output_;
  EXPECT_EQ(run(common + "--frames 2 --cache-slots 0 --overwrite --out " + out), 2);  // bad flag: nothing touched
  EXPECT_EQ(file_text(fs::path(out) / "stats.jsonl"), stats);
  EXPECT_TRUE(fs::exists(fs::path(out) / "frame_00004.png"));

  ASSERT_EQ(run(common + "--frames 2 --overwrite --out " + out), 0) << output_;
  EXPECT_EQ(stats_lines(out).size(), 2u);
  EXPECT_TRUE(fs::exists(fs::path(out) / "frame_00000.png"));
  EXPECT_TRUE(fs::exists(fs::path(out) / "frame_00001.png"));  // the last frame is always written
  EXPECT_FALSE(fs::exists(fs::path(out) / "frame_00002.png"));  // the earlier run's
  EXPECT_FALSE(fs::exists(fs::path(out) / "frame_00004.png"));
  EXPECT_EQ(file_text(fs::path(out) / "notes.txt"), "mine");

  // A stats.jsonl that is a symbolic link: refused, and with --overwrite the link is replaced,
  // never written through.
  const std::string linked = path("linked"), precious = path("precious.txt");
  fs::create_directories(linked);
  std::ofstream(precious) << "keep";
  fs::create_symlink(precious, fs::path(linked) / "stats.jsonl");
  EXPECT_EQ(run(common + "--frames 1 --out " + linked), 2);
  ASSERT_EQ(run(common + "--frames 1 --overwrite --out " + linked), 0) << output_;
  EXPECT_EQ(file_text(precious), "keep");
  EXPECT_FALSE(fs::is_symlink(fs::path(linked) / "stats.jsonl"));
  EXPECT_EQ(stats_lines(linked).size(), 1u);

  const std::string cam = path("cam.json");
  std::ofstream(cam) << "mine";
  EXPECT_EQ(run("render --save-camera " + cam), 2);
  EXPECT_NE(output_.find("--save-camera: " + cam + " exists"), std::string::npos) << output_;
  EXPECT_EQ(file_text(cam), "mine");
  ASSERT_EQ(run("render --overwrite --save-camera " + cam), 0) << output_;
  EXPECT_NE(file_text(cam).find("\"keys\""), std::string::npos);
}

TEST_F(RenderCli, TheSavedBuiltInFlythroughIsTheDocumentedTemplateAndFliesTheSamePath) {
  const std::string cam = path("flythrough.json");
  ASSERT_EQ(run("render --save-camera " + cam), 0) << output_;
  EXPECT_NE(output_.find("built-in flythrough (7 keys, 24.0 s, 1 cut)"), std::string::npos) << output_;
  std::ifstream saved(cam), doc(std::string(TVT_SOURCE_DIR) + "/docs/default-camera.json");
  const std::string saved_text(std::istreambuf_iterator<char>(saved), {}), doc_text(std::istreambuf_iterator<char>(doc), {});
  EXPECT_EQ(saved_text, doc_text) << "docs/default-camera.json is stale: terravt render --overwrite --save-camera docs/default-camera.json";

  // The same frames from the file as from the built-in path (positions and angles per frame).
  const std::string common = "render --quiet --frames 3 --every 5 --width 64 --height 36 --cache-slots 64 --method linear ";
  ASSERT_EQ(run(common + "--out " + path("builtin")), 0) << output_;
  ASSERT_EQ(run(common + "--camera " + cam + " --out " + path("file")), 0) << output_;
  EXPECT_NE(output_.find("camera: " + cam + " (7 keys, 24.0 s, 1 cut)"), std::string::npos) << output_;
  const auto a = stats_lines(path("builtin")), b = stats_lines(path("file"));
  ASSERT_EQ(a.size(), 3u);
  ASSERT_EQ(b.size(), 3u);
  for (size_t f = 0; f < a.size(); ++f) {
    const auto &ca = a[f]["camera"], &cb = b[f]["camera"];
    for (int i = 0; i < 3; ++i)
      EXPECT_NEAR(ca["position_m"][i].get<double>(), cb["position_m"][i].get<double>(), 1e-6) << "frame " << f;
    EXPECT_NEAR(ca["yaw_deg"].get<double>(), cb["yaw_deg"].get<double>(), 1e-6) << "frame " << f;
    EXPECT_NEAR(ca["pitch_deg"].get<double>(), cb["pitch_deg"].get<double>(), 1e-6) << "frame " << f;
  }
}

// A terrain wider than camera coordinates may reach (1e9 m) is refused when the scene loads,
// naming the field: before the scene format capped extent_m, its built-in flythrough (clearance
// 1e-4 of the extent) left the camera file limits. --save-camera still checks what it writes
// against those limits and writes nothing otherwise.
TEST_F(RenderCli, ATerrainBeyondTheCameraLimitsIsRefusedAndNothingIsWritten) {
  std::ifstream in(std::string(TVT_SOURCE_DIR) + "/docs/default-scene.json");
  auto scene = nlohmann::json::parse(in);
  scene["terrain"]["extent_m"] = 2e10;
  std::ofstream(path("huge.json")) << scene.dump();
  const std::string cam = path("huge-camera.json");
  EXPECT_EQ(run("render --scene " + path("huge.json") + " --save-camera " + cam), 2);
  EXPECT_NE(output_.find("/terrain/extent_m"), std::string::npos) << output_;
  EXPECT_FALSE(fs::exists(cam));
  scene["terrain"]["extent_m"] = 1e9;  // the largest: its flythrough fits the camera file
  std::ofstream(path("largest.json")) << scene.dump();
  ASSERT_EQ(run("render --scene " + path("largest.json") + " --save-camera " + cam), 0) << output_;
  EXPECT_TRUE(fs::exists(cam));
}

TEST_F(RenderCli, ACameraFileIsFlownWholeUnlessFramesAreGiven) {
  const std::string cam = path("short.json");
  std::ofstream(cam) << R"({"lens": {"vertical_fov_deg": 45, "far_m": 30000},
    "keys": [{"time_s": 0, "position_m": [2000, 2000], "above_ground_m": 40, "look_at_m": [3000, 3000, 0]},
             {"time_s": 0.25, "position_m": [2100, 2050], "above_ground_m": 40, "look_at_m": [3000, 3000, 0]},
             {"time_s": 0.25, "position_m": [6000, 1000, 1500], "yaw_deg": 120, "pitch_deg": -35, "cut": true},
             {"time_s": 0.5, "position_m": [6000, 1100, 1500], "yaw_deg": 125, "pitch_deg": -35}]})";
  const std::string common = "render --quiet --fps 10 --width 64 --height 36 --cache-slots 64 --method linear --camera " + cam;
  ASSERT_EQ(run(common + " --out " + path("whole")), 0) << output_;
  const auto whole = stats_lines(path("whole"));
  ASSERT_EQ(whole.size(), 6u);  // 0.5 s at 10 fps, both ends
  EXPECT_FALSE(whole[2]["camera"]["cut"].get<bool>());
  EXPECT_TRUE(whole[3]["camera"]["cut"].get<bool>());  // t = 0.3: the first frame of the second shot
  EXPECT_NEAR(whole[5]["camera"]["position_m"][1].get<double>(), 1100.0, 1e-9);
  EXPECT_NEAR(whole[5]["camera"]["yaw_deg"].get<double>(), 125.0, 1e-9);
  ASSERT_EQ(run(common + " --frames 2 --out " + path("two")), 0) << output_;
  EXPECT_EQ(stats_lines(path("two")).size(), 2u);

  // A path too long to fly whole at this rate needs --frames; nothing is written.
  const std::string long_cam = path("long.json");
  std::ofstream(long_cam) << R"({"keys": [{"time_s": 0, "position_m": [1, 2, 300], "yaw_deg": 0},
                                          {"time_s": 1e6, "position_m": [1, 2, 300], "yaw_deg": 9}]})";
  EXPECT_EQ(run("render --quiet --camera " + long_cam + " --out " + path("long")), 2);
  EXPECT_NE(output_.find("--frames: the camera path is 1000000"), std::string::npos) << output_;
  EXPECT_FALSE(fs::exists(path("long")));
}

}  // namespace

// --vt-filter's names (app/terrain_renderer.h): the named filters, brilinear's band, and
// every text that is not one of them, including bands outside [0, 1] and NaN.
// A write that fails part-way (here the file writes meet a full disk after ~100 KB, a few
// frames in) fails the run: exit 1, the message names the file and the OS error, no "wrote"
// line, and nothing of the run is left to look complete (no stats.jsonl, no frame; the folder
// the run made is gone).
TEST_F(RenderCli, AFullDiskFailsTheRunNamingTheFileAndKeepsNothing) {
  const std::string out = path("out");
  EXPECT_EQ(run("render --quiet --frames 10 --every 1 --width 160 --height 90 --cache-slots 64 --out " + out,
                "TERRAVT_FAULT_WRITE_AFTER=100000"),
            1)
      << output_;
  EXPECT_NE(output_.find("No space left on device"), std::string::npos) << output_;
  EXPECT_NE(output_.find(out + "/frame_000"), std::string::npos) << output_;
  EXPECT_EQ(output_.find("wrote"), std::string::npos) << output_;
  EXPECT_FALSE(fs::exists(out)) << output_;
  // Folders made above the output for it (and its lock) are gone too.
  const std::string deep = path("made/for/out");
  EXPECT_EQ(run("render --quiet --frames 10 --every 1 --width 160 --height 90 --cache-slots 64 --out " + deep,
                "TERRAVT_FAULT_WRITE_AFTER=100000"),
            1)
      << output_;
  EXPECT_FALSE(fs::exists(path("made"))) << output_;
  // The same run with room to spare completes.
  EXPECT_EQ(run("render --quiet --frames 10 --every 1 --width 160 --height 90 --cache-slots 64 --out " + out), 0) << output_;
  EXPECT_TRUE(fs::exists(fs::path(out) / "stats.jsonl"));
  EXPECT_TRUE(fs::exists(fs::path(out) / "frame_00009.png"));
}

// The reported repro: a 64 KiB tmpfs fills during the run. Needs root to mount (skipped
// otherwise). An earlier folder the run did not make is kept, emptied of this run's files.
TEST_F(RenderCli, ARealFullTmpfsFailsTheRunAndKeepsNoFrameOrStats) {
  tvt::test::SmallTmpfs disk(dir_ / "disk", 64);
  if (!disk.ok()) GTEST_SKIP() << disk.why();
  const std::string out = (disk.dir() / "out").string();
  fs::create_directories(out);
  EXPECT_EQ(run("render --quiet --frames 10 --every 1 --width 160 --height 90 --cache-slots 64 --out " + out), 1) << output_;
  EXPECT_NE(output_.find("No space left on device"), std::string::npos) << output_;
  EXPECT_NE(output_.find(out + "/"), std::string::npos) << output_;
  EXPECT_EQ(output_.find("wrote"), std::string::npos) << output_;
  ASSERT_TRUE(fs::is_directory(out));
  EXPECT_TRUE(fs::is_empty(out)) << output_;
}

TEST(MipFilterNames, ParseAndPrintRoundTripAndRejectEverythingElse) {
  using namespace tvt;
  EXPECT_EQ(mip_filter_from_string("trilinear"), VtMipFilter::Trilinear);
  EXPECT_EQ(mip_filter_from_string("bilinear"), VtMipFilter::Bilinear);
  EXPECT_EQ(mip_filter_from_string("brilinear"), VtMipFilter{kDefaultBrilinearBand});
  EXPECT_EQ(mip_filter_from_string("brilinear:0.125"), VtMipFilter{0.125f});
  EXPECT_EQ(mip_filter_from_string("brilinear:1"), VtMipFilter::Trilinear);  // the band's ends are the others
  EXPECT_EQ(mip_filter_from_string("brilinear:0"), VtMipFilter::Bilinear);
  for (const char* name : {"trilinear", "bilinear", "brilinear:0.25", "brilinear:0.1", "brilinear:1e-07"}) {
    const auto f = mip_filter_from_string(name);
    ASSERT_TRUE(f) << name;
    EXPECT_EQ(mip_filter_name(*f), name);
  }
  for (const char* bad : {"", "nearest", "Trilinear", "brilinear:", "brilinear0.5", "brilinear:x", "brilinear:0.5x",
                          "brilinear:1.5", "brilinear:-0.25", "brilinear:nan", "brilinear:inf", "brilinear: 0.5"})
    EXPECT_FALSE(mip_filter_from_string(bad)) << "'" << bad << "'";
}
