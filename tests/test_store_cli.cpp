// `terravt bake / merge / verify / info` end to end through the executable, composing with the
// CPU reference (`bake --cpu`) on a 2^10 version of the built-in scene (85 pages).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "support/cli.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;

namespace {

class StoreCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tvt::test::fresh_test_dir("tvt_store_cli");
    scene_ = tvt::test::write_small_default_scene(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  // Runs terravt; stdout+stderr land in `output_`.
  int run(const std::string& args) { return tvt::test::run_terravt(dir_, args, output_); }
  std::string bake_args(const std::string& out) const {
    return "bake --cpu --quiet --method linear --scene " + scene_ + " --out " + out;
  }
  static std::string bytes(const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  fs::path dir_;
  std::string scene_;
  std::string output_;
};

TEST_F(StoreCli, ShardedBakeMergesToTheSingleBakeAndVerifyFindsACorruptPage) {
  ASSERT_EQ(run(bake_args(path("single.tvt"))), 0) << output_;
  for (int i = 0; i < 3; ++i)
    ASSERT_EQ(run(bake_args(path("part" + std::to_string(i) + ".tvt")) + " --shard " + std::to_string(i) + "/3"), 0) << output_;
  ASSERT_EQ(run("merge " + path("part2.tvt") + " " + path("part0.tvt") + " " + path("part1.tvt") + " --out " + path("merged.tvt")), 0)
      << output_;
  const std::string single = bytes(path("single.tvt"));
  ASSERT_GT(single.size(), 85u * 1000u);
  EXPECT_TRUE(single == bytes(path("merged.tvt")));  // byte for byte
  EXPECT_FALSE(fs::exists(path("single.tvt.partial")));

  // A finished store is replaced only with --overwrite (a bake may have taken hours).
  EXPECT_EQ(run(bake_args(path("single.tvt")) + " --shard 1/3"), 2);
  EXPECT_NE(output_.find("single.tvt exists; pass --overwrite"), std::string::npos) << output_;
  EXPECT_EQ(run("merge " + path("part0.tvt") + " --out " + path("merged.tvt")), 2);
  EXPECT_NE(output_.find("merged.tvt exists; pass --overwrite"), std::string::npos) << output_;
  EXPECT_TRUE(single == bytes(path("single.tvt")));
  EXPECT_TRUE(single == bytes(path("merged.tvt")));
  ASSERT_EQ(run("merge " + path("part0.tvt") + " " + path("part2.tvt") + " " + path("part1.tvt") + " --overwrite --out " +
                path("merged.tvt")),
            0)
      << output_;
  EXPECT_TRUE(single == bytes(path("merged.tvt")));

  ASSERT_EQ(run("verify " + path("merged.tvt")), 0) << output_;
  EXPECT_NE(output_.find("85 of 85 pages ok"), std::string::npos) << output_;
  ASSERT_EQ(run("info --json " + path("merged.tvt")), 0) << output_;
  const auto info = nlohmann::json::parse(output_);
  EXPECT_EQ(info["pages"], 85);
  EXPECT_EQ(info["vt"]["log2_size"], 10);
  EXPECT_EQ(info["mips"].size(), 4u);

  // One flipped byte in the middle of the file: verify names the page and fails.
  std::string broken = single;
  broken[broken.size() / 2] = char(broken[broken.size() / 2] ^ 0x40);
  std::ofstream(path("broken.tvt"), std::ios::binary) << broken;
  EXPECT_EQ(run("verify " + path("broken.tvt")), 1) << output_;
  EXPECT_NE(output_.find("broken.tvt"), std::string::npos) << output_;
  EXPECT_NE(output_.find("84 of 85 pages ok"), std::string::npos) << output_;
}

TEST_F(StoreCli, BadFlagsNameTheFieldAndWriteNothing) {
  const std::string out = path("out.tvt");
  const std::pair<std::string, std::string> cases[] = {
      {" --level 50", "--level"},          {" --level 0", "--level"},
      {" --shard 3/2", "--shard"},         {" --shard one/two", "--shard"},
      {" --region 1,2,3", "--region"},     {" --region 0,0,0,16", "--region"},
      {" --mips 5", "--mips"},             {" --mips 7,9", "--mips"},
      {" --dict /no/such/dict", "--dict"}, {" --batch 0", "--batch"},
      {" --method nope", "--method"},
  };
  for (const auto& [args, field] : cases) {
    EXPECT_EQ(run(bake_args(out) + args), 2) << args << ": " << output_;
    EXPECT_NE(output_.find(field), std::string::npos) << args << ": " << output_;
  }
  EXPECT_EQ(run(bake_args("/no/such/folder/out.tvt")), 2) << output_;
  EXPECT_NE(output_.find("--out"), std::string::npos) << output_;
  EXPECT_NE(run("bake --cpu --scene " + scene_), 0);  // --out is required
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out + ".partial"));

  std::ofstream(path("garbage.tvt")) << "not a page store";
  EXPECT_EQ(run("info " + path("garbage.tvt")), 1);
  EXPECT_NE(output_.find("garbage.tvt"), std::string::npos) << output_;
  EXPECT_EQ(run("verify " + path("garbage.tvt")), 1);
  EXPECT_NE(run("merge " + path("garbage.tvt") + " --out " + path("merged.tvt")), 0);
  EXPECT_FALSE(fs::exists(path("merged.tvt")));
  EXPECT_NE(run("render --source stored --store " + path("garbage.tvt") + " --out " + path("r")), 0);
  EXPECT_NE(output_.find("garbage.tvt"), std::string::npos) << output_;
}

}  // namespace
