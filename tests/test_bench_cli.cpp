// `terravt bench mips` end to end (lavapipe): the table, its JSON and the PSNR-against-cost SVG,
// the costs alone (--cost-only), and the flags it refuses.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "support/cli.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;

namespace {
size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// `terravt bench mips` in `dir` on `scene` with these flags and --json `json`; its exit
// status, its output in `out`.
int run_bench_mips(const fs::path& dir, const std::string& scene, const std::string& flags, const fs::path& json,
                   std::string& out) {
  return tvt::test::run_terravt(dir, "bench mips --scene " + scene + " " + flags + " --json " + json.string(), out);
}
}  // namespace

TEST(BenchMipsCli, WritesJsonAndOnePlotPanelPerMethodWithACurvePerStrategy) {
  const fs::path dir = tvt::test::fresh_test_dir("tvt_bench_mips");
  const std::string scene = tvt::test::write_small_default_scene(dir);
  const fs::path json_path = dir / "mips.json";
  std::string out;
  ASSERT_EQ(run_bench_mips(dir, scene, "--method blendmap,dpt2 --mips 1,2 --pages 1 --repeats 1", json_path, out), 0) << out;
  EXPECT_EQ(count(out, "target (prefiltered, the default: >= 35 dB at <= 2x direct): met at mips "), 2u) << out;
  std::ifstream in(json_path);
  const nlohmann::json j = nlohmann::json::parse(in);
  for (const char* method : {"blendmap", "dpt2"}) {
    for (const char* mip : {"1", "2"}) {
      const nlohmann::json& m = j.at("methods").at(method).at(mip);
      const double direct = m.at("direct").at("psnr_db").get<double>();
      const double ss2 = m.at("supersample:2").at("psnr_db").get<double>();
      const double pre = m.at("prefiltered").at("psnr_db").get<double>();
      EXPECT_TRUE(std::isfinite(direct) && direct > 10.0) << method << " mip " << mip;
      EXPECT_TRUE(std::isfinite(pre) && pre > 10.0) << method << " mip " << mip;
      EXPECT_GT(ss2, direct) << method << " mip " << mip;  // supersampling gets closer to the filtered truth
      EXPECT_DOUBLE_EQ(m.at("direct").at("cost_vs_direct").get<double>(), 1.0);
      // The verdict on the default strategy follows from its own figures.
      EXPECT_EQ(m.at("target_met").get<bool>(),
                pre >= 35.0 && m.at("prefiltered").at("cost_vs_direct").get<double>() <= 2.0)
          << method << " mip " << mip;
    }
    EXPECT_TRUE(j.at("methods").at(method).at("2").contains("supersample:4"));
    EXPECT_FALSE(j.at("methods").at(method).at("1").contains("supersample:4"));  // capped at 2^mip
  }
  // The SVG beside the JSON: two panels, four strategies in each (direct, prefiltered, 2 and
  // 4), and the 35 dB target line.
  std::ifstream svg_in(dir / "mips.svg");
  const std::string svg((std::istreambuf_iterator<char>(svg_in)), {});
  ASSERT_FALSE(svg.empty());
  EXPECT_EQ(svg.rfind("<svg ", 0), 0u);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_EQ(count(svg, "class=\"panel\""), 2u);
  EXPECT_EQ(count(svg, "class=\"series\""), 8u);
  EXPECT_EQ(count(svg, "data-name=\"prefiltered\""), 2u);
  EXPECT_EQ(count(svg, "data-name=\"supersample:4\""), 2u);
  EXPECT_NE(svg.find(">blendmap<"), std::string::npos);
  EXPECT_NE(svg.find(">dpt2<"), std::string::npos);
  EXPECT_NE(svg.find("35 dB target"), std::string::npos);
  fs::remove_all(dir);
}

TEST(BenchMipsCli, CostOnlyTimesTheStrategiesWithoutTheGroundTruth) {
  const fs::path dir = tvt::test::fresh_test_dir("tvt_bench_mips_cost");
  const std::string scene = tvt::test::write_small_default_scene(dir);
  const fs::path json_path = dir / "costs.json";
  std::string out;
  ASSERT_EQ(run_bench_mips(dir, scene, "--method blendmap --mips 1,2 --pages 1 --repeats 1 --cost-only", json_path, out), 0) << out;
  EXPECT_EQ(out.find("level-0 pages composed"), std::string::npos) << out;  // no truth composed
  EXPECT_EQ(count(out, "not judged (--cost-only: no ground truth)"), 1u) << out;
  std::ifstream in(json_path);
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_TRUE(j.at("cost_only").get<bool>());
  for (const char* mip : {"1", "2"}) {
    const nlohmann::json& m = j.at("methods").at("blendmap").at(mip);
    EXPECT_DOUBLE_EQ(m.at("direct").at("cost_vs_direct").get<double>(), 1.0) << mip;
    for (const char* strategy : {"direct", "prefiltered", "supersample:2"}) {
      const double ms = m.at(strategy).at("ms_per_page").get<double>();
      EXPECT_TRUE(std::isfinite(ms) && ms > 0.0) << strategy << " mip " << mip;
      EXPECT_FALSE(m.at(strategy).contains("psnr_db")) << strategy << " mip " << mip;
    }
    EXPECT_FALSE(m.contains("ground_truth")) << mip;
    EXPECT_FALSE(m.contains("target_met")) << mip;
  }
  EXPECT_FALSE(fs::exists(dir / "costs.svg"));  // nothing to plot without PSNR
  fs::remove_all(dir);
}

TEST(BenchMipsCli, BadFlagsNameTheFlagAndWriteNothing) {
  const fs::path dir = tvt::test::fresh_test_dir("tvt_bench_mips_bad");
  const std::string scene = tvt::test::write_small_default_scene(dir);
  const fs::path json_path = dir / "m.json";
  const std::pair<std::string, std::string> cases[] = {
      {"--method nope", "--method"},
      {"--method blendmap,bogus", "--method"},
      {"--mips 0", "--mips"},
      {"--mips 7", "--mips"},
      {"--pages 0", "--pages"},
      {"--repeats 0", "--repeats"},
      {"--svg " + (dir / "missing" / "x.svg").string(), "--svg"},
      {"--cost-only --svg " + (dir / "x.svg").string(), "--svg"},  // a plot of PSNR, which it does not measure
  };
  for (const auto& [flags, field] : cases) {
    std::string out;
    EXPECT_NE(run_bench_mips(dir, scene, "--mips 1 --pages 1 --repeats 1 " + flags, json_path, out), 0) << flags;
    EXPECT_NE(out.find(field), std::string::npos) << flags << ": " << out;
    EXPECT_FALSE(fs::exists(json_path)) << flags;
  }
  fs::remove_all(dir);
}
