#include "calibration/geometry.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace lp {

GeometryFit CalibrateGeometry(const std::vector<ImageRgb8>& images, const CheckerboardOptions& o) {
  if (images.empty()) throw InputError("calibrate geometry: no images");
  if (o.inner_columns < 2 || o.inner_rows < 2 || !(o.square > 0))
    throw InputError("calibrate geometry: the board needs at least 2x2 inner corners and a positive square size");
  const int w = images[0].width, h = images[0].height;
  const cv::Size pattern(o.inner_columns, o.inner_rows);
  std::vector<cv::Point3f> board;
  for (int r = 0; r < o.inner_rows; ++r)
    for (int c = 0; c < o.inner_columns; ++c)
      board.emplace_back(static_cast<float>(c * o.square), static_cast<float>(r * o.square), 0.f);
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> corners;
  GeometryFit fit;
  for (const ImageRgb8& im : images) {
    if (im.width != w || im.height != h) throw InputError("calibrate geometry: the images differ in size");
    cv::Mat rgb(im.height, im.width, CV_8UC3, const_cast<std::uint8_t*>(im.data.data())), grey;
    cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
    std::vector<cv::Point2f> found;
    const bool ok = cv::findChessboardCorners(grey, pattern, found,
                                              cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    fit.board_found.push_back(ok);
    if (!ok) continue;
    cv::cornerSubPix(grey, found, cv::Size(5, 5), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-4));
    corners.push_back(found);
    object.push_back(board);
  }
  fit.images_used = static_cast<int>(corners.size());
  if (fit.images_used < 3)
    throw InputError("calibrate geometry: the " + std::to_string(o.inner_columns) + "x" +
                     std::to_string(o.inner_rows) + " board was found in " + std::to_string(fit.images_used) + " of " +
                     std::to_string(images.size()) + " images; at least 3 are needed");
  cv::Mat K, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  int flags = 0;
  if (!o.distortion) flags |= cv::CALIB_ZERO_TANGENT_DIST | cv::CALIB_FIX_K1 | cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3;
  fit.rms_reprojection = cv::calibrateCamera(object, corners, cv::Size(w, h), K, dist, rvecs, tvecs, flags);
  CameraModel& m = fit.camera;
  m.width = w;
  m.height = h;
  m.fx = K.at<double>(0, 0);
  m.fy = K.at<double>(1, 1);
  m.cx = K.at<double>(0, 2);
  m.cy = K.at<double>(1, 2);
  for (int i = 0; i < 5 && i < static_cast<int>(dist.total()); ++i) m.distortion[static_cast<std::size_t>(i)] = dist.at<double>(i);
  return fit;
}

}  // namespace lp
