#include "reconstruction/reconstruction_run.h"

#include <cmath>
#include <cstdio>

#include "calibration/calibration.h"
#include "capture/trajectory.h"
#include "common/error.h"

namespace lp {

std::string CsvNumber(double v) {
  if (std::isnan(v)) return "";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

ReconstructionRun::ReconstructionRun(ReconstructionRunOptions options)
    : options_(std::move(options)), reconstructor_(std::make_unique<Reconstructor>(options_.reconstruction)) {
  log_ << "frame,state,seconds,preprocess_s,track_s,fuse_s,raycast_s,overlap,inlier_ratio,rmse_m,relocalized,"
          "blocks_updated,position_error_m,reason\n";
}

FrameReport ReconstructionRun::Process(const RgbdFrame& frame) {
  std::optional<RgbdFrame> posed;  // a copy only when the pose comes from the given ones
  if (!options_.poses.empty()) {
    // The pose of the source's frame, whichever frames came before (a live run drops some).
    if (frame.index < 0 || static_cast<std::size_t>(frame.index) >= options_.poses.size())
      throw InputError(options_.poses_name, "has " + std::to_string(options_.poses.size()) +
                                                " poses, fewer than the frames (none for frame " +
                                                std::to_string(frame.index) + ")");
    posed = frame;
    posed->world_from_camera = options_.poses[static_cast<std::size_t>(frame.index)];
  }
  const RgbdFrame& f = posed ? *posed : frame;
  if (frames_ == 0) clock_.Reset();  // the log's seconds count from the first frame
  if (frames_ == 0 && !f.registered && !options_.reconstruction.calibration.color_from_depth) {
    if (f.device_extrinsics) {
      // Nothing is fused yet: the reconstructor starts again with the device's extrinsics.
      options_.reconstruction.calibration.color_from_depth = f.device_extrinsics->color_from_depth;
      reconstructor_ = std::make_unique<Reconstructor>(options_.reconstruction);
      warnings_.push_back("depth is not registered to colour and no calibration gives the extrinsics: using the "
                          "device's factory transform, " + f.device_extrinsics->source +
                          " (lightprobe calibrate extrinsics measures your camera's)");
    } else {
      warnings_.push_back(
          "depth is not registered to colour and no calibration gives the extrinsics (lightprobe calibrate "
          "extrinsics): colour is taken from the depth camera's view");
    }
  }
  const FrameReport r = reconstructor_->Process(f);
  ++frames_;
  tracked_ += r.state == TrackingState::kTracking;
  doubtful_ += r.doubtful;
  lost_ += r.state == TrackingState::kLost;
  double err = NAN;
  if (f.world_from_camera && r.state != TrackingState::kWaiting) {
    estimated_.push_back(r.world_from_camera);
    truth_.push_back(*f.world_from_camera);
    err = (r.world_from_camera.block<3, 1>(0, 3) - f.world_from_camera->block<3, 1>(0, 3)).norm();
  }
  log_ << r.index << ',' << ToString(r.state) << ',' << CsvNumber(clock_.Seconds()) << ','
       << CsvNumber(r.times.preprocess) << ',' << CsvNumber(r.times.track) << ',' << CsvNumber(r.times.fuse) << ','
       << CsvNumber(r.times.raycast) << ',' << CsvNumber(r.overlap) << ',' << CsvNumber(r.inlier_ratio) << ','
       << CsvNumber(r.rmse) << ',' << r.relocalized << ',' << r.blocks_updated << ',' << CsvNumber(err) << ','
       << r.reason << '\n';
  return r;
}

double ReconstructionRun::TrajectoryRmse() const { return truth_.empty() ? NAN : PositionRmse(estimated_, truth_); }

/// The log, the trajectory and the calibration are part of the bundle, written with it as
/// a whole (an interrupted write leaves the previous bundle, not a mix).
std::vector<std::pair<std::string, std::string>> ReconstructionRun::ExtraFiles() const {
  std::vector<std::pair<std::string, std::string>> files;
  files.emplace_back("reconstruction.csv", log_.str());
  std::vector<Eigen::Matrix4d> trajectory;
  for (const FrameReport& r : reconstructor_->reports())
    if (r.state != TrackingState::kWaiting) trajectory.push_back(r.world_from_camera);
  files.emplace_back("trajectory.log", FormatTrajectoryLog(trajectory));
  // What the keyframes were linearized with: `calibrate vignetting --scene` must know.
  if (options_.calibrated)
    files.emplace_back("calibration.json", FormatCalibration(options_.reconstruction.calibration));
  return files;
}

SceneBundle ReconstructionRun::Finish() const {
  SceneBundle bundle = reconstructor_->Finish();
  if (!truth_.empty()) bundle.truth_json = options_.truth_json;  // the world is the true poses' frame
  bundle.extra_files = ExtraFiles();
  return bundle;
}

ReconstructionRunSnapshot ReconstructionRun::Snapshot() const {
  ReconstructionRunSnapshot s;
  s.snapshot_ = reconstructor_->Snapshot();
  s.extra_files_ = ExtraFiles();
  if (!truth_.empty()) s.truth_json_ = options_.truth_json;
  return s;
}

SceneBundle ReconstructionRunSnapshot::Finish(const std::function<bool()>& cancelled) const {
  SceneBundle bundle = snapshot_.Finish(cancelled);
  bundle.truth_json = truth_json_;
  bundle.extra_files = extra_files_;
  return bundle;
}

}  // namespace lp
