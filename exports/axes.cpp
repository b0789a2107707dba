#include "exports/axes.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "estimation/envmap.h"

namespace lp {
namespace {
constexpr double kPi = 3.14159265358979323846;
}

ExportAxes::ExportAxes(const Eigen::Vector3d& up) {
  blender_from_world = Eigen::Quaterniond::FromTwoVectors(up.normalized(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  gltf_from_world = GltfFromBlender() * blender_from_world;
}

Eigen::Matrix3d ExportAxes::GltfFromBlender() {
  Eigen::Matrix3d m;
  m << 1, 0, 0,  //
      0, 0, 1,   //
      0, -1, 0;
  return m;
}

Eigen::Vector2d BlenderEquirectUt(const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b.normalized();
  double u = 0.5 - std::atan2(d.y(), d.x()) / (2 * kPi);
  u -= std::floor(u);
  return {u, std::acos(std::clamp(d.z(), -1.0, 1.0)) / kPi};
}

Eigen::Vector3d BlenderEquirectDirection(double u, double t) {
  const double phi = kPi - 2 * kPi * u, theta = kPi * t;
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

ImageRGB BlenderWorldImage(const ImageRGB& map, const Eigen::Vector3d& up, int height) {
  const EnvMap frame(2, up);  // its frame only: frame_x(), frame_y(), up()
  const Eigen::Matrix3d world_from_blender = ExportAxes(up).blender_from_world.transpose();
  ImageRGB out(2 * height, height);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      const Eigen::Vector3d w =
          world_from_blender * BlenderEquirectDirection((x + 0.5) / out.width, (y + 0.5) / out.height);
      double theta, phi;
      frame.ToSpherical(w, &theta, &phi);
      const int sx = std::clamp(static_cast<int>(phi / (2 * kPi) * map.width), 0, map.width - 1);
      const int sy = std::clamp(static_cast<int>(theta / kPi * map.height), 0, map.height - 1);
      for (int c = 0; c < 3; ++c) out.at(x, y)[c] = map.at(sx, sy)[c];
    }
  return out;
}

}  // namespace lp
