#pragma once
/// Ground truth (truth.json) for evaluation only, and the lighting error measures.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "estimation/envmap.h"

namespace lp {

/// A light of the ground truth: its unit direction from the scene centre and its
/// luminous weight (used to rank lights as "dominant").
struct TruthLight {
  std::string type;  ///< "sphere", "sun" or "environment"
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  double weight = 1;
};

/// Parses truth.json text (`name` for errors); throws InputError when malformed.
std::vector<TruthLight> ParseTruthLights(const std::string& text, const std::string& name);

/// Up to `count` dominant directions of an estimate, found one after another: the modes
/// of its power (luminance x solid angle) smoothed by a Gaussian of half `separation_deg`
/// on the sphere (mean shift from the cell that gathers the most power, at least
/// `separation_deg` from the lights already found); the cells within `separation_deg` of
/// a light found are then taken out. A light spread over several cells gets the centre of
/// its spread, not of its brightest cell.
std::vector<Eigen::Vector3d> DominantDirections(const EnvMap& env, const std::vector<double>& lambda, int count,
                                                double separation_deg = 30);

/// Mean angle (degrees) between each truth light (the strongest min(k, 2) with a
/// direction) and the nearest of the estimate's dominant directions.
double DominantAngularErrorDeg(const EnvMap& env, const std::vector<double>& lambda,
                               const std::vector<TruthLight>& truth);

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

/// Relative RMSE of `image` against a view's reference over its valid pixels:
/// sqrt(mean squared difference) / mean reference value. NaN without valid pixels.
double RelativeImageRmse(const ImageRGB& image, const ImageRGB& reference, const std::vector<std::uint8_t>& valid);

/// Relative error of an estimated map against the true per-cell radiance (both 3 per cell):
/// sqrt(sum_j Omega_j |l_j - t_j|^2 / sum_j Omega_j |t_j|^2) over the cells not left out
/// (cells no path reached are unobservable; `left_out` may be empty). NaN if `truth` is empty.
double EnvMapRelativeError(const EnvMap& env, const std::vector<double>& lambda, const std::vector<double>& truth,
                           const std::vector<std::uint8_t>& left_out);

}  // namespace lp
