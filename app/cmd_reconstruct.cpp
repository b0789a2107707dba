// `lightprobe reconstruct`: RGB-D frames (an .oni recording, a TUM / Redwood / joinMap
// directory, or synthetic frames) -> a scene bundle, by KinectFusion on the CPU.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "app/commands.h"
#include "capture/frame_source.h"
#include "capture/trajectory.h"
#include "common/atomic_file.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "reconstruction/reconstructor.h"

namespace lp::app {
namespace fs = std::filesystem;

namespace {

/// One line on a terminal (rewritten), a line per tenth of the input otherwise.
class Progress {
 public:
  explicit Progress(std::int64_t total) : total_(total), tty_(isatty(2)) {}
  void Update(std::int64_t done, double fps, const char* state) {
    if (tty_) {
      if (sw_.Seconds() - last_ < 0.1 && done != total_) return;
      last_ = sw_.Seconds();
      const int width = 30, filled = total_ > 0 ? static_cast<int>(width * done / total_) : 0;
      std::fprintf(stderr, "\r[%s%s] %lld/%lld frames, %.1f frames/s, %s   ", std::string(filled, '=').c_str(),
                   std::string(width - filled, ' ').c_str(), static_cast<long long>(done),
                   static_cast<long long>(total_), fps, state);
    } else if (total_ > 0 && (done * 10 / total_ != (done - 1) * 10 / total_)) {
      std::fprintf(stderr, "%lld/%lld frames, %.1f frames/s, %s\n", static_cast<long long>(done),
                   static_cast<long long>(total_), fps, state);
    }
  }
  void Done() {
    if (tty_) std::fprintf(stderr, "\n");
  }

 private:
  std::int64_t total_;
  bool tty_;
  Stopwatch sw_;
  double last_ = -1;
};

}  // namespace

Run AddReconstruct(CLI::App& app) {
  auto* cmd = app.add_subcommand("reconstruct", "RGB-D frames -> scene bundle (KinectFusion on the CPU)");
  auto input = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto o = std::make_shared<ReconstructionOptions>();
  auto truncation = std::make_shared<float>(0);
  auto max_frames = std::make_shared<int>(0);
  auto poses = std::make_shared<std::string>();
  auto threads = std::make_shared<int>(0);
  cmd->add_option("INPUT", *input, ".oni recording or frame directory (TUM, Redwood, joinMap, lightprobe synth --frames)")
      ->required();
  cmd->add_option("--out", *out, "scene bundle directory to write (replaced only when complete)")->required();
  cmd->add_option("--voxel", o->tsdf.voxel, "voxel size, metres (0.01 for a room, 0.004 for a table top)")
      ->capture_default_str();
  cmd->add_option("--truncation", *truncation, "TSDF truncation, metres (default: 4 voxels)");
  cmd->add_option("--max-frames", *max_frames, "stop after this many frames (0 = all)")->capture_default_str();
  cmd->add_option("--keyframes", o->keyframes, "views in the bundle")->capture_default_str();
  cmd->add_option("--fuse-every", o->fuse_every,
                  "fuse every Nth tracked frame (all are tracked; 2 keeps up with a 30 Hz camera at 320x240 on 2 "
                  "cores, 1 fuses every frame)")
      ->capture_default_str();
  cmd->add_option("--view-width", o->view_width,
                  "average keyframe images down to about this width (the estimator's cost grows with pixels; "
                  "0 = as captured)")
      ->capture_default_str();
  cmd->add_option("--poses", *poses,
                  "true camera poses (trajectory.log or pose.txt, one per frame): the world frame, and the "
                  "trajectory error is reported (frame directories with poses need no flag)");
  cmd->add_option("--smooth", o->smooth_iterations,
                  "Taubin smoothing passes over the mesh (fused depth noise makes voxel-sized bumps that "
                  "shade and shadow themselves; 0 = as meshed)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000));
  cmd->add_option("--albedo", o->albedo.segment,
                  "1: flatten the shading baked into the fused colour per segment of one chromaticity (default); "
                  "0: keep each vertex's mean observed colour")
      ->capture_default_str();
  cmd->add_flag("--use-poses", o->use_source_poses, "fuse with the given poses instead of tracking");
  auto calibration = std::make_shared<std::string>();
  cmd->add_option("--calibration", *calibration,
                  "calibration file (lightprobe calibrate): response, vignetting, exposure, intrinsics; without "
                  "one, sRGB is assumed");
  cmd->add_option("--threads", *threads, "worker threads (0 = all cores)")->capture_default_str();
  return [=] {
    ThreadLimit limit(*threads);
    ReconstructionOptions ro = *o;
    if (!calibration->empty()) ro.calibration = ReadCalibration(*calibration);
    ro.tsdf.truncation = *truncation > 0 ? *truncation : 4 * ro.tsdf.voxel;
    Reconstructor rec(ro);
    auto src = OpenFrameSource(*input);
    std::vector<Eigen::Matrix4d> given;
    if (!poses->empty()) given = ReadTrajectory(*poses);
    std::int64_t total = src->FrameCount().value_or(0);
    if (*max_frames > 0 && (total == 0 || total > *max_frames)) total = *max_frames;
    std::printf("%s\n%s\n", src->Describe().c_str(), ro.calibration.Describe().c_str());
    Progress progress(total);
    Stopwatch sw;
    std::ostringstream csv;
    csv << "frame,state,seconds,preprocess_s,track_s,fuse_s,raycast_s,overlap,inlier_ratio,rmse_m,relocalized,"
           "blocks_updated,position_error_m,reason\n";
    std::vector<Eigen::Matrix4d> estimated, truth;
    RgbdFrame f;
    std::int64_t n = 0, tracked = 0, lost = 0;
    while ((*max_frames == 0 || n < *max_frames) && src->Next(&f, 5.0) == SourceStatus::kFrame) {
      if (!given.empty()) {
        if (static_cast<std::size_t>(n) >= given.size())
          throw InputError(*poses, "has " + std::to_string(given.size()) + " poses, fewer than the frames");
        f.world_from_camera = given[static_cast<std::size_t>(n)];
      }
      if (n == 0 && !f.registered && !ro.calibration.color_from_depth)
        std::fprintf(stderr, "warning: depth is not registered to colour and no calibration gives the extrinsics "
                             "(lightprobe calibrate extrinsics): colour is taken from the depth camera's view\n");
      const FrameReport r = rec.Process(f);
      ++n;
      tracked += r.state == TrackingState::kTracking;
      lost += r.state == TrackingState::kLost;
      double err = NAN;
      if (f.world_from_camera && r.state != TrackingState::kWaiting) {
        estimated.push_back(r.world_from_camera);
        truth.push_back(*f.world_from_camera);
        err = (r.world_from_camera.block<3, 1>(0, 3) - f.world_from_camera->block<3, 1>(0, 3)).norm();
      }
      csv << r.index << ',' << ToString(r.state) << ',' << Num(sw.Seconds()) << ',' << Num(r.times.preprocess)
          << ',' << Num(r.times.track) << ',' << Num(r.times.fuse) << ',' << Num(r.times.raycast) << ','
          << Num(r.overlap) << ',' << Num(r.inlier_ratio) << ',' << Num(r.rmse) << ',' << r.relocalized << ','
          << r.blocks_updated << ',' << Num(err) << ',' << r.reason << '\n';
      progress.Update(n, n / std::max(1e-9, sw.Seconds()), ToString(r.state));
    }
    progress.Done();
    if (n == 0) throw InputError(*input, "has no frames");
    const double seconds = sw.Seconds();
    Stopwatch finish;
    SceneBundle bundle = rec.Finish();
    const double finish_s = finish.Seconds();
    // Ground truth of a synthetic input applies when the world is the source's.
    const fs::path in(*input);
    const fs::path truth_file = (fs::is_directory(in) ? in : in.parent_path()) / "truth.json";
    if (!truth.empty() && fs::exists(truth_file)) bundle.truth_json = ReadTextFile(truth_file);
    // The log, the trajectory and the calibration are part of the bundle, written with it
    // as a whole (an interrupted write leaves the previous bundle, not a mix).
    bundle.extra_files.emplace_back("reconstruction.csv", csv.str());
    std::vector<Eigen::Matrix4d> trajectory;
    for (const FrameReport& r : rec.reports())
      if (r.state != TrackingState::kWaiting) trajectory.push_back(r.world_from_camera);
    bundle.extra_files.emplace_back("trajectory.log", FormatTrajectoryLog(trajectory));
    // What the keyframes were linearized with: `calibrate vignetting --scene` must know.
    if (!calibration->empty()) bundle.extra_files.emplace_back("calibration.json", FormatCalibration(ro.calibration));
    WriteSceneBundle(*out, bundle);

    const StageTimes& t = rec.times();
    std::printf("%lld frames in %.1f s (%.1f frames/s): %lld tracked, %lld lost; per frame %.1f ms preprocess, "
                "%.1f ms track, %.1f ms fuse, %.1f ms raycast\n",
                static_cast<long long>(n), seconds, n / seconds, static_cast<long long>(tracked),
                static_cast<long long>(lost), 1e3 * t.preprocess / n, 1e3 * t.track / n, 1e3 * t.fuse / n,
                1e3 * t.raycast / n);
    std::printf("volume: %zu blocks, %.1f MiB; mesh %zu vertices, %zu triangles, up (%.3f, %.3f, %.3f); "
                "%zu keyframes; finishing took %.1f s\n",
                rec.volume().BlockCount(), rec.volume().MemoryBytes() / 1048576.0, bundle.mesh.positions.size(),
                bundle.mesh.triangles.size(), bundle.up.x(), bundle.up.y(), bundle.up.z(), bundle.views.size(),
                finish_s);
    if (!truth.empty())
      std::printf("trajectory error against the given poses: %.1f mm RMS over %zu frames\n",
                  1e3 * PositionRmse(estimated, truth), truth.size());
    std::printf("wrote %s\n", fs::absolute(*out).lexically_normal().c_str());
  };
}

}  // namespace lp::app
