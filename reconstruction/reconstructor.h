#pragma once
/// KinectFusion on the CPU: per frame, preprocess -> track (frame-to-model ICP) -> fuse
/// (sparse TSDF) -> raycast; at the end, the scene bundle (mesh with albedo, keyframes
/// with masks, the up direction). The orchestrator reads as that list of stages.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calibration/calibration.h"
#include "capture/frame.h"
#include "scene/scene_bundle.h"
#include "scene/albedo.h"
#include "reconstruction/depth_maps.h"
#include "reconstruction/icp.h"
#include "reconstruction/relocalizer.h"
#include "reconstruction/tsdf_volume.h"

namespace lp {

struct ReconstructionOptions {
  PreprocessOptions preprocess;
  TsdfOptions tsdf;
  IcpOptions icp;
  /// When ICP from the last pose fails, find the camera from colour features and track
  /// from there (large motions, recovery after loss).
  bool relocalize = true;
  RelocalizerOptions relocalizer;
  /// ICP results overlapping the model with fewer of the frame's points than this, or
  /// matching fewer of those than suspicious_inlier_ratio, also try relocalizing and keep
  /// the better fit (at 30 frames/s nearly every point overlaps and matches).
  float suspicious_overlap = 0.6f;
  float suspicious_inlier_ratio = 0.7f;
  /// A tracked frame whose fit is doubtful beside the frames fused before it is neither
  /// fused nor a keyframe, and the next frame starts from the last trusted pose moved on at
  /// the last trusted step (its own pose without two trusted frames in a row): its ICP
  /// error above doubtful_error times their median (and a millimetre above it), or its
  /// inlier ratio below doubtful_inliers times theirs. On flat walls a pose centimetres off
  /// still matches most points (above suspicious_inlier_ratio); fused, it leaves a ghost
  /// the frames after it lock onto. Judged once doubtful_history frames were fused; after
  /// max_doubtful doubtful frames in a row the fit is taken as the scene's new normal
  /// (relocalized frames are judged too: at 7.7 cm between frames most are relocalized).
  /// doubtful_history is at most 8.
  float doubtful_error = 1.4f;
  float doubtful_inliers = 0.85f;
  int doubtful_history = 3;
  int max_doubtful = 3;
  int keyframes = 4;         ///< views in the bundle
  /// Keyframe images are averaged down by an integer factor to about this width (the
  /// paper estimates at 160x120; the estimator's cost grows with the pixels); 0 = as captured.
  int view_width = 160;
  int max_candidates = 64;   ///< keyframe candidates kept while running (memory bound)
  float mesh_min_weight = 2; ///< voxels seen fewer times are left out of the mesh
  /// Taubin smoothing passes over the bundle's mesh (SmoothMesh). Fused depth noise leaves
  /// bumps about a voxel across (at 3.5 m an Xtion's sigma is 2 cm: ~5 mm after 20 frames on
  /// 1 cm voxels): their facets face away from a grazing light and shadow each other, so the
  /// walls render too dark and the estimated light sinks towards them. 0 = as meshed.
  int smooth_iterations = 40;
  /// The bundle's albedo: per-segment mean colour (shading flattened), see albedo.h.
  AlbedoOptions albedo;
  /// Raycast the model for tracking at this pyramid level (1 = half size: a quarter of
  /// the rays; the frame's full-size points still associate into it).
  int model_level = 1;
  /// Frames at least this wide are tracked from pyramid level 1 (at 640x480 the full-size
  /// level costs 4x and adds little; fusion always uses the full-size depth).
  int track_half_from_width = 600;
  /// Fuse every Nth tracked frame (all are tracked): at 30 frames/s neighbours are nearly
  /// the same view, and fusion is the costliest stage; 2 keeps up with a live camera with
  /// the same accuracy (measured in docs/benchmarks.md).
  int fuse_every = 2;
  /// Makes colour frames linear (response, undistortion, vignetting, exposure); without
  /// one, sRGB is assumed (Calibration{}.Describe() says so). A calibrated camera model
  /// replaces the colour intrinsics the source reports.
  Calibration calibration;
  /// Use the poses the source provides (synthetic frames, trajectory files) instead of
  /// tracking: for testing fusion alone, or datasets with better poses.
  bool use_source_poses = false;
};

enum class TrackingState {
  kWaiting,   ///< no frame with enough depth yet: nothing fused
  kTracking,  ///< tracked and fused
  kLost,      ///< tracking failed: not fused; the next frame is tracked from the last good pose
};
const char* ToString(TrackingState s);

/// Seconds spent per stage.
struct StageTimes {
  double preprocess = 0, track = 0, fuse = 0, raycast = 0;
  double total() const { return preprocess + track + fuse + raycast; }
  void Add(const StageTimes& o);
};

struct FrameReport {
  std::int64_t index = 0;
  TrackingState state = TrackingState::kWaiting;
  std::string reason;  ///< why tracking failed or nothing was fused
  Eigen::Matrix4d world_from_camera = Eigen::Matrix4d::Identity();  ///< estimated (or held) pose
  double overlap = 0, inlier_ratio = 0, rmse = 0;
  bool relocalized = false;  ///< tracked from a pose found by colour features
  bool doubtful = false;     ///< tracked, but the fit is doubtful (ReconstructionOptions): not fused
  std::size_t blocks_updated = 0;
  StageTimes times;
};

/// What Reconstructor::Finish needs, copied out of a running reconstruction: the volume,
/// the keyframes chosen so far (their frames) and the options. Taking one costs a copy of
/// the voxel blocks (milliseconds); Finish, the slow part (meshing, smoothing, albedo, up,
/// keyframe masks), can then run on another thread while frames go on.
class ReconstructionSnapshot {
 public:
  /// The bundle Reconstructor::Finish would have returned when the snapshot was taken.
  /// Throws InputError when nothing was fused; Cancelled when `cancelled` (polled between
  /// its steps) returns true.
  SceneBundle Finish(const std::function<bool()>& cancelled = {}) const;

 private:
  friend class Reconstructor;
  struct Impl;
  std::shared_ptr<const Impl> impl_;
};

class Reconstructor {
 public:
  /// Throws InputError for options out of range (voxel, truncation, keyframes).
  explicit Reconstructor(const ReconstructionOptions& options);
  ~Reconstructor();

  /// Processes one frame. The world frame is the source's when the first fused frame
  /// carries a pose (world_from_camera), else that camera's. Throws InputError
  /// for a frame that cannot be used at all (size differs from its intrinsics or from the
  /// first frame's, intrinsics not finite and positive, a given pose that is not rigid);
  /// per-frame events (tracking lost, no depth) are in the report. Unregistered frames
  /// use the calibration's depth-to-colour extrinsics, or none (colour from the depth
  /// camera's view).
  FrameReport Process(const RgbdFrame& frame);

  /// The mesh (marching cubes, per-vertex albedo = mean linear colour), the up direction
  /// (dominant horizontal plane, else the first camera's -y), and `keyframes` sharp,
  /// well-spread views with their masks. Throws InputError when nothing was fused.
  SceneBundle Finish() const;
  /// A copy of what Finish needs, to finish elsewhere (see ReconstructionSnapshot).
  ReconstructionSnapshot Snapshot() const;

  /// Up from the dominant horizontal plane of `mesh` (PCL RANSAC; normal within 30 degrees
  /// of the first camera's -y, turned towards that camera), else the first camera's -y;
  /// `from_plane` says which.
  Eigen::Vector3d EstimateUp(const Mesh& mesh, bool* from_plane = nullptr) const;

  const TsdfVolume& volume() const;
  const StageTimes& times() const;
  /// One entry per processed frame (frames before the first fused one included).
  const std::vector<FrameReport>& reports() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Variance of the Laplacian of the luminance: larger is sharper.
double Sharpness(const ImageRgb8& image);

}  // namespace lp
