#include "reconstruction/live_trigger.h"

#include "reconstruction/icp.h"

namespace lp {

bool LiveTrigger::Due(const ReconstructionRun& run, const Eigen::Matrix4d& pose) const {
  if (run.tracked() < options_.first_after) return false;
  if (taken_ == 0) return true;
  const std::size_t blocks = run.reconstructor().volume().BlockCount();
  return blocks >= (1 + options_.growth) * static_cast<double>(blocks_) || PoseDistance(pose, pose_) >= options_.travel;
}

void LiveTrigger::Taken(const ReconstructionRun& run, const Eigen::Matrix4d& pose) {
  blocks_ = run.reconstructor().volume().BlockCount();
  pose_ = pose;
  ++taken_;
}

}  // namespace lp
