#pragma once
/// Colour camera intrinsics and distortion from checkerboard images (OpenCV's corner
/// finder and calibrateCamera, kept in geometry.cpp).

#include <vector>

#include "calibration/calibration.h"
#include "common/image.h"

namespace lp {

struct CheckerboardOptions {
  int inner_columns = 9, inner_rows = 6;  ///< inner corners of the board
  double square = 0.025;                  ///< metres (only scales the poses)
  bool distortion = true;                 ///< fit k1, k2, p1, p2, k3 (else none)
};

struct GeometryFit {
  CameraModel camera;
  double rms_reprojection = 0;  ///< pixels
  int images_used = 0;
  std::vector<int> board_found;  ///< per image: 1 when its board was found
};

/// Calibrates from images of a checkerboard (all of one size). Throws InputError when
/// fewer than 3 images show the whole board, or the images differ in size.
GeometryFit CalibrateGeometry(const std::vector<ImageRgb8>& images, const CheckerboardOptions& options);

}  // namespace lp
