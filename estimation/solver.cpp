#include "estimation/solver.h"

#include <algorithm>
#include <cmath>
#include <limits>

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

int SolveNnqp(const std::vector<double>& G, const std::vector<double>& b, int n, std::vector<double>* xp) {
  std::vector<double>& x = *xp;
  if (n == 0) return 0;
  LP_CHECK(static_cast<int>(x.size()) == n, "x size");
  Eigen::Map<const Eigen::MatrixXd> Gm(G.data(), n, n);
  Eigen::Map<const Eigen::VectorXd> bm(b.data(), n);
  Eigen::Map<Eigen::VectorXd> xm(x.data(), n);
  for (int i = 0; i < n; ++i)
    if (!(x[i] > 0)) x[i] = 0;  // also clears NaN
  double bscale = 0, dscale = 0;
  for (int i = 0; i < n; ++i) {
    bscale = std::max(bscale, std::abs(b[i]));
    dscale = std::max(dscale, Gm(i, i));
  }
  if (bscale == 0) {
    std::fill(x.begin(), x.end(), 0.0);
    return 0;
  }
  // 1. Projected coordinate descent to find the support cheaply.
  Eigen::VectorXd g = Gm * xm - bm;
  for (int sweep = 0; sweep < 30; ++sweep) {
    double change = 0, xmax = 0;
    for (int i = 0; i < n; ++i) {
      const double d = Gm(i, i);
      if (!(d > 0)) continue;
      const double xi = std::max(0.0, x[i] - g[i] / d);
      const double delta = xi - x[i];
      if (delta != 0) {
        g += delta * Gm.col(i);
        x[i] = xi;
        change = std::max(change, std::abs(delta));
      }
      xmax = std::max(xmax, x[i]);
    }
    if (change <= 1e-6 * xmax) break;
  }
  // 2. Active set (Lawson-Hanson on the Gram form), warm-started from the support.
  const double tol = 1e-12 * std::max(bscale, dscale);
  std::vector<char> passive(n, 0);
  for (int i = 0; i < n; ++i) passive[i] = x[i] > 0;
  int iterations = 0;
  const int max_iterations = 3 * n + 50;
  std::vector<int> P;
  Eigen::VectorXd z;
  auto solve_passive = [&]() {
    P.clear();
    for (int i = 0; i < n; ++i)
      if (passive[i]) P.push_back(i);
    const int m = static_cast<int>(P.size());
    Eigen::MatrixXd Gp(m, m);
    Eigen::VectorXd bp(m);
    for (int a = 0; a < m; ++a) {
      bp[a] = b[P[a]];
      for (int c = 0; c < m; ++c) Gp(a, c) = Gm(P[a], P[c]);
    }
    Eigen::LLT<Eigen::MatrixXd> llt(Gp);
    if (llt.info() == Eigen::Success) {
      z = llt.solve(bp);
    } else {
      z = Gp.ldlt().solve(bp);
    }
    for (int a = 0; a < m; ++a)
      if (!std::isfinite(z[a])) z[a] = 0;
  };
  while (iterations++ < max_iterations) {
    // Inner loop: move towards the unconstrained minimizer on the passive set, staying feasible.
    for (int inner = 0; inner <= n; ++inner) {
      solve_passive();
      double step = 1;
      int blocking = -1;
      for (std::size_t a = 0; a < P.size(); ++a)
        if (z[a] <= 0) {
          const double xi = x[P[a]];
          const double ratio = xi - z[a] > 0 ? xi / (xi - z[a]) : 0.0;
          if (blocking < 0 || ratio < step) {
            step = ratio;
            blocking = P[a];
          }
        }
      if (blocking < 0) {  // unconstrained minimizer is feasible
        for (std::size_t a = 0; a < P.size(); ++a) x[P[a]] = z[a];
        break;
      }
      step = std::clamp(step, 0.0, 1.0);
      for (std::size_t a = 0; a < P.size(); ++a) x[P[a]] += step * (z[a] - x[P[a]]);
      x[blocking] = 0;  // the blocking variable leaves exactly
      for (std::size_t a = 0; a < P.size(); ++a)
        if (x[P[a]] <= 0) {
          x[P[a]] = 0;
          passive[P[a]] = 0;
        }
      passive[blocking] = 0;
    }
    // Optimality: the most negative gradient among the active (zero) variables.
    g = Gm * xm - bm;
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

namespace {

void Report(const SolverOptions& o, int it, double e, const Objective& obj, const std::vector<double>& lambda) {
  if (!o.on_iteration) return;
  IterationInfo info;
  info.iteration = it;
  info.objective = e;
  info.rmse = obj.Rmse(lambda);
  info.lambda = &lambda;
  o.on_iteration(info);
}

/// G_c = A_c^T A_c for the 3 channels, column-major L x L. Column j gathers the
/// rows touching cell j (upper triangle, i >= j), so the sum order is fixed: the
/// result does not depend on the thread count. Then mirrored.
void BuildNormalMatrices(const LinearProblem& p, std::vector<double> G[3]) {
  const int L = p.unknown_cells;
  for (int c = 0; c < 3; ++c) G[c].assign(static_cast<std::size_t>(L) * L, 0.0);
  ParallelFor(0, L, [&](std::size_t j) {
    double* g0 = &G[0][j * L];
    double* g1 = &G[1][j * L];
    double* g2 = &G[2][j * L];
    for (std::int64_t k = p.col_start[j]; k < p.col_start[j + 1]; ++k) {
      const int r = p.col_row[k];
      const double a0 = p.col_val[k][0], a1 = p.col_val[k][1], a2 = p.col_val[k][2];
      for (std::int64_t q = p.col_pos[k]; q < p.row_start[r + 1]; ++q) {
        const int i = p.col[q];
        g0[i] += a0 * p.val[q][0];
        g1[i] += a1 * p.val[q][1];
        g2[i] += a2 * p.val[q][2];
      }
    }
  });
  for (int c = 0; c < 3; ++c)
    for (int j = 0; j < L; ++j)
      for (int i = j + 1; i < L; ++i)
        G[c][static_cast<std::size_t>(i) * L + j] = G[c][static_cast<std::size_t>(j) * L + i];
}

/// Majorize-minimize. The Cauchy loss has curvature rho'' <= 1, so around the current
/// residual r0 it is majorized by rho(r0) + psi(r0)(r - r0) + (r - r0)^2 / 2; the concave
/// log penalty by its tangent c_j = alpha*beta / (1 + beta*sum_c lambda_jc). The
/// majorizer is a non-negative QP per channel whose matrix G = A^T A does not depend
/// on lambda: it is built once, and each step costs one pass over A plus a small NNQP.
SolveResult SolveMM(const Objective& obj, std::vector<double> lambda, const SolverOptions& o) {
  Stopwatch sw;
  const LinearProblem& p = obj.problem();
  const ObjectiveParams& prm = obj.params();
  const int L = p.unknown_cells;
  const double s2 = prm.sigma * prm.sigma;
  SolveResult res;
  std::vector<double> G[3];
  BuildNormalMatrices(p, G);
  double mu[3];
  for (int c = 0; c < 3; ++c) {
    double trace = 0;
    for (int j = 0; j < L; ++j) trace += G[c][static_cast<std::size_t>(j) * L + j];
    // Proximal term mu/2 |x - lambda|^2 keeps G positive definite; it is >= 0 and 0 at the
    // current point, so the step still majorizes E.
    mu[c] = 1e-10 * trace / std::max(1, L) + 1e-300;
    for (int j = 0; j < L; ++j) G[c][static_cast<std::size_t>(j) * L + j] += mu[c];
  }
  std::vector<double> r;
  double e = obj.Value(lambda, &r);
  const double e0 = e;
  std::vector<double> atpsi, bc(L), xc(L), next(lambda.size()), r_next;
  for (int it = 1; it <= o.max_iterations; ++it) {
    for (double& v : r) v = v / (1 + v * v / s2);  // psi(r0)
    p.MultiplyTransposed(r, &atpsi);
    for (int c = 0; c < 3; ++c) {
      Eigen::Map<const Eigen::MatrixXd> Gm(G[c].data(), L, L);
      Eigen::VectorXd x0(L);
      for (int j = 0; j < L; ++j) x0[j] = lambda[3 * j + c];
      const Eigen::VectorXd gx = Gm * x0;  // includes mu * x0 (the proximal centre)
      for (int j = 0; j < L; ++j) {
        const double cost = prm.alpha * prm.beta / (1 + prm.beta * (lambda[3 * j] + lambda[3 * j + 1] + lambda[3 * j + 2]));
        bc[j] = gx[j] + atpsi[3 * j + c] - cost;
        xc[j] = x0[j];
      }
      SolveNnqp(G[c], bc, L, &xc);
      for (int j = 0; j < L; ++j) next[3 * j + c] = xc[j];
    }
    const double e_next = obj.Value(next, &r_next);
    res.iterations = it;
    if (!(e_next <= e)) {
      // A converged step can look like a rounding-level increase: keep the old point and stop.
      res.objective_increased = !(e_next <= e + 1e-9 * std::abs(e) + 1e-12 * std::abs(e0));
      res.converged = true;
      Report(o, it, e, obj, lambda);
      break;
    }
    const double decrease = e - e_next;
    lambda.swap(next);
    r.swap(r_next);
    e = e_next;
    Report(o, it, e, obj, lambda);
    if (decrease <= o.relative_tolerance * std::abs(e)) {
      res.converged = true;
      break;
    }
    if (sw.Seconds() > o.max_seconds) break;
  }
  res.lambda = std::move(lambda);
  res.objective = e;
  res.kkt_violation = obj.KktViolation(res.lambda);
  return res;
}

SolveResult SolveGradient(const Objective& obj, std::vector<double> lambda, const SolverOptions& o) {
  Stopwatch sw;
  SolveResult res;
  std::vector<double> g, trial(lambda.size()), g_trial;
  double e = obj.ValueAndGradient(lambda, &g);
  // Initial step from the diagonal scale of A^T A (a safe guess; backtracking corrects it).
  const LinearProblem& p = obj.problem();
  double diag = 0;
  for (std::size_t k = 0; k < p.val.size(); ++k)
    diag = std::max(diag, static_cast<double>(p.val[k][0]) * p.val[k][0] * (p.col_start[p.col[k] + 1] - p.col_start[p.col[k]]));
  double t = diag > 0 ? 1.0 / diag : 1.0;
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
      e_trial = obj.ValueAndGradient(trial, &g_trial);
      if (e_trial <= e - 1e-4 * decrease_model) {
        accepted = true;
        break;
      }
      t *= 0.5;
    }
    res.iterations = it;
    if (!accepted) {
      res.converged = true;  // no decrease possible at machine precision
      Report(o, it, e, obj, lambda);
      break;
    }
    lambda.swap(trial);
    g.swap(g_trial);
    e = e_trial;
    t *= 2;  // let the step grow again
    Report(o, it, e, obj, lambda);
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
