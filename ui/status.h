#pragma once
/// What the viewer's session publishes for the window to draw: the live source and
/// reconstruction, the estimate, the recording and the export. Copied out under a lock;
/// the images, meshes and results they point to are shared and immutable.
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "capture/frame.h"
#include "estimation/estimator.h"
#include "reconstruction/reconstructor.h"

namespace lp::ui {

/// Where recording the camera stands (Session::Record).
enum class RecordState { kIdle, kRecording, kRecorded, kFailed };

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
  RecordState record_state = RecordState::kIdle;
  bool recording = false;         ///< record_state == kRecording
  int recorded_frames = 0;        ///< depth frames so far
  double recorded_seconds = 0;
  std::string record_message;     ///< the last recording's outcome, one line
  Eigen::Matrix4d camera_pose = Eigen::Matrix4d::Identity();  ///< world_from_camera of the latest frame
  bool live_estimation = false;  ///< Session::SetLive: estimates start by themselves
  int live_estimates = 0;        ///< how many it started since the source opened
};

enum class EstimateState { kIdle, kPreparing, kRunning, kDone, kCancelled, kFailed };
const char* ToString(EstimateState s);

/// Where the last Export stands.
enum class ExportState { kIdle, kExporting, kExported, kFailed };
const char* ToString(ExportState s);

/// What the estimate panel, the lit mesh and the environment-map view show.
struct EstimateStatus {
  EstimateState state = EstimateState::kIdle;
  std::string message;  ///< the last progress line or the error
  double progress = 0;  ///< 0..1: rounds done of the most allowed
  EstimateOptions options;
  std::vector<ConvergenceRow> rows;  ///< the convergence log so far
  std::shared_ptr<const SceneBundle> scene;     ///< the snapshot being estimated
  std::shared_ptr<const EnvMap> env;            ///< set with the first round
  Lighting lighting;                            ///< the latest estimate (its map 3 per cell; image units)
  std::vector<Eigen::Vector3d> dominant;        ///< its dominant light directions
  std::uint64_t version = 0;                    ///< bumps with every new lambda
  std::shared_ptr<const EstimateResult> result; ///< when done (relit renders of the keyframes)
  /// Seconds from pressing Estimate to the first finished round (the first usable
  /// estimate) and to the end; NaN until then.
  double seconds_to_first = std::nan(""), seconds_total = std::nan("");
  /// Seconds from pressing Estimate to round 1's first solve shown (on a cold start the map
  /// alone, before round 1 seeks lamps: EstimateOptions::on_first_solve); NaN until then.
  double seconds_to_map = std::nan("");
  /// On the session's clock: when the job started and when its result came (NaN until
  /// then): the panel says how old the shown estimate is. `live`: started by live estimation.
  double started_at = std::nan(""), finished_at = std::nan("");
  bool live = false;
  int live_index = 0;  ///< which live estimate since the source opened (1 = the first)
  bool preview = false;  ///< a live preview while the scan plays (LivePreview), not a full estimate
  /// Whether the job has its own result (a live job shows the last one's until it has it).
  bool HasOwnResult() const { return result && !std::isnan(finished_at) && !(finished_at < started_at); }
  bool warm = false;   ///< warm-started from the last estimate
  /// Lit shading of the snapshot's mesh under the estimate (per vertex, image units),
  /// refined progressively after the estimate; photometric error per vertex against the
  /// nearest keyframe that sees it (|lit - observed| / mean observed; NaN = unseen).
  std::shared_ptr<const std::vector<Eigen::Vector3f>> lit;
  std::shared_ptr<const std::vector<float>> error;
  int lit_samples = 0;
  double lit_noise = std::nan("");  ///< LitShading::noise of `lit` (its Monte Carlo noise, smoothed)
  bool lit_done = false;            ///< the lit shading stopped refining (its noise or its samples reached)
  std::uint64_t lit_version = 0;
  /// The keyframes' clean render under the estimate (ProgressiveRender, after the lit
  /// shading; EstimateOptions::render_noise), the latest pass's: its samples per pixel and
  /// relative noise; null until its first pass.
  std::shared_ptr<const std::vector<ImageRGB>> renders;
  int render_samples = 0;
  double render_noise = std::nan("");
  std::uint64_t render_version = 0;
  ExportState export_state = ExportState::kIdle;
  std::string export_message;  ///< the last export's outcome, one line
};

}  // namespace lp::ui
