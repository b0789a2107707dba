#pragma once
/// Every kind of light beside the environment map, behind one interface (in the manner of
/// pbrt-v4's Light): a closed set of kinds, each in its own file under estimation/lights/
/// with what only it knows, and these functions that any code handling "a light" calls.
/// A new kind: its file (its struct, UnitColumn, Irradiance, SameShape, Scale, ShapeDims /
/// ShapeBasis / Moved, CompassMoves / CompassUnit / CompassMove / ShapeDistance), its test, and its
/// entry in `Light` below (docs/architecture.md, "Light kinds").
#include <cstdint>
#include <limits>
#include <type_traits>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "estimation/lights/directional_light.h"
#include "estimation/lights/emitter_light.h"
#include "estimation/lights/point_light.h"

namespace lp {

using Light = std::variant<PointLight, DirectionalLight, EmitterLight>;

/// The light's column of unit scale on shading vertices (3 per row), and its derivative
/// with respect to the shape (9 per row: [9*row + 3*c + k], the kind's 3 raw coordinates;
/// ShapeGradient maps them to the shape's); with the halves' difference and its derivative
/// when asked (ColumnOut). Each kind gives the ColumnOut form.
inline void UnitColumn(const RayTracer& scene, const ShadingVertices& vertices, const Light& light,
                       const ColumnOut& out) {
  std::visit([&](const auto& l) { UnitColumn(scene, vertices, l, out); }, light);
}
inline void UnitColumn(const RayTracer& scene, const ShadingVertices& vertices, const Light& light,
                       std::vector<float>* out, std::vector<float>* jacobian = nullptr) {
  UnitColumn(scene, vertices, light, ColumnOut{out, jacobian});
}
/// Whether two lights are of one kind and one shape (the same column), their scales aside.
inline bool SameShape(const Light& a, const Light& b) {
  return a.index() == b.index() &&
         std::visit([&](const auto& l) { return SameShape(l, std::get<std::decay_t<decltype(l)>>(b)); }, a);
}
inline Eigen::Vector3d& Scale(Light& light) {
  return std::visit([](auto& l) -> Eigen::Vector3d& { return Scale(l); }, light);
}
inline const Eigen::Vector3d& Scale(const Light& light) {
  return std::visit([](const auto& l) -> const Eigen::Vector3d& { return Scale(l); }, light);
}
inline int ShapeDims(const Light& light) {
  return std::visit([](const auto& l) { return ShapeDims(l); }, light);
}
/// The directions (the first ShapeDims columns) a step of each shape coordinate moves the
/// kind's 3 raw coordinates at this shape.
inline Eigen::Matrix3d ShapeBasis(const Light& light) {
  return std::visit([](const auto& l) { return ShapeBasis(l); }, light);
}
/// A column's derivative in the shape's coordinates: its 3 raw entries `d` (a row and
/// channel of UnitColumn's Jacobian) along each of `basis`'s first `dims` columns.
inline void ShapeGradient(const Eigen::Matrix3d& basis, int dims, const float* d, double* out) {
  const Eigen::Vector3d v(d[0], d[1], d[2]);
  for (int a = 0; a < dims; ++a) out[a] = v.dot(basis.col(a));
}
inline Light Moved(const Light& light, const double* step) {
  return std::visit([&](const auto& l) -> Light { return Moved(l, step); }, light);
}
/// How far apart two lights' shapes are in CompassUnits of `b` (a lamp's move over its
/// distance from `centre`, a direction's angle); infinite for two kinds.
inline double ShapeDistance(const Light& a, const Light& b, const Eigen::Vector3d& centre) {
  if (a.index() != b.index()) return std::numeric_limits<double>::infinity();
  return std::visit([&](const auto& l) { return ShapeDistance(l, std::get<std::decay_t<decltype(l)>>(b), centre); },
                    a);
}
inline int CompassMoves(const Light& light) {
  return std::visit([](const auto& l) { return CompassMoves(l); }, light);
}
inline double CompassUnit(const Light& light, const Eigen::Vector3d& centre) {
  return std::visit([&](const auto& l) { return CompassUnit(l, centre); }, light);
}
inline Light CompassMove(const Light& light, int move, double step) {
  return std::visit([&](const auto& l) -> Light { return CompassMove(l, move, step); }, light);
}

/// The irradiance (image units) a light sends to a surface point (its kind's Irradiance).
inline Eigen::Vector3d Irradiance(const RayTracer& scene, const Light& light, const Eigen::Vector3d& origin,
                                  const Eigen::Vector3d& n, const Eigen::Vector3d& g, std::uint64_t key,
                                  std::int64_t* rays) {
  return std::visit([&](const auto& l) { return Irradiance(scene, l, origin, n, g, key, rays); }, light);
}
/// The irradiance the lights send to a surface point, summed in their order: what the
/// renderers and the lit shading add at a path vertex.
Eigen::Vector3d Irradiance(const RayTracer& scene, const std::vector<Light>& lights, const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& n, const Eigen::Vector3d& g, std::uint64_t key,
                           std::int64_t* rays);

/// The radiance a viewer (`towards_viewer`, unit) sees leave a surface point by a light's
/// own glow: an emitter's where the point is on it, else 0.
inline Eigen::Vector3d Emission(const Light& light, const Eigen::Vector3d& point, const Eigen::Vector3d& towards_viewer) {
  if (const EmitterLight* e = std::get_if<EmitterLight>(&light)) return Emission(*e, point, towards_viewer);
  return Eigen::Vector3d::Zero();
}
/// The same summed over `lights`.
Eigen::Vector3d Emission(const std::vector<Light>& lights, const Eigen::Vector3d& point,
                         const Eigen::Vector3d& towards_viewer);

/// The lights of a list of one kind as `Light`s, and back (those of kind T).
template <class T>
std::vector<Light> AsLights(const std::vector<T>& lights) {
  return std::vector<Light>(lights.begin(), lights.end());
}
template <class T>
std::vector<T> OfKind(const std::vector<Light>& lights) {
  std::vector<T> out;
  for (const Light& l : lights)
    if (const T* t = std::get_if<T>(&l)) out.push_back(*t);
  return out;
}

}  // namespace lp
