#pragma once
/// When a live estimate should start on a fresh snapshot of a running reconstruction: once
/// it has fused a few frames, then whenever the model has grown by a share of its voxel
/// blocks, or the camera has moved far enough to see something new, since the last
/// snapshot taken. Used by `--headless --live` and the viewer's live switch alike.
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "reconstruction/reconstruction_run.h"

namespace lp {

struct LiveTriggerOptions {
  double growth = 0.1;  ///< the model's voxel blocks grew by this share since the last snapshot
  /// ... or the camera moved this far since it (metres plus 0.5 m per radian turned, as
  /// the keyframes are spread)
  double travel = 0.25;
  std::int64_t first_after = 5;  ///< the first snapshot once this many frames are tracked
};

class LiveTrigger {
 public:
  explicit LiveTrigger(LiveTriggerOptions options = {}) : options_(options) {}
  /// Whether `run`, its camera now at `pose` (world_from_camera), has changed enough.
  bool Due(const ReconstructionRun& run, const Eigen::Matrix4d& pose) const;
  /// A snapshot of `run` was taken with the camera at `pose`.
  void Taken(const ReconstructionRun& run, const Eigen::Matrix4d& pose);
  int taken() const { return taken_; }

 private:
  LiveTriggerOptions options_;
  std::size_t blocks_ = 0;
  Eigen::Matrix4d pose_ = Eigen::Matrix4d::Identity();
  int taken_ = 0;
};

}  // namespace lp
