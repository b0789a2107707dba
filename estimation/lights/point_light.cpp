#include "estimation/lights/point_light.h"

#include <cmath>

#include "common/parallel.h"
#include "estimation/envmap.h"
#include "estimation/sampling.h"

namespace lp {
namespace {

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

}  // namespace

double SphereVisibility(const RayTracer& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& q, double radius,
                        const Eigen::Vector3d& l, double d, std::uint64_t key, int rays) {
  if (!(radius > 0)) return scene.Occluded(p, l, d) ? 0.0 : 1.0;
  if (d <= radius) return 1.0;  // inside the light
  const SphereFrame frame(l);  // the disc facing p
  const double turn = HashUnit(key), jitter = HashUnit(key ^ 0x5DEECE66Dull);
  int seen = 0;
  for (int i = 0; i < rays; ++i) {
    const double rho = radius * std::sqrt((i + jitter) / rays);  // equal-area rings
    const double a = 2 * kPi * (turn + i * 0.6180339887498949);
    const Eigen::Vector3d s = q + rho * (std::cos(a) * frame.t + std::sin(a) * frame.b) - p;
    const double len = s.norm();
    seen += !scene.Occluded(p, s / len, len);
  }
  return static_cast<double>(seen) / rays;
}

void PointLightColumn(const RayTracer& scene, const ShadingVertices& v, const Eigen::Vector3d& q, const ColumnOut& out,
                      double radius, int rays) {
  out.Assign(v.rows());
  ParallelForChunks(0, v.rows(), 64, [&](std::size_t b, std::size_t e) {
    for (std::size_t r = b; r < e; ++r) {
      ColumnRow row;
      for (std::int64_t k = v.row_start[r]; k < v.row_start[r + 1]; ++k) {
        const Eigen::Vector3d p = v.position[k].cast<double>(), n = v.normal[k].cast<double>();
        Eigen::Vector3d l;
        double d = 0;
        const double f = Falloff(p, n, v.geometric[k].cast<double>(), q, &l, &d);
        if (f == 0) continue;
        const double seen = SphereVisibility(scene, p, q, radius, l, d, static_cast<std::uint64_t>(k), rays);
        if (seen == 0) continue;
        const Eigen::Vector3d w = v.weight[k].cast<double>() * seen;
        row.Add(v.Half(k), w * f);
        if (out.jacobian || out.spread_jacobian) {
          // f = n.(q-p) / d^3:  df/dq = n / d^3 - 3 n.(q-p) (q-p) / d^5 = (n - 3 (n.l) l) / d^3.
          const Eigen::Vector3d grad = (n - 3 * n.dot(l) * l) / (d * d * d);
          row.AddDerivative(v.Half(k), w * grad.transpose());
        }
      }
      row.Store(r, out);
    }
  });
}

Eigen::Vector3d Irradiance(const RayTracer& scene, const PointLight& light, const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& n, const Eigen::Vector3d& g, std::uint64_t key,
                           std::int64_t* rays) {
  Eigen::Vector3d l;
  double d = 0;
  const double f = Falloff(origin, n, g, light.position, &l, &d);
  if (f == 0) return Eigen::Vector3d::Zero();
  ++*rays;
  const double seen = SphereVisibility(scene, origin, light.position, light.radius, l, d, key, 1);
  if (!(seen > 0)) return Eigen::Vector3d::Zero();
  return light.intensity * (f * seen);
}

std::vector<Eigen::Vector3d> CandidatePositions(const Eigen::Vector3d& centre, double radius,
                                                const Eigen::Vector3d& up, int rings,
                                                const std::vector<double>& radii) {
  const EnvMap shell(rings, up);
  std::vector<Eigen::Vector3d> out;
  for (double r : radii)
    for (int j = 0; j < shell.size(); ++j) out.push_back(centre + r * radius * shell.direction(j));
  return out;
}

bool FoldInto(PointLight* into, const PointLight& other, double distance) {
  if (!((into->position - other.position).norm() < 0.1 * distance)) return false;
  const double wk = into->intensity.sum(), wl = other.intensity.sum();
  into->position = (wk * into->position + wl * other.position) / (wk + wl);
  into->intensity += other.intensity;
  return true;
}

}  // namespace lp
