// The rule the map's prior is chosen by (EstimateResult::prior, docs/method.md "The map's
// prior"): the strongest weight whose held-out loss exceeds the least by no more than the
// standard error of that difference over the blocks; checked against the closed form.
#include <cmath>

#include <gtest/gtest.h>

#include "estimation/estimator.h"

namespace lp {
namespace {

TEST(PriorChoice, TheStrongestWithinOneStandardErrorOfItsDifferenceIsKept) {
  // Four blocks used and a fifth left out (its huge losses must not count). Weight 1 is the
  // least; weight 0 differs from it by (1, -1, 1, -0.5): 0.5 more, its deviations from
  // their mean 0.125 square to 3.1875, a standard error of sqrt(4 * 3.1875 / 3): kept.
  const std::vector<std::uint8_t> used = {1, 1, 1, 1, 0};
  std::vector<double> loss, se;
  std::size_t k = StrongestWithinOneStandardError({{11, 9, 11, 9.5, 1e9}, {10, 10, 10, 10, 0}}, used, &loss, &se);
  EXPECT_EQ(k, 0u);
  EXPECT_DOUBLE_EQ(loss[0], 40.5);
  EXPECT_DOUBLE_EQ(loss[1], 40);
  EXPECT_NEAR(se[0], std::sqrt(4 * 3.1875 / 3), 1e-12);
  EXPECT_EQ(se[1], 0);
  // Weight 0 worse by (2, 0, 2, 0): 4 more, standard error again sqrt(16 / 3) = 2.31: not
  // within it; weight 1 (the least) is the strongest that is.
  k = StrongestWithinOneStandardError({{12, 10, 12, 10, 0}, {10, 10, 10, 10, 0}, {10.5, 10.5, 9.5, 9.5, 0}}, used,
                                      &loss, &se);
  EXPECT_EQ(k, 1u);
  EXPECT_NEAR(se[0], std::sqrt(16.0 / 3), 1e-12);
  // A difference the same in every block (1 each) has no spread: any gain is trusted.
  k = StrongestWithinOneStandardError({{11, 11, 11, 11, 0}, {10, 10, 10, 10, 0}}, used, &loss, &se);
  EXPECT_EQ(k, 1u);
  EXPECT_EQ(se[0], 0);
  // The weakest is the least only by less than its blocks' spread: the strongest is kept.
  k = StrongestWithinOneStandardError({{10, 10, 10, 10, 0}, {10, 10, 10, 10, 0}, {13, 7, 12, 7.5, 0}}, used, &loss,
                                      &se);
  EXPECT_EQ(k, 0u);
}

TEST(PriorChoice, AWeakerWeightWithinTheErrorIsTakenWhenTheStrongestGainsTooLittle) {
  // Weight 0 (the given one) loses 100 in every block's sum; weight 2 is the least (96, a
  // 4 % gain); weight 1 (97.6, 2.4 %) is within one standard error of it (its differences
  // (-1, 1.6, -1, 2) have a standard error of sqrt(4 * 7.92 / 3) = 3.25 > 1.6) but gains
  // under 3 %: weight 2 is taken, not the given one. With 5 % asked none gains enough.
  const std::vector<std::uint8_t> used = {1, 1, 1, 1};
  const std::vector<std::vector<double>> block_loss = {{25, 25, 25, 25}, {23, 25.6, 23, 26}, {24, 24, 24, 24}};
  std::vector<double> loss, se;
  EXPECT_EQ(StrongestWithinOneStandardError(block_loss, used, &loss, &se), 1u);
  EXPECT_NEAR(se[1], std::sqrt(4 * 7.92 / 3), 1e-12);
  EXPECT_EQ(StrongestThatGains(block_loss, used, 0.03, &loss, &se), 2u);
  EXPECT_EQ(StrongestThatGains(block_loss, used, 0.05, &loss, &se), 0u);
  EXPECT_EQ(StrongestThatGains(block_loss, used, 0.02, &loss, &se), 1u);
}

}  // namespace
}  // namespace lp
