#include "estimation/objective.h"

#include <cmath>

#include <gtest/gtest.h>

#include "tests/estimation/problem_fixture.h"

namespace lp {
namespace {

TEST(Objective, GradientMatchesCentralFiniteDifferences) {
  const auto rp = test::MakeRandomProblem(120, 20, 0.3, 0.2, 11);
  const LinearProblem p = MakeLinearProblem(rp.A, rp.y);
  // The last case weights the penalty per cell (as the estimator does by solid angle).
  std::vector<double> weights(p.unknown_cells);
  for (int j = 0; j < p.unknown_cells; ++j) weights[j] = 0.3 + 0.1 * j;
  for (const ObjectiveParams& prm : {ObjectiveParams{0.3, 0.5, 2.0, {}}, ObjectiveParams{5.0, 0.0, 1.0, {}},
                                    ObjectiveParams{0.05, 2.0, 0.1, {}}, ObjectiveParams{2.0, 0.5, 1.5, weights}}) {
    const Objective obj(p, prm);
    std::vector<double> lambda(obj.unknowns());
    for (std::size_t i = 0; i < lambda.size(); ++i) lambda[i] = 0.2 + 0.05 * (i % 7);
    std::vector<double> g;
    obj.ValueAndGradient(lambda, &g);
    for (std::size_t i = 0; i < lambda.size(); ++i) {
      const double h = 1e-5;
      std::vector<double> lp = lambda, lm = lambda;
      lp[i] += h;
      lm[i] -= h;
      const double fd = (obj.Value(lp) - obj.Value(lm)) / (2 * h);
      EXPECT_LT(std::abs(fd - g[i]), 1e-6 * std::max(1.0, std::abs(g[i])))
          << "unknown " << i << " fd " << fd << " analytic " << g[i];
    }
  }
}

TEST(Objective, UnreachedCellsAreLeftOut) {
  auto rp = test::MakeRandomProblem(50, 10, 0.3, 0.0, 3);
  // Add 5 columns nobody touches.
  rp.A.cells = 15;
  const LinearProblem p = MakeLinearProblem(rp.A, rp.y);
  EXPECT_EQ(p.unknown_cells, 10);
}

TEST(Objective, TransposeIsTheAdjoint) {
  const auto rp = test::MakeRandomProblem(80, 12, 0.4, 0.1, 5);
  const LinearProblem p = MakeLinearProblem(rp.A, rp.y);
  std::vector<double> x(3 * p.unknown_cells), v(3 * p.rows()), Ax, Atv;
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::sin(1.0 + i);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = std::cos(2.0 + i);
  p.Multiply(x, &Ax);
  p.MultiplyTransposed(v, &Atv);
  double a = 0, b = 0;
  for (std::size_t i = 0; i < v.size(); ++i) a += Ax[i] * v[i];
  for (std::size_t i = 0; i < x.size(); ++i) b += Atv[i] * x[i];
  EXPECT_NEAR(a, b, 1e-9 * std::abs(a));
}

}  // namespace
}  // namespace lp
