#include "estimation/solver.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "common/error.h"
#include "common/parallel.h"
#include "common/timer.h"

namespace lp {

SolverKind ParseSolverKind(const std::string& name) {
  if (name == "fast") return SolverKind::kFast;
  if (name == "gradient") return SolverKind::kGradient;
  throw InputError("unknown solver '" + name + "' (use fast or gradient)");
}

const char* ToString(SolverKind kind) { return kind == SolverKind::kFast ? "fast" : "gradient"; }

// ---------------------------------------------------------------------------------------------
// NNQP: min 0.5 x'Gx - b'x, x >= 0.

/// Solves NNQPs that share one matrix G, caching the Cholesky factor of the last
/// passive set: successive solves of an MM run mostly keep their support.
class NnqpSolver {
 public:
  /// Largest support solved exactly by the active-set phase (a wider one by coordinate descent).
  static constexpr int kMaxExactSupport = 256;
  /// ... where the map is smooth: its Laplacian couples every cell to its neighbours, and
  /// coordinate descent (Gauss-Seidel) needs of the order of a sweep per cell to carry a
  /// change across the map (Cycles' flat sky: 0.5-1.7 s a solve, 2000 sweeps).
  static constexpr int kMaxExactSmoothSupport = 2048;

  NnqpSolver(const double* G, int n, int max_exact_support = kMaxExactSupport)
      : G_(G, n, n), n_(n), max_exact_support_(max_exact_support) {
    // With thousands of cells most pairs share no path and G is mostly zeros: keep each
    // column's non-zero rows so coordinate updates cost O(non-zeros), not O(n).
    if (n < 256) return;
    std::size_t nnz = 0;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) nnz += G_(i, j) != 0;
    if (nnz > static_cast<std::size_t>(n) * n / 4) return;
    nonzero_rows_.resize(n);
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        if (G_(i, j) != 0) nonzero_rows_[j].push_back(i);
  }

  /// G x, touching only the columns where x is non-zero: the estimates are sparse (the
  /// penalty turns most cells off), so this is far cheaper than the dense product.
  template <typename Vec>
  Eigen::VectorXd Times(const Vec& x) const {
    Eigen::VectorXd out = Eigen::VectorXd::Zero(n_);
    for (int j = 0; j < n_; ++j)
      if (x[j] != 0) AddColumn(j, x[j], &out);
    return out;
  }

  /// Warm-started from x. `exact` = false: coordinate descent sweeps only (an
  /// approximate minimizer, enough for a candidate that is checked afterwards).
  int Solve(const double* bp, double* xp, bool exact = true) {
    const int n = n_;
    if (n == 0) return 0;
    Eigen::Map<const Eigen::VectorXd> b(bp, n);
    Eigen::Map<Eigen::VectorXd> x(xp, n);
    for (int i = 0; i < n; ++i)
      if (!(x[i] > 0)) x[i] = 0;  // also clears NaN
    double bscale = 0, dscale = 0;
    for (int i = 0; i < n; ++i) {
      bscale = std::max(bscale, std::abs(b[i]));
      dscale = std::max(dscale, G_(i, i));
    }
    if (bscale == 0) {
      x.setZero();
      return 0;
    }
    // 1. Projected coordinate descent to find the support cheaply.
    Eigen::VectorXd g = Times(x) - b;
    int support = 0;
    for (int i = 0; i < n; ++i) support += x[i] > 0;
    // A wide support (thousands of near-collinear cells, e.g. 61 rings at 4 spp) would make
    // the active-set phase cost O(support^3) per factorization: descend to a tight tolerance
    // instead (each sweep O(n^2), never increasing the quadratic).
    const bool wide = exact && support > max_exact_support_;
    const int sweeps = wide ? 2000 : 30;
    const double stop = wide ? 1e-10 : 1e-6;
    for (int sweep = 0; sweep < sweeps; ++sweep) {
      double change = 0, xmax = 0;
      for (int i = 0; i < n; ++i) {
        const double d = G_(i, i);
        if (!(d > 0)) continue;
        const double xi = std::max(0.0, x[i] - g[i] / d);
        const double delta = xi - x[i];
        if (delta != 0) {
          AddColumn(i, delta, &g);
          x[i] = xi;
          change = std::max(change, std::abs(delta));
        }
        xmax = std::max(xmax, x[i]);
      }
      if (change <= stop * xmax) break;
      if (!exact && sweep >= 4) break;
      if (exact && !wide && sweep == 29) {  // the support grew wide while descending
        support = 0;
        for (int i = 0; i < n; ++i) support += x[i] > 0;
        if (support > max_exact_support_) return Solve(bp, xp, exact);
      }
    }
    if (!exact || wide) return 0;
    // 2. Active set (Lawson-Hanson on the Gram form), warm-started from the support.
    const double tol = 1e-12 * std::max(bscale, dscale);
    std::vector<char> passive(n, 0);
    for (int i = 0; i < n; ++i) passive[i] = x[i] > 0;
    int iterations = 0;
    const int max_iterations = 3 * n + 50;
    while (iterations++ < max_iterations) {
      // Inner loop: move towards the unconstrained minimizer on the passive set, staying feasible.
      for (int inner = 0; inner <= n; ++inner) {
        SolvePassive(passive, b);
        double step = 1;
        int blocking = -1;
        for (std::size_t a = 0; a < P_.size(); ++a)
          if (z_[a] <= 0) {
            const double xi = x[P_[a]];
            const double ratio = xi - z_[a] > 0 ? xi / (xi - z_[a]) : 0.0;
            if (blocking < 0 || ratio < step) {
              step = ratio;
              blocking = P_[a];
            }
          }
        if (blocking < 0) {  // unconstrained minimizer is feasible
          for (std::size_t a = 0; a < P_.size(); ++a) x[P_[a]] = z_[a];
          break;
        }
        step = std::clamp(step, 0.0, 1.0);
        for (std::size_t a = 0; a < P_.size(); ++a) x[P_[a]] += step * (z_[a] - x[P_[a]]);
        x[blocking] = 0;  // the blocking variable leaves exactly
        for (std::size_t a = 0; a < P_.size(); ++a)
          if (x[P_[a]] <= 0) {
            x[P_[a]] = 0;
            passive[P_[a]] = 0;
          }
        passive[blocking] = 0;
      }
      // Optimality: the most negative gradient among the active (zero) variables.
      g = Times(x) - b;
      int add = -1;
      double most = -tol;
      for (int i = 0; i < n; ++i)
        if (!passive[i] && g[i] < most) {
          most = g[i];
          add = i;
        }
      if (add < 0) break;
      passive[add] = 1;
    }
    for (int i = 0; i < n; ++i)
      if (!(x[i] > 0)) x[i] = 0;
    return iterations;
  }

 private:
  /// out += scale * G column j (only its non-zero rows when G is sparse).
  void AddColumn(int j, double scale, Eigen::VectorXd* out) const {
    if (nonzero_rows_.empty()) {
      out->noalias() += scale * G_.col(j);
      return;
    }
    const double* col = G_.data() + static_cast<std::size_t>(j) * n_;
    for (int r : nonzero_rows_[j]) (*out)[r] += scale * col[r];
  }

  /// z_ = G_PP^{-1} b_P for the passive set P_ (factor reused when P is unchanged).
  void SolvePassive(const std::vector<char>& passive, const Eigen::Map<const Eigen::VectorXd>& b) {
    P_.clear();
    for (int i = 0; i < n_; ++i)
      if (passive[i]) P_.push_back(i);
    const int m = static_cast<int>(P_.size());
    Eigen::VectorXd bp(m);
    for (int a = 0; a < m; ++a) bp[a] = b[P_[a]];
    if (P_ != cached_P_) {
      Eigen::MatrixXd Gp(m, m);
      for (int c = 0; c < m; ++c)
        for (int a = 0; a < m; ++a) Gp(a, c) = G_(P_[a], P_[c]);
      llt_.compute(Gp);
      use_ldlt_ = llt_.info() != Eigen::Success;
      if (use_ldlt_) ldlt_.compute(Gp);
      cached_P_ = P_;
    }
    z_ = use_ldlt_ ? Eigen::VectorXd(ldlt_.solve(bp)) : Eigen::VectorXd(llt_.solve(bp));
    for (int a = 0; a < m; ++a)
      if (!std::isfinite(z_[a])) z_[a] = 0;
  }

  Eigen::Map<const Eigen::MatrixXd> G_;
  int n_;
  int max_exact_support_;
  std::vector<std::vector<int>> nonzero_rows_;  ///< per column, when G is sparse
  std::vector<int> P_, cached_P_{-1};
  Eigen::LLT<Eigen::MatrixXd> llt_;
  Eigen::LDLT<Eigen::MatrixXd> ldlt_;
  bool use_ldlt_ = false;
  Eigen::VectorXd z_;
};

int SolveNnqp(const std::vector<double>& G, const std::vector<double>& b, int n, std::vector<double>* x) {
  LP_CHECK(static_cast<int>(x->size()) == n && static_cast<int>(b.size()) == n, "NNQP sizes");
  NnqpSolver solver(G.data(), n);
  return solver.Solve(b.data(), x->data());
}

double IterationInfo::Rmse() const {
  if (!residual || residual->empty()) return 0;
  double s = 0;
  for (double v : *residual) s += v * v;
  return std::sqrt(s / residual->size());
}

namespace {

void Report(const SolverOptions& o, int it, double e, const std::vector<double>& lambda,
            const std::vector<double>& residual) {
  if (!o.on_iteration) return;
  IterationInfo info;
  info.iteration = it;
  info.objective = e;
  info.lambda = &lambda;
  info.residual = &residual;
  o.on_iteration(info);
}

}  // namespace

double OneSidedCurvature(double v) {
  if (!(v > 0)) return 1;
  // g(u) = log(1 + u^2) / (u + v)^2 rises from 0 at u = 0 to one maximum and falls after it:
  // g'(u) = 0 where u (u + v) = (1 + u^2) log(1 + u^2). Bisect that on a bracket.
  const auto slope = [v](double u) { return u * (u + v) - (1 + u * u) * std::log1p(u * u); };
  double lo = 0, hi = 1;
  while (slope(hi) > 0 && hi < 1e150) {
    lo = hi;
    hi *= 2;
  }
  for (int i = 0; i < 200 && hi - lo > 1e-12 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (slope(mid) > 0 ? lo : hi) = mid;
  }
  const double u = 0.5 * (lo + hi);
  // (a relative margin: the bisection's u is the maximum's to 1e-12, g flat there)
  return std::min(1.0, std::log1p(u * u) / ((u + v) * (u + v)) * (1 + 1e-9));
}

namespace {

/// Majorize-minimize. The Cauchy loss has curvature rho'' <= 1, so around the current
/// point lambda_k the data term is majorized by a quadratic with the constant matrix
/// G = A^T A (plus a tiny proximal term mu*I that keeps it positive definite):
///   M(x) = E(lambda_k) - h'(x - lambda_k) + 1/2 (x - lambda_k)' G (x - lambda_k) + P(x) - P(lambda_k),
/// h = A^T psi(y - A lambda_k), with the log penalty P kept exact. G is built once per solve
/// and then only updated where a row's curvature changes (Reweigh: rows far off the fit and
/// one-sided rows above their level need less than 1); each outer step costs one pass over A
/// (residual, E and h together) and then works in the L-dimensional space only: M is
/// minimized by reweighted l1 (P majorized by its tangent, a non-negative QP per channel),
/// each inner step lowering M. E(next) <= M(next) <= M(lambda_k) = E(lambda_k), so E never
/// increases.
/// Once progress slows (a step gains < 1 % of E), each outer step also tries a
/// continuation on the penalty weight (alpha/256, /64, /16, /4, then alpha; a few QPs in
/// L-space) and keeps whichever candidate has the lower M: reweighted l1 at full weight
/// zeroes cells early and tends to stop in poorer local minima of this non-convex E.
/// Early steps use approximate QPs (coordinate descent) and an over-relaxed step along
/// the MM direction, accepted only when E falls.
class MajorizeMinimize {
 public:
  MajorizeMinimize(const Objective& obj) : obj_(obj), p_(obj.problem()), prm_(obj.params()), L_(p_.unknown_cells) {
    BuildNormalMatrices(p_, G_);
    obj.AddSmoothnessCurvature(G_, L_);  // a quadratic: its own majorizer
    for (int c = 0; c < 3; ++c) {
      double trace = 0;
      for (int j = 0; j < L_; ++j) trace += G_[c][static_cast<std::size_t>(j) * L_ + j];
      const double mu = 1e-10 * trace / std::max(1, L_) + 1e-300;
      for (int j = 0; j < L_; ++j) G_[c][static_cast<std::size_t>(j) * L_ + j] += mu;
      MakeQp(c);
    }
    curvature_.assign(p_.y.size(), 1.0);
  }

  SolveResult Run(std::vector<double> lambda, const SolverOptions& o) {
    Stopwatch sw;
    SolveResult res;
    std::vector<double> r, h, m, r_next, h_next, m_next;  // residual, adjoint and model (A lambda)
    double e = obj_.DataPass(lambda, &r, &h, &m) + obj_.Penalty(lambda);
    double last_decrease = HUGE_VAL;
    for (int it = 1; it <= o.max_iterations; ++it) {
      // Far from convergence the support still moves: approximate QPs are enough there
      // (M is checked either way); exact ones take over when progress slows.
      const bool settling = last_decrease < 1e-2 * std::abs(e);
      SetCentre(lambda, h, r, settling && it > kOutlierAfter);
      std::vector<double> next;
      if (prm_.alpha > 0 && settling) {
        // The step and the continuation side by side: each is three channels' QPs, which
        // leave one of two cores idle half the time alone. (The continuation's QPs are
        // approximate: they touch no solver's state, only G.)
        std::vector<double> cont = lambda;
        ParallelFor(0, 2, [&](std::size_t task) {
          if (task == 0) {
            next = InnerMinimize(lambda, 1.0, 20, true);
            return;
          }
          for (int m = 8; m >= 1; m -= 2) cont = InnerMinimize(cont, std::ldexp(1.0, -m), 1);
          cont = InnerMinimize(cont, 1.0, 20, false);
        });
        if (Majorizer(cont) < Majorizer(next)) next.swap(cont);
      } else {
        next = InnerMinimize(lambda, 1.0, settling ? 20 : 3, settling);
        if (!settling && next == lambda) next = InnerMinimize(lambda, 1.0);
      }
      double e_next = obj_.DataPass(next, &r_next, &h_next, &m_next) + obj_.Penalty(next);
      // Over-relaxation: the unit-curvature majorizer is loose where residuals are large
      // (early on), so try longer steps along the MM direction while E keeps falling. A is
      // linear: each trial's E comes from the two models without a pass over A (only the
      // columns the bound at 0 clips are read), and one pass follows at the step taken.
      if (e_next < e) {
        std::vector<double> longer, m_long;
        bool longer_taken = false;
        for (double t = 2; t <= 64; t *= 2) {
          const double e_long = obj_.ValueOnSegment(lambda, next, m, m_next, t, &longer, &m_long);
          if (!(e_long < e_next)) break;
          next.swap(longer);
          m_next.swap(m_long);
          e_next = e_long;
          longer_taken = true;
        }
        // (A next computed again: carried from step to step, the rounding of the models would
        // grow by the step's factor each time)
        if (longer_taken) e_next = obj_.DataPass(next, &r_next, &h_next, &m_next) + obj_.Penalty(next);
      }
      res.iterations = it;
      if (!(e_next <= e)) {
        // A converged step can look like a rounding-level increase: keep the old point and stop.
        res.objective_increased = !(e_next <= e + 1e-9 * std::abs(e));
        res.converged = true;
        Report(o, it, e, lambda, r);
        break;
      }
      const double decrease = e - e_next;
      last_decrease = decrease;
      lambda.swap(next);
      r.swap(r_next);
      h.swap(h_next);
      m.swap(m_next);
      e = e_next;
      Report(o, it, e, lambda, r);
      if (decrease <= o.relative_tolerance * std::abs(e)) {
        res.converged = true;
        break;
      }
      if (sw.Seconds() > o.max_seconds) break;
    }
    res.lambda = std::move(lambda);
    res.objective = e;
    res.kkt_violation = obj_.KktViolation(res.lambda);
    return res;
  }

 private:
  void MakeQp(int c) {
    qp_[c] = std::make_unique<NnqpSolver>(G_[c].data(), L_,
                                          prm_.smooth > 0 ? NnqpSolver::kMaxExactSmoothSupport
                                                          : NnqpSolver::kMaxExactSupport);
  }

  /// Each row's curvature in the majorizer at lambda_k, G = A^T W A. Unit curvature (the
  /// Cauchy loss's bound, G built once) is loose where a row's residual is large: there the
  /// loss is flat, and rows the fit treats as outliers held lambda near lambda_k along their
  /// columns while the solve crawled along a valley of E (a glowing surface and the map
  /// cells that light the room alike: 3DJ with 2 keyframes, 9 of 20 rounds at the
  /// 200-iteration cap, docs/benchmarks.md session 47). So a row whose residual u (in sigma)
  /// lies beyond kOutlier gets the Cauchy loss's own reweighting, 1 / (1 + u^2) (the loss is
  /// concave in r^2: the quadratic with that curvature and the loss's slope lies above it and
  /// touches it at r), and a one-sided row above its level v sigma gets OneSidedCurvature(v)
  /// (its loss is flat there). A row's curvature may stay above what it needs (still a
  /// majorizer): it changes, by a rank-one update of G, only where it must rise or where it
  /// would fall to under half, so a step costs the rows that changed.
  void Reweigh(const std::vector<double>& lambda, const std::vector<double>& residual, bool outliers) {
    // Nothing to change before the outliers' turn, in a problem without one-sided rows.
    outliers_seen_ = outliers_seen_ || outliers;
    if (!outliers_seen_ && p_.one_sided.empty()) return;
    const double sigma = prm_.sigma;
    const std::size_t rows = p_.row_start.size() - 1;
    for (int c = 0; c < 3; ++c) {
      std::vector<std::pair<std::size_t, double>> change;  // (row, new curvature - old)
      for (std::size_t r = 0; r < rows; ++r) {
        const std::size_t i = 3 * r + c;
        double need = 1;
        if (!p_.one_sided.empty() && p_.one_sided[i]) {  // (exactly what it needs, each step)
          double render = 0;
          for (std::int64_t k = p_.row_start[r]; k < p_.row_start[r + 1]; ++k)
            render += p_.val[k][c] * lambda[3 * static_cast<std::size_t>(p_.col[k]) + c];
          // (how far past the bound on its free side: above a lower one, below an upper one)
          const double past = p_.one_sided[i] == kAtMost ? p_.y[i] - render : render - p_.y[i];
          if (past > 0) need = OneSidedCurvature(past / sigma);
          if (need != curvature_[i]) change.emplace_back(r, need - curvature_[i]);
          curvature_[i] = need;
          continue;
        }
        const double u = residual[i] / sigma;
        if (std::abs(u) > kOutlier && (outliers || curvature_[i] < 1)) need = 1 / (1 + u * u);
        if (need > curvature_[i] || need < 0.5 * curvature_[i]) {
          const double w = std::min(1.0, kHeadroom * need);
          change.emplace_back(r, w - curvature_[i]);
          curvature_[i] = w;
        }
      }
      if (change.empty()) continue;
      for (const auto& [r, d] : change)
        for (std::int64_t k = p_.row_start[r]; k < p_.row_start[r + 1]; ++k)
          for (std::int64_t m = p_.row_start[r]; m < p_.row_start[r + 1]; ++m)
            G_[c][static_cast<std::size_t>(p_.col[m]) * L_ + p_.col[k]] +=
                d * static_cast<double>(p_.val[k][c]) * p_.val[m][c];
      MakeQp(c);
    }
  }

  /// Fixes the expansion point lambda_k and h = A^T psi there (and G's rows' curvatures).
  void SetCentre(const std::vector<double>& lambda, const std::vector<double>& h, const std::vector<double>& residual,
                 bool outliers) {
    Reweigh(lambda, residual, outliers);
    centre_ = lambda;
    // The smoothness is in G (its curvature): its gradient at the centre leaves h.
    h_ = h;
    std::vector<double> smooth(h.size(), 0.0);
    obj_.AddSmoothnessGradient(lambda, &smooth);
    for (std::size_t i = 0; i < h_.size(); ++i) h_[i] -= smooth[i];
    for (int c = 0; c < 3; ++c) {
      Eigen::VectorXd x0(L_);
      for (int j = 0; j < L_; ++j) x0[j] = lambda[3 * j + c];
      const Eigen::VectorXd gx = qp_[c]->Times(x0);
      b0_[c].resize(L_);
      for (int j = 0; j < L_; ++j) b0_[c][j] = gx[j] + h_[3 * j + c];
    }
    penalty_centre_ = obj_.Activation(lambda);
  }

  /// M(x) - E(lambda_k), computed in L-space.
  double Majorizer(const std::vector<double>& x) const {
    double mc[3] = {0, 0, 0};  // per channel, summed in a fixed order
    ParallelFor(0, 3, [&](std::size_t c) {
      Eigen::VectorXd d(L_);
      for (int j = 0; j < L_; ++j) d[j] = x[3 * j + c] - centre_[3 * j + c];
      mc[c] = 0.5 * d.dot(qp_[c]->Times(d));
      for (int j = 0; j < L_; ++j) mc[c] -= h_[3 * j + c] * d[j];
    });
    return mc[0] + mc[1] + mc[2] + obj_.Activation(x) - penalty_centre_;
  }

  /// Reweighted l1 on M with the penalty weight scaled by `weight`, from x; at most
  /// `max_steps` QPs, stopping when M no longer decreases.
  std::vector<double> InnerMinimize(std::vector<double> x, double weight, int max_steps = 20, bool exact = true) {
    double m = weight == 1.0 ? Majorizer(x) : 0;
    std::vector<double> trial(x.size());
    for (int step = 0; step < max_steps; ++step) {
      // The channels' QPs are independent (the penalty's weights are fixed at x): one task each.
      ParallelFor(0, 3, [&](std::size_t c) {
        std::vector<double> bc(L_), xc(L_);
        for (int j = 0; j < L_; ++j) {
          const double cost = weight * obj_.Alpha(j) * prm_.beta / (1 + prm_.beta * (x[3 * j] + x[3 * j + 1] + x[3 * j + 2]));
          bc[j] = b0_[c][j] - cost;
          xc[j] = x[3 * j + c];
        }
        qp_[c]->Solve(bc.data(), xc.data(), exact && weight == 1.0);
        for (int j = 0; j < L_; ++j) trial[3 * j + c] = xc[j];
      });
      if (weight != 1.0) {  // continuation stage: no monotonicity to keep
        x.swap(trial);
        continue;
      }
      const double m_trial = Majorizer(trial);
      if (!(m_trial < m)) break;
      const double gain = m - m_trial;
      x.swap(trial);
      m = m_trial;
      if (gain <= 1e-13 * (1 + std::abs(m))) break;
      if (prm_.alpha == 0) break;  // no penalty to reweight: one QP minimizes M
    }
    return x;
  }

  const Objective& obj_;
  const LinearProblem& p_;
  const ObjectiveParams& prm_;
  const int L_;
  std::vector<double> G_[3];
  /// Residuals (in sigma) past which a row's curvature is the loss's own reweighting.
  static constexpr double kOutlier = 3;
  /// ... in a solve that has run this many outer steps (and settled): most solves end
  /// before, as they did with unit curvature (docs/method.md: past one sigma and from the
  /// start, the map-alone scenes and Cycles' frosted window came back poorer).
  static constexpr int kOutlierAfter = 60;
  /// A row's curvature when it changes: this much above what it needs (so that small changes
  /// of its residual do not each cost an update of G).
  static constexpr double kHeadroom = 1.25;
  std::vector<double> curvature_;  ///< each row and channel's curvature in G_
  bool outliers_seen_ = false;     ///< whether any step so far reweighted the outliers
  std::unique_ptr<NnqpSolver> qp_[3];
  std::vector<double> centre_, h_, b0_[3];
  double penalty_centre_ = 0;
};

SolveResult SolveMM(const Objective& obj, std::vector<double> lambda, const SolverOptions& o) {
  MajorizeMinimize mm(obj);
  return mm.Run(std::move(lambda), o);
}

SolveResult SolveGradient(const Objective& obj, std::vector<double> lambda, const SolverOptions& o) {
  Stopwatch sw;
  SolveResult res;
  std::vector<double> g, trial(lambda.size()), g_trial, r, r_trial;
  double e = obj.ValueAndGradient(lambda, &g, &r);
  // Initial step 1 / max_j (A^T A)_jj: the Hessian's scale along one coordinate, a natural
  // first guess that backtracking corrects (the Lipschitz constant can be larger).
  const LinearProblem& p = obj.problem();
  double diag = 0;
  for (int j = 0; j < p.unknown_cells; ++j)
    for (int c = 0; c < 3; ++c) {
      double sum = 0;
      for (std::int64_t k = p.col_start[j]; k < p.col_start[j + 1]; ++k)
        sum += static_cast<double>(p.col_val[k][c]) * p.col_val[k][c];
      diag = std::max(diag, sum);
    }
  const double t0 = diag > 0 ? 1.0 / diag : 1.0;
  double t = t0;
  double gscale = 1;
  {
    std::vector<double> aty;
    p.MultiplyTransposed(p.y, &aty);
    for (double v : aty) gscale = std::max(gscale, std::abs(v));
  }
  const int max_it = o.max_iterations * 100;
  for (int it = 1; it <= max_it; ++it) {
    double pg = 0;
    for (std::size_t i = 0; i < g.size(); ++i)
      if (lambda[i] > 0 || g[i] < 0) pg = std::max(pg, std::abs(g[i]));
    if (pg <= o.gradient_tolerance * gscale) {
      res.converged = true;
      break;
    }
    // Backtracking (Armijo along the projection arc).
    bool accepted = false;
    double e_trial = e;
    for (int bt = 0; bt < 60; ++bt) {
      double decrease_model = 0;
      for (std::size_t i = 0; i < lambda.size(); ++i) {
        trial[i] = std::max(0.0, lambda[i] - t * g[i]);
        decrease_model += g[i] * (lambda[i] - trial[i]);
      }
      e_trial = obj.ValueAndGradient(trial, &g_trial, &r_trial);
      if (e_trial <= e - 1e-4 * decrease_model) {
        accepted = true;
        break;
      }
      t *= 0.5;
    }
    res.iterations = it;
    if (!accepted) {
      res.converged = true;  // no decrease possible at machine precision
      Report(o, it, e, lambda, r);
      break;
    }
    lambda.swap(trial);
    g.swap(g_trial);
    r.swap(r_trial);
    e = e_trial;
    // The paper's backtracking (Nocedal & Wright, Alg. 3.1) starts every iteration from the
    // same initial step; the adaptive variant starts from twice the last accepted one.
    t = o.adaptive_step ? 2 * t : t0;
    Report(o, it, e, lambda, r);
    if (sw.Seconds() > o.max_seconds) break;
  }
  res.lambda = std::move(lambda);
  res.objective = e;
  res.kkt_violation = obj.KktViolation(res.lambda);
  return res;
}

}  // namespace

SolveResult Solve(SolverKind kind, const Objective& objective, std::vector<double> initial, const SolverOptions& o) {
  LP_CHECK(static_cast<int>(initial.size()) == objective.unknowns(), "initial size");
  for (double& v : initial)
    if (!(v > 0)) v = 0;
  return kind == SolverKind::kFast ? SolveMM(objective, std::move(initial), o)
                                   : SolveGradient(objective, std::move(initial), o);
}

}  // namespace lp
