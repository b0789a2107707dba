#pragma once
/// The spherical-harmonics export for AR engines (ARCore, ARKit, three.js's LightProbe,
/// Unity): DIR/lighting.json with order-2 real SH of the radiance and of the irradiance,
/// a main light, and the point and directional lights by value. docs/formats.md, "Exports".
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/image.h"
#include "estimation/lights/directional_light.h"
#include "estimation/lights/emitter_light.h"
#include "exports/export_scene.h"

namespace lp {

/// Nine RGB coefficients, in the order (l, m) = (0,0), (1,-1), (1,0), (1,1), (2,-2), (2,-1),
/// (2,0), (2,1), (2,2).
using Sh9 = std::array<Eigen::Vector3d, 9>;

/// The real SH basis, orthonormal over the sphere (integral of Y_i Y_j = delta_ij), of a unit
/// direction d = (x, y, z): 0.282095; 0.488603 (y, z, x); 1.092548 xy, 1.092548 yz,
/// 0.315392 (3z^2 - 1), 1.092548 xz, 0.546274 (x^2 - y^2).
std::array<double, 9> ShBasis(const Eigen::Vector3d& d);

/// The radiance coefficients L_i = integral of L(w) Y_i(w) dw of an equirectangular map
/// (EnvMap's convention around `up`), each pixel integrated over `sub` x `sub` points with
/// their exact solid angles; directions are turned by `frame_from_world` before the basis.
Sh9 ProjectMap(const ImageRGB& map, const Eigen::Vector3d& up, const Eigen::Matrix3d& frame_from_world, int sub = 4);
/// Adds a directional light (a delta of its irradiance along its direction) to `sh`.
void AddDirectional(const DirectionalLight& light, const Eigen::Matrix3d& frame_from_world, Sh9* sh);
/// Adds a glowing surface as seen from `at` (its radiance over the solid angle of each of its
/// triangles' pieces on the side that emits; nothing in between is taken to block it).
void AddEmitter(const EmitterLight& light, const Eigen::Vector3d& at, const Eigen::Matrix3d& frame_from_world, Sh9* sh);
/// The solid angle of triangle (a, b, c) seen from the origin (Van Oosterom and Strackee 1983).
double TriangleSolidAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c);
/// Irradiance coefficients: the radiance's convolved with the clamped cosine (Ramamoorthi
/// and Hanrahan 2001): times pi (l = 0), 2pi/3 (l = 1), pi/4 (l = 2).
Sh9 IrradianceFromRadiance(const Sh9& radiance);
/// Sum of c_i Y_i(d).
Eigen::Vector3d EvaluateSh(const Sh9& sh, const Eigen::Vector3d& d);

/// The irradiance a surface with unit normal `n` receives from the map (the same quadrature as
/// ProjectMap, `n` in the world frame) and the directional lights, without truncation.
Eigen::Vector3d MapIrradiance(const ImageRGB& map, const Eigen::Vector3d& up, const Eigen::Vector3d& n, int sub = 2);

std::vector<std::string> WriteShExport(const ExportScene& scene, const std::filesystem::path& dir);

}  // namespace lp
