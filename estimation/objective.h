#pragma once
/// The estimation objective (paper Eq. 10-13) on a fixed light-transport matrix:
///   E(lambda) = sum_{p,c} rho_sigma(y_pc - (A lambda)_pc) + sum_j alpha_j*log(1 + beta*sum_c lambda_jc),
///   rho_sigma(r) = sigma^2/2 * log(1 + r^2/sigma^2)  (Cauchy),  lambda >= 0.
/// All quantities are in normalized units (observations divided by their mean).
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "estimation/transport.h"

namespace lp {

struct ObjectiveParams {
  double sigma = 0.5;  ///< Cauchy scale (normalized intensity units)
  double alpha = 3.0;  ///< activation penalty weight (normalized units: observations / their mean)
  double beta = 1.0;   ///< activation penalty sharpness
  /// Per unknown cell (compact index): a multiplier of alpha for that cell; empty = 1.
  /// The estimator passes each cell's solid angle over a reference one, so the penalty
  /// approximates an integral over the sphere and does not change with the ring count.
  std::vector<double> cell_weight;
  /// The map's smoothness: smooth/2 * sum over `neighbours` (compact indices) of weight *
  /// |lambda_a - lambda_b|^2, a discrete Dirichlet energy (EnvMap::Adjacency); 0 = none.
  double smooth = 0;
  struct Neighbours {
    int a = 0, b = 0;
    double weight = 0;
  };
  std::vector<Neighbours> neighbours;
};

struct LinearProblem;

/// G_c = A_c^T A_c of a problem's unknowns (per channel c, column-major), with what it
/// was built from (the compact cells and rows) so that a problem extending that one can
/// tell whether it may start from it.
struct NormalMatrices {
  std::vector<int> cell_of;  ///< the problem's compact index -> cell
  std::size_t rows = 0;
  std::vector<double> G[3];  ///< cell_of.size()^2 each
};

/// How an observation bounds the model (LinearProblem::one_sided's values).
enum Bound : std::uint8_t {
  kExact = 0,    ///< a measurement: the residual counts both ways
  kAtLeast = 1,  ///< a lower bound (a clipped pixel): the model above it costs nothing
  kAtMost = 2,   ///< an upper bound (a pixel beside a clipped one, brightened by bloom)
};

/// The residual r = y - model as a bound `b` counts it: 0 where the model passes the bound
/// on its free side (above a lower bound, below an upper one).
inline double BoundedResidual(std::uint8_t b, double r) {
  return b == kAtLeast ? (r > 0 ? r : 0.0) : b == kAtMost ? (r < 0 ? r : 0.0) : r;
}

/// Whether a residual r != 0 passes its bound `b` on the free side (it then counts 0).
inline bool PassesBound(std::uint8_t b, double r) { return r != 0 && BoundedResidual(b, r) == 0; }

/// A with the unreachable columns removed, in row (CSR) and column (CSC) form,
/// plus the observations. Unknowns are lambda[3*j + c] for compact cell j.
struct LinearProblem {
  int unknown_cells = 0;
  std::vector<int> cell_of;             ///< compact index -> environment cell
  std::vector<std::int64_t> row_start;  ///< CSR
  std::vector<int> col;
  std::vector<std::array<float, 3>> val;
  std::vector<std::int64_t> col_start;  ///< CSC
  std::vector<int> col_row;
  std::vector<std::array<float, 3>> col_val;
  std::vector<std::int64_t> col_pos;    ///< CSR position of each CSC entry
  std::vector<double> y;  ///< 3*rows observations
  /// Per entry of y: how it bounds the model (Bound: kAtLeast for a clipped pixel, the
  /// residual counting only where the model is below it, max(0, y - A lambda); kAtMost for
  /// a pixel that bloom may have brightened, min(0, y - A lambda)); empty: every one exact.
  std::vector<std::uint8_t> one_sided;
  /// The normal matrices of this problem's leading unknowns, when they are known (a
  /// problem made by WithColumns from one whose matrices were built): the solver then
  /// builds only the appended unknowns' rows and columns of G.
  std::shared_ptr<const NormalMatrices> base_normal;

  std::size_t rows() const { return row_start.empty() ? 0 : row_start.size() - 1; }
  /// out = A * lambda (3*rows).
  void Multiply(const std::vector<double>& lambda, std::vector<double>* out) const;
  /// out[3j+c] = sum_p A_pjc * v_pc.
  void MultiplyTransposed(const std::vector<double>& v, std::vector<double>* out) const;
};

/// Builds the problem from A and the observation of each row (3 per row), keeping
/// only the cells with at least one entry.
LinearProblem MakeLinearProblem(const TransportMatrix& A, const std::vector<double>& y);

/// MakeLinearProblem(AppendColumns(A, columns), y) for base = MakeLinearProblem(A, y) and
/// A.cells == cells, entry for entry, in one linear pass over base (no transposition); the
/// new problem keeps base's normal matrices (base.base_normal, when they cover all of base)
/// so that a solve builds G only for the appended columns.
LinearProblem WithColumns(const LinearProblem& base, int cells, const std::vector<std::vector<float>>& columns);

/// G = A^T A per channel for every unknown of `p` (from p.base_normal where it applies: its
/// block is copied and only the rest is summed). Column j sums the rows touching cell j in
/// row order, so the result does not depend on the thread count, nor on whether a base
/// block was used.
void BuildNormalMatrices(const LinearProblem& p, std::vector<double> G[3]);
/// The same, kept with what it was built from (LinearProblem::base_normal).
std::shared_ptr<const NormalMatrices> MakeNormalMatrices(const LinearProblem& p);

class Objective {
 public:
  Objective(const LinearProblem& problem, const ObjectiveParams& params);
  /// E(lambda); `residual` (optional) receives y - A lambda.
  double Value(const std::vector<double>& lambda, std::vector<double>* residual = nullptr) const;
  /// E and its gradient dE/dlambda (analytical, Eq. 13).
  /// `residual` (optional) receives y - A lambda.
  double ValueAndGradient(const std::vector<double>& lambda, std::vector<double>* gradient,
                          std::vector<double>* residual = nullptr) const;
  /// One pass over A: the data term sum rho(y - A lambda); `residual` (optional)
  /// receives y - A lambda, `adjoint` (optional) A^T psi(y - A lambda), psi = rho', `model`
  /// (optional) A lambda.
  double DataPass(const std::vector<double>& lambda, std::vector<double>* residual, std::vector<double>* adjoint,
                  std::vector<double>* model = nullptr) const;
  /// E at x = max(0, lambda + t (next - lambda)) (into `x`, its model A x into `model_x`)
  /// without a pass over A: A x is model + t (model_next - model), the models being A lambda
  /// and A next, plus the columns of the unknowns the bound at 0 clips times what the clip
  /// adds. Equal to Value(x) up to rounding; its cost is the rows' and the clipped columns',
  /// not A's.
  double ValueOnSegment(const std::vector<double>& lambda, const std::vector<double>& next,
                        const std::vector<double>& model, const std::vector<double>& model_next, double t,
                        std::vector<double>* x, std::vector<double>* model_x) const;
  /// The priors: the activation penalty and the smoothness.
  double Penalty(const std::vector<double>& lambda) const { return Activation(lambda) + Smoothness(lambda); }
  /// The activation penalty sum_j alpha_j*log(1 + beta*sum_c lambda_jc).
  double Activation(const std::vector<double>& lambda) const;
  /// The map's smoothness (ObjectiveParams::smooth), 0 without one.
  double Smoothness(const std::vector<double>& lambda) const;
  /// out += its gradient, smooth * L lambda (L the neighbours' weighted graph Laplacian).
  void AddSmoothnessGradient(const std::vector<double>& lambda, std::vector<double>* out) const;
  /// G[c] += smooth * L (each n x n, column-major): the smoothness's curvature.
  void AddSmoothnessCurvature(std::vector<double> G[3], int n) const;
  /// alpha_j: alpha times the cell's weight.
  double Alpha(int j) const { return params_.cell_weight.empty() ? params_.alpha : params_.alpha * params_.cell_weight[j]; }
  /// Root mean square of the residual y - A lambda over all rows and channels.
  double Rmse(const std::vector<double>& lambda) const;
  /// Largest violation of the KKT conditions at lambda (>= 0), as the natural residual
  /// |max(0, lambda - g) - lambda| (= |g| where lambda > 0 and g small, max(0, -g) where
  /// lambda = 0), relative to max(1, max|A^T y|).
  double KktViolation(const std::vector<double>& lambda) const;

  const LinearProblem& problem() const { return p_; }
  const ObjectiveParams& params() const { return params_; }
  int unknowns() const { return 3 * p_.unknown_cells; }

 private:
  const LinearProblem& p_;
  ObjectiveParams params_;
  double kkt_scale_ = 1;
};

}  // namespace lp
