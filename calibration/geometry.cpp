#include "calibration/geometry.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"

#include <optional>

#include <Eigen/Dense>

namespace lp {

namespace {
GeometryFit CalibrateGeometryImpl(const std::vector<ImageRgb8>& images, const CheckerboardOptions& o) {
  if (images.empty()) throw InputError("calibrate geometry: no images");
  if (o.inner_columns < 3 || o.inner_rows < 3 || !(o.square > 0))
    throw InputError("calibrate geometry: the board needs at least 3x3 inner corners and a positive square size");
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


/// The board's inner corners in the image, or nothing.
std::optional<std::vector<cv::Point2f>> FindBoard(const ImageRgb8& im, const CheckerboardOptions& o) {
  cv::Mat rgb(im.height, im.width, CV_8UC3, const_cast<std::uint8_t*>(im.data.data())), grey;
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  std::vector<cv::Point2f> found;
  if (!cv::findChessboardCorners(grey, cv::Size(o.inner_columns, o.inner_rows), found,
                                 cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE))
    return std::nullopt;
  cv::cornerSubPix(grey, found, cv::Size(5, 5), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-4));
  return found;
}

/// Depth points inside the board's outline: its corners taken to depth pixels through
/// normalized coordinates (undistorted; the small baseline is ignored), their hull shrunk by
/// a fifth towards the centre since the depth camera sees the board a little shifted.
std::vector<Eigen::Vector3d> DepthPointsOnBoard(const DepthColorView& v, const std::vector<cv::Point2f>& corners,
                                                const cv::Mat& K, const cv::Mat& dist) {
  std::vector<cv::Point2f> normalized, in_depth, hull;
  cv::undistortPoints(corners, normalized, K, dist);
  for (const cv::Point2f& p : normalized)
    in_depth.emplace_back(static_cast<float>(v.dfx * p.x + v.dcx), static_cast<float>(v.dfy * p.y + v.dcy));
  cv::convexHull(in_depth, hull);
  cv::Point2f centre(0, 0);
  for (const cv::Point2f& p : hull) centre += p * (1.f / hull.size());
  for (cv::Point2f& p : hull) p = centre + 0.8f * (p - centre);
  std::vector<Eigen::Vector3d> pts;
  for (int y = 0; y < v.depth_height; ++y)
    for (int x = 0; x < v.depth_width; ++x) {
      const float z = v.depth[static_cast<std::size_t>(y) * v.depth_width + x];
      if (z <= 0 || cv::pointPolygonTest(hull, cv::Point2f(static_cast<float>(x), static_cast<float>(y)), false) < 0)
        continue;
      pts.emplace_back((x - v.dcx) / v.dfx * z, (y - v.dcy) / v.dfy * z, z);
    }
  return pts;
}

void FitRigid(const std::vector<Eigen::Vector3d>& nc, const std::vector<double>& dc,
              const std::vector<Eigen::Vector3d>& nd, const std::vector<double>& dd,
              const std::vector<std::vector<Eigen::Vector3d>>& depth_points, ExtrinsicsFit* fit);

ExtrinsicsFit CalibrateDepthToColorImpl(const std::vector<DepthColorView>& views, const CameraModel& color,
                                        const CheckerboardOptions& o) {
  if (o.inner_columns < 3 || o.inner_rows < 3 || !(o.square > 0))
    throw InputError("calibrate extrinsics: the board needs at least 3x3 inner corners and a positive square size");
  if (!(color.fx > 0 && color.fy > 0)) throw InputError("calibrate extrinsics: the colour camera needs focal lengths");
  const cv::Mat K = (cv::Mat_<double>(3, 3) << color.fx, 0, color.cx, 0, color.fy, color.cy, 0, 0, 1);
  const cv::Mat dist(1, 5, CV_64F, const_cast<double*>(color.distortion.data()));
  std::vector<cv::Point3f> board;
  for (int r = 0; r < o.inner_rows; ++r)
    for (int c = 0; c < o.inner_columns; ++c)
      board.emplace_back(static_cast<float>(c * o.square), static_cast<float>(r * o.square), 0.f);
  std::vector<Eigen::Vector3d> nc, nd;  // plane normals in colour / depth
  std::vector<double> dc, dd;           // plane offsets: n . x + d = 0
  std::vector<std::vector<Eigen::Vector3d>> depth_points;
  for (const DepthColorView& v : views) {
    if (v.color.width != color.width || v.color.height != color.height)
      throw InputError("calibrate extrinsics: colour images must be " + std::to_string(color.width) + "x" +
                       std::to_string(color.height) + " (the calibrated camera)");
    if (v.depth.size() != static_cast<std::size_t>(v.depth_width) * v.depth_height || !(v.dfx > 0 && v.dfy > 0) ||
        !std::isfinite(v.dcx) || !std::isfinite(v.dcy))
      throw InputError("calibrate extrinsics: a depth map does not match its size or intrinsics");
    const auto corners = FindBoard(v.color, o);
    if (!corners) continue;
    cv::Mat rvec, tvec, R;
    if (!cv::solvePnP(board, *corners, K, dist, rvec, tvec)) continue;
    cv::Rodrigues(rvec, R);
    const Eigen::Vector3d n(R.at<double>(0, 2), R.at<double>(1, 2), R.at<double>(2, 2));
    const Eigen::Vector3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
    std::vector<Eigen::Vector3d> pts = DepthPointsOnBoard(v, *corners, K, dist);
    if (pts.size() < 50) continue;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : pts) mean += p / static_cast<double>(pts.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    Eigen::Vector3d n_d = eig.eigenvectors().col(0);
    if (n_d.dot(mean) > 0) n_d = -n_d;  // both normals face their camera
    Eigen::Vector3d n_c = n;
    if (n_c.dot(t) > 0) n_c = -n_c;
    nc.push_back(n_c);
    dc.push_back(-n_c.dot(t));
    nd.push_back(n_d);
    dd.push_back(-n_d.dot(mean));
    depth_points.push_back(std::move(pts));
  }
  ExtrinsicsFit fit;
  fit.views_used = static_cast<int>(nc.size());
  if (fit.views_used < 3)
    throw InputError("calibrate extrinsics: the board was found with depth in " + std::to_string(fit.views_used) +
                     " of " + std::to_string(views.size()) + " views; at least 3 are needed");
  FitRigid(nc, dc, nd, dd, depth_points, &fit);
  return fit;
}

/// color_from_depth from the boards' planes seen by both cameras (normals n and offsets d,
/// n . x + d = 0), and its plane RMS over the depth points: the rotation by Kabsch on the
/// normals (n_c = R n_d), the translation by least squares (x_c = R x_d + t, so on the plane
/// n_c . t = d_d - d_c).
void FitRigid(const std::vector<Eigen::Vector3d>& nc, const std::vector<double>& dc,
              const std::vector<Eigen::Vector3d>& nd, const std::vector<double>& dd,
              const std::vector<std::vector<Eigen::Vector3d>>& depth_points, ExtrinsicsFit* fit) {
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < nc.size(); ++k) H += nd[k] * nc[k].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
  const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
  Eigen::MatrixXd A(nc.size(), 3);
  Eigen::VectorXd b(nc.size());
  for (std::size_t k = 0; k < nc.size(); ++k) {
    A.row(static_cast<Eigen::Index>(k)) = nc[k].transpose();
    b[static_cast<Eigen::Index>(k)] = dd[k] - dc[k];
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> tsvd(A, Eigen::ComputeThinU | Eigen::ComputeThinV);
  if (tsvd.singularValues().minCoeff() < 0.05 * tsvd.singularValues().maxCoeff())
    throw InputError("calibrate extrinsics: the boards are tilted too alike (tilt them differently: left, right, up)");
  const Eigen::Vector3d t = tsvd.solve(b);
  fit->color_from_depth.block<3, 3>(0, 0) = R;
  fit->color_from_depth.block<3, 1>(0, 3) = t;
  double sum2 = 0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < nc.size(); ++k)
    for (const Eigen::Vector3d& p : depth_points[k]) {
      const double e = nc[k].dot(R * p + t) + dc[k];
      sum2 += e * e;
      ++n;
    }
  fit->plane_rms = std::sqrt(sum2 / std::max<std::size_t>(1, n));
}

}  // namespace

// OpenCV reports some bad input (odd boards, degenerate point sets) by throwing: that is
// the user's input, not a bug, so it becomes an InputError.
GeometryFit CalibrateGeometry(const std::vector<ImageRgb8>& images, const CheckerboardOptions& o) {
  try {
    return CalibrateGeometryImpl(images, o);
  } catch (const cv::Exception& e) {
    throw InputError(std::string("calibrate geometry: OpenCV could not use the images: ") + e.err);
  }
}

ExtrinsicsFit CalibrateDepthToColor(const std::vector<DepthColorView>& views, const CameraModel& color,
                                    const CheckerboardOptions& o) {
  try {
    return CalibrateDepthToColorImpl(views, color, o);
  } catch (const cv::Exception& e) {
    throw InputError(std::string("calibrate extrinsics: OpenCV could not use the views: ") + e.err);
  }
}

}  // namespace lp
