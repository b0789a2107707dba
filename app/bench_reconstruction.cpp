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
std::vector<float> BoxRoomDepth(const Intrinsics& k, const Eigen::Matrix4d& T, const Eigen::Vector3d& size) {
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

}  // namespace

void ReconstructionBench(const BenchRow& row) {
  for (const auto& [w, h] : {std::pair{320, 240}, std::pair{640, 480}}) {
    const std::string size = std::to_string(w) + "x" + std::to_string(h);
    SynthOptions so;
    so.width = w;
    so.height = h;
    so.spp = 1;  // colour does not change the timing
    so.depth_noise = true;
    const int n = 40;
    const std::vector<RgbdFrame> frames = ToRgbdFrames(RenderSynthFrames("one-light", so, DefaultDataDir(), n));

    // lightprobe: fusing every second frame (the default), then every frame (all frames
    // tracked); the latter is compared with OpenCV per integration below.
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
    const Reconstructor& rec = *every;
    const StageTimes& t = rec.times();
    Stopwatch sw;
    const Mesh mesh = rec.volume().ExtractMesh(2);
    std::snprintf(note, sizeof note, "%zu triangles", mesh.triangles.size());
    row(size, "lightprobe marching cubes", sw.Seconds(), 0, NAN, note);

    // OpenCV on the same frames: frame-to-frame ICP odometry, and the hash TSDF fed the
    // true poses (the same fusion work as ours), raycast at full and half size.
    const Intrinsics& k = frames[0].depth_intrinsics;
    const cv::Mat K = (cv::Mat_<double>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
    cv::Ptr<cv::rgbd::ICPOdometry> odo = cv::rgbd::ICPOdometry::create(K, 0.2f, 5.f);
    std::vector<cv::Mat> depth_m;
    for (const RgbdFrame& f : frames) {
      cv::Mat d(f.depth.height, f.depth.width, CV_16UC1, const_cast<std::uint16_t*>(f.depth.data.data()));
      cv::Mat m;
      d.convertTo(m, CV_32FC1, 1e-3);
      depth_m.push_back(m);
    }
    std::vector<Eigen::Matrix4d> chain{*frames[0].world_from_camera};
    double odo_s = 0;
    for (int i = 1; i < n; ++i) {
      cv::Mat Rt;
      sw.Reset();
      const bool ok = odo->compute(cv::Mat(), depth_m[i - 1], cv::Mat(), cv::Mat(), depth_m[i], cv::Mat(), Rt);
      odo_s += sw.Seconds();
      Eigen::Matrix4d cur_from_prev = Eigen::Matrix4d::Identity();
      if (ok)
        for (int r = 0; r < 4; ++r)
          for (int c = 0; c < 4; ++c) cur_from_prev(r, c) = Rt.at<double>(r, c);
      chain.push_back(chain.back() * cur_from_prev.inverse());
    }
    // 1 cm voxels, 4 cm truncation, weights up to 64 as ours; the default raycast step and
    // volume units of 16^3.
    const auto defaults = cv::kinfu::VolumeParams::defaultParams(cv::kinfu::VolumeType::HASHTSDF);
    cv::Ptr<cv::kinfu::Volume> volume =
        cv::kinfu::makeVolume(cv::kinfu::VolumeType::HASHTSDF, 0.01f, cv::Matx44f::eye(), defaults->raycastStepFactor,
                              0.04f, 64, 5.f, cv::Vec3i::all(defaults->unitResolution));
    const cv::kinfu::Intr intr(static_cast<float>(k.fx), static_cast<float>(k.fy), static_cast<float>(k.cx),
                               static_cast<float>(k.cy));
    const cv::kinfu::Intr half(static_cast<float>(k.fx / 2), static_cast<float>(k.fy / 2),
                               static_cast<float>((k.cx - 0.5) / 2), static_cast<float>((k.cy - 0.5) / 2));
    double integrate_s = 0, raycast_s = 0, raycast_half_s = 0;
    for (int i = 0; i < n; ++i) {
      const cv::Matx44f pose = ToCv(*frames[i].world_from_camera);
      sw.Reset();
      volume->integrate(depth_m[i], 1.f, pose, intr, i);  // float metres: what its hash TSDF takes
      integrate_s += sw.Seconds();
      cv::Mat points, normals;
      sw.Reset();
      volume->raycast(pose, intr, cv::Size(w, h), points, normals);
      raycast_s += sw.Seconds();
      sw.Reset();
      volume->raycast(pose, half, cv::Size(w / 2, h / 2), points, normals);
      raycast_half_s += sw.Seconds();
    }
    std::snprintf(note, sizeof note,
                  "per frame: ICPOdometry %.1f ms (frame to frame, ATE %.1f mm; ours %.1fx its time), hash-TSDF "
                  "integrate %.1f ms (ours %.2fx), raycast %.1f ms full / %.1f ms half size (ours at half %.2fx)",
                  1e3 * odo_s / (n - 1), 1e3 * Ate(chain, frames), (t.track / n) / (odo_s / (n - 1)),
                  1e3 * integrate_s / n, (t.fuse / n) / (integrate_s / n), 1e3 * raycast_s / n,
                  1e3 * raycast_half_s / n, (t.raycast / n) / (raycast_half_s / n));
    row(size, "OpenCV rgbd baseline (same frames)", odo_s + integrate_s + raycast_half_s, 0, NAN, note);
  }

  // Meshing a 3 m room: a 3 x 3 x 2.5 m box scanned by a camera turning on the spot.
  TsdfOptions to;
  TsdfVolume room(to);
  const Intrinsics k{320, 240, 277.1, 277.1, 159.5, 119.5};
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

}  // namespace lp::app
