#include "estimation/lights/point_light.h"

#include <cmath>

#include "common/parallel.h"
#include "estimation/lights/chunk_visibility.h"
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

/// SphereVisibility's shadow rays from p (appended to `out`): one to q for a point, none
/// inside the light (it sees all of it), else `rays` to the disc. Returns how many.
int DiscShadowRays(const Eigen::Vector3d& p, const Eigen::Vector3d& q, double radius, const Eigen::Vector3d& l,
                   double d, std::uint64_t key, int rays, std::vector<RayTracer::ShadowRay>* out) {
  const Eigen::Vector3f origin = p.cast<float>();
  if (!(radius > 0)) {
    out->push_back({origin, l.cast<float>(), static_cast<float>(std::min(d, 1e30))});
    return 1;
  }
  if (d <= radius) return 0;
  const SphereFrame frame(l);  // the disc facing p
  const double turn = HashUnit(key), jitter = HashUnit(key ^ 0x5DEECE66Dull);
  // The i-th ray's angle is 2 pi (turn + i golden): one sine and cosine, then each next by a
  // fixed rotation.
  constexpr double kGoldenTurn = 2 * kPi * 0.6180339887498949;
  static const double cos_step = std::cos(kGoldenTurn), sin_step = std::sin(kGoldenTurn);
  double c = std::cos(2 * kPi * turn), s = std::sin(2 * kPi * turn);
  for (int i = 0; i < rays; ++i) {
    const double rho = radius * std::sqrt((i + jitter) / rays);  // equal-area rings
    const Eigen::Vector3d to = q + rho * (c * frame.t + s * frame.b) - p;
    const double len = to.norm();
    out->push_back({origin, (to / len).cast<float>(), static_cast<float>(std::min(len, 1e30))});
    const double next_c = c * cos_step - s * sin_step;
    s = s * cos_step + c * sin_step;
    c = next_c;
  }
  return rays;
}

}  // namespace

double SphereVisibility(const RayTracer& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& q, double radius,
                        const Eigen::Vector3d& l, double d, std::uint64_t key, int rays) {
  thread_local std::vector<RayTracer::ShadowRay> disc;  // (the renders ask per vertex: no allocation each)
  disc.clear();
  const int n = DiscShadowRays(p, q, radius, l, d, key, rays, &disc);
  if (n == 0) return 1.0;
  int seen = 0;
  for (const RayTracer::ShadowRay& r : disc)
    seen += !scene.Occluded(r.origin.cast<double>(), r.dir.cast<double>(), r.tmax);
  return static_cast<double>(seen) / n;
}

void PointLightColumn(const RayTracer& scene, const ShadingVertices& v, const Eigen::Vector3d& q, const ColumnOut& out,
                      double radius, int rays) {
  out.Assign(v.rows());
  ParallelForChunks(0, v.rows(), 64, [&](std::size_t b, std::size_t e) {
    const ChunkVisibility seen(scene, v.row_start[b], v.row_start[e], [&](std::int64_t k, auto* rays_out) {
      Eigen::Vector3d l = Eigen::Vector3d::Zero();
      double d = 0;
      const Eigen::Vector3d p = v.position[k].cast<double>();
      if (Falloff(p, v.normal[k].cast<double>(), v.geometric[k].cast<double>(), q, &l, &d) == 0) return -1;
      return DiscShadowRays(p, q, radius, l, d, static_cast<std::uint64_t>(k), rays, rays_out);
    });
    for (std::size_t r = b; r < e; ++r) {
      ColumnRow row;
      for (std::int64_t k = v.row_start[r]; k < v.row_start[r + 1]; ++k) {
        if (!seen.Faces(k)) continue;
        const double share = seen.Seen(k);
        if (share == 0) continue;
        const Eigen::Vector3d p = v.position[k].cast<double>(), n = v.normal[k].cast<double>();
        Eigen::Vector3d l = Eigen::Vector3d::Zero();
        double d = 0;
        const double f = Falloff(p, n, v.geometric[k].cast<double>(), q, &l, &d);
        const Eigen::Vector3d w = v.weight[k].cast<double>() * share;
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
  if (other.held) into->position = other.position;
  else if (!into->held) into->position = (wk * into->position + wl * other.position) / (wk + wl);
  into->held = into->held || other.held;
  into->intensity += other.intensity;
  return true;
}

}  // namespace lp
