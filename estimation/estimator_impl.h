#pragma once
/// The estimator's shared state and its stages (private to estimation/): the class behind
/// Estimate (estimator.h), its methods in one file per stage: estimator.cpp (the rounds:
/// trace, solve, take the solution; the conclusion and the render), estimator_lights.cpp
/// (the lamps: search, refine, fold, select; the lights' columns and the held-out loss),
/// estimator_sun.cpp (the directional light and the sky), estimator_albedo.cpp (the
/// albedo refinement).
#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <sstream>

#include "common/color.h"
#include "common/error.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "scene/albedo.h"
#include "scene/ray_tracer.h"
#include "scene/simplify.h"
#include "estimation/light_fit.h"
#include "estimation/light_uncertainty.h"
#include "estimation/light_render.h"
#include "estimation/lights/light.h"
#include "estimation/robust_loss.h"
#include "estimation/sampling.h"
#include "estimation/seen_lamps.h"
#include "estimation/seen_windows.h"
#include "estimation/vertex_radiance.h"
#include "estimation/estimator.h"
#include "estimation/truth_scorer.h"

namespace lp::detail {

inline std::vector<double> Plus(std::vector<double> a, const std::vector<double>& b) {
  for (std::size_t i = 0; i < a.size(); ++i) a[i] += b[i];
  return a;
}

/// printf into a string, its format checked against its arguments by the compiler.
[[gnu::format(printf, 1, 2)]] inline std::string Fmt(const char* fmt, ...) {
  char buf[512];
  std::va_list args;
  va_start(args, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, args);
  va_end(args);
  return buf;
}

/// Whether pixel `p` of an image `width` wide is on the grid of every `stride`-th pixel of
/// every `stride`-th row.
inline bool OnGrid(std::size_t p, int width, int stride) {
  return (p % width) % stride == 0 && (p / width) % stride == 0;
}

/// Pixels within this many (Chebyshev distance, at the bundle's resolution) of a clipped
/// pixel are upper bounds in the fit (EstimateOptions::clipped_rows): a lamp's bloom and the
/// lens's flare brighten them, and a bulb's partly covered pixels clip on the wall behind it.
constexpr int kBloomMargin = 1;

/// The map's prior is fitted on every kPriorStride-th pixel of every kPriorStride-th row
/// outside the fold (ChoosePrior; the fold's pixels are all scored).
constexpr int kPriorStride = 2;

/// A directional light whose held-out loss is under this share of the cells' it replaced
/// is a sun, not a flat sky taken for one: the map's prior is not chosen beside it (the map
/// alone at weaker weights is tried to catch that sky; Cycles' uniform sky's light came in at
/// 0.94 of its cells', the suns measured 0.08-0.27: docs/benchmarks.md, session 33).
constexpr double kDecisiveSunRatio = 0.5;

/// The rows (every n-th) the lights' shadow-seeing refinements look at: a quarter of a
/// 160 x 120 view's (what a column costs on all rows: docs/benchmarks.md).
constexpr std::size_t kShadowRows = 4800;
/// A lamp round 1 kept within this share of a triangulated seen place's distance from the
/// scene's centre, or kSeenHoldReachMin metres, of the place is held there
/// (PointLightOptions::hold_seen).
constexpr double kSeenHoldReach = 0.25;
constexpr double kSeenHoldReachMin = 0.15;
/// Levenberg-Marquardt steps of each part's refit for the columns' noise in the lamps'
/// uncertainty (PartsCovariance): from the estimate, a few millimetres away (12 measured
/// the same coverage as 4 on halves: docs/benchmarks.md, session 37).
constexpr int kPartsIterations = 4;
/// The polish's Levenberg-Marquardt stops where a step lowers its objective by less than
/// this share: its last steps each gained 1e-5 or less and moved a lamp by under a
/// micrometre, at a fifth of an estimate's time (docs/benchmarks.md, session 40).
constexpr double kPolishMinDrop = 1e-5;
/// Left to the estimate, the lamps are polished where a lamp's place is less sure from its
/// columns' paths than from the images in some direction (LightUncertainty::paths_ratio);
/// where the images limit it (a lamp 4 m away) the polish's quarter of the rows moved it
/// along its ray as often away from the truth as towards it (docs/benchmarks.md, session 40).
constexpr double kPolishPathsRatio = 1;

/// The lights' uncertainty takes each view as this many blocks across and down (16 a view),
/// each independent of the others: the model's errors (the mesh's, the albedo's, another
/// renderer's) are smooth across neighbouring pixels (docs/method.md, "Uncertainty").
constexpr int kUncertaintyBlocksAcross = 4;

/// `problem`'s solution (compact: 3 per unknown column) over all `columns` (3 per column;
/// those it has no unknown for at 0).
inline std::vector<double> Scattered(const LinearProblem& problem, const std::vector<double>& compact,
                                     std::size_t columns) {
  std::vector<double> full(3 * columns, 0.0);
  for (int k = 0; k < problem.unknown_cells; ++k)
    for (int c = 0; c < 3; ++c) full[3 * problem.cell_of[k] + c] = compact[3 * k + c];
  return full;
}

/// A round's linear problem over the cells some sampled path reached and the lights'
/// columns after them (each light's Scale its 3 unknowns), and the way back from its
/// compact unknowns to the whole map and the lights.
struct RoundProblem {
  std::shared_ptr<const LinearProblem> problem;
  std::vector<double> init;  ///< the estimate so far, compact (3 per unknown cell)
  /// The lights whose columns follow the map's (their shapes; the lamps so far or the
  /// candidates, then the directional lights).
  std::vector<Light> lights;

  /// The unknowns over every column (3 per column): the map's cells, then `lights`.
  std::vector<double> Scatter(const std::vector<double>& compact, int cells) const {
    return Scattered(*problem, compact, cells + lights.size());
  }
  /// The lights of kind T of a full vector (those with any scale), their scales from it.
  template <class T>
  std::vector<T> Lit(const std::vector<double>& full, int cells) const {
    std::vector<T> out;
    for (std::size_t i = 0; i < lights.size(); ++i) {
      const double* v = &full[3 * (cells + i)];
      const T* light = std::get_if<T>(&lights[i]);
      if (!light || !(v[0] > 0 || v[1] > 0 || v[2] > 0)) continue;
      out.push_back(*light);
      Scale(out.back()) = Eigen::Vector3d(v[0], v[1], v[2]);
    }
    return out;
  }
  /// Whether a light of kind T has a column.
  template <class T>
  bool Has() const {
    for (const Light& l : lights)
      if (std::holds_alternative<T>(l)) return true;
    return false;
  }
};

/// One estimate (the method, docs/method.md): sequential Monte Carlo rounds of tracing the
/// transport matrix with importance from the estimate so far and solving the robust
/// non-negative problem warm-started; then, on a reconstructed mesh, passes of albedo
/// refinement each followed by more rounds; then the fitted views rendered under the
/// result. Each step is a method; the state they share is the members.
class Estimator {
 public:
  /// `bundle`'s albedo is already scaled by `albedo_scale` (EstimateResult::albedo_scale).
  Estimator(const SceneBundle& bundle, const EstimateOptions& options, double albedo_scale = 1);

  /// Up to max_rounds rounds under the current albedo (round 1 is the cold start; after an
  /// albedo pass they are warm-started from the estimate so far, with an A of their own);
  /// stops early when the rendered estimate settles.
  void RunRounds();
  /// Whether the last rounds fitted the grid of the rounds before an albedo pass
  /// (PreAlbedoStride) and no pass came: then the rounds go on, on every pixel.
  bool OnPreAlbedoGrid() const { return stride_ > 1 && after_grid_ > 0; }
  /// Whether the albedo is refined at all (sets res_.albedo_left_out when not).
  bool AlbedoRefinable();
  /// Why the options and the bundle leave the albedo unrefined (kRefined: they do not).
  AlbedoLeftOut AlbedoLeftOutByOptions() const;
  /// De-lights the colours seen by the estimate's irradiance and segments them again into
  /// the albedo the next rounds run under; false when there is nothing to divide by.
  bool RefineAlbedo(int pass);
  /// The lights as they stand (directional lights first, then lamps, then glowing surfaces).
  std::vector<Light> Lights() const {
    std::vector<Light> out = Joined(suns_, points_);
    out.insert(out.end(), emitters_.begin(), emitters_.end());
    return out;
  }
  /// Whether the lights moved no more than albedo_settle since `before` (Lights() then): the
  /// largest, over the lights, of a lamp's distance from the nearest lamp before over that
  /// one's distance from the scene's centre, and a directional light's angle to the nearest
  /// before (radians); infinite when the count of a kind changed. Recorded as the last
  /// albedo pass's move, and said.
  bool Settled(const std::vector<Light>& before);
  std::vector<float> OverClusters(const std::vector<float>& values) const;
  int AlbedoPaths() const;
  std::vector<float> AlbedoIrradiance(VertexRadiance* radiance, int pass);
  std::size_t MarkNoisyClusters(const VertexRadiance& radiance, std::vector<std::uint8_t>* more) const;
  Mesh WithAlbedoOf(const Mesh& full, const std::vector<float>& irradiance) const;
  /// The estimate in image units, its scores and what the user should know about it.
  void Conclude();
  int PolishSpp(std::optional<std::vector<LightUncertainty>>* rounds);
  std::vector<LightUncertainty> Carried(const std::vector<LightUncertainty>& rounds, const std::vector<Light>& before,
                                        const std::vector<Light>& now);
  bool PolishLamps(int spp);
  /// How well the images fix each light (Lights()' order, normalized units), on the last
  /// round's rows; empty without lights or shading vertices.
  std::vector<LightUncertainty> Uncertainty();
  void SayUncertainty(const std::vector<LightUncertainty>& u);
  /// The map's prior chosen by the data (docs/method.md, "The map's prior"; res_.prior says
  /// how): where it is weaker than the given one, the round's map and lights' intensities
  /// are solved again at it (its rows in `info`) and the rounds after it run at it. Returns
  /// whether the prior changed.
  bool ChoosePrior(RoundInfo* info);
  /// Beside lamps, where a weaker prior than the given one was chosen, the map solved once
  /// more at the weakest one tried (its shrinkage of the extended light undone).
  void RelaxPrior();
  /// Whether this round (of `last`) chooses the map's prior (kPriorRound).
  bool PriorRound(int round, int last);
  /// The sky beside a directional light, after the rounds (docs/method.md).
  void FitSky();
  /// The lights are final: their time, and EstimateOptions::on_lights with the result so far.
  void LightsFinal() {
    res_.lights_seconds = clock_.Seconds();
    if (opt_.on_lights) opt_.on_lights(res_);
  }
  /// Relit renders of the fitted views under the estimate (EstimateOptions::render_spp).
  void RenderFittedViews();
  std::vector<ImageRGB> CleanRender(const CellSampler& sampler);
  EstimateResult TakeResult() {
    res_.total_seconds = clock_.Seconds() - res_.clean_render_seconds;
    return std::move(res_);
  }

 private:
  double Now() const { return opt_.time_offset + clock_.Seconds(); }
  void Progress(const std::string& s) const {
    if (opt_.progress) opt_.progress(s);
  }
  void CheckCancel() const {
    if (opt_.cancelled && opt_.cancelled()) throw Cancelled();
  }
  std::string SceneFile() const { return (bundle_.dir / "scene.json").string(); }
  static std::vector<View> UnusedPixels(std::vector<View> views);
  void PutFit(std::vector<ImageRGB>* renders);
  void Observe();
  void StartWarm(const WarmStart& warm);
  void UseViews(int stride);
  void UseStride(int stride, int round);
  int FirstRoundStride() const;
  int PreAlbedoStride() const;
  int MapSamples(int round) const;
  double MapShare();
  Mesh TracedMesh();
  RoundProblem TraceRound(int round, int first, RoundInfo* info);
  SolveResult Solve(const RoundProblem& rp, int round, RoundInfo* info, bool graduated);
  std::vector<double> TakeSolution(const RoundProblem& rp, const SolveResult& sr, RoundInfo* info);
  void FitLights(const RoundProblem& rp, const std::vector<double>& full, RoundInfo* info);
  void EndRound(const SolveResult& sr, RoundInfo* info);
  void MakeMapProblem();
  /// Per row of A_: its block, `across` x `across` blocks a view, numbered
  /// (view * across + y) * across + x.
  std::vector<int> RowBlocks(int across) const;
  /// The lights in the order of a round problem's columns: `lights`, then the directional
  /// lights so far.
  std::vector<Light> ColumnOrder(const std::vector<PointLight>& lights) const;
  /// The render of some rows: `map_rows` (those of A_) times the map's part of `full`, plus
  /// each light's `columns` (those rows) times its scale in `full`.
  std::vector<double> HeldOutRender(const TransportMatrix& map_rows, const std::vector<std::vector<float>>& columns,
                                    const std::vector<double>& full) const;
  /// `problem`'s unknowns (over the map's cells, then `lights`' columns) at the estimate so
  /// far: lambda_ and the lights' scales.
  std::vector<double> StartOf(const LinearProblem& problem, const std::vector<Light>& lights) const;
  /// Per weight of `weights` (strongest first): the held-out loss per block of RowBlocks
  /// (each block scored in its fold), and the folds' mean solution (the map's cells, then
  /// `lights`), the map and `lights` fitted.
  struct PriorFolds {
    std::vector<std::vector<double>> loss, mean;
  };
  PriorFolds PriorLosses(const std::vector<Light>& lights, const std::vector<MapPrior>& priors,
                         const std::vector<int>& block, const std::vector<double>* start = nullptr);
  void TrySmoothMaps(const std::vector<Light>& lights, const std::vector<int>& block, std::vector<MapPrior>* priors,
                     PriorFolds* folds);
  void SolveAtPrior(MapPrior prior, const std::vector<double>& start, RoundInfo* info);
  std::string PriorLeftOut(const std::vector<Light>& lights) const;
  std::string PriorGivenByOptions() const;
  void SayPrior(const std::vector<double>& loss, const std::vector<double>& se, std::size_t k, std::size_t lights);
  // The near-light steps (docs/method.md, "Point lights").
  bool NearLights() const { return opt_.point_lights.max_lights > 0; }
  /// Whether `round` looks for a directional light: the first round on every pixel (round 2
  /// after round 1's grid; a sun's shadow edges are a few pixels wide), while none was kept.
  bool SunRound(int round) const {
    return opt_.directional_lights && suns_.empty() &&
           (round == 1 ? stride_ == 1 : round == after_grid_);
  }
  /// The brightest cell's neighbourhood in the map (cells within 2.5 ring spacings of it)
  /// and its share of the map's power (0: a dark map).
  std::pair<std::vector<int>, double> BrightestNeighbourhood() const;
  void GatherVertices(int round, int first);
  RoundProblem WithLights(const std::vector<PointLight>& lights);
  bool FitPointLights(const RoundProblem& rp, const std::vector<double>& full, RoundInfo* info);
  std::vector<PointLight> Candidates(RoundInfo* info);
  const std::vector<SeenLamp>& SeenLampsOnce();
  std::vector<Eigen::Vector3d> SearchPlaces(std::size_t* first_seen, std::size_t* first_grid);
  /// After round 1's model selection: the kept lamp nearest each triangulated seen place,
  /// when round 1 left it within kSeenHoldReach of it, is put there and held
  /// (PointLight::held), the map and the intensities then solved again. Says why either way.
  void HoldAtSeen(std::vector<PointLight>* lights, RoundInfo* info);
  /// `y` - `render` with one_sided_'s entries (`keep`'s rows of them where given) above
  /// their level counted as 0.
  std::vector<double> Residuals(const std::vector<double>& y, const std::vector<double>& render,
                                const std::vector<std::uint8_t>* keep = nullptr) const;
  /// one_sided_ of `keep`'s rows (`want`: those kept, or those not).
  std::vector<std::uint8_t> OneSidedRows(const std::vector<std::uint8_t>& keep, bool want) const;
  void RefinePositions(std::vector<PointLight>* lights, RoundInfo* info, const char* step = "lights",
                       bool shadows = true);
  void SolveWithLights(std::vector<PointLight>* lights, RoundInfo* info, bool graduated);
  void FoldLights(std::vector<PointLight>* lights, int round);
  bool FitRadii(std::vector<PointLight>* lights);
  void SelectModel(std::vector<PointLight>* lights);
  /// `traced`: the directional light's held-out rows traced at tracer.spp (HeldOutSunColumn:
  /// against the map alone, whose columns have those paths); else from the shading vertices,
  /// as a lamp's are (against a lamp: the same noise).
  double HoldoutLoss(const std::vector<PointLight>& lights, const DirectionalLight* directional = nullptr,
                     bool traced = false, int iterations = kTrialIterations);
  std::vector<float> HeldOutSunColumn(const DirectionalLight& light);
  std::vector<float> TracedSunColumn(DirectionalLight light, const std::vector<std::uint8_t>* rows, int spp,
                                     std::uint64_t seed);
  std::vector<int> SkyCells() const;
  double RenderedShare(const PointLight& light);
  std::vector<float> Column(const Light& light);
  SplitColumn Split(const Light& light);
  ObjectiveParams CellWeights(const LinearProblem& problem, ObjectiveParams params, double prior = 0) const;
  ObjectiveParams WithSmoothness(const LinearProblem& problem, ObjectiveParams params) const;
  void Score(ConvergenceRow* row, const Lighting& lighting) const;
  /// A convergence row of a light's refinement (the objective and the sum of squared
  /// residuals over y_ as given), scored and step left to the caller.
  ConvergenceRow LightRow(const RoundInfo& info, double sigma, double objective, double sse) const {
    ConvergenceRow row;
    row.wall_seconds = Now();
    row.round = info.round;
    row.iteration = res_.convergence.empty() ? 0 : res_.convergence.back().iteration + 1;
    row.sigma = sigma;
    row.albedo_pass = res_.albedo_passes;
    row.objective = objective;
    row.relative_rmse = std::sqrt(sse / static_cast<double>(y_.size()));
    row.photometric_rmse = row.relative_rmse * res_.image_mean;
    return row;
  }
  /// A model's trial solve (the held-out fits that choose the lights and the prior, a
  /// glowing surface's objective), at most `iterations`: each iteration a convergence row
  /// "trial" of the trial's own problem (its objective and RMSE), so that the time the
  /// choices take shows in the log and its plot. With `sink` (a solve on a worker thread)
  /// the rows go there, for the caller to Push in its thread.
  SolverOptions TrialOptions(int iterations, std::vector<ConvergenceRow>* sink = nullptr) {
    SolverOptions so;
    so.max_iterations = iterations;
    so.on_iteration = [this, sink](const IterationInfo& it) {
      ConvergenceRow row;
      row.wall_seconds = Now();
      row.round = round_;
      row.iteration = it.iteration;
      row.sigma = res_.objective_params.sigma;
      row.albedo_pass = res_.albedo_passes;
      row.step = "trial";
      row.objective = it.objective;
      row.relative_rmse = it.Rmse();
      row.photometric_rmse = row.relative_rmse * res_.image_mean;
      row.point_lights = static_cast<int>(points_.size());
      if (!sink) return Push(row);
      sink->push_back(row);
      CheckCancel();
    };
    return so;
  }
  /// Appends a convergence row, tells the caller's callback, and stops here when cancelled.
  void Push(const ConvergenceRow& row) {
    res_.convergence.push_back(row);
    if (opt_.on_convergence) opt_.on_convergence(row);
    CheckCancel();
  }
  /// The estimate so far in image units: the map `lambda_` and the lights.
  Lighting InImageUnits() const {
    Lighting out{lambda_, Lights()};
    for (double& v : out.map) v *= res_.image_mean;
    for (Light& l : out.lights) Scale(l) *= res_.image_mean;
    return out;
  }
  // The directional light (docs/method.md, "Directional lights"): proposed, shaped,
  // settled beside the map, selected.
  struct DirectionalProposal {
    DirectionalLight light;
    std::vector<int> cells;  ///< the map's cells it takes the place of
    double map_share = 0;    ///< their share of the map's power
    std::vector<double> without;  ///< the map without them
  };
  /// The light's fit on kShadowRows of the rows, the rest of the image (`base`) held; every
  /// accepted step is a convergence row ("sun", scored with the map `without` its cells).
  struct SunFit {
    SunFit(Estimator& e, RoundInfo* info)
        : fit(e.FitProblem(&base)),
          log([&e, info, this](int, double E, double sse, const std::vector<Light>& now) {
            // (the map's penalty left out: held fixed here; E and the squared residuals
            // times the stride estimate the whole problem's)
            ConvergenceRow row = e.LightRow(*info, fit.loss.sigma, E * share->stride, sse * share->stride);
            row.step = "sun";
            e.Score(&row, {*without, Joined(OfKind<DirectionalLight>(now), e.points_)});
            e.Push(row);
          }) {}
    SunFit(const SunFit&) = delete;
    SunFit& operator=(const SunFit&) = delete;
    /// Holds `rest` (3 per row) fixed, logging rows against the map `map_without`.
    void Hold(std::vector<double> rest, const std::vector<double>& map_without) {
      base = std::move(rest);
      without = &map_without;
      share = std::make_unique<LightFitSubset>(fit, kShadowRows);
    }
    int Search(DirectionalLight* sun, double start_deg) const;
    std::vector<double> base;
    const std::vector<double>* without = nullptr;
    LightFitProblem fit;
    std::unique_ptr<LightFitSubset> share;
    LightFitLog log;
  };
  bool FitDirectionalLight(RoundInfo* info);
  // Glowing surfaces (docs/method.md, "Glowing surfaces"; estimator_emitters.cpp).
  /// Whether `round` looks for them: the first on every pixel, once, after the lamps and the sun.
  bool EmitterRound() const { return opt_.emitters && !emitters_sought_ && PastFirstGrid() && !vertices_.camera.empty(); }
  /// Whether the rounds are past round 1's first estimate on a grid: on every pixel, or on
  /// the grid of the rounds before the first albedo pass (PreAlbedoStride).
  bool PastFirstGrid() const { return stride_ == 1 || after_grid_ > 0; }
  /// Whether the map's prior is still to be chosen, in a round on every pixel (PriorRound).
  bool PriorAhead() const { return PastFirstGrid() && !res_.prior.done; }
  bool ProposeEmitters(RoundInfo* info);
  /// SelectModel on the lamps again beside the glowing surfaces kept (solved again if one goes).
  void ReselectLamps(RoundInfo* info);
  // Windows (estimator_openings.cpp): a glowing surface that could be a window tried as an opening.
  /// `candidate` (not in emitters_) as an opening against the lights `as_is` (emitters_ with
  /// it, where its trial kept it, or without), both on fresh paths; true where the data
  /// chose the opening: the round's state is then the opening's, with its `objective` and
  /// `held`-out loss.
  bool TryOpening(const EmitterLight& candidate, const std::vector<EmitterLight>& as_is, double* objective,
                  double* held);
  void MarkWindowCells(const Eigen::Vector3d& out);
  bool KeepTheGivenPrior();
  void UseAlpha(double alpha);
  void MarkSparsePeak();
  bool prior_restored_ = false;  ///< KeepTheGivenPrior changed the weight: a round follows at it
  /// The map's next-event sampler by `lambda` (empty: uniform) over `reachable`, aiming
  /// kPortalShare of its samples through portals_ where there are any.
  CellSampler Sampler(const std::vector<double>& lambda, const std::vector<std::uint8_t>& reachable) const;
  void MarkSeenWindows();
  /// Says, for each window seen as a hole, its rectangle and the light the estimate sends into
  /// the room through it: the map's (PowerThrough) and a pane's over it.
  void SayTheLightThroughWindows();
  void StartBesideSeenWindows();
  /// After the glowing surfaces are chosen: a window seen as a hole whose glowing pane was
  /// kept is no longer a window whose light the map holds; window_cells_ again from the
  /// openings and the other windows (cells are marked per wall: an unpaned window on the
  /// same wall keeps them the windows'; none left: the given prior for the rounds to its
  /// choice). Not once the prior is chosen.
  void WindowCellsBesidePanes();
  /// Flat, and most rays out of its back leave the scene (`opened`: the scene with it open).
  bool CouldBeWindow(const EmitterLight& e, const RayTracer& opened) const;
  /// Per triangle of the traced mesh: open already, or its centre on `shape`.
  std::vector<std::uint8_t> TrianglesOn(const std::shared_ptr<const EmitterShape>& shape) const;
  TracerOptions MapTracer(int round, std::uint64_t stream) const;
  void MarkReachable(const LinearProblem& problem);
  /// A_, its problem and the shading vertices traced afresh on scene_ (every cell sampled).
  void TraceAfresh(int round);
  struct TracedState;
  /// Keeps `candidate` beside `kept` when the objective and the held-out loss say so (both
  /// updated then).
  /// A pane over a hole (EmitterLight::in_a_hole) is neither tried with a lamp inside nor as
  /// an opening (it is one).
  bool TryEmitter(const EmitterLight& candidate, std::vector<EmitterLight>* kept, double* objective, double* held);
  /// `kept` beside `candidate` with no surface glowing twice: each kept emitter on the traced
  /// mesh without the triangles the candidate covers (dropped when it covers them all; its
  /// clipped pixels' floor carried over). A candidate that is a part of a kept surface is
  /// then that part glowing apart from the rest, at its own radiance.
  std::vector<EmitterLight> ApartFrom(const std::vector<EmitterLight>& kept, const EmitterLight& candidate);
  /// The windows seen as holes (res_.windows), each as a glowing pane over its opening
  /// (frosted glass or a curtain that returned no depth), its radiance at least what its
  /// clipped pixels show.
  std::vector<EmitterLight> PanesOverHoles();
  /// The kept emitter a lamp sits inside (within half its extent of where LampInside puts
  /// one: a bulb in its shade), or null.
  const EmitterLight* ShadeOf(const PointLight& lamp) const;
  /// Beside a candidate emitter (`with`: the emitters then), the lamp nearest to where one
  /// inside it would be moved there, and kept there when the objective and the held-out loss
  /// (given for where it is) both fall; they are then the new ones.
  bool LampInside(const EmitterLight& candidate, const std::vector<EmitterLight>& with, double* objective, double* held);
  /// The round's whole objective solved again with `emitters` (left as emitters_) beside the map and the lights.
  double ObjectiveWith(const std::vector<EmitterLight>& emitters, int iterations = kTrialIterations);
  /// The traced mesh's segments the views see brighter than a white surface under the
  /// lights so far (at least kMinEmitterPixels each), as emitters of a first radiance.
  std::vector<EmitterLight> GlowingSegments();
  struct Glow;
  Glow GlowingTriangles();
  std::vector<double> Bounded(const RoundProblem& rp, std::vector<double> lambda) const;
  /// Raises each emitter's radiance to what its clipped pixels show at least (emitter_floor_).
  void BoundEmitters();
  /// The emitters of `lights` on the bundle's own mesh (its triangles on the traced mesh's
  /// emitter), as emitters.ply holds them; as they are when the mesh is traced as it is.
  void OnBundleMesh(std::vector<Light>* lights);
  bool ProposeDirectionalLight(DirectionalProposal* out);
  bool ShapeDirectionalLight(DirectionalProposal* proposal, SunFit* fit);
  void SettleDirectionalLight(DirectionalProposal* proposal, SunFit* fit, RoundInfo* info);
  bool SelectDirectionalLight(const DirectionalProposal& proposal, double without_loss);
  std::vector<double> LightsRender(const std::vector<PointLight>& points, const std::vector<DirectionalLight>& suns);
  /// The lights' robust objective on vertices_, `base` the rest of the image held.
  LightFitProblem FitProblem(const std::vector<double>* base) const {
    LightFitProblem fit;
    fit.scene = scene_.get();
    fit.vertices = &vertices_;
    fit.y = &y_;
    if (!one_sided_.empty()) fit.one_sided = &one_sided_;
    fit.base = base;
    fit.loss = CauchyLoss{res_.objective_params.sigma};
    fit.alpha = res_.objective_params.alpha * opt_.point_lights.weight;
    fit.beta = res_.objective_params.beta;
    fit.debiased = opt_.point_lights.debiased;
    if (row_segment_.size() * 3 == y_.size()) fit.segment = &row_segment_;  // (made only with free_albedo)
    return fit;
  }

  const SceneBundle& bundle_;
  const EstimateOptions& opt_;
  Stopwatch clock_;
  EstimateResult res_;
  const EnvMap& env_;  ///< res_.env
  /// The map's prior, as EstimateOptions' objective.alpha (per kAlphaReferencePixels): the
  /// given one, then the one ChoosePrior chose.
  double alpha_ = 3;
  /// Per cell: the neighbourhood of the map's brightest cell where it held a compact light
  /// (directional.min_map_share of the map's power) when the prior was chosen, which keeps
  /// the given prior (CellWeights); empty: none.
  std::vector<std::uint8_t> sparse_cells_;
  /// Per cell: whether its direction lies behind a window, an opening or a hole the cameras
  /// saw (in the half of the sphere its wall faces away from the room), where the map's light
  /// through the window is a sky's; beside a window the prior chosen applies to these cells
  /// alone and the others keep the given one (CellWeights); empty: no window.
  std::vector<std::uint8_t> window_cells_;
  /// The windows' openings as next-event estimation aims through them (path_tracer.h's
  /// Portal): every sampler of the map's light aims a share of its samples there (Sampler).
  std::vector<Portal> portals_;
  std::vector<EnvMap::Neighbours> adjacency_;  ///< env_.Adjacency(), for the map's smoothness
  int cells_ = 0;
  /// The views the rounds fit (the bundle's, or round 1's grid of their pixels: UseViews)
  /// and their grid's stride.
  std::vector<View> views_;
  int stride_ = 0;
  int after_grid_ = 0;  ///< the first round on every pixel after round 1's grid (0: none)
  std::optional<std::vector<SeenLamp>> seen_lamps_;  ///< SeenLampsOnce
  int rounds_past_grid_ = 0;  ///< the rounds on every pixel so far (PriorRound)
  int round_ = 0;             ///< the round running (RunRounds), for TrialOptions' rows
  bool warm_ = false;  ///< round 1 starts from a live estimate's map (EstimateOptions::warm)
  /// The share of the rendered light that is the map's (the rest the lights'), after the last round.
  double map_share_ = 1;
  std::vector<double> y_;  ///< their observations over the mean of all the valid pixels'
  /// Per entry of y_: 1 where its row is a pixel clipped on the mesh (its value a lower bound
  /// the render must reach: LinearProblem::one_sided); empty where no row is.
  std::vector<std::uint8_t> one_sided_;
  std::unique_ptr<RayTracer> scene_;
  /// Per vertex of the bundle's mesh: its vertex in the traced mesh (empty: the same mesh).
  std::vector<int> cluster_;
  Mesh mesh_;  ///< the bundle's mesh, whose albedo is refined (empty until then)
  /// Per row of y_: the de-lit segment (of the last albedo pass) its pixel sees, or -1
  /// (empty before a pass, or once the rows change).
  std::vector<int> row_segment_;
  /// Per row of views_: the segment of `labels` (per vertex of `full`, a tracer of the
  /// bundle's mesh) its pixel's centre sees, or -1.
  std::vector<int> RowSegments(const RayTracer& full, const std::vector<int>& labels) const;
  std::vector<double> lambda_;  ///< the estimate, normalized units, 3 per cell
  std::vector<std::uint8_t> reachable_;  ///< per cell: some sampled path reached it
  TransportMatrix A_;  ///< the map's columns, averaged over the rounds under one albedo
  /// A_'s problem, with its normal matrices (every problem of the round appends to it).
  std::shared_ptr<LinearProblem> map_problem_;
  /// The same over the rows the model selection fits (left out: holdout_), and A_'s
  /// held-out rows; made on first use after A_ changes.
  std::shared_ptr<LinearProblem> holdout_fit_;
  TransportMatrix holdout_held_;
  // Near lights.
  std::vector<PointLight> points_;  ///< the point lights so far, normalized units
  std::vector<DirectionalLight> suns_;  ///< the directional lights so far, normalized units
  /// The kept directional light's held-out loss over its cells' (SelectDirectionalLight); 1
  /// when none was selected in this estimate.
  double sun_held_out_ratio_ = 1;
  std::vector<EmitterLight> emitters_;  ///< the glowing surfaces so far, normalized units
  bool emitters_sought_ = false;
  /// Per emitter (its triangles): the least radiance its clipped pixels show (normalized).
  /// (Held by the shape itself: a candidate's freed address could not come back with another's floor.)
  std::map<std::shared_ptr<const EmitterShape>, Eigen::Vector3d> emitter_floor_;
  /// Per triangle of the traced mesh: the least radiance its clipped pixels show, as the last
  /// search for glowing surfaces found it (ApartFrom's floor for what is left of a surface).
  std::vector<Eigen::Vector3d> triangle_floor_;
  ShadingVertices vertices_;        ///< the rounds', for the lights' columns and positions
  /// The last few columns on vertices_ (Column), cleared when vertices_ change.
  struct CachedColumn {
    Light light;  ///< its shape (its scale aside)
    SplitColumn column;
  };
  std::vector<CachedColumn> columns_;
  double vertex_samples_ = 0;       ///< paths per pixel they hold
  std::vector<std::uint8_t> holdout_;  ///< per row: left out of the model selection's fit
  const char* solve_step_ = "solve";   ///< the step Solve's convergence rows are
  Eigen::Vector3d centre_;
  double radius_ = 1;
};

}  // namespace lp::detail
