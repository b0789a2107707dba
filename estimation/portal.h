#pragma once
/// Portals: a window's opening as next-event estimation aims through it (path_tracer.h's
/// CellSampler), a rectangle through which the map is seen from inside the room, and the
/// portals of an estimate's windows (its openings and the holes its views saw).
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace lp {

class EnvMap;
struct EmitterShape;
struct SeenWindow;

/// A window's opening as next-event estimation sees it (a portal): a rectangle through which
/// the map is seen from inside the room. `axis_u` and `axis_v` are orthonormal, in its plane.
struct Portal {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_u = Eigen::Vector3d::UnitX(), axis_v = Eigen::Vector3d::UnitY();
  double half_u = 0, half_v = 0;
  double Area() const { return 4 * half_u * half_v; }
  /// The point at (u, v) in [0, 1)^2, uniform over the rectangle.
  Eigen::Vector3d Point(double u, double v) const {
    return centre + (2 * u - 1) * half_u * axis_u + (2 * v - 1) * half_v * axis_v;
  }
  /// Where the ray from `origin` along unit `w` crosses the rectangle: its distance, or 0 when
  /// it does not (behind the origin, beside the rectangle, or along its plane); `cos` the
  /// cosine to the rectangle's normal there.
  double Crossing(const Eigen::Vector3d& origin, const Eigen::Vector3d& w, double* cos) const;
};

/// The rectangle (in the plane through `point` with unit `normal`) that holds `points`
/// projected on that plane, its first axis along `along` projected on the plane.
Portal PortalAround(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& point,
                    const Eigen::Vector3d& normal, const Eigen::Vector3d& along);

/// The rectangle in an opening's plane (through its area's centre, facing its surface's
/// summed normal) that holds its triangles, its first axis horizontal (across `up`).
Portal PortalOf(const EmitterShape& opening, const Eigen::Vector3d& up);

/// The rectangle on a seen hole's wall that holds its outline, its first axis horizontal;
/// false where the hole has none (seen too near edge on).
bool PortalOf(const SeenWindow& hole, const Eigen::Vector3d& up, Portal* out);

/// The light a map (`rgb`: 3 * env.size() radiances) sends into a room through `window`, a
/// hole in a thin wall whose unit normal `inward` points into the room: its area times, over
/// the directions out through it, the radiance times the cosine to the wall (image units x
/// m^2 x sr: watts when the images are radiance; a diffuse pane of radiance L sends
/// pi L area). Each cell's cosine is averaged over 64 stratified directions in it.
Eigen::Vector3d PowerThrough(const Portal& window, const Eigen::Vector3d& inward, const EnvMap& env,
                             const std::vector<double>& rgb);

}  // namespace lp
