// PCL stays in this file (and marching_cubes.cpp): its headers are slow to compile.
#include "reconstruction/geometry.h"

#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <cmath>

#include "common/parallel.h"

namespace lp {

namespace {

pcl::PointCloud<pcl::PointXYZ>::Ptr ToCloud(const std::vector<Eigen::Vector3f>& points, std::size_t max_points) {
  auto cloud = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  const std::size_t stride = std::max<std::size_t>(1, (points.size() + max_points - 1) / max_points);
  for (std::size_t i = 0; i < points.size(); i += stride)
    if (points[i].allFinite()) cloud->push_back(pcl::PointXYZ(points[i].x(), points[i].y(), points[i].z()));
  return cloud;
}

}  // namespace

std::optional<Plane> DominantPlane(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3d& rough_up,
                                   double max_angle_deg, double distance, double min_fraction) {
  const auto cloud = ToCloud(points, 50000);
  if (cloud->size() < 10) return std::nullopt;
  pcl::SACSegmentation<pcl::PointXYZ> seg;
  seg.setOptimizeCoefficients(true);
  // A plane perpendicular to the axis: its normal within eps_angle of rough_up.
  seg.setModelType(pcl::SACMODEL_PERPENDICULAR_PLANE);
  seg.setMethodType(pcl::SAC_RANSAC);
  seg.setAxis(rough_up.normalized().cast<float>());
  seg.setEpsAngle(max_angle_deg * 3.14159265358979323846 / 180);
  seg.setDistanceThreshold(distance);
  seg.setMaxIterations(500);
  seg.setInputCloud(cloud);
  pcl::PointIndices inliers;
  pcl::ModelCoefficients coefficients;
  seg.segment(inliers, coefficients);
  if (coefficients.values.size() != 4 || inliers.indices.size() < min_fraction * cloud->size()) return std::nullopt;
  Plane plane;
  plane.normal = Eigen::Vector3d(coefficients.values[0], coefficients.values[1], coefficients.values[2]);
  const double len = plane.normal.norm();
  if (!(len > 0)) return std::nullopt;
  plane.normal /= len;
  plane.d = coefficients.values[3] / len;
  if (plane.normal.dot(rough_up) < 0) {
    plane.normal = -plane.normal;
    plane.d = -plane.d;
  }
  plane.inliers = static_cast<int>(inliers.indices.size());
  return plane;
}

std::vector<float> NearestDistances(const std::vector<Eigen::Vector3f>& from, const std::vector<Eigen::Vector3f>& to) {
  std::vector<float> out(from.size(), std::numeric_limits<float>::infinity());
  const auto cloud = ToCloud(to, to.size() + 1);
  if (cloud->empty()) return out;
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(cloud);
  ParallelForChunks(0, from.size(), 1024, [&](std::size_t i0, std::size_t i1) {
    std::vector<int> index(1);
    std::vector<float> sq(1);
    for (std::size_t i = i0; i < i1; ++i) {
      const pcl::PointXYZ q(from[i].x(), from[i].y(), from[i].z());
      if (from[i].allFinite() && tree.nearestKSearch(q, 1, index, sq) == 1) out[i] = std::sqrt(sq[0]);
    }
  });
  return out;
}

}  // namespace lp
