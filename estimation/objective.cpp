#include "estimation/objective.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/parallel.h"

namespace lp {

LinearProblem MakeLinearProblem(const TransportMatrix& A, const std::vector<double>& y) {
  LP_CHECK(y.size() == 3 * A.rows(), "observation size " << y.size() << " vs rows " << A.rows());
  LinearProblem p;
  const std::vector<int> counts = A.ColumnCounts();
  std::vector<int> compact(A.cells, -1);
  for (int j = 0; j < A.cells; ++j)
    if (counts[j] > 0) {
      compact[j] = static_cast<int>(p.cell_of.size());
      p.cell_of.push_back(j);
    }
  p.unknown_cells = static_cast<int>(p.cell_of.size());
  p.row_start = A.row_start;
  p.col.resize(A.col.size());
  for (std::size_t k = 0; k < A.col.size(); ++k) p.col[k] = compact[A.col[k]];
  p.val = A.val;
  p.y = y;
  // Transpose (CSC).
  p.col_start.assign(p.unknown_cells + 1, 0);
  for (int c : p.col) ++p.col_start[c + 1];
  for (int j = 0; j < p.unknown_cells; ++j) p.col_start[j + 1] += p.col_start[j];
  p.col_row.resize(p.col.size());
  p.col_val.resize(p.col.size());
  p.col_pos.resize(p.col.size());
  std::vector<std::int64_t> fill(p.col_start.begin(), p.col_start.end() - 1);
  for (std::size_t r = 0; r + 1 < p.row_start.size(); ++r)
    for (std::int64_t k = p.row_start[r]; k < p.row_start[r + 1]; ++k) {
      const std::int64_t dst = fill[p.col[k]]++;
      p.col_row[dst] = static_cast<int>(r);
      p.col_val[dst] = p.val[k];
      p.col_pos[dst] = k;
    }
  return p;
}

void LinearProblem::Multiply(const std::vector<double>& lambda, std::vector<double>* out) const {
  out->assign(3 * rows(), 0.0);
  ParallelForChunks(0, rows(), 512, [&](std::size_t b, std::size_t e) {
    for (std::size_t r = b; r < e; ++r) {
      double s0 = 0, s1 = 0, s2 = 0;
      for (std::int64_t k = row_start[r]; k < row_start[r + 1]; ++k) {
        const double* l = &lambda[3 * col[k]];
        s0 += val[k][0] * l[0];
        s1 += val[k][1] * l[1];
        s2 += val[k][2] * l[2];
      }
      (*out)[3 * r] = s0;
      (*out)[3 * r + 1] = s1;
      (*out)[3 * r + 2] = s2;
    }
  });
}

void LinearProblem::MultiplyTransposed(const std::vector<double>& v, std::vector<double>* out) const {
  out->assign(3 * static_cast<std::size_t>(unknown_cells), 0.0);
  ParallelForChunks(0, unknown_cells, 16, [&](std::size_t b, std::size_t e) {
    for (std::size_t j = b; j < e; ++j) {
      double s0 = 0, s1 = 0, s2 = 0;
      for (std::int64_t k = col_start[j]; k < col_start[j + 1]; ++k) {
        const double* x = &v[3 * col_row[k]];
        s0 += col_val[k][0] * x[0];
        s1 += col_val[k][1] * x[1];
        s2 += col_val[k][2] * x[2];
      }
      (*out)[3 * j] = s0;
      (*out)[3 * j + 1] = s1;
      (*out)[3 * j + 2] = s2;
    }
  });
}

Objective::Objective(const LinearProblem& problem, const ObjectiveParams& params) : p_(problem), params_(params) {
  if (!(params.sigma > 0) || !std::isfinite(params.sigma)) throw InputError("sigma must be positive and finite");
  if (!(params.alpha >= 0) || !std::isfinite(params.alpha)) throw InputError("alpha must be >= 0 and finite");
  if (!(params.beta >= 0) || !std::isfinite(params.beta)) throw InputError("beta must be >= 0 and finite");
  if (!params.cell_weight.empty()) {
    LP_CHECK(static_cast<int>(params.cell_weight.size()) == problem.unknown_cells, "one weight per unknown cell");
    for (double w : params.cell_weight) LP_CHECK(w >= 0 && std::isfinite(w), "cell weights must be finite, >= 0");
  }
  std::vector<double> aty;
  p_.MultiplyTransposed(p_.y, &aty);
  for (double v : aty) kkt_scale_ = std::max(kkt_scale_, std::abs(v));
}

double Objective::Penalty(const std::vector<double>& lambda) const {
  double penalty = 0;
  if (params_.alpha > 0)
    for (int j = 0; j < p_.unknown_cells; ++j)
      penalty += Alpha(j) * std::log1p(params_.beta * (lambda[3 * j] + lambda[3 * j + 1] + lambda[3 * j + 2]));
  return penalty;
}

double Objective::DataPass(const std::vector<double>& lambda, std::vector<double>* residual,
                           std::vector<double>* adjoint) const {
  const std::size_t rows = p_.rows();
  const std::size_t L3 = 3 * static_cast<std::size_t>(p_.unknown_cells);
  const double s2 = params_.sigma * params_.sigma;
  // Fixed chunks (independent of the thread count), each with its own partial sums,
  // reduced in chunk order: the result is bit-identical for any number of threads.
  const std::size_t chunks = std::max<std::size_t>(1, std::min<std::size_t>(64, (rows + 511) / 512));
  const std::size_t per = (rows + chunks - 1) / chunks;
  std::vector<double> data(chunks, 0.0);
  std::vector<double> partial(adjoint ? chunks * L3 : 0, 0.0);
  if (residual) residual->resize(3 * rows);
  ParallelFor(0, chunks, [&](std::size_t c) {
    const std::size_t b = c * per, e = std::min(rows, b + per);
    double* acc = adjoint ? &partial[c * L3] : nullptr;
    double sum = 0;
    for (std::size_t r = b; r < e; ++r) {
      double a0 = 0, a1 = 0, a2 = 0;
      for (std::int64_t k = p_.row_start[r]; k < p_.row_start[r + 1]; ++k) {
        const double* l = &lambda[3 * p_.col[k]];
        a0 += p_.val[k][0] * l[0];
        a1 += p_.val[k][1] * l[1];
        a2 += p_.val[k][2] * l[2];
      }
      const double r0 = p_.y[3 * r] - a0, r1 = p_.y[3 * r + 1] - a1, r2 = p_.y[3 * r + 2] - a2;
      if (residual) {
        (*residual)[3 * r] = r0;
        (*residual)[3 * r + 1] = r1;
        (*residual)[3 * r + 2] = r2;
      }
      sum += 0.5 * s2 * (std::log1p(r0 * r0 / s2) + std::log1p(r1 * r1 / s2) + std::log1p(r2 * r2 / s2));
      if (acc) {
        const double p0 = r0 / (1 + r0 * r0 / s2), p1 = r1 / (1 + r1 * r1 / s2), p2 = r2 / (1 + r2 * r2 / s2);
        for (std::int64_t k = p_.row_start[r]; k < p_.row_start[r + 1]; ++k) {
          double* a = acc + 3 * p_.col[k];
          a[0] += p_.val[k][0] * p0;
          a[1] += p_.val[k][1] * p1;
          a[2] += p_.val[k][2] * p2;
        }
      }
    }
    data[c] = sum;
  });
  double total = 0;
  for (double d : data) total += d;
  if (adjoint) {
    adjoint->assign(L3, 0.0);
    for (std::size_t c = 0; c < chunks; ++c)
      for (std::size_t i = 0; i < L3; ++i) (*adjoint)[i] += partial[c * L3 + i];
  }
  return total;
}

double Objective::Value(const std::vector<double>& lambda, std::vector<double>* residual) const {
  return DataPass(lambda, residual, nullptr) + Penalty(lambda);
}

double Objective::ValueAndGradient(const std::vector<double>& lambda, std::vector<double>* gradient,
                                   std::vector<double>* residual) const {
  const double e = DataPass(lambda, residual, gradient) + Penalty(lambda);
  for (int j = 0; j < p_.unknown_cells; ++j) {
    const double pen = Alpha(j) * params_.beta /
                       (1 + params_.beta * (lambda[3 * j] + lambda[3 * j + 1] + lambda[3 * j + 2]));
    for (int c = 0; c < 3; ++c) (*gradient)[3 * j + c] = -(*gradient)[3 * j + c] + pen;
  }
  return e;
}

double Objective::Rmse(const std::vector<double>& lambda) const {
  std::vector<double> r;
  Value(lambda, &r);
  double s = 0;
  for (double v : r) s += v * v;
  return r.empty() ? 0.0 : std::sqrt(s / r.size());
}

double Objective::KktViolation(const std::vector<double>& lambda) const {
  std::vector<double> g;
  ValueAndGradient(lambda, &g);
  double worst = 0;
  for (std::size_t i = 0; i < g.size(); ++i) {
    // Natural residual |P(lambda - g) - lambda|: |g| where lambda is well inside, max(0, -g) at 0.
    const double v = std::abs(std::max(0.0, lambda[i] - g[i]) - lambda[i]);
    worst = std::max(worst, v);
  }
  return worst / kkt_scale_;
}

}  // namespace lp
