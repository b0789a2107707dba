#pragma once
/// A lamp in the room: the lighting model's near part (beside the environment map, the far
/// part). lights.json's "point_lights" (docs/formats.md).
#include <Eigen/Core>

namespace lp {

struct PointLight {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< the bundle's world frame, metres
  /// Radiant intensity in image units x m^2: a surface facing the light at distance d
  /// receives intensity / d^2 (W/sr when the images are radiance).
  Eigen::Vector3d intensity = Eigen::Vector3d::Zero();
  double radius = 0;  ///< metres; 0: a point. A sphere's radius only softens its shadows
};

}  // namespace lp
