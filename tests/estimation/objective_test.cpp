#include "estimation/objective.h"

#include <cmath>

#include <gtest/gtest.h>

#include "tests/estimation/problem_fixture.h"

namespace lp {
namespace {

/// `prm` with a smoothness between each cell and the next two (weights unequal).
ObjectiveParams Smooth(ObjectiveParams prm, int cells) {
  prm.smooth = 0.7;
  for (int j = 0; j + 1 < cells; ++j) {
    prm.neighbours.push_back({j, j + 1, 0.5 + 0.1 * j});
    if (j + 2 < cells) prm.neighbours.push_back({j, j + 2, 1.5});
  }
  return prm;
}

/// The objective's gradient at `lambda` against central differences of step `h`, each within
/// `tolerance` of max(1, |g|).
void ExpectGradientIsCentralDifferences(const Objective& obj, const std::vector<double>& lambda, double h,
                                        double tolerance) {
  std::vector<double> g;
  obj.ValueAndGradient(lambda, &g);
  for (std::size_t i = 0; i < lambda.size(); ++i) {
    std::vector<double> lp = lambda, lm = lambda;
    lp[i] += h;
    lm[i] -= h;
    const double fd = (obj.Value(lp) - obj.Value(lm)) / (2 * h);
    EXPECT_LT(std::abs(fd - g[i]), tolerance * std::max(1.0, std::abs(g[i])))
        << "unknown " << i << " fd " << fd << " analytic " << g[i];
  }
}

// (the last case: the map's smoothness beside the weighted penalty)
TEST(Objective, GradientMatchesCentralFiniteDifferences) {
  const auto rp = test::MakeRandomProblem(120, 20, 0.3, 0.2, 11);
  const LinearProblem p = MakeLinearProblem(rp.A, rp.y);
  // The last case weights the penalty per cell (as the estimator does by solid angle).
  std::vector<double> weights(p.unknown_cells);
  for (int j = 0; j < p.unknown_cells; ++j) weights[j] = 0.3 + 0.1 * j;
  for (const ObjectiveParams& prm : {ObjectiveParams{0.3, 0.5, 2.0, {}, 0, {}}, ObjectiveParams{5.0, 0.0, 1.0, {}, 0, {}},
                                    ObjectiveParams{0.05, 2.0, 0.1, {}, 0, {}}, ObjectiveParams{2.0, 0.5, 1.5, weights, 0, {}},
                                    Smooth(ObjectiveParams{0.3, 0.5, 2.0, weights, 0, {}}, p.unknown_cells)}) {
    const Objective obj(p, prm);
    std::vector<double> lambda(obj.unknowns());
    for (std::size_t i = 0; i < lambda.size(); ++i) lambda[i] = 0.2 + 0.05 * (i % 7);
    ExpectGradientIsCentralDifferences(obj, lambda, 1e-5, 1e-6);
  }
}

TEST(Objective, AOneSidedRowCountsOnlyBelowItsLevel) {
  // A clipped pixel's value is a lower bound: its residual is max(0, y - A lambda). The
  // problem with every third row one-sided against the same problem without those rows and
  // with them two-sided, at points where the model is above and below them; and the
  // gradient against central differences (the loss is C1 at the level).
  const auto rp = test::MakeRandomProblem(90, 12, 0.3, 0.2, 5);
  LinearProblem one = MakeLinearProblem(rp.A, rp.y), two = one;
  one.one_sided.assign(one.y.size(), kExact);
  for (std::size_t r = 0; r < one.rows(); r += 3) std::fill_n(&one.one_sided[3 * r], 3, kAtLeast);
  const ObjectiveParams prm{0.3, 0.0, 1.0, {}, 0, {}};  // (the data term alone)
  const Objective o1(one, prm), o2(two, prm);
  for (const double level : {0.0, 0.35, 5.0}) {  // the model below every bound, mixed, above every bound
    std::vector<double> lambda(o1.unknowns(), level);
    std::vector<double> r1, r2;
    const double e1 = o1.Value(lambda, &r1), e2 = o2.Value(lambda, &r2);
    double expected = 0;
    const double s2 = prm.sigma * prm.sigma;
    for (std::size_t i = 0; i < r2.size(); ++i) {
      const double r = one.one_sided[i] == kAtLeast ? std::max(0.0, r2[i]) : r2[i];
      EXPECT_EQ(r1[i], r) << i;
      expected += 0.5 * s2 * std::log1p(r * r / s2);
    }
    EXPECT_NEAR(e1, expected, 1e-9 * std::max(1.0, expected));
    EXPECT_LE(e1, e2);                       // (a bound never costs more than an observation)
    if (level == 5.0) EXPECT_LT(e1, e2);  // (above them all: the bounds cost nothing)
    ExpectGradientIsCentralDifferences(o1, lambda, 1e-6, 1e-5);
  }
  // WithColumns keeps the flags.
  EXPECT_EQ(WithColumns(one, rp.A.cells, {std::vector<float>(one.y.size(), 0.1f)}).one_sided, one.one_sided);
}

TEST(Objective, AnUpperBoundCountsOnlyAboveItsLevel) {
  // A pixel beside a clipped one may be brightened by bloom: an upper bound, its residual
  // min(0, y - A lambda). Every third row an upper bound, the next a lower bound, against the
  // same rows two-sided; with the model below, around and above them; and the gradient
  // against central differences.
  const auto rp = test::MakeRandomProblem(90, 12, 0.3, 0.2, 5);
  LinearProblem bounded = MakeLinearProblem(rp.A, rp.y), exact = bounded;
  bounded.one_sided.assign(bounded.y.size(), kExact);
  for (std::size_t r = 0; r + 1 < bounded.rows(); r += 3) {
    std::fill_n(&bounded.one_sided[3 * r], 3, kAtMost);
    std::fill_n(&bounded.one_sided[3 * r + 3], 3, kAtLeast);
  }
  const ObjectiveParams prm{0.3, 0.0, 1.0, {}, 0, {}};
  const Objective ob(bounded, prm), oe(exact, prm);
  for (const double level : {0.0, 0.35, 5.0}) {
    std::vector<double> lambda(ob.unknowns(), level);
    std::vector<double> rb, re;
    const double eb = ob.Value(lambda, &rb), ee = oe.Value(lambda, &re);
    double expected = 0;
    const double s2 = prm.sigma * prm.sigma;
    int free = 0;
    for (std::size_t i = 0; i < re.size(); ++i) {
      const std::uint8_t b = bounded.one_sided[i];
      const double r = b == kAtMost ? std::min(0.0, re[i]) : b == kAtLeast ? std::max(0.0, re[i]) : re[i];
      EXPECT_EQ(rb[i], r) << i;
      free += b == kAtMost && re[i] > 0;  // (below an upper bound: free)
      expected += 0.5 * s2 * std::log1p(r * r / s2);
    }
    EXPECT_NEAR(eb, expected, 1e-9 * std::max(1.0, expected));
    EXPECT_LE(eb, ee);
    if (level == 0.0) EXPECT_GT(free, 0) << "the model below the upper bounds passes them";
    ExpectGradientIsCentralDifferences(ob, lambda, 1e-6, 1e-5);
  }
}

// The solver's over-relaxation evaluates E along its step without a pass over A:
// ValueOnSegment at t gives E and A x at x = max(0, lambda + t (next - lambda)), from A lambda
// and A next alone plus the columns of the unknowns the bound at 0 clips. Against Value and
// Multiply at that x, on a problem with both kinds of bound and the smoothness, for steps that
// clip no unknown, some and most.
TEST(Objective, EAlongAStepFromTheTwoModelsIsEAtThePoint) {
  const auto rp = test::MakeRandomProblem(150, 16, 0.3, 0.2, 3);
  LinearProblem p = MakeLinearProblem(rp.A, rp.y);
  p.one_sided.assign(p.y.size(), kExact);
  for (std::size_t r = 0; r + 1 < p.rows(); r += 4) {
    std::fill_n(&p.one_sided[3 * r], 3, kAtLeast);
    std::fill_n(&p.one_sided[3 * r + 3], 3, kAtMost);
  }
  const Objective obj(p, Smooth(ObjectiveParams{0.3, 0.5, 2.0, {}, 0, {}}, p.unknown_cells));
  std::vector<double> lambda(obj.unknowns()), next(obj.unknowns());
  for (std::size_t i = 0; i < lambda.size(); ++i) {
    lambda[i] = 0.1 + 0.04 * (i % 5);
    next[i] = lambda[i] + (i % 3 == 0 ? -0.03 : 0.02);  // every third falls: clipped at 0 once t is large
  }
  std::vector<double> model, model_next, r_model, h_model;
  obj.DataPass(lambda, nullptr, nullptr, &model);
  obj.DataPass(next, nullptr, nullptr, &model_next);
  int clipped_cases = 0;
  for (const double t : {1.0, 2.0, 4.0, 16.0, 64.0}) {
    std::vector<double> x, ax, want_ax;
    const double e = obj.ValueOnSegment(lambda, next, model, model_next, t, &x, &ax);
    int clipped = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double v = lambda[i] + t * (next[i] - lambda[i]);
      EXPECT_EQ(x[i], std::max(0.0, v)) << i;
      clipped += v < 0;
    }
    clipped_cases += clipped > 0;
    const double want = obj.Value(x);
    EXPECT_NEAR(e, want, 1e-10 * std::max(1.0, std::abs(want))) << "t " << t << ", " << clipped << " clipped";
    p.Multiply(x, &want_ax);
    ASSERT_EQ(ax.size(), want_ax.size());
    for (std::size_t k = 0; k < ax.size(); ++k) EXPECT_NEAR(ax[k], want_ax[k], 1e-10 * (1 + std::abs(want_ax[k]))) << k;
    // DataPass's model is A x too.
    std::vector<double> pass_ax;
    obj.DataPass(x, nullptr, nullptr, &pass_ax);
    for (std::size_t k = 0; k < ax.size(); ++k) EXPECT_NEAR(pass_ax[k], want_ax[k], 1e-12 * (1 + std::abs(want_ax[k]))) << k;
  }
  EXPECT_GE(clipped_cases, 2) << "the steps should clip some unknowns";
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

/// Dense columns for WithColumns: one all zero (not an unknown), one with holes, one full,
/// one non-zero in a single channel only.
std::vector<std::vector<float>> ExtraColumns(std::size_t rows) {
  std::vector<std::vector<float>> cols(4, std::vector<float>(3 * rows, 0.0f));
  for (std::size_t r = 0; r < rows; ++r) {
    if (r % 3 != 0)
      for (int c = 0; c < 3; ++c) cols[1][3 * r + c] = static_cast<float>(0.1 + 0.01 * r + c);
    for (int c = 0; c < 3; ++c) cols[2][3 * r + c] = static_cast<float>(std::cos(0.3 * r + c) + 1.5);
    if (r % 5 == 2) cols[3][3 * r + 1] = 0.25f;
  }
  return cols;
}

TEST(Objective, WithColumnsIsAppendColumnsEntryForEntry) {
  auto rp = test::MakeRandomProblem(60, 12, 0.3, 0.0, 9);
  rp.A.cells = 14;  // two cells no row touches: compact indices differ from cells
  const std::vector<std::vector<float>> cols = ExtraColumns(rp.A.rows());
  const LinearProblem want = MakeLinearProblem(AppendColumns(rp.A, cols), rp.y);
  const LinearProblem got = WithColumns(MakeLinearProblem(rp.A, rp.y), rp.A.cells, cols);
  EXPECT_EQ(got.unknown_cells, 12 + 3);
  EXPECT_EQ(got.cell_of, want.cell_of);
  EXPECT_EQ(got.row_start, want.row_start);
  EXPECT_EQ(got.col, want.col);
  EXPECT_EQ(got.val, want.val);
  EXPECT_EQ(got.col_start, want.col_start);
  EXPECT_EQ(got.col_row, want.col_row);
  EXPECT_EQ(got.col_val, want.col_val);
  EXPECT_EQ(got.col_pos, want.col_pos);
  EXPECT_EQ(got.y, want.y);
}

TEST(Objective, NormalMatricesFromABaseBlockAreTheSameBitForBit) {
  const auto rp = test::MakeRandomProblem(70, 11, 0.35, 0.0, 13);
  LinearProblem base = MakeLinearProblem(rp.A, rp.y);
  base.base_normal = MakeNormalMatrices(base);
  const std::vector<std::vector<float>> cols = ExtraColumns(rp.A.rows());
  const LinearProblem extended = WithColumns(base, rp.A.cells, cols);
  ASSERT_TRUE(extended.base_normal);
  LinearProblem plain = extended;
  plain.base_normal.reset();
  std::vector<double> a[3], b[3];
  BuildNormalMatrices(extended, a);
  BuildNormalMatrices(plain, b);
  const int L = extended.unknown_cells;
  for (int c = 0; c < 3; ++c) {
    ASSERT_EQ(a[c].size(), static_cast<std::size_t>(L) * L);
    EXPECT_EQ(a[c], b[c]) << "channel " << c;
  }
  // Against the definition, G_c(i, j) = sum_r A_ric A_rjc, summed densely.
  std::vector<double> dense(static_cast<std::size_t>(extended.rows()) * L * 3, 0.0);
  for (std::size_t r = 0; r < extended.rows(); ++r)
    for (std::int64_t k = extended.row_start[r]; k < extended.row_start[r + 1]; ++k)
      for (int c = 0; c < 3; ++c) dense[(r * L + extended.col[k]) * 3 + c] = extended.val[k][c];
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < L; ++i)
      for (int j = 0; j < L; ++j) {
        double g = 0;
        for (std::size_t r = 0; r < extended.rows(); ++r) g += dense[(r * L + i) * 3 + c] * dense[(r * L + j) * 3 + c];
        EXPECT_NEAR(a[c][static_cast<std::size_t>(j) * L + i], g, 1e-9 * (1 + std::abs(g)));
      }
  // A base over other rows is not used (its block, doubled, would show).
  LinearProblem other = extended;
  auto wrong = std::make_shared<NormalMatrices>(*extended.base_normal);
  wrong->rows += 1;
  for (double& v : wrong->G[0]) v *= 2;
  other.base_normal = wrong;
  std::vector<double> o[3];
  BuildNormalMatrices(other, o);
  EXPECT_EQ(o[0], b[0]);
}

}  // namespace
}  // namespace lp
