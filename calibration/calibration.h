#pragma once
/// What makes the colour camera's pixels comparable irradiance: geometry (intrinsics,
/// distortion, depth-to-colour extrinsics), the inverse response, vignetting and the
/// exposure. Held in a versioned JSON calibration file (docs/formats.md) and applied to
/// every colour frame before reconstruction and estimation.

#include <array>
#include <filesystem>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "calibration/response.h"
#include "calibration/vignetting.h"
#include "common/image.h"
#include "scene/camera.h"

namespace lp {

/// The colour camera: its pinhole intrinsics (the pose is unused) with OpenCV's
/// distortion (k1, k2, p1, p2, k3).
struct CameraModel : Camera {
  std::array<double, 5> distortion{};
  bool distorted() const;
};

struct Calibration {
  std::optional<CameraModel> color;               ///< none: as the device reports, undistorted
  std::optional<Eigen::Matrix4d> color_from_depth;  ///< none: registered by the device
  std::optional<InverseResponse> response;        ///< none: sRGB assumed
  Vignetting vignetting;                          ///< identity when not calibrated
  /// Frames are scaled to this exposure x gain (device units) when both are known for
  /// the frame and here; 0 = no normalization.
  double reference_exposure = 0, reference_gain = 0;
  /// One line: what is calibrated, or that it runs uncalibrated and what it assumes.
  std::string Describe() const;
};

/// Reads a calibration file; throws InputError naming the file and the problem (not JSON,
/// another format or version, values out of range).
Calibration ReadCalibration(const std::filesystem::path& path);
/// The same from the file's text (`name` for errors).
Calibration ParseCalibration(const std::string& text, const std::string& name);
/// An intrinsics file (`--intrinsics`): a calibration file's "camera" section alone,
/// `{"width", "height", "fx", "fy", "cx", "cy"[, "distortion"]}` (docs/formats.md).
CameraModel ReadIntrinsicsFile(const std::filesystem::path& path);
/// The same from the file's text (`name` for errors).
CameraModel ParseIntrinsics(const std::string& text, const std::string& name);
/// Gives `calibration` the file's camera when it has none of its own: a calibration's
/// intrinsics win over an intrinsics file, which wins over the recording's.
void UseIntrinsicsFile(Calibration* calibration, const std::filesystem::path& path);
/// Writes it atomically.
void WriteCalibration(const std::filesystem::path& path, const Calibration& calibration);
/// The text WriteCalibration writes.
std::string FormatCalibration(const Calibration& calibration);

/// An 8-bit colour frame as linear irradiance: inverse response (sRGB without one),
/// undistortion (with a camera model that has distortion), division by the vignetting,
/// and scaling to the reference exposure x gain (when the frame's exposure and gain are
/// known, > 0). Throws InputError when the image size does not match the calibrated
/// camera's.
ImageRGB Linearize(const ImageRgb8& image, const Calibration& calibration, double exposure = 0, double gain = 0);

/// Depth registered to the colour camera lies on the colour camera's distorted pixel grid:
/// the same undistortion as Linearize (nearest neighbour: depths are not blended across
/// edges; pixels with no source are 0, invalid), so depth and colour share the model's
/// pinhole intrinsics. Throws InputError when the sizes differ.
DepthImage UndistortRegisteredDepth(const DepthImage& depth, const CameraModel& model);

}  // namespace lp
