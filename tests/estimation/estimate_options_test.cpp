// The one table of an estimate's options: every default valid, every range enforced by
// Validate and by SetEstimateOption (the command line's and the command file's way in),
// text round trips, choices and flags by name.
#include <algorithm>
#include <cmath>
#include <functional>
#include <string>

#include <gtest/gtest.h>

#include "common/error.h"
#include "estimation/estimate_options.h"
#include "tests/test_util.h"

namespace lp {
namespace {

using test::ErrorOf;

TEST(EstimateOptions, TheDefaultsAreValidAndEveryOptionRoundTripsAsText) {
  const EstimateOptions defaults;
  EXPECT_NO_THROW(Validate(defaults));
  EXPECT_GE(EstimateOptionTable().size(), 18u);
  for (const EstimateOption& option : EstimateOptionTable()) {
    EstimateOptions o;
    option.set(&o, option.type == EstimateOption::Type::kBool ? 1 - option.get(defaults) : option.get(defaults));
    SetEstimateOption(&o, option.key, EstimateOptionText(option, defaults));
    EXPECT_EQ(option.get(o), option.get(defaults)) << option.key;
    EXPECT_EQ(FindEstimateOption(option.key), &option);
  }
}

TEST(EstimateOptions, EveryRangeIsEnforcedInOnePlace) {
  for (const EstimateOption& option : EstimateOptionTable()) {
    if (option.type == EstimateOption::Type::kChoice) continue;
    // Just below the range (or at an exclusive minimum), and just above a finite maximum.
    const double below = option.min_exclusive ? option.min : option.min - 1;
    EstimateOptions o;
    option.set(&o, below);
    if (option.get(o) == below) {  // (an unsigned or bool member cannot hold it)
      const std::string why = ErrorOf([&] { Validate(o); });
      EXPECT_NE(why.find(std::string(option.key) + " must be"), std::string::npos) << option.key << ": " << why;
    }
    char text[64];
    std::snprintf(text, sizeof text, "%.17g", below);
    EXPECT_NE(ErrorOf([&] { SetEstimateOption(&o, option.key, text); }).find(option.key), std::string::npos)
        << option.key;
    if (std::isfinite(option.max)) {
      std::snprintf(text, sizeof text, "%.17g", option.max + std::max(1.0, option.max));  // (2^53 + 1 is 2^53)
      EXPECT_NE(ErrorOf([&] { SetEstimateOption(&o, option.key, text); }).find("between"), std::string::npos)
          << option.key;
    }
  }
  EstimateOptions o;
  o.objective.sigma = std::nan("");
  EXPECT_EQ(ErrorOf([&] { Validate(o); }), "sigma must be positive and finite");
  o = EstimateOptions{};
  o.rings = 1;
  EXPECT_EQ(ErrorOf([&] { Validate(o); }), "rings must be between 2 and 181");
}

TEST(EstimateOptions, TextIsReadOneWayEverywhere) {
  EstimateOptions o;
  SetEstimateOption(&o, "solver", "gradient");
  EXPECT_EQ(o.solver, SolverKind::kGradient);
  EXPECT_NE(ErrorOf([&] { SetEstimateOption(&o, "solver", "newton"); }).find("unknown solver 'newton'"),
            std::string::npos);
  EXPECT_EQ(o.solver, SolverKind::kGradient) << "a refused value leaves the option as it was";
  SetEstimateOption(&o, "directional-lights", "false");
  EXPECT_FALSE(o.directional_lights);
  SetEstimateOption(&o, "directional-lights", "1");
  EXPECT_TRUE(o.directional_lights);
  SetEstimateOption(&o, "rounds", "3");  // the command file's older key for max-rounds
  EXPECT_EQ(o.max_rounds, 3);
  SetEstimateOption(&o, "trace-pixels", "2.5");
  EXPECT_EQ(o.trace_pixels, 2.5);
  EXPECT_NE(ErrorOf([&] { SetEstimateOption(&o, "rings", "21.5"); }).find("whole number"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { SetEstimateOption(&o, "spp", "8x"); }).find("must be a number"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { SetEstimateOption(&o, "colour", "1"); }).find("unknown setting 'colour'"),
            std::string::npos);
  EXPECT_EQ(o.rings, 21);
}

}  // namespace
}  // namespace lp
