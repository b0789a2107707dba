#pragma once
/// Camera tracking: projective point-to-plane ICP of a depth pyramid against maps raycast
/// from the model (frame-to-model, coarse to fine), as KinectFusion does.

#include <array>
#include <vector>

#include <Eigen/Core>

#include "reconstruction/depth_maps.h"

namespace lp {

struct IcpOptions {
  std::array<int, 3> iterations{6, 5, 4};  ///< per level, finest first (level 0 = full size)
  float max_distance = 0.10f;               ///< metres between associated points (coarse levels)
  float fine_max_distance = 0.04f;          ///< the same at the finest level tracked
  float max_angle_deg = 60;                 ///< between associated normals (noisy at range)
  /// Tracking fails when fewer of the frame's valid points than this land on the model
  /// (overlap), or fewer of those than min_inlier_ratio match it (distance and angle).
  float min_overlap = 0.15f;
  float min_inlier_ratio = 0.5f;
  float max_rmse = 0.05f;              ///< metres, point-to-plane, at the finest level
  float max_step_translation = 0.20f;  ///< metres per frame; a larger jump is a failure
  float max_step_rotation_deg = 20;    ///< degrees per frame
};

/// The model as the last good camera saw it: world-frame vertex and normal maps (NaN =
/// nothing) per pyramid level, and that camera.
struct ModelMaps {
  std::vector<Camera> k;
  std::vector<std::vector<Eigen::Vector3f>> vertex, normal;
  Eigen::Matrix4d world_from_camera = Eigen::Matrix4d::Identity();
};

/// The rotation angle of a rigid transform's rotation part, radians.
double RotationAngle(const Eigen::Matrix4d& transform);
/// The distance between two camera poses as the keyframes are spread (and a live estimate
/// is triggered): metres plus 0.5 m per radian of the rotation between them.
double PoseDistance(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b);

/// Model maps for `levels` pyramid levels from a raycast (world frame) made at pyramid
/// level `first_level` of the frame (0 = full size, 1 = half): levels up to first_level
/// share the raycast, coarser ones take every second pixel of the one before.
ModelMaps MakeModelMaps(const Camera& k, const std::vector<Eigen::Vector3f>& vertex,
                        const std::vector<Eigen::Vector3f>& normal, const Eigen::Matrix4d& world_from_camera,
                        int levels, int first_level = 0);

struct TrackResult {
  bool ok = false;
  Eigen::Matrix4d world_from_camera = Eigen::Matrix4d::Identity();
  double overlap = 0;       ///< frame points landing on the model, at the finest level
  double inlier_ratio = 0;  ///< of those, the ones matching it
  double rmse = 0;          ///< metres, point-to-plane, at the finest level
  int iterations = 0;
  const char* reason = "";  ///< why it failed (for logs and the UI)
};

/// Aligns `frame` (camera-frame maps) to `model`, starting from `initial`
/// (world_from_camera). Fails (ok = false, with a reason) on too few inliers, a large
/// residual, a jump larger than the per-frame limits, or a degenerate system.
TrackResult TrackFrameToModel(const std::vector<DepthLevel>& frame, const ModelMaps& model,
                              const Eigen::Matrix4d& initial, const IcpOptions& options);

}  // namespace lp
