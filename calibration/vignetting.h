#pragma once
/// Vignetting as Kim & Pollefeys (2008) model it: V(r) = 1 + a r^2 + b r^4 + c r^6 about
/// the image centre, r the distance from it over the half diagonal (0 at the centre, 1 in
/// the corners). A pixel's irradiance is its linear value divided by V(r).

#include <vector>

#include "common/image.h"

namespace lp {

struct Vignetting {
  double a = 0, b = 0, c = 0;
  double cx = -1, cy = -1;  ///< centre in pixels (-1: the image centre)
  /// V at pixel (x, y) of a width x height image.
  double At(double x, double y, int width, int height) const;
  bool identity() const { return a == 0 && b == 0 && c == 0; }
  /// V above 0.05 for r up to 1 (At() holds V(1) beyond, as an off-centre centre can
  /// reach past the corners): a correction that would not divide by ~0 or flip signs.
  bool Plausible() const;
};

/// From images of a uniformly lit flat target filling the view (linear values, e.g. after
/// the inverse response; averaged over the images and channels): I(x) = k V(r(x)) by
/// linear least squares. Pixels that are not finite or not positive are skipped. Throws
/// InputError for no images or mismatched sizes.
Vignetting FitVignettingFlatField(const std::vector<ImageRGB>& images);

/// One surface point seen twice: linear values and the radii (0..1) where it was seen.
struct VignettingPair {
  double value_i, r_i, value_j, r_j;
};

/// From the same surface points seen at different image radii (keyframes of a
/// reconstruction): value_i / V(r_i) = value_j / V(r_j), fitted in logarithms (linear in
/// the coefficients of log V, unbiased by noise in the values), then V projected onto the
/// model. Throws
/// InputError with too few pairs or radii too alike to tell V apart.
Vignetting FitVignettingPairs(const std::vector<VignettingPair>& pairs);

}  // namespace lp
