#pragma once
/// Non-negative solvers for the objective on a fixed A.
#include <functional>
#include <string>
#include <vector>

#include "estimation/objective.h"

namespace lp {

enum class SolverKind {
  kFast,      ///< majorize-minimize: quadratic majorizer + reweighted l1, NNQP on G = A^T A
  kGradient,  ///< the paper's projected gradient descent with backtracking
};
/// "fast" or "gradient"; throws InputError on anything else.
SolverKind ParseSolverKind(const std::string& name);
const char* ToString(SolverKind kind);

/// One row of the convergence log.
struct IterationInfo {
  int iteration = 0;
  double objective = 0;
  const std::vector<double>* lambda = nullptr;
  const std::vector<double>* residual = nullptr;  ///< y - A lambda at this iterate
  /// Photometric RMSE (normalized units) from the residual: O(rows), no pass over A.
  double Rmse() const;
};

struct SolverOptions {
  int max_iterations = 200;         ///< MM steps, or gradient steps (x100 for the gradient solver)
  double relative_tolerance = 1e-9; ///< MM: stop when the relative decrease of E is below this
  double gradient_tolerance = 1e-6; ///< PGD: stop when |projected gradient|_inf (relative) is below this
  double max_seconds = 1e30;        ///< wall-clock cap
  /// PGD only: start each line search from twice the last accepted step instead of the
  /// paper's fixed initial step (a stronger baseline, reported beside the paper's).
  bool adaptive_step = false;
  std::function<void(const IterationInfo&)> on_iteration;  ///< called after every iteration
};

struct SolveResult {
  std::vector<double> lambda;  ///< 3 * unknown cells, >= 0 exactly
  double objective = 0;
  int iterations = 0;
  bool converged = false;
  double kkt_violation = 0;
  bool objective_increased = false;  ///< set if any iteration increased E (must not happen)
};

SolveResult Solve(SolverKind kind, const Objective& objective, std::vector<double> initial,
                  const SolverOptions& options);

/// The least curvature w of a quadratic 1/2 w (u + v)^2 that lies on or above a one-sided
/// Cauchy row's loss 1/2 log(1 + max(0, u)^2) (in units of sigma) everywhere, touching it
/// with zero slope at u = -v, a render v sigmas above the row's level: sup over u > 0 of
/// log(1 + u^2) / (u + v)^2. 1 at v <= 0 (the loss's own curvature bound), falling towards
/// 0 as v grows (the loss is flat above the level). The fast solver's majorizer uses it.
double OneSidedCurvature(double v);

/// Minimizes 0.5 x^T G x - b^T x subject to x >= 0 (G symmetric positive definite,
/// n x n column-major), warm-started from x; coordinate descent then active set.
/// Returns the number of active-set iterations.
int SolveNnqp(const std::vector<double>& G, const std::vector<double>& b, int n, std::vector<double>* x);

}  // namespace lp
