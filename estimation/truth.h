#pragma once
/// Ground truth (truth.json) for evaluation only, and the lighting error measures.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "estimation/lights/directional_light.h"
#include "estimation/lights/emitter_light.h"
#include "estimation/envmap.h"
#include "estimation/lights/point_light.h"

namespace lp {

/// A light of the ground truth: its unit direction from the scene centre and its
/// luminous weight (used to rank lights as "dominant").
struct TruthLight {
  std::string type;  ///< "sphere", "sun", "point" or "environment"
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  double weight = 1;
  /// Where the light is (world frame, metres), when the truth says.
  std::optional<Eigen::Vector3d> position;
};

/// Parses truth.json text (`name` for errors); throws InputError when malformed. A light is
/// read when it has a "direction" (from the scene centre) or a "position" (its direction is
/// then taken from "scene_bbox"'s "centre", or the origin without one); its weight ranks the
/// lights: "weight", else the luminance of "rgb_power", "rgb" or "rgb_radiance", else, for a
/// light given by "radiant_intensity_rgb_W_per_sr" I at distance d from the centre,
/// luminance(I) / d^2 (its irradiance there).
std::vector<TruthLight> ParseTruthLights(const std::string& text, const std::string& name);

/// truth.json's "emitters" (none without the key): each a glowing surface given by its
/// quads, "corners" (4 points, one quad) or "quads" (a list of {"corners", "normal"}), each
/// glowing on the side of its "normal", at its mean "radiance" (image units). Throws
/// InputError when malformed.
std::vector<EmitterLight> ParseTruthEmitters(const std::string& text, const std::string& name);

/// Directions of the truth's lights that have a position, taken again from `centre` (the
/// estimator's scene centre: the centre of the mesh's bounding box).
void CentreTruthLights(std::vector<TruthLight>* truth, const Eigen::Vector3d& centre);

/// Up to `count` dominant directions of an estimate, found one after another: the modes
/// of its power (luminance x solid angle) smoothed by a Gaussian of half `separation_deg`
/// on the sphere (mean shift from the cell that gathers the most power, at least
/// `separation_deg` from the lights already found); the cells within `separation_deg` of
/// a light found are then taken out. A light spread over several cells gets the centre of
/// its spread, not of its brightest cell.
std::vector<Eigen::Vector3d> DominantDirections(const EnvMap& env, const std::vector<double>& lambda, int count,
                                                double separation_deg = 30);

/// The same with directional lights beside the map: the map's dominant directions (each
/// weighted by the luminance power within 30 degrees of it) and the lights' (weighted by
/// their irradiance's luminance), strongest first, at most `count`.
std::vector<Eigen::Vector3d> DominantDirections(const EnvMap& env, const std::vector<double>& lambda,
                                                const std::vector<DirectionalLight>& suns, int count);

/// Mean angle (degrees) between each truth light (the strongest min(k, 2) with a
/// direction) and the nearest of the estimate's dominant directions.
double DominantAngularErrorDeg(const EnvMap& env, const std::vector<double>& lambda,
                               const std::vector<TruthLight>& truth);

/// With point lights beside the map: the estimate's lights are the map's dominant
/// directions (up to 2) and the point lights' directions from `centre`, ranked by the
/// irradiance each gives at the centre (a map mode: the luminance x solid angle of the
/// cells within 30 degrees of it; a point light: luminance(I) / d^2); the strongest
/// min(2, truth lights) of them are compared as above. A directional light counts with
/// luminance(irradiance) from its direction. Without point or directional lights this is
/// the function above.
double DominantAngularErrorDeg(const EnvMap& env, const std::vector<double>& lambda,
                               const std::vector<PointLight>& points, const Eigen::Vector3d& centre,
                               const std::vector<TruthLight>& truth, const std::vector<DirectionalLight>& suns = {});

/// The worst distance (metres) from a true near light (one with a position less than
/// `far_distance` from `centre`) to the nearest estimated point light; NaN when the truth
/// has no near light, infinity when the estimate has no point light. `share`, when given,
/// receives the worst of each near light's error over its distance from `centre`.
double WorstPositionError(const std::vector<PointLight>& points, const std::vector<TruthLight>& truth,
                          const Eigen::Vector3d& centre, double far_distance, double* share = nullptr);

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

/// Relative RMSE of `image` against a view's reference over its valid pixels:
/// sqrt(mean squared difference) / mean reference value. NaN without valid pixels.
double RelativeImageRmse(const ImageRGB& image, const ImageRGB& reference, const std::vector<std::uint8_t>& valid);

/// The same error with the Monte Carlo noise of both sides taken out: `image` and `image2`
/// are two renders of one estimate with independent samples, `reference` and `reference2`
/// two of the truth. Each pair's difference is its noise times sqrt 2, so
/// sqrt(max(0, e^2 - n_i^2 - n_r^2)) with e = RelativeImageRmse(image, reference), n_i that of
/// image against image2 over sqrt 2, n_r the same for the references (all over the mean of
/// `reference`). The noises go to `noise_image` and `noise_reference` when given. NaN without
/// valid pixels.
double RelativeImageRmseBeyondNoise(const ImageRGB& image, const ImageRGB& image2, const ImageRGB& reference,
                                    const ImageRGB& reference2, const std::vector<std::uint8_t>& valid,
                                    double* noise_image = nullptr, double* noise_reference = nullptr);

/// Relative error of an estimated map against the true per-cell radiance (both 3 per cell):
/// sqrt(sum_j Omega_j |l_j - t_j|^2 / sum_j Omega_j |t_j|^2) over the cells not left out
/// (cells no path reached are unobservable; `left_out` may be empty). NaN if `truth` is empty.
double EnvMapRelativeError(const EnvMap& env, const std::vector<double>& lambda, const std::vector<double>& truth,
                           const std::vector<std::uint8_t>& left_out);

}  // namespace lp
