#pragma once
/// One reconstruction run, frames in and a scene bundle out, assembled once for
/// `lightprobe reconstruct`, the headless pipeline and the viewer: the Reconstructor, the
/// true poses given beside the frames (they fix the world frame and measure the
/// trajectory), the per-frame log, and a bundle that carries the log
/// (reconstruction.csv), the estimated trajectory (trajectory.log) and the calibration its
/// keyframes were linearized with (calibration.json) as part of itself.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "capture/frame.h"
#include "common/timer.h"
#include "reconstruction/reconstructor.h"
#include "scene/scene_bundle.h"

namespace lp {

struct ReconstructionRunOptions {
  ReconstructionOptions reconstruction;
  /// The calibration in `reconstruction` came from a file: the bundle keeps it.
  bool calibrated = false;
  /// True camera poses, one per frame in order (a trajectory file); empty = none. Frames
  /// that carry a pose of their own (synthetic) keep it when none is given.
  std::vector<Eigen::Matrix4d> poses;
  std::string poses_name;  ///< where they came from (errors)
  /// truth.json for the bundle (ground truth of a synthetic scene), kept when the world
  /// frame is the true poses' (some frame had one).
  std::optional<std::string> truth_json;
};

/// The extra files of a run's bundle at one moment, and its snapshot to finish elsewhere.
class ReconstructionRunSnapshot {
 public:
  /// The bundle as the run's Finish would have returned it when the snapshot was taken
  /// (`cancelled`: as ReconstructionSnapshot::Finish).
  SceneBundle Finish(const std::function<bool()>& cancelled = {}) const;

 private:
  friend class ReconstructionRun;
  ReconstructionSnapshot snapshot_;
  std::vector<std::pair<std::string, std::string>> extra_files_;
  std::optional<std::string> truth_json_;
};

class ReconstructionRun {
 public:
  /// Throws InputError for options out of range (as Reconstructor).
  explicit ReconstructionRun(ReconstructionRunOptions options);

  /// Gives the frame its true pose (the given one of its index in the source: frames may
  /// be skipped), tracks and fuses it, and logs it. Throws InputError when no pose is given
  /// for its index, or as Reconstructor::Process.
  FrameReport Process(const RgbdFrame& frame);

  /// The bundle (Reconstructor::Finish) with the log, the trajectory and the calibration
  /// inside, and truth.json when it applies. Throws InputError when nothing was fused.
  SceneBundle Finish() const;
  /// What Finish needs, copied (milliseconds), to finish on another thread.
  ReconstructionRunSnapshot Snapshot() const;

  /// One line each, said once: e.g. colour taken from the depth camera's view.
  const std::vector<std::string>& warnings() const { return warnings_; }
  std::int64_t frames() const { return frames_; }
  std::int64_t tracked() const { return tracked_; }
  std::int64_t lost() const { return lost_; }
  /// Tracked frames left unfused because their fit was doubtful (FrameReport::doubtful).
  std::int64_t doubtful() const { return doubtful_; }
  /// Seconds since its first frame.
  double seconds() const { return clock_.Seconds(); }
  /// RMS distance of the tracked positions from the true ones (metres) over `compared()`
  /// frames; NaN when no frame had a true pose.
  double TrajectoryRmse() const;
  std::size_t compared() const { return truth_.size(); }
  const Reconstructor& reconstructor() const { return *reconstructor_; }
  const ReconstructionOptions& options() const { return options_.reconstruction; }

 private:
  std::vector<std::pair<std::string, std::string>> ExtraFiles() const;

  ReconstructionRunOptions options_;
  std::unique_ptr<Reconstructor> reconstructor_;
  Stopwatch clock_;
  std::ostringstream log_;
  std::vector<std::string> warnings_;
  std::vector<Eigen::Matrix4d> estimated_, truth_;
  std::int64_t frames_ = 0, tracked_ = 0, lost_ = 0, doubtful_ = 0;
};

/// A number for CSV files: %.9g, empty for NaN.
std::string CsvNumber(double v);

}  // namespace lp
