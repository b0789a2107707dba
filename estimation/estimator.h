#pragma once
/// Light-source estimation by analytical path tracing: sequential Monte Carlo
/// rounds of (trace A with importance from the current estimate, solve the
/// robust non-negative problem warm-started), until the estimate settles.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "estimation/lights/directional_light.h"
#include "estimation/objective.h"
#include "estimation/path_tracer.h"
#include "estimation/lights/point_light.h"
#include "scene/scene_bundle.h"
#include "estimation/solver.h"
#include "estimation/truth.h"

namespace lp {

/// EstimateOptions::objective.alpha is per this many observed pixels (one 160x120 view),
constexpr double kAlphaReferencePixels = 19200;
/// and per cell of this solid angle (the mean cell of 21 rings, 4 pi / 522): a cell of
/// solid angle Omega_j is penalized with alpha * Omega_j / kAlphaReferenceSolidAngle.
constexpr double kAlphaReferenceSolidAngle = 4 * 3.14159265358979323846 / 522;
/// Round 1 (the cold start) solves at this Cauchy scale first when a smaller one is asked
/// for, then halves it down to the one asked for, each solve warm-started (graduated
/// non-convexity; see Estimate).
constexpr double kGraduatedSigmaStart = 0.5;

/// Round 1 (the first estimate) fits the valid pixels on the widest grid that keeps this
/// many of them (a quarter of a 160x120 view: every 2nd pixel of every 2nd row of one such
/// view, every 3rd of every 3rd of the demo's 4); the rounds after fit them all.
constexpr double kFirstRoundPixels = 4800;

/// The traced mesh is clustered only where its grid is at least this many median edges.
constexpr double kMinTraceCellEdges = 1.5;
/// and where the clustered mesh keeps at least this share of the surface's area.
constexpr double kMinTracedArea = 0.5;
/// EstimateOptions::trace_pixels is 0 .. this.
constexpr double kMaxTracePixels = 64;

/// The most albedo passes an estimate takes (EstimateOptions::albedo_passes is 0 .. this):
/// the command line, the viewer's setting and its script check against it.
constexpr int kMaxAlbedoPasses = 5;
/// Samples per pixel of the pixels the fit did not use in the default final render.
constexpr int kMaskedRenderSpp = 64;
/// EstimateOptions::rings is kMinRings .. kMaxRings.
constexpr int kMinRings = 2, kMaxRings = 181;

struct ConvergenceRow;
struct RoundInfo;

/// The near-light model (docs/method.md, "Point lights"): point lights beside the map.
struct PointLightOptions {
  /// At most this many point lights; 0 = the environment map alone (the far-light model).
  int max_lights = 4;
  /// Paths per pixel whose shading vertices the lights' columns and positions come from.
  int spp = 8;
  /// The same for the first round's candidates (many columns, so fewer paths).
  int candidate_spp = 1;
  /// A point light's activation penalty, in cells of the reference solid angle.
  double weight = 1;
  /// Share of the pixels the model selection scores lights on (left out of that fit), in
  /// blocks of 8 x 8 pixels (a light that fits a local patch must predict the next block).
  double holdout = 0.2;
  /// A light is kept when it lowers the held-out loss by at least this share,
  double min_gain = 0.02;
  /// and renders at least this share of the observed light (a lamp is what lights a good
  /// part of the scene; fits of noise and of a map's discretization live below this).
  double min_share = 0.1;
  /// Lights refined farther than this many scene radii from the centre are far lights:
  /// dropped, the map takes their light (a sun is not a lamp).
  double far = 5;
};

struct EstimateOptions {
  int rings = 21;
  /// tracer.spp: the map's samples per pixel in round 1; later rounds trace fewer where the
  /// map renders less than half the light (down to a quarter of them; docs/method.md).
  TracerOptions tracer;
  ObjectiveParams objective;
  SolverKind solver = SolverKind::kFast;
  SolverOptions solver_options;
  int max_rounds = 4;
  PointLightOptions point_lights;
  /// A directional light (a sun: sharp shadows) where the map concentrates its power
  /// (docs/method.md, "Directional lights"): tried in the first round on every pixel
  /// (round 2 after round 1's grid, else round 1) when the brightest cell's neighbourhood
  /// holds at least directional_min_share of the map's power and renders at least
  /// PointLightOptions::min_share of the light seen, kept when the held-out pixels want it
  /// (PointLightOptions::holdout, min_gain). Needs the near-light model's shading vertices
  /// (point_lights.max_lights > 0).
  bool directional_lights = true;
  double directional_min_share = 0.25;
  /// The mesh the estimator traces (docs/method.md, "The traced mesh"): the bundle's mesh
  /// clustered on a grid of this many pixels, a pixel being what one spans on the nearest
  /// tenth of the surfaces the views see (PixelFootprints), when that grid is at least
  /// kMinTraceCellEdges of the mesh's median edges (a mesh no finer than the pixels is traced
  /// as it is); 0 always traces the bundle's mesh. The albedo refinement still de-lights
  /// every vertex of the bundle's mesh (about albedo_samples paths per cluster, averaged
  /// over it), and the result's albedo is per vertex of it (each cluster's the mean of its
  /// vertices' weighted by their irradiance).
  double trace_pixels = 1;
  /// Albedo refinement (intrinsic decomposition, scene/albedo.h), when the mesh has
  /// `shaded` colours (a reconstruction; a bundle with known albedo needs none): after the
  /// rounds settle, the colours seen are de-lit by the estimate's irradiance at every vertex
  /// (albedo_samples paths each), segmented again and flattened, and the rounds go on
  /// warm-started under the new albedo (at most max_rounds more); this many times, 0 ..
  /// kMaxAlbedoPasses (what it gains and costs: docs/method.md).
  int albedo_passes = 1;
  int albedo_samples = 64;
  /// Stop when the rendered estimate changes by less than this between rounds:
  /// |A (lambda_k - lambda_{k-1})| / |A lambda_k| < 2 % (over the observed pixels).
  double change_threshold = 0.02;
  /// Average A over rounds, weighted by sample counts (all rounds are unbiased).
  bool combine_rounds = true;
  /// The final relit render of the fitted views: 0 (the default) renders their valid pixels
  /// as the fit itself, the last round's A lambda plus the lights' columns (no new paths;
  /// its error is the fit's, in-sample), and traces only the pixels the fit did not use
  /// (masked, no depth) at kMaskedRenderSpp; N > 0 traces every pixel again at N samples
  /// (an independent render, at N / tracer.spp of a round's cost per pixel).
  int render_spp = 0;
  bool render = true;
  /// Wall-clock origin for the convergence log (seconds already spent before Estimate).
  double time_offset = 0;
  /// Progress lines ("round 2: traced 19200 pixels in 0.6 s ...").
  std::function<void(const std::string&)> progress;
  /// Polled before and during each round's trace (every 64 pixels per worker), after every
  /// solver iteration, and before and during the final render; when it returns true
  /// Estimate throws Cancelled (a viewer's Cancel button). Called from worker threads.
  std::function<bool()> cancelled;
  /// Called on the estimating thread with every convergence row as it is logged, and
  /// with every finished round (its estimate so far): a live plot and map.
  std::function<void(const ConvergenceRow&)> on_convergence;
  std::function<void(const RoundInfo&, const EnvMap&)> on_round;
};

/// One row of convergence.csv.
struct ConvergenceRow {
  double wall_seconds = 0;
  int round = 0;
  int iteration = 0;
  double objective = 0;
  double photometric_rmse = 0;  ///< in image units
  double relative_rmse = 0;     ///< photometric_rmse / mean observed value
  double angular_error_deg = std::nan("");  ///< dominant light(s) vs truth.json; NaN without truth
  /// The Cauchy scale this iteration's objective is measured at (round 1 steps down to
  /// the requested one from kGraduatedSigmaStart; objectives at different scales differ).
  double sigma = 0;
  /// The albedo pass the round runs under (0: the bundle's albedo; see albedo_passes).
  int albedo_pass = 0;
  /// Point lights in the estimate at this iteration (in round 1's solve: the candidates lit).
  int point_lights = 0;
  /// With positions in truth.json: the worst distance (m) from a true near light to the
  /// nearest point light (infinite without one); NaN otherwise.
  double position_error_m = std::nan("");
  /// "solve" (the map's and lights' intensities on a fixed A), "lights" (a step of the
  /// lights' refinement, the map held), "search" (round 1's search for lamps, the map
  /// dark: each light it adds starts a new descent) or "sun" (a directional light's
  /// refinement, the map without its cells and the lamps held). The objective is the same function
  /// in all (the Cauchy loss and every penalty); it never rises from one row to the next
  /// within a round except where a search starts or adds a light, where the number of
  /// point lights changes (a light dropped: the model changed), and at a directional
  /// light's rows ("sun", which leave the map's penalty out) and the solve after them.
  const char* step = "solve";
};

struct RoundInfo {
  int round = 0;
  int spp = 0;  ///< the map's samples per pixel this round (EstimateOptions::tracer.spp, or fewer)
  int pixels = 0;  ///< the valid pixels it fitted (round 1: a grid of them; kFirstRoundPixels)
  double trace_seconds = 0, solve_seconds = 0;
  int solver_iterations = 0;
  double objective = 0, kkt_violation = 0;
  double change = 0;        ///< |lambda_k - lambda_{k-1}| / |lambda_k|
  double image_change = 0;  ///< |A (lambda_k - lambda_{k-1})| / |A lambda_k|: the stopping test
  std::int64_t nonzeros = 0;
  int unknown_cells = 0;
  double end_seconds = 0;      ///< wall clock at the end of the round (with time_offset)
  std::vector<double> lambda;  ///< the estimate after this round (3 * cells, image units)
  std::vector<PointLight> point_lights;  ///< after this round (image units)
  std::vector<DirectionalLight> directional_lights;  ///< after this round (image units)
  int light_iterations = 0;    ///< steps of the positions' refinement
  bool lights_moved = false;   ///< the point lights changed or moved more than 2 % of their distance
};

/// Why an estimate did not refine the albedo.
enum class AlbedoLeftOut {
  kRefined,      ///< it did
  kNoPasses,     ///< EstimateOptions::albedo_passes is 0
  kKnownAlbedo,  ///< the bundle's albedo is known (its mesh has no shaded colours)
  kNothingLit,   ///< the estimate lights nothing, or every colour seen is black
};
/// One line saying why ("" for kRefined).
const char* ToString(AlbedoLeftOut why);

struct EstimateResult {
  EnvMap env{2, Eigen::Vector3d::UnitZ()};
  std::vector<double> lambda;  ///< 3 * env.size(), linear radiance in image units; 0 for left-out cells
  std::vector<std::uint8_t> left_out;  ///< per cell: 1 = no sampled path reached it
  std::vector<ImageRGB> renders;       ///< relit views (every pixel), when options.render
  std::vector<ConvergenceRow> convergence;
  std::vector<RoundInfo> rounds;
  TraceStats trace;
  double image_mean = 1;  ///< normalization
  double bvh_seconds = 0, total_seconds = 0, render_seconds = 0;
  /// The mesh the estimator traced (EstimateOptions::trace_pixels): its triangles and
  /// vertices, the grid it was clustered on (m; 0: the bundle's mesh as it is) and the
  /// seconds clustering took (in bvh_seconds too).
  int traced_triangles = 0, traced_vertices = 0;
  double trace_cell_m = 0, cluster_seconds = 0;
  int observations = 0;   ///< valid pixels over all views
  double final_rmse = 0, final_relative_rmse = 0;
  double final_angular_error_deg = std::nan("");
  double kkt_violation = 0;
  bool objective_increased = false;
  std::vector<Eigen::Vector3d> dominant;  ///< the strongest light directions (map and directional lights)
  /// The near part of the lighting (image units), strongest first.
  std::vector<PointLight> point_lights;
  /// The sharp far part (a sun), strongest first; its cells of the map are empty.
  std::vector<DirectionalLight> directional_lights;
  /// Why each light was kept or dropped (model selection), one line each.
  std::vector<std::string> point_light_choices;
  Eigen::Vector3d scene_centre = Eigen::Vector3d::Zero();  ///< the mesh's bounding box's centre
  double final_position_error_m = std::nan("");  ///< as ConvergenceRow::position_error_m
  /// The worst near true light's position error over its distance from the scene centre.
  double final_position_error_share = std::nan("");
  /// The rendered estimate's mean over the observed pixels, relative to theirs (1 = as
  /// bright as the images); from the last round's A.
  double rendered_fraction = 0;
  /// What the user should know about this estimate (e.g. it lights nothing: a Cauchy scale
  /// below the residuals, or a penalty that outweighs the data). One line each.
  std::vector<std::string> warnings;
  ObjectiveParams objective_params;  ///< as solved: alpha scaled to the observed pixel count
  /// The refined per-vertex albedo the estimate was made under (empty: the bundle's, unrefined).
  std::vector<Eigen::Vector3f> albedo;
  int albedo_passes = 0, albedo_segments = 0;
  double albedo_seconds = 0;  ///< de-lighting and segmenting (the extra rounds are in `rounds`)
  AlbedoLeftOut albedo_left_out = AlbedoLeftOut::kRefined;  ///< why the albedo was not refined
};

/// Runs the estimate on a loaded bundle. Throws InputError when nothing usable is
/// observed (every pixel masked/invalid, or a black image).
EstimateResult Estimate(const SceneBundle& bundle, const EstimateOptions& options);

/// Observations of the valid pixels in row order (3 per pixel), in image units.
std::vector<double> CollectObservations(const std::vector<View>& views);

}  // namespace lp
