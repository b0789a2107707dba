#include "estimation/solver.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/error.h"
#include "tests/estimation/problem_fixture.h"

namespace lp {
namespace {

struct LoggedRun {
  SolveResult result;
  std::vector<double> objectives;
};

LoggedRun SolveLogged(SolverKind kind, const Objective& obj, const SolverOptions& base) {
  LoggedRun run;
  SolverOptions o = base;
  o.on_iteration = [&](const IterationInfo& it) { run.objectives.push_back(it.objective); };
  run.result = Solve(kind, obj, std::vector<double>(obj.unknowns(), 1e-3), o);
  return run;
}

void ExpectSane(const LoggedRun& run) {
  for (double v : run.result.lambda) {
    ASSERT_TRUE(std::isfinite(v));
    ASSERT_GE(v, 0.0);
  }
  for (std::size_t i = 1; i < run.objectives.size(); ++i) EXPECT_LE(run.objectives[i], run.objectives[i - 1]);
  EXPECT_FALSE(run.result.objective_increased);
}

TEST(Solver, BothSolversReachTheSameObjective) {
  const auto rp = test::MakeRandomProblem(300, 30, 0.25, 0.05, 21);
  const LinearProblem p = MakeLinearProblem(rp.A, rp.y);
  const Objective obj(p, ObjectiveParams{0.5, 0.01, 1.0, {}, 0, {}});
  SolverOptions o;
  o.max_iterations = 500;
  o.relative_tolerance = 1e-14;
  o.gradient_tolerance = 1e-10;
  o.adaptive_step = true;  // the paper's fixed initial step gets there too, ~20x slower
  const LoggedRun fast = SolveLogged(SolverKind::kFast, obj, o);
  const LoggedRun grad = SolveLogged(SolverKind::kGradient, obj, o);
  ExpectSane(fast);
  ExpectSane(grad);
  EXPECT_NEAR(fast.result.objective, grad.result.objective, 1e-6 * std::abs(fast.result.objective));
  EXPECT_LT(fast.result.kkt_violation, 1e-6);
}

TEST(Solver, RecoversTheSparseAnswerWithoutNoise) {
  const auto rp = test::MakeRandomProblem(300, 30, 0.25, 0.0, 8);
  const LinearProblem p = MakeLinearProblem(rp.A, rp.y);
  const Objective obj(p, ObjectiveParams{1.0, 0.0, 1.0, {}, 0, {}});
  SolverOptions o;
  o.relative_tolerance = 1e-15;
  const LoggedRun fast = SolveLogged(SolverKind::kFast, obj, o);
  ExpectSane(fast);
  for (int k = 0; k < p.unknown_cells; ++k)
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(fast.result.lambda[3 * k + c], rp.truth[3 * p.cell_of[k] + c], 1e-4) << k << "," << c;
}

// The map's smoothness fills what the data hardly fix: a chain of 300 cells, each seen by one
// pixel, the two ends strongly (observing 1 and 3), the others a thousand times more weakly
// (observing values between 1 and 3 that jump from cell to cell). With the chain's smoothness
// (weight 1) the map is the straight line between the ends, which the smoothness pulls towards
// each other: with the ends' data curvature 1, the slope s = 2 / (n - 1 + 2), the ends 1 + s
// and 3 - s (closed form, up to the weak pixels' pull); without it, the jumps. The support (300
// cells) is wider than the NNQP's exact phase takes without a smoothness.
TEST(Solver, TheSmoothnessFillsWhatTheDataHardlyFix) {
  const int n = 300;
  const double weak = 1e-3;
  TransportMatrix A;
  A.cells = n;
  A.row_start = {0};
  std::vector<double> y;
  for (int j = 0; j < n; ++j) {
    const bool end = j == 0 || j == n - 1;
    const float a = end ? 1.0f : static_cast<float>(weak);
    A.col.push_back(j);
    A.val.push_back({a, a, a});
    A.row_start.push_back(static_cast<std::int64_t>(A.col.size()));
    A.row_view.push_back(0);
    A.row_pixel.push_back(j);
    const double seen = j == 0 ? 1 : j == n - 1 ? 3 : 2 + std::sin(3.0 * j);
    for (int c = 0; c < 3; ++c) y.push_back(a * seen);
  }
  const LinearProblem p = MakeLinearProblem(A, y);
  ASSERT_EQ(p.unknown_cells, n);
  ObjectiveParams prm{10.0, 0.0, 1.0, {}, 1.0, {}};  // a Cauchy scale far above the residuals: least squares
  for (int j = 0; j + 1 < n; ++j) prm.neighbours.push_back({j, j + 1, 1.0});
  SolverOptions o;
  o.max_iterations = 200;
  o.relative_tolerance = 1e-14;
  const LoggedRun smooth = SolveLogged(SolverKind::kFast, Objective(p, prm), o);
  ExpectSane(smooth);
  EXPECT_LT(smooth.result.kkt_violation, 1e-6);
  const double s = 2.0 / (n - 1 + 2);
  double worst = 0;
  for (int k = 0; k < n; ++k) {
    const int j = p.cell_of[k];
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(smooth.result.lambda[3 * k + c] - (1 + s + j * s)));
  }
  EXPECT_LT(worst, 2e-3);
  prm.smooth = 0;
  const LoggedRun jagged = SolveLogged(SolverKind::kFast, Objective(p, prm), o);
  double off = 0;
  for (int k = 0; k < n; ++k) off = std::max(off, std::abs(jagged.result.lambda[3 * k] - (1 + s + p.cell_of[k] * s)));
  EXPECT_GT(off, 0.5);  // each weak cell its own pixel's value
}

TEST(Nnqp, SatisfiesKktOnAnIllConditionedProblem) {
  // Near-collinear columns: G = B^T B with B's columns almost equal.
  const int n = 40, m = 60;
  std::vector<double> B(static_cast<std::size_t>(m) * n);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < n; ++j) B[static_cast<std::size_t>(j) * m + i] = 1.0 + std::sin(i * 0.1) + 1e-4 * std::cos(i * j);
  std::vector<double> G(static_cast<std::size_t>(n) * n, 0.0), b(n, 0.0);
  for (int a = 0; a < n; ++a) {
    for (int c = 0; c < n; ++c)
      for (int i = 0; i < m; ++i) G[static_cast<std::size_t>(a) * n + c] += B[a * m + i] * B[c * m + i];
    G[static_cast<std::size_t>(a) * n + a] += 1e-10;
    for (int i = 0; i < m; ++i) b[a] += B[a * m + i] * (i % 3 == 0 ? 2.0 : 0.5);
  }
  std::vector<double> x(n, 0.0);
  SolveNnqp(G, b, n, &x);
  for (int a = 0; a < n; ++a) {
    ASSERT_GE(x[a], 0.0);
    double g = -b[a];
    for (int c = 0; c < n; ++c) g += G[static_cast<std::size_t>(a) * n + c] * x[c];
    if (x[a] > 0) EXPECT_NEAR(g, 0.0, 1e-6 * std::abs(b[a]));
    else EXPECT_GE(g, -1e-6 * std::abs(b[a]));
  }
}

TEST(Solver, UnknownSolverNameIsAnInputError) {
  EXPECT_THROW(ParseSolverKind("newton"), InputError);
  EXPECT_EQ(ParseSolverKind("fast"), SolverKind::kFast);
  EXPECT_EQ(ParseSolverKind("gradient"), SolverKind::kGradient);
}

}  // namespace
}  // namespace lp
