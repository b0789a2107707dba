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
  const Objective obj(p, ObjectiveParams{0.5, 0.01, 1.0, {}});
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
  const Objective obj(p, ObjectiveParams{1.0, 0.0, 1.0, {}});
  SolverOptions o;
  o.relative_tolerance = 1e-15;
  const LoggedRun fast = SolveLogged(SolverKind::kFast, obj, o);
  ExpectSane(fast);
  for (int k = 0; k < p.unknown_cells; ++k)
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(fast.result.lambda[3 * k + c], rp.truth[3 * p.cell_of[k] + c], 1e-4) << k << "," << c;
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
