#pragma once
/// The tangent frame of a unit direction on the sphere, written once for every light kind:
/// a light's disc across the direction towards it (soft shadows) and a directional light's
/// steps across the sphere (its refinement and search). The path tracers' sampling frames
/// (estimation/sampling.h) have their own, opposite-handed convention, which their random
/// draws are tied to.
#include <cmath>
#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace lp {

/// Unit t and b with (t, b, l) orthonormal, for unit `l`: t = a x l normalized with a the
/// x axis unless l is within 26 degrees of it (then the y axis), b = l x t.
struct SphereFrame {
  explicit SphereFrame(const Eigen::Vector3d& l)
      : t((std::abs(l.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).cross(l).normalized()),
        b(l.cross(t)) {}
  Eigen::Vector3d t, b;
};

/// splitmix64 of `z` as a number in [0, 1): the jitter of a light's disc of shadow rays,
/// drawn from a key so that the same key gives the same pattern (common random numbers
/// across a light's shapes).
inline double HashUnit(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

/// Shadow rays per vertex from a column towards a light with a size (its disc, stratified),
/// where the columns of sizes are compared (a lamp's radius chosen) and for a sun's disc.
constexpr int kSphereShadowRays = 4;
/// Shadow rays per vertex from a lamp's column in the rounds' fits: a row averages over its
/// tens of vertices (8-24 paths a pixel, combined over rounds), each with its own point of
/// the disc, so two rays each estimate the penumbra as well as four do for half the rays
/// (one each let the penumbra's noise move the compass search: docs/benchmarks.md, session 33). Choosing the radius compares columns of different
/// sizes, whose noise the loss would count against the larger: that keeps kSphereShadowRays.
constexpr int kColumnShadowRays = 2;

}  // namespace lp
