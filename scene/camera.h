#pragma once
/// The one pinhole camera type: a stream's intrinsics (capture), the calibrated colour
/// camera (calibration, with distortion beside it) and a keyframe's camera in a scene
/// bundle (with its pose) are all this. Header-only, so that capture/ and calibration/
/// use it without linking the scene library.
#include <cmath>

#include <Eigen/Core>

namespace lp {

/// Pinhole camera, OpenCV convention (x right, y down, z forward); pixel centres at
/// integer coordinates: u = fx*X/Z + cx, v = fy*Y/Z + cy (X, Y, Z in the camera frame,
/// metres; u, v in pixels). `world_from_camera` places it in a world frame (a scene
/// bundle's keyframes); a stream's intrinsics leave it at the identity.
struct Camera {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  Eigen::Matrix4d world_from_camera = Eigen::Matrix4d::Identity();

  Eigen::Vector3d center() const { return world_from_camera.block<3, 1>(0, 3); }
  /// Unit world direction of the ray through image point (u, v) (pixel units).
  Eigen::Vector3d RayDirection(double u, double v) const {
    const Eigen::Vector3d d_cam((u - cx) / fx, (v - cy) / fy, 1.0);
    return (world_from_camera.block<3, 3>(0, 0) * d_cam).normalized();
  }
  /// Camera at `eye` looking at `target` with image up along world `up` (another axis
  /// is used if the view is parallel to it); centred principal point, square pixels.
  static Camera LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up, int w,
                       int h, double hfov_deg);
  /// Projects a world point; returns false if behind the camera.
  bool Project(const Eigen::Vector3d& world, double* u, double* v) const {
    const Eigen::Matrix3d R = world_from_camera.block<3, 3>(0, 0);
    const Eigen::Vector3d p = R.transpose() * (world - center());
    if (p.z() <= 1e-9) return false;
    *u = fx * p.x() / p.z() + cx;
    *v = fy * p.y() / p.z() + cy;
    return true;
  }
  /// This camera's intrinsics at the identity pose (what a stream reports).
  Camera Intrinsics() const {
    Camera c = *this;
    c.world_from_camera.setIdentity();
    return c;
  }
};

inline Camera Camera::LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up_in,
                             int w, int h, double hfov_deg) {
  Camera c;
  c.width = w;
  c.height = h;
  c.fx = c.fy = 0.5 * w / std::tan(0.5 * hfov_deg * 3.14159265358979323846 / 180);
  c.cx = 0.5 * (w - 1);
  c.cy = 0.5 * (h - 1);
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d up = up_in.normalized();
  if (std::abs(z.dot(up)) > 0.99) up = std::abs(z.y()) < 0.9 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d x = z.cross(up).normalized();  // right
  const Eigen::Vector3d y = z.cross(x);                // down
  c.world_from_camera.setIdentity();
  c.world_from_camera.block<3, 1>(0, 0) = x;
  c.world_from_camera.block<3, 1>(0, 1) = y;
  c.world_from_camera.block<3, 1>(0, 2) = z;
  c.world_from_camera.block<3, 1>(0, 3) = eye;
  return c;
}

}  // namespace lp
