#pragma once
/// A camera pose from colour features when ICP cannot start from the last pose (a large
/// motion between frames, or tracking lost): ORB features of the frame matched to those
/// of recent tracked frames, whose depth gives them world positions, and the pose by
/// PnP with RANSAC. OpenCV (features2d, calib3d) stays in relocalizer.cpp.

#include <memory>
#include <optional>

#include <Eigen/Core>

#include "capture/frame.h"

namespace lp {

struct RelocalizerOptions {
  int keep = 8;              ///< tracked frames remembered
  int features = 2000;       ///< ORB features per frame
  int min_inliers = 12;      ///< PnP inliers needed to try a pose (ICP then checks it)
  double reprojection = 4;   ///< pixels, RANSAC inlier threshold
};

class Relocalizer {
 public:
  explicit Relocalizer(const RelocalizerOptions& options = {});
  ~Relocalizer();

  /// Remembers a tracked frame (registered depth needed: a feature's depth is read at its
  /// colour pixel). Its features are computed only when a Locate needs them.
  void Remember(const RgbdFrame& frame, const Eigen::Matrix4d& world_from_camera);
  /// world_from_camera for `frame` from its features, or nothing when too few agree.
  std::optional<Eigen::Matrix4d> Locate(const RgbdFrame& frame);
  bool empty() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lp
