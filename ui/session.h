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
#include "exports/export_scene.h"
#include "ui/status.h"
#include "reconstruction/live_trigger.h"
#include "reconstruction/reconstruction_run.h"

namespace lp::ui {

/// Writes an estimate's outputs into a directory (the app's estimate writer).
using EstimateWriter = std::function<void(const std::string& dir, const SceneBundle&, const EstimateOptions&,
                                          const EstimateResult&)>;

struct SessionOptions {
  std::string demo_input;  ///< what Open("demo") opens (the bundled recording)
  /// The reconstruction run's options (the calibration from `view --calibration`).
  ReconstructionRunOptions reconstruction;
  EstimateWriter write_estimate;  ///< used by Export
  int lit_samples = 256;          ///< lit shading stops refining here
  /// Live estimation (SetLive) at the start: estimates start by themselves while a camera
  /// or a file is reconstructed. The window turns it on; off for a bare session (tests).
  bool live = false;
  LiveTriggerOptions live_trigger;
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
  /// Live estimation: while frames are reconstructed, whenever the model has changed enough
  /// (reconstruction/live_trigger.h) and the last estimate has its result (or none runs), a
  /// new one starts on a fresh snapshot with `options`, warm-started from the last
  /// (EstimateOptions::warm). The shown estimate stays until the new one's first round.
  void SetLive(bool on, const EstimateOptions& options);
  /// Writes DIR/scene (the bundle: mesh with albedo, keyframes; from a reconstruction also
  /// its log, trajectory and calibration, as `reconstruct` writes them) and DIR/estimate
  /// (envmap.exr, convergence.csv, ...) of the last finished estimate, on a background
  /// thread; each file atomically; then each of `formats` into DIR/<format> (blender, gltf,
  /// sh: what `lightprobe export` writes). The outcome lands in EstimateStatus::export_message.
  void Export(const std::string& dir, const std::vector<ExportFormat>& formats = {});

  LiveStatus live() const;
  EstimateStatus estimate() const;
  /// Seconds on the session's clock (EstimateStatus::started_at and finished_at are on it).
  double seconds() const;
  /// True while a command is queued or being handled by the worker (for scripts).
  bool busy() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lp::ui
