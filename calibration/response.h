#pragma once
/// The camera's inverse response f^-1: pixel value (0..1) -> relative irradiance, per
/// channel, as Mitsunaga & Nayar's polynomial (1999), fitted from an exposure bracket of
/// a static scene.

#include <array>
#include <vector>

#include "common/image.h"

namespace lp {

/// g(M) = sum_n c_n M^n with g(1) = 1 (irradiance relative to the value that just saturates).
struct InverseResponse {
  std::array<std::vector<double>, 3> coefficients;  ///< per channel R, G, B; c_0 first
  double Apply(int channel, double value) const;
  /// sRGB's inverse transfer function as a polynomial (the uncalibrated default).
  static InverseResponse Srgb();
};

struct ResponseFitOptions {
  int max_degree = 8;            ///< degrees 2..max tried per channel, the best kept
  double dark = 0.02, bright = 0.98;  ///< values outside are not used (noise, clipping)
  bool refine_ratios = true;     ///< re-estimate exposure ratios (Mitsunaga-Nayar iteration)
  int iterations = 20;
  int max_samples = 4000;        ///< pixel positions sampled (spread over the image)
};

struct ResponseFit {
  InverseResponse response;
  std::vector<double> exposures;  ///< as given or refined, relative to the first (= 1)
  std::array<int, 3> degree{};
  std::array<double, 3> rms{};    ///< fit residual per channel (irradiance units)
};

/// Fits the inverse response from images of one static scene at different exposures
/// (`exposures`: the camera's exposure times x gains, any scale; only their ratios
/// matter). Images must be the same size, at least two. With refine_ratios, the ratios
/// are re-estimated from the images starting from the given ones, keeping their product
/// (the overall range) as given: g -> g^k with R -> R^k fits equally well, so that one
/// number must come from the camera. Throws InputError on bad input (sizes,
/// fewer than 2 images, exposures not positive, too few usable pixels).
ResponseFit FitResponse(const std::vector<ImageRgb8>& images, const std::vector<double>& exposures,
                        const ResponseFitOptions& options = {});

}  // namespace lp
