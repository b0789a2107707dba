// `lightprobe evaluate`'s measures against closed forms: a surface against itself moved,
// an albedo at a known scale, a lamp at a known distance, a held-out file's errors.
#include <cmath>
#include <filesystem>

#include <unistd.h>
#include <gtest/gtest.h>

#include "app/scan_evaluation.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "common/image_io.h"
#include "tests/test_util.h"

namespace lp {
namespace {
namespace fs = std::filesystem;
using app::AlbedoScale;
using app::CompareMeshes;
using app::HeldOutView;

/// A plane split into a grid of n x n quads (vertices every size/n metres).
Mesh GridPlane(double size, int n, double rho, double z = 0) {
  Mesh m;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i)
      m.positions.emplace_back(static_cast<float>(size * (i / double(n) - 0.5)),
                               static_cast<float>(size * (j / double(n) - 0.5)), static_cast<float>(z));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
      m.triangles.push_back({a, b, c});
      m.triangles.push_back({a, c, d});
    }
  m.normals.assign(m.positions.size(), Eigen::Vector3f::UnitZ());
  m.albedo.assign(m.positions.size(), Eigen::Vector3f::Constant(static_cast<float>(rho)));
  return m;
}

TEST(ScanEvaluation, AMeshAgainstItselfMovedIsOffByTheMove) {
  const Mesh truth = test::Plane(2, 0.5);  // two triangles: the measure samples its surface
  const Mesh same = GridPlane(1.6, 160, 0.5);  // vertices 1 cm apart
  const app::MeshError at_zero = CompareMeshes(same, truth);
  EXPECT_LT(at_zero.p90_m, 0.004) << "vertices on the true surface (the samples are ~5 mm apart)";
  const app::MeshError moved = CompareMeshes(GridPlane(1.6, 160, 0.5, 0.03), truth);
  EXPECT_NEAR(moved.median_m, 0.03, 0.002);
  EXPECT_NEAR(moved.p90_m, 0.03, 0.003);
  // Completeness: the reconstruction covers the middle 1.6 x 1.6 of the true 2 x 2 (and a
  // band 2 cm wide around it is within 2 cm); after the 3 cm move, nothing is.
  EXPECT_NEAR(at_zero.complete_2cm, 1.64 * 1.64 / 4, 0.02);
  EXPECT_EQ(moved.complete_2cm, 0);
}

TEST(ScanEvaluation, TheAlbedosScaleIsTheRatioToTheTrueAlbedo) {
  HeldOutView held;
  held.view = test::BlankView(test::LookAt({0, 0, 2}, {0, 0, 0}, 40, 30, 60));
  held.true_albedo = ImageRGB(40, 30);
  for (float& v : held.true_albedo.data) v = 0.4f;
  int samples = 0;
  EXPECT_NEAR(AlbedoScale(GridPlane(4, 8, 0.1), held, &samples), 0.25, 1e-6);
  EXPECT_EQ(samples, 40 * 30) << "every pixel sees the plane";
  held.view.valid.assign(held.view.valid.size(), 0);
  EXPECT_TRUE(std::isnan(AlbedoScale(GridPlane(4, 8, 0.1), held, &samples)));
  EXPECT_EQ(samples, 0);
}

TEST(ScanEvaluation, TheAlbedosErrorIsWhatIsLeftOnceItsScaleIsUndone) {
  HeldOutView held;
  held.view = test::BlankView(test::LookAt({0, 0, 2}, {0, 0, 0}, 40, 30, 60));
  held.true_albedo = ImageRGB(40, 30);
  for (float& v : held.true_albedo.data) v = 0.4f;
  double error = -1;
  EXPECT_NEAR(AlbedoScale(GridPlane(4, 8, 0.1), held, nullptr, &error), 0.25, 1e-6);
  EXPECT_NEAR(error, 0, 1e-6) << "a quarter of the truth everywhere: right but for its scale";
  // The left half of the view 0.4, the right half 0.2: the ratios are 0.25 and 0.5 on as
  // many pixels, the median takes the upper, 0.5; undone, the plane is 0.2 where the truth
  // is 0.4 (error 0.2) and right elsewhere: sqrt(0.2^2 / (0.4^2 + 0.2^2)).
  for (int y = 0; y < 30; ++y)
    for (int x = 20; x < 40; ++x)
      for (int c = 0; c < 3; ++c) held.true_albedo.data[3 * (y * 40 + x) + c] = 0.2f;
  EXPECT_NEAR(AlbedoScale(GridPlane(4, 8, 0.1), held, nullptr, &error), 0.5, 1e-6);
  EXPECT_NEAR(error, std::sqrt(0.04 / 0.2), 1e-6);
}

// The held-out error split without a true albedo: a light's error (smooth: here 10 % too
// bright everywhere) survives the blur; a colour map's (pixel-sharp: a +-10 % checker of
// one-pixel squares) is what the blur takes away.
TEST(ScanEvaluation, TheBlurSplitsSmoothErrorsFromSharpOnes) {
  ImageRGB reference(64, 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x)
      for (int c = 0; c < 3; ++c) reference.at(x, y)[c] = 0.2f + 0.005f * x;  // a smooth wall
  std::vector<std::uint8_t> valid(64 * 48, 1);
  for (int x = 40; x < 64; ++x) valid[10 * 64 + x] = 0;  // a hole: neither gives nor takes
  ImageRGB brighter = reference, speckled = reference;
  for (float& v : brighter.data) v *= 1.1f;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x)
      for (int c = 0; c < 3; ++c) speckled.at(x, y)[c] *= (x + y) % 2 ? 1.1f : 0.9f;
  // (RelativeImageRmse is over the reference's mean: 10 % everywhere is 0.1 x RMS / mean.)
  double sum = 0, squares = 0;
  for (float v : reference.data) sum += v, squares += double(v) * v;
  const double n = static_cast<double>(reference.data.size()), ten_percent = 0.1 * std::sqrt(squares / n) / (sum / n);
  const app::BlurSplit light = app::SplitByBlur(brighter, reference, valid);
  EXPECT_NEAR(light.total, ten_percent, 1e-3);
  EXPECT_NEAR(light.smooth, light.total, 0.02 * light.total) << "a uniform 10 % survives the blur";
  EXPECT_LT(light.sharp, 0.2 * light.total);
  const app::BlurSplit colour = app::SplitByBlur(speckled, reference, valid);
  EXPECT_NEAR(colour.total, ten_percent, 2e-3);
  EXPECT_LT(colour.smooth, 0.1 * colour.total) << "a one-pixel checker averages out";
  EXPECT_NEAR(colour.sharp, colour.total, 0.01 * colour.total);
}

TEST(ScanEvaluation, AHeldOutFileWithAWrongSizeIsAClearError) {
  const fs::path dir = fs::temp_directory_path() / ("lp_scan_eval_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  WriteExr(dir / "held.exr", ImageRGB(8, 6));
  WriteTextAtomically(dir / "holdout.json",
                      R"({"image": "held.exr", "width": 16, "height": 6, "fx": 10, "fy": 10, "cx": 8, "cy": 3,
                          "world_from_camera": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})");
  EXPECT_NE(test::ErrorOf([&] { app::ReadHeldOutView(dir / "holdout.json"); }).find("the image's size is not the camera's"),
            std::string::npos);
  WriteTextAtomically(dir / "holdout.json", R"({"image": "held.exr"})");
  EXPECT_NE(test::ErrorOf([&] { app::ReadHeldOutView(dir / "holdout.json"); }).find("no number \"width\""),
            std::string::npos);
  fs::remove_all(dir);
}

TEST(ScanEvaluation, AClippedHeldOutPixelIsOnlyALowerBound) {
  const fs::path dir = fs::temp_directory_path() / ("lp_scan_clip_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  ImageRGB held(2, 1);
  held.data = {1.f, 0.5f, 0.25f, 0.5f, 0.5f, 0.5f};  // the first pixel's red at the top code
  WritePngSrgb(dir / "held.png", held);
  WriteExr(dir / "held.exr", held);
  const auto json = [](const char* image) {
    return std::string(R"({"image": ")") + image +
           R"(", "width": 2, "height": 1, "fx": 10, "fy": 10, "cx": 1, "cy": 0.5,
               "world_from_camera": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})";
  };
  WriteTextAtomically(dir / "holdout.json", json("held.png"));
  const HeldOutView png = app::ReadHeldOutView(dir / "holdout.json");
  EXPECT_EQ(png.view.saturation, 1.0);
  ImageRGB render(2, 1);
  render.data = {3.f, 0.7f, 0.25f, 3.f, 0.5f, 0.5f};
  const ImageRGB cut = app::UpToTheClip(render, png.view);
  EXPECT_FLOAT_EQ(cut.data[0], 1.f) << "above the clip: no error";
  EXPECT_FLOAT_EQ(cut.data[1], 0.7f) << "the pixel's unclipped channels are measured";
  EXPECT_FLOAT_EQ(cut.data[3], 3.f) << "an unclipped pixel is measured";
  render.data[0] = 0.4f;
  EXPECT_FLOAT_EQ(app::UpToTheClip(render, png.view).data[0], 0.4f) << "below the clip: an error";
  WriteTextAtomically(dir / "holdout.json", json("held.exr"));
  const HeldOutView exr = app::ReadHeldOutView(dir / "holdout.json");
  EXPECT_FALSE(std::isfinite(exr.view.saturation)) << "a linear image clips nothing";
  render.data[0] = 3.f;
  EXPECT_FLOAT_EQ(app::UpToTheClip(render, exr.view).data[0], 3.f);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lp
