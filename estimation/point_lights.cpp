#include "estimation/point_lights.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "common/error.h"
#include "common/parallel.h"
#include "common/rng.h"
#include "estimation/pixel_loop.h"
#include "estimation/sampling.h"

namespace lp {
namespace {

using detail::Counters;
using detail::ForEachPixel;
using detail::PixelRef;
using detail::PixelsToTrace;
using detail::PathContinues;

/// One camera path of pixel (x, y): calls vertex(hit, offset origin, weight) at every
/// surface interaction, weight = throughput x albedo / pi (per sample).
template <class Sink>
void WalkPath(const RayTracer& scene, const Camera& cam, int x, int y, Rng& rng, const TracerOptions& opt,
              Counters& cnt, Sink&& vertex) {
  ++cnt.paths;
  const Eigen::Vector3d origin = cam.center();
  const Eigen::Vector3d dir = cam.RayDirection(x + rng.Uniform() - 0.5, y + rng.Uniform() - 0.5);
  Eigen::Vector3d T(1, 1, 1);
  SurfacePoint hit;
  ++cnt.rays;
  if (!scene.Intersect(origin, dir, &hit)) return;
  const double eps = scene.epsilon();
  for (int bounce = 0;; ++bounce) {
    const Eigen::Vector3d off = hit.position + hit.geometric * (4 * eps);
    vertex(hit, off, Eigen::Vector3d(T.cwiseProduct(hit.albedo) * kInvPi));
    const Eigen::Vector3d w = SampleCosine(hit.shading, rng.Uniform(), rng.Uniform());
    T = T.cwiseProduct(hit.albedo);
    if (hit.geometric.dot(w) <= 0) return;
    if (bounce + 1 >= opt.bounces) {
      ++cnt.max_bounces;
      return;
    }
    ++cnt.rays;
    SurfacePoint next;
    if (!scene.Intersect(off, w, &next)) return;
    if (!PathContinues(bounce, opt, &T, rng, cnt)) return;
    hit = next;
  }
}

/// cos / d^2 from a vertex to a light at q, 0 when the light is behind either normal.
inline double Falloff(const Eigen::Vector3d& p, const Eigen::Vector3d& n, const Eigen::Vector3d& g,
                      const Eigen::Vector3d& q, Eigen::Vector3d* to_light, double* dist) {
  const Eigen::Vector3d r = q - p;
  const double d2 = r.squaredNorm();
  if (!(d2 > 0)) return 0;
  const double d = std::sqrt(d2);
  const double cn = n.dot(r), cg = g.dot(r);
  if (!(cn > 0 && cg > 0)) return 0;
  *to_light = r / d;
  *dist = d;
  return cn / (d2 * d);
}

void CheckOptions(const TracerOptions& o) {
  if (o.spp < 1) throw InputError("spp must be at least 1");
  if (o.bounces < 1) throw InputError("bounces must be at least 1");
}

}  // namespace

ShadingVertices GatherShadingVertices(const RayTracer& scene, const std::vector<View>& views,
                                      const TracerOptions& opt, bool all_pixels, TraceStats* stats) {
  CheckOptions(opt);
  struct Vertex {
    Eigen::Vector3f p, n, g, w;
  };
  const std::vector<PixelRef> pixels = PixelsToTrace(views, all_pixels);
  std::vector<std::vector<Vertex>> rows(pixels.size());
  const float inv = 1.0f / opt.spp;
  ForEachPixel(pixels, opt, stats, [&](std::size_t i, const PixelRef& px, Counters& cnt) {
    const Camera& cam = views[px.view].camera;
    const int x = px.pixel % cam.width, y = px.pixel / cam.width;
    for (int s = 0; s < opt.spp; ++s) {
      Rng rng(opt.seed, px.view, px.pixel, s);
      WalkPath(scene, cam, x, y, rng, opt, cnt,
               [&](const SurfacePoint& hit, const Eigen::Vector3d& off, const Eigen::Vector3d& w) {
                 rows[i].push_back({off.cast<float>(), hit.shading.cast<float>(), hit.geometric.cast<float>(),
                                    w.cast<float>() * inv});
               });
    }
  });
  ShadingVertices out;
  std::size_t n = 0;
  for (const auto& r : rows) n += r.size();
  out.row_start.reserve(rows.size() + 1);
  out.position.reserve(n);
  out.normal.reserve(n);
  out.geometric.reserve(n);
  out.weight.reserve(n);
  for (auto& r : rows) {
    for (const Vertex& v : r) {
      out.position.push_back(v.p);
      out.normal.push_back(v.n);
      out.geometric.push_back(v.g);
      out.weight.push_back(v.w);
    }
    out.row_start.push_back(static_cast<std::int64_t>(out.position.size()));
    std::vector<Vertex>().swap(r);
  }
  if (stats) stats->pixels_traced += static_cast<std::int64_t>(pixels.size());
  return out;
}

ShadingVertices Combine(const ShadingVertices& a, double a_samples, const ShadingVertices& b, double b_samples) {
  LP_CHECK(a.rows() == b.rows(), "combining gatherings of different rows");
  const double n = a_samples + b_samples;
  LP_CHECK(n > 0, "no samples");
  const float wa = static_cast<float>(a_samples / n), wb = static_cast<float>(b_samples / n);
  ShadingVertices out;
  const std::size_t total = a.size() + b.size();
  out.row_start.reserve(a.rows() + 1);
  out.position.reserve(total);
  out.normal.reserve(total);
  out.geometric.reserve(total);
  out.weight.reserve(total);
  for (std::size_t r = 0; r < a.rows(); ++r) {
    for (const auto& [v, w] : {std::pair<const ShadingVertices*, float>{&a, wa}, {&b, wb}})
      for (std::int64_t k = v->row_start[r]; k < v->row_start[r + 1]; ++k) {
        out.position.push_back(v->position[k]);
        out.normal.push_back(v->normal[k]);
        out.geometric.push_back(v->geometric[k]);
        out.weight.push_back(v->weight[k] * w);
      }
    out.row_start.push_back(static_cast<std::int64_t>(out.position.size()));
  }
  return out;
}

namespace {

/// splitmix64 of `z` as a number in [0, 1).
double HashUnit(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

}  // namespace

double SphereVisibility(const RayTracer& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& q, double radius,
                        const Eigen::Vector3d& l, double d, std::uint64_t key, int rays) {
  if (!(radius > 0)) return scene.Occluded(p, l, d) ? 0.0 : 1.0;
  if (d <= radius) return 1.0;  // inside the light
  // An orthonormal frame (t, b) across l.
  const Eigen::Vector3d t = (std::abs(l.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY())
                                .cross(l)
                                .normalized();
  const Eigen::Vector3d b = l.cross(t);
  const double turn = HashUnit(key), jitter = HashUnit(key ^ 0x5DEECE66Dull);
  int seen = 0;
  for (int i = 0; i < rays; ++i) {
    const double rho = radius * std::sqrt((i + jitter) / rays);  // equal-area rings
    const double a = 2 * kPi * (turn + i * 0.6180339887498949);
    const Eigen::Vector3d s = q + rho * (std::cos(a) * t + std::sin(a) * b) - p;
    const double len = s.norm();
    seen += !scene.Occluded(p, s / len, len);
  }
  return static_cast<double>(seen) / rays;
}

double ConeVisibility(const RayTracer& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& l, double angular_radius,
                      std::uint64_t key, int rays) {
  if (!(angular_radius > 0)) return scene.Occluded(p, l) ? 0.0 : 1.0;
  const Eigen::Vector3d t = (std::abs(l.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY())
                                .cross(l)
                                .normalized();
  const Eigen::Vector3d b = l.cross(t);
  const double turn = HashUnit(key), jitter = HashUnit(key ^ 0x5DEECE66Dull), spread = std::tan(angular_radius);
  int seen = 0;
  for (int i = 0; i < rays; ++i) {  // the disc at unit distance, as SphereVisibility's
    const double rho = spread * std::sqrt((i + jitter) / rays);
    const double a = 2 * kPi * (turn + i * 0.6180339887498949);
    seen += !scene.Occluded(p, (l + rho * (std::cos(a) * t + std::sin(a) * b)).normalized());
  }
  return static_cast<double>(seen) / rays;
}

void PointLightColumn(const RayTracer& scene, const ShadingVertices& v, const Eigen::Vector3d& q,
                      std::vector<float>* out, std::vector<float>* jacobian, double radius) {
  const std::size_t rows = v.rows();
  out->assign(3 * rows, 0.0f);
  if (jacobian) jacobian->assign(9 * rows, 0.0f);
  ParallelForChunks(0, rows, 64, [&](std::size_t b, std::size_t e) {
    for (std::size_t r = b; r < e; ++r) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      Eigen::Matrix3d jac = Eigen::Matrix3d::Zero();  // (channel, coordinate)
      for (std::int64_t k = v.row_start[r]; k < v.row_start[r + 1]; ++k) {
        const Eigen::Vector3d p = v.position[k].cast<double>(), n = v.normal[k].cast<double>();
        Eigen::Vector3d l;
        double d = 0;
        const double f = Falloff(p, n, v.geometric[k].cast<double>(), q, &l, &d);
        if (f == 0) continue;
        const double seen = SphereVisibility(scene, p, q, radius, l, d, static_cast<std::uint64_t>(k));
        if (seen == 0) continue;
        const Eigen::Vector3d w = v.weight[k].cast<double>() * seen;
        sum += w * f;
        if (jacobian) {
          // f = n.(q-p) / d^3:  df/dq = n / d^3 - 3 n.(q-p) (q-p) / d^5 = (n - 3 (n.l) l) / d^3.
          const Eigen::Vector3d grad = (n - 3 * n.dot(l) * l) / (d * d * d);
          jac += w * grad.transpose();
        }
      }
      for (int c = 0; c < 3; ++c) (*out)[3 * r + c] = static_cast<float>(sum[c]);
      if (jacobian)
        for (int c = 0; c < 3; ++c)
          for (int a = 0; a < 3; ++a) (*jacobian)[9 * r + 3 * c + a] = static_cast<float>(jac(c, a));
    }
  });
}

void DirectionalLightColumn(const RayTracer& scene, const ShadingVertices& v, const Eigen::Vector3d& towards,
                            std::vector<float>* out, std::vector<float>* jacobian, double angular_radius) {
  const Eigen::Vector3d l = towards.normalized();
  out->assign(3 * v.rows(), 0.0f);
  if (jacobian) jacobian->assign(9 * v.rows(), 0.0f);
  ParallelForChunks(0, v.rows(), 64, [&](std::size_t b, std::size_t e) {
    for (std::size_t r = b; r < e; ++r) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      Eigen::Matrix3d jac = Eigen::Matrix3d::Zero();  // (channel, coordinate)
      for (std::int64_t k = v.row_start[r]; k < v.row_start[r + 1]; ++k) {
        const Eigen::Vector3d n = v.normal[k].cast<double>();
        const double cn = n.dot(l), cg = v.geometric[k].cast<double>().dot(l);
        if (!(cn > 0 && cg > 0)) continue;
        const double seen =
            ConeVisibility(scene, v.position[k].cast<double>(), l, angular_radius, static_cast<std::uint64_t>(k));
        if (seen == 0) continue;
        const Eigen::Vector3d w = v.weight[k].cast<double>() * seen;
        sum += w * cn;
        if (jacobian) jac += w * (n - cn * l).transpose();  // d cos / d l on the unit sphere
      }
      for (int c = 0; c < 3; ++c) (*out)[3 * r + c] = static_cast<float>(sum[c]);
      if (jacobian)
        for (int c = 0; c < 3; ++c)
          for (int a = 0; a < 3; ++a) (*jacobian)[9 * r + 3 * c + a] = static_cast<float>(jac(c, a));
    }
  });
}

namespace {

/// What the point lights (and directional ones) send to a path vertex (per unit of its
/// weight); one shadow ray per light, to a point of its disc jittered by `key`.
Eigen::Vector3d LampsAtVertex(const RayTracer& scene, const std::vector<PointLight>& lights,
                              const std::vector<DirectionalLight>& directional, const SurfacePoint& hit,
                              const Eigen::Vector3d& off, std::uint64_t key, std::int64_t& rays) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const DirectionalLight& light : directional) {
    const double cn = hit.shading.dot(light.direction), cg = hit.geometric.dot(light.direction);
    if (!(cn > 0 && cg > 0)) continue;
    ++rays;
    const double seen = ConeVisibility(scene, off, light.direction, light.angular_radius, key, 1);
    if (seen > 0) sum += light.irradiance * (cn * seen);
  }
  for (const PointLight& light : lights) {
    Eigen::Vector3d l;
    double d = 0;
    const double f = Falloff(off, hit.shading, hit.geometric, light.position, &l, &d);
    if (f == 0) continue;
    ++rays;
    const double seen = SphereVisibility(scene, off, light.position, light.radius, l, d, key, 1);
    if (seen > 0) sum += light.intensity * (f * seen);
  }
  return sum;
}

}  // namespace

std::vector<ImageRGB> RenderLighting(const RayTracer& scene, const EnvMap& env, const std::vector<double>& lambda,
                                     const CellSampler& sampler, const std::vector<PointLight>& lights,
                                     const std::vector<DirectionalLight>& directional, const std::vector<View>& views,
                                     const TracerOptions& options, bool all_pixels, TraceStats* stats) {
  VertexLight lamps;
  if (!lights.empty() || !directional.empty())
    lamps = [&](const SurfacePoint& hit, const Eigen::Vector3d& off, std::uint64_t key, std::int64_t& rays) {
      return LampsAtVertex(scene, lights, directional, hit, off, key, rays);
    };
  return RenderEnvironment(scene, env, views, lambda, sampler, options, all_pixels, lamps, stats);
}

std::vector<ImageRGB> RenderPointLights(const RayTracer& scene, const std::vector<View>& views,
                                        const std::vector<PointLight>& lights, const TracerOptions& opt,
                                        bool all_pixels, TraceStats* stats,
                                        const std::vector<DirectionalLight>& directional) {
  CheckOptions(opt);
  std::vector<ImageRGB> out;
  for (const View& v : views) out.emplace_back(v.camera.width, v.camera.height);
  const std::vector<PixelRef> pixels = PixelsToTrace(views, all_pixels);
  ForEachPixel(pixels, opt, stats, [&](std::size_t, const PixelRef& px, Counters& cnt) {
    const Camera& cam = views[px.view].camera;
    const int x = px.pixel % cam.width, y = px.pixel / cam.width;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int s = 0; s < opt.spp; ++s) {
      Rng rng(opt.seed, px.view, px.pixel, s);
      std::uint64_t key = (static_cast<std::uint64_t>(px.pixel) << 32) ^ (static_cast<std::uint64_t>(s) << 8);
      WalkPath(scene, cam, x, y, rng, opt, cnt,
               [&](const SurfacePoint& hit, const Eigen::Vector3d& off, const Eigen::Vector3d& w) {
                 sum += w.cwiseProduct(LampsAtVertex(scene, lights, directional, hit, off, ++key, cnt.rays));
               });
    }
    float* p = out[px.view].at(x, y);
    for (int c = 0; c < 3; ++c) p[c] = static_cast<float>(sum[c] / opt.spp);
  });
  if (stats) stats->pixels_traced += static_cast<std::int64_t>(pixels.size());
  return out;
}

}  // namespace lp

namespace lp {

std::vector<Eigen::Vector3d> CandidatePositions(const Eigen::Vector3d& centre, double radius,
                                                const Eigen::Vector3d& up, int rings,
                                                const std::vector<double>& radii) {
  const EnvMap shell(rings, up);
  std::vector<Eigen::Vector3d> out;
  for (double r : radii)
    for (int j = 0; j < shell.size(); ++j) out.push_back(centre + r * radius * shell.direction(j));
  return out;
}

namespace {

/// Residuals y - base - sum_k I_k c_k over all rows, the lights' columns given.
std::vector<double> Residual(const PointFitProblem& p, const std::vector<PointLight>& lights,
                             const std::vector<std::vector<float>>& columns) {
  LP_CHECK(columns.size() == lights.size(), "a column per light");
  std::vector<double> r(p.y->size());
  for (std::size_t i = 0; i < r.size(); ++i) r[i] = (*p.y)[i] - (*p.base)[i];
  for (std::size_t k = 0; k < lights.size(); ++k) {
    LP_CHECK(columns[k].size() == r.size(), "a column of the problem's rows");
    for (std::size_t i = 0; i < r.size(); ++i) r[i] -= lights[k].intensity[i % 3] * columns[k][i];
  }
  return r;
}

/// The lights' unit columns on the problem's vertices (and their Jacobians when asked).
void TraceColumns(const PointFitProblem& p, const std::vector<PointLight>& lights,
                  std::vector<std::vector<float>>* columns, std::vector<std::vector<float>>* jacobians) {
  columns->resize(lights.size());
  if (jacobians) jacobians->resize(lights.size());
  for (std::size_t k = 0; k < lights.size(); ++k)
    PointLightColumn(*p.scene, *p.vertices, lights[k].position, &(*columns)[k],
                     jacobians ? &(*jacobians)[k] : nullptr, lights[k].radius);
}

/// The same residuals, tracing the columns (and Jacobians when asked).
std::vector<double> Residual(const PointFitProblem& p, const std::vector<PointLight>& lights,
                             std::vector<std::vector<float>>* columns, std::vector<std::vector<float>>* jacobians) {
  TraceColumns(p, lights, columns, jacobians);
  return Residual(p, lights, *columns);
}

double Energy(const PointFitProblem& p, const std::vector<PointLight>& lights, const std::vector<double>& r) {
  double e = CauchyLoss(r, p.sigma);
  for (const PointLight& l : lights) e += p.alpha * std::log1p(p.beta * std::max(0.0, l.intensity.sum()));
  return e;
}

}  // namespace

double CauchyLoss(const std::vector<double>& r, double sigma) {
  const double s2 = sigma * sigma;
  double e = 0;
  for (double v : r) e += 0.5 * s2 * std::log1p(v * v / s2);
  return e;
}

double PointFitProblem::Value(const std::vector<PointLight>& lights, double* sse) const {
  std::vector<std::vector<float>> columns;
  TraceColumns(*this, lights, &columns, nullptr);
  return Value(lights, columns, sse);
}

double PointFitProblem::Value(const std::vector<PointLight>& lights, const std::vector<std::vector<float>>& columns,
                              double* sse) const {
  const std::vector<double> r = Residual(*this, lights, columns);
  if (sse) {
    *sse = 0;
    for (double v : r) *sse += v * v;
  }
  return Energy(*this, lights, r);
}

PointFitSubset::PointFitSubset(const PointFitProblem& full, std::size_t max_rows) : problem(full) {
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
    }
    vertices.row_start.push_back(static_cast<std::int64_t>(vertices.position.size()));
    for (int c = 0; c < 3; ++c) {
      y.push_back((*full.y)[3 * r + c]);
      base.push_back((*full.base)[3 * r + c]);
    }
  }
  problem.vertices = &vertices;
  problem.y = &y;
  problem.base = &base;
  problem.alpha /= stride;
}

int RefinePointLights(const PointFitProblem& p, std::vector<PointLight>* lights, int max_iterations,
                      const std::function<void(int, double, double, const std::vector<PointLight>&)>& log) {
  const int K = static_cast<int>(lights->size());
  if (K == 0) return 0;
  const int n = 6 * K;  // per light: position (3), intensity (3)
  std::vector<std::vector<float>> cols, jacs;
  std::vector<double> r = Residual(p, *lights, &cols, &jacs);
  double E = Energy(p, *lights, r);
  double mu = 1e-3;
  int it = 0;
  for (; it < max_iterations; ++it) {
    // Normal equations of the reweighted least squares (Cauchy weight 1 / (1 + r^2/sigma^2)).
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
    Eigen::VectorXd J(n);
    for (std::size_t i = 0; i < r.size(); ++i) {
      const std::size_t row = i / 3;
      const int c = static_cast<int>(i % 3);
      J.setZero();
      bool any = false;
      for (int k = 0; k < K; ++k) {
        const float* jq = &jacs[k][9 * row + 3 * c];
        for (int a = 0; a < 3; ++a) J[6 * k + a] = (*lights)[k].intensity[c] * jq[a];
        J[6 * k + 3 + c] = cols[k][i];
        any = any || cols[k][i] != 0;
      }
      if (!any) continue;
      const double w = 1 / (1 + r[i] * r[i] / (p.sigma * p.sigma));
      H.selfadjointView<Eigen::Lower>().rankUpdate(J, w);
      g += w * r[i] * J;
    }
    H = H.selfadjointView<Eigen::Lower>();
    for (int k = 0; k < K; ++k)  // the penalty's gradient on the intensities
      for (int c = 0; c < 3; ++c)
        g[6 * k + 3 + c] -= p.alpha * p.beta / (1 + p.beta * std::max(0.0, (*lights)[k].intensity.sum()));
    bool accepted = false;
    for (int tries = 0; tries < 8 && !accepted; ++tries) {
      Eigen::MatrixXd M = H;
      for (int a = 0; a < n; ++a) M(a, a) += mu * std::max(H(a, a), 1e-12);
      const Eigen::VectorXd step = M.ldlt().solve(g);
      if (!step.allFinite()) {
        mu *= 10;
        continue;
      }
      std::vector<PointLight> trial = *lights;
      for (int k = 0; k < K; ++k) {
        trial[k].position += step.segment<3>(6 * k);
        trial[k].intensity = (trial[k].intensity + step.segment<3>(6 * k + 3)).cwiseMax(0.0);
      }
      std::vector<std::vector<float>> tcols, tjacs;
      std::vector<double> tr = Residual(p, trial, &tcols, &tjacs);
      const double tE = Energy(p, trial, tr);
      if (tE < E) {
        accepted = true;
        const double drop = (E - tE) / std::max(E, 1e-300);
        *lights = std::move(trial);
        cols.swap(tcols);
        jacs.swap(tjacs);
        r.swap(tr);
        E = tE;
        mu = std::max(mu / 3, 1e-9);
        if (log) {
          double sse = 0;
          for (double v : r) sse += v * v;
          log(it + 1, E, sse, *lights);
        }
        if (drop < 1e-6) return it + 1;
      } else {
        mu *= 10;
      }
    }
    if (!accepted) break;
  }
  return it;
}

namespace {

/// Residuals y - base - E c(l) of one directional light, its column and Jacobian.
std::vector<double> DirectionalResidual(const PointFitProblem& p, const DirectionalLight& light, std::vector<float>* col,
                                        std::vector<float>* jac) {
  DirectionalLightColumn(*p.scene, *p.vertices, light.direction, col, jac, light.angular_radius);
  std::vector<double> r(p.y->size());
  for (std::size_t i = 0; i < r.size(); ++i) r[i] = (*p.y)[i] - (*p.base)[i] - light.irradiance[i % 3] * (*col)[i];
  return r;
}

}  // namespace

int RefineDirectionalLight(const PointFitProblem& p, DirectionalLight* light, int max_iterations,
                           const std::function<void(int, double, double, const DirectionalLight&)>& log) {
  std::vector<float> col, jac;
  std::vector<double> r = DirectionalResidual(p, *light, &col, &jac);
  const auto energy = [&](const DirectionalLight& l, const std::vector<double>& res) {
    return CauchyLoss(res, p.sigma) + p.alpha * std::log1p(p.beta * std::max(0.0, l.irradiance.sum()));
  };
  double E = energy(*light, r), mu = 1e-3;
  int it = 0;
  for (; it < max_iterations; ++it) {
    // Unknowns: two steps across the direction (an orthonormal frame t, u of its tangent
    // plane) and the irradiance; the same reweighted normal equations as RefinePointLights.
    const Eigen::Vector3d& l = light->direction;
    const Eigen::Vector3d t = (std::abs(l.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).cross(l).normalized();
    const Eigen::Vector3d u = l.cross(t);
    Eigen::Matrix<double, 5, 5> H = Eigen::Matrix<double, 5, 5>::Zero();
    Eigen::Matrix<double, 5, 1> g = Eigen::Matrix<double, 5, 1>::Zero(), J;
    for (std::size_t i = 0; i < r.size(); ++i) {
      if (col[i] == 0) continue;
      const std::size_t row = i / 3;
      const int c = static_cast<int>(i % 3);
      const Eigen::Vector3d d(jac[9 * row + 3 * c], jac[9 * row + 3 * c + 1], jac[9 * row + 3 * c + 2]);
      J.setZero();
      J[0] = light->irradiance[c] * d.dot(t);
      J[1] = light->irradiance[c] * d.dot(u);
      J[2 + c] = col[i];
      const double w = 1 / (1 + r[i] * r[i] / (p.sigma * p.sigma));
      H += w * J * J.transpose();
      g += w * r[i] * J;
    }
    for (int c = 0; c < 3; ++c) g[2 + c] -= p.alpha * p.beta / (1 + p.beta * std::max(0.0, light->irradiance.sum()));
    bool accepted = false;
    for (int tries = 0; tries < 8 && !accepted; ++tries) {
      Eigen::Matrix<double, 5, 5> M = H;
      for (int a = 0; a < 5; ++a) M(a, a) += mu * std::max(H(a, a), 1e-12);
      const Eigen::Matrix<double, 5, 1> step = M.ldlt().solve(g);
      if (!step.allFinite()) {
        mu *= 10;
        continue;
      }
      DirectionalLight trial = *light;
      trial.direction = (l + step[0] * t + step[1] * u).normalized();
      trial.irradiance = (light->irradiance + step.segment<3>(2)).cwiseMax(0.0);
      std::vector<float> tcol, tjac;
      std::vector<double> tr = DirectionalResidual(p, trial, &tcol, &tjac);
      const double tE = energy(trial, tr);
      if (tE < E) {
        accepted = true;
        const double drop = (E - tE) / std::max(E, 1e-300);
        *light = trial;
        col.swap(tcol);
        jac.swap(tjac);
        r.swap(tr);
        E = tE;
        mu = std::max(mu / 3, 1e-9);
        if (log) {
          double sse = 0;
          for (double v : r) sse += v * v;
          log(it + 1, E, sse, *light);
        }
        if (drop < 1e-6) return it + 1;
      } else {
        mu *= 10;
      }
    }
    if (!accepted) break;
  }
  return it;
}

namespace {

/// The energy (Cauchy loss and penalty) of a light's unit column `col` against what the
/// rest leaves (`left`), its RGB scale refitted by reweighted least squares (4 passes from
/// `scale`); `sse` receives the sum of squared residuals.
double FitScale(const PointFitProblem& p, const std::vector<float>& col, const std::vector<double>& left,
                Eigen::Vector3d* scale, double* sse) {
  const double s2 = p.sigma * p.sigma;
  for (int it = 0; it < 4; ++it) {
    Eigen::Vector3d num = Eigen::Vector3d::Zero(), den = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < col.size(); ++i) {
      const double r = left[i] - (*scale)[i % 3] * col[i], w = 1 / (1 + r * r / s2);
      num[i % 3] += w * col[i] * left[i];
      den[i % 3] += w * double(col[i]) * col[i];
    }
    for (int c = 0; c < 3; ++c) (*scale)[c] = den[c] > 0 ? std::max(0.0, num[c] / den[c]) : 0.0;
  }
  std::vector<double> r(col.size());
  *sse = 0;
  for (std::size_t i = 0; i < col.size(); ++i) {
    r[i] = left[i] - (*scale)[i % 3] * col[i];
    *sse += r[i] * r[i];
  }
  return CauchyLoss(r, p.sigma) + p.alpha * std::log1p(p.beta * std::max(0.0, scale->sum()));
}

/// A directional light's energy at its direction and angular radius, its irradiance
/// refitted there (FitScale).
double DirectionalEnergy(const PointFitProblem& p, DirectionalLight* l, double* sse) {
  std::vector<float> col;
  DirectionalLightColumn(*p.scene, *p.vertices, l->direction, &col, nullptr, l->angular_radius);
  std::vector<double> left(col.size());
  for (std::size_t i = 0; i < col.size(); ++i) left[i] = (*p.y)[i] - (*p.base)[i];
  return FitScale(p, col, left, &l->irradiance, sse);
}

}  // namespace

namespace {

/// A point light's energy at its position, the other lights' render (`others`) held and
/// its intensity refitted there (FitScale).
double PointEnergy(const PointFitProblem& p, const std::vector<float>& others, PointLight* l, double* sse) {
  std::vector<float> col;
  PointLightColumn(*p.scene, *p.vertices, l->position, &col, nullptr, l->radius);
  std::vector<double> left(col.size());
  for (std::size_t i = 0; i < col.size(); ++i) left[i] = (*p.y)[i] - (*p.base)[i] - others[i];
  return FitScale(p, col, left, &l->intensity, sse);
}

}  // namespace

int SearchPointLights(const PointFitProblem& p, std::vector<PointLight>* lights, const Eigen::Vector3d& centre,
                      double start, double stop, int max_evaluations,
                      const std::function<void(int, double, double, const std::vector<PointLight>&)>& log) {
  int moves = 0;
  for (std::size_t k = 0; k < lights->size(); ++k) {
    std::vector<float> others(p.y->size(), 0.0f), col;  // the other lights' render, held
    for (std::size_t j = 0; j < lights->size(); ++j) {
      if (j == k) continue;
      PointLightColumn(*p.scene, *p.vertices, (*lights)[j].position, &col, nullptr, (*lights)[j].radius);
      for (std::size_t i = 0; i < col.size(); ++i) others[i] += static_cast<float>((*lights)[j].intensity[i % 3] * col[i]);
    }
    // The light as it is, its intensity refitted on these rows: written back only if it moves.
    PointLight current = (*lights)[k];
    double sse = 0;
    double E = PointEnergy(p, others, &current, &sse);
    const double distance = std::max((current.position - centre).norm(), 1e-6);
    int evaluations = 0;
    for (double step = start * distance; step >= stop * distance * 0.999 && evaluations < max_evaluations;) {
      bool moved = false;
      for (int a = 0; a < 6 && !moved && evaluations < max_evaluations; ++a) {
        PointLight trial = current;
        trial.position[a / 2] += a % 2 ? -step : step;
        double trial_sse = 0;
        const double tE = PointEnergy(p, others, &trial, &trial_sse);
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

int SearchDirectionalLight(const PointFitProblem& p, DirectionalLight* light, double start_deg, double stop_deg,
                           const std::function<void(int, double, double, const DirectionalLight&)>& log) {
  constexpr double kDeg = 3.14159265358979323846 / 180;
  const auto evaluate = [&](DirectionalLight* l, double* sse) { return DirectionalEnergy(p, l, sse); };
  double sse = 0;
  double E = evaluate(light, &sse);
  int moves = 0;
  for (double step = start_deg * kDeg; step >= stop_deg * kDeg * 0.999;) {
    const Eigen::Vector3d& d = light->direction;
    const Eigen::Vector3d t = (std::abs(d.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).cross(d).normalized();
    const Eigen::Vector3d u = d.cross(t);
    bool moved = false;
    for (const Eigen::Vector3d& off : {t, Eigen::Vector3d(-t), u, Eigen::Vector3d(-u)}) {
      DirectionalLight trial = *light;
      trial.direction = (d + std::tan(step) * off).normalized();
      double trial_sse = 0;
      const double tE = evaluate(&trial, &trial_sse);
      if (tE < E) {
        *light = trial;
        E = tE;
        sse = trial_sse;
        moved = true;
        ++moves;
        if (log) log(moves, E, sse, *light);
        break;
      }
    }
    if (!moved) step *= 0.5;
  }
  return moves;
}

double FitAngularRadius(const PointFitProblem& p, DirectionalLight* light) {
  constexpr double kDeg = 3.14159265358979323846 / 180;
  double sse = 0, best_sse = 0;
  DirectionalLight sharp = *light;
  sharp.angular_radius = 0;
  const double sharp_energy = DirectionalEnergy(p, &sharp, &sse);
  DirectionalLight best = sharp;
  double best_energy = sharp_energy;
  for (double deg = kMaxAngularRadiusDeg / 32; deg <= kMaxAngularRadiusDeg; deg *= 2) {
    DirectionalLight trial = *light;
    trial.angular_radius = deg * kDeg;
    const double e = DirectionalEnergy(p, &trial, &sse);
    if (e < best_energy) best_energy = e, best = trial, best_sse = sse;
  }
  (void)best_sse;
  *light = best_energy < (1 - 0.005) * sharp_energy ? best : sharp;
  return light->angular_radius;
}

}  // namespace lp
