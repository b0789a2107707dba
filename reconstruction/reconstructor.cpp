#include "reconstruction/reconstructor.h"

#include <algorithm>
#include <deque>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/Geometry>

#include "common/color.h"
#include "common/error.h"
#include "common/parallel.h"
#include "reconstruction/geometry.h"

namespace lp {

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// A frame kept as a possible keyframe.
struct Candidate {
  std::int64_t index = 0;
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  double sharpness = 0;
  ImageRgb8 color;
  DepthImage depth;
  Camera depth_k, color_k;
  bool registered = false;
  double exposure = 0, gain = 0;
};

bool GoodIntrinsics(const Camera& k) {
  return std::isfinite(k.fx) && std::isfinite(k.fy) && std::isfinite(k.cx) && std::isfinite(k.cy) && k.fx > 0 &&
         k.fy > 0 && k.width > 0 && k.height > 0;
}

/// Averages a view down by `f` x `f` blocks (linear radiance: the mean is what a camera
/// with bigger pixels would see). A block is valid only if all its pixels are valid and
/// none is saturated (a mean over clipped pixels is biased low); a block whose pixels are
/// all inside the mask and one of them saturated is `clipped` (its mean a lower bound); one
/// holding a pixel `clipped_off` the mesh is that.
void Downsample(View* v, int f) {
  if (f <= 1) return;
  Camera& c = v->camera;
  const int w = c.width / f, h = c.height / f;
  ImageRGB image(w, h);
  std::vector<std::uint8_t> valid(static_cast<std::size_t>(w) * h, 0), clipped(valid.size(), 0),
      clipped_off(valid.size(), 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float sum[3] = {0, 0, 0};
      bool inside = true, saturated = false, off = false;
      for (int dy = 0; dy < f; ++dy)
        for (int dx = 0; dx < f; ++dx) {
          const int sx = x * f + dx, sy = y * f + dy;
          const float* p = v->image.at(sx, sy);
          inside = inside && v->valid[static_cast<std::size_t>(sy) * c.width + sx];
          off = off || v->clipped_off[static_cast<std::size_t>(sy) * c.width + sx];
          saturated = saturated || std::max({p[0], p[1], p[2]}) >= v->saturation;
          for (int ch = 0; ch < 3; ++ch) sum[ch] += p[ch];
        }
      for (int ch = 0; ch < 3; ++ch) image.at(x, y)[ch] = sum[ch] / (f * f);
      valid[static_cast<std::size_t>(y) * w + x] = inside && !saturated;
      clipped[static_cast<std::size_t>(y) * w + x] = inside && saturated;
      clipped_off[static_cast<std::size_t>(y) * w + x] = off;
    }
  // Pixel centres at integers: block x covers source pixels [f x, f x + f - 1].
  c.cx = (c.cx + 0.5) / f - 0.5;
  c.cy = (c.cy + 0.5) / f - 0.5;
  c.fx /= f;
  c.fy /= f;
  c.width = w;
  c.height = h;
  v->image = std::move(image);
  v->valid = std::move(valid);
  v->clipped = std::move(clipped);
  v->clipped_off = std::move(clipped_off);
}

/// The pixels the camera clipped off the mesh (outside the mask: no depth, or depth that
/// disagrees with the model there; View::clipped_off).
std::vector<std::uint8_t> ClippedOffMesh(const View& v) {
  std::vector<std::uint8_t> off(v.valid.size(), 0);
  for (std::size_t p = 0; p < off.size(); ++p) {
    const float* c = &v.image.data[3 * p];
    off[p] = !v.valid[p] && std::max({c[0], c[1], c[2]}) >= v.saturation;
  }
  return off;
}

}  // namespace

const char* ToString(TrackingState s) {
  switch (s) {
    case TrackingState::kWaiting: return "waiting for depth";
    case TrackingState::kTracking: return "tracking";
    case TrackingState::kLost: return "lost";
  }
  return "?";
}

void StageTimes::Add(const StageTimes& o) {
  preprocess += o.preprocess;
  track += o.track;
  fuse += o.fuse;
  raycast += o.raycast;
}

double Sharpness(const ImageRgb8& im) {
  const int w = im.width, h = im.height;
  if (w < 3 || h < 3) return 0;
  std::vector<float> grey(im.pixels());
  ParallelForChunks(0, grey.size(), 16384, [&](std::size_t p0, std::size_t p1) {
    for (std::size_t p = p0; p < p1; ++p)
      grey[p] = 0.299f * im.data[3 * p] + 0.587f * im.data[3 * p + 1] + 0.114f * im.data[3 * p + 2];
  });
  // Per row, then summed in row order: the same value on any number of threads.
  std::vector<double> row_sum(static_cast<std::size_t>(h), 0.0), row_sum2(row_sum.size(), 0.0);
  ParallelForChunks(1, static_cast<std::size_t>(h - 1), 16, [&](std::size_t y0, std::size_t y1) {
    for (std::size_t y = y0; y < y1; ++y) {
      double a = 0, b = 0;
      for (int x = 1; x + 1 < w; ++x) {
        const std::size_t p = y * w + x;
        const double lap = grey[p - 1] + grey[p + 1] + grey[p - w] + grey[p + w] - 4.0 * grey[p];
        a += lap;
        b += lap * lap;
      }
      row_sum[y] = a;
      row_sum2[y] = b;
    }
  });
  double sum = 0, sum2 = 0;
  for (int y = 1; y + 1 < h; ++y) {
    sum += row_sum[y];
    sum2 += row_sum2[y];
  }
  const double n = static_cast<double>(w - 2) * (h - 2);
  const double mean = sum / n;
  return sum2 / n - mean * mean;
}

/// How many fused frames' fits a new frame's is judged against (Impl::Doubtful).
constexpr std::size_t kFitHistory = 8;

struct Reconstructor::Impl {
  ReconstructionOptions o;
  TsdfVolume volume;
  ModelMaps model;
  int since_fused = 0;  // tracked frames since the last fused one
  TsdfVolume::Maps last_maps;  // the last raycast: where the next one searches
  Eigen::Matrix4d last_maps_pose = Eigen::Matrix4d::Identity();
  bool started = false;
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();  // last good
  Eigen::Matrix4d first_pose = Eigen::Matrix4d::Identity();
  Camera first_depth_k, first_color_k;
  StageTimes times;
  std::vector<FrameReport> reports;
  // Keyframe candidates: the sharpest tracked frame of each window of `window` frames;
  // when the pool is full, neighbours are merged and the window doubles.
  std::vector<Candidate> pool;
  std::optional<Candidate> pending;
  int window = 1, in_window = 0;

  Relocalizer relocalizer;
  Eigen::Matrix4d remembered = Eigen::Matrix4d::Identity();  // pose of the last frame the relocalizer kept
  // The fits (ICP error, inlier ratio) of the last kFitHistory fused tracked frames, newest
  // last, and how many doubtful frames came in a row since.
  std::deque<std::pair<double, double>> fits;
  int doubtful_run = 0;
  // The last two trusted poses and the frames since the last: where the next frame starts
  // after a doubtful one (PredictedPose).
  Eigen::Matrix4d good = Eigen::Matrix4d::Identity(), previous_good = Eigen::Matrix4d::Identity();
  int since_good = 0, trusted = 0, good_gap = 1;  // good_gap: frames between the two

  /// Where the frame after a doubtful one starts: the last trusted pose moved on at the
  /// last trusted step for every frame since (constant velocity), or `doubtful` itself
  /// without two trusted frames in a row.
  Eigen::Matrix4d PredictedPose(const Eigen::Matrix4d& doubtful) {
    ++since_good;
    if (trusted < 2 || good_gap != 1) return doubtful;
    const Eigen::Matrix4d step = previous_good.inverse() * good;
    Eigen::Matrix4d predicted = good;
    for (int k = 0; k < since_good; ++k) predicted = predicted * step;
    return predicted;
  }

  explicit Impl(const ReconstructionOptions& opt) : o(opt), volume(opt.tsdf), relocalizer(opt.relocalizer) {}

  /// The model as a camera at `pose` sees it, for tracking (raycast at model_level);
  /// `hint` (the last raycast) and `measured` (the depth just fused, metres, full size) bound
  /// the search (TsdfVolume::Raycast); `raycast` receives the maps if asked.
  ModelMaps ModelFrom(const Camera& depth_k, const Eigen::Matrix4d& pose, const TsdfVolume::Maps* hint = nullptr,
                      TsdfVolume::Maps* raycast = nullptr, const std::vector<float>* measured = nullptr) const {
    TsdfVolume::Maps maps;
    const int level = std::clamp(o.model_level, 0, std::max(0, o.preprocess.levels - 1));
    const Camera k = ScaleIntrinsics(depth_k, level);
    const std::vector<float> guide =
        measured ? NearestDepthAtLevel(*measured, depth_k.width, depth_k.height, level) : std::vector<float>();
    volume.Raycast(k, pose, &maps, false, hint, guide.empty() ? nullptr : &guide);
    ModelMaps model_maps = MakeModelMaps(k, maps.vertex, maps.normal, pose, o.preprocess.levels, level);
    if (raycast) *raycast = std::move(maps);
    return model_maps;
  }

  /// Keeps a tracked frame's features when the camera moved on from the last one kept.
  void MaybeRemember(const RgbdFrame& f, const Eigen::Matrix4d& pose, bool force) {
    if (!o.relocalize) return;
    const Eigen::Matrix4d d = remembered.inverse() * pose;
    if (!force && !relocalizer.empty() && d.block<3, 1>(0, 3).norm() < 0.1 && RotationAngle(d) < 0.17) return;
    relocalizer.Remember(f, pose);
    remembered = pose;
  }

  void Validate(const RgbdFrame& f) const {
    const std::string at = "frame " + std::to_string(f.index);
    if (!GoodIntrinsics(f.depth_intrinsics)) throw InputError(at + ": depth intrinsics are not finite and positive");
    if (!GoodIntrinsics(f.color_intrinsics)) throw InputError(at + ": colour intrinsics are not finite and positive");
    if (f.depth.width != f.depth_intrinsics.width || f.depth.height != f.depth_intrinsics.height ||
        f.depth.data.size() != f.depth.pixels())
      throw InputError(at + ": depth image " + std::to_string(f.depth.width) + "x" + std::to_string(f.depth.height) +
                       " does not match its intrinsics (" + std::to_string(f.depth_intrinsics.width) + "x" +
                       std::to_string(f.depth_intrinsics.height) + ")");
    if (f.color.width != f.color_intrinsics.width || f.color.height != f.color_intrinsics.height ||
        f.color.data.size() != 3 * f.color.pixels())
      throw InputError(at + ": colour image does not match its intrinsics");
    if (f.world_from_camera) {
      const Eigen::Matrix4d& T = *f.world_from_camera;
      const Eigen::Matrix3d R = T.block<3, 3>(0, 0);
      if (!T.allFinite() || (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || R.determinant() <= 0 ||
          (T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9 || T.block<3, 1>(0, 3).norm() > 1e4)
        throw InputError(at + ": the given pose is not a rigid transform (finite rotation and translation)");
    }
    if (started && (f.depth.width != first_depth_k.width || f.depth.height != first_depth_k.height ||
                    f.color.width != first_color_k.width || f.color.height != first_color_k.height))
      throw InputError(at + ": frame size " + std::to_string(f.depth.width) + "x" + std::to_string(f.depth.height) +
                       " differs from the first frame's " + std::to_string(first_depth_k.width) + "x" +
                       std::to_string(first_depth_k.height));
  }

  /// The colour camera: the calibrated model (for undistorted images) when there is one.
  Camera ColorK(const RgbdFrame& f) const {
    if (!o.calibration.color) return f.color_intrinsics;
    return *o.calibration.color;  // its pinhole part
  }

  void Fuse(const RgbdFrame& f, const Eigen::Matrix4d& world_from_camera, FrameReport* r) {
    auto t0 = Clock::now();
    const ImageRGB color = Linearize(f.color, o.calibration, f.exposure, f.gain);
    const Eigen::Matrix4d* extrinsics =
        !f.registered && o.calibration.color_from_depth ? &*o.calibration.color_from_depth : nullptr;
    const std::vector<float> metres = DepthToMetres(f.depth, o.preprocess);
    r->blocks_updated =
        volume.Integrate(metres, f.depth_intrinsics, &color, ColorK(f), world_from_camera, extrinsics);
    r->times.fuse = Since(t0);
    t0 = Clock::now();
    // The last raycast bounds the search only when the camera moved less than its margin
    // since (it searches +-(truncation + 5 cm) around the depths it found).
    const Eigen::Matrix4d moved = last_maps_pose.inverse() * world_from_camera;
    const bool hint = !last_maps.depth.empty() && moved.block<3, 1>(0, 3).norm() < 0.5 * (o.tsdf.truncation + 0.05) &&
                      RotationAngle(moved) < 0.05;
    TsdfVolume::Maps maps;
    model = ModelFrom(f.depth_intrinsics, world_from_camera, hint ? &last_maps : nullptr, &maps, &metres);
    last_maps = std::move(maps);
    last_maps_pose = world_from_camera;
    r->times.raycast = Since(t0);
  }

  void Offer(const RgbdFrame& f, const Eigen::Matrix4d& pose) {
    Candidate c;
    c.index = f.index;
    c.pose = pose;
    c.sharpness = Sharpness(f.color);
    if (!pending || c.sharpness > pending->sharpness) {
      c.color = f.color;
      c.depth = f.depth;
      c.depth_k = f.depth_intrinsics;
      c.color_k = ColorK(f);
      c.registered = f.registered;
      c.exposure = f.exposure;
      c.gain = f.gain;
      pending = std::move(c);
    }
    if (++in_window < window) return;
    pool.push_back(std::move(*pending));
    pending.reset();
    in_window = 0;
    if (static_cast<int>(pool.size()) < std::max(2, o.max_candidates)) return;
    std::vector<Candidate> merged;
    for (std::size_t i = 0; i < pool.size(); i += 2) {
      if (i + 1 < pool.size() && pool[i + 1].sharpness > pool[i].sharpness) merged.push_back(std::move(pool[i + 1]));
      else merged.push_back(std::move(pool[i]));
    }
    pool = std::move(merged);
    window *= 2;
  }
  std::optional<RgbdFrame> OnColorGrid(const RgbdFrame& input) const;
  void Start(const RgbdFrame& f, const RgbdFrame& input, bool enough_depth, FrameReport* r);
  TrackResult Track(const RgbdFrame& f, const RgbdFrame& input, const std::vector<DepthLevel>& levels,
                    const std::optional<Eigen::Matrix4d>& source_pose, bool enough_depth, FrameReport* r);
  bool Doubtful(const TrackResult& tr, FrameReport* r);
  void Follow(const RgbdFrame& f, const RgbdFrame& input, const std::vector<DepthLevel>& levels,
              const std::optional<Eigen::Matrix4d>& source_pose, bool enough_depth, FrameReport* r);
};

Reconstructor::Reconstructor(const ReconstructionOptions& o) : impl_(std::make_unique<Impl>(o)) {
  if (!(o.tsdf.voxel >= 0.001f && o.tsdf.voxel <= 0.1f))
    throw InputError("reconstruction: the voxel size must be between 0.001 and 0.1 m");
  if (!(o.tsdf.truncation >= 2 * o.tsdf.voxel && o.tsdf.truncation <= 1.f))
    throw InputError("reconstruction: the truncation distance must be at least two voxels and at most 1 m");
  if (o.keyframes < 1 || o.keyframes > 64) throw InputError("reconstruction: the keyframe count must be between 1 and 64");
  if (!(o.preprocess.sigma_depth > 0) || !(o.preprocess.sigma_space > 0) || o.preprocess.bilateral_radius < 0 ||
      o.preprocess.normal_radius < 1 || o.preprocess.levels < 1 || o.relocalizer.min_inliers < 4)
    throw InputError("reconstruct: preprocessing / relocalization options out of range");
}

Reconstructor::~Reconstructor() = default;

const TsdfVolume& Reconstructor::volume() const { return impl_->volume; }
const StageTimes& Reconstructor::times() const { return impl_->times; }
const std::vector<FrameReport>& Reconstructor::reports() const { return impl_->reports; }

FrameReport Reconstructor::Process(const RgbdFrame& input) {
  Impl& m = *impl_;
  m.Validate(input);
  const std::optional<RgbdFrame> undistorted = m.OnColorGrid(input);
  const RgbdFrame& f = undistorted ? *undistorted : input;
  FrameReport r;
  r.index = f.index;
  const auto t0 = Clock::now();
  PreprocessOptions po = m.o.preprocess;
  if (f.depth.width >= m.o.track_half_from_width) po.first_level = std::max(po.first_level, 1);
  const std::vector<DepthLevel> levels = PreprocessDepth(f.depth, f.depth_intrinsics, po);
  r.times.preprocess = Since(t0);
  const DepthLevel& tracked = levels[static_cast<std::size_t>(std::min<int>(po.first_level, levels.size() - 1))];
  std::size_t valid = 0;
  for (std::size_t p = 0; p < tracked.depth.size(); ++p) valid += tracked.valid(p);
  const bool enough_depth = valid >= tracked.depth.size() / 20;
  std::optional<Eigen::Matrix4d> source_pose;
  if (m.o.use_source_poses) {
    if (!f.world_from_camera)
      throw InputError("frame " + std::to_string(f.index) + ": no pose from the source (use_source_poses)");
    source_pose = *f.world_from_camera;
  }
  if (!m.started) m.Start(f, input, enough_depth, &r);
  else m.Follow(f, input, levels, source_pose, enough_depth, &r);
  m.times.Add(r.times);
  m.reports.push_back(r);
  return r;
}

/// Depth registered to a calibrated colour camera lies on its pixel grid: it takes the
/// colour model's intrinsics and, when the calibration undistorts the colour, the same
/// undistortion (back-projected as delivered, walls bent towards the image corners). None
/// when the frame is used as it is. (The relocalizer matches colour features to depth on
/// the delivered grid: the input.)
std::optional<RgbdFrame> Reconstructor::Impl::OnColorGrid(const RgbdFrame& input) const {
  const CameraModel* cm = o.calibration.color ? &*o.calibration.color : nullptr;
  if (!(input.registered && cm && cm->width == input.depth.width && cm->height == input.depth.height))
    return std::nullopt;
  std::optional<RgbdFrame> out = input;
  if (cm->distorted()) out->depth = UndistortRegisteredDepth(input.depth, *cm);
  out->depth_intrinsics = ColorK(input);
  return out;
}

/// The first frame with enough depth starts the model: the world is the source's when it
/// gives poses (synthetic frames, trajectory files: ground truth applies directly), else
/// the first camera's.
void Reconstructor::Impl::Start(const RgbdFrame& f, const RgbdFrame& input, bool enough_depth, FrameReport* r) {
  if (!enough_depth) {
    r->state = TrackingState::kWaiting;
    r->reason = "too little valid depth to start";
    return;
  }
  started = true;
  first_depth_k = f.depth_intrinsics;
  first_color_k = f.color_intrinsics;
  pose = f.world_from_camera.value_or(Eigen::Matrix4d::Identity());
  first_pose = pose;
  good = previous_good = pose;
  trusted = 1;
  Fuse(f, pose, r);
  r->state = TrackingState::kTracking;
  r->world_from_camera = pose;
  Offer(f, pose);
  MaybeRemember(input, pose, true);
}

/// The frame's pose: the source's, or tracked against the model; a failure or a weak match
/// (at 30 frames/s nearly every point matches) tries the pose from colour features too, and
/// keeps the better fit.
TrackResult Reconstructor::Impl::Track(const RgbdFrame& f, const RgbdFrame& input, const std::vector<DepthLevel>& levels,
                                       const std::optional<Eigen::Matrix4d>& source_pose, bool enough_depth,
                                       FrameReport* r) {
  TrackResult tr;
  if (source_pose) {
    tr.ok = true;
    tr.world_from_camera = *source_pose;
    return tr;
  }
  if (!enough_depth) {
    tr.reason = "too little valid depth";
    return tr;
  }
  tr = TrackFrameToModel(levels, model, pose, o.icp);
  const bool weak = !tr.ok || tr.overlap < o.suspicious_overlap || tr.inlier_ratio < o.suspicious_inlier_ratio;
  if (!o.relocalize || !weak) return tr;
  if (const std::optional<Eigen::Matrix4d> guess = relocalizer.Locate(input)) {
    const TrackResult again = TrackFrameToModel(levels, ModelFrom(f.depth_intrinsics, *guess), *guess, o.icp);
    if (again.ok && (!tr.ok || again.overlap * again.inlier_ratio > tr.overlap * tr.inlier_ratio)) {
      tr = again;
      r->relocalized = true;
    }
  }
  return tr;
}

/// Whether a tracked frame's fit is doubtful beside the last fused frames' (see
/// ReconstructionOptions::doubtful_error); says why in `r`. Counts the doubtful run.
bool Reconstructor::Impl::Doubtful(const TrackResult& tr, FrameReport* r) {
  if (static_cast<int>(fits.size()) < std::clamp(o.doubtful_history, 1, static_cast<int>(kFitHistory))) return false;
  std::vector<double> errors, inliers;
  for (const auto& [e, i] : fits) errors.push_back(e), inliers.push_back(i);
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  std::nth_element(inliers.begin(), inliers.begin() + inliers.size() / 2, inliers.end());
  const double error = errors[errors.size() / 2], inlier = inliers[inliers.size() / 2];
  // (an ICP error a millimetre above the median is noise however small the median: clean depth)
  const bool doubtful = tr.rmse > std::max(o.doubtful_error * error, error + 0.001) ||
                        tr.inlier_ratio < o.doubtful_inliers * inlier;
  if (!doubtful) {
    doubtful_run = 0;
    return false;
  }
  if (++doubtful_run > std::max(0, o.max_doubtful)) {  // the scene changed: a new normal
    fits.clear();
    doubtful_run = 0;
    return false;
  }
  char why[200];
  std::snprintf(why, sizeof why,
                "doubtful fit: ICP error %.1f mm against a median %.1f mm of the last fused; inliers %.2f against %.2f; not fused",
                1e3 * tr.rmse, 1e3 * error, tr.inlier_ratio, inlier);
  r->reason = why;
  r->doubtful = true;
  return true;
}

/// A frame after the first: tracked, then fused every fuse_every-th tracked frame (and after
/// a relocalization; in between the model maps stay those raycast at the last fused pose),
/// unless its fit is doubtful.
void Reconstructor::Impl::Follow(const RgbdFrame& f, const RgbdFrame& input, const std::vector<DepthLevel>& levels,
                                 const std::optional<Eigen::Matrix4d>& source_pose, bool enough_depth,
                                 FrameReport* r) {
  const auto t0 = Clock::now();
  const TrackResult tr = Track(f, input, levels, source_pose, enough_depth, r);
  r->times.track = Since(t0);
  r->overlap = tr.overlap;
  r->inlier_ratio = tr.inlier_ratio;
  r->rmse = tr.rmse;
  if (tr.ok) {
    r->state = TrackingState::kTracking;
    r->world_from_camera = tr.world_from_camera;
    if (!source_pose && Doubtful(tr, r)) {
      pose = PredictedPose(tr.world_from_camera);
      return;
    }
    pose = tr.world_from_camera;
    previous_good = good;
    good = pose;
    good_gap = since_good + 1;
    since_good = 0;
    ++trusted;  // (after lost frames good_gap > 1: no constant-velocity step across them)
    if (++since_fused >= std::max(1, o.fuse_every) || r->relocalized) {
      Fuse(f, pose, r);
      since_fused = 0;
      if (!source_pose) {
        fits.emplace_back(tr.rmse, tr.inlier_ratio);
        if (fits.size() > kFitHistory) fits.pop_front();
      }
    }
    Offer(f, pose);
    if (!source_pose) MaybeRemember(input, pose, r->relocalized);
  } else {
    r->state = TrackingState::kLost;
    r->reason = tr.reason;
    ++since_good;  // (a constant-velocity prediction after it spans the lost frames too)
  }
  r->world_from_camera = pose;
}

namespace {

/// Up from the dominant horizontal plane of `mesh` (a floor or a ceiling, its normal on the
/// side of the first camera's -y), else the first camera's -y.
Eigen::Vector3d UpOf(const Mesh& mesh, const Eigen::Matrix4d& first, double voxel, bool* from_plane) {
  const Eigen::Vector3d rough = -first.block<3, 1>(0, 1);
  const std::optional<Plane> plane = DominantPlane(mesh.positions, rough, 30, 2 * voxel + 0.01);
  if (from_plane) *from_plane = plane.has_value();
  return plane ? plane->normal : rough;
}

/// The sharpest candidate first, then the one farthest (in pose) from those chosen,
/// weighted by sharpness, until `keyframes`; in frame order.
std::vector<const Candidate*> ChooseKeyframes(const std::vector<Candidate>& candidates,
                                              const std::optional<Candidate>& pending, int keyframes) {
  std::vector<const Candidate*> pool;
  for (const Candidate& c : candidates) pool.push_back(&c);
  if (pending) pool.push_back(&*pending);
  double best_sharp = 0;
  for (const Candidate* c : pool) best_sharp = std::max(best_sharp, c->sharpness);
  std::vector<const Candidate*> chosen;
  while (static_cast<int>(chosen.size()) < keyframes && chosen.size() < pool.size()) {
    const Candidate* pick = nullptr;
    double best = -1;
    for (const Candidate* c : pool) {
      if (std::find(chosen.begin(), chosen.end(), c) != chosen.end()) continue;
      double spread = 1;
      if (!chosen.empty()) {
        spread = std::numeric_limits<double>::max();
        for (const Candidate* k : chosen) spread = std::min(spread, PoseDistance(c->pose, k->pose));
      }
      const double score = spread * std::sqrt(best_sharp > 0 ? c->sharpness / best_sharp : 1.0);
      if (score > best) {
        best = score;
        pick = c;
      }
    }
    chosen.push_back(pick);
  }
  std::sort(chosen.begin(), chosen.end(), [](const Candidate* a, const Candidate* b) { return a->index < b->index; });
  return chosen;
}

/// Frames processed, fused and lost, for the error when nothing can be meshed.
struct FrameCounts {
  std::size_t frames = 0, fused = 0, lost = 0;
};

FrameCounts CountFrames(const std::vector<FrameReport>& reports) {
  FrameCounts n;
  n.frames = reports.size();
  for (const FrameReport& r : reports) {
    n.fused += r.state == TrackingState::kTracking && !r.doubtful;
    n.lost += r.state == TrackingState::kLost;
  }
  return n;
}

/// The bundle from a volume and the chosen keyframes (Reconstructor::Finish); `cancelled`
/// (may be empty) is polled between the steps.
SceneBundle FinishBundle(bool started, const ReconstructionOptions& o, const TsdfVolume& volume,
                         const std::vector<const Candidate*>& chosen, const Eigen::Matrix4d& first_pose,
                         const FrameCounts& counts, const std::function<bool()>& cancelled = {}) {
  if (!started) throw InputError("reconstruct: no frame had enough valid depth to build a model");
  const auto check = [&] {
    if (cancelled && cancelled()) throw Cancelled();
  };
  SceneBundle b;
  b.mesh = volume.ExtractMesh(o.mesh_min_weight);
  check();
  if (b.mesh.triangles.empty())
    throw InputError("reconstruct: the fused model has no surface seen at least " +
                     std::to_string(static_cast<int>(o.mesh_min_weight)) + " times (" + std::to_string(counts.fused) +
                     " of " + std::to_string(counts.frames) + " frames fused, tracking lost in " +
                     std::to_string(counts.lost) + ": moving too fast between frames?)");
  SmoothMesh(&b.mesh, o.smooth_iterations);
  check();
  SanitizeMesh(&b.mesh, "reconstructed mesh");
  b.up = UpOf(b.mesh, first_pose, o.tsdf.voxel, nullptr);
  b.mesh.shaded = b.mesh.albedo;  // the colour seen: the estimator de-lights it (scene/albedo.h)
  FlattenAlbedo(&b.mesh, o.albedo);

  for (const Candidate* c : chosen) {
    check();
    View v;
    const Camera& k = c->color_k;
    v.camera = k;
    // The view is the colour camera's: moved from the depth camera's pose by the
    // calibrated extrinsics when depth was not registered to colour.
    v.camera.world_from_camera = c->pose;
    if (!c->registered && o.calibration.color_from_depth)
      v.camera.world_from_camera = c->pose * o.calibration.color_from_depth->inverse();
    v.image = Linearize(c->color, o.calibration, c->exposure, c->gain);
    v.saturation = 1.0;  // 8-bit: the top code is clipped
    // Mask: the model is hit, away from its depth discontinuities, and (registered depth
    // of the same size) the measured depth agrees with it. The paper's discussion: pixels
    // at depth edges mix surfaces.
    TsdfVolume::Maps maps;
    volume.Raycast(k, v.camera.world_from_camera, &maps);
    const int w = k.width, h = k.height;
    const bool compare = c->registered && c->depth.width == w && c->depth.height == h;
    v.valid.assign(static_cast<std::size_t>(w) * h, 0);
    for (int y = 1; y + 1 < h; ++y)
      for (int x = 1; x + 1 < w; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * w + x;
        const float z = maps.depth[p];
        if (z <= 0) continue;
        bool edge = false;
        for (int dy = -1; dy <= 1 && !edge; ++dy)
          for (int dx = -1; dx <= 1 && !edge; ++dx) {
            const float zn = maps.depth[p + static_cast<std::ptrdiff_t>(dy) * w + dx];
            edge = zn <= 0 || std::abs(zn - z) > 0.03f * z;
          }
        if (edge) continue;
        if (compare) {
          const float measured = c->depth.data[p] * 1e-3f;
          const float sigma = 0.0012f + 0.0019f * (z - 0.4f) * (z - 0.4f);
          if (measured <= 0 || std::abs(measured - z) > std::max(0.02f, 3 * sigma)) continue;
        }
        v.valid[p] = 1;
      }
    v.clipped_off = ClippedOffMesh(v);
    if (o.view_width > 0) Downsample(&v, std::max(1, static_cast<int>(std::lround(static_cast<double>(w) / o.view_width))));
    char name[32];
    std::snprintf(name, sizeof name, "view%zu.exr", b.views.size());
    v.image_file = name;
    std::snprintf(name, sizeof name, "mask%zu.png", b.views.size());
    v.mask_file = name;
    b.views.push_back(std::move(v));
  }
  return b;
}

}  // namespace

struct ReconstructionSnapshot::Impl {
  ReconstructionOptions o;
  TsdfVolume volume;
  std::vector<Candidate> chosen;
  Eigen::Matrix4d first_pose = Eigen::Matrix4d::Identity();
  FrameCounts counts;
  bool started = false;
  Impl(const ReconstructionOptions& opt, TsdfVolume v) : o(opt), volume(std::move(v)) {}
};

SceneBundle ReconstructionSnapshot::Finish(const std::function<bool()>& cancelled) const {
  LP_CHECK(impl_ != nullptr, "a snapshot not taken from a reconstruction");
  std::vector<const Candidate*> chosen;
  for (const Candidate& c : impl_->chosen) chosen.push_back(&c);
  return FinishBundle(impl_->started, impl_->o, impl_->volume, chosen, impl_->first_pose, impl_->counts, cancelled);
}

ReconstructionSnapshot Reconstructor::Snapshot() const {
  const Impl& m = *impl_;
  auto s = std::make_shared<ReconstructionSnapshot::Impl>(m.o, m.volume.Clone());
  for (const Candidate* c : ChooseKeyframes(m.pool, m.pending, m.o.keyframes)) s->chosen.push_back(*c);
  s->first_pose = m.first_pose;
  s->counts = CountFrames(m.reports);
  s->started = m.started;
  ReconstructionSnapshot out;
  out.impl_ = std::move(s);
  return out;
}

Eigen::Vector3d Reconstructor::EstimateUp(const Mesh& mesh, bool* from_plane) const {
  // The first fused camera's -y is up unless a horizontal plane says better.
  return UpOf(mesh, impl_->first_pose, impl_->o.tsdf.voxel, from_plane);
}

SceneBundle Reconstructor::Finish() const {
  const Impl& m = *impl_;
  return FinishBundle(m.started, m.o, m.volume, ChooseKeyframes(m.pool, m.pending, m.o.keyframes), m.first_pose,
                      CountFrames(m.reports));
}

}  // namespace lp
