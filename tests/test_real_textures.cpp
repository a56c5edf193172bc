// Automatic feature isolation on real tileable textures from Debian packages
// (tests/data/textures/README.md: sources, licences, how each was hand-counted). Asserted: the
// polarity (which side is the features) on every image, with the defaults scene loading uses.
// Measured on every hand-counted image, with the defaults and with the joint cut
// (IsolationOptions::cut_joints): the count against the hand count (bound: 10 %) and the
// largest feature against the median (bound: 3x, or the hand-measured ratio where the image
// really has a bigger feature: tiles.png's big slab). Each bound is asserted where counts.txt
// records that it is met today (last column), so what works stays working; the misses are
// printed with their figures (docs/metatex.md, "On real photographs").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "compose/feature_isolation.h"
#include "compose/material_image.h"

namespace {

struct RealTexture {
  std::string file;
  uint32_t hand_count = 0;      // 0: not counted
  bool features_light = false;  // the features are the lighter side (dark mortar / grout)
  std::string how;              // careful, ambiguous
  double max_ratio = 3.0;       // largest / median feature area allowed
  std::string meets;            // bounds met today, per mode: "default:ca,joints:c" (c count, a area), "-"
};

// tests/data/textures/counts.txt: "<file> <hand count> <light|dark> <how> <largest/median allowed>
// <bounds met>" per line, '#' comments.
std::vector<RealTexture> read_counts() {
  std::ifstream in(std::string(TVT_SOURCE_DIR) + "/tests/data/textures/counts.txt");
  std::vector<RealTexture> textures;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    RealTexture t;
    std::string side;
    fields >> t.file >> t.hand_count >> side >> t.how >> t.max_ratio >> t.meets;
    if (!fields || (side != "light" && side != "dark") || !(t.max_ratio >= 1.0)) {
      ADD_FAILURE() << "counts.txt: bad line '" << line << "'";
      continue;
    }
    t.features_light = side == "light";
    textures.push_back(t);
  }
  return textures;
}

TEST(RealTextures, TheSetHasAtLeastSixCountedTexturesWithBothPolarities) {
  std::vector<RealTexture> counted;
  for (const RealTexture& t : read_counts())
    if (t.hand_count > 0) counted.push_back(t);
  EXPECT_GE(counted.size(), 6u);
  EXPECT_TRUE(std::any_of(counted.begin(), counted.end(), [](const RealTexture& t) { return t.features_light; }))
      << "a dark-mortar image";
  EXPECT_TRUE(std::any_of(counted.begin(), counted.end(), [](const RealTexture& t) { return !t.features_light; }))
      << "a light-mortar image";
}

tvt::FeatureLabels isolate(const RealTexture& t, tvt::IsolationReport& report,
                           const tvt::IsolationOptions& options = tvt::IsolationOptions{}) {
  auto image = tvt::load_material_image(std::string(TVT_SOURCE_DIR) + "/tests/data/textures/" + t.file, {});
  if (!image.ok()) {
    ADD_FAILURE() << image.error().message;
    return {};
  }
  return tvt::isolate_features(image->image, options, &report);
}

// Light mortar (flagstones.png) and dark grout, mortar and gaps (the others) alike.
TEST(RealTextures, PolarityIsTheSideThatIsNotTheNetwork) {
  for (const RealTexture& t : read_counts()) {
    tvt::IsolationReport report;
    isolate(t, report);
    EXPECT_EQ(report.features_light, t.features_light) << t.file << ": " << report.summary();
  }
}

// Whether counts.txt records bound `bound` ('c' or 'a') as met in `mode` ("default", "joints").
bool recorded_as_met(const RealTexture& t, const std::string& mode, char bound) {
  std::istringstream entries(t.meets);
  std::string entry;
  while (std::getline(entries, entry, ','))
    if (entry.rfind(mode + ":", 0) == 0) return entry.find(bound, mode.size() + 1) != std::string::npos;
  return false;
}

TEST(RealTextures, AutomaticCountsAreWithinTenPercentOfTheHandCounts) {
  for (const RealTexture& t : read_counts()) {
    if (t.hand_count == 0) continue;
    for (const std::string mode : {"default", "joints"}) {
      SCOPED_TRACE(t.file + " (" + t.how + "), " + mode);
      tvt::IsolationOptions options;
      options.cut_joints = mode == "joints";
      tvt::IsolationReport report;
      const tvt::FeatureLabels labels = isolate(t, report, options);
      std::vector<uint32_t> areas(labels.count, 0);
      for (int32_t l : labels.labels)
        if (l >= 0) ++areas[size_t(l)];
      ASSERT_FALSE(areas.empty());
      std::vector<uint32_t> sorted = areas;
      std::nth_element(sorted.begin(), sorted.begin() + ptrdiff_t(sorted.size() / 2), sorted.end());
      const uint32_t median = sorted[sorted.size() / 2];
      const uint32_t largest = *std::max_element(areas.begin(), areas.end());
      const bool count_ok = std::abs(double(labels.count) - double(t.hand_count)) <= 0.1 * t.hand_count;
      const bool area_ok = double(largest) <= t.max_ratio * double(median);
      std::cout << "[ figures  ] " << t.file << " " << mode << ": found " << labels.count << ", hand " << t.hand_count
                << (count_ok ? " (within 10 %)" : " (outside 10 %)") << "; largest/median " << double(largest) / median
                << ", allowed " << t.max_ratio << (area_ok ? "" : " (over)") << "\n";
      if (recorded_as_met(t, mode, 'c')) {
        EXPECT_TRUE(count_ok) << "found " << labels.count << ", hand count " << t.hand_count << "; "
                              << report.summary();
      }
      if (recorded_as_met(t, mode, 'a')) {
        EXPECT_TRUE(area_ok) << "largest feature " << largest << " texels, median " << median << " (allowed "
                             << t.max_ratio << "x)";
      }
    }
  }
}

}  // namespace
