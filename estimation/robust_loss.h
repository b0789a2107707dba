#pragma once
/// The robust loss every fit of the estimator shares (the paper's Cauchy loss), as a value
/// in the manner of Ceres' CauchyLoss: its value, and the weight its iteratively
/// reweighted least squares give a residual.
#include <cmath>
#include <vector>

namespace lp {

struct CauchyLoss {
  double sigma = 0.5;  ///< the scale, in the residuals' units
  /// sigma^2/2 log(1 + r^2/sigma^2).
  double Value(double r) const { return 0.5 * (sigma * sigma) * std::log1p(r * r / (sigma * sigma)); }
  /// The sum of Value over `r`.
  double Sum(const std::vector<double>& r) const {
    const double s2 = sigma * sigma;
    double e = 0;
    for (double v : r) e += 0.5 * s2 * std::log1p(v * v / s2);
    return e;
  }
  /// rho'(r) / r = 1 / (1 + r^2/sigma^2): the weight of a residual in reweighted least squares.
  double Weight(double r) const { return 1 / (1 + r * r / (sigma * sigma)); }
  /// rho''(r) = (1 - r^2/sigma^2) / (1 + r^2/sigma^2)^2: what a zero-mean noise of variance v
  /// in r adds to rho's expectation is about rho''(r) v / 2.
  double Curvature(double r) const {
    const double t = r * r / (sigma * sigma);
    return (1 - t) / ((1 + t) * (1 + t));
  }
};

}  // namespace lp
