#pragma once
/// An estimate's options (EstimateOptions), their defaults, and the one table of them
/// (EstimateOptionTable) from which the command line, the viewer's command file and its
/// Settings panel, and report.json's "settings" are all made; Validate checks every range
/// in one place.
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "estimation/objective.h"
#include "estimation/path_tracer.h"
#include "estimation/solver.h"

namespace lp {

struct ConvergenceRow;
struct RoundInfo;
struct EstimateResult;
struct Lighting;
class EnvMap;
struct WarmStart;
class TruthScorer;

/// EstimateOptions::objective.alpha is per this many observed pixels (one 160x120 view),
constexpr double kAlphaReferencePixels = 19200;
/// and per cell of this solid angle (the mean cell of 21 rings, 4 pi / 522): a cell of
/// solid angle Omega_j is penalized with alpha * Omega_j / kAlphaReferenceSolidAngle.
constexpr double kAlphaReferenceSolidAngle = 4 * 3.14159265358979323846 / 522;
/// The map's prior the data chooses from (EstimateOptions::choose_prior): objective.alpha
/// times each of these, strongest first (a stronger one than given is not tried: from the
/// estimate made at it, a stronger penalty moves nothing; nor a weaker one than 1/30 of it,
/// which scored within one standard error of 1/30 on every scene measured and costs the most:
/// docs/benchmarks.md, sessions 26-27).
constexpr double kPriorFactors[] = {1, 1.0 / 3, 1.0 / 10, 1.0 / 30};
/// ... and after them, for the map alone where the weakest of those weights scored best, at
/// that weight, the map's smoothness at each of these (objective.smooth; strongest first): a
/// sky is smooth, and where the fitted pixels hardly fix a direction the smoothness fills it
/// from its neighbours (Cycles' flat sky: docs/method.md, "The map's prior"). After the
/// sparse ones, a smooth map is taken only where no sparse one is within one standard error
/// of the least loss.
constexpr double kSmoothFactors[] = {1000, 100, 10};
/// ... scored on this many folds of the views' blocks (kPriorBlocksAcross across and down a
/// view; block (x, y) of view v in fold (x + y + v) mod kPriorFolds): neighbouring pixels
/// have nearly the same rows of A, so small held-out blocks favour weak priors.
constexpr int kPriorFolds = 4;
/// A weaker prior than the given one is taken only where it lowers the held-out loss by
/// more than this share of the given one's (as a light must, PointLightOptions::min_gain):
/// gains of 1-2 % came with two lamps' and a stiff case's compact light spread over its neighbours
/// (docs/benchmarks.md, session 27). Beside a window's opening the least loss's weight is
/// taken instead (the light through a window is a sky's: docs/method.md, "The map's prior").
constexpr double kPriorMinGain = 0.03;
constexpr int kPriorBlocksAcross = 4;
/// Beside lamps the prior is chosen in this round on every pixel (after round 1's grid), so
/// that the lamps were refined there twice first: chosen in the first, after one refinement
/// from round 1's places, the far lamp was still 7-8 cm off and a weak prior's sky that is
/// not there took up its error (`lamp-4m` 8-14 cm off on 7 of 25 seeds; docs/benchmarks.md,
/// session 41).
constexpr int kPriorRound = 2;
/// Beside a window, the share of the map's next events aimed through its opening (a portal:
/// a point uniform over it) rather than at a cell (docs/method.md, "Windows").
constexpr double kPortalShare = 0.5;
/// The iterations of a model's trial solve (a candidate light's held-out fit, a prior's, a
/// glowing surface's objective): each a "trial" row of the convergence log.
constexpr int kTrialIterations = 50;

/// Round 1 (the cold start) solves at this Cauchy scale first when a smaller one is asked
/// for, then halves it down to the one asked for, each solve warm-started (graduated
/// non-convexity; see Estimate).
constexpr double kGraduatedSigmaStart = 0.5;

/// Round 1 (the first estimate) fits the valid pixels on the widest grid that keeps this
/// many of them (a quarter of a 160x120 view: every 2nd pixel of every 2nd row of one such
/// view, every 3rd of every 3rd of the demo's 4); the rounds after fit them all (before
/// an albedo pass, a grid of EstimateOptions::pre_albedo_stride).
constexpr double kFirstRoundPixels = 4800;
/// The least share of tracer.spp the map is traced at after round 1, however little of the
/// light it renders (Estimator::MapSamples).
constexpr double kMinMapSamples = 0.25;

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
/// The clean render (EstimateOptions::render_noise) stops at this many samples per pixel.
constexpr int kMaxCleanRenderSpp = 16384;
/// The clean render's time when EstimateOptions::render_seconds is 0 is at least this.
constexpr double kMinCleanRenderSeconds = 2;
/// EstimateOptions::rings is kMinRings .. kMaxRings.
constexpr int kMinRings = 2, kMaxRings = 181;


/// PointLightOptions::polish_spp's paths where it is left to the estimate.
constexpr int kPolishSpp = 64;

/// The near-light model (docs/method.md, "Point lights"): point lights beside the map.
struct PointLightOptions {
  /// At most this many point lights; 0 = the environment map alone (the far-light model).
  int max_lights = 4;
  /// Paths per pixel whose shading vertices the lights' columns and positions come from.
  int spp = 8;
  /// The same for the first round's candidates (many columns, so fewer paths).
  int candidate_spp = 1;
  /// The search also tries the places where the cameras saw clipped blobs (SeenLamps).
  bool seen = true;
  /// The lamp round 1 kept nearest a triangulated seen place, within kSeenHoldReach of it,
  /// is held there (PointLight::held): the rounds, the albedo passes and the polish do not
  /// move it.
  bool hold_seen = true;
  /// The lights' fit takes the columns' Monte Carlo noise out of its objective
  /// (LightFitProblem::debiased): without, a lamp drifts along its ray by about 1 / spp.
  bool debiased = false;
  /// After the last round the lamps are refined once more on fresh shading vertices of this
  /// many paths per pixel on kShadowRows of the rows, the fit debiased (PolishLamps); 0 = not;
  /// -1: kPolishSpp on a scan (an albedo pass de-lit the colours seen) and where the paths'
  /// noise limits a lamp's place more than the images do (LightUncertainty::paths_ratio at
  /// least kPolishPathsRatio), else 0.
  int polish_spp = -1;
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

/// When a directional light is tried and kept (EstimateOptions::directional_lights).
struct DirectionalLightOptions {
  /// Tried where the map's brightest cell's neighbourhood holds at least this share of the
  /// map's power
  double min_map_share = 0.25;
  /// and renders at least this share of the light seen;
  double min_share = 0.1;
  /// kept when the held-out pixels' loss (PointLightOptions::holdout's pixels) falls by at
  /// least this share with it in place of the cells.
  double min_gain = 0.02;
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
  /// (docs/method.md, "Directional lights"), whatever point_lights.max_lights: tried in the
  /// first round on every pixel (round 2 after round 1's grid, else round 1) as `directional`
  /// says, on the shading vertices gathered for it.
  bool directional_lights = true;
  DirectionalLightOptions directional;
  /// Glowing surfaces of the mesh (docs/method.md, "Glowing surfaces"): where the views see
  /// pixels brighter than a white surface under the lights so far, after the lamps and the
  /// sun were sought; kept when the held-out pixels say so.
  bool emitters = true;
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
  /// warm-started under the new albedo (at most max_rounds more); at most this many times,
  /// 0 .. kMaxAlbedoPasses, a pass after the first only while the one before moved a light
  /// by more than albedo_settle (what it gains and costs: docs/method.md).
  int albedo_passes = 4;
  /// A further albedo pass only while the last moved a lamp by more than this share of its
  /// distance from the scene's centre, or a directional light by more than this many
  /// radians, or a light came or went (0: every pass). Where texture splits the surfaces
  /// into many segments, each pass moves a lamp part of the way (docs/method.md).
  double albedo_settle = 0.1;
  int albedo_samples = 32;
  /// An albedo pass gives a cluster's vertices more paths (doubling from 2 a vertex, up to
  /// albedo_samples a cluster) only while its mean irradiance's relative standard error is
  /// above this; 0: albedo_samples paths everywhere.
  double albedo_noise = 0.1;
  /// The rounds before the first albedo pass fit the valid pixels on a grid of this many
  /// (at most round 1's grid): they only settle the lights the pass de-lights under, and the
  /// rounds after it start over under the new albedo (docs/method.md, "Rounds"); 1 fits
  /// every pixel. Only where an albedo pass is to come.
  int pre_albedo_stride = 2;
  /// The albedo's absolute scale, for a reconstructed mesh (one with `shaded` colours): the
  /// colours seen are albedo times the light, so their scale is the light's, and it sets
  /// the interreflections (which scale with the albedo) and so where the lamps go. The
  /// mesh's albedo is scaled so that its median luminance over the vertices (about the
  /// surface's median: in a room, a wall) is this, the albedo of light paint; every albedo
  /// pass keeps that scale. 0 keeps the colours' scale (docs/method.md, "The albedo's
  /// scale").
  double room_albedo = 0.6;
  /// After an albedo pass, the lights' shapes are fitted with each de-lit segment's albedo
  /// left free (eliminated, LightFitProblem::segment): the shading within the segments
  /// places them, not the de-lit albedos the last estimate implied (docs/method.md).
  bool free_albedo = true;
  /// In the first round on every pixel the map's prior (the activation penalty's weight) is
  /// chosen by the data: the map and the lights' intensities (the lights held where they
  /// are; beside a directional light also the map alone) solved at objective.alpha times
  /// each of kPriorFactors on three quarters of the pixels and scored on the fourth (four
  /// folds of large blocks), the strongest weight within one standard error of the best
  /// kept, and the rounds after it run at it (docs/method.md, "The map's prior"; not on a
  /// reconstructed mesh but beside a window's opening, whose cells' prior alone is chosen then;
  /// nor below the default Cauchy scale). false: objective.alpha as given.
  bool choose_prior = true;
  /// Stop when the rendered estimate changes by less than this between rounds:
  /// |A (lambda_k - lambda_{k-1})| / |A lambda_k| < 2 % (over the observed pixels); beside a
  /// window's opening also |lambda_k - lambda_{k-1}| / |lambda_k| (the map lights the room
  /// through it where the views hardly see: docs/method.md, "The map's prior").
  double change_threshold = 0.02;
  /// Average A over rounds, weighted by sample counts (all rounds are unbiased).
  bool combine_rounds = true;
  /// The pixels the camera clipped on the mesh (View::clipped) are rows whose value is a
  /// lower bound (one-sided residuals: the render must reach it), and the pixels within
  /// kBloomMargin of any clipped pixel are upper bounds (bloom brightens them: the render
  /// must not pass them; the default); false: clipped pixels dropped (those beside them
  /// fitted as any other), a glowing surface's radiance bounded below by them instead
  /// (docs/method.md, "Clipped pixels as lower bounds").
  bool clipped_rows = true;
  /// The final relit render of the fitted views (EstimateResult::renders): N > 0 traces every
  /// pixel again at N samples (an independent render, at N / tracer.spp of a round's cost per
  /// pixel); 0 (the default): the clean render below. (EstimateResult::fits is the fit
  /// itself either way: its valid pixels the last round's A lambda plus the lights' columns,
  /// no new paths; the pixels it did not use, masked or without depth, traced at
  /// kMaskedRenderSpp.)
  int render_spp = 0;
  /// The clean render of the fitted views (EstimateResult::renders, render_view*; the fit
  /// itself is EstimateResult::fits): every pixel traced again in passes, the last sized to
  /// reach this (ProgressiveRender), until its relative noise is at most this or the time
  /// (render_seconds) is up; 0: no clean render (renders are the fit). Ignored when
  /// render_spp > 0. The noise is the two halves' difference: what the denoiser's fit
  /// misses comes on top (about 0.5 % on the demo recording and the Cycles cornerbox), so
  /// 0.7 % puts the picture within about 1 % of a reference render.
  double render_noise = 0.007;
  /// The clean render's time; 0 (the default): as long as the estimate took, at least
  /// kMinCleanRenderSeconds.
  double render_seconds = 0;
  /// The clean render's noise smoothed out, guided by what each pixel sees, the lights'
  /// direct light at the first surface traced by the guide (estimation/render_denoise.h);
  /// its stop and its noise are the denoised render's.
  bool render_denoise = true;
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
  /// Called on the estimating thread once, after round 1's first solve and before its search
  /// for lamps and its model selection (about half of round 1), on a cold start only: that
  /// solve's lighting (image units; the map alone). A window shows it while the lamps are
  /// sought (a warm start's first solve lacks the last estimate's lamps: not called).
  std::function<void(const Lighting&, const EnvMap&)> on_first_solve;
  /// Called on the estimating thread once, when the lights are final (polished, their
  /// uncertainty known), before the views are relit: the result so far (its lighting,
  /// uncertainty, albedo, openings, convergence, rounds and lights_seconds; no renders or
  /// fits yet). A caller writes lights.json there, so that it does not wait for the pictures.
  std::function<void(const EstimateResult&)> on_lights;
  /// Scores every convergence row and the result against a ground truth (their angular and
  /// position errors; NaN without one): TruthScorer::FromBundle(bundle) where truth.json is.
  std::shared_ptr<const TruthScorer> scorer;
  /// A live estimate's start (estimator.h's WarmStart: the last estimate's lighting): its map
  /// as the first round's map (its importance and the solver's start), its lamps as the
  /// search's first candidates. Null: from nothing.
  std::shared_ptr<const WarmStart> warm;
};

/// One option of an estimate as every interface shows it.
struct EstimateOption {
  enum class Type { kInt, kReal, kBool, kChoice };
  const char* key;     ///< the command line's --KEY and the command file's KEY=value
  const char* report;  ///< its key in report.json's "settings"
  const char* help;
  Type type;
  double min, max;     ///< valid values (inclusive; min exclusive when min_exclusive)
  bool min_exclusive;
  double (*get)(const EstimateOptions&);
  void (*set)(EstimateOptions*, double);
  /// The viewer's Settings: its label ("" = not shown) and its slider's range (an input
  /// field when ui_min == ui_max).
  const char* label;
  double ui_min, ui_max;
  /// kChoice: the names of the values 0, 1, ... (the value's name is what every interface shows).
  std::vector<std::string> names;
  /// Another key the viewer's command file takes for it ("" = none): its older name there.
  const char* alias = "";
};

/// Every option of an estimate, in the order the interfaces list them.
const std::vector<EstimateOption>& EstimateOptionTable();
/// The option of that key (or alias), or nullptr.
const EstimateOption* FindEstimateOption(const std::string& key);
/// Sets option `key` from its text (a number; a name for a choice; 0/1/true/false for a
/// flag). Throws InputError naming the key on an unknown key or a value it cannot read;
/// the range is Validate's.
void SetEstimateOption(EstimateOptions* o, const std::string& key, const std::string& text);
/// The option's value as text (a choice's name; a number as it would be typed).
std::string EstimateOptionText(const EstimateOption& option, const EstimateOptions& o);
/// Throws InputError naming the first option out of its range ("rings must be between 2
/// and 181", "sigma must be positive and finite").
void Validate(const EstimateOptions& o);

/// The traced mesh's grid in a live preview (LivePreview): pixels a cluster spans.
constexpr double kPreviewTracePixels = 3;
/// A live preview of `full` (docs/method.md, "Live"): what a scan still growing gets, in a
/// few seconds on one core. Round 1 alone (its lamp search and the map on round 1's grid)
/// at half the map's samples, the mesh traced on a kPreviewTracePixels grid, the bundle's
/// albedo (the colours seen at the room's scale: no albedo pass), no polish, no relit
/// views. The lights come out rougher than the full estimate's (a lamp 0.02-0.09 of its
/// distance off on the 60 s scan of scripts/bench-live.sh, against 0.045-0.06); the full
/// estimate is made on the finished scan.
EstimateOptions LivePreview(EstimateOptions full);

}  // namespace lp
