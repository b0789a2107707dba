#pragma once
/// A sun, or a lamp too far for its position to matter: light from one direction, the
/// lighting model's kind beside the map and the point lights. lights.json's
/// "directional_lights" (docs/formats.md). What only this kind knows: its unit column on
/// shading vertices and the column's derivative across the sphere, the light it sends to a
/// point, its shape (a direction on S^2, stepped in its tangent plane) and how a step moves it.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "estimation/lights/sphere_frame.h"
#include "estimation/shading_vertices.h"
#include "scene/ray_tracer.h"

namespace lp {

struct DirectionalLight {
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  ///< unit, towards the light, world frame
  /// Irradiance in image units on a surface facing the light (W/m^2 when the images are
  /// radiance): a Lambertian surface of albedo rho at angle theta to it has radiance
  /// rho / pi x irradiance x cos theta.
  Eigen::Vector3d irradiance = Eigen::Vector3d::Zero();
  double angular_radius = 0;  ///< the half-angle of its disc, radians; 0: sharp shadows
};

/// The share of a light of `angular_radius` (a disc around unit direction l, as seen from
/// p) that p sees: one shadow ray along l when sharp, else `rays` jittered stratified rays
/// across the disc, the pattern drawn from a hash of `key` (as SphereVisibility's).
double ConeVisibility(const RayTracer& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& l, double angular_radius,
                      std::uint64_t key, int rays = kSphereShadowRays);

/// The column of a directional light of unit irradiance (on a surface facing it) from unit
/// world direction `towards` (towards the light): out[3*row + c]. When `jacobian` is given
/// it receives the derivative with respect to the direction moved on the unit sphere
/// (towards + delta, normalized; visibility held fixed) at [9*row + 3*c + k]. With an
/// `angular_radius` (a disc of that half-angle) each vertex sends kSphereShadowRays shadow
/// rays across it (ConeVisibility, a fixed pattern per vertex). ColumnOut: with the
/// halves' difference when asked.
void DirectionalLightColumn(const RayTracer& scene, const ShadingVertices& vertices, const Eigen::Vector3d& towards,
                            const ColumnOut& out, double angular_radius = 0);
inline void DirectionalLightColumn(const RayTracer& scene, const ShadingVertices& vertices,
                                   const Eigen::Vector3d& towards, std::vector<float>* out,
                                   std::vector<float>* jacobian = nullptr, double angular_radius = 0) {
  DirectionalLightColumn(scene, vertices, towards, ColumnOut{out, jacobian}, angular_radius);
}
inline void UnitColumn(const RayTracer& scene, const ShadingVertices& vertices, const DirectionalLight& light,
                       const ColumnOut& out) {
  DirectionalLightColumn(scene, vertices, light.direction, out, light.angular_radius);
}

/// The irradiance (image units) the light sends to a surface point `origin` (already off
/// the surface) of shading normal `n` and geometric normal `g`: 0 where it is behind
/// either; one shadow ray across its disc jittered by `key`, counted in `rays`.
Eigen::Vector3d Irradiance(const RayTracer& scene, const DirectionalLight& light, const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& n, const Eigen::Vector3d& g, std::uint64_t key,
                           std::int64_t* rays);

/// Whether two directional lights have one shape (their columns are the same).
inline bool SameShape(const DirectionalLight& a, const DirectionalLight& b) {
  return a.direction == b.direction && a.angular_radius == b.angular_radius;
}

/// Its RGB scale, the unknown of the linear problem: the irradiance.
inline Eigen::Vector3d& Scale(DirectionalLight& l) { return l.irradiance; }
inline const Eigen::Vector3d& Scale(const DirectionalLight& l) { return l.irradiance; }

/// Its shape is its direction: 2 coordinates, steps along the tangent frame (SphereFrame)
/// at the direction (ShapeBasis: t and b as its first two columns; a column's derivative
/// along them is its Jacobian's entries dotted with each). Moved takes a step and normalizes.
inline int ShapeDims(const DirectionalLight&) { return 2; }
inline Eigen::Matrix3d ShapeBasis(const DirectionalLight& l) {
  const SphereFrame frame(l.direction);
  Eigen::Matrix3d basis = Eigen::Matrix3d::Zero();
  basis.col(0) = frame.t;
  basis.col(1) = frame.b;
  return basis;
}
inline DirectionalLight Moved(DirectionalLight l, const double* step) {
  const SphereFrame frame(l.direction);
  l.direction = (l.direction + step[0] * frame.t + step[1] * frame.b).normalized();
  return l;
}

/// A compass search's moves: across the sphere along the tangent frame both ways (4), by
/// an angle `step` in radians (CompassUnit 1).
inline int CompassMoves(const DirectionalLight&) { return 4; }
inline double CompassUnit(const DirectionalLight&, const Eigen::Vector3d&) { return 1; }
DirectionalLight CompassMove(DirectionalLight l, int move, double step);
/// How far `now` is from `was` in CompassUnits: the angle between their directions.
inline double ShapeDistance(const DirectionalLight& now, const DirectionalLight& was, const Eigen::Vector3d&) {
  return std::acos(std::clamp(now.direction.dot(was.direction), -1.0, 1.0));
}

}  // namespace lp
