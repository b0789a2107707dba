#pragma once
/// Point-set geometry done with PCL (kept inside geometry.cpp): the dominant horizontal
/// plane by RANSAC, and nearest-neighbour distances between point sets (k-d tree).

#include <optional>
#include <vector>

#include <Eigen/Core>

namespace lp {

/// A plane n . x + d = 0 with unit normal n.
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 0;
  int inliers = 0;
};

/// The plane with the most points within `distance` (metres) whose normal is within
/// `max_angle_deg` of `rough_up`'s axis (RANSAC over at most 50,000 of the points), its
/// normal turned to `rough_up`'s side: up for a floor below the cameras and for a ceiling
/// above them alike (a normal turned towards the camera would point down from a ceiling).
/// Empty when no such plane holds at least `min_fraction` of the points.
std::optional<Plane> DominantPlane(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3d& rough_up,
                                   double max_angle_deg = 30, double distance = 0.02, double min_fraction = 0.05);

/// For each point of `from`, the distance to the nearest point of `to` (metres).
std::vector<float> NearestDistances(const std::vector<Eigen::Vector3f>& from, const std::vector<Eigen::Vector3f>& to);

}  // namespace lp
