#pragma once
/// Light-source estimation by analytical path tracing: sequential Monte Carlo
/// rounds of (trace A with importance from the current estimate, solve the
/// robust non-negative problem warm-started), until the estimate settles.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "estimation/seen_lamps.h"
#include "estimation/seen_windows.h"
#include "estimation/estimate_options.h"
#include "estimation/light_render.h"
#include "estimation/light_uncertainty.h"
#include "estimation/lighting.h"
#include "estimation/objective.h"
#include "estimation/path_tracer.h"
#include "scene/scene_bundle.h"
#include "estimation/solver.h"
#include "estimation/truth.h"

namespace lp {

struct ConvergenceRow;
struct RoundInfo;

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
  /// "prior": the map and the intensities solved again at the map's prior the data chose
  /// (EstimateResult::prior; a penalty of another weight, so its objective is another function).
  /// "polish": the lamps refined after the last round on fresh vertices (PolishLamps; its
  /// objective is debiased and on its own rows, times their stride: another function too).
  const char* step = "solve";
};

/// Where a live estimate starts (EstimateOptions::warm): the last estimate's lighting and
/// the layout of its map (rings, up). The map is resampled onto the new estimate's cells
/// when the up moved (a new snapshot's up comes from its own mesh), and each directional
/// light's irradiance is put into its cell as radiance, so the first round samples there.
struct WarmStart {
  Lighting lighting;
  int rings = 0;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
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
  Lighting lighting;           ///< the estimate after this round (its map 3 * cells; image units)
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

/// The map's prior chosen by the data (docs/method.md, "The map's prior"): the activation
/// penalty's weight, tried from the given one down, with the lights found and with the map
/// alone, each scored by the Cauchy loss on pixels the fit did not use (folds of large
/// blocks); the strongest weight within one standard error of the best is kept, and the
/// lights only if they predict better than the map alone.
/// A prior of the map: the activation penalty's weight (as EstimateOptions' objective.alpha)
/// and its smoothness's (as objective.smooth; 0: none).
struct MapPrior {
  double alpha = 0;
  double smooth = 0;
};

struct PriorChoice {
  struct Tried {
    double alpha = 0;           ///< the weight (as EstimateOptions' alpha)
    double loss = 0;            ///< its held-out loss, summed over the folds (normalized units)
    double standard_error = 0;  ///< of its difference from the least of its kind
    int lights = 0;             ///< the lights fitted beside the map (0: the map alone)
    double smooth = 0;          ///< the smoothness's weight (as EstimateOptions' objective.smooth)
  };
  std::vector<Tried> tried;      ///< with the lights (strongest first), then the map alone
  double chosen = std::nan("");  ///< the weight solved at (NaN: the given one, nothing tried)
  double chosen_smooth = 0;      ///< and the smoothness's
  bool lights_dropped = false;   ///< the map alone predicted as well: the lights were dropped
  std::string why;               ///< one line: how it was chosen, or why nothing was tried
  bool done = false;             ///< whether the choice was made (or said why not)
  int folds = 0, blocks = 0;
  double seconds = 0;
  /// Whether `t` (one of `tried`) is the weight and the lights the estimate was solved at.
  bool IsChosen(const Tried& t) const {
    return t.alpha == chosen && t.smooth == chosen_smooth && (lights_dropped ? t.lights == 0 : t.lights == tried.front().lights);
  }
};

/// The rule PriorChoice follows, on `block_loss[k][b]`: the held-out loss of weight k
/// (strongest first) on block b. Fills `loss` (each weight's total over the blocks used) and
/// `standard_error` (of each total's difference from the least: sqrt(B) times the standard
/// deviation of the blocks' differences, B the blocks used) and returns the first k whose
/// loss exceeds the least by no more than its standard error.
std::size_t StrongestWithinOneStandardError(const std::vector<std::vector<double>>& block_loss,
                                            const std::vector<std::uint8_t>& used, std::vector<double>* loss,
                                            std::vector<double>* standard_error);
/// The weight PriorChoice takes (0, the first, the given one, unless another gains): of the
/// weights within one standard error of the least loss (StrongestWithinOneStandardError's
/// `loss` and `standard_error`, which it fills), the strongest whose loss is below the
/// first's by more than `min_gain` of it; 0 when none is. (Taking only the strongest within
/// one standard error, and the given weight when it gains too little, kept alpha on the
/// synthetic lamp beside a sky where a weaker weight within the error gained 3.9 %.)
std::size_t StrongestThatGains(const std::vector<std::vector<double>>& block_loss, const std::vector<std::uint8_t>& used,
                               double min_gain, std::vector<double>* loss, std::vector<double>* standard_error);

struct EstimateResult {
  EnvMap env{2, Eigen::Vector3d::UnitZ()};
  /// The estimate (image units): the map, 3 * env.size() linear radiances (0 for left-out
  /// cells); the lights, the directional ones (a sun: its cells of the map are empty) then
  /// the point lights (the near part), each kind strongest first.
  Lighting lighting;
  /// How well the images fix each light of `lighting.lights` (same order; image units;
  /// estimation/light_uncertainty.h), conditional on the mesh and albedo; empty when there
  /// are no lights.
  std::vector<LightUncertainty> uncertainty;
  std::vector<std::uint8_t> left_out;  ///< per cell: 1 = no sampled path reached it
  /// Relit views (every pixel), when options.render: the clean render (render_noise, or
  /// render_spp), else the fit.
  std::vector<ImageRGB> renders;
  /// The fit itself on the views' pixels it used (the last round's A lambda plus the lights'
  /// columns), the pixels it did not use traced at kMaskedRenderSpp, when options.render.
  std::vector<ImageRGB> fits;
  /// The clean render's passes (empty when there was none).
  std::vector<RenderPass> render_passes;
  std::vector<ConvergenceRow> convergence;
  std::vector<RoundInfo> rounds;
  TraceStats trace;
  double image_mean = 1;  ///< normalization
  /// total_seconds: the estimate, the fit's render included and the clean render (its own
  /// clean_render_seconds, after the estimate) not; render_seconds: both renders.
  double bvh_seconds = 0, total_seconds = 0, render_seconds = 0, clean_render_seconds = 0;
  /// When the lights were final (EstimateOptions::on_lights), on total_seconds' clock: a
  /// caller's lights.json need not wait for the renders.
  double lights_seconds = 0;
  /// The mesh the estimator traced (EstimateOptions::trace_pixels): its triangles and
  /// vertices, the grid it was clustered on (m; 0: the bundle's mesh as it is) and the
  /// seconds clustering took (in bvh_seconds too).
  int traced_triangles = 0, traced_vertices = 0;
  double trace_cell_m = 0, cluster_seconds = 0;
  int observations = 0;   ///< valid pixels over all views
  /// The rounds' last rows: the pixels clipped on the mesh fitted as lower bounds, and the
  /// valid pixels beside a clipped one fitted as upper bounds (bloom;
  /// EstimateOptions::clipped_rows).
  int clipped_rows = 0, bloom_rows = 0;
  double final_rmse = 0, final_relative_rmse = 0;
  double final_angular_error_deg = std::nan("");
  double kkt_violation = 0;
  bool objective_increased = false;
  std::vector<Eigen::Vector3d> dominant;  ///< the strongest light directions (map and directional lights)
  /// Why each light was kept or dropped (model selection), one line each.
  std::vector<std::string> point_light_choices;
  /// The places where the cameras saw clipped blobs, tried by the search (seen_lamps.h).
  std::vector<SeenLamp> seen_lamps;
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
  PriorChoice prior;                 ///< the map's prior the data chose
  /// The refined per-vertex albedo the estimate was made under (empty: the bundle's, unrefined).
  std::vector<Eigen::Vector3f> albedo;
  int albedo_passes = 0, albedo_segments = 0;
  /// The last albedo pass's paths per vertex of the bundle's mesh, on average
  /// (EstimateOptions::albedo_noise: fewer where the irradiance settles early).
  double albedo_paths = 0;
  /// Surfaces seen glowing that the data chose as a window's opening (the map seen through
  /// it, its triangles no surface) over a glowing pane or a plain one (docs/method.md,
  /// "Windows: a pane or an opening"), on the bundle's mesh; lights.json's "openings".
  std::vector<std::shared_ptr<const EmitterShape>> openings;
  /// The windows the cameras saw as holes (seen_windows.h): the map lights the room through
  /// them (and a glowing pane over one, where the data chose it: an emitter in_a_hole);
  /// report.json's choices say the light through each.
  std::vector<SeenWindow> windows;
  double albedo_seconds = 0;  ///< de-lighting and segmenting (the extra rounds are in `rounds`)
  /// How far the last albedo pass moved the lights (EstimateOptions::albedo_settle's
  /// measure; NaN without a pass).
  double albedo_last_move = std::nan("");
  AlbedoLeftOut albedo_left_out = AlbedoLeftOut::kRefined;  ///< why the albedo was not refined
  /// The factor a reconstructed mesh's albedo was scaled by before the rounds
  /// (EstimateOptions::room_albedo; 1: not scaled). The lights' intensities are in the
  /// scaled albedo's terms, and `albedo` holds the scaled (or refined) albedo.
  double albedo_scale = 1;
};

/// The clean render of `views` under `lighting` as EstimateOptions asks it (render_noise; for
/// render_seconds, or by default as long as the estimate took, `estimate_seconds`, at least
/// kMinCleanRenderSeconds): ProgressiveRender from kMaskedRenderSpp samples, its own seeds.
/// What Estimate writes as render_view*, and the viewer's job shows pass by pass.
std::vector<ImageRGB> CleanRender(const RayTracer& scene, const EnvMap& env, const Lighting& lighting,
                                  const CellSampler& sampler, const std::vector<View>& views,
                                  const EstimateOptions& options, double estimate_seconds,
                                  std::vector<RenderPass>* passes, const RenderPassCallback& on_pass = {});

/// The start of a live estimate from the last one's lighting and map.
std::shared_ptr<const WarmStart> WarmStartOf(const EstimateResult& result);

/// Runs the estimate on a loaded bundle. Throws InputError when nothing usable is
/// observed (every pixel masked/invalid, or a black image).
EstimateResult Estimate(const SceneBundle& bundle, const EstimateOptions& options);

/// Observations of the valid pixels in row order (3 per pixel), in image units.
std::vector<double> CollectObservations(const std::vector<View>& views);

}  // namespace lp
