// The calibration file and its application (OpenCV for undistortion stays in this folder).
#include "calibration/calibration.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "common/atomic_file.h"
#include "common/parallel.h"
#include "common/color.h"
#include "common/error.h"
#include "common/parallel.h"

namespace lp {

namespace {

constexpr const char* kFormat = "lightprobe-calibration";
constexpr int kVersion = 1;
constexpr int kMaxImageSide = 1 << 16;                 // docs/formats.md: limits
constexpr std::size_t kMaxResponseCoefficients = 16;  // the fit tries degrees up to 8

double Number(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.contains(key) || !j.at(key).is_number()) throw InputError(where + ": \"" + key + "\" must be a number");
  const double v = j.at(key).get<double>();
  if (!std::isfinite(v)) throw InputError(where + ": \"" + key + "\" is not finite");
  return v;
}

/// A width or height: a whole number from 1 to kMaxImageSide (no cast of a huge double).
int ImageSide(const nlohmann::json& j, const char* key, const std::string& where) {
  const double v = Number(j, key, where);
  if (!(v >= 1 && v <= kMaxImageSide) || v != std::floor(v))
    throw InputError(where + ": \"" + key + "\" must be a whole number from 1 to " + std::to_string(kMaxImageSide));
  return static_cast<int>(v);
}

/// A camera section: {"width", "height", "fx", "fy", "cx", "cy"[, "distortion": 5 numbers]}.
CameraModel ParseCameraSection(const nlohmann::json& k, const std::string& where) {
  if (!k.is_object()) throw InputError(where, "camera: must be an object");
  CameraModel m;
  m.width = ImageSide(k, "width", where + " camera");
  m.height = ImageSide(k, "height", where + " camera");
  m.fx = Number(k, "fx", where + " camera");
  m.fy = Number(k, "fy", where + " camera");
  m.cx = Number(k, "cx", where + " camera");
  m.cy = Number(k, "cy", where + " camera");
  if (!(m.fx > 0) || !(m.fy > 0)) throw InputError(where, "camera: size and focal lengths must be positive");
  if (k.contains("distortion")) {
    const auto& d = k.at("distortion");
    if (!d.is_array() || d.size() != 5) throw InputError(where, "camera: \"distortion\" must be 5 numbers (k1 k2 p1 p2 k3)");
    for (std::size_t i = 0; i < 5; ++i) m.distortion[i] = d.at(i).get<double>();
    for (double x : m.distortion)
      if (!std::isfinite(x)) throw InputError(where, "camera: \"distortion\" is not finite");
  }
  return m;
}

}  // namespace

bool CameraModel::distorted() const {
  for (double d : distortion)
    if (d != 0) return true;
  return false;
}

std::string Calibration::Describe() const {
  std::ostringstream s;
  if (!color && !color_from_depth && !response && vignetting.identity() && reference_exposure <= 0)
    return "uncalibrated: assuming an sRGB response, no vignetting, the device's intrinsics";
  s << "calibrated: ";
  s << (response ? "response (Mitsunaga-Nayar)" : "response assumed sRGB");
  s << (vignetting.identity() ? ", no vignetting" : ", vignetting");
  if (color) s << ", intrinsics" << (color->distorted() ? " and distortion" : "");
  if (color_from_depth) s << ", depth-to-colour extrinsics";
  if (reference_exposure > 0 && reference_gain > 0) s << ", exposure normalized";
  return s.str();
}

Calibration ReadCalibration(const std::filesystem::path& path) { return ParseCalibration(ReadTextFile(path), path.string()); }

CameraModel ParseIntrinsics(const std::string& text, const std::string& where) {
  try {
    return ParseCameraSection(nlohmann::json::parse(text), where);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where, std::string("not a JSON intrinsics file: ") + e.what());
  }
}

CameraModel ReadIntrinsicsFile(const std::filesystem::path& path) {
  return ParseIntrinsics(ReadTextFile(path), path.string());
}

void UseIntrinsicsFile(Calibration* calibration, const std::filesystem::path& path) {
  const CameraModel m = ReadIntrinsicsFile(path);  // read (and checked) even when the calibration wins
  if (!calibration->color) calibration->color = m;
}

Calibration ParseCalibration(const std::string& text, const std::string& where) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where, std::string("not a JSON calibration file: ") + e.what());
  }
  // (value("format", "") would throw for a format that is not a string: asked first.)
  if (!j.is_object() || !j.contains("format") || !j.at("format").is_string() || j.at("format").get<std::string>() != kFormat)
    throw InputError(where, std::string("not a lightprobe calibration file (\"format\" must be \"") + kFormat + "\")");
  if (!j.contains("version") || !j.at("version").is_number_integer() || j.at("version").get<long long>() != kVersion)
    throw InputError(where, "calibration file version " +
                                (j.contains("version") && j.at("version").is_number() ? j.at("version").dump() : "(not a number)") +
                                " is not supported (this build reads version " + std::to_string(kVersion) + ")");
  Calibration c;
  try {
    if (j.contains("camera")) c.color = ParseCameraSection(j.at("camera"), where);
    if (j.contains("color_from_depth")) {
      const auto& t = j.at("color_from_depth");
      if (!t.is_array() || t.size() != 4) throw InputError(where, "\"color_from_depth\" must be 4 rows of 4 numbers");
      Eigen::Matrix4d m;
      for (int r = 0; r < 4; ++r) {
        if (!t.at(r).is_array() || t.at(r).size() != 4) throw InputError(where, "\"color_from_depth\" must be 4 rows of 4 numbers");
        for (int col = 0; col < 4; ++col) m(r, col) = t.at(r).at(col).get<double>();
      }
      if (!m.allFinite()) throw InputError(where, "\"color_from_depth\" is not finite");
      c.color_from_depth = m;
    }
    if (j.contains("response")) {
      const auto& r = j.at("response");
      if (r.value("model", "") != "mitsunaga-nayar") throw InputError(where, "response: \"model\" must be \"mitsunaga-nayar\"");
      const auto& co = r.at("coefficients");
      if (!co.is_array() || co.size() != 3) throw InputError(where, "response: \"coefficients\" must be 3 lists (R, G, B)");
      InverseResponse ir;
      for (std::size_t ch = 0; ch < 3; ++ch) {
        if (!co.at(ch).is_array() || co.at(ch).empty() || co.at(ch).size() > kMaxResponseCoefficients)
          throw InputError(where, "response: each channel needs 1 to " + std::to_string(kMaxResponseCoefficients) +
                                      " coefficients");
        ir.coefficients[ch] = co.at(ch).get<std::vector<double>>();
        const double at1 = ir.Apply(static_cast<int>(ch), 1.0), at0 = ir.Apply(static_cast<int>(ch), 0.0);
        if (!(std::abs(at1 - 1) < 1e-3) || !(at0 < at1))
          throw InputError(where, "response: channel " + std::to_string(ch) + " must rise to 1 at the top value");
      }
      c.response = ir;
    }
    if (j.contains("vignetting")) {
      const auto& v = j.at("vignetting");
      if (v.value("model", "") != "kim-pollefeys") throw InputError(where, "vignetting: \"model\" must be \"kim-pollefeys\"");
      c.vignetting.a = Number(v, "a", where + " vignetting");
      c.vignetting.b = Number(v, "b", where + " vignetting");
      c.vignetting.c = Number(v, "c", where + " vignetting");
      if (v.contains("center")) {
        c.vignetting.cx = v.at("center").at(0).get<double>();
        c.vignetting.cy = v.at("center").at(1).get<double>();
        if (!std::isfinite(c.vignetting.cx) || !std::isfinite(c.vignetting.cy))
          throw InputError(where, "vignetting: \"center\" is not finite");
      }
      if (!c.vignetting.Plausible()) throw InputError(where, "vignetting: V(r) must stay above 0.05 up to r = 1");
    }
    if (j.contains("exposure")) {
      c.reference_exposure = Number(j.at("exposure"), "reference_exposure", where + " exposure");
      c.reference_gain = Number(j.at("exposure"), "reference_gain", where + " exposure");
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where, std::string("malformed calibration: ") + e.what());
  }
  return c;
}

void WriteCalibration(const std::filesystem::path& path, const Calibration& c) {
  WriteTextAtomically(path, FormatCalibration(c));
}

std::string FormatCalibration(const Calibration& c) {
  nlohmann::json j;
  j["format"] = kFormat;
  j["version"] = kVersion;
  if (c.color) {
    const CameraModel& m = *c.color;
    j["camera"] = {{"width", m.width}, {"height", m.height}, {"fx", m.fx}, {"fy", m.fy},
                   {"cx", m.cx},       {"cy", m.cy},         {"distortion", m.distortion}};
  }
  if (c.color_from_depth) {
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r)
      rows.push_back({(*c.color_from_depth)(r, 0), (*c.color_from_depth)(r, 1), (*c.color_from_depth)(r, 2),
                      (*c.color_from_depth)(r, 3)});
    j["color_from_depth"] = rows;
  }
  if (c.response)
    j["response"] = {{"model", "mitsunaga-nayar"},
                     {"coefficients", {c.response->coefficients[0], c.response->coefficients[1], c.response->coefficients[2]}}};
  if (!c.vignetting.identity()) {
    j["vignetting"] = {{"model", "kim-pollefeys"}, {"a", c.vignetting.a}, {"b", c.vignetting.b}, {"c", c.vignetting.c}};
    if (c.vignetting.cx >= 0) j["vignetting"]["center"] = {c.vignetting.cx, c.vignetting.cy};
  }
  if (c.reference_exposure > 0)
    j["exposure"] = {{"reference_exposure", c.reference_exposure}, {"reference_gain", c.reference_gain}};
  return j.dump(2) + "\n";
}

namespace {

/// For each pixel of the undistorted (pinhole) image, where it lies in the distorted one.
void UndistortMaps(const CameraModel& m, cv::Mat* map1, cv::Mat* map2) {
  const cv::Mat K = (cv::Mat_<double>(3, 3) << m.fx, 0, m.cx, 0, m.fy, m.cy, 0, 0, 1);
  const cv::Mat d(1, 5, CV_64F, const_cast<double*>(m.distortion.data()));
  cv::initUndistortRectifyMap(K, d, cv::Mat(), K, cv::Size(m.width, m.height), CV_32FC1, *map1, *map2);
}

}  // namespace

DepthImage UndistortRegisteredDepth(const DepthImage& depth, const CameraModel& model) {
  if (depth.width != model.width || depth.height != model.height)
    throw InputError("calibration is for " + std::to_string(model.width) + "x" + std::to_string(model.height) +
                     " images, the registered depth is " + std::to_string(depth.width) + "x" +
                     std::to_string(depth.height));
  if (!model.distorted()) return depth;
  cv::Mat map1, map2, dst;
  UndistortMaps(model, &map1, &map2);
  const cv::Mat src(depth.height, depth.width, CV_16UC1, const_cast<std::uint16_t*>(depth.data.data()));
  cv::remap(src, dst, map1, map2, cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  DepthImage out{depth.width, depth.height, std::vector<std::uint16_t>(depth.data.size())};
  std::memcpy(out.data.data(), dst.ptr<std::uint16_t>(), out.data.size() * sizeof(std::uint16_t));
  return out;
}

ImageRGB Linearize(const ImageRgb8& image, const Calibration& c, double exposure, double gain) {
  if (c.color && (c.color->width != image.width || c.color->height != image.height))
    throw InputError("calibration is for " + std::to_string(c.color->width) + "x" + std::to_string(c.color->height) +
                     " images, the frame is " + std::to_string(image.width) + "x" + std::to_string(image.height));
  float table[3][256];
  for (int ch = 0; ch < 3; ++ch)
    for (int v = 0; v < 256; ++v)
      table[ch][v] = c.response ? static_cast<float>(std::max(0.0, c.response->Apply(ch, v / 255.0)))
                                : SrgbToLinear(v / 255.f);  // uncalibrated: the sRGB standard
  ImageRGB out(image.width, image.height);
  ParallelForChunks(0, image.pixels(), 16384, [&](std::size_t p0, std::size_t p1) {
    for (std::size_t p = p0; p < p1; ++p)
      for (int ch = 0; ch < 3; ++ch) out.data[3 * p + ch] = table[ch][image.data[3 * p + ch]];
  });
  if (c.color && c.color->distorted()) {
    cv::Mat src(out.height, out.width, CV_32FC3, out.data.data()), dst, map1, map2;
    UndistortMaps(*c.color, &map1, &map2);
    // Pixels with no source become NaN (never used), not black.
    const float nan = std::numeric_limits<float>::quiet_NaN();
    cv::remap(src, dst, map1, map2, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(nan, nan, nan));
    std::memcpy(out.data.data(), dst.ptr<float>(), out.data.size() * sizeof(float));
  }
  double scale = 1;
  if (c.reference_exposure > 0 && c.reference_gain > 0 && exposure > 0 && gain > 0)
    scale = (c.reference_exposure * c.reference_gain) / (exposure * gain);
  const bool flat = c.vignetting.a == 0 && c.vignetting.b == 0 && c.vignetting.c == 0;
  if (flat && scale == 1) return out;  // every pixel's factor is 1
  ParallelForChunks(0, static_cast<std::size_t>(out.height), 16, [&](std::size_t y0, std::size_t y1) {
    for (int y = static_cast<int>(y0); y < static_cast<int>(y1); ++y)
      for (int x = 0; x < out.width; ++x) {
        const float f = static_cast<float>(scale / c.vignetting.At(x, y, out.width, out.height));
        float* px = out.at(x, y);
        px[0] *= f;
        px[1] *= f;
        px[2] *= f;
      }
  });
  return out;
}

}  // namespace lp
