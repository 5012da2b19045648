// The one stereo pairer (pipeline/stereo_pairer.hpp) that a bag's image
// topics and the server's cameras go through: pairs within the tolerance,
// an older image without a partner given up, a side that runs ahead bounded,
// what is left at the end handed back left side first.
#include "pipeline/stereo_pairer.hpp"

#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

namespace locaid::pipeline {
namespace {

constexpr int64_t kMs = 1'000'000;

// Images are their names; every event the pairer reports, in order.
struct Events {
  std::vector<std::string> seen;
  void Pair(StereoPairer<std::string>& p) {
    p.Pair([this](const std::string& l, const std::string& r) { seen.push_back("pair " + l + "+" + r); },
           [this](StereoSide side, const std::string& image) {
             seen.push_back(std::string(side == StereoSide::kLeft ? "left" : "right") + " alone " + image);
           });
  }
};

TEST(StereoPairer, PairsWithinTheToleranceAndGivesUpTheOlderImageOtherwise) {
  StereoPairer<std::string> pairer(5 * kMs, 8);
  Events e;
  EXPECT_FALSE(pairer.Add(StereoSide::kLeft, 100 * kMs, "L100"));
  e.Pair(pairer);  // no right image yet: nothing
  EXPECT_FALSE(pairer.Add(StereoSide::kRight, 104 * kMs, "R104"));
  e.Pair(pairer);  // 4 ms apart: a pair
  EXPECT_FALSE(pairer.Add(StereoSide::kRight, 200 * kMs, "R200"));
  EXPECT_FALSE(pairer.Add(StereoSide::kLeft, 190 * kMs, "L190"));
  e.Pair(pairer);  // 10 ms apart: the left is older, it has no partner; R200 waits
  EXPECT_FALSE(pairer.Add(StereoSide::kLeft, 205 * kMs, "L205"));
  e.Pair(pairer);  // exactly 5 ms: a pair
  EXPECT_EQ(e.seen, (std::vector<std::string>{"pair L100+R104", "left alone L190", "pair L205+R200"}));
}

TEST(StereoPairer, ASideThatRunsAheadKeepsItsNewestImages) {
  StereoPairer<std::string> pairer(5 * kMs, 2);
  EXPECT_FALSE(pairer.Add(StereoSide::kLeft, 100 * kMs, "L100"));
  EXPECT_FALSE(pairer.Add(StereoSide::kLeft, 200 * kMs, "L200"));
  const std::optional<std::string> pushed_out = pairer.Add(StereoSide::kLeft, 300 * kMs, "L300");
  ASSERT_TRUE(pushed_out);
  EXPECT_EQ(*pushed_out, "L100");
  Events e;
  EXPECT_FALSE(pairer.Add(StereoSide::kRight, 301 * kMs, "R301"));
  e.Pair(pairer);
  EXPECT_EQ(e.seen, (std::vector<std::string>{"left alone L200", "pair L300+R301"}));
}

TEST(StereoPairer, DrainHandsBackWhatWaitsLeftSideFirstAndClearForgetsIt) {
  StereoPairer<std::string> pairer(5 * kMs, 8);
  pairer.Add(StereoSide::kRight, 100 * kMs, "R100");
  pairer.Add(StereoSide::kRight, 200 * kMs, "R200");
  std::vector<std::string> left_over;
  pairer.Drain([&](StereoSide, const std::string& image) { left_over.push_back(image); });
  EXPECT_EQ(left_over, (std::vector<std::string>{"R100", "R200"}));
  left_over.clear();
  pairer.Drain([&](StereoSide, const std::string& image) { left_over.push_back(image); });
  EXPECT_TRUE(left_over.empty()) << "drained: nothing waits";

  pairer.Add(StereoSide::kLeft, 300 * kMs, "L300");
  pairer.Clear();
  Events e;
  pairer.Add(StereoSide::kRight, 301 * kMs, "R301");
  e.Pair(pairer);
  EXPECT_TRUE(e.seen.empty()) << "cleared: L300 is gone, R301 waits";
}

}  // namespace
}  // namespace locaid::pipeline
