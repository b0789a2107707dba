#pragma once
/// Colour camera intrinsics and distortion from checkerboard images (OpenCV's corner
/// finder and calibrateCamera, kept in geometry.cpp).

#include <vector>

#include <Eigen/Core>

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

/// One view of the board by both cameras: the colour image and the depth map (metres
/// along the depth camera's axis, 0 = none) with the depth camera's pinhole intrinsics.
struct DepthColorView {
  ImageRgb8 color;
  std::vector<float> depth;
  int depth_width = 0, depth_height = 0;
  double dfx = 0, dfy = 0, dcx = 0, dcy = 0;
};

struct ExtrinsicsFit {
  Eigen::Matrix4d color_from_depth = Eigen::Matrix4d::Identity();
  int views_used = 0;
  double plane_rms = 0;  ///< metres: depth points of the boards to the boards moved into the depth frame
};

/// Depth-to-colour extrinsics from views of a checkerboard (plane-based, as Herrera et al.
/// 2012): the board's plane in the colour camera from its corners (solvePnP with
/// `color`'s intrinsics and distortion), the same plane in the depth camera fitted to the
/// depth points inside the board's outline; normals give the rotation (Kabsch), plane
/// offsets the translation. Needs 3 views whose boards are tilted differently; throws
/// InputError otherwise.
ExtrinsicsFit CalibrateDepthToColor(const std::vector<DepthColorView>& views, const CameraModel& color,
                                    const CheckerboardOptions& options);

}  // namespace lp
