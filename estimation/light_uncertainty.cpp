#include "estimation/light_uncertainty.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "common/error.h"
#include "common/parallel.h"
#include "estimation/light_fit.h"
#include "estimation/transport.h"

namespace lp {
namespace {

/// A row and channel's Jacobian, sparse: its parameters and their derivatives.
struct SparseRow {
  std::vector<int> index;
  std::vector<double> value;
  void Clear() {
    index.clear();
    value.clear();
  }
  void Add(int i, double v) {
    if (v == 0) return;
    index.push_back(i);
    value.push_back(v);
  }
};

/// The parameters (each light's shape coordinates and 3 scales, then the map's lit cells'
/// channels) and the lights' columns and their derivatives on the problem's rows.
struct Parameters {
  std::vector<int> offset{0};   ///< per light: its first parameter; the last: the lights' count
  std::vector<int> cell_param;  ///< per cell and channel: its parameter, or -1
  int n = 0;
  std::vector<std::vector<float>> cols, jacs;
  std::vector<Eigen::Matrix3d> bases;

  Parameters(const LightFitProblem& p, const std::vector<Light>& lights, const TransportMatrix* map,
             const std::vector<double>& lambda) {
    for (const Light& l : lights) offset.push_back(offset.back() + ShapeDims(l) + 3);
    n = offset.back();
    if (map) {
      cell_param.assign(lambda.size(), -1);
      for (std::size_t k = 0; k < lambda.size(); ++k)
        if (lambda[k] > 0) cell_param[k] = n++;
    }
    cols.resize(lights.size());
    jacs.resize(lights.size());
    for (std::size_t k = 0; k < lights.size(); ++k) {
      UnitColumn(*p.scene, *p.vertices, lights[k], &cols[k], &jacs[k]);
      bases.push_back(ShapeBasis(lights[k]));
    }
  }
  int ShapeDimsOf(std::size_t k) const { return offset[k + 1] - offset[k] - 3; }

  /// Row `row`'s channel `c`: its Jacobian into `J`, and the model's value there.
  double Row(const LightFitProblem& p, const std::vector<Light>& lights, const TransportMatrix* map, std::size_t row,
             int c, SparseRow* J) const {
    const std::size_t i = 3 * row + c;
    J->Clear();
    double model = (*p.base)[i], shape[3];
    for (std::size_t k = 0; k < lights.size(); ++k) {
      const double s = Scale(lights[k])[c];
      const int dims = ShapeDimsOf(k);
      ShapeGradient(bases[k], dims, &jacs[k][9 * row + 3 * c], shape);
      for (int a = 0; a < dims; ++a) J->Add(offset[k] + a, s * shape[a]);
      J->Add(offset[k] + dims + c, cols[k][i]);
      model += s * cols[k][i];
    }
    if (map)
      for (std::int64_t e = map->row_start[row]; e < map->row_start[row + 1]; ++e) {
        const int param = cell_param[3 * static_cast<std::size_t>(map->col[e]) + c];
        if (param >= 0) J->Add(param, map->val[e][c]);
      }
    return model;
  }
};

/// The bread (sum w J J^T) and each block's score (sum w r J, a column per block), summed
/// over fixed chunks of rows in parallel and then in the chunks' order (the same result on
/// any number of threads).
void BreadAndScores(const LightFitProblem& p, const std::vector<Light>& lights, const TransportMatrix* map,
                    const Parameters& par, const std::vector<int>& row_block, int blocks, Eigen::MatrixXd* bread,
                    Eigen::MatrixXd* scores) {
  const std::size_t rows = p.vertices->rows();
  constexpr int kChunks = 8;
  std::vector<Eigen::MatrixXd> Hs(kChunks, Eigen::MatrixXd::Zero(par.n, par.n));
  std::vector<Eigen::MatrixXd> Gs(kChunks, Eigen::MatrixXd::Zero(par.n, blocks));
  const std::size_t per_chunk = (rows + kChunks - 1) / kChunks;
  ParallelFor(0, kChunks, [&](std::size_t chunk) {
    SparseRow J;
    for (std::size_t row = chunk * per_chunk; row < std::min(rows, (chunk + 1) * per_chunk); ++row)
      for (int c = 0; c < 3; ++c) {
        const double model = par.Row(p, lights, map, row, c, &J);
        if (J.index.empty()) continue;
        const double r = (*p.y)[3 * row + c] - model, w = p.loss.Weight(r);
        for (std::size_t a = 0; a < J.index.size(); ++a) {  // the upper triangle
          const double wa = w * J.value[a];
          for (std::size_t b = a; b < J.index.size(); ++b)
            Hs[chunk](std::min(J.index[a], J.index[b]), std::max(J.index[a], J.index[b])) += wa * J.value[b];
          Gs[chunk](J.index[a], row_block[row]) += wa * r;
        }
      }
  });
  *bread = Eigen::MatrixXd::Zero(par.n, par.n);
  *scores = Eigen::MatrixXd::Zero(par.n, blocks);
  for (int chunk = 0; chunk < kChunks; ++chunk) {
    *bread += Hs[chunk];
    *scores += Gs[chunk];
  }
  *bread = bread->selfadjointView<Eigen::Upper>();
}

/// Each block's rows' bread (sum w J J^T over them).
Eigen::MatrixXd BlockBread(const LightFitProblem& p, const std::vector<Light>& lights, const TransportMatrix* map,
                           const Parameters& par, const std::vector<std::size_t>& rows) {
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(par.n, par.n);
  SparseRow J;
  for (std::size_t row : rows)
    for (int c = 0; c < 3; ++c) {
      const double model = par.Row(p, lights, map, row, c, &J);
      if (J.index.empty()) continue;
      const double w = p.loss.Weight((*p.y)[3 * row + c] - model);
      for (std::size_t a = 0; a < J.index.size(); ++a)
        for (std::size_t b = a; b < J.index.size(); ++b)
          h(std::min(J.index[a], J.index[b]), std::max(J.index[a], J.index[b])) += w * J.value[a] * J.value[b];
    }
  return h.selfadjointView<Eigen::Upper>();
}

}  // namespace

std::vector<LightUncertainty> LightUncertainties(const LightFitProblem& p, const std::vector<Light>& lights,
                                                 const TransportMatrix* map, const std::vector<double>& lambda,
                                                 const std::vector<int>& row_block) {
  const std::size_t rows = p.vertices->rows();
  LP_CHECK(p.y->size() == 3 * rows && p.base->size() == 3 * rows && row_block.size() == rows,
           "LightUncertainties: 3 observations, a base and a block per row");
  LP_CHECK(!map || (map->rows() == rows && lambda.size() == 3 * static_cast<std::size_t>(map->cells)),
           "LightUncertainties: the map's rows are the problem's");
  const Parameters par(p, lights, map, lambda);
  const int blocks = row_block.empty() ? 0 : *std::max_element(row_block.begin(), row_block.end()) + 1;
  Eigen::MatrixXd H, score;
  BreadAndScores(p, lights, map, par, row_block, blocks, &H, &score);
  // The bread's inverse, only its columns of the lights' parameters (the map's parameters
  // are marginalized out by it). A pivoted LDL^T with a ridge of 1e-12 of the largest
  // diagonal entry (a parameter no row sees would make H singular). The covariance is
  // (G-1)/G sum_b d_b d_b^T over the G blocks, d_b = (H - H_b)^-1 g_b the step leaving block b
  // out moves the lights by (the jackknife, CR3; with one block, H^-1 g).
  const int nl = par.offset.back();
  const double ridge = 1e-12 * std::max(H.diagonal().maxCoeff(), 1e-300);
  H.diagonal().array() += ridge;
  const Eigen::MatrixXd hinv_l = Eigen::LDLT<Eigen::MatrixXd>(H).solve(Eigen::MatrixXd::Identity(par.n, nl));
  Eigen::MatrixXd z = hinv_l.transpose() * score;  // the columns d_b
  if (blocks > 1) {
    std::vector<std::vector<std::size_t>> block_rows(blocks);
    for (std::size_t row = 0; row < rows; ++row) block_rows[row_block[row]].push_back(row);
    ParallelFor(0, blocks, [&](std::size_t b) {
      const Eigen::MatrixXd without = H - BlockBread(p, lights, map, par, block_rows[b]);
      z.col(b) = Eigen::LDLT<Eigen::MatrixXd>(without).solve(score.col(b)).head(nl);
    });
  }
  const Eigen::MatrixXd cov = z * z.transpose() * (blocks > 1 ? (blocks - 1.0) / blocks : 1.0);
  // A parameter the data do not fix (its variance with the others free over its variance
  // with them held, H^-1_aa H_aa, beyond 1e8: a zero direction of H, or one the other
  // parameters can take over entirely) is unknown.
  const auto unknown = [&](int a) { return !(hinv_l(a, a) * (H(a, a) - ridge) < 1e8) || !(H(a, a) > ridge); };
  std::vector<LightUncertainty> out(lights.size());
  for (std::size_t k = 0; k < lights.size(); ++k) {
    const int first = par.offset[k], dims = par.ShapeDimsOf(k);
    const Eigen::MatrixXd basis = par.bases[k].leftCols(dims);
    out[k].shape_covariance = basis * cov.block(first, first, dims, dims) * basis.transpose();
    for (int c = 0; c < 3; ++c) out[k].scale_sigma[c] = std::sqrt(std::max(0.0, cov(first + dims + c, first + dims + c)));
    for (int a = 0; a < dims; ++a)
      if (unknown(first + a)) out[k].shape_covariance.setConstant(INFINITY);
    for (int c = 0; c < 3; ++c)
      if (unknown(first + dims + c)) out[k].scale_sigma[c] = INFINITY;
  }
  return out;
}

bool Region95(const Eigen::Matrix3d& covariance, int dims, Eigen::Vector3d* semi_axes, Eigen::Matrix3d* axes) {
  if (!covariance.allFinite()) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(covariance);
  *semi_axes = (eig.eigenvalues().cwiseMax(0.0) * (dims == 2 ? kChiSquare95Dim2 : kChiSquare95Dim3)).cwiseSqrt();
  *axes = eig.eigenvectors();
  return true;
}

double SquaredMahalanobis(const Eigen::Vector3d& d, const Eigen::Matrix3d& covariance) {
  if (!covariance.allFinite()) return 0;  // nothing known: everywhere is inside
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(covariance);
  const double floor = 1e-12 * std::max(eig.eigenvalues().cwiseAbs().maxCoeff(), 1e-300);
  double m = 0;
  for (int a = 0; a < 3; ++a) {
    const double along = eig.eigenvectors().col(a).dot(d);
    if (eig.eigenvalues()[a] > floor) m += along * along / eig.eigenvalues()[a];
  }
  return m;
}

double LargestVarianceRatio(const Eigen::Matrix3d& of, const Eigen::Matrix3d& to) {
  if (!of.allFinite() || !to.allFinite()) return 0;
  const Eigen::LLT<Eigen::Matrix3d> llt(to);
  if (llt.info() != Eigen::Success) return 0;
  // With to = L Lᵀ, the ratio's largest value is the largest eigenvalue of L⁻¹ of L⁻ᵀ.
  const Eigen::Matrix3d l_inv = llt.matrixL().solve(Eigen::Matrix3d::Identity());
  const Eigen::Matrix3d w = l_inv * of * l_inv.transpose();
  return std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(0.5 * (w + w.transpose()), Eigen::EigenvaluesOnly)
                           .eigenvalues()
                           .maxCoeff());
}

}  // namespace lp
