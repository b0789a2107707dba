#include "estimation/objective.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/parallel.h"

namespace lp {
namespace {

/// Columns [first, L) of G, upper triangle (i >= j): column j gathers the rows touching
/// cell j into one interleaved buffer (the 3 channels of an entry share a cache line).
void SumNormalColumns(const LinearProblem& p, int first, std::vector<double> G[3]) {
  const int L = p.unknown_cells;
  ParallelForChunks(first, L, 8, [&](std::size_t jb, std::size_t je) {
    std::vector<double> acc(3 * static_cast<std::size_t>(L));
    for (std::size_t j = jb; j < je; ++j) {
      std::fill(acc.begin() + 3 * j, acc.end(), 0.0);
      for (std::int64_t k = p.col_start[j]; k < p.col_start[j + 1]; ++k) {
        const int r = p.col_row[k];
        const double a0 = p.col_val[k][0], a1 = p.col_val[k][1], a2 = p.col_val[k][2];
        const std::int64_t end = p.row_start[r + 1];
        for (std::int64_t q = p.col_pos[k]; q < end; ++q) {
          double* g = &acc[3 * static_cast<std::size_t>(p.col[q])];
          const float* v = p.val[q].data();
          g[0] += a0 * v[0];
          g[1] += a1 * v[1];
          g[2] += a2 * v[2];
        }
      }
      for (int c = 0; c < 3; ++c) {
        double* col = &G[c][j * L];
        for (int i = static_cast<int>(j); i < L; ++i) col[i] = acc[3 * static_cast<std::size_t>(i) + c];
      }
    }
  });
}

/// Rows [first, L) of G, columns [0, first): the appended unknowns against the base's
/// (each row of an appended column read whole), the same products in the same row order
/// as SumNormalColumns would sum them.
void SumNormalCross(const LinearProblem& p, int first, std::vector<double> G[3]) {
  const int L = p.unknown_cells;
  ParallelForChunks(first, L, 1, [&](std::size_t ib, std::size_t ie) {
    std::vector<double> acc(3 * static_cast<std::size_t>(first));
    for (std::size_t i = ib; i < ie; ++i) {
      std::fill(acc.begin(), acc.end(), 0.0);
      for (std::int64_t k = p.col_start[i]; k < p.col_start[i + 1]; ++k) {
        const int r = p.col_row[k];
        const double a0 = p.col_val[k][0], a1 = p.col_val[k][1], a2 = p.col_val[k][2];
        for (std::int64_t q = p.row_start[r]; q < p.row_start[r + 1] && p.col[q] < first; ++q) {
          double* g = &acc[3 * static_cast<std::size_t>(p.col[q])];
          const float* v = p.val[q].data();
          g[0] += v[0] * a0;
          g[1] += v[1] * a1;
          g[2] += v[2] * a2;
        }
      }
      for (int c = 0; c < 3; ++c)
        for (int j = 0; j < first; ++j) G[c][static_cast<std::size_t>(j) * L + i] = acc[3 * static_cast<std::size_t>(j) + c];
    }
  });
}

/// The fixed chunks of rows a pass sums apart (their count, rows per chunk): independent of
/// the thread count, so the sums reduced in chunk order are too.
std::pair<std::size_t, std::size_t> RowChunks(std::size_t rows) {
  const std::size_t chunks = std::max<std::size_t>(1, std::min<std::size_t>(64, (rows + 511) / 512));
  return {chunks, (rows + chunks - 1) / chunks};
}

/// Whether `n` are the normal matrices of p's leading unknowns over the same rows.
bool Extends(const LinearProblem& p, const NormalMatrices& n) {
  return n.rows == p.rows() && n.cell_of.size() <= p.cell_of.size() &&
         std::equal(n.cell_of.begin(), n.cell_of.end(), p.cell_of.begin());
}

}  // namespace

void BuildNormalMatrices(const LinearProblem& p, std::vector<double> G[3]) {
  const int L = p.unknown_cells;
  for (int c = 0; c < 3; ++c) G[c].assign(static_cast<std::size_t>(L) * L, 0.0);
  int first = 0;
  if (p.base_normal && Extends(p, *p.base_normal)) {
    first = static_cast<int>(p.base_normal->cell_of.size());
    for (int c = 0; c < 3; ++c)
      for (int j = 0; j < first; ++j)
        std::copy_n(&p.base_normal->G[c][static_cast<std::size_t>(j) * first], first, &G[c][static_cast<std::size_t>(j) * L]);
    SumNormalCross(p, first, G);
  }
  SumNormalColumns(p, first, G);
  for (int c = 0; c < 3; ++c)
    for (int j = 0; j < L; ++j)
      for (int i = j + 1; i < L; ++i)
        G[c][static_cast<std::size_t>(i) * L + j] = G[c][static_cast<std::size_t>(j) * L + i];
}


std::shared_ptr<const NormalMatrices> MakeNormalMatrices(const LinearProblem& p) {
  auto n = std::make_shared<NormalMatrices>();
  n->cell_of = p.cell_of;
  n->rows = p.rows();
  BuildNormalMatrices(p, n->G);
  return n;
}

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

LinearProblem WithColumns(const LinearProblem& base, int cells, const std::vector<std::vector<float>>& columns) {
  const std::size_t R = base.rows();
  const auto nonzero = [&](std::size_t j, std::size_t r) {
    const float* v = &columns[j][3 * r];
    return v[0] != 0 || v[1] != 0 || v[2] != 0;
  };
  LinearProblem p;
  p.cell_of = base.cell_of;
  std::vector<int> compact(columns.size(), -1);
  std::vector<std::int64_t> extra(R + 1, 0);  // appended entries in rows before r
  for (std::size_t j = 0; j < columns.size(); ++j) {
    LP_CHECK(columns[j].size() == 3 * R, "column size " << columns[j].size());
    for (std::size_t r = 0; r < R; ++r)
      if (nonzero(j, r)) ++extra[r + 1], compact[j] = base.unknown_cells;  // a cell of its own (numbered below)
  }
  for (std::size_t j = 0; j < columns.size(); ++j)
    if (compact[j] >= 0) {
      compact[j] = static_cast<int>(p.cell_of.size());
      p.cell_of.push_back(cells + static_cast<int>(j));
    }
  p.unknown_cells = static_cast<int>(p.cell_of.size());
  for (std::size_t r = 0; r < R; ++r) extra[r + 1] += extra[r];
  const std::size_t nnz = base.col.size() + static_cast<std::size_t>(extra[R]);
  // Rows: each base row, then its entries of the new columns.
  p.row_start.resize(R + 1);
  p.col.resize(nnz);
  p.val.resize(nnz);
  ParallelForChunks(0, R, 1024, [&](std::size_t b, std::size_t e) {
    for (std::size_t r = b; r < e; ++r) {
      std::int64_t out = base.row_start[r] + extra[r];
      p.row_start[r] = out;
      std::copy(base.col.begin() + base.row_start[r], base.col.begin() + base.row_start[r + 1], p.col.begin() + out);
      std::copy(base.val.begin() + base.row_start[r], base.val.begin() + base.row_start[r + 1], p.val.begin() + out);
      out += base.row_start[r + 1] - base.row_start[r];
      for (std::size_t j = 0; j < columns.size(); ++j)
        if (compact[j] >= 0 && nonzero(j, r)) {
          p.col[out] = compact[j];
          p.val[out++] = {columns[j][3 * r], columns[j][3 * r + 1], columns[j][3 * r + 2]};
        }
    }
  });
  p.row_start[R] = static_cast<std::int64_t>(nnz);
  // Columns: base's, their rows' positions moved by the entries appended before them; then
  // the new ones.
  // (room for the new columns first: appending to exact copies moved them all again)
  p.col_start.reserve(base.col_start.size() + columns.size());
  p.col_row.reserve(nnz);
  p.col_val.reserve(nnz);
  p.col_pos.reserve(nnz);
  p.col_start = base.col_start;
  p.col_row.assign(base.col_row.begin(), base.col_row.end());
  p.col_val.assign(base.col_val.begin(), base.col_val.end());
  p.col_pos.resize(base.col_pos.size());
  for (std::size_t k = 0; k < base.col_pos.size(); ++k) p.col_pos[k] = base.col_pos[k] + extra[base.col_row[k]];
  for (std::size_t j = 0; j < columns.size(); ++j) {
    if (compact[j] < 0) continue;
    for (std::size_t r = 0; r < R; ++r)
      if (nonzero(j, r)) {
        p.col_row.push_back(static_cast<int>(r));
        p.col_val.push_back({columns[j][3 * r], columns[j][3 * r + 1], columns[j][3 * r + 2]});
        std::int64_t q = p.row_start[r + 1] - 1;  // its entry is among the row's last ones
        while (p.col[q] != compact[j]) --q;
        p.col_pos.push_back(q);
      }
    p.col_start.push_back(static_cast<std::int64_t>(p.col_row.size()));
  }
  p.y = base.y;
  p.one_sided = base.one_sided;
  if (base.base_normal && base.base_normal->cell_of.size() == static_cast<std::size_t>(base.unknown_cells))
    p.base_normal = base.base_normal;
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

double Objective::Smoothness(const std::vector<double>& lambda) const {
  double s = 0;
  if (params_.smooth > 0)
    for (const ObjectiveParams::Neighbours& e : params_.neighbours)
      for (int c = 0; c < 3; ++c) {
        const double d = lambda[3 * e.a + c] - lambda[3 * e.b + c];
        s += e.weight * d * d;
      }
  return 0.5 * params_.smooth * s;
}

void Objective::AddSmoothnessGradient(const std::vector<double>& lambda, std::vector<double>* out) const {
  if (!(params_.smooth > 0)) return;
  for (const ObjectiveParams::Neighbours& e : params_.neighbours)
    for (int c = 0; c < 3; ++c) {
      const double g = params_.smooth * e.weight * (lambda[3 * e.a + c] - lambda[3 * e.b + c]);
      (*out)[3 * e.a + c] += g;
      (*out)[3 * e.b + c] -= g;
    }
}

void Objective::AddSmoothnessCurvature(std::vector<double> G[3], int n) const {
  if (!(params_.smooth > 0)) return;
  for (const ObjectiveParams::Neighbours& e : params_.neighbours) {
    const double w = params_.smooth * e.weight;
    const std::size_t a = static_cast<std::size_t>(e.a), b = static_cast<std::size_t>(e.b), N = static_cast<std::size_t>(n);
    for (int c = 0; c < 3; ++c) {
      G[c][a * N + a] += w;
      G[c][b * N + b] += w;
      G[c][a * N + b] -= w;
      G[c][b * N + a] -= w;
    }
  }
}

double Objective::Activation(const std::vector<double>& lambda) const {
  double penalty = 0;
  if (params_.alpha > 0)
    for (int j = 0; j < p_.unknown_cells; ++j)
      penalty += Alpha(j) * std::log1p(params_.beta * (lambda[3 * j] + lambda[3 * j + 1] + lambda[3 * j + 2]));
  return penalty;
}

double Objective::DataPass(const std::vector<double>& lambda, std::vector<double>* residual,
                           std::vector<double>* adjoint, std::vector<double>* model) const {
  const std::size_t rows = p_.rows();
  const std::size_t L3 = 3 * static_cast<std::size_t>(p_.unknown_cells);
  const double s2 = params_.sigma * params_.sigma;
  // Fixed chunks (independent of the thread count), each with its own partial sums,
  // reduced in chunk order: the result is bit-identical for any number of threads.
  const std::pair<std::size_t, std::size_t> chunking = RowChunks(rows);
  const std::size_t chunks = chunking.first, per = chunking.second;  // (named: lambdas capture them)
  std::vector<double> data(chunks, 0.0);
  std::vector<double> partial(adjoint ? chunks * L3 : 0, 0.0);
  if (residual) residual->resize(3 * rows);
  if (model) model->resize(3 * rows);
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
      if (model) {
        (*model)[3 * r] = a0;
        (*model)[3 * r + 1] = a1;
        (*model)[3 * r + 2] = a2;
      }
      double r0 = p_.y[3 * r] - a0, r1 = p_.y[3 * r + 1] - a1, r2 = p_.y[3 * r + 2] - a2;
      if (!p_.one_sided.empty()) {  // a bound: past it on its free side costs nothing
        r0 = BoundedResidual(p_.one_sided[3 * r], r0);
        r1 = BoundedResidual(p_.one_sided[3 * r + 1], r1);
        r2 = BoundedResidual(p_.one_sided[3 * r + 2], r2);
      }
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

double Objective::ValueOnSegment(const std::vector<double>& lambda, const std::vector<double>& next,
                                 const std::vector<double>& model, const std::vector<double>& model_next, double t,
                                 std::vector<double>* x, std::vector<double>* model_x) const {
  const std::size_t rows = p_.rows();
  LP_CHECK(model.size() == 3 * rows && model_next.size() == 3 * rows, "ValueOnSegment: models of " << model.size()
                                                                          << " and " << model_next.size() << " values");
  x->resize(lambda.size());
  std::vector<std::pair<std::size_t, double>> clipped;  // (unknown, what the clip adds)
  for (std::size_t i = 0; i < lambda.size(); ++i) {
    const double v = lambda[i] + t * (next[i] - lambda[i]);
    (*x)[i] = std::max(0.0, v);
    if (v < 0) clipped.emplace_back(i, -v);
  }
  std::vector<double>& a = *model_x;
  a.resize(3 * rows);
  for (std::size_t k = 0; k < a.size(); ++k) a[k] = model[k] + t * (model_next[k] - model[k]);
  for (const auto& [i, add] : clipped) {
    const std::size_t j = i / 3, c = i % 3;
    for (std::int64_t k = p_.col_start[j]; k < p_.col_start[j + 1]; ++k) a[3 * p_.col_row[k] + c] += p_.col_val[k][c] * add;
  }
  const double s2 = params_.sigma * params_.sigma;
  // (DataPass's chunks, reduced in their order: the same for any number of threads)
  const std::pair<std::size_t, std::size_t> chunking = RowChunks(rows);
  const std::size_t chunks = chunking.first, per = chunking.second;  // (named: lambdas capture them)
  std::vector<double> data(chunks, 0.0);
  ParallelFor(0, chunks, [&](std::size_t c) {
    double sum = 0;
    for (std::size_t k = 3 * c * per; k < std::min(3 * rows, 3 * (c + 1) * per); ++k) {
      double r = p_.y[k] - a[k];
      if (!p_.one_sided.empty()) r = BoundedResidual(p_.one_sided[k], r);
      sum += 0.5 * s2 * std::log1p(r * r / s2);
    }
    data[c] = sum;
  });
  double total = 0;
  for (double d : data) total += d;
  return total + Penalty(*x);
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
  AddSmoothnessGradient(lambda, gradient);
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
