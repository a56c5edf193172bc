// `terravt compose` end to end on the CPU reference (the GPU path is covered by gpu_*).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "compose/image.h"

namespace fs = std::filesystem;

namespace {
int run(const std::string& args) {
  const std::string cmd = std::string(TVT_TERRAVT_EXE) + " " + args + " >/dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  return WEXITSTATUS(status);
}
fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("terravt-compose-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
}  // namespace

TEST(ComposeCli, WritesSixLabelledPanelsOnTheCpu) {
  const fs::path d = temp_dir("ok");
  const fs::path out = d / "sheet.png";
  ASSERT_EQ(run("compose --device cpu --size 32 --mip 3 --out " + out.string() + " --panels " + d.string()), 0);
  auto img = tvt::read_image_rgba8(out.string());
  ASSERT_TRUE(img.ok()) << img.error().message;
  EXPECT_EQ(img->width, 3 * 32 + 4 * 4);
  EXPECT_EQ(img->height, 2 * 32 + 3 * 4);
  for (const char* m : {"linear", "blendmap", "fbpb", "dpt1", "dpt2", "fbpb+dpt2"})
    EXPECT_TRUE(fs::exists(d / (std::string("compose-") + m + ".png"))) << m;
  // The methods differ: blend map and FBPB+DPT2 panels are not identical.
  auto a = tvt::read_image_rgba8((d / "compose-blendmap.png").string());
  auto b = tvt::read_image_rgba8((d / "compose-fbpb+dpt2.png").string());
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_NE(a->texels, b->texels);
  fs::remove_all(d);
}

// --hex overrides the scene's per-material choice: the default scene has hex-tiling on but for
// its FBPB cobbles, which never take it, so with fbpb+dpt2 "scene" and "on" compose the same
// panels; "off" composes the plainly tiled textures.
TEST(ComposeCli, HexOverrideTurnsTheAntiRepetitionModeOnAndOff) {
  const fs::path d = temp_dir("hex");
  std::vector<std::vector<uint8_t>> sheets;
  for (const char* hex : {"scene", "on", "off"}) {
    const fs::path out = d / (std::string("sheet-") + hex + ".png");
    ASSERT_EQ(run(std::string("compose --device cpu --size 32 --mip 0 --methods fbpb+dpt2 --hex ") + hex + " --out " +
                  out.string()),
              0)
        << hex;
    auto img = tvt::read_image_rgba8(out.string());
    ASSERT_TRUE(img.ok()) << img.error().message;
    sheets.push_back(img->texels);
  }
  EXPECT_EQ(sheets[0], sheets[1]);
  EXPECT_NE(sheets[1], sheets[2]);
  fs::remove_all(d);
}

TEST(ComposeCli, BadFlagsExitWithUsageErrorAndWriteNothing) {
  const fs::path d = temp_dir("bad");
  const std::string out = " --out " + (d / "x.png").string();
  EXPECT_EQ(run("compose --device tpu" + out), 2);
  for (const std::string args : {"compose --methods linear,nope", "compose --mip 99",
                                  "compose --region 1,2,3", "compose --region -5,0,16,16", "compose --mip-strategy supersample:3",
                                  "compose --size 2", "compose --scene /does/not/exist.json", "compose --panels /no/such/dir",
                                  "compose --hex maybe"})
    EXPECT_EQ(run(args + " --device cpu" + out), 2) << args;
  EXPECT_TRUE(fs::is_empty(d));
  fs::remove_all(d);
}

// The panels and the sheet are written all or none: a full disk part-way (after ~20 KB, so a
// few panels are written first) fails with the file and the OS error, and removes the panels.
TEST(ComposeCli, AFullDiskFailsNamingTheFileAndLeavesNoSheetOrPanel) {
  const fs::path d = temp_dir("full");
  const fs::path out = d / "sheet.png", log = d / "log.txt";
  const std::string cmd = "TERRAVT_FAULT_WRITE_AFTER=20000 " + std::string(TVT_TERRAVT_EXE) +
                          " compose --device cpu --size 64 --mip 3 --out " + out.string() + " --panels " + d.string() +
                          " >" + log.string() + " 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream in(log);
  const std::string output{std::istreambuf_iterator<char>(in), {}};
  EXPECT_EQ(WEXITSTATUS(status), 1) << output;
  EXPECT_NE(output.find("No space left on device"), std::string::npos) << output;
  EXPECT_NE(output.find(d.string() + "/"), std::string::npos) << output;
  EXPECT_EQ(output.find("wrote"), std::string::npos) << output;
  fs::remove(log);
  EXPECT_TRUE(fs::is_empty(d)) << output;
  fs::remove_all(d);
}
