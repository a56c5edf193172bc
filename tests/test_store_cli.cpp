// `terravt bake / merge / verify / info` end to end through the executable, composing with the
// CPU reference (`bake --cpu`) on a 2^10 version of the built-in scene (85 pages).
#include <algorithm>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "support/cli.h"
#include "support/temp_dir.h"
#include "streaming/page_store.h"

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
  // A small render of the scene with the validation layer on; stdout+stderr land in `output_`.
  int render_with_validation(const std::string& args) {
    const std::string cmd = "TERRAVT_VALIDATION=1 " + std::string(TVT_TERRAVT_EXE) + " render --quiet --scene " +
                            scene_ + " --every 1 --width 64 --height 36 --cache-slots 64 --page-budget 8 " + args +
                            " >" + path("log.txt") + " 2>&1";
    const int status = std::system(cmd.c_str());
    output_ = bytes(path("log.txt"));
    return WEXITSTATUS(status);
  }
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
  EXPECT_NE(output_.find("filtered pyramid: 21 coarse pages checked to be the box filter of the finer mip"), std::string::npos)
      << output_;
  ASSERT_EQ(run("info --json " + path("merged.tvt")), 0) << output_;
  const auto info = nlohmann::json::parse(output_);
  EXPECT_EQ(info["pyramid"], "filtered");  // the default
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

// --pyramid composed keeps the byte-identical bake of every mip; the filtered one differs from
// it exactly in the coarse mips (level 0 is composed either way).
TEST_F(StoreCli, ComposedPyramidDiffersFromTheFilteredOneOnlyAboveLevelZero) {
  using namespace tvt;
  ASSERT_EQ(run(bake_args(path("composed.tvt")) + " --pyramid composed"), 0) << output_;
  EXPECT_NE(output_.find("composed pyramid"), std::string::npos) << output_;
  ASSERT_EQ(run(bake_args(path("filtered.tvt"))), 0) << output_;
  EXPECT_NE(output_.find("filtered pyramid: "), std::string::npos) << output_;
  auto composed = PageStoreReader::open(path("composed.tvt"));
  auto filtered = PageStoreReader::open(path("filtered.tvt"));
  ASSERT_TRUE(composed.ok() && filtered.ok());
  EXPECT_EQ(composed.value()->desc().pyramid, StorePyramid::composed);
  EXPECT_EQ(filtered.value()->desc().pyramid, StorePyramid::filtered);
  auto dc = composed.value()->make_decoder();
  auto df = filtered.value()->make_decoder();
  std::vector<uint8_t> a(composed.value()->page_bytes()), b(a.size());
  int coarse_differ = 0;
  for (const StoreEntry& e : composed.value()->entries()) {
    ASSERT_EQ(composed.value()->read_page(e.page, a, *dc), PageError::none);
    ASSERT_EQ(filtered.value()->read_page(e.page, b, *df), PageError::none);
    if (e.page.mip == 0) EXPECT_EQ(a, b) << to_string(e.page);
    else coarse_differ += a != b;
  }
  EXPECT_GT(coarse_differ, 0);
  ASSERT_EQ(run("info " + path("composed.tvt")), 0) << output_;
  EXPECT_NE(output_.find("composed pyramid"), std::string::npos) << output_;
}

// compare reports procedural pages against the filtered pyramid per mip: computed from level-0
// pages next to its own (composed, identical) bake, or read from a filtered --store, whose
// frames differ from the procedural ones by design (exit 0).
TEST_F(StoreCli, CompareReportsTheErrorPerMipAgainstTheFilteredPyramid) {
  const std::string compare = "compare --quiet --scene " + scene_ + " --frames 3 --every 1 --width 64 --height 36 "
                              "--cache-slots 64 --page-budget 16 --truth-pages 1 --truth-max-mip 3 --out ";
  ASSERT_EQ(run(compare + path("own")), 0) << output_;
  EXPECT_NE(output_.find("images: IDENTICAL"), std::string::npos) << output_;
  EXPECT_NE(output_.find("procedural pages vs the filtered pyramid"), std::string::npos) << output_;
  std::ifstream own_json(path("own/compare.json"));
  const auto own = nlohmann::json::parse(own_json);
  ASSERT_TRUE(own.contains("error_vs_filtered")) << own.dump(2);
  for (const auto& [mip, e] : own["error_vs_filtered"].items()) {
    EXPECT_EQ(e["pages"], 1) << mip;
    EXPECT_EQ(e["truth"], "computed") << mip;
    // The 4^m level-0 pages under one page, less those a finer mip's page composed already.
    EXPECT_GT(e["truth_level0_pages"].get<int>(), 0) << mip;
    EXPECT_LE(e["truth_level0_pages"].get<int>(), 1 << (2 * std::stoi(mip))) << mip;
    EXPECT_GT(e["psnr_db"].get<double>(), 5.0) << mip;
    EXPECT_LT(e["psnr_db"].get<double>(), 99.0) << mip << ": direct composition is not the filtered truth";
  }

  ASSERT_EQ(run("bake --quiet --method fbpb+dpt2 --scene " + scene_ + " --out " + path("filtered.tvt")), 0) << output_;
  ASSERT_EQ(run(compare + path("stored") + " --store " + path("filtered.tvt")), 0) << output_;
  EXPECT_NE(output_.find("DIFFER (expected: the store holds the filtered pyramid)"), std::string::npos) << output_;
  std::ifstream stored_json(path("stored/compare.json"));
  const auto stored = nlohmann::json::parse(stored_json);
  EXPECT_EQ(stored["store"]["pyramid"], "filtered");
  // PSNR per compared frame and its median (the flythrough figure against the filtered pyramid).
  EXPECT_NE(output_.find("frame PSNR dB (every 1 frames; identical = 99): median "), std::string::npos) << output_;
  const auto& per_frame = stored["images"]["psnr_db_per_frame"];
  ASSERT_EQ(per_frame.size(), stored["images"]["frames_compared"].get<size_t>());
  std::vector<double> sorted = per_frame.get<std::vector<double>>();
  std::sort(sorted.begin(), sorted.end());
  EXPECT_LT(sorted.front(), 99.0) << "at least one frame differs from the filtered pyramid";
  EXPECT_DOUBLE_EQ(stored["images"]["worst_psnr_db"].get<double>(), sorted.front());
  const double median = sorted.size() % 2 ? sorted[sorted.size() / 2]
                                          : 0.5 * (sorted[sorted.size() / 2 - 1] + sorted[sorted.size() / 2]);
  EXPECT_DOUBLE_EQ(stored["images"]["median_psnr_db"].get<double>(), median);
  EXPECT_EQ(own["images"]["median_psnr_db"], 99.0) << "the own bake's frames are identical";
  ASSERT_TRUE(stored.contains("error_vs_filtered")) << stored.dump(2);
  for (const auto& [mip, e] : stored["error_vs_filtered"].items()) {
    EXPECT_EQ(e["truth"], "store") << mip;
    EXPECT_GE(e["pages"].get<int>(), 1) << mip;
  }
}

TEST_F(StoreCli, BadFlagsNameTheFieldAndWriteNothing) {
  const std::string out = path("out.tvt");
  const std::pair<std::string, std::string> cases[] = {
      {" --level 50", "--level"},          {" --level 0", "--level"},
      {" --shard 3/2", "--shard"},         {" --shard one/two", "--shard"},
      {" --region 1,2,3", "--region"},     {" --region 0,0,0,16", "--region"},
      {" --mips 5", "--mips"},             {" --mips 7,9", "--mips"},
      {" --dict /no/such/dict", "--dict"}, {" --batch 0", "--batch"},
      {" --method nope", "--method"},      {" --pyramid box", "--pyramid"},
      {" --pyramid composed --finer " + path("x.tvt"), "--finer"},
      {" --finer /no/such/part.tvt", "--finer"},
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

// A plan that cannot fit the disk even at 32:1 compression is refused before anything is
// written, naming --out, the sizes and the ways out. Deterministic: the built-in scene with
// 1024-texel pages at V = 2^23 is 89 478 485 pages of 1032^2 texels, 381 TB raw, 11.9 TB at
// 32:1, more than any test machine has free. The whole built-in scene itself (6.6 TB raw,
// 207 GB at 32:1) is checked too where the disk has less than that free. A timeout turns a
// regression (a bake that starts) into a failure, not a hang.
TEST_F(StoreCli, BakeThatCannotFitTheDiskIsRefusedBeforeWritingAnything) {
  const std::string huge = tvt::test::write_default_scene_with_vt(
      dir_, R"({"log2_size": 23, "page_texels": 1024, "border_texels": 4})", "huge.json");
  const std::string out = path("whole.tvt");
  EXPECT_EQ(tvt::test::run_terravt(dir_, "bake --cpu --quiet --scene " + huge + " --out " + out, output_, "timeout 120 "),
            2)
      << output_;
  for (const char* part : {"--out", "whole.tvt", "89478485 pages", "381186.9 GB raw", "11912.1 GB", "free",
                           "--region", "--shard", "--ignore-free-space"})
    EXPECT_NE(output_.find(part), std::string::npos) << part << ": " << output_;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out + ".partial"));

  const uint64_t least = uint64_t(89478485) * 136 * 136 * 4 / 32;
  if (least > fs::space(dir_).available) {
    EXPECT_EQ(tvt::test::run_terravt(dir_, "bake --cpu --quiet --out " + out, output_, "timeout 120 "), 2) << output_;
    for (const char* part : {"89478485 pages", "6620.0 GB raw", "206.9 GB"})
      EXPECT_NE(output_.find(part), std::string::npos) << part << ": " << output_;
    EXPECT_FALSE(fs::exists(out));
    EXPECT_FALSE(fs::exists(out + ".partial"));
  }
}

}  // namespace

namespace {

size_t count_of(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// A store whose index is lost (trailing bytes, a truncated index, a truncated record area with
// a corrupt record) opens as "0 of 0 pages ok"; verify --salvage writes a new store of exactly
// its intact records, which verifies clean, and never replaces an existing file without
// --overwrite. A damaged header cannot be salvaged (it names what is missing).
TEST_F(StoreCli, VerifySalvageWritesAValidStoreOfTheIntactRecords) {
  ASSERT_EQ(run(bake_args(path("good.tvt"))), 0) << output_;
  const std::string good = bytes(path("good.tvt"));
  const size_t index_at = good.size() - 85 * 40;
  struct Damage {
    const char* name;
    std::string bytes;
    int intact_pages;  // -1: some, fewer than 85
  };
  const std::string cut_records = good.substr(0, good.size() * 6 / 10);
  std::string cut_flipped = cut_records;  // and one record corrupt
  cut_flipped[cut_flipped.size() / 2] = char(cut_flipped[cut_flipped.size() / 2] ^ 0x40);
  const Damage cases[] = {{"trailing.tvt", good + "junk after the index", 85},
                          {"cut-index.tvt", good.substr(0, index_at + 100), 85},
                          {"cut-records.tvt", cut_records, -1},
                          {"cut-flipped.tvt", cut_flipped, -1}};
  std::vector<int> salvaged;
  for (const Damage& d : cases) {
    SCOPED_TRACE(d.name);
    std::ofstream(path(d.name), std::ios::binary) << d.bytes;
    EXPECT_EQ(run("verify " + path(d.name)), 1) << output_;
    EXPECT_NE(output_.find("0 of 0 pages ok"), std::string::npos) << output_;
    EXPECT_NE(output_.find("--salvage"), std::string::npos) << output_;  // the way out is offered
    const std::string out = path(std::string("saved-") + d.name);
    ASSERT_EQ(run("verify " + path(d.name) + " --salvage " + out), 0) << output_;
    ASSERT_EQ(run("verify " + out), 0) << output_;
    if (d.intact_pages == 85) {
      EXPECT_NE(output_.find("85 of 85 pages ok"), std::string::npos) << output_;
      EXPECT_TRUE(bytes(out) == good);  // the same records in the same order: the same store
    } else {
      ASSERT_EQ(run("info --json " + out), 0) << output_;
      salvaged.push_back(nlohmann::json::parse(output_)["pages"]);
    }
  }
  // Every whole record before the cut (the last one is cut short), less the corrupt one.
  ASSERT_EQ(salvaged.size(), 2u);
  EXPECT_GT(salvaged[0], 10);
  EXPECT_LT(salvaged[0], 85);
  EXPECT_EQ(salvaged[1], salvaged[0] - 1);
  // An existing file is replaced only with --overwrite.
  const std::string before = bytes(path("saved-trailing.tvt"));
  EXPECT_EQ(run("verify " + path("cut-records.tvt") + " --salvage " + path("saved-trailing.tvt")), 1) << output_;
  EXPECT_NE(output_.find("saved-trailing.tvt: exists; pass --overwrite"), std::string::npos) << output_;
  EXPECT_TRUE(bytes(path("saved-trailing.tvt")) == before);
  EXPECT_EQ(run("verify " + path("cut-records.tvt") + " --salvage " + path("saved-trailing.tvt") + " --overwrite"), 0) << output_;
  EXPECT_FALSE(bytes(path("saved-trailing.tvt")) == before);
  // A damaged header: nothing to salvage, nothing written.
  std::string bad_header = good;
  bad_header[20] = char(bad_header[20] ^ 1);
  std::ofstream(path("bad-header.tvt"), std::ios::binary) << bad_header;
  EXPECT_EQ(run("verify " + path("bad-header.tvt") + " --salvage " + path("never.tvt")), 1) << output_;
  EXPECT_NE(output_.find("intact header"), std::string::npos) << output_;
  EXPECT_FALSE(fs::exists(path("never.tvt")));
  EXPECT_FALSE(fs::exists(path("never.tvt.partial")));
}

// --source hybrid composes what the store cannot give: a store that cannot be opened is
// reported once and every page is composed (exit 0); --strict makes it an error (exit 2, nothing
// written). --strict is only for hybrid.
TEST_F(StoreCli, HybridRenderWithAnUnopenableStoreComposesEverythingUnlessStrict) {
  ASSERT_EQ(run(bake_args(path("good.tvt"))), 0) << output_;
  std::ofstream(path("trailing.tvt"), std::ios::binary) << bytes(path("good.tvt")) << "junk";
  const auto run_render = [&](const std::string& more) {
    return render_with_validation("--frames 3 --store " + path("trailing.tvt") + " " + more);
  };
  EXPECT_EQ(run_render("--source hybrid --out " + path("degraded")), 0) << output_;
  EXPECT_EQ(count_of(output_, "trailing.tvt"), 1u) << output_;  // reported once
  EXPECT_NE(output_.find("composing every page"), std::string::npos) << output_;
  EXPECT_EQ(output_.find("vulkan"), std::string::npos) << output_;  // no validation message
  EXPECT_TRUE(fs::exists(path("degraded/stats.jsonl")));
  EXPECT_TRUE(fs::exists(path("degraded/frame_00002.png")));

  EXPECT_EQ(run_render("--source hybrid --strict --out " + path("strict")), 2) << output_;
  EXPECT_NE(output_.find("--store: "), std::string::npos) << output_;
  EXPECT_FALSE(fs::exists(path("strict")));
  EXPECT_EQ(run_render("--source stored --out " + path("stored")), 2) << output_;  // stored has nothing to show
  EXPECT_EQ(run_render("--source stored --strict --out " + path("stored")), 2) << output_;
  EXPECT_NE(output_.find("--strict: only used with --source hybrid"), std::string::npos) << output_;
}

// A store baked from another method (or scene) opens fine but holds other pages: hybrid treats
// it as unusable (reported once, every page composed, exit 0); stored and --strict refuse it
// before anything is written.
TEST_F(StoreCli, HybridRenderWithAStoreOfAnotherMethodComposesEverythingUnlessStrict) {
  ASSERT_EQ(run(bake_args(path("linear.tvt"))), 0) << output_;  // baked with --method linear
  const auto run_render = [&](const std::string& more) {
    return render_with_validation("--frames 2 --method blendmap --store " + path("linear.tvt") + " " + more);
  };
  EXPECT_EQ(run_render("--source hybrid --out " + path("degraded")), 0) << output_;
  EXPECT_EQ(count_of(output_, "scene_hash"), 1u) << output_;  // reported once, naming the field
  EXPECT_NE(output_.find("composing every page"), std::string::npos) << output_;
  EXPECT_TRUE(fs::exists(path("degraded/frame_00001.png")));
  EXPECT_EQ(run_render("--source hybrid --strict --out " + path("strict")), 2) << output_;
  EXPECT_NE(output_.find("scene_hash"), std::string::npos) << output_;
  EXPECT_FALSE(fs::exists(path("strict")));
  EXPECT_EQ(run_render("--source stored --out " + path("stored")), 2) << output_;
  EXPECT_FALSE(fs::exists(path("stored")));
}

}  // namespace
