#include "estimation/lights/light.h"

namespace lp {

Eigen::Vector3d Irradiance(const RayTracer& scene, const std::vector<Light>& lights, const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& n, const Eigen::Vector3d& g, std::uint64_t key,
                           std::int64_t* rays) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Light& light : lights) sum += Irradiance(scene, light, origin, n, g, key, rays);
  return sum;
}

Eigen::Vector3d Emission(const std::vector<Light>& lights, const Eigen::Vector3d& point,
                         const Eigen::Vector3d& towards_viewer) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Light& light : lights) sum += Emission(light, point, towards_viewer);
  return sum;
}

}  // namespace lp
