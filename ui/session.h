#pragma once
/// The viewer's model of the pipeline, without any window: a source (camera, .oni file,
/// frame directory, scene bundle, the bundled demo), a reconstruction worker that reads
/// and fuses frames, and an estimation worker started by Estimate on a snapshot of the
/// scene. The window (viewer.h) only posts commands here and draws the published
/// snapshots; every method is safe to call from the main thread and never blocks on the
/// workers' computation.
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "capture/frame.h"
#include "estimation/estimator.h"
#include "reconstruction/reconstructor.h"

namespace lp::ui {

/// What the live panel shows (copied out under a lock; the images are shared, immutable).
struct LiveStatus {
  std::string source;  ///< the source's one-line description ("" = nothing open)
  std::string error;   ///< the last error (opening, a frame, reconstruction); "" = none
  bool open = false, is_camera = false, is_bundle = false;
  bool playing = false, at_end = false;
  std::int64_t position = 0;      ///< the next frame's index in the source
  std::int64_t frame_count = -1;  ///< -1 = unknown (a camera)
  double speed = 1;               ///< playback speed for files (0 = as fast as processed)
  double source_fps = 0;          ///< frames delivered per second (over the last second)
  double processed_fps = 0;       ///< frames reconstructed per second
  std::int64_t frames_read = 0, dropped = 0;  ///< dropped: by the camera queue (live only)
  bool reconstructing = false;
  TrackingState tracking = TrackingState::kWaiting;
  std::string tracking_reason;
  std::int64_t frames_tracked = 0, frames_lost = 0;
  std::shared_ptr<const RgbdFrame> frame;  ///< the latest frame (previews)
  std::uint64_t frame_version = 0;
  std::shared_ptr<const Mesh> model;  ///< the growing model (or the loaded bundle's mesh)
  std::uint64_t model_version = 0;
  bool has_pose = false;
  /// Recording the camera to an .oni file (Session::Record).
  bool recording = false;
  int recorded_frames = 0;        ///< depth frames so far
  double recorded_seconds = 0;
  std::string record_message;     ///< the last recording's outcome
  Eigen::Matrix4d camera_pose = Eigen::Matrix4d::Identity();  ///< world_from_camera of the latest frame
};

enum class EstimateState { kIdle, kPreparing, kRunning, kDone, kCancelled, kFailed };
const char* ToString(EstimateState s);

/// What the estimate panel, the lit mesh and the environment-map view show.
struct EstimateStatus {
  EstimateState state = EstimateState::kIdle;
  std::string message;  ///< the last progress line or the error
  double progress = 0;  ///< 0..1: rounds done of the most allowed
  EstimateOptions options;
  std::vector<ConvergenceRow> rows;  ///< the convergence log so far
  std::shared_ptr<const SceneBundle> scene;     ///< the snapshot being estimated
  std::shared_ptr<const EnvMap> env;            ///< set with the first round
  std::vector<double> lambda;                   ///< the latest estimate (3 per cell)
  std::vector<Eigen::Vector3d> dominant;        ///< its dominant light directions
  std::uint64_t version = 0;                    ///< bumps with every new lambda
  std::shared_ptr<const EstimateResult> result; ///< when done (relit renders of the keyframes)
  /// Seconds from pressing Estimate to the first finished round (the first usable
  /// estimate) and to the end; NaN until then.
  double seconds_to_first = std::nan(""), seconds_total = std::nan("");
  /// Lit shading of the snapshot's mesh under the estimate (per vertex, image units),
  /// refined progressively after the estimate; photometric error per vertex against the
  /// nearest keyframe that sees it (|lit - observed| / mean observed; NaN = unseen).
  std::shared_ptr<const std::vector<Eigen::Vector3f>> lit;
  std::shared_ptr<const std::vector<float>> error;
  int lit_samples = 0;
  std::uint64_t lit_version = 0;
  std::string export_message;  ///< the last export's result
};

/// Writes an estimate's outputs into a directory (the app's estimate writer).
using EstimateWriter = std::function<void(const std::string& dir, const SceneBundle&, const EstimateOptions&,
                                          const EstimateResult&)>;

struct SessionOptions {
  std::string demo_input;  ///< what Open("demo") opens (the bundled recording)
  ReconstructionOptions reconstruction;
  EstimateWriter write_estimate;  ///< used by Export
  int lit_samples = 256;          ///< lit shading stops refining here
};

class Session {
 public:
  explicit Session(SessionOptions options);
  /// Cancels the estimate, stops playback and reconstruction, waits for the workers.
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  /// Opens a source on the worker: "demo", "camera" or "camera:URI" (OpenNI2), a scene
  /// bundle directory (scene.json: loaded as the scene, nothing to reconstruct), an .oni
  /// file or a frame directory. Failures land in LiveStatus::error. Playback starts
  /// paused at the first frame; the reconstruction is reset.
  void Open(const std::string& input);
  void SetPlaying(bool playing);
  void Seek(std::int64_t frame);
  void SetSpeed(double speed);
  void StartReconstruction();
  void StopReconstruction();
  void ResetReconstruction();
  /// Used from the next reset (or Open) on.
  void SetReconstructionOptions(const ReconstructionOptions& options);
  /// Records the open camera into the .oni file `path` (OpenNI2's Recorder attached to the
  /// camera's streams: depth lossless, colour uncompressed, exposure as locked when the
  /// camera opened; the file and its side file are written under a temporary name and
  /// moved into place when finished) for `seconds` (<= 0: until StopRecording). The
  /// previews and the reconstruction go on while it records; opening another source or
  /// closing the session finishes the file. Needs a camera source.
  void Record(const std::string& path, double seconds);
  /// Ends a recording early; the frames so far are kept (not queued behind other commands).
  void StopRecording();
  /// Snapshots the scene (the reconstruction's bundle, or the loaded one) and estimates
  /// its lighting on a background thread; an estimate still running is cancelled first.
  void Estimate(const EstimateOptions& options);
  void CancelEstimate();
  /// Writes DIR/scene (the bundle: mesh with albedo, keyframes) and DIR/estimate
  /// (envmap.exr, convergence.csv, ...) of the last finished estimate, on a background
  /// thread; each file atomically. The outcome lands in EstimateStatus::export_message.
  void Export(const std::string& dir);

  LiveStatus live() const;
  EstimateStatus estimate() const;
  /// True while a command is queued or being handled by the worker (for scripts).
  bool busy() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lp::ui
