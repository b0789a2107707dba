#include "estimation/lights/directional_light.h"

#include <cmath>

#include "common/parallel.h"
#include "estimation/lights/chunk_visibility.h"
#include "estimation/sampling.h"

namespace lp {

namespace {

/// ConeVisibility's shadow rays from p (appended to `out`): one along l when sharp, else
/// `rays` across the disc. Returns how many.
int ConeShadowRays(const Eigen::Vector3d& p, const Eigen::Vector3d& l, double angular_radius, std::uint64_t key,
                   int rays, std::vector<RayTracer::ShadowRay>* out) {
  constexpr float kFar = 1e30f;  // (Occluded's default reach)
  const Eigen::Vector3f origin = p.cast<float>();
  if (!(angular_radius > 0)) {
    out->push_back({origin, l.cast<float>(), kFar});
    return 1;
  }
  const SphereFrame frame(l);
  const double turn = HashUnit(key), jitter = HashUnit(key ^ 0x5DEECE66Dull), spread = std::tan(angular_radius);
  for (int i = 0; i < rays; ++i) {  // the disc at unit distance, as SphereVisibility's
    const double rho = spread * std::sqrt((i + jitter) / rays);
    const double a = 2 * kPi * (turn + i * 0.6180339887498949);
    const Eigen::Vector3d dir = (l + rho * (std::cos(a) * frame.t + std::sin(a) * frame.b)).normalized();
    out->push_back({origin, dir.cast<float>(), kFar});
  }
  return rays;
}

}  // namespace

double ConeVisibility(const RayTracer& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& l, double angular_radius,
                      std::uint64_t key, int rays) {
  thread_local std::vector<RayTracer::ShadowRay> cone;  // (the renders ask per vertex: no allocation each)
  cone.clear();
  const int n = ConeShadowRays(p, l, angular_radius, key, rays, &cone);
  int seen = 0;
  for (const RayTracer::ShadowRay& r : cone) seen += !scene.Occluded(r.origin.cast<double>(), r.dir.cast<double>());
  return static_cast<double>(seen) / n;
}

void DirectionalLightColumn(const RayTracer& scene, const ShadingVertices& v, const Eigen::Vector3d& towards,
                            const ColumnOut& out, double angular_radius) {
  const Eigen::Vector3d l = towards.normalized();
  out.Assign(v.rows());
  ParallelForChunks(0, v.rows(), 64, [&](std::size_t b, std::size_t e) {
    const ChunkVisibility seen(scene, v.row_start[b], v.row_start[e], [&](std::int64_t k, auto* rays_out) {
      if (!(v.normal[k].cast<double>().dot(l) > 0 && v.geometric[k].cast<double>().dot(l) > 0)) return -1;
      return ConeShadowRays(v.position[k].cast<double>(), l, angular_radius, static_cast<std::uint64_t>(k),
                            kSphereShadowRays, rays_out);
    });
    for (std::size_t r = b; r < e; ++r) {
      ColumnRow row;
      for (std::int64_t k = v.row_start[r]; k < v.row_start[r + 1]; ++k) {
        if (!seen.Faces(k)) continue;
        const double share = seen.Seen(k);
        if (share == 0) continue;
        const Eigen::Vector3d n = v.normal[k].cast<double>();
        const double cn = n.dot(l);
        const Eigen::Vector3d w = v.weight[k].cast<double>() * share;
        row.Add(v.Half(k), w * cn);
        // d cos / d l on the unit sphere
        if (out.jacobian || out.spread_jacobian) row.AddDerivative(v.Half(k), w * (n - cn * l).transpose());
      }
      row.Store(r, out);
    }
  });
}

Eigen::Vector3d Irradiance(const RayTracer& scene, const DirectionalLight& light, const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& n, const Eigen::Vector3d& g, std::uint64_t key,
                           std::int64_t* rays) {
  const double cn = n.dot(light.direction), cg = g.dot(light.direction);
  if (!(cn > 0 && cg > 0)) return Eigen::Vector3d::Zero();
  ++*rays;
  const double seen = ConeVisibility(scene, origin, light.direction, light.angular_radius, key, 1);
  if (!(seen > 0)) return Eigen::Vector3d::Zero();
  return light.irradiance * (cn * seen);
}

DirectionalLight CompassMove(DirectionalLight l, int move, double step) {
  const SphereFrame frame(l.direction);
  const Eigen::Vector3d off = move < 2 ? frame.t : frame.b;
  l.direction = (l.direction + std::tan(step) * (move % 2 ? Eigen::Vector3d(-off) : off)).normalized();
  return l;
}

}  // namespace lp
