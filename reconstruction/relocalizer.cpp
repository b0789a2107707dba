// The only reconstruction file with OpenCV: ORB features, matching, PnP + RANSAC.
#include "reconstruction/relocalizer.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <deque>

#include <Eigen/Geometry>

namespace lp {

namespace {

struct Memory {
  RgbdFrame frame;  // kept until features are needed (most runs never relocalize)
  Eigen::Matrix4d world_from_camera = Eigen::Matrix4d::Identity();
  bool computed = false;
  cv::Mat descriptors;             // rows of features with a world point
  std::vector<cv::Point3f> world;  // one per row
};

cv::Mat Grey(const ImageRgb8& image) {
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.data.data()));
  cv::Mat grey;
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  return grey;
}

}  // namespace

struct Relocalizer::Impl {
  RelocalizerOptions o;
  cv::Ptr<cv::ORB> orb;
  std::deque<Memory> memory;
};

Relocalizer::Relocalizer(const RelocalizerOptions& o) : impl_(std::make_unique<Impl>()) {
  impl_->o = o;
  impl_->orb = cv::ORB::create(o.features);
}

Relocalizer::~Relocalizer() = default;

bool Relocalizer::empty() const { return impl_->memory.empty(); }

void Relocalizer::Remember(const RgbdFrame& f, const Eigen::Matrix4d& world_from_camera) {
  if (!f.registered || f.depth.width != f.color.width || f.depth.height != f.color.height) return;
  Memory m;
  m.frame.color = f.color;
  m.frame.depth = f.depth;
  m.frame.color_intrinsics = f.color_intrinsics;
  m.world_from_camera = world_from_camera;
  impl_->memory.push_back(std::move(m));
  while (static_cast<int>(impl_->memory.size()) > impl_->o.keep) impl_->memory.pop_front();
}

namespace {

/// Features of a remembered frame with world positions from its depth.
void ComputeFeatures(cv::ORB& orb, Memory* m) {
  const RgbdFrame& f = m->frame;
  std::vector<cv::KeyPoint> keys;
  cv::Mat desc;
  orb.detectAndCompute(Grey(f.color), cv::noArray(), keys, desc);
  const Camera& k = f.color_intrinsics;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    // Corners sit on edges, where depth is often missing: the nearest surface within
    // 2 pixels (the smallest valid depth: a corner belongs to the front object).
    const int x = static_cast<int>(std::lround(keys[i].pt.x)), y = static_cast<int>(std::lround(keys[i].pt.y));
    float z = 0;
    for (int dy = -2; dy <= 2; ++dy)
      for (int dx = -2; dx <= 2; ++dx) {
        const int xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= f.depth.width || yy >= f.depth.height) continue;
        const float d = f.depth.data[static_cast<std::size_t>(yy) * f.depth.width + xx] * 1e-3f;
        if (d > 0 && (z == 0 || d < z)) z = d;
      }
    if (z <= 0) continue;
    const Eigen::Vector3d pc((keys[i].pt.x - k.cx) / k.fx * z, (keys[i].pt.y - k.cy) / k.fy * z, z);
    const Eigen::Vector3d pw = (m->world_from_camera * pc.homogeneous()).head<3>();
    m->descriptors.push_back(desc.row(static_cast<int>(i)));
    m->world.emplace_back(static_cast<float>(pw.x()), static_cast<float>(pw.y()), static_cast<float>(pw.z()));
  }
  m->computed = true;
  m->frame = RgbdFrame{};  // the images are no longer needed
}

}  // namespace

std::optional<Eigen::Matrix4d> Relocalizer::Locate(const RgbdFrame& f) {
  if (impl_->memory.empty()) return std::nullopt;
  for (Memory& m : impl_->memory)
    if (!m.computed) ComputeFeatures(*impl_->orb, &m);
  std::vector<cv::KeyPoint> keys;
  cv::Mat desc;
  impl_->orb->detectAndCompute(Grey(f.color), cv::noArray(), keys, desc);
  if (desc.empty()) return std::nullopt;
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<cv::Point3f> world;
  std::vector<cv::Point2f> image;
  for (const Memory& m : impl_->memory) {
    if (m.world.size() < static_cast<std::size_t>(impl_->o.min_inliers)) continue;
    std::vector<std::vector<cv::DMatch>> knn;
    matcher.knnMatch(desc, m.descriptors, knn, 2);
    for (const auto& pair : knn)  // Lowe's ratio test
      if (pair.size() == 2 && pair[0].distance < 0.8f * pair[1].distance) {
        image.push_back(keys[static_cast<std::size_t>(pair[0].queryIdx)].pt);
        world.push_back(m.world[static_cast<std::size_t>(pair[0].trainIdx)]);
      }
  }
  if (world.size() < static_cast<std::size_t>(impl_->o.min_inliers)) return std::nullopt;
  const Camera& k = f.color_intrinsics;
  const cv::Mat K = (cv::Mat_<double>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  if (!cv::solvePnPRansac(world, image, K, cv::noArray(), rvec, tvec, false, 300,
                          static_cast<float>(impl_->o.reprojection), 0.999, inliers) ||
      static_cast<int>(inliers.size()) < impl_->o.min_inliers)
    return std::nullopt;
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix4d camera_from_world = Eigen::Matrix4d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) camera_from_world(r, c) = R.at<double>(r, c);
    camera_from_world(r, 3) = tvec.at<double>(r);
  }
  return camera_from_world.inverse();
}

}  // namespace lp
