#include "estimation/light_fit.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "common/error.h"

namespace lp {
namespace {

/// What base and the lights render, 3 per row (the lights' columns given).
std::vector<double> Model(const LightFitProblem& p, const std::vector<Light>& lights,
                          const std::vector<std::vector<float>>& columns) {
  LP_CHECK(columns.size() == lights.size(), "a column per light");
  std::vector<double> model(*p.base);
  for (std::size_t k = 0; k < lights.size(); ++k) {
    LP_CHECK(columns[k].size() == model.size(), "a column of the problem's rows");
    const Eigen::Vector3d& s = Scale(lights[k]);
    for (std::size_t i = 0; i < model.size(); ++i) model[i] += s[i % 3] * columns[k][i];
  }
  return model;
}

/// Residuals y - m model over all rows, the lights' columns given; `mult` receives m (3
/// per row; all 1 without segments).
std::vector<double> Residual(const LightFitProblem& p, const std::vector<Light>& lights,
                             const std::vector<std::vector<float>>& columns, std::vector<double>* mult = nullptr) {
  const std::vector<double> model = Model(p, lights, columns);
  const std::vector<double> m = SegmentMultipliers(p, model);
  std::vector<double> r(model.size());
  for (std::size_t i = 0; i < r.size(); ++i) r[i] = (*p.y)[i] - m[i] * model[i];
  if (mult) *mult = m;
  return r;
}

/// The lights' unit columns on the problem's vertices (and their Jacobians when asked).
void TraceColumns(const LightFitProblem& p, const std::vector<Light>& lights, std::vector<std::vector<float>>* columns,
                  std::vector<std::vector<float>>* jacobians) {
  columns->resize(lights.size());
  if (jacobians) jacobians->resize(lights.size());
  for (std::size_t k = 0; k < lights.size(); ++k)
    UnitColumn(*p.scene, *p.vertices, lights[k], &(*columns)[k], jacobians ? &(*jacobians)[k] : nullptr);
}

double Penalty(const LightFitProblem& p, const Eigen::Vector3d& scale) {
  return p.alpha * std::log1p(p.beta * std::max(0.0, scale.sum()));
}

double Energy(const LightFitProblem& p, const std::vector<Light>& lights, const std::vector<double>& r) {
  double e = p.loss.Sum(r);
  for (const Light& l : lights) e += Penalty(p, Scale(l));
  return e;
}

double SquaredSum(const std::vector<double>& r) {
  double sse = 0;
  for (double v : r) sse += v * v;
  return sse;
}

/// The reweighted normal equations of RefineLights at `lights` (H lower and upper, g).
void NormalEquations(const LightFitProblem& p, const std::vector<Light>& lights, const std::vector<int>& offset,
                     const std::vector<std::vector<float>>& cols, const std::vector<std::vector<float>>& jacs,
                     const std::vector<double>& r, const std::vector<double>& mult, Eigen::MatrixXd* H,
                     Eigen::VectorXd* g) {
  const int K = static_cast<int>(lights.size()), n = offset.back();
  *H = Eigen::MatrixXd::Zero(n, n);
  *g = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd J(n);
  double shape[3];
  std::vector<Eigen::Matrix3d> bases;  // each light's, once (not per row)
  for (const Light& l : lights) bases.push_back(ShapeBasis(l));
  for (std::size_t i = 0; i < r.size(); ++i) {
    const std::size_t row = i / 3;
    const int c = static_cast<int>(i % 3);
    J.setZero();
    bool any = false;
    for (int k = 0; k < K; ++k) {
      const int dims = offset[k + 1] - offset[k] - 3;
      ShapeGradient(bases[k], dims, &jacs[k][9 * row + 3 * c], shape);
      for (int a = 0; a < dims; ++a) J[offset[k] + a] = Scale(lights[k])[c] * shape[a];
      J[offset[k] + dims + c] = cols[k][i];
      any = any || cols[k][i] != 0;
    }
    if (!any) continue;
    J *= mult[i];  // the segments' multipliers held (their own derivative left out)
    const double w = p.loss.Weight(r[i]);
    H->selfadjointView<Eigen::Lower>().rankUpdate(J, w);
    *g += w * r[i] * J;
  }
  *H = H->selfadjointView<Eigen::Lower>();
  for (int k = 0; k < K; ++k)  // the penalty's gradient on the scales
    for (int c = 0; c < 3; ++c)
      (*g)[offset[k + 1] - 3 + c] -= p.alpha * p.beta / (1 + p.beta * std::max(0.0, Scale(lights[k]).sum()));
}

}  // namespace

double LightFitProblem::Value(const std::vector<Light>& lights, double* sse) const {
  std::vector<std::vector<float>> columns;
  TraceColumns(*this, lights, &columns, nullptr);
  return Value(lights, columns, sse);
}

double LightFitProblem::Value(const std::vector<Light>& lights, const std::vector<std::vector<float>>& columns,
                              double* sse) const {
  const std::vector<double> r = Residual(*this, lights, columns);
  if (sse) *sse = SquaredSum(r);
  return Energy(*this, lights, r);
}

std::vector<double> SegmentMultipliers(const LightFitProblem& p, const std::vector<double>& model) {
  std::vector<double> m(model.size(), 1.0);
  if (!p.segment) return m;
  const std::vector<int>& seg = *p.segment;
  LP_CHECK(seg.size() * 3 == model.size(), "a segment per row");
  int segments = 0;
  for (int s : seg) segments = std::max(segments, s + 1);
  std::vector<int> rows(segments, 0);
  for (int s : seg)
    if (s >= 0) ++rows[s];
  std::vector<double> k(3 * segments, 1.0), num(3 * segments), den(3 * segments);
  for (int it = 0; it < 4; ++it) {
    std::fill(num.begin(), num.end(), 0.0);
    std::fill(den.begin(), den.end(), 0.0);
    for (std::size_t i = 0; i < model.size(); ++i) {
      const int s = seg[i / 3];
      if (s < 0 || rows[s] < kMinSegmentRows) continue;
      const std::size_t j = 3 * s + i % 3;
      const double w = p.loss.Weight((*p.y)[i] - k[j] * model[i]);
      num[j] += w * model[i] * (*p.y)[i];
      den[j] += w * model[i] * model[i];
    }
    for (std::size_t j = 0; j < k.size(); ++j)
      if (den[j] > 0)
        k[j] = std::clamp(num[j] / den[j], 1 / kMaxSegmentMultiplier, kMaxSegmentMultiplier);
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
    }
    vertices.row_start.push_back(static_cast<std::int64_t>(vertices.position.size()));
    for (int c = 0; c < 3; ++c) {
      y.push_back((*full.y)[3 * r + c]);
      base.push_back((*full.base)[3 * r + c]);
    }
    if (full.segment) segment.push_back((*full.segment)[r]);
  }
  problem.vertices = &vertices;
  problem.y = &y;
  problem.base = &base;
  if (full.segment) problem.segment = &segment;
  problem.alpha /= stride;
}

int RefineLights(const LightFitProblem& p, std::vector<Light>* lights, int max_iterations, const LightFitLog& log) {
  const int K = static_cast<int>(lights->size());
  if (K == 0) return 0;
  std::vector<int> offset{0};  // per light: its shape's coordinates, then its scale (3)
  for (const Light& l : *lights) offset.push_back(offset.back() + ShapeDims(l) + 3);
  const int n = offset.back();
  std::vector<std::vector<float>> cols, jacs;
  TraceColumns(p, *lights, &cols, &jacs);
  std::vector<double> mult;
  std::vector<double> r = Residual(p, *lights, cols, &mult);
  double E = Energy(p, *lights, r);
  double mu = 1e-3;
  int it = 0;
  for (; it < max_iterations; ++it) {
    Eigen::MatrixXd H;
    Eigen::VectorXd g;
    NormalEquations(p, *lights, offset, cols, jacs, r, mult, &H, &g);
    bool accepted = false;
    for (int tries = 0; tries < 8 && !accepted; ++tries) {
      Eigen::MatrixXd M = H;
      for (int a = 0; a < n; ++a) M(a, a) += mu * std::max(H(a, a), 1e-12);
      const Eigen::VectorXd step = M.ldlt().solve(g);
      if (!step.allFinite()) {
        mu *= 10;
        continue;
      }
      std::vector<Light> trial;
      for (int k = 0; k < K; ++k) {
        trial.push_back(Moved((*lights)[k], &step[offset[k]]));
        Scale(trial[k]) = (Scale(trial[k]) + step.segment<3>(offset[k + 1] - 3)).cwiseMax(0.0);
      }
      std::vector<std::vector<float>> tcols, tjacs;
      TraceColumns(p, trial, &tcols, &tjacs);
      std::vector<double> tmult;
      std::vector<double> tr = Residual(p, trial, tcols, &tmult);
      const double tE = Energy(p, trial, tr);
      if (tE < E) {
        accepted = true;
        const double drop = (E - tE) / std::max(E, 1e-300);
        *lights = std::move(trial);
        cols.swap(tcols);
        jacs.swap(tjacs);
        r.swap(tr);
        mult.swap(tmult);
        E = tE;
        mu = std::max(mu / 3, 1e-9);
        if (log) log(it + 1, E, SquaredSum(r), *lights);
        if (drop < 1e-6) return it + 1;
      } else {
        mu *= 10;
      }
    }
    if (!accepted) break;
  }
  return it;
}

double RefitScale(const LightFitProblem& p, const std::vector<float>& others, Light* light, double* sse) {
  std::vector<float> col;
  UnitColumn(*p.scene, *p.vertices, *light, &col);
  return RefitScale(p, col, others, &Scale(*light), sse);
}

double RefitScale(const LightFitProblem& p, const std::vector<float>& col, const std::vector<float>& others,
                  Eigen::Vector3d* scale_out, double* sse) {
  std::vector<double> rest(*p.base);  // what the others render, held
  if (!others.empty())
    for (std::size_t i = 0; i < col.size(); ++i) rest[i] += others[i];
  Eigen::Vector3d& scale = *scale_out;
  const auto model = [&] {
    std::vector<double> out(rest);
    for (std::size_t i = 0; i < col.size(); ++i) out[i] += scale[i % 3] * col[i];
    return out;
  };
  std::vector<double> m(col.size(), 1.0);
  for (int it = 0; it < 4; ++it) {
    if (p.segment) m = SegmentMultipliers(p, model());  // the albedos for this scale, then the scale for them
    Eigen::Vector3d num = Eigen::Vector3d::Zero(), den = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < col.size(); ++i) {
      const double left = (*p.y)[i] - m[i] * rest[i], mc = m[i] * col[i];
      const double r = left - scale[i % 3] * mc, w = p.loss.Weight(r);
      num[i % 3] += w * mc * left;
      den[i % 3] += w * mc * mc;
    }
    for (int c = 0; c < 3; ++c) scale[c] = den[c] > 0 ? std::max(0.0, num[c] / den[c]) : 0.0;
  }
  const std::vector<double> final_model = model();
  if (p.segment) m = SegmentMultipliers(p, final_model);
  std::vector<double> r(col.size());
  for (std::size_t i = 0; i < col.size(); ++i) r[i] = (*p.y)[i] - m[i] * final_model[i];
  *sse = SquaredSum(r);
  return p.loss.Sum(r) + Penalty(p, scale);
}

int SearchLights(const LightFitProblem& p, std::vector<Light>* lights, const Eigen::Vector3d& centre,
                 const CompassOptions& o, const LightFitLog& log) {
  int moves = 0;
  for (std::size_t k = 0; k < lights->size(); ++k) {
    std::vector<float> others(p.y->size(), 0.0f), col;  // the other lights' render, held
    for (std::size_t j = 0; j < lights->size(); ++j) {
      if (j == k) continue;
      UnitColumn(*p.scene, *p.vertices, (*lights)[j], &col);
      const Eigen::Vector3d& s = Scale((*lights)[j]);
      for (std::size_t i = 0; i < col.size(); ++i) others[i] += static_cast<float>(s[i % 3] * col[i]);
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

double FitAngularRadius(const LightFitProblem& p, DirectionalLight* light) {
  constexpr double kDeg = 3.14159265358979323846 / 180;
  double sse = 0;
  const auto energy = [&](DirectionalLight* l) {
    Light as_light = *l;
    const double e = RefitScale(p, {}, &as_light, &sse);
    *l = std::get<DirectionalLight>(as_light);
    return e;
  };
  DirectionalLight sharp = *light;
  sharp.angular_radius = 0;
  const double sharp_energy = energy(&sharp);
  DirectionalLight best = sharp;
  double best_energy = sharp_energy;
  for (double deg = kMaxAngularRadiusDeg / 32; deg <= kMaxAngularRadiusDeg; deg *= 2) {
    DirectionalLight trial = *light;
    trial.angular_radius = deg * kDeg;
    const double e = energy(&trial);
    if (e < best_energy) best_energy = e, best = trial;
  }
  *light = best_energy < (1 - 0.005) * sharp_energy ? best : sharp;
  return light->angular_radius;
}

}  // namespace lp
