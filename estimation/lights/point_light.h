#pragma once
/// A lamp in the room: the lighting model's near part beside the environment map.
/// lights.json's "point_lights" (docs/formats.md). What only this kind knows: its unit
/// column on shading vertices and the column's derivative with respect to its position, the
/// light it sends to a point, its shape (a position in R^3) and how a step moves it, where
/// candidates are first sought, and how two fold into one.
#include <algorithm>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "estimation/lights/sphere_frame.h"
#include "estimation/shading_vertices.h"
#include "scene/ray_tracer.h"

namespace lp {

struct PointLight {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< the bundle's world frame, metres
  /// Radiant intensity in image units x m^2: a surface facing the light at distance d
  /// receives intensity / d^2 (W/sr when the images are radiance).
  Eigen::Vector3d intensity = Eigen::Vector3d::Zero();
  double radius = 0;  ///< metres; 0: a point. A sphere's radius only softens its shadows
  /// Its place measured where the cameras saw it (a bulb's clipped blobs triangulated;
  /// docs/method.md, "A lamp where the camera saw it"), not fitted: its shape has no
  /// coordinates (no step or search moves it); its intensity and radius are fitted.
  bool held = false;
};

/// The share of a spherical light of `radius` centred at q that `p` sees (l, d: the unit
/// direction and distance from p to q): one shadow ray to q for a point (radius 0), else
/// `rays` shadow rays to jittered stratified points of the disc of `radius` facing p, the
/// pattern drawn from a hash of `key` (deterministic: common random numbers across positions
/// and radii; the renderers pass a key per sample and 1 ray). The cosine and 1/d^2 stay the
/// centre's: exact for a uniform sphere wholly seen and above the horizon, so the radius
/// only softens shadows.
double SphereVisibility(const RayTracer& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& q, double radius,
                        const Eigen::Vector3d& l, double d, std::uint64_t key, int rays = kSphereShadowRays);

/// The unit-intensity column of a point light at `q` (of `radius`: soft shadows, `rays`
/// shadow rays per vertex to its disc): out.value[3*row + c]; its derivative with respect to
/// q (out.jacobian: d value[3*row + c] / d q_k at [9*row + 3*c + k], visibility held fixed)
/// and its halves' difference (ColumnOut) when asked.
void PointLightColumn(const RayTracer& scene, const ShadingVertices& vertices, const Eigen::Vector3d& q,
                      const ColumnOut& out, double radius = 0, int rays = kColumnShadowRays);
inline void PointLightColumn(const RayTracer& scene, const ShadingVertices& vertices, const Eigen::Vector3d& q,
                             std::vector<float>* out, std::vector<float>* jacobian = nullptr, double radius = 0,
                             int rays = kColumnShadowRays) {
  PointLightColumn(scene, vertices, q, ColumnOut{out, jacobian}, radius, rays);
}
inline void UnitColumn(const RayTracer& scene, const ShadingVertices& vertices, const PointLight& light,
                       const ColumnOut& out) {
  PointLightColumn(scene, vertices, light.position, out, light.radius);
}

/// The irradiance (image units) the light sends to a surface point `origin` (already off
/// the surface) of shading normal `n` and geometric normal `g`: 0 where it is behind
/// either; one shadow ray to a point of its disc jittered by `key`, counted in `rays`.
Eigen::Vector3d Irradiance(const RayTracer& scene, const PointLight& light, const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& n, const Eigen::Vector3d& g, std::uint64_t key,
                           std::int64_t* rays);

/// Whether two lamps have one shape (their columns are the same), whatever their intensities.
inline bool SameShape(const PointLight& a, const PointLight& b) {
  return a.position == b.position && a.radius == b.radius;
}

/// Its RGB scale, the unknown of the linear problem: the intensity.
inline Eigen::Vector3d& Scale(PointLight& l) { return l.intensity; }
inline const Eigen::Vector3d& Scale(const PointLight& l) { return l.intensity; }

/// Its shape is its position: 3 coordinates, along the axes (ShapeBasis: the directions, as
/// columns, a step of each coordinate moves the position; a column's derivative along them
/// is its Jacobian's entries). Moved takes a step of them.
/// A held lamp's shape has none: no step moves it.
inline int ShapeDims(const PointLight& l) { return l.held ? 0 : 3; }
inline Eigen::Matrix3d ShapeBasis(const PointLight&) { return Eigen::Matrix3d::Identity(); }
inline PointLight Moved(PointLight l, const double* step) {
  if (!l.held) l.position += Eigen::Vector3d(step[0], step[1], step[2]);
  return l;
}

/// A compass search's moves: along each axis both ways (6), by `step` times its distance
/// from `centre` (CompassUnit) in metres.
inline int CompassMoves(const PointLight& l) { return l.held ? 0 : 6; }
inline double CompassUnit(const PointLight& l, const Eigen::Vector3d& centre) {
  return std::max((l.position - centre).norm(), 1e-6);
}
/// How far `now` is from `was` in CompassUnits of `was`: the move over its distance from
/// `centre`.
inline double ShapeDistance(const PointLight& now, const PointLight& was, const Eigen::Vector3d& centre) {
  return (now.position - was.position).norm() / CompassUnit(was, centre);
}
inline PointLight CompassMove(PointLight l, int move, double step) {
  if (!l.held) l.position[move / 2] += move % 2 ? -step : step;
  return l;
}

/// Where the estimator first looks for lamps: shells of directions (a coarse ring map
/// around `up`, `rings` rings) at each of `radii` (multiples of the scene's bounding radius)
/// around the scene's centre. Free space and the space beyond the scan alike: a candidate
/// inside geometry or behind a wall lights no observed pixel and drops out of the problem.
std::vector<Eigen::Vector3d> CandidatePositions(const Eigen::Vector3d& centre, double radius,
                                                const Eigen::Vector3d& up, int rings = 7,
                                                const std::vector<double>& radii = {0.35, 0.6, 1.0, 1.6});

/// Two lights closer than a tenth of `distance` (`other`'s from the scene's centre) are one:
/// then `into` takes `other`'s intensity, at the intensity-weighted mean of their places
/// (at the held one's place where either is held), and FoldInto returns true.
bool FoldInto(PointLight* into, const PointLight& other, double distance);

}  // namespace lp
