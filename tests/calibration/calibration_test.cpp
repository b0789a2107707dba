// Calibration against known answers: brackets made with a known response (sRGB, gamma
// 2.2, an S-curve), known exposure ratios and known vignetting; the file round trip and
// its errors; and OpenCV's Debevec and Robertson on the same brackets, for comparison.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>

#include <gtest/gtest.h>
#include <opencv2/photo.hpp>

#include "calibration/calibration.h"
#include "calibration/geometry.h"
#include "common/color.h"
#include "common/error.h"
#include "common/rng.h"
#include "scene/scene_bundle.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

constexpr double kPi = 3.14159265358979323846;

/// Camera curves: irradiance (0..1) -> value (0..1), and their inverses.
struct Curve {
  const char* name;
  std::function<double(double)> f, inverse;
};

std::vector<Curve> Curves() {
  auto s = [](double t) { return t + 0.15 * std::sin(2 * kPi * t) / (2 * kPi); };  // S-shaped tone curve
  auto s_inv = [s](double m) {  // bisection: s is increasing
    double lo = 0, hi = 1;
    for (int i = 0; i < 60; ++i) (s(0.5 * (lo + hi)) < m ? lo : hi) = 0.5 * (lo + hi);
    return 0.5 * (lo + hi);
  };
  return {
      {"sRGB", [](double x) { return LinearToSrgb(static_cast<float>(x)); },
       [](double m) { return SrgbToLinear(static_cast<float>(m)); }},
      {"gamma 2.2", [](double x) { return std::pow(x, 1 / 2.2); }, [](double m) { return std::pow(m, 2.2); }},
      {"S-curve", [s](double x) { return s(std::pow(x, 1 / 2.2)); }, [s_inv](double m) { return std::pow(s_inv(m), 2.2); }},
  };
}

/// A static scene (irradiance per pixel over ~2.5 decades, smooth plus texture, a
/// little different per channel) seen at `exposures` through `curve`, 8-bit, with 0.3 %
/// noise before quantization.
std::vector<ImageRgb8> Bracket(const Curve& curve, const std::vector<double>& exposures, int w = 160, int h = 120) {
  std::vector<double> scene(static_cast<std::size_t>(w) * h * 3);
  Rng rng(11);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int ch = 0; ch < 3; ++ch) {
        const double t = 0.5 + 0.5 * std::sin(0.07 * x + 0.11 * y + ch);
        scene[(static_cast<std::size_t>(y) * w + x) * 3 + ch] = std::pow(10.0, -2.6 + 2.6 * (0.7 * t + 0.3 * rng.Uniform()));
      }
  std::vector<ImageRgb8> out;
  for (double e : exposures) {
    ImageRgb8 im{w, h, std::vector<std::uint8_t>(scene.size())};
    for (std::size_t i = 0; i < scene.size(); ++i) {
      const double E = std::min(1.0, scene[i] * e * (1 + 0.003 * (rng.Uniform() - 0.5) * 3.4));
      im.data[i] = static_cast<std::uint8_t>(std::lround(255 * std::clamp(curve.f(E), 0.0, 1.0)));
    }
    out.push_back(std::move(im));
  }
  return out;
}

/// RMS of the recovered inverse response against the true one over the unsaturated range.
double ResponseRms(const std::function<double(int, double)>& g, const Curve& curve) {
  double sum = 0;
  int n = 0;
  for (int v = 6; v <= 249; ++v)
    for (int ch = 0; ch < 3; ++ch) {
      const double m = v / 255.0, value = g(ch, m);
      if (!std::isfinite(value)) continue;
      sum += std::pow(value - curve.inverse(m), 2);
      ++n;
    }
  return std::sqrt(sum / n);
}

TEST(Response, MitsunagaNayarRecoversKnownCurvesAndRatios) {
  const std::vector<double> exposures = {1, 2, 4, 8, 16, 32};
  for (const Curve& curve : Curves()) {
    const std::vector<ImageRgb8> images = Bracket(curve, exposures);
    // Start from ratios 4 % off (as a camera's nominal settings might be) and refine.
    std::vector<double> nominal = exposures;
    for (std::size_t i = 1; i < nominal.size(); ++i) nominal[i] *= (i % 2 ? 1.04 : 0.96);
    const ResponseFit fit = FitResponse(images, nominal);
    const double rms = ResponseRms([&](int ch, double m) { return fit.response.Apply(ch, m); }, curve);
    ResponseFitOptions known;  // the ratios exact and kept
    known.refine_ratios = false;
    const ResponseFit exact = FitResponse(images, exposures, known);
    const double rms_known = ResponseRms([&](int ch, double m) { return exact.response.Apply(ch, m); }, curve);
    double ratio_err = 0;
    for (std::size_t i = 1; i < exposures.size(); ++i)
      ratio_err = std::max(ratio_err, std::abs(fit.exposures[i] / fit.exposures[i - 1] / 2 - 1));

    // OpenCV on the same bracket, with the least-squares scale to the truth over the
    // range compared (its curves have no fixed scale; ours is 1 at value 255).
    std::vector<cv::Mat> mats;
    for (const ImageRgb8& im : images) {
      cv::Mat rgb(im.height, im.width, CV_8UC3, const_cast<std::uint8_t*>(im.data.data()));
      mats.push_back(rgb.clone());
    }
    std::vector<float> times(exposures.begin(), exposures.end());
    double cv_rms[2];
    for (int k = 0; k < 2; ++k) {
      cv::Mat resp;
      if (k == 0) cv::createCalibrateDebevec()->process(mats, resp, times);
      else cv::createCalibrateRobertson()->process(mats, resp, times);
      double scale[3];
      for (int ch = 0; ch < 3; ++ch) {
        double num = 0, den = 0;
        for (int v = 6; v <= 249; ++v) {
          const double o = resp.at<cv::Vec3f>(v)[ch], t = curve.inverse(v / 255.0);
          if (!std::isfinite(o)) continue;  // Robertson leaves values it never saw undefined
          num += o * t;
          den += o * o;
        }
        scale[ch] = num / den;
      }
      cv_rms[k] = ResponseRms(
          [&](int ch, double m) { return scale[ch] * resp.at<cv::Vec3f>(static_cast<int>(std::lround(m * 255)))[ch]; },
          curve);
    }
    std::printf("%-10s Mitsunaga-Nayar: f^-1 RMS %.3f %% with ratios refined from +-4 %% errors (degrees %d/%d/%d; "
                "ratios within %.3f %%), %.3f %% with the exact ratios | OpenCV Debevec %.3f %%, Robertson %.3f %%\n",
                curve.name, 100 * rms, fit.degree[0], fit.degree[1], fit.degree[2], 100 * ratio_err, 100 * rms_known,
                100 * cv_rms[0], 100 * cv_rms[1]);
    EXPECT_LT(rms, 0.01) << curve.name;
    EXPECT_LT(rms_known, 0.01) << curve.name;
    EXPECT_LT(ratio_err, 0.01) << curve.name;
  }
}

TEST(Response, BadInputIsAClearError) {
  const Curve curve = Curves()[0];
  const auto images = Bracket(curve, {1, 2});
  EXPECT_THROW(FitResponse({images[0]}, {1}), InputError);
  EXPECT_THROW(FitResponse(images, {1}), InputError);
  EXPECT_THROW(FitResponse(images, {1, -2}), InputError);
  EXPECT_THROW(FitResponse(images, {1, 1.05}), InputError);  // the same exposure: no bracket
  auto small = images;
  small[1].width = 10;
  EXPECT_THROW(FitResponse(small, {1, 2}), InputError);
  ImageRgb8 black{160, 120, std::vector<std::uint8_t>(160 * 120 * 3, 0)};
  EXPECT_THROW(FitResponse({black, black}, {1, 2}), InputError);  // nothing usable
}

Vignetting TrueVignetting() {
  Vignetting v;
  v.a = -0.32;
  v.b = 0.11;
  v.c = -0.06;
  return v;
}

double WorstVignettingError(const Vignetting& fit, int w, int h) {
  const Vignetting truth = TrueVignetting();
  double worst = 0;
  for (int y = 0; y < h; y += 4)
    for (int x = 0; x < w; x += 4)
      worst = std::max(worst, std::abs(fit.At(x, y, w, h) / truth.At(x, y, w, h) - 1));
  return worst;
}

TEST(Vignetting, FlatFieldAndSurfacePointsRecoverTheModel) {
  const int w = 320, h = 240;
  const Vignetting truth = TrueVignetting();
  Rng rng(3);
  std::vector<ImageRGB> flats;
  for (int k = 0; k < 2; ++k) {
    ImageRGB im(w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int ch = 0; ch < 3; ++ch)
          im.at(x, y)[ch] = static_cast<float>(0.6 * truth.At(x, y, w, h) * (1 + 0.01 * (rng.Uniform() - 0.5)));
    flats.push_back(im);
  }
  const double flat_err = WorstVignettingError(FitVignettingFlatField(flats), w, h);

  std::vector<VignettingPair> pairs;  // surface points of random albedo seen at two radii
  for (int i = 0; i < 2000; ++i) {
    const double albedo = 0.1 + 0.8 * rng.Uniform();
    auto seen = [&](double* r) {
      const double x = rng.Uniform() * (w - 1), y = rng.Uniform() * (h - 1);
      *r = std::hypot(x - (0.5 * w - 0.5), y - (0.5 * h - 0.5)) / (0.5 * std::hypot(w, h));
      return albedo * truth.At(x, y, w, h) * (1 + 0.01 * (rng.Uniform() - 0.5));
    };
    VignettingPair p;
    p.value_i = seen(&p.r_i);
    p.value_j = seen(&p.r_j);
    pairs.push_back(p);
  }
  const double pair_err = WorstVignettingError(FitVignettingPairs(pairs), w, h);
  std::printf("vignetting: worst error of V over the image %.3f %% (flat field), %.3f %% (surface points)\n",
              100 * flat_err, 100 * pair_err);
  EXPECT_LT(flat_err, 0.01);
  EXPECT_LT(pair_err, 0.01);
  EXPECT_THROW(FitVignettingPairs(std::vector<VignettingPair>(5, pairs[0])), InputError);
  EXPECT_THROW(FitVignettingFlatField({}), InputError);
}

// Linearize inverts what the camera did: response, vignetting and exposure.
TEST(Calibration, LinearizeUndoesResponseVignettingAndExposure) {
  const int w = 64, h = 48;
  const Curve curve = Curves()[1];  // gamma 2.2
  Calibration c;
  c.response = FitResponse(Bracket(curve, {1, 2, 4, 8, 16, 32}, w, h), {1, 2, 4, 8, 16, 32}).response;
  c.vignetting = TrueVignetting();
  c.reference_exposure = 100;
  c.reference_gain = 1;
  // A grey card of irradiance 0.2 at the reference exposure, seen at exposure 50 (half):
  // the camera records f(0.1 V(r)).
  ImageRgb8 im{w, h, std::vector<std::uint8_t>(static_cast<std::size_t>(w) * h * 3)};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int ch = 0; ch < 3; ++ch)
        im.data[(static_cast<std::size_t>(y) * w + x) * 3 + ch] =
            static_cast<std::uint8_t>(std::lround(255 * curve.f(0.1 * c.vignetting.At(x, y, w, h))));
  const ImageRGB lin = Linearize(im, c, 50, 1);
  double worst = 0, mean = 0;
  for (float v : lin.data) {
    worst = std::max(worst, std::abs(v / 0.2 - 1));
    mean += std::abs(v / 0.2 - 1) / lin.data.size();
  }
  EXPECT_LT(mean, 0.01);
  // Half a code of 8-bit quantization at value ~80 (the darkest corner) is ~1.4 % in
  // irradiance for gamma 2.2, plus the response fit.
  EXPECT_LT(worst, 0.03);
  EXPECT_NE(c.Describe().find("calibrated"), std::string::npos);
  EXPECT_NE(Calibration{}.Describe().find("uncalibrated"), std::string::npos);
  // Undistortion: pixels with no source are NaN (never used), not black.
  Calibration d;
  d.color = CameraModel{{w, h, 40, 40, 31.5, 23.5}, {0.4, 0.1, 0, 0, 0}};  // pincushion: corners from outside
  const ImageRGB und = Linearize(ImageRgb8{w, h, std::vector<std::uint8_t>(static_cast<std::size_t>(w) * h * 3, 200)}, d);
  EXPECT_TRUE(std::isnan(und.at(0, 0)[0])) << und.at(0, 0)[0];
  EXPECT_NEAR(und.at(w / 2, h / 2)[0], SrgbToLinear(200 / 255.f), 1e-3);
  // Uncalibrated: sRGB decoding.
  const ImageRGB srgb = Linearize(ImageRgb8{1, 1, {128, 128, 128}}, Calibration{});
  EXPECT_NEAR(srgb.data[0], SrgbToLinear(128 / 255.f), 1e-3);
}

TEST(Calibration, FileRoundTripAndClearErrors) {
  const fs::path dir = fs::temp_directory_path() / ("lp_calib_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  Calibration c;
  c.color = CameraModel{{640, 480, 520.5, 521.25, 318.4, 242.1}, {0.05, -0.1, 0.001, -0.002, 0.02}};
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T(0, 3) = -0.025;
  c.color_from_depth = T;
  c.response = InverseResponse::Srgb();
  c.vignetting = TrueVignetting();
  c.reference_exposure = 100;
  c.reference_gain = 2;
  WriteCalibration(dir / "c.json", c);
  const Calibration r = ReadCalibration(dir / "c.json");
  ASSERT_TRUE(r.color && r.color_from_depth && r.response);
  EXPECT_EQ(r.color->fy, 521.25);
  EXPECT_EQ(r.color->distortion[3], -0.002);
  EXPECT_EQ((*r.color_from_depth)(0, 3), -0.025);
  EXPECT_EQ(r.response->coefficients[1], c.response->coefficients[1]);
  EXPECT_EQ(r.vignetting.b, c.vignetting.b);
  EXPECT_EQ(r.reference_gain, 2);

  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return dir / name;
  };
  for (const auto& [name, text] : std::vector<std::pair<std::string, std::string>>{
           {"notjson.json", "{ calibration"},
           {"format.json", R"({"format": "something-else", "version": 1})"},
           {"version.json", R"({"format": "lightprobe-calibration", "version": 99})"},
           {"fx.json", R"({"format": "lightprobe-calibration", "version": 1, "camera": {"width": 640, "height": 480, "fx": -1, "fy": 500, "cx": 320, "cy": 240}})"},
           {"response.json", R"({"format": "lightprobe-calibration", "version": 1, "response": {"model": "mitsunaga-nayar", "coefficients": [[0, 0.5], [0, 1], [0, 1]]}})"},
           {"vignetting.json", R"({"format": "lightprobe-calibration", "version": 1, "vignetting": {"model": "kim-pollefeys", "a": -2, "b": 0, "c": 0}})"},
           // Hostile values (issue 23): a width no int holds, a fractional one, a version that
           // is a deep array (once printed back whole), a response polynomial of 17 terms.
           {"width.json", R"({"format": "lightprobe-calibration", "version": 1, "camera": {"width": 1e300, "height": 480, "fx": 500, "fy": 500, "cx": 320, "cy": 240}})"},
           {"fraction.json", R"({"format": "lightprobe-calibration", "version": 1, "camera": {"width": 640.5, "height": 480, "fx": 500, "fy": 500, "cx": 320, "cy": 240}})"},
           {"deepversion.json", R"({"format": "lightprobe-calibration", "version": [[[[[[[[1]]]]]]]]})"},
           {"terms.json", R"({"format": "lightprobe-calibration", "version": 1, "response": {"model": "mitsunaga-nayar", "coefficients": [[0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,1], [0, 1], [0, 1]]}})"},
       }) {
    try {
      ReadCalibration(write(name, text));
      ADD_FAILURE() << name << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(ReadCalibration(dir / "missing.json"), InputError);
  // An intrinsics file (--intrinsics) is a camera section alone; a calibration's camera wins.
  const fs::path k = write("k.json", R"({"width": 640, "height": 480, "fx": 530, "fy": 531, "cx": 320, "cy": 241})");
  EXPECT_EQ(ReadIntrinsicsFile(k).fy, 531);
  Calibration none;
  UseIntrinsicsFile(&none, k);
  ASSERT_TRUE(none.color);
  EXPECT_EQ(none.color->cy, 241);
  Calibration with = r;  // r.color->fy is 521.25
  UseIntrinsicsFile(&with, k);
  EXPECT_EQ(with.color->fy, 521.25);
  EXPECT_THROW(ReadIntrinsicsFile(write("k0.json", R"({"width": 640, "height": 480, "fx": 0, "fy": 1, "cx": 1, "cy": 1})")),
               InputError);
  EXPECT_THROW(ReadIntrinsicsFile(write("k1.json", "[1, 2]")), InputError);
  // A calibration for another image size does not apply.
  EXPECT_THROW(Linearize(ImageRgb8{320, 240, std::vector<std::uint8_t>(320 * 240 * 3)}, r), InputError);
  fs::remove_all(dir);
}

/// A checkerboard (inner corners cols x rows, squares of `square` m, one square of white
/// margin) seen by a pinhole camera K at world_from_camera: each pixel is 4x4 supersampled.
ImageRgb8 RenderBoard(const CameraModel& K, const Eigen::Matrix4d& world_from_camera, int cols, int rows,
                      double square) {
  ImageRgb8 im{K.width, K.height, std::vector<std::uint8_t>(static_cast<std::size_t>(K.width) * K.height * 3)};
  const Eigen::Matrix3d R = world_from_camera.block<3, 3>(0, 0);
  const Eigen::Vector3d o = world_from_camera.block<3, 1>(0, 3);
  for (int y = 0; y < K.height; ++y)
    for (int x = 0; x < K.width; ++x) {
      double sum = 0;
      for (int sy = 0; sy < 4; ++sy)
        for (int sx = 0; sx < 4; ++sx) {
          const Eigen::Vector3d d =
              R * Eigen::Vector3d((x - 0.375 + 0.25 * sx - K.cx) / K.fx, (y - 0.375 + 0.25 * sy - K.cy) / K.fy, 1);
          if (std::abs(d.z()) < 1e-12) continue;
          const double t = -o.z() / d.z();  // the board is the plane z = 0
          if (t <= 0) continue;
          const double u = (o.x() + t * d.x()) / square + 1, v = (o.y() + t * d.y()) / square + 1;  // squares
          double value = 0.9;  // white margin and background
          if (u >= 0 && v >= 0 && u < cols + 1 && v < rows + 1)
            value = ((static_cast<int>(std::floor(u)) + static_cast<int>(std::floor(v))) % 2) ? 0.9 : 0.05;
          sum += value;
        }
      const auto g = static_cast<std::uint8_t>(std::lround(255 * LinearToSrgb(static_cast<float>(sum / 16))));
      for (int ch = 0; ch < 3; ++ch) im.data[(static_cast<std::size_t>(y) * K.width + x) * 3 + ch] = g;
    }
  return im;
}

// Checkerboard images rendered with known intrinsics: recovered within 0.5 %.
TEST(Geometry, CheckerboardsRecoverKnownIntrinsics) {
  const CameraModel truth{640, 480, 528.0, 531.0, 322.5, 236.0, {}};
  const int cols = 9, rows = 6;
  const double square = 0.03;
  const Eigen::Vector3d centre(0.5 * (cols - 1) * square, 0.5 * (rows - 1) * square, 0);
  std::vector<ImageRgb8> images;
  for (int i = 0; i < 10; ++i) {
    const double a = 2 * kPi * i / 10, tilt = 0.35 + 0.1 * (i % 3);
    const Eigen::Vector3d eye = centre + Eigen::Vector3d(std::sin(tilt) * std::cos(a), std::sin(tilt) * std::sin(a),
                                                         -std::cos(tilt)) * (0.45 + 0.05 * (i % 2));
    Eigen::Matrix4d T = Camera::LookAt(eye, centre + Eigen::Vector3d(0.01 * (i % 4), 0.01 * (i % 3), 0),
                                       Eigen::Vector3d::UnitY(), 4, 4, 60).world_from_camera;
    images.push_back(RenderBoard(truth, T, cols, rows, square));
  }
  CheckerboardOptions o;
  o.inner_columns = cols;
  o.inner_rows = rows;
  o.square = square;
  const GeometryFit fit = CalibrateGeometry(images, o);
  const CameraModel& m = fit.camera;
  std::printf("checkerboards: %d of %zu used, reprojection RMS %.3f px; fx %.2f (%.3f %%), fy %.2f (%.3f %%), cx %.2f "
              "(%.3f %%), cy %.2f (%.3f %%)\n",
              fit.images_used, images.size(), fit.rms_reprojection, m.fx, 100 * (m.fx / truth.fx - 1), m.fy,
              100 * (m.fy / truth.fy - 1), m.cx, 100 * (m.cx / truth.cx - 1), m.cy, 100 * (m.cy / truth.cy - 1));
  EXPECT_GE(fit.images_used, 8);
  EXPECT_NEAR(m.fx / truth.fx, 1, 0.005);
  EXPECT_NEAR(m.fy / truth.fy, 1, 0.005);
  EXPECT_NEAR(m.cx / truth.cx, 1, 0.005);
  EXPECT_NEAR(m.cy / truth.cy, 1, 0.005);
  EXPECT_LT(fit.rms_reprojection, 0.5);
  // No board: a clear error.
  ImageRgb8 blank{640, 480, std::vector<std::uint8_t>(640 * 480 * 3, 200)};
  EXPECT_THROW(CalibrateGeometry({blank, blank, blank}, o), InputError);
}

// Depth-to-colour extrinsics from the board's plane seen by both cameras: a known
// transform (1 degree, 2.5 cm baseline) comes back within 1 mm and 0.1 degree.
TEST(Geometry, DepthToColorExtrinsicsFromBoardPlanes) {
  const CameraModel color{640, 480, 528.0, 531.0, 322.5, 236.0, {}};
  Eigen::Matrix4d truth = Eigen::Matrix4d::Identity();
  truth.block<3, 3>(0, 0) = Eigen::AngleAxisd(kPi / 180, Eigen::Vector3d(0.3, 1, 0.2).normalized()).toRotationMatrix();
  truth.block<3, 1>(0, 3) = Eigen::Vector3d(-0.025, 0.002, 0.001);
  const int cols = 9, rows = 6;
  const double square = 0.03;
  const Eigen::Vector3d centre(0.5 * (cols - 1) * square, 0.5 * (rows - 1) * square, 0);
  std::vector<DepthColorView> views;
  for (int i = 0; i < 5; ++i) {
    const double a = 2 * kPi * i / 5, tilt = 0.45;
    const Eigen::Vector3d eye =
        centre + Eigen::Vector3d(std::sin(tilt) * std::cos(a), std::sin(tilt) * std::sin(a), -std::cos(tilt)) * 0.6;
    const Eigen::Matrix4d world_from_color =
        Camera::LookAt(eye, centre, Eigen::Vector3d::UnitY(), 4, 4, 60).world_from_camera;
    DepthColorView v;
    v.color = RenderBoard(color, world_from_color, cols, rows, square);
    v.depth_width = 320;
    v.depth_height = 240;
    v.dfx = v.dfy = 285;
    v.dcx = 159.5;
    v.dcy = 119.5;
    const Eigen::Matrix4d world_from_depth = world_from_color * truth;  // truth = color_from_depth
    v.depth.assign(320 * 240, 0.f);
    for (int y = 0; y < 240; ++y)
      for (int x = 0; x < 320; ++x) {
        const Eigen::Vector3d ray((x - v.dcx) / v.dfx, (y - v.dcy) / v.dfy, 1);
        const Eigen::Vector3d d = world_from_depth.block<3, 3>(0, 0) * ray, o = world_from_depth.block<3, 1>(0, 3);
        const double z = -o.z() / d.z();  // the board plane z = 0; depth along the axis = z (ray has z 1)
        if (z > 0) v.depth[static_cast<std::size_t>(y) * 320 + x] = static_cast<float>(z);
      }
    views.push_back(std::move(v));
  }
  CheckerboardOptions o;
  o.inner_columns = cols;
  o.inner_rows = rows;
  o.square = square;
  const ExtrinsicsFit fit = CalibrateDepthToColor(views, color, o);
  const Eigen::Matrix4d err = truth.inverse() * fit.color_from_depth;
  const double angle = std::acos(std::clamp((err.block<3, 3>(0, 0).trace() - 1) / 2, -1.0, 1.0)) * 180 / kPi;
  std::printf("extrinsics: %d views, translation error %.2f mm, rotation error %.3f deg, plane RMS %.2f mm\n",
              fit.views_used, 1e3 * (err.block<3, 1>(0, 3)).norm(), angle, 1e3 * fit.plane_rms);
  EXPECT_EQ(fit.views_used, 5);
  const double moved = err.block<3, 1>(0, 3).norm();
  EXPECT_LT(moved, 0.001);
  EXPECT_LT(angle, 0.1);
  views.resize(2);
  EXPECT_THROW(CalibrateDepthToColor(views, color, o), InputError);
}

}  // namespace
}  // namespace lp
