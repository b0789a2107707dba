#pragma once
/// How well the images fix each light (issue 42; docs/method.md, "Uncertainty"): the
/// covariance of its shape and the standard deviation of its scale, marginal over the other
/// lights and the map's lit cells (nuisance parameters), from the data term's Gauss-Newton
/// curvature with the cells at zero held there (active constraints; the activation penalty,
/// concave, left out) and a sandwich over blocks of pixels (neighbouring residuals are
/// correlated: the model's errors are spatially smooth), each block left out in turn (the
/// jackknife, CR3: a fit follows the few blocks that fix a light). It is conditional on the mesh and
/// the albedo: their errors are not in it.
#include <vector>

#include <Eigen/Core>

#include "estimation/lights/light.h"

namespace lp {

struct LightFitProblem;  // estimation/light_fit.h
struct TransportMatrix;  // estimation/transport.h

struct LightUncertainty {
  /// The shape's covariance in world coordinates: a lamp's position (m^2); a directional
  /// light's direction in its tangent plane (radians^2), embedded in world coordinates
  /// (rank 2: nothing along the direction itself).
  Eigen::Matrix3d shape_covariance = Eigen::Matrix3d::Zero();
  /// Per channel, the standard deviation of its Scale (a lamp's intensity, a directional
  /// light's irradiance), in the same units.
  Eigen::Vector3d scale_sigma = Eigen::Vector3d::Zero();
  /// A lamp's: the largest ratio, over directions, of its place's variance from its columns'
  /// Monte Carlo noise (the paths' parts) to the images' (the blocks left out): above 1 the
  /// paths, not the images, limit where the lamp is. 0 for other lights.
  double paths_ratio = 0;
};

/// The square of the 95 % quantile of the chi distribution with 3 / 2 degrees of freedom:
/// a position / a direction is inside its 95 % region when its Mahalanobis distance is at
/// most sqrt of these (2.80 and 2.45).
inline constexpr double kChiSquare95Dim3 = 7.814727903251178;
inline constexpr double kChiSquare95Dim2 = 5.991464547107979;

/// The uncertainty of `lights` fitted by `problem` (its rows, observations, loss; `base`
/// the map's render, A lambda, so that y - base - the lights is the residual), with the
/// map's lit cells (lambda > 0 in a channel: that channel is a parameter, its column A's)
/// as nuisance parameters when `map` is given. `row_block`: per row its block (0 ..), the
/// units the sandwich treats as independent. One per light, in its order. Where the data do
/// not fix a parameter at all (a singular curvature) its variance is infinite.
std::vector<LightUncertainty> LightUncertainties(const LightFitProblem& problem, const std::vector<Light>& lights,
                                                 const TransportMatrix* map, const std::vector<double>& lambda,
                                                 const std::vector<int>& row_block);

/// The 95 % region of a light's shape (`dims`: its ShapeDims, 3 or 2, whose bound it takes):
/// its semi-axes (ascending; a direction's smallest, along the direction itself, 0) and
/// their directions (columns); false when the covariance is unknown.
bool Region95(const Eigen::Matrix3d& covariance, int dims, Eigen::Vector3d* semi_axes, Eigen::Matrix3d* axes);

/// The squared Mahalanobis distance of a shape error `d` (world coordinates; a direction's
/// in its tangent plane) under `covariance` (its pseudo-inverse where it is rank 2).
double SquaredMahalanobis(const Eigen::Vector3d& d, const Eigen::Matrix3d& covariance);

/// The largest, over directions u, of uᵀ `of` u / uᵀ `to` u (the largest generalized
/// eigenvalue): how many times one covariance exceeds another where it does most. 0 where
/// `to` is not positive definite (infinite or unknown somewhere) or not finite.
double LargestVarianceRatio(const Eigen::Matrix3d& of, const Eigen::Matrix3d& to);

}  // namespace lp
