// Reconstruction against closed forms and ground truth: a sphere fused from analytic depth
// maps, a synthetic room with Xtion-like noise tracked along a known trajectory (trajectory
// error and Chamfer distance to the true surface), real frames with given poses, bad input.
#include <algorithm>
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "capture/frame_source.h"
#include "capture/synth_source.h"
#include "capture/trajectory.h"
#include "common/error.h"
#include "common/rng.h"
#include "estimation/synth.h"
#include "reconstruction/geometry.h"
#include "reconstruction/keyframe_vignetting.h"
#include "reconstruction/reconstruction_run.h"
#include "reconstruction/reconstructor.h"
#include "reconstruction/tsdf_volume.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

const fs::path kAssets = fs::path(LIGHTPROBE_SOURCE_DIR) / "assets";
const fs::path kTestData = fs::path(LIGHTPROBE_SOURCE_DIR) / "tests" / "data";

double Percentile(std::vector<float> v, double q) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[static_cast<std::size_t>(q * (v.size() - 1))];
}

Eigen::Matrix4d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Camera c = Camera::LookAt(eye, target, Eigen::Vector3d::UnitZ(), 4, 4, 60);
  return c.world_from_camera;
}

/// Depth (metres along the axis) of a sphere seen by camera k at pose T; 0 = background.
std::vector<float> SphereDepth(const Camera& k, const Eigen::Matrix4d& T, const Eigen::Vector3d& c, double r) {
  std::vector<float> d(static_cast<std::size_t>(k.width) * k.height, 0.f);
  const Eigen::Vector3d o = T.block<3, 1>(0, 3);
  for (int y = 0; y < k.height; ++y)
    for (int x = 0; x < k.width; ++x) {
      const Eigen::Vector3d ray((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1);
      const Eigen::Vector3d dir = (T.block<3, 3>(0, 0) * ray).normalized();
      const Eigen::Vector3d oc = o - c;
      const double b = oc.dot(dir), disc = b * b - (oc.squaredNorm() - r * r);
      if (disc < 0) continue;
      const double t = -b - std::sqrt(disc);
      if (t > 0) d[static_cast<std::size_t>(y) * k.width + x] = static_cast<float>(t * dir.dot(T.block<3, 1>(0, 2)));
    }
  return d;
}

/// 8 mm voxels, 4 voxels of truncation: the sphere tests' volume.
TsdfOptions SphereVolumeOptions() {
  TsdfOptions o;
  o.voxel = 0.008f;
  o.truncation = 0.032f;
  return o;
}

/// A sphere fused from 8 exact depth maps around it (camera k).
TsdfVolume FusedSphere(const Eigen::Vector3d& centre, double r, const Camera& k) {
  TsdfVolume volume(SphereVolumeOptions());
  for (int i = 0; i < 8; ++i) {
    const double a = 2 * 3.14159265358979 * i / 8;
    const Eigen::Matrix4d T = LookAt(centre + Eigen::Vector3d(std::cos(a), std::sin(a), 0.4 * (i % 2) - 0.2), centre);
    volume.Integrate(SphereDepth(k, T, centre, r), k, nullptr, k, T);
  }
  return volume;
}

// A sphere fused from exact depth maps around it: the mesh lies on the sphere (within a
// fraction of a voxel) with outward normals, and a raycast from a new viewpoint gives the
// sphere's depth.
TEST(TsdfVolume, SphereFromExactDepthMapsMeshesAndRaycastsTheSphere) {
  const Eigen::Vector3d centre(0.1, -0.05, 0.3);
  const double r = 0.25;
  const Camera k{160, 120, 140, 140, 79.5, 59.5};
  const TsdfOptions o = SphereVolumeOptions();
  const TsdfVolume volume = FusedSphere(centre, r, k);
  const Mesh mesh = volume.ExtractMesh(1);
  ASSERT_GT(mesh.triangles.size(), 1000u);
  std::vector<float> off;
  int outward = 0;
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const Eigen::Vector3d p = mesh.positions[v].cast<double>();
    off.push_back(static_cast<float>(std::abs((p - centre).norm() - r)));
    outward += mesh.normals[v].cast<double>().dot(p - centre) > 0;
  }
  std::printf("mesh off the sphere: median %.2f mm, 99th %.2f mm, max %.2f mm\n", 1e3 * Percentile(off, 0.5),
              1e3 * Percentile(off, 0.99), 1e3 * Percentile(off, 1.0));
  EXPECT_LT(Percentile(off, 0.5), 0.1 * o.voxel) << "mesh vertices off the sphere";
  EXPECT_LT(Percentile(off, 0.99), 0.5 * o.voxel) << "mesh vertices off the sphere";
  EXPECT_GT(outward, 0.99 * mesh.positions.size()) << "normals must point to free space";
  // The fused distance is projective (along camera rays): the sign is exact, the size at
  // least the Euclidean distance and at most about twice it here.
  const float out = volume.SignedDistance((centre + Eigen::Vector3d(r + 0.01, 0, 0)).cast<float>());
  const float in = volume.SignedDistance((centre + Eigen::Vector3d(0, r - 0.01, 0)).cast<float>());
  EXPECT_GT(out, 0.009);
  EXPECT_LT(out, 0.02);
  EXPECT_LT(in, -0.009);
  EXPECT_GT(in, -0.02);

  const Eigen::Matrix4d T = LookAt(centre + Eigen::Vector3d(0.7, 0.7, 0.1), centre);
  TsdfVolume::Maps maps;
  volume.Raycast(k, T, &maps);
  const std::vector<float> truth = SphereDepth(k, T, centre, r);
  int hits = 0, both = 0;
  std::vector<float> err;  // away from the rim, where projective fusion is least exact
  for (std::size_t p = 0; p < truth.size(); ++p) {
    if (truth[p] > 0 && maps.depth[p] > 0) {
      ++both;
      const Eigen::Vector3d ray((p % k.width - k.cx) / k.fx, (p / k.width - k.cy) / k.fy, 1);
      const Eigen::Vector3d hit = (T * (ray * truth[p]).homogeneous()).head<3>();
      const Eigen::Vector3d view = (hit - T.block<3, 1>(0, 3)).normalized();
      if (-view.dot((hit - centre) / r) > 0.5) err.push_back(std::abs(truth[p] - maps.depth[p]));
    }
    hits += truth[p] > 0;
  }
  std::printf("raycast depth error (surface within 60 degrees of facing the camera): median %.2f mm, 99th %.2f "
              "mm; %d of %d sphere pixels hit\n",
              1e3 * Percentile(err, 0.5), 1e3 * Percentile(err, 0.99), both, hits);
  EXPECT_GT(both, 0.97 * hits) << "the raycast misses parts of the sphere";
  EXPECT_LT(Percentile(err, 0.5), 0.1 * o.voxel);
  EXPECT_LT(Percentile(err, 0.99), 0.5 * o.voxel);
}

// A raycast guided by a measured depth (tracking's, after fusing that frame) finds what the
// whole search finds: with the true depth it searches only around it, and where the depth
// is wrong (half a metre behind or in front of the surface) it finds nothing there and
// falls back to the whole range.
TEST(TsdfVolume, ARaycastGuidedByAMeasuredDepthFindsWhatTheWholeSearchFinds) {
  const Eigen::Vector3d centre(0.1, -0.05, 0.3);
  const double r = 0.25;
  const Camera k{160, 120, 140, 140, 79.5, 59.5};
  const TsdfVolume volume = FusedSphere(centre, r, k);
  const Eigen::Matrix4d T = LookAt(centre + Eigen::Vector3d(0.7, 0.7, 0.1), centre);
  TsdfVolume::Maps whole;
  volume.Raycast(k, T, &whole);
  const std::vector<float> truth = SphereDepth(k, T, centre, r);
  int hits = 0;
  for (float d : whole.depth) hits += d > 0;
  ASSERT_GT(hits, 1000);
  for (const float shift : {0.f, 0.5f, -0.5f}) {
    std::vector<float> measured = truth;
    for (float& d : measured)
      if (d > 0) d += shift;
    TsdfVolume::Maps guided;
    volume.Raycast(k, T, &guided, false, nullptr, &measured);
    int differ = 0;
    std::vector<float> moved, err_whole, err_guided;  // against the sphere
    for (std::size_t p = 0; p < truth.size(); ++p) {
      if ((whole.depth[p] > 0) != (guided.depth[p] > 0)) ++differ;
      if (!(whole.depth[p] > 0 && guided.depth[p] > 0 && truth[p] > 0)) continue;
      moved.push_back(std::abs(whole.depth[p] - guided.depth[p]));
      err_whole.push_back(std::abs(whole.depth[p] - truth[p]));
      err_guided.push_back(std::abs(guided.depth[p] - truth[p]));
    }
    std::printf("measured depth shifted by %+.1f m: %d pixels hit by one search only; the crossing moved by %.3f mm "
                "at most; from the sphere: median %.3f / 99th %.3f mm guided, %.3f / %.3f mm whole\n",
                shift, differ, 1e3 * Percentile(moved, 1.0), 1e3 * Percentile(err_guided, 0.5),
                1e3 * Percentile(err_guided, 0.99), 1e3 * Percentile(err_whole, 0.5), 1e3 * Percentile(err_whole, 0.99));
    EXPECT_EQ(differ, 0) << "pixels hit by one search only";
    if (shift != 0) {  // nothing found around the measured depth: the whole search, the same crossings
      EXPECT_EQ(Percentile(moved, 1.0), 0.f);
      continue;
    }
    // Starting nearer, a ray brackets the crossing between other steps (one regula falsi
    // step places it within): as close to the sphere as the whole search's.
    const float voxel = SphereVolumeOptions().voxel;
    EXPECT_LT(Percentile(err_guided, 0.5), Percentile(err_whole, 0.5) + 0.01f * voxel);
    EXPECT_LT(Percentile(err_guided, 0.99), Percentile(err_whole, 0.99) + 0.05f * voxel);
  }
}

/// Which paint a point of the painted sphere has: 8 sectors of longitude around the
/// vertical axis through `c`, red and blue in turn (boundaries are meridians, so a colour
/// camera beside the depth camera moves colours across them).
bool RedSector(const Eigen::Vector3d& p, const Eigen::Vector3d& c) {
  const double a = std::atan2(p.y() - c.y(), p.x() - c.x()) + 3.14159265358979;
  return static_cast<int>(std::floor(a / (3.14159265358979 / 4))) % 2 == 0;
}
/// Distance (metres, along the sphere's parallel) from p to the nearest sector boundary.
double SectorBoundaryDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& c) {
  const double a = std::atan2(p.y() - c.y(), p.x() - c.x()) + 3.14159265358979, w = 3.14159265358979 / 4;
  const double f = a / w - std::floor(a / w);
  return std::min(f, 1 - f) * w * std::hypot(p.x() - c.x(), p.y() - c.y());
}

/// Depth of the painted sphere (centre c, radius r) and a green ball (b, rb) in front of
/// it, camera k at pose T.
std::vector<float> TwoSpheresDepth(const Camera& k, const Eigen::Matrix4d& T, const Eigen::Vector3d& c, double r,
                                   const Eigen::Vector3d& b, double rb) {
  std::vector<float> d = SphereDepth(k, T, c, r);
  const std::vector<float> db = SphereDepth(k, T, b, rb);
  for (std::size_t i = 0; i < d.size(); ++i)
    if (db[i] > 0 && (d[i] <= 0 || db[i] < d[i])) d[i] = db[i];
  return d;
}

/// The colour camera's image (linear RGB, black where the rays miss) of the painted sphere
/// (RedSector) and the green ball, the camera at `world_from_color`.
ImageRGB PaintedSpheres(const Camera& k, const Eigen::Matrix4d& world_from_color, const Eigen::Vector3d& c,
                        double r, const Eigen::Vector3d& b, double rb) {
  ImageRGB img(k.width, k.height);
  const std::vector<float> d = TwoSpheresDepth(k, world_from_color, c, r, b, rb);
  for (int y = 0; y < k.height; ++y)
    for (int x = 0; x < k.width; ++x) {
      const float z = d[static_cast<std::size_t>(y) * k.width + x];
      if (z <= 0) continue;
      const Eigen::Vector3d pc((x - k.cx) / k.fx * z, (y - k.cy) / k.fy * z, z);
      const Eigen::Vector3d p = (world_from_color * pc.homogeneous()).head<3>();
      float* px = &img.data[3 * (static_cast<std::size_t>(y) * k.width + x)];
      px[(p - b).norm() < rb + 1e-3 ? 1 : RedSector(p, c) ? 0 : 2] = 0.8f;
    }
  return img;
}

// Unregistered frames (a colour camera 6 cm beside the depth camera, turned 3 degrees):
// with the calibration's colour_from_depth each vertex of a sector-painted sphere takes
// the colour of its own point, and the parts of it a green ball in front hides from the
// colour camera (but not from the depth camera) take no green: colour fusion tests what
// the colour camera sees. Without colour_from_depth the colours come from the wrong place.
TEST(TsdfVolume, UnregisteredColourIsTakenThroughColourFromDepth) {
  const Eigen::Vector3d centre(0.1, -0.05, 0.3), ball = centre + Eigen::Vector3d(0.36, 0.0, 0.0);
  const double r = 0.25, rb = 0.05;
  const Camera k{160, 120, 140, 140, 79.5, 59.5};
  Eigen::Matrix4d color_from_depth = Eigen::Matrix4d::Identity();
  color_from_depth.block<3, 3>(0, 0) = Eigen::AngleAxisd(3 * 3.14159265358979 / 180, Eigen::Vector3d::UnitY()).toRotationMatrix();
  color_from_depth.block<3, 1>(0, 3) = Eigen::Vector3d(-0.06, 0.01, 0);
  struct Outcome {
    double wrong = 0, green = 0;
  };
  auto fuse = [&](bool use_extrinsic) {
    const TsdfOptions o = SphereVolumeOptions();
    TsdfVolume volume(o);
    for (int i = 0; i < 8; ++i) {
      const double a = 2 * 3.14159265358979 * i / 8;
      // Cameras above and below the equator, looking at it from 0.6 m (the first two see
      // the ball in front of the sphere).
      const Eigen::Matrix4d T = LookAt(centre + Eigen::Vector3d(0.6 * std::cos(a), 0.6 * std::sin(a), 0.3 * (i % 2) - 0.15), centre);
      const ImageRGB color = PaintedSpheres(k, T * color_from_depth.inverse(), centre, r, ball, rb);
      volume.Integrate(TwoSpheresDepth(k, T, centre, r, ball, rb), k, &color, k, T,
                       use_extrinsic ? &color_from_depth : nullptr);
    }
    const Mesh mesh = volume.ExtractMesh(1);
    int checked = 0, wrong = 0, green = 0;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      const Eigen::Vector3d p = mesh.positions[v].cast<double>();
      if (std::abs((p - centre).norm() - r) > 0.5 * o.voxel || (p - ball).norm() < rb + 4 * o.voxel) continue;  // the sphere only
      if (SectorBoundaryDistance(p, centre) < 2 * o.voxel) continue;  // the boundary itself is a blend
      const Eigen::Vector3f& c = mesh.albedo[v];
      if ((c.array() - 0.5f).abs().maxCoeff() < 1e-3f || c.maxCoeff() < 0.05f) continue;  // never coloured (grey) or only background
      ++checked;
      green += c.y() > 0.1f;
      wrong += RedSector(p, centre) ? !(c.x() > 2 * std::max(c.y(), c.z())) : !(c.z() > 2 * std::max(c.x(), c.y()));
    }
    EXPECT_GT(checked, 1000);
    return Outcome{static_cast<double>(wrong) / std::max(1, checked), static_cast<double>(green) / std::max(1, checked)};
  };
  const Outcome with = fuse(true), without = fuse(false);
  std::printf("sphere vertices with the wrong colour: %.2f %% (%.2f %% with green) through colour_from_depth, "
              "%.2f %% without\n", 100 * with.wrong, 100 * with.green, 100 * without.wrong);
  EXPECT_LT(with.wrong, 0.003);
  EXPECT_LT(with.green, 0.001);
  EXPECT_GT(without.wrong, 0.1);
}

/// `n` frames of synth's one-light room at 160 x 120, one sample per pixel.
std::vector<RgbdFrame> SmallOneLightFrames(int n) {
  SynthOptions so;
  so.width = 160;
  so.height = 120;
  so.spp = 1;
  return ToRgbdFrames(RenderSynthFrames("one-light", so, "", n));
}

// Given poses go with the source's frame index, not with the count of frames processed: a
// live run (--headless --live) drops the frames it is too busy for, and a frame fused with
// the pose of the one before it would double every wall.
TEST(ReconstructionRun, AGivenPoseIsTheFramesOwnWhenFramesWereSkipped) {
  std::vector<RgbdFrame> frames = SmallOneLightFrames(6);
  ReconstructionRunOptions o;
  o.reconstruction.tsdf.truncation = 4 * o.reconstruction.tsdf.voxel;
  o.reconstruction.use_source_poses = true;
  for (const RgbdFrame& f : frames) o.poses.push_back(*f.world_from_camera);
  o.poses_name = "poses";
  ReconstructionRun run(o);
  for (int k : {0, 2, 5}) {
    RgbdFrame f = frames.at(k);
    f.world_from_camera.reset();  // the given poses only
    const FrameReport r = run.Process(f);
    EXPECT_LT((r.world_from_camera - o.poses[k]).norm(), 1e-9) << "frame " << k;
  }
  EXPECT_GT((o.poses[5] - o.poses[3]).norm(), 1e-3) << "the poses differ, so the test can fail";
  RgbdFrame beyond = frames.at(5);
  beyond.index = 6;
  EXPECT_THROW(run.Process(beyond), InputError);
}

// Unregistered depth from a device whose factory transform the source knows (an OpenNI
// recording or camera: capture/openni_runtime.cpp) is fused through that transform, with a
// warning naming it; a calibration's extrinsics win; without either, the old warning.
TEST(ReconstructionRun, UnregisteredDepthTakesTheDevicesFactoryTransformUnlessCalibrated) {
  std::vector<RgbdFrame> frames = SmallOneLightFrames(1);
  Eigen::Matrix4d factory = Eigen::Matrix4d::Identity();
  factory(0, 3) = -0.025;
  RgbdFrame f = frames.at(0);
  f.registered = false;
  f.device_extrinsics = RgbdFrame::Extrinsics{factory, "a test device's 2.5 cm"};
  auto run_with = [&](std::optional<Eigen::Matrix4d> calibrated, const RgbdFrame& frame) {
    ReconstructionRunOptions o;
    o.reconstruction.tsdf.truncation = 4 * o.reconstruction.tsdf.voxel;
    o.reconstruction.calibration.color_from_depth = calibrated;
    auto run = std::make_unique<ReconstructionRun>(o);
    run->Process(frame);
    return run;
  };
  auto warned = [](const ReconstructionRun& r, const std::string& what) {
    for (const std::string& w : r.warnings())
      if (w.find(what) != std::string::npos) return true;
    return false;
  };
  const auto factory_run = run_with(std::nullopt, f);
  ASSERT_TRUE(factory_run->options().calibration.color_from_depth);
  EXPECT_EQ((*factory_run->options().calibration.color_from_depth)(0, 3), -0.025);
  EXPECT_TRUE(warned(*factory_run, "using the device's factory transform, a test device's 2.5 cm"));
  Eigen::Matrix4d measured = Eigen::Matrix4d::Identity();
  measured(0, 3) = -0.031;
  const auto calibrated_run = run_with(measured, f);
  EXPECT_EQ((*calibrated_run->options().calibration.color_from_depth)(0, 3), -0.031);
  EXPECT_TRUE(calibrated_run->warnings().empty() || !warned(*calibrated_run, "not registered"));
  RgbdFrame unknown = f;
  unknown.device_extrinsics.reset();
  const auto unknown_run = run_with(std::nullopt, unknown);
  EXPECT_FALSE(unknown_run->options().calibration.color_from_depth);
  EXPECT_TRUE(warned(*unknown_run, "colour is taken from the depth camera's view"));
}

/// Points spread over a mesh's triangles, about `spacing` apart.
std::vector<Eigen::Vector3f> SampleSurface(const Mesh& m, double spacing) {
  std::vector<Eigen::Vector3f> out;
  Rng rng(5);
  for (const Eigen::Vector3i& t : m.triangles) {
    const Eigen::Vector3f a = m.positions[t[0]], b = m.positions[t[1]], c = m.positions[t[2]];
    const double area = 0.5 * (b - a).cross(c - a).norm();
    const double expected = area / (spacing * spacing);
    int n = static_cast<int>(expected);
    if (rng.Uniform() < expected - n) ++n;
    for (int i = 0; i < n; ++i) {
      float u = static_cast<float>(rng.Uniform()), v = static_cast<float>(rng.Uniform());
      if (u + v > 1) {
        u = 1 - u;
        v = 1 - v;
      }
      out.push_back(a + u * (b - a) + v * (c - a));
    }
  }
  return out;
}


// The synthetic room corner (boxes and a sphere, ~3.5 m away) with Xtion-like depth noise
// (sigma ~2 cm at that range) and holes, tracked along its true 40-degree arc.
struct Tracked {
  int frames = 0, tracked = 0;
  double ate = 0;  ///< metres, against the frames' own poses
};

/// Runs `frames` (each with its true pose) through `rec`.
Tracked Track(Reconstructor& rec, const std::vector<RgbdFrame>& frames) {
  Tracked t;
  std::vector<Eigen::Matrix4d> estimated, truth;
  for (const RgbdFrame& f : frames) {
    const FrameReport r = rec.Process(f);
    t.tracked += r.state == TrackingState::kTracking;
    estimated.push_back(r.world_from_camera);
    truth.push_back(*f.world_from_camera);
  }
  t.frames = static_cast<int>(frames.size());
  t.ate = PositionRmse(estimated, truth);
  return t;
}

std::vector<RgbdFrame> ReadFrames(const fs::path& dir) {
  auto src = OpenDirectorySource(dir.string());
  std::vector<RgbdFrame> frames;
  RgbdFrame f;
  while (src->Next(&f) == SourceStatus::kFrame) frames.push_back(f);
  return frames;
}

class SyntheticRoom : public ::testing::TestWithParam<int> {};

TEST_P(SyntheticRoom, TrackedAlongItsTrueTrajectory) {
  SynthOptions so;
  so.width = 320;
  so.height = 240;
  so.spp = 1;
  so.depth_noise = true;
  const std::vector<RgbdFrame> frames = ToRgbdFrames(RenderSynthFrames("one-light", so, "", 24));
  ReconstructionOptions o;
  o.fuse_every = GetParam();
  Reconstructor rec(o);
  const Tracked run = Track(rec, frames);
  const int tracked = run.tracked;
  const double ate = run.ate;
  const SceneBundle b = rec.Finish();
  // Accuracy: reconstructed surface to the true one; completeness: true surface seen in
  // the first frame to the reconstruction.
  SynthOptions one = so;
  one.depth_noise = false;
  const Mesh truth = MakeSynth("one-light", one, "").bundle.mesh;
  const std::vector<float> acc = NearestDistances(b.mesh.positions, SampleSurface(truth, 0.005));
  std::vector<Eigen::Vector3f> seen;
  {
    const auto exact = RenderSynthFrames("one-light", one, "", 1);
    const Camera& c = exact[0].camera;
    for (int y = 0; y < c.height; y += 2)
      for (int x = 0; x < c.width; x += 2) {
        const float z = exact[0].depth[static_cast<std::size_t>(y) * c.width + x];
        if (z <= 0) continue;
        const Eigen::Vector3d ray((x - c.cx) / c.fx, (y - c.cy) / c.fy, 1);
        seen.push_back((c.world_from_camera * (ray * z).homogeneous()).head<3>().cast<float>());
      }
  }
  const std::vector<float> comp = NearestDistances(seen, b.mesh.positions);
  const double complete = std::count_if(comp.begin(), comp.end(), [](float d) { return d < 0.02f; }) /
                          static_cast<double>(comp.size());
  // Chamfer distance: the mean of both directions' mean nearest distances.
  double acc_mean = 0, comp_mean = 0;
  for (float d : acc) acc_mean += d / acc.size();
  for (float d : comp) comp_mean += d / comp.size();
  const double chamfer = 0.5 * (acc_mean + comp_mean);
  std::printf("fusing every %d: tracked %d/%zu, ATE %.1f mm; accuracy median %.1f mm, 90th %.1f mm; complete (2 cm) "
              "%.1f %%; Chamfer %.1f mm; up (%.3f %.3f %.3f)\n",
              GetParam(), tracked, frames.size(), 1e3 * ate, 1e3 * Percentile(acc, 0.5), 1e3 * Percentile(acc, 0.9),
              100 * complete, 1e3 * chamfer, b.up.x(), b.up.y(), b.up.z());
  EXPECT_LT(chamfer, 0.01);
  EXPECT_EQ(tracked, static_cast<int>(frames.size()));
  EXPECT_LT(ate, 0.02);
  EXPECT_LT(Percentile(acc, 0.5), 0.006);
  EXPECT_LT(Percentile(acc, 0.9), 0.02);
  EXPECT_GT(complete, 0.9);
  EXPECT_GT(b.up.dot(Eigen::Vector3d::UnitZ()), std::cos(2 * 3.14159265358979 / 180)) << "the floor is z = 0";
  ASSERT_EQ(b.views.size(), 4u);
  for (const View& v : b.views) {
    const long valid = std::count(v.valid.begin(), v.valid.end(), 1);
    EXPECT_GT(valid, 0.5 * v.valid.size());
  }
}

// Every frame fused, and every second frame (all tracked): the same bounds.
INSTANTIATE_TEST_SUITE_P(FuseEvery, SyntheticRoom, ::testing::Values(1, 2));

/// A registered pinhole frame as a camera with radial distortion k1 (OpenCV's model)
/// delivers it: colour and depth both on the distorted grid (nearest neighbour), the
/// pinhole intrinsics still reported.
RgbdFrame Distort(const RgbdFrame& f, double k1) {
  RgbdFrame out = f;
  const Camera& k = f.color_intrinsics;
  std::fill(out.depth.data.begin(), out.depth.data.end(), 0);
  std::fill(out.color.data.begin(), out.color.data.end(), 0);
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const double xd = (u - k.cx) / k.fx, yd = (v - k.cy) / k.fy;
      double xu = xd, yu = yd;  // x_d = x_u (1 + k1 r_u^2), solved by fixed point
      for (int it = 0; it < 50; ++it) {
        const double s = 1 + k1 * (xu * xu + yu * yu);
        xu = xd / s;
        yu = yd / s;
      }
      const int su = static_cast<int>(std::lround(k.fx * xu + k.cx)), sv = static_cast<int>(std::lround(k.fy * yu + k.cy));
      if (su < 0 || sv < 0 || su >= k.width || sv >= k.height) continue;
      const std::size_t d = static_cast<std::size_t>(v) * k.width + u, src = static_cast<std::size_t>(sv) * k.width + su;
      out.depth.data[d] = f.depth.data[src];
      for (int c = 0; c < 3; ++c) out.color.data[3 * d + c] = f.color.data[3 * src + c];
    }
  return out;
}

// A calibrated colour camera with lens distortion and depth registered to it: the depth is
// undistorted with the colour, so the room keeps its shape; back-projected as delivered,
// the walls bend (the reconstruction's accuracy against the true room, fused at the true
// poses so only the geometry differs).
/// The synthetic room's 16 frames (320x240, Xtion-like depth noise) along its arc, frames
/// [from, to) with their depth's right half 8 cm farther (a glitch no pose fits all of).
std::vector<RgbdFrame> GlitchedRoom(int from, int to) {
  SynthOptions so;
  so.width = 320;
  so.height = 240;
  so.spp = 1;
  so.depth_noise = true;
  std::vector<RgbdFrame> frames = ToRgbdFrames(RenderSynthFrames("one-light", so, "", 16));
  for (int k = from; k < to; ++k) {
    DepthImage& d = frames[k].depth;
    for (int y = 0; y < d.height; ++y)
      for (int x = d.width / 2; x < d.width; ++x) {
        std::uint16_t& z = d.data[static_cast<std::size_t>(y) * d.width + x];
        if (z > 0) z = static_cast<std::uint16_t>(z + 80);
      }
  }
  return frames;
}

TEST(Reconstruction, AFrameWhoseFitIsDoubtfulIsNotFused) {
  // The synthetic room along its arc; one frame's depth glitches: its right half 8 cm
  // farther (no pose fits all of it, and ICP still finds one that fits most). That frame's
  // fit is doubtful beside those fused before it (its ICP error or its inlier ratio), so it
  // is not fused; every other frame is, and the track goes on as without it.
  constexpr int kBad = 8;
  const std::vector<RgbdFrame> frames = GlitchedRoom(kBad, kBad + 1);
  ReconstructionOptions o;
  o.fuse_every = 1;
  Reconstructor rec(o);
  std::vector<FrameReport> reports;
  for (const RgbdFrame& f : frames) reports.push_back(rec.Process(f));
  for (const FrameReport& r : reports) {
    std::printf("frame %lld: inliers %.3f, ICP error %.2f mm, %s%s\n", static_cast<long long>(r.index),
                r.inlier_ratio, 1e3 * r.rmse, r.doubtful ? "doubtful: " : "", r.reason.c_str());
    ASSERT_EQ(r.state, TrackingState::kTracking) << r.index;
    EXPECT_EQ(r.doubtful, r.index == kBad) << r.index << ": " << r.reason;
    EXPECT_EQ(r.blocks_updated == 0, r.index == kBad) << r.index;
  }
  EXPECT_NE(reports[kBad].reason.find("doubtful fit"), std::string::npos);
  EXPECT_EQ(reports[kBad].reason.find(','), std::string::npos) << "a reason is one CSV field";
  // Without the rule (a doubtful frame is one whose ICP error is a million times the
  // median), the glitch is fused.
  o.doubtful_error = 1e6f;
  o.doubtful_inliers = 0;
  Reconstructor trusting(o);
  for (const RgbdFrame& f : frames) {
    const FrameReport r = trusting.Process(f);
    if (r.index == kBad) {
      EXPECT_GT(r.blocks_updated, 0u);
    }
  }
}

TEST(Reconstruction, ALastingChangeIsDoubtfulOnlyForMaxDoubtfulFramesThenFused) {
  // From frame 8 on, every frame's right half is 8 cm farther (the scene changed for good,
  // or the depth camera's calibration did): the first max_doubtful such frames are left
  // out, then the fit is the new normal and fusing goes on (a rule that never gave in
  // would stop the reconstruction).
  const std::vector<RgbdFrame> frames = GlitchedRoom(8, 16);
  ReconstructionOptions o;
  o.fuse_every = 1;
  Reconstructor rec(o);
  int doubtful = 0, fused_after = 0;
  for (const RgbdFrame& f : frames) {
    const FrameReport r = rec.Process(f);
    doubtful += r.doubtful;
    if (r.index >= 8 && !r.doubtful && r.blocks_updated > 0) ++fused_after;
    if (r.index >= 8 && r.index < 8 + o.max_doubtful) {
      EXPECT_TRUE(r.doubtful) << r.index << ": " << r.reason;
    }
  }
  EXPECT_LE(doubtful, o.max_doubtful + 1) << "left out past the new normal";
  EXPECT_GE(fused_after, 3) << "fusing went on after the change";
}

TEST(Reconstruction, RegisteredDepthIsUndistortedWithTheColour) {
  SynthOptions so;
  so.width = 320;
  so.height = 240;
  so.spp = 1;
  const double k1 = -0.2;  // barrel: 7 pixels at the corners of this 320x240 view
  std::vector<RgbdFrame> frames = ToRgbdFrames(RenderSynthFrames("one-light", so, "", 8));
  for (RgbdFrame& f : frames) {
    ASSERT_TRUE(f.registered);
    f = Distort(f, k1);
  }
  const Mesh truth = MakeSynth("one-light", so, "").bundle.mesh;
  const std::vector<Eigen::Vector3f> truth_points = SampleSurface(truth, 0.005);
  auto accuracy = [&](bool calibrated) {
    ReconstructionOptions o;
    o.use_source_poses = true;
    o.fuse_every = 1;
    o.smooth_iterations = 0;
    if (calibrated) {
      const Camera& k = frames[0].color_intrinsics;
      o.calibration.color = CameraModel{k, {k1, 0, 0, 0, 0}};
    }
    Reconstructor rec(o);
    for (const RgbdFrame& f : frames) rec.Process(f);
    const std::vector<float> acc = NearestDistances(rec.Finish().mesh.positions, truth_points);
    return std::make_pair(Percentile(acc, 0.5), Percentile(acc, 0.9));
  };
  const auto [with_median, with_p90] = accuracy(true);
  const auto [as_delivered_median, as_delivered_p90] = accuracy(false);
  std::printf("reconstructed surface to the true room: median %.1f / 90th %.1f mm undistorted, %.1f / %.1f mm as "
              "delivered\n",
              1e3 * with_median, 1e3 * with_p90, 1e3 * as_delivered_median, 1e3 * as_delivered_p90);
  EXPECT_LT(with_median, 0.004);
  EXPECT_LT(with_p90, 0.012);
  EXPECT_GT(as_delivered_p90, 2 * with_p90);
}

// Real Redwood frames (PrimeSense, 640x480) tracked against the dataset's trajectory.
TEST(Reconstruction, RedwoodFramesAgainstTheirTrajectory) {
  const fs::path dir = kAssets / "rgbd" / "redwood_open3d" / "RGBD";
  Reconstructor rec(ReconstructionOptions{});
  const Tracked run = Track(rec, ReadFrames(dir));
  const int tracked = run.tracked, n = run.frames;
  const double ate = run.ate;
  std::printf("Redwood: %d/%d tracked, ATE %.1f mm\n", tracked, n, 1e3 * ate);
  EXPECT_EQ(tracked, n);
  EXPECT_LT(ate, 0.01);
  EXPECT_GT(rec.Finish().mesh.triangles.size(), 10000u);
}

// Real joinMap frames (slambook): 0.2-0.7 m and up to 25 degrees between consecutive frames,
// far beyond what frame-to-model ICP from the last pose can bridge; colour features
// (Relocalizer) give the starting pose, ICP refines it.
TEST(Reconstruction, JoinMapLargeMotionsTrackedWithRelocalization) {
  const fs::path dir = kTestData / "rgbd" / "joinmap_slambook";
  const std::vector<RgbdFrame> frames = ReadFrames(dir);
  for (bool relocalize : {false, true}) {
    ReconstructionOptions o;
    o.relocalize = relocalize;
    Reconstructor rec(o);
    const Tracked run = Track(rec, frames);
    const int tracked = run.tracked, n = run.frames;
    const double ate = run.ate;
    std::printf("joinMap, relocalization %s: %d/%d tracked, ATE %.1f mm\n", relocalize ? "on" : "off", tracked, n,
                1e3 * ate);
    if (!relocalize) {
      EXPECT_LT(tracked, n) << "ICP alone should not bridge these motions (else this test shows nothing)";
      continue;
    }
    EXPECT_EQ(tracked, n);
    EXPECT_LT(ate, 0.15);
  }
}

RgbdFrame FlatFrame(int w, int h, std::uint16_t mm) {
  RgbdFrame f;
  f.depth = {w, h, std::vector<std::uint16_t>(static_cast<std::size_t>(w) * h, mm)};
  f.color = {w, h, std::vector<std::uint8_t>(static_cast<std::size_t>(w) * h * 3, 128)};
  f.depth_intrinsics = f.color_intrinsics = {w, h, 0.9 * w, 0.9 * w, 0.5 * w - 0.5, 0.5 * h - 0.5};
  f.registered = true;
  return f;
}

// The viewer's Estimate takes a snapshot between frames and finishes it on another thread
// while frames go on: the snapshot must be the reconstruction as it was, not as it becomes.
TEST(Reconstruction, SnapshotFinishesAsTheReconstructionWasWhenTaken) {
  SynthOptions so;
  so.width = 160;
  so.height = 120;
  so.spp = 1;
  const std::vector<RgbdFrame> frames = ToRgbdFrames(RenderSynthFrames("one-light", so, "", 12));
  ReconstructionOptions o;
  o.keyframes = 2;
  Reconstructor rec(o);
  for (int i = 0; i < 6; ++i) rec.Process(frames[i]);
  const SceneBundle then = rec.Finish();
  const ReconstructionSnapshot snapshot = rec.Snapshot();
  for (int i = 6; i < 12; ++i) rec.Process(frames[i]);
  const SceneBundle later = rec.Finish();
  const SceneBundle finished = snapshot.Finish();
  ASSERT_EQ(finished.mesh.positions.size(), then.mesh.positions.size());
  EXPECT_EQ(finished.mesh.positions, then.mesh.positions);
  EXPECT_EQ(finished.mesh.albedo, then.mesh.albedo);
  EXPECT_EQ(finished.up, then.up);
  ASSERT_EQ(finished.views.size(), then.views.size());
  for (std::size_t k = 0; k < then.views.size(); ++k) {
    EXPECT_EQ(finished.views[k].image.data, then.views[k].image.data);
    EXPECT_EQ(finished.views[k].valid, then.views[k].valid);
    EXPECT_EQ(finished.views[k].camera.world_from_camera, then.views[k].camera.world_from_camera);
  }
  // The frames after the snapshot did change the reconstruction.
  EXPECT_NE(later.mesh.positions.size(), then.mesh.positions.size());
  // A live estimate cancelled while its snapshot finishes stops between the steps: asked
  // after the first, it throws Cancelled; never asked, the bundle is the same.
  int polls = 0;
  EXPECT_THROW(snapshot.Finish([&] { return ++polls >= 2; }), Cancelled);
  EXPECT_EQ(polls, 2);
  EXPECT_EQ(snapshot.Finish([] { return false; }).mesh.positions, then.mesh.positions);
  // Nothing fused yet: the snapshot's Finish is the same clear error.
  Reconstructor empty(ReconstructionOptions{});
  EXPECT_THROW(empty.Snapshot().Finish(), InputError);
}

TEST(Reconstruction, BadInputIsAClearError) {
  {  // all-zero depth: nothing to fuse
    Reconstructor rec(ReconstructionOptions{});
    for (int i = 0; i < 3; ++i) EXPECT_EQ(rec.Process(FlatFrame(64, 48, 0)).state, TrackingState::kWaiting);
    EXPECT_THROW(rec.Finish(), InputError);
    EXPECT_THROW(rec.Snapshot().Finish(), InputError);
  }
  {  // a frame of another size mid-stream
    Reconstructor rec(ReconstructionOptions{});
    rec.Process(FlatFrame(64, 48, 1000));
    try {
      rec.Process(FlatFrame(32, 24, 1000));
      ADD_FAILURE() << "a frame of another size was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("differs from the first frame"), std::string::npos) << e.what();
    }
  }
  {  // NaN intrinsics, and depth that does not match its intrinsics
    Reconstructor rec(ReconstructionOptions{});
    RgbdFrame f = FlatFrame(64, 48, 1000);
    f.depth_intrinsics.fx = std::nan("");
    EXPECT_THROW(rec.Process(f), InputError);
    f = FlatFrame(64, 48, 1000);
    f.depth.data.resize(10);
    EXPECT_THROW(rec.Process(f), InputError);
  }
  {  // a given pose that is not a rigid transform
    Reconstructor rec(ReconstructionOptions{});
    RgbdFrame f = FlatFrame(64, 48, 1000);
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T(0, 0) = 2;  // a scale, not a rotation
    f.world_from_camera = T;
    EXPECT_THROW(rec.Process(f), InputError);
    T(0, 0) = std::nan("");
    f.world_from_camera = T;
    EXPECT_THROW(rec.Process(f), InputError);
  }
  {  // a flat wall fixes only 3 of the 6 pose directions: ICP says degenerate, not a guess
    ReconstructionOptions o;
    o.relocalize = false;
    Reconstructor rec(o);
    EXPECT_EQ(rec.Process(FlatFrame(64, 48, 1000)).state, TrackingState::kTracking);
    const FrameReport r = rec.Process(FlatFrame(64, 48, 1000));
    EXPECT_EQ(r.state, TrackingState::kLost);
    EXPECT_NE(r.reason.find("degenerate"), std::string::npos) << r.reason;
  }
  ReconstructionOptions bad;
  bad.tsdf.voxel = 0;
  EXPECT_THROW(Reconstructor{bad}, InputError);
}

// Vignetting from keyframes: a synthetic scene's two views (different viewpoints) with a
// known vignetting applied; the same surface points seen at different radii give it back.
/// Points of a 4 x 4 m room's horizontal plane at height `z` (none when NaN) and of its
/// four walls up to 2.5 m (every `step` metres), with 2 mm of noise.
std::vector<Eigen::Vector3f> RoomPoints(double z, bool with_walls, double step = 0.04) {
  std::vector<Eigen::Vector3f> p;
  Rng rng(7, 1, 2, 3);
  const auto noise = [&] { return static_cast<float>(0.004 * (rng.Uniform() - 0.5)); };
  if (!std::isnan(z))
    for (double a = -2; a <= 2; a += step)
      for (double b = -2; b <= 2; b += step) p.emplace_back(a + noise(), b + noise(), z + noise());
  if (with_walls)
    for (double a = -2; a <= 2; a += step)
      for (double h = 0; h <= 2.5; h += step) {
        p.emplace_back(a, -2 + noise(), h);
        p.emplace_back(a, 2 + noise(), h);
        p.emplace_back(-2 + noise(), a, h);
        p.emplace_back(2 + noise(), a, h);
      }
  return p;
}

TEST(DominantPlane, UpFromAFloorOrACeilingPointsUpTheCamerasWay) {
  // The camera's own -y, tilted 20 degrees from the true up (a hand-held camera looking
  // down or up): the plane's normal is turned to its side, not towards the camera, so a
  // ceiling above the camera gives up too (turned towards the camera it pointed down).
  const double t = 20 * 3.14159265358979 / 180;
  for (const Eigen::Vector3d& rough : {Eigen::Vector3d(std::sin(t), 0, std::cos(t)), Eigen::Vector3d(0, -std::sin(t), std::cos(t))}) {
    for (const double z : {0.0, 2.5}) {  // a floor below the camera (at 1.4 m), a ceiling above it
      const std::optional<Plane> plane = DominantPlane(RoomPoints(z, true), rough, 30, 0.02);
      ASSERT_TRUE(plane.has_value()) << "z " << z;
      EXPECT_GT(plane->normal.z(), std::cos(1 * 3.14159265358979 / 180)) << "z " << z << ": " << plane->normal.transpose();
      EXPECT_NEAR(plane->normal.dot(Eigen::Vector3d(0, 0, z)) + plane->d, 0, 0.01) << "the plane holds z = " << z;
    }
    // Held upside down (its -y pointing down), the camera's side wins: down.
    const std::optional<Plane> flipped = DominantPlane(RoomPoints(2.5, true), -rough, 30, 0.02);
    ASSERT_TRUE(flipped.has_value());
    EXPECT_LT(flipped->normal.z(), -0.99);
  }
  // Only walls: no horizontal plane within 30 degrees.
  EXPECT_FALSE(DominantPlane(RoomPoints(NAN, true), Eigen::Vector3d::UnitZ(), 30, 0.02).has_value());
}

TEST(KeyframeVignetting, SurfacePointsSeenTwiceRecoverTheVignetting) {
  SynthOptions so;
  so.width = 160;
  so.height = 120;
  so.spp = 256;
  so.held_out_views = 1;
  SceneBundle b = MakeSynth("one-light", so, "").bundle;
  Vignetting truth;
  truth.a = -0.3;
  truth.b = 0.1;
  truth.c = -0.05;
  for (View& v : b.views)
    for (int y = 0; y < v.camera.height; ++y)
      for (int x = 0; x < v.camera.width; ++x)
        for (int ch = 0; ch < 3; ++ch)
          v.image.at(x, y)[ch] *= static_cast<float>(truth.At(x, y, v.camera.width, v.camera.height));
  const std::vector<VignettingPair> pairs = KeyframeVignettingPairs(b);
  const Vignetting fit = FitVignettingPairs(pairs);
  double worst = 0;
  for (int y = 0; y < 120; y += 4)
    for (int x = 0; x < 160; x += 4) worst = std::max(worst, std::abs(fit.At(x, y, 160, 120) / truth.At(x, y, 160, 120) - 1));
  std::printf("keyframe vignetting: %zu pairs, worst error of V %.2f %% (a %.3f b %.3f c %.3f)\n", pairs.size(),
              100 * worst, fit.a, fit.b, fit.c);
  EXPECT_GT(pairs.size(), 500u);
  EXPECT_LT(worst, 0.02) << "render noise (256 spp) limits this";
}

}  // namespace
}  // namespace lp
