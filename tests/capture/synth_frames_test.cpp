// Synthetic RGB-D frames with true poses: depth matches the closed-form floor, and a frame
// directory written by capture/ reads back exactly (poses, intrinsics, depth, colour).
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "capture/frame_source.h"
#include "common/error.h"
#include "estimation/synth.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

SynthOptions Tiny(int w, int h) {
  SynthOptions o;
  o.width = w;
  o.height = h;
  o.spp = 4;
  return o;
}

TEST(SynthFrames, DepthIsTheDistanceAlongTheOpticalAxis) {
  const SynthOptions o = Tiny(48, 36);
  const auto frames = RenderSynthFrames("one-light", o, "", 3);
  ASSERT_EQ(frames.size(), 3u);
  for (const SynthFrame& f : frames) {
    // The bottom-centre pixel sees the floor (z = 0): closed-form depth.
    const Camera& c = f.camera;
    const int x = c.width / 2, y = c.height - 1;
    const Eigen::Vector3d d = c.RayDirection(x, y), axis = c.world_from_camera.block<3, 1>(0, 2);
    const double t = -c.center().z() / d.z();
    ASSERT_GT(t, 0);
    EXPECT_NEAR(f.depth[static_cast<std::size_t>(y) * c.width + x], t * d.dot(axis), 1e-4);
  }
  // The arc turns about the up axis: same height, different positions.
  EXPECT_NEAR(frames[0].camera.center().z(), frames[2].camera.center().z(), 1e-9);
  EXPECT_GT((frames[0].camera.center() - frames[2].camera.center()).norm(), 0.5);
  EXPECT_THROW(RenderSynthFrames("env-studio", o, "", 2), InputError);  // its HDR map is not in ""
}

// Sensor-like depth: noise of the stated size about the exact depth, and holes.
TEST(SynthFrames, DepthNoiseHasTheStatedSizeAndHoles) {
  SynthOptions o = Tiny(80, 60);
  const auto exact = RenderSynthFrames("one-light", o, "", 2);
  o.depth_noise = true;
  const auto noisy = RenderSynthFrames("one-light", o, "", 2);
  double sum2 = 0, n = 0, holes = 0, covered = 0;
  for (std::size_t k = 0; k < exact.size(); ++k)
    for (std::size_t p = 0; p < exact[k].depth.size(); ++p) {
      const double z = exact[k].depth[p], zn = noisy[k].depth[p];
      if (z <= 0) {
        EXPECT_EQ(zn, 0);
        continue;
      }
      ++covered;
      if (zn == 0) {
        ++holes;
        continue;
      }
      const double sigma = 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
      sum2 += (zn - z) * (zn - z) / (sigma * sigma);
      ++n;
    }
  ASSERT_GT(n, 1000);
  EXPECT_NEAR(std::sqrt(sum2 / n), 1.0, 0.1) << "normalized depth error should be a unit Gaussian";
  EXPECT_GT(holes / covered, 0.005);
  EXPECT_LT(holes / covered, 0.2);
}

// The HDR-map scenes have frames too: the middle of a 1-frame arc is the bundle's first
// view, rendered the same way (map integrated over a fine grid, same seed).
TEST(SynthFrames, HdrMapSceneFramesMatchTheBundleRender) {
  const fs::path data = fs::path(LIGHTPROBE_SOURCE_DIR) / "assets";
  const SynthOptions o = Tiny(32, 24);
  const auto frames = RenderSynthFrames("env-sunset", o, data, 1);
  const SynthScene scene = MakeSynth("env-sunset", o, data);
  ASSERT_EQ(frames.size(), 1u);
  const ImageRGB& a = frames[0].color;
  const ImageRGB& b = scene.bundle.views[0].image;
  ASSERT_EQ(a.data.size(), b.data.size());
  double sum = 0, diff = 0;
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    ASSERT_TRUE(std::isfinite(a.data[i]));
    sum += b.data[i];
    diff += std::abs(a.data[i] - b.data[i]);
  }
  EXPECT_GT(sum, 0);
  EXPECT_LT(diff / sum, 1e-6);
}

// A clone is complete by itself: every scene `synth --list` names builds from the repository's
// own assets (the HDR maps and the real mesh included) and has a finite, non-black image.
TEST(SynthFrames, EverySceneBuildsFromTheBundledAssets) {
  const fs::path assets = fs::path(LIGHTPROBE_SOURCE_DIR) / "assets";
  SynthOptions o = Tiny(16, 12);
  o.spp = 2;
  for (const auto& [name, about] : SynthSceneList()) {
    const SceneBundle b = MakeSynthScene(name, o, assets);
    ASSERT_EQ(b.views.size(), 1u) << name;
    double sum = 0;
    for (float v : b.views[0].image.data) {
      ASSERT_TRUE(std::isfinite(v)) << name;
      sum += v;
    }
    EXPECT_GT(sum, 0) << name;
    EXPECT_GT(b.mesh.triangles.size(), 100u) << name;
  }
}

TEST(SynthFrames, FrameDirectoryRoundTrip) {
  const SynthOptions o = Tiny(40, 30);
  const auto synth = RenderSynthFrames("two-light", o, "", 2);
  std::vector<RgbdFrame> frames;
  for (const SynthFrame& s : synth) {
    RgbdFrame f;
    f.color = {s.color.width, s.color.height, std::vector<std::uint8_t>(s.color.pixels() * 3)};
    for (std::size_t i = 0; i < f.color.data.size(); ++i)
      f.color.data[i] = static_cast<std::uint8_t>(std::min(255.f, 255 * s.color.data[i]));
    f.depth = {s.color.width, s.color.height, std::vector<std::uint16_t>(s.depth.size())};
    for (std::size_t i = 0; i < s.depth.size(); ++i) f.depth.data[i] = static_cast<std::uint16_t>(s.depth[i] * 1000);
    const Camera& c = s.camera;
    f.color_intrinsics = f.depth_intrinsics = c.Intrinsics();
    f.registered = true;
    f.world_from_camera = c.world_from_camera;
    frames.push_back(f);
  }
  const fs::path dir = fs::temp_directory_path() / ("lp_synth_frames_" + std::to_string(::getpid()));
  WriteFrameDirectory(dir.string(), frames);
  auto src = OpenDirectorySource(dir.string());
  ASSERT_EQ(src->FrameCount(), 2);
  for (const RgbdFrame& want : frames) {
    RgbdFrame got;
    ASSERT_EQ(src->Next(&got), SourceStatus::kFrame);
    EXPECT_EQ(got.depth.data, want.depth.data);
    EXPECT_EQ(got.color.data, want.color.data);
    EXPECT_DOUBLE_EQ(got.color_intrinsics.fx, want.color_intrinsics.fx);
    EXPECT_DOUBLE_EQ(got.color_intrinsics.cy, want.color_intrinsics.cy);
    ASSERT_TRUE(got.world_from_camera.has_value());
    EXPECT_LT((*got.world_from_camera - *want.world_from_camera).cwiseAbs().maxCoeff(), 1e-12);
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
}

}  // namespace
}  // namespace lp
