#pragma once
/// Sampling helpers shared by the tracers.
#include <cmath>
#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace lp {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInvPi = 1.0 / kPi;

/// Cosine-weighted direction about unit `n` (pdf cos(theta)/pi).
inline Eigen::Vector3d SampleCosine(const Eigen::Vector3d& n, double u1, double u2) {
  const double r = std::sqrt(u1), phi = 2 * kPi * u2;
  const double x = r * std::cos(phi), y = r * std::sin(phi), z = std::sqrt(std::max(0.0, 1 - u1));
  const Eigen::Vector3d a = std::abs(n.x()) > 0.9 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d t = n.cross(a).normalized();
  const Eigen::Vector3d b = n.cross(t);
  return (x * t + y * b + z * n).normalized();
}

/// Direction uniformly inside the cone around unit `axis` with cos half-angle `cos_max`
/// (pdf 1 / (2*pi*(1 - cos_max))).
inline Eigen::Vector3d SampleCone(const Eigen::Vector3d& axis, double cos_max, double u1, double u2) {
  const double z = 1 - u1 * (1 - cos_max);
  const double s = std::sqrt(std::max(0.0, 1 - z * z)), phi = 2 * kPi * u2;
  const Eigen::Vector3d a = std::abs(axis.x()) > 0.9 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d t = axis.cross(a).normalized();
  const Eigen::Vector3d b = axis.cross(t);
  return (s * std::cos(phi) * t + s * std::sin(phi) * b + z * axis).normalized();
}

/// The k-th point of the two-dimensional Sobol sequence (a (0,2)-sequence: every first 2^m
/// points put one in each of the 2^m elementary intervals of any shape), in [0, 1)².
/// Shifted by a random offset modulo 1 per estimate (Cranley-Patterson rotation) it stays
/// unbiased, and a smooth integrand's error falls faster than with independent points.
inline void Sobol2(std::uint32_t k, double* u1, double* u2) {
  std::uint32_t x = 0, y = 0, v = 1u << 31;
  for (std::uint32_t i = k, bit = 0; i != 0; i >>= 1, ++bit) {
    if (i & 1u) {
      x ^= 1u << (31 - bit);
      y ^= v;
    }
    v ^= v >> 1;
  }
  *u1 = x * (1.0 / 4294967296.0);
  *u2 = y * (1.0 / 4294967296.0);
}

/// Power heuristic (beta = 2) weight of strategy a against b.
inline double PowerHeuristic(double pdf_a, double pdf_b) {
  const double a2 = pdf_a * pdf_a, b2 = pdf_b * pdf_b;
  return a2 + b2 > 0 ? a2 / (a2 + b2) : 0.0;
}

}  // namespace lp
