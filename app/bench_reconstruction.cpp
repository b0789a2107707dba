// `lightprobe bench --parts reconstruct`: frames per second of the reconstruction by stage
// at 320x240 and 640x480 (synthetic room with Xtion-like depth noise, true trajectory
// known), memory, meshing a 3 m room, and OpenCV's rgbd pieces on the same frames as a
// baseline (ICPOdometry, the hash-TSDF volume's integrate and raycast; Debian's OpenCV
// blocks cv::kinfu::KinFu itself as patented). OpenCV's rgbd module is used only here.
#include <opencv2/core.hpp>
#include <opencv2/rgbd.hpp>

#include <cmath>
#include <cstdio>
#include <memory>

#include "app/commands.h"
#include "capture/synth_source.h"
#include "capture/trajectory.h"
#include "common/timer.h"
#include "estimation/synth.h"
#include "reconstruction/reconstructor.h"
#include "reconstruction/tsdf_volume.h"

namespace lp::app {

namespace {

cv::Matx44f ToCv(const Eigen::Matrix4d& m) {
  cv::Matx44f o;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) o(r, c) = static_cast<float>(m(r, c));
  return o;
}

double Ate(const std::vector<Eigen::Matrix4d>& est, const std::vector<RgbdFrame>& frames) {
  std::vector<Eigen::Matrix4d> truth;
  for (const RgbdFrame& f : frames) truth.push_back(*f.world_from_camera);
  return PositionRmse(est, truth);
}

/// Depth of an axis-aligned box room [0, size] seen from inside (metres along the axis).
std::vector<float> BoxRoomDepth(const Camera& k, const Eigen::Matrix4d& T, const Eigen::Vector3d& size) {
  std::vector<float> d(static_cast<std::size_t>(k.width) * k.height, 0.f);
  const Eigen::Vector3d o = T.block<3, 1>(0, 3), axis = T.block<3, 1>(0, 2);
  for (int y = 0; y < k.height; ++y)
    for (int x = 0; x < k.width; ++x) {
      const Eigen::Vector3d dir = T.block<3, 3>(0, 0) * Eigen::Vector3d((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1);
      double t = 1e9;
      for (int a = 0; a < 3; ++a) {
        if (dir[a] > 1e-12) t = std::min(t, (size[a] - o[a]) / dir[a]);
        if (dir[a] < -1e-12) t = std::min(t, -o[a] / dir[a]);
      }
      d[static_cast<std::size_t>(y) * k.width + x] = static_cast<float>(t * dir.dot(axis));
    }
  return d;
}

/// lightprobe on the frames, fusing every second frame (the default), then every frame (all
/// frames tracked); returns the latter, which is compared with OpenCV per integration.
std::unique_ptr<Reconstructor> BenchOurs(const std::string& size, const std::vector<RgbdFrame>& frames,
                                         const BenchRow& row) {
  const int n = static_cast<int>(frames.size());
  char note[320];
  std::unique_ptr<Reconstructor> every;
  for (int fuse_every : {2, 1}) {
    ReconstructionOptions ro;
    ro.fuse_every = fuse_every;
    auto run = std::make_unique<Reconstructor>(ro);
    Reconstructor& r2 = *run;
    std::vector<Eigen::Matrix4d> p2;
    Stopwatch s2;
    for (const RgbdFrame& f : frames) p2.push_back(r2.Process(f).world_from_camera);
    const double total2 = s2.Seconds();
    const StageTimes& t2 = r2.times();
    std::snprintf(note, sizeof note,
                  "%.1f frames/s; per frame %.1f ms preprocess, %.1f ms track, %.1f ms fuse, %.1f ms raycast "
                  "(tracking raycast at half size); ATE %.1f mm; volume %zu blocks, %.1f MiB",
                  n / total2, 1e3 * t2.preprocess / n, 1e3 * t2.track / n, 1e3 * t2.fuse / n, 1e3 * t2.raycast / n,
                  1e3 * Ate(p2, frames), r2.volume().BlockCount(), r2.volume().MemoryBytes() / 1048576.0);
    row(size, "lightprobe reconstruct, 40 frames (1 cm voxels), fusing every " +
                  std::string(fuse_every == 1 ? "frame" : "second frame"),
        total2, 0, NAN, note);
    if (fuse_every == 1) every = std::move(run);
  }
  return every;
}

std::vector<cv::Mat> DepthMetres(const std::vector<RgbdFrame>& frames) {
  std::vector<cv::Mat> depth_m;
  for (const RgbdFrame& f : frames) {
    cv::Mat d(f.depth.height, f.depth.width, CV_16UC1, const_cast<std::uint16_t*>(f.depth.data.data()));
    cv::Mat m;
    d.convertTo(m, CV_32FC1, 1e-3);
    depth_m.push_back(m);
  }
  return depth_m;
}

/// OpenCV's frame-to-frame ICP odometry chained from the first true pose; adds the seconds
/// it took to *seconds.
std::vector<Eigen::Matrix4d> OpenCvOdometry(const std::vector<RgbdFrame>& frames, const std::vector<cv::Mat>& depth_m,
                                            double* seconds) {
  const Camera& k = frames[0].depth_intrinsics;
  const cv::Mat K = (cv::Mat_<double>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  cv::Ptr<cv::rgbd::ICPOdometry> odo = cv::rgbd::ICPOdometry::create(K, 0.2f, 5.f);
  std::vector<Eigen::Matrix4d> chain{*frames[0].world_from_camera};
  Stopwatch sw;
  for (std::size_t i = 1; i < frames.size(); ++i) {
    cv::Mat Rt;
    sw.Reset();
    const bool ok = odo->compute(cv::Mat(), depth_m[i - 1], cv::Mat(), cv::Mat(), depth_m[i], cv::Mat(), Rt);
    *seconds += sw.Seconds();
    Eigen::Matrix4d cur_from_prev = Eigen::Matrix4d::Identity();
    if (ok)
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) cur_from_prev(r, c) = Rt.at<double>(r, c);
    chain.push_back(chain.back() * cur_from_prev.inverse());
  }
  return chain;
}

/// Seconds OpenCV's hash TSDF took over all frames, fed the true poses.
struct OpenCvTsdfSeconds {
  double integrate = 0, raycast = 0, raycast_half = 0;
};

/// OpenCV's hash TSDF fed the true poses (the same fusion work as ours), raycast at full and
/// half size.
OpenCvTsdfSeconds OpenCvTsdf(const std::vector<RgbdFrame>& frames, const std::vector<cv::Mat>& depth_m, int w, int h) {
  // 1 cm voxels, 4 cm truncation, weights up to 64 as ours; the default raycast step and
  // volume units of 16^3.
  const auto defaults = cv::kinfu::VolumeParams::defaultParams(cv::kinfu::VolumeType::HASHTSDF);
  cv::Ptr<cv::kinfu::Volume> volume =
      cv::kinfu::makeVolume(cv::kinfu::VolumeType::HASHTSDF, 0.01f, cv::Matx44f::eye(), defaults->raycastStepFactor,
                            0.04f, 64, 5.f, cv::Vec3i::all(defaults->unitResolution));
  const Camera& k = frames[0].depth_intrinsics;
  const cv::kinfu::Intr intr(static_cast<float>(k.fx), static_cast<float>(k.fy), static_cast<float>(k.cx),
                             static_cast<float>(k.cy));
  const cv::kinfu::Intr half(static_cast<float>(k.fx / 2), static_cast<float>(k.fy / 2),
                             static_cast<float>((k.cx - 0.5) / 2), static_cast<float>((k.cy - 0.5) / 2));
  OpenCvTsdfSeconds s;
  Stopwatch sw;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const cv::Matx44f pose = ToCv(*frames[i].world_from_camera);
    sw.Reset();
    volume->integrate(depth_m[i], 1.f, pose, intr, static_cast<int>(i));  // float metres: what its hash TSDF takes
    s.integrate += sw.Seconds();
    cv::Mat points, normals;
    sw.Reset();
    volume->raycast(pose, intr, cv::Size(w, h), points, normals);
    s.raycast += sw.Seconds();
    sw.Reset();
    volume->raycast(pose, half, cv::Size(w / 2, h / 2), points, normals);
    s.raycast_half += sw.Seconds();
  }
  return s;
}

/// OpenCV on the same frames: frame-to-frame ICP odometry and the hash TSDF, per frame
/// against our stage times `t`.
void BenchOpenCv(const std::string& size, const std::vector<RgbdFrame>& frames, int w, int h, const StageTimes& t,
                 const BenchRow& row) {
  const int n = static_cast<int>(frames.size());
  const std::vector<cv::Mat> depth_m = DepthMetres(frames);
  double odo_s = 0;
  const std::vector<Eigen::Matrix4d> chain = OpenCvOdometry(frames, depth_m, &odo_s);
  const OpenCvTsdfSeconds s = OpenCvTsdf(frames, depth_m, w, h);
  char note[320];
  std::snprintf(note, sizeof note,
                "per frame: ICPOdometry %.1f ms (frame to frame, ATE %.1f mm; ours %.1fx its time), hash-TSDF "
                "integrate %.1f ms (ours %.2fx), raycast %.1f ms full / %.1f ms half size (ours at half %.2fx)",
                1e3 * odo_s / (n - 1), 1e3 * Ate(chain, frames), (t.track / n) / (odo_s / (n - 1)),
                1e3 * s.integrate / n, (t.fuse / n) / (s.integrate / n), 1e3 * s.raycast / n,
                1e3 * s.raycast_half / n, (t.raycast / n) / (s.raycast_half / n));
  row(size, "OpenCV rgbd baseline (same frames)", odo_s + s.integrate + s.raycast_half, 0, NAN, note);
}

/// One image size: 40 synthetic frames through ours, our meshing, and OpenCV's pieces.
void BenchSize(int w, int h, const BenchRow& row) {
  const std::string size = std::to_string(w) + "x" + std::to_string(h);
  SynthOptions so;
  so.width = w;
  so.height = h;
  so.spp = 1;  // colour does not change the timing
  so.depth_noise = true;
  const int n = 40;
  const std::vector<RgbdFrame> frames = ToRgbdFrames(RenderSynthFrames("one-light", so, DefaultDataDir(), n));
  const std::unique_ptr<Reconstructor> rec = BenchOurs(size, frames, row);
  Stopwatch sw;
  const Mesh mesh = rec->volume().ExtractMesh(2);
  char note[320];
  std::snprintf(note, sizeof note, "%zu triangles", mesh.triangles.size());
  row(size, "lightprobe marching cubes", sw.Seconds(), 0, NAN, note);
  BenchOpenCv(size, frames, w, h, rec->times(), row);
}

/// Meshing a 3 m room: a 3 x 3 x 2.5 m box scanned by a camera turning on the spot.
void BenchRoomMeshing(const BenchRow& row) {
  TsdfOptions to;
  TsdfVolume room(to);
  const Camera k{320, 240, 277.1, 277.1, 159.5, 119.5};
  const Eigen::Vector3d extent(3, 3, 2.5), centre(1.5, 1.5, 1.3);
  for (int i = 0; i < 36; ++i) {
    const double a = i * 10 * 3.14159265358979 / 180;
    const Eigen::Matrix4d T =
        Camera::LookAt(centre, centre + Eigen::Vector3d(std::cos(a), std::sin(a), -0.3), Eigen::Vector3d::UnitZ(), 4, 4, 60)
            .world_from_camera;
    room.Integrate(BoxRoomDepth(k, T, extent), k, nullptr, k, T);
  }
  Stopwatch sw;
  const Mesh mesh = room.ExtractMesh(1);
  char note[256];
  std::snprintf(note, sizeof note, "3 x 3 x 2.5 m room at 1 cm, 36 views: %zu blocks, %.1f MiB, %zu triangles",
                room.BlockCount(), room.MemoryBytes() / 1048576.0, mesh.triangles.size());
  row("room", "meshing a 3 m room (marching cubes)", sw.Seconds(), 0, NAN, note);
}

}  // namespace

void ReconstructionBench(const BenchRow& row) {
  for (const auto& [w, h] : {std::pair{320, 240}, std::pair{640, 480}}) BenchSize(w, h, row);
  BenchRoomMeshing(row);
}

}  // namespace lp::app
