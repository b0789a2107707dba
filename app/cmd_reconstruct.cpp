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
#include "reconstruction/reconstruction_run.h"

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

void AddReconstructOptions(CLI::App& cmd, ReconstructSettings* s) {
  ReconstructionOptions* o = &s->options;
  cmd.add_option("--voxel", o->tsdf.voxel, "voxel size, metres (0.01 for a room, 0.004 for a table top)")
      ->capture_default_str()
      ->check(CLI::Range(0.001f, 0.1f));
  cmd.add_option("--truncation", s->truncation, "TSDF truncation, metres (default: 4 voxels)");
  cmd.add_option("--max-frames", s->max_frames, "stop after this many frames (0 = all)")->capture_default_str();
  cmd.add_option("--keyframes", o->keyframes, "views in the bundle")->capture_default_str()->check(CLI::Range(1, 64));
  cmd.add_option("--fuse-every", o->fuse_every,
                 "fuse every Nth tracked frame (all are tracked; 2 keeps up with a 30 Hz camera at 320x240 on 2 "
                 "cores, 1 fuses every frame)")
      ->capture_default_str();
  cmd.add_option("--view-width", o->view_width,
                 "average keyframe images down to about this width (the estimator's cost grows with pixels; "
                 "0 = as captured)")
      ->capture_default_str();
  cmd.add_option("--poses", s->poses,
                 "true camera poses (trajectory.log or pose.txt, one per frame): the world frame, and the "
                 "trajectory error is reported (frame directories with poses need no flag)");
  cmd.add_option("--smooth", o->smooth_iterations,
                 "Taubin smoothing passes over the mesh (fused depth noise makes voxel-sized bumps that "
                 "shade and shadow themselves; 0 = as meshed)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000));
  cmd.add_option("--albedo", o->albedo.segment,
                 "1: flatten the shading baked into the fused colour per segment of one chromaticity (default); "
                 "0: keep each vertex's mean observed colour")
      ->capture_default_str();
  cmd.add_flag("--use-poses", o->use_source_poses, "fuse with the given poses instead of tracking");
  cmd.add_option("--calibration", s->calibration,
                 "calibration file (lightprobe calibrate): response, vignetting, exposure, intrinsics; without "
                 "one, sRGB is assumed");
  cmd.add_option("--intrinsics", s->intrinsics, kIntrinsicsHelp);
  cmd.add_option("--threads", s->threads, "worker threads (0 = all cores)")->capture_default_str();
}

ReconstructionRunOptions MakeRunOptions(const ReconstructSettings& s, const std::string& input) {
  ReconstructionRunOptions run;
  run.reconstruction = s.options;
  if (!s.calibration.empty()) {
    run.reconstruction.calibration = ReadCalibration(s.calibration);
    run.calibrated = true;
  }
  if (!s.intrinsics.empty()) UseIntrinsicsFile(&run.reconstruction.calibration, s.intrinsics);
  run.reconstruction.tsdf.truncation = s.truncation > 0 ? s.truncation : 4 * run.reconstruction.tsdf.voxel;
  if (!s.poses.empty()) {
    run.poses = ReadTrajectory(s.poses);
    run.poses_name = s.poses;
  }
  // Ground truth of a synthetic input (truth.json beside it) applies when the world is the
  // source's (the run keeps it only then).
  const fs::path in(input);
  const fs::path truth_file = (fs::is_directory(in) ? in : in.parent_path()) / "truth.json";
  if (fs::exists(truth_file)) run.truth_json = ReadTextFile(truth_file);
  return run;
}

namespace {

void PrintSummary(const ReconstructionRun& run, const SceneBundle& bundle, double seconds, double finish_s,
                  const std::string& out) {
  const std::int64_t n = run.frames();
  const StageTimes& t = run.reconstructor().times();
  std::printf("%lld frames in %.1f s (%.1f frames/s): %lld tracked (%lld of them doubtful: not fused), %lld lost; "
              "per frame %.1f ms preprocess, %.1f ms track, %.1f ms fuse, %.1f ms raycast\n",
              static_cast<long long>(n), seconds, n / seconds, static_cast<long long>(run.tracked()),
              static_cast<long long>(run.doubtful()), static_cast<long long>(run.lost()), 1e3 * t.preprocess / n, 1e3 * t.track / n, 1e3 * t.fuse / n,
              1e3 * t.raycast / n);
  const TsdfVolume& volume = run.reconstructor().volume();
  std::printf("volume: %zu blocks, %.1f MiB; mesh %zu vertices, %zu triangles, up (%.3f, %.3f, %.3f); "
              "%zu keyframes; finishing took %.1f s\n",
              volume.BlockCount(), volume.MemoryBytes() / 1048576.0, bundle.mesh.positions.size(),
              bundle.mesh.triangles.size(), bundle.up.x(), bundle.up.y(), bundle.up.z(), bundle.views.size(),
              finish_s);
  if (run.compared() > 0)
    std::printf("trajectory error against the given poses: %.1f mm RMS over %zu frames\n", 1e3 * run.TrajectoryRmse(),
                run.compared());
  std::printf("wrote %s\n", fs::absolute(out).lexically_normal().c_str());
}

}  // namespace

void Reconstruct(const std::string& input, const std::string& out, const ReconstructSettings& s) {
  ThreadLimit limit(s.threads);
  ReconstructionRun run(MakeRunOptions(s, input));
  auto src = OpenFrameSource(input);
  std::int64_t total = src->FrameCount().value_or(0);
  if (s.max_frames > 0 && (total == 0 || total > s.max_frames)) total = s.max_frames;
  std::printf("%s\n%s\n", src->Describe().c_str(), run.options().calibration.Describe().c_str());
  Progress progress(total);
  Stopwatch sw;
  RgbdFrame f;
  std::size_t warned = 0;
  while ((s.max_frames == 0 || run.frames() < s.max_frames) && src->Next(&f, 5.0) == SourceStatus::kFrame) {
    const FrameReport r = run.Process(f);
    for (; warned < run.warnings().size(); ++warned) std::fprintf(stderr, "warning: %s\n", run.warnings()[warned].c_str());
    progress.Update(run.frames(), run.frames() / std::max(1e-9, sw.Seconds()), ToString(r.state));
  }
  progress.Done();
  if (run.frames() == 0) throw InputError(input, "has no frames");
  const double seconds = sw.Seconds();
  Stopwatch finish;
  const SceneBundle bundle = run.Finish();
  const double finish_s = finish.Seconds();
  WriteSceneBundle(out, bundle);
  PrintSummary(run, bundle, seconds, finish_s, out);
}

Run AddReconstruct(CLI::App& app) {
  auto* cmd = app.add_subcommand("reconstruct", "RGB-D frames -> scene bundle (KinectFusion on the CPU)");
  auto input = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto settings = std::make_shared<ReconstructSettings>();
  cmd->add_option("INPUT", *input, ".oni recording or frame directory (TUM, Redwood, joinMap, lightprobe synth --frames)")
      ->required();
  cmd->add_option("--out", *out, "scene bundle directory to write (replaced only when complete)")->required();
  AddReconstructOptions(*cmd, settings.get());
  return [=] { Reconstruct(*input, *out, *settings); };
}

}  // namespace lp::app
