#pragma once
/// `lightprobe evaluate`: a headless run (RUN/scene, RUN/estimate) scored against a scan's
/// ground truth (a frame directory with truth.json, gt_mesh.ply and holdout/, as the Cycles
/// scans in docs/benchmarks.md): the mesh against the true geometry, each true lamp against
/// the nearest estimated one, the albedo's scale and the held-out view relit.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/image.h"
#include "scene/mesh.h"
#include "scene/scene_bundle.h"

namespace lp::app {

/// A view the run never saw: its camera, the rendered image (linear, image units), the
/// pixels it covers, and the renderer's true albedo there (holdout/holdout.json).
struct HeldOutView {
  View view;             ///< image, camera, valid = the mask
  ImageRGB true_albedo;  ///< empty when holdout.json names none
};
/// Reads holdout.json and the files it names. Throws InputError naming the file. An
/// integer image (PNG, JPEG) is clipped at its top code (`view.saturation` 1); a linear
/// EXR is not.
HeldOutView ReadHeldOutView(const std::filesystem::path& holdout_json);

/// `render` as the held-out view's camera would have recorded it: where the view clipped a
/// channel (at or above its saturation) the truth is "at least this bright", so a render
/// above it is no error there (it is cut to the recorded value; one below it is an error as
/// anywhere else). Every held-out error is measured on this.
ImageRGB UpToTheClip(ImageRGB render, const View& held);

/// Distances (metres) from the reconstructed surface to the true one (its vertices to
/// points sampled on `truth`'s triangles every ~5 mm: upper bounds, ~1.9 mm for a vertex
/// on the surface on average), and the share of the true points
/// that have a reconstructed vertex within 2 cm (where the true surface was seen: only
/// `seen_from` cameras' first hits are counted; all of them without cameras).
struct MeshError {
  double median_m = 0, p90_m = 0;
  double complete_2cm = 0;
};
MeshError CompareMeshes(const Mesh& reconstructed, const Mesh& truth, const std::vector<Camera>& seen_from = {});

/// The albedo's scale: the median, over the held-out view's masked pixels whose ray hits
/// `mesh`, of luminance(the albedo at the hit) / luminance(the true albedo there). NaN
/// without samples. `error`, when given, gets ScanScore::albedo_error at that scale.
double AlbedoScale(const Mesh& mesh, const HeldOutView& view, int* samples = nullptr, double* error = nullptr);

/// The Gaussian blur (sigma, pixels) SplitByBlur uses by default: registration of a
/// reconstruction's colours is off by a pixel or two at the keyframes' scale.
inline constexpr double kSplitBlurPx = 4;
/// The relative RMSE of `image` against `reference` over the `valid` pixels (`total`);
/// the same with both blurred by a Gaussian of `sigma_px` over the valid pixels alone
/// (`smooth`: a light's errors, which are smooth, survive the blur); and
/// sqrt(max(0, total^2 - smooth^2)) (`sharp`: what the blur took away, the colour map's).
struct BlurSplit {
  double total = NAN, smooth = NAN, sharp = NAN;
};
BlurSplit SplitByBlur(const ImageRGB& image, const ImageRGB& reference, const std::vector<std::uint8_t>& valid,
                      double sigma_px = kSplitBlurPx);

/// One true lamp against the nearest estimated point light.
struct LampScore {
  Eigen::Vector3d truth = Eigen::Vector3d::Zero(), estimate = Eigen::Vector3d::Zero();
  double distance_m = 0;      ///< the true lamp from the room's centre
  double error_m = INFINITY;  ///< to the nearest estimate (infinite without one)
  double share = INFINITY;    ///< error_m / distance_m
  double intensity_ratio = NAN;      ///< luminance(estimated I) / luminance(true I)
  double light_times_albedo = NAN;   ///< intensity_ratio * the albedo's scale (1 = right)
};

/// One true sun (a light with a direction and no position) against the nearest estimated
/// directional light.
struct SunScore {
  Eigen::Vector3d truth = Eigen::Vector3d::UnitZ();
  double angle_deg = INFINITY;  ///< to the nearest directional light (infinite without one)
  double irradiance_ratio = NAN;  ///< luminance(estimated) / luminance(true)
};

/// One true glowing surface (truth.json's "emitters") against the estimated emitter that
/// overlaps it most.
struct EmitterScore {
  double true_area = 0;  ///< m^2
  double iou = 0;        ///< by area, a point on the other within half its cell (1 cm) of it
  double power_ratio = NAN;  ///< luminance(estimated power) / luminance(true power)
};

struct ScanScore {
  std::optional<MeshError> mesh;  ///< when the truth has gt_mesh.ply
  std::vector<LampScore> lamps;
  std::vector<SunScore> suns;
  std::vector<EmitterScore> emitters;
  int estimated_emitters = 0;
  /// The estimated emitters that overlap no true one: their share of all estimated
  /// emitters' power, the largest (0 without any).
  double spurious_emitter_share = 0;
  int estimated_lamps = 0;
  /// The estimated lamps that are no true lamp's nearest: their share of the irradiance
  /// all estimated lamps give the room's centre (luminance / d^2), the largest.
  double spurious_share = 0;  ///< NaN without truth.json
  double albedo_scale = NAN;
  int albedo_samples = 0;
  /// The albedo's error once its scale is undone: over the same pixels, the relative RMS of
  /// (the albedo at the hit / albedo_scale - the true albedo), RGB, against the true
  /// albedo's RMS (0 = the albedo right but for its scale). NaN without samples.
  double albedo_error = NAN;
  double held_out_relit = NAN;  ///< relative RMSE of the held-out view relit under the estimate
  /// The share of the held-out view's pixels the reconstruction covers, and the relit error
  /// over those alone (the light's part, the holes of the scan aside).
  double held_out_covered = NAN, held_out_relit_covered = NAN;
  /// The same over the covered pixels with the estimate's shading (the render over the
  /// albedo each pixel's ray hits) times the true albedo there: the light's part of the
  /// error, the colour map's (sharpness, registration, segmentation) taken out, at the one
  /// scale that fits best (held_out_true_albedo_scale: light x albedo's own error aside).
  double held_out_relit_true_albedo = NAN, held_out_true_albedo_scale = NAN;
  /// The same error split without a true albedo (SplitByBlur): over the covered pixels,
  /// with both images blurred by a Gaussian of kSplitBlurPx pixels (the light's part: its
  /// errors are smooth) and what the blur takes away (the colour map's: its sharpness and
  /// registration are pixel-sharp).
  double held_out_relit_blurred = NAN, held_out_colour_map_part = NAN;
  double seconds = 0;
};

/// Scores `run_dir` (RUN/scene, RUN/estimate) against `truth_dir`. The held-out view is
/// relit with `spp` paths per pixel (seed 1). Throws InputError naming a missing or bad file.
ScanScore EvaluateScan(const std::filesystem::path& truth_dir, const std::filesystem::path& run_dir, int spp);

/// evaluation.json's text.
std::string ScanScoreJson(const ScanScore& score);
/// Adds the score to the run's estimate/report.json as its "evaluation" (atomically; the
/// rest of the report as it was). Returns false when the run has no report.json.
bool AddToReport(const std::filesystem::path& run_dir, const ScanScore& score);

}  // namespace lp::app
