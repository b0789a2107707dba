#pragma once
/// A sun, or a lamp too far for its position to matter: light from one direction, the
/// lighting model's third kind beside the map and the point lights. lights.json's
/// "directional_lights" (docs/formats.md).
#include <Eigen/Core>

namespace lp {

struct DirectionalLight {
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  ///< unit, towards the light, world frame
  /// Irradiance in image units on a surface facing the light (W/m^2 when the images are
  /// radiance): a Lambertian surface of albedo rho at angle theta to it has radiance
  /// rho / pi x irradiance x cos theta.
  Eigen::Vector3d irradiance = Eigen::Vector3d::Zero();
  double angular_radius = 0;  ///< the half-angle of its disc, radians; 0: sharp shadows
};

}  // namespace lp
