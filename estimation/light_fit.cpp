#include "estimation/light_fit.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/Dense>

#include "common/error.h"

namespace lp {
namespace {

/// The lights' columns on the problem's vertices (their spreads when debiased) and, when
/// asked, their derivatives.
struct Traced {
  std::vector<SplitColumn> cols;
  std::vector<std::vector<float>> jac, spread_jac;
};

void TraceColumns(const LightFitProblem& p, const std::vector<Light>& lights, Traced* t, bool derivatives) {
  const std::size_t K = lights.size();
  t->cols.assign(K, {});
  t->jac.assign(derivatives ? K : 0, {});
  t->spread_jac.assign(derivatives && p.debiased ? K : 0, {});
  for (std::size_t k = 0; k < K; ++k)
    UnitColumn(*p.scene, *p.vertices, lights[k],
               ColumnOut{&t->cols[k].value, derivatives ? &t->jac[k] : nullptr,
                         p.debiased ? &t->cols[k].spread : nullptr,
                         derivatives && p.debiased ? &t->spread_jac[k] : nullptr});
}

/// Whether a column has its spread, the problem being debiased.
bool HasSpread(const LightFitProblem& p, const SplitColumn& c) {
  return p.debiased && p.vertices && !p.vertices->half.empty() && c.spread.size() == c.value.size();
}

/// Whether the problem is debiased and every column has its spread.
bool HasSpreads(const LightFitProblem& p, const std::vector<SplitColumn>& cols) {
  return p.debiased && p.vertices && !p.vertices->half.empty() &&
         std::all_of(cols.begin(), cols.end(), [&](const SplitColumn& c) { return HasSpread(p, c); });
}

/// The residuals y - m model over all rows, `mult` m (3 per row; all 1 without segments),
/// and `noise` the model's halves' difference times m (its square estimates the variance
/// the columns' Monte Carlo noise adds to the residual; empty when not debiased).
struct Fitted {
  std::vector<double> r, mult, noise;
};

Fitted Residual(const LightFitProblem& p, const std::vector<Light>& lights, const std::vector<SplitColumn>& cols) {
  LP_CHECK(cols.size() == lights.size(), "a column per light");
  std::vector<double> model(*p.base), noise;
  const bool debiased = HasSpreads(p, cols);
  if (debiased) noise.assign(model.size(), 0.0);
  for (std::size_t k = 0; k < lights.size(); ++k) {
    LP_CHECK(cols[k].value.size() == model.size(), "a column of the problem's rows");
    const Eigen::Vector3d& s = Scale(lights[k]);
    for (std::size_t i = 0; i < model.size(); ++i) model[i] += s[i % 3] * cols[k].value[i];
    if (debiased)
      for (std::size_t i = 0; i < model.size(); ++i) noise[i] += s[i % 3] * cols[k].spread[i];
  }
  Fitted f;
  f.mult = SegmentMultipliers(p, model, noise);
  f.r.resize(model.size());
  for (std::size_t i = 0; i < model.size(); ++i) f.r[i] = p.RowResidual(i, f.mult[i] * model[i]);
  for (std::size_t i = 0; i < noise.size(); ++i) noise[i] *= f.mult[i];
  f.noise = std::move(noise);
  return f;
}

/// sum rho(r), less what the noise adds to its expectation (rho''(r) noise^2 / 2 each).
double LossSum(const CauchyLoss& loss, const std::vector<double>& r, const std::vector<double>& noise) {
  double e = loss.Sum(r);
  for (std::size_t i = 0; i < noise.size(); ++i) e -= 0.5 * loss.Curvature(r[i]) * noise[i] * noise[i];
  return e;
}

double Penalty(const LightFitProblem& p, const Eigen::Vector3d& scale) {
  return p.alpha * std::log1p(p.beta * std::max(0.0, scale.sum()));
}

double Energy(const LightFitProblem& p, const std::vector<Light>& lights, const Fitted& f) {
  double e = LossSum(p.loss, f.r, f.noise);
  for (const Light& l : lights) e += Penalty(p, Scale(l));
  return e;
}

double SquaredSum(const std::vector<double>& r) {
  double sse = 0;
  for (double v : r) sse += v * v;
  return sse;
}

/// One entry's derivative with respect to the parameters (each light's shape, then its
/// scale) of what the lights render, from their columns (`value`) and the columns'
/// derivatives (`jac`): the model's, or (the spreads) its noise's. False where every column
/// is 0 there.
bool EntryGradient(const std::vector<Light>& lights, const std::vector<Eigen::Matrix3d>& bases,
                   const std::vector<int>& offset, const std::vector<const std::vector<float>*>& value,
                   const std::vector<std::vector<float>>& jac, std::size_t i, Eigen::VectorXd* J) {
  const std::size_t row = i / 3;
  const int c = static_cast<int>(i % 3);
  double shape[3];
  J->setZero();
  bool any = false;
  for (std::size_t k = 0; k < lights.size(); ++k) {
    const int dims = offset[k + 1] - offset[k] - 3;
    ShapeGradient(bases[k], dims, &jac[k][9 * row + 3 * c], shape);
    for (int a = 0; a < dims; ++a) (*J)[offset[k] + a] = Scale(lights[k])[c] * shape[a];
    (*J)[offset[k] + dims + c] = (*value[k])[i];
    any = any || (*value[k])[i] != 0;
  }
  return any;
}

/// The reweighted normal equations of RefineLights at `lights` (H lower and upper, g). When
/// debiased, the noise's part (its gradient J_n) is taken out: H = sum w (J J' - J_n J_n'),
/// g = sum w (r J + noise J_n), the Gauss-Newton form of LossSum's correction.
void NormalEquations(const LightFitProblem& p, const std::vector<Light>& lights, const std::vector<int>& offset,
                     const Traced& t, const Fitted& f, Eigen::MatrixXd* H, Eigen::VectorXd* g) {
  const int K = static_cast<int>(lights.size()), n = offset.back();
  *H = Eigen::MatrixXd::Zero(n, n);
  *g = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd J(n), Jn(n);
  std::vector<Eigen::Matrix3d> bases;  // each light's, once (not per row)
  for (const Light& l : lights) bases.push_back(ShapeBasis(l));
  std::vector<const std::vector<float>*> values, spreads;
  for (const SplitColumn& c : t.cols) values.push_back(&c.value), spreads.push_back(&c.spread);
  const bool debiased = !f.noise.empty() && t.spread_jac.size() == lights.size();
  for (std::size_t i = 0; i < f.r.size(); ++i) {
    if (!EntryGradient(lights, bases, offset, values, t.jac, i, &J)) continue;
    J *= f.mult[i];  // the segments' multipliers held (their own derivative left out)
    const double w = p.loss.Weight(f.r[i]);
    H->selfadjointView<Eigen::Lower>().rankUpdate(J, w);
    *g += w * f.r[i] * J;
    if (debiased && EntryGradient(lights, bases, offset, spreads, t.spread_jac, i, &Jn)) {
      Jn *= f.mult[i];
      H->selfadjointView<Eigen::Lower>().rankUpdate(Jn, -w);
      *g += w * f.noise[i] * Jn;
    }
  }
  *H = H->selfadjointView<Eigen::Lower>();
  for (int k = 0; k < K; ++k)  // the penalty's gradient on the scales
    for (int c = 0; c < 3; ++c)
      (*g)[offset[k + 1] - 3 + c] -= p.alpha * p.beta / (1 + p.beta * std::max(0.0, Scale(lights[k]).sum()));
}

}  // namespace

double LightFitProblem::Value(const std::vector<Light>& lights, double* sse) const {
  Traced t;
  TraceColumns(*this, lights, &t, false);
  return Value(lights, t.cols, sse);
}

double LightFitProblem::Value(const std::vector<Light>& lights, const std::vector<SplitColumn>& columns,
                              double* sse) const {
  const Fitted f = Residual(*this, lights, columns);
  if (sse) *sse = SquaredSum(f.r);
  return Energy(*this, lights, f);
}

Eigen::Vector2d FitLightBesideSky(const std::vector<float>& x, const std::vector<float>& z,
                                  const std::vector<double>& s, const std::vector<double>& t, double a0,
                                  const CauchyLoss& loss, const std::vector<std::uint8_t>* one_sided,
                                  std::size_t first, std::size_t step) {
  Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
  Eigen::Vector2d v = Eigen::Vector2d::Zero();
  for (std::size_t e = first; e < t.size(); e += step) {
    const double r = t[e] - a0 * x[e];
    if (one_sided && PassesBound((*one_sided)[e], r)) continue;
    const double w = loss.Weight(r);  // at the fit
    m(0, 0) += w * z[e] * x[e], m(0, 1) += w * z[e] * s[e];
    m(1, 0) += w * s[e] * x[e], m(1, 1) += w * s[e] * s[e];
    v(0) += w * z[e] * t[e], v(1) += w * s[e] * t[e];
  }
  Eigen::Vector2d ab = m.fullPivLu().solve(v);
  if (!(ab(1) > 0) || !ab.allFinite()) ab = Eigen::Vector2d(m(0, 0) > 0 ? v(0) / m(0, 0) : a0, 0.0);
  return ab;
}

std::vector<double> SegmentMultipliers(const LightFitProblem& p, const std::vector<double>& model,
                                       const std::vector<double>& noise) {
  std::vector<double> m(model.size(), 1.0);
  if (!p.segment) return m;
  const std::vector<int>& seg = *p.segment;
  LP_CHECK(seg.size() * 3 == model.size(), "a segment per row");
  int segments = 0;
  for (int s : seg) segments = std::max(segments, s + 1);
  std::vector<int> rows(segments, 0);
  for (int s : seg)
    if (s >= 0) ++rows[s];
  std::vector<double> k(3 * segments, 1.0), num(3 * segments), den(3 * segments), var(3 * segments);
  for (int it = 0; it < 4; ++it) {
    std::fill(num.begin(), num.end(), 0.0);
    std::fill(den.begin(), den.end(), 0.0);
    std::fill(var.begin(), var.end(), 0.0);
    for (std::size_t i = 0; i < model.size(); ++i) {
      const int s = seg[i / 3];
      if (s < 0 || rows[s] < kMinSegmentRows) continue;
      const std::size_t j = 3 * s + i % 3;
      const double r = (*p.y)[i] - k[j] * model[i];
      if (p.Passes(i, r)) continue;  // a bound the segment's albedo keeps: no pull (an active one pulls as a measurement)
      const double w = p.loss.Weight(r);
      num[j] += w * model[i] * (*p.y)[i];
      den[j] += w * model[i] * model[i];
      if (!noise.empty()) var[j] += w * noise[i] * noise[i];
    }
    for (std::size_t j = 0; j < k.size(); ++j)
      if (den[j] > 0)  // (the noise's share of sum model^2 taken out, at most half of it)
        k[j] = std::clamp(num[j] / std::max(den[j] - var[j], 0.5 * den[j]), 1 / kMaxSegmentMultiplier,
                          kMaxSegmentMultiplier);
  }
  for (std::size_t i = 0; i < model.size(); ++i) {
    const int s = seg[i / 3];
    if (s >= 0 && rows[s] >= kMinSegmentRows) m[i] = k[3 * s + i % 3];
  }
  return m;
}

LightFitSubset::LightFitSubset(const LightFitProblem& full, std::size_t max_rows) : problem(full) {
  const std::size_t rows = full.vertices->rows();
  if (max_rows == 0 || rows <= max_rows) return;
  stride = static_cast<int>((rows + max_rows - 1) / max_rows);
  const ShadingVertices& v = *full.vertices;
  for (std::size_t r = 0; r < rows; r += stride) {
    for (std::int64_t k = v.row_start[r]; k < v.row_start[r + 1]; ++k) {
      vertices.position.push_back(v.position[k]);
      vertices.normal.push_back(v.normal[k]);
      vertices.geometric.push_back(v.geometric[k]);
      vertices.weight.push_back(v.weight[k]);
      if (v.camera.size() == v.size()) vertices.camera.push_back(v.camera[k]);
      if (v.half.size() == v.size()) vertices.half.push_back(v.half[k]);
      if (v.part.size() == v.size()) vertices.part.push_back(v.part[k]);
    }
    vertices.row_start.push_back(static_cast<std::int64_t>(vertices.position.size()));
    for (int c = 0; c < 3; ++c) {
      y.push_back((*full.y)[3 * r + c]);
      base.push_back((*full.base)[3 * r + c]);
      if (full.one_sided) one_sided.push_back((*full.one_sided)[3 * r + c]);
    }
    if (full.segment) segment.push_back((*full.segment)[r]);
  }
  problem.vertices = &vertices;
  problem.y = &y;
  problem.base = &base;
  problem.one_sided = full.one_sided ? &one_sided : nullptr;
  if (full.segment) problem.segment = &segment;
  problem.alpha /= stride;
}

DampedStep::DampedStep(Eigen::MatrixXd H, Eigen::VectorXd g) : H_(std::move(H)), g_(std::move(g)), d_(H_.rows()) {
  for (int a = 0; a < H_.rows(); ++a) d_[a] = std::max(H_(a, a), 1e-12);
}

Eigen::VectorXd DampedStep::Within(double radius, double* mu) const {
  Eigen::VectorXd s = At(*mu);
  for (int k = 0; k < 200 && s.allFinite() && Length(s) > radius; ++k) s = At(*mu *= 2);
  for (int k = 0; k < 8 && !s.allFinite(); ++k) s = At(*mu *= 10);
  return s;
}

Eigen::VectorXd DampedStep::At(double mu) const {
  Eigen::MatrixXd M = H_;
  M.diagonal() += mu * d_;
  return M.ldlt().solve(g_);
}

int RefineLights(const LightFitProblem& p, std::vector<Light>* lights, int max_iterations, const LightFitLog& log,
                 double min_drop) {
  const int K = static_cast<int>(lights->size());
  if (K == 0) return 0;
  std::vector<int> offset{0};  // per light: its shape's coordinates, then its scale (3)
  for (const Light& l : *lights) offset.push_back(offset.back() + ShapeDims(l) + 3);
  Traced t;
  TraceColumns(p, *lights, &t, true);
  Fitted f = Residual(p, *lights, t.cols);
  double E = Energy(p, *lights, f);
  double mu = 1e-3;
  int it = 0;
  for (; it < max_iterations; ++it) {
    Eigen::MatrixXd H;
    Eigen::VectorXd g;
    NormalEquations(p, *lights, offset, t, f, &H, &g);
    const DampedStep damped(H, g);
    bool accepted = false;
    double radius = INFINITY;  // the last rejected step's damped length, a quarter of it next
    for (int tries = 0; tries < 8 && !accepted; ++tries) {
      const Eigen::VectorXd step = damped.Within(radius, &mu);
      if (!step.allFinite()) break;
      // A step the model says gains less than min_drop is not traced: its columns cost
      // what the fit does, and steps that small gain what the model says (or nothing).
      const double predicted = damped.PredictedDrop(step);
      if (predicted > 0 && predicted < min_drop * std::abs(E)) return it;
      std::vector<Light> trial;
      for (int k = 0; k < K; ++k) {
        trial.push_back(Moved((*lights)[k], &step[offset[k]]));
        Scale(trial[k]) = (Scale(trial[k]) + step.segment<3>(offset[k + 1] - 3)).cwiseMax(0.0);
      }
      Traced tt;
      TraceColumns(p, trial, &tt, true);
      Fitted tf = Residual(p, trial, tt.cols);
      const double tE = Energy(p, trial, tf);
      if (tE < E) {
        accepted = true;
        const double drop = (E - tE) / std::max(std::abs(E), 1e-300);
        *lights = std::move(trial);
        t = std::move(tt);
        f = std::move(tf);
        E = tE;
        mu = std::max(mu / 3, 1e-9);
        if (log) log(it + 1, E, SquaredSum(f.r), *lights);
        if (drop < min_drop) return it + 1;
      } else {
        radius = damped.Length(step) / 4;
      }
    }
    if (!accepted) break;
  }
  return it;
}

std::vector<Eigen::Matrix3d> PartsCovariance(LightFitProblem p, const std::vector<Light>& lights, int iterations,
                                             std::vector<Eigen::Vector3d>* pull) {
  std::vector<Eigen::Matrix3d> out(lights.size(), Eigen::Matrix3d::Zero());
  if (pull) pull->assign(lights.size(), Eigen::Vector3d::Zero());
  const ShadingVertices& whole = *p.vertices;
  if (whole.part.size() != whole.size() || whole.size() == 0) return out;
  std::vector<Light> refit_whole = lights;
  RefineLights(p, &refit_whole, iterations);
  std::vector<std::vector<Light>> refit(kPathParts, lights);
  for (int q = 0; q < kPathParts; ++q) {
    const ShadingVertices part = PartOf(whole, q);
    p.vertices = &part;
    RefineLights(p, &refit[q], iterations);
  }
  for (std::size_t k = 0; k < lights.size(); ++k) {
    if (!std::holds_alternative<PointLight>(lights[k])) continue;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& r : refit) mean += std::get<PointLight>(r[k]).position / kPathParts;
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (const auto& r : refit) {
      const Eigen::Vector3d d = std::get<PointLight>(r[k]).position - mean;
      scatter += d * d.transpose();
    }
    // The parts' sample covariance (over kPathParts - 1), a part's; the whole's is 1/kPathParts of it.
    if (scatter.allFinite()) out[k] = scatter / ((kPathParts - 1) * kPathParts);
    // The pull goes as one over the paths: a part's is kPathParts times the whole's, so the
    // parts' mean is (kPathParts - 1) pulls from the whole's refit.
    const Eigen::Vector3d b = (mean - std::get<PointLight>(refit_whole[k]).position) / (kPathParts - 1);
    if (!b.allFinite()) continue;
    out[k] += b * b.transpose();
    if (pull) (*pull)[k] = b;
  }
  return out;
}

double RefitScale(const LightFitProblem& p, const SplitColumn& others, Light* light, double* sse) {
  SplitColumn col;
  UnitColumn(*p.scene, *p.vertices, *light, ColumnOut{&col.value, nullptr, p.debiased ? &col.spread : nullptr});
  return RefitScale(p, col, others, &Scale(*light), sse);
}

double RefitScale(const LightFitProblem& p, const SplitColumn& column, const SplitColumn& others,
                  Eigen::Vector3d* scale_out, double* sse) {
  const std::vector<float>& col = column.value;
  std::vector<double> rest(*p.base);  // what the others render, held
  if (!others.value.empty())
    for (std::size_t i = 0; i < col.size(); ++i) rest[i] += others.value[i];
  // Debiased: the model's noise is the others' spread plus the scale times the column's.
  const bool debiased = HasSpread(p, column) && (others.spread.empty() || others.spread.size() == col.size());
  std::vector<double> rest_noise(debiased ? col.size() : 0, 0.0);
  if (debiased && others.spread.size() == col.size())
    std::copy(others.spread.begin(), others.spread.end(), rest_noise.begin());
  Eigen::Vector3d& scale = *scale_out;
  const auto model = [&](std::vector<double>* noise) {
    std::vector<double> out(rest);
    for (std::size_t i = 0; i < col.size(); ++i) out[i] += scale[i % 3] * col[i];
    *noise = rest_noise;
    for (std::size_t i = 0; i < noise->size(); ++i) (*noise)[i] += scale[i % 3] * column.spread[i];
    return out;
  };
  std::vector<double> m(col.size(), 1.0), noise;
  for (int it = 0; it < 4; ++it) {
    if (p.segment) {  // the albedos for this scale, then the scale for them
      const std::vector<double> now = model(&noise);
      m = SegmentMultipliers(p, now, noise);
    }
    // d/ds sum w ((left - s mc)^2 - (m (rest_noise + s spread))^2) = 0
    Eigen::Vector3d num = Eigen::Vector3d::Zero(), den = Eigen::Vector3d::Zero(), var = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < col.size(); ++i) {
      const double left = (*p.y)[i] - m[i] * rest[i], mc = m[i] * col[i];
      const double r = left - scale[i % 3] * mc, w = p.loss.Weight(r);
      if (p.Passes(i, r)) continue;  // (a bound it passes)
      num[i % 3] += w * mc * left;
      den[i % 3] += w * mc * mc;
      if (debiased) {
        const double ms = m[i] * column.spread[i];
        num[i % 3] += w * ms * m[i] * rest_noise[i];
        var[i % 3] += w * ms * ms;
      }
    }
    for (int c = 0; c < 3; ++c)  // (the noise's share of the curvature at most half of it)
      scale[c] = den[c] > 0 ? std::max(0.0, num[c] / std::max(den[c] - var[c], 0.5 * den[c])) : 0.0;
  }
  const std::vector<double> final_model = model(&noise);
  if (p.segment) m = SegmentMultipliers(p, final_model, noise);
  std::vector<double> r(col.size());
  for (std::size_t i = 0; i < col.size(); ++i) r[i] = p.RowResidual(i, m[i] * final_model[i]);
  for (std::size_t i = 0; i < noise.size(); ++i) noise[i] *= m[i];
  *sse = SquaredSum(r);
  return LossSum(p.loss, r, noise) + Penalty(p, scale);
}

int SearchLights(const LightFitProblem& p, std::vector<Light>* lights, const Eigen::Vector3d& centre,
                 const CompassOptions& o, const LightFitLog& log) {
  int moves = 0;
  for (std::size_t k = 0; k < lights->size(); ++k) {
    SplitColumn others, col;  // the other lights' render, held
    others.value.assign(p.y->size(), 0.0f);
    if (p.debiased) others.spread.assign(p.y->size(), 0.0f);
    for (std::size_t j = 0; j < lights->size(); ++j) {
      if (j == k) continue;
      UnitColumn(*p.scene, *p.vertices, (*lights)[j],
                 ColumnOut{&col.value, nullptr, p.debiased ? &col.spread : nullptr});
      const Eigen::Vector3d& s = Scale((*lights)[j]);
      for (std::size_t i = 0; i < col.value.size(); ++i) {
        others.value[i] += static_cast<float>(s[i % 3] * col.value[i]);
        if (p.debiased) others.spread[i] += static_cast<float>(s[i % 3] * col.spread[i]);
      }
    }
    // The light as it is, its scale refitted on these rows.
    Light current = (*lights)[k];
    double sse = 0;
    double E = RefitScale(p, others, &current, &sse);
    if (o.refit_unmoved) (*lights)[k] = current;
    const double unit = CompassUnit(current, centre);
    int evaluations = 0;
    for (double step = o.start * unit; step >= o.stop * unit * 0.999 && evaluations < o.max_evaluations;) {
      bool moved = false;
      for (int a = 0; a < CompassMoves(current) && !moved && evaluations < o.max_evaluations; ++a) {
        Light trial = CompassMove(current, a, step);
        double trial_sse = 0;
        const double tE = RefitScale(p, others, &trial, &trial_sse);
        ++evaluations;
        if (tE < E) {
          current = trial;
          (*lights)[k] = trial;
          E = tE;
          sse = trial_sse;
          moved = true;
          ++moves;
          if (log) log(moves, E, sse, *lights);
        }
      }
      if (!moved) step *= 0.5;
    }
  }
  return moves;
}

namespace {

/// A bracket of log2 sizes (a < x < c) with x's loss the lowest of the three.
struct SizeBracket {
  double a, x, c, la, lx, lc;
  /// The vertex of the parabola through the three, kept inside and a little away from x.
  double Vertex() const {
    const double p = (x - a) * (x - a) * (lx - lc) - (x - c) * (x - c) * (lx - la);
    const double q = (x - a) * (lx - lc) - (x - c) * (lx - la);
    constexpr double kMinStep = 0.05;  // in log2: 3.5 % of the size
    double v = q != 0 ? x - 0.5 * p / q : x;
    v = std::clamp(v, a + kMinStep, c - kMinStep);
    if (!(std::abs(v - x) >= kMinStep)) v = x + (c - x > x - a ? kMinStep : -kMinStep);
    return v;
  }
  /// Take a trial at v with loss lv: the bracket narrows around the lowest.
  bool Take(double v, double lv) {
    if (lv < lx) {
      if (v < x) c = x, lc = lx;
      else a = x, la = lx;
      x = v, lx = lv;
      return true;
    }
    if (v < x) a = v, la = lv;
    else c = v, lc = lv;
    return false;
  }
};

}  // namespace

namespace {

/// ChooseSize's search: the lowest loss over the grid, refined; the scale at size 0 in
/// `zero_scale`.
SizeChoice LowestSize(const SizeLoss& loss, double first, int steps, int refinements, Eigen::Vector3d* zero_scale) {
  SizeChoice best;
  Eigen::Vector3d scale;
  best.zero_loss = best.loss = loss(0, &best.scale);
  *zero_scale = best.scale;
  std::vector<double> u, l;  // the grid's log2 sizes and losses
  int b = -1;
  for (int g = 0; g < steps; ++g) {
    u.push_back(std::log2(first) + g);
    l.push_back(loss(std::exp2(u.back()), &scale));
    if (l.back() < best.loss) best.loss = l.back(), best.size = std::exp2(u.back()), best.scale = scale, b = g;
  }
  // A point, or the widest: kept as it is (the widest says "at least this wide": a sun
  // there is a wide far light, left to the map).
  if (b < 0 || b == steps - 1) return best;
  SizeBracket br{0, u[b], 0, 0, l[b], 0};
  if (b == 0) {  // the first: bracketed by half of it, or that is taken
    br.c = u[1], br.lc = l[1], br.a = u[0] - 1;
    br.la = loss(std::exp2(br.a), &scale);
    if (br.la < br.lx) {
      best.loss = br.la, best.size = std::exp2(br.a), best.scale = scale;
      return best;
    }
  } else {
    br.a = u[b - 1], br.la = l[b - 1], br.c = u[b + 1], br.lc = l[b + 1];
  }
  for (int r = 0; r < refinements; ++r) {
    const double v = br.Vertex(), lv = loss(std::exp2(v), &scale);
    if (br.Take(v, lv)) best.loss = lv, best.size = std::exp2(v), best.scale = scale;
  }
  return best;
}

}  // namespace

SizeChoice ChooseSize(const SizeLoss& loss, double first, int steps, int refinements, double min_gain) {
  Eigen::Vector3d zero_scale;
  SizeChoice best = LowestSize(loss, first, steps, refinements, &zero_scale);
  if (best.size > 0 && !(best.loss < (1 - min_gain) * best.zero_loss))  // not worth a size
    best.size = 0, best.loss = best.zero_loss, best.scale = zero_scale;
  return best;
}

double FitAngularRadius(const LightFitProblem& p, DirectionalLight* light) {
  constexpr double kDeg = 3.14159265358979323846 / 180;
  const SizeLoss energy = [&](double radius, Eigen::Vector3d* irradiance) {
    Light trial = *light;
    std::get<DirectionalLight>(trial).angular_radius = radius;
    double sse = 0;
    const double e = RefitScale(p, {}, &trial, &sse);
    *irradiance = Scale(trial);
    return e;
  };
  const SizeChoice best = ChooseSize(energy, kMaxAngularRadiusDeg / 32 * kDeg, 6);
  light->angular_radius = best.size;
  light->irradiance = best.scale;
  return light->angular_radius;
}

}  // namespace lp
