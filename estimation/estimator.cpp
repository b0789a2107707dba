#include "estimation/estimator.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>

#include "common/color.h"
#include "common/error.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "scene/albedo.h"
#include "scene/ray_tracer.h"
#include "scene/simplify.h"
#include "estimation/light_fit.h"
#include "estimation/light_render.h"
#include "estimation/lights/light.h"
#include "estimation/robust_loss.h"
#include "estimation/sampling.h"
#include "estimation/vertex_radiance.h"

namespace lp {

const char* ToString(AlbedoLeftOut why) {
  switch (why) {
    case AlbedoLeftOut::kRefined: return "";
    case AlbedoLeftOut::kNoPasses: return "no albedo passes asked for";
    case AlbedoLeftOut::kKnownAlbedo: return "the bundle's albedo is known (its mesh has no shaded colours)";
    case AlbedoLeftOut::kNothingLit: return "the estimate lights nothing, or every colour seen is black";
  }
  return "?";
}

std::vector<double> CollectObservations(const std::vector<View>& views) {
  std::vector<double> y;
  for (const View& v : views)
    for (std::size_t i = 0; i < v.valid.size(); ++i)
      if (v.valid[i])
        for (int c = 0; c < 3; ++c) y.push_back(v.image.data[3 * i + c]);
  return y;
}

namespace {

std::vector<double> Plus(std::vector<double> a, const std::vector<double>& b) {
  for (std::size_t i = 0; i < a.size(); ++i) a[i] += b[i];
  return a;
}

std::string Fmt(const char* fmt, double a, double b = 0, double c = 0, double d = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, fmt, a, b, c, d);
  return buf;
}

/// The rows (every n-th) the lights' shadow-seeing refinements look at: a quarter of a
/// 160 x 120 view's (what a column costs on all rows: docs/benchmarks.md).
constexpr std::size_t kShadowRows = 4800;

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
    std::vector<double> full(3 * (cells + lights.size()), 0.0);
    for (int k = 0; k < problem->unknown_cells; ++k)
      for (int c = 0; c < 3; ++c) full[3 * problem->cell_of[k] + c] = compact[3 * k + c];
    return full;
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
  Estimator(const SceneBundle& bundle, const EstimateOptions& options);

  /// Up to max_rounds rounds under the current albedo (round 1 is the cold start; after an
  /// albedo pass they are warm-started from the estimate so far, with an A of their own);
  /// stops early when the rendered estimate settles.
  void RunRounds();
  /// Whether the albedo is refined at all (sets res_.albedo_left_out when not).
  bool AlbedoRefinable();
  /// De-lights the colours seen by the estimate's irradiance and segments them again into
  /// the albedo the next rounds run under; false when there is nothing to divide by.
  bool RefineAlbedo(int pass);
  std::vector<float> OverClusters(const std::vector<float>& values) const;
  int AlbedoPaths() const;
  Mesh WithAlbedoOf(const Mesh& full, const std::vector<float>& irradiance) const;
  /// The estimate in image units, its scores and what the user should know about it.
  void Conclude();
  /// The sky beside a directional light, after the rounds (docs/method.md).
  void FitSky();
  /// Relit renders of the fitted views under the estimate (EstimateOptions::render_spp).
  void RenderFittedViews();
  EstimateResult TakeResult() {
    res_.total_seconds = clock_.Seconds();
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
  void UseViews(int stride);
  int FirstRoundStride() const;
  int MapSamples(int round) const;
  double MapShare();
  Mesh TracedMesh();
  RoundProblem TraceRound(int round, int first, RoundInfo* info);
  SolveResult Solve(const RoundProblem& rp, int round, RoundInfo* info, bool graduated);
  void Update(const RoundProblem& rp, const SolveResult& sr, RoundInfo* info);
  void MakeMapProblem();
  // The near-light steps (docs/method.md, "Point lights").
  bool NearLights() const { return opt_.point_lights.max_lights > 0; }
  /// Whether `round` looks for a directional light: the first round on every pixel (round 2
  /// after round 1's grid; a sun's shadow edges are a few pixels wide), while none was kept.
  bool SunRound(int round) const {
    return NearLights() && opt_.directional_lights && suns_.empty() &&
           (round == 1 ? stride_ == 1 : round == after_grid_);
  }
  /// The brightest cell's neighbourhood in the map (cells within 2.5 ring spacings of it)
  /// and its share of the map's power (0: a dark map).
  std::pair<std::vector<int>, double> BrightestNeighbourhood() const;
  void GatherVertices(int round, int first);
  RoundProblem WithLights(const std::vector<PointLight>& lights);
  bool FitPointLights(const RoundProblem& rp, const std::vector<double>& full, RoundInfo* info);
  std::vector<PointLight> Candidates(RoundInfo* info);
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
                     bool traced = false);
  std::vector<float> HeldOutSunColumn(const DirectionalLight& light);
  std::vector<float> TracedSunColumn(DirectionalLight light, const std::vector<std::uint8_t>* rows, int spp,
                                     std::uint64_t seed);
  std::vector<int> SkyCells() const;
  double RenderedShare(const PointLight& light);
  std::vector<float> Column(const Light& light);
  ObjectiveParams CellWeights(const LinearProblem& problem, ObjectiveParams params) const;
  void Score(ConvergenceRow* row, const std::vector<double>& env_lambda, const std::vector<PointLight>& points,
             const std::vector<DirectionalLight>& suns) const;
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
  /// Appends a convergence row, tells the caller's callback, and stops here when cancelled.
  void Push(const ConvergenceRow& row) {
    res_.convergence.push_back(row);
    if (opt_.on_convergence) opt_.on_convergence(row);
    CheckCancel();
  }
  std::vector<PointLight> InImageUnits(std::vector<PointLight> lights) const {
    for (PointLight& l : lights) l.intensity *= res_.image_mean;
    return lights;
  }
  std::vector<DirectionalLight> InImageUnits(std::vector<DirectionalLight> lights) const {
    for (DirectionalLight& l : lights) l.irradiance *= res_.image_mean;
    return lights;
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
            e.Score(&row, *without, e.points_, OfKind<DirectionalLight>(now));
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
    fit.base = base;
    fit.loss = CauchyLoss{res_.objective_params.sigma};
    fit.alpha = res_.objective_params.alpha * opt_.point_lights.weight;
    fit.beta = res_.objective_params.beta;
    return fit;
  }

  const SceneBundle& bundle_;
  const EstimateOptions& opt_;
  Stopwatch clock_;
  EstimateResult res_;
  const EnvMap& env_;  ///< res_.env
  int cells_ = 0;
  /// The views the rounds fit (the bundle's, or round 1's grid of their pixels: UseViews)
  /// and their grid's stride.
  std::vector<View> views_;
  int stride_ = 0;
  int after_grid_ = 0;  ///< the first round on every pixel after round 1's grid (0: none)
  /// The share of the rendered light that is the map's (the rest the lights'), after the last round.
  double map_share_ = 1;
  std::vector<double> y_;  ///< their observations over the mean of all the valid pixels'
  std::vector<TruthLight> truth_;
  std::unique_ptr<RayTracer> scene_;
  /// Per vertex of the bundle's mesh: its vertex in the traced mesh (empty: the same mesh).
  std::vector<int> cluster_;
  Mesh mesh_;  ///< the bundle's mesh, whose albedo is refined (empty until then)
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
  ShadingVertices vertices_;        ///< the rounds', for the lights' columns and positions
  /// The last few columns on vertices_ (Column), cleared when vertices_ change.
  struct CachedColumn {
    Light light;  ///< its shape (its scale aside)
    std::vector<float> column;
  };
  std::vector<CachedColumn> columns_;
  double vertex_samples_ = 0;       ///< paths per pixel they hold
  std::vector<std::uint8_t> holdout_;  ///< per row: left out of the model selection's fit
  Eigen::Vector3d centre_;
  double radius_ = 1;
};

void CheckOptions(const EstimateOptions& opt) {
  if (opt.rings < kMinRings || opt.rings > kMaxRings)
    throw InputError("rings must be between " + std::to_string(kMinRings) + " and " + std::to_string(kMaxRings));
  if (opt.max_rounds < 1) throw InputError("max-rounds must be at least 1");
  if (!(opt.objective.sigma > 0) || !std::isfinite(opt.objective.sigma))
    throw InputError("sigma must be positive and finite");
}

Estimator::Estimator(const SceneBundle& bundle, const EstimateOptions& options)
    : bundle_(bundle), opt_(options), env_(res_.env) {
  CheckOptions(opt_);
  res_.env = EnvMap(opt_.rings, bundle_.up);
  cells_ = env_.size();
  Observe();
  Stopwatch bvh;
  scene_ = std::make_unique<RayTracer>(TracedMesh());
  res_.bvh_seconds = bvh.Seconds();
  // The scene's centre and size are the bundle's mesh's (truth.json's measures use them).
  BoundingSphere(bundle_.mesh, &centre_, &radius_);
  res_.scene_centre = centre_;
  if (bundle_.truth_json) {
    truth_ = ParseTruthLights(*bundle_.truth_json, (bundle_.dir / "truth.json").string());
    CentreTruthLights(&truth_, centre_);
  }
  // Start dark and uniform (paper): every cell equally likely to be sampled.
  lambda_.assign(3 * cells_, 1e-3);
  reachable_.assign(cells_, 1);
}

/// The bundle's mesh, clustered on a grid of opt_.trace_pixels pixels where it is finer
/// than that (cluster_ then maps its vertices to the traced mesh's).
Mesh Estimator::TracedMesh() {
  const Mesh& full = bundle_.mesh;
  res_.traced_triangles = static_cast<int>(full.triangles.size());
  res_.traced_vertices = static_cast<int>(full.positions.size());
  if (!(opt_.trace_pixels > 0)) return full;
  Stopwatch cs;
  std::vector<Camera> cameras;
  for (const View& v : bundle_.views) cameras.push_back(v.camera);
  const float pixel = FiniteQuantile(PixelFootprints(full, cameras), 0.1);
  const float cell = static_cast<float>(opt_.trace_pixels) * pixel;
  if (!(cell >= kMinTraceCellEdges * MedianEdgeLength(full))) return full;
  ClusteredMesh coarse;
  try {
    coarse = ClusterVertices(full, cell);
    SanitizeMesh(&coarse.mesh, bundle_.mesh_file);
  } catch (const InputError&) {  // a mesh within a few cells: nothing to leave out
    return full;
  }
  // A mesh only a few cells across folds into a sliver of itself: trace it as it is.
  if (MeshArea(coarse.mesh) < kMinTracedArea * MeshArea(full)) {
    Progress("traced mesh: the bundle's (a grid of " + std::to_string(100 * cell) +
             " cm would keep too little of its surface)");
    return full;
  }
  cluster_ = std::move(coarse.cluster);
  res_.trace_cell_m = cell;
  res_.traced_triangles = static_cast<int>(coarse.mesh.triangles.size());
  res_.traced_vertices = static_cast<int>(coarse.mesh.positions.size());
  res_.cluster_seconds = cs.Seconds();
  char line[200];
  std::snprintf(line, sizeof line, "traced mesh: %d triangles, %d vertices (a grid of %.2f cm, %g pixel(s)) in %.2f s",
                res_.traced_triangles, res_.traced_vertices, 100 * cell, opt_.trace_pixels, res_.cluster_seconds);
  Progress(line);
  return std::move(coarse.mesh);
}

/// The valid pixels' mean (the normalization) and count; the rounds' observations are
/// set by UseViews.
void Estimator::Observe() {
  const std::vector<double> y = CollectObservations(bundle_.views);
  res_.observations = static_cast<int>(y.size() / 3);
  if (y.empty()) throw InputError(SceneFile(), "every pixel of every view is masked or invalid");
  double mean = 0;
  for (double v : y) mean += v;
  mean /= y.size();
  if (!(mean > 0) || !std::isfinite(mean)) throw InputError(SceneFile(), "the observed pixels are all black");
  res_.image_mean = mean;
  res_.objective_params = opt_.objective;
  UseViews(1);
}


/// Whether pixel `p` of an image `width` wide is on the grid of every `stride`-th pixel of
/// every `stride`-th row.
bool OnGrid(std::size_t p, int width, int stride) {
  return (p % width) % stride == 0 && (p / width) % stride == 0;
}

/// The rounds from now on fit the valid pixels on a grid of `stride` (1: all of them):
/// the observations normalized to mean 1, and the penalty at their scale. What was traced
/// on other pixels is dropped.
void Estimator::UseViews(int stride) {
  stride_ = stride;
  views_ = bundle_.views;
  if (stride > 1)
    for (View& v : views_)
      for (std::size_t p = 0; p < v.valid.size(); ++p)
        if (!OnGrid(p, v.camera.width, stride)) v.valid[p] = 0;
  y_ = CollectObservations(views_);
  for (double& v : y_) v /= res_.image_mean;
  // alpha is given per 19,200 observed pixels (one 160x120 view): the data term grows with
  // the number of observations, and so must the penalty, or the balance between them
  // (how many cells light the scene) would change with resolution and view count.
  res_.objective_params.alpha = opt_.objective.alpha * static_cast<double>(y_.size() / 3) / kAlphaReferencePixels;
  A_ = TransportMatrix();
  vertices_ = ShadingVertices();
  columns_.clear();
  holdout_.clear();
  holdout_fit_.reset();
}

/// Round 1's grid of pixels: the widest that keeps kFirstRoundPixels of the valid ones
/// (a first estimate needs no more; 1 where there are fewer).
int Estimator::FirstRoundStride() const {
  int stride = 1;
  // Counted on the grid itself: a mask can leave a grid's pixels all masked.
  const auto on_grid = [&](int s) {
    int n = 0;
    for (const View& v : bundle_.views)
      for (std::size_t p = 0; p < v.valid.size(); ++p)
        n += v.valid[p] && OnGrid(p, v.camera.width, s);
    return n;
  };
  while (res_.observations / ((stride + 1.0) * (stride + 1.0)) >= kFirstRoundPixels &&
         on_grid(stride + 1) >= kFirstRoundPixels)
    ++stride;
  return stride;
}

void Estimator::RunRounds() {
  const int first = static_cast<int>(res_.rounds.size()) + 1, last = first + opt_.max_rounds - 1;
  int since = first;  // the first round on the current pixels and albedo
  for (int round = first; round <= last; ++round) {
    CheckCancel();
    const int stride = round == 1 ? FirstRoundStride() : 1;
    if (stride != stride_) {
      if (stride_ > 1) after_grid_ = round;
      UseViews(stride);
      since = round;
    }
    RoundInfo info;
    info.round = round;
    const RoundProblem rp = TraceRound(round, since, &info);
    const SolveResult sr = Solve(rp, round, &info, round == 1);
    Update(rp, sr, &info);
    if (round > first && info.image_change < opt_.change_threshold && !info.lights_moved) break;
  }
}

/// Traces A with importance from the estimate so far (uniform in round 1), averages it
/// with the rounds before under the same albedo, and makes the round's problem.
RoundProblem Estimator::TraceRound(int round, int first, RoundInfo* info) {
  Stopwatch ts;
  CellSampler sampler(env_, round == 1 ? std::vector<double>() : lambda_, reachable_, opt_.tracer.nee_floor);
  TracerOptions topt = opt_.tracer;
  topt.seed = opt_.tracer.seed * 1000003ull + round;
  topt.cancelled = opt_.cancelled;  // a cancelled trace stops within 64 pixels
  topt.spp = MapSamples(round);
  info->spp = topt.spp;
  info->pixels = static_cast<int>(y_.size() / 3);
  TransportMatrix Ar = TraceTransport(*scene_, env_, views_, sampler, topt, &res_.trace);
  CheckCancel();
  const double trace_a = ts.Seconds();
  A_ = (opt_.combine_rounds && round > first) ? Combine(A_, Ar) : std::move(Ar);
  MakeMapProblem();
  const double normal = ts.Seconds();
  // Point lights: round 1 searches for them; later rounds trace their columns (and the
  // directional lights') only if any were found (the far-light scenes pay for the search alone).
  const bool sun = SunRound(round) && BrightestNeighbourhood().second >= opt_.directional_min_share;
  if ((NearLights() && round == 1) || sun || !points_.empty() || !suns_.empty())
    GatherVertices(round, first);
  RoundProblem rp = WithLights(points_);
  Progress(Fmt("round %.0f: A traced at %.0f samples per pixel in %.2f s", round, topt.spp, trace_a) +
           Fmt(", combined and its normal matrices in %.2f s, the lights' vertices and columns in %.2f s",
               normal - trace_a, ts.Seconds() - normal));
  info->trace_seconds = ts.Seconds();
  info->nonzeros = static_cast<std::int64_t>(rp.problem->col.size());
  const LinearProblem& problem = *rp.problem;
  info->unknown_cells = static_cast<int>(  // the map's (the lights' columns are unknowns too)
      std::count_if(problem.cell_of.begin(), problem.cell_of.end(), [&](int j) { return j < cells_; }));
  // Cells no sampled path reached are not unknowns, and are not sampled again.
  std::fill(reachable_.begin(), reachable_.end(), 0);
  for (int j : problem.cell_of)
    if (j < cells_) reachable_[j] = 1;
  Progress(Fmt("round %.0f: traced in %.2f s, %.0f unknown cells of ", round, info->trace_seconds,
               info->unknown_cells) +
           std::to_string(cells_) + ", " + std::to_string(A_.nonzeros()) + " non-zeros");
  if (info->unknown_cells == 0)
    throw InputError(SceneFile(), "no sampled path reaches the environment (camera inside closed geometry?)");
  return rp;
}

/// The share of the estimate's rendered light (over the fitted pixels) that is the map's.
double Estimator::MapShare() {
  if (points_.empty() && suns_.empty()) return 1;
  double map = 0, lights = 0;
  for (double v : A_.Multiply(lambda_)) map += v;
  for (double v : LightsRender(points_, suns_)) lights += v;
  return map + lights > 0 ? map / (map + lights) : 1.0;
}

/// The map's samples per pixel in `round`: tracer.spp in round 1 (nothing known yet), then
/// in proportion to the share of the light the map renders (its noise reaches the fit in
/// that proportion: a map that renders half the light or more gets them all), at least a
/// quarter of them (a map left dark can still take light back).
int Estimator::MapSamples(int round) const {
  const int spp = opt_.tracer.spp;
  if (round == 1) return spp;
  const double share = std::clamp(2 * map_share_, 0.25, 1.0);
  return std::max(1, static_cast<int>(std::lround(share * spp)));
}

/// A_'s problem and its normal matrices, built once per round: the round's solves append
/// the lights' columns to it (WithColumns), so G is summed again only for those.
void Estimator::MakeMapProblem() {
  map_problem_ = std::make_shared<LinearProblem>(MakeLinearProblem(A_, y_));
  map_problem_->base_normal = MakeNormalMatrices(*map_problem_);
  holdout_fit_.reset();
  holdout_held_ = TransportMatrix();
}

/// The shading vertices the lights' columns come from: this round's paths and (like A) the
/// rounds' before it under the same albedo.
void Estimator::GatherVertices(int round, int first) {
  TracerOptions topt = opt_.tracer;
  topt.cancelled = opt_.cancelled;
  // Round 1 on a grid of the pixels is a first estimate: half the paths. The round after
  // it, the first on every pixel, has no earlier round's vertices to average with: twice
  // the paths (what rounds 1 and 2 hold on every pixel; with 8, the Cycles bundle's lamp
  // came back 11 % dimmer: noise in a column biases its intensity low).
  const int spp = opt_.point_lights.spp;
  topt.spp = stride_ > 1 ? std::max(1, spp / 2) : round == after_grid_ ? 2 * spp : spp;
  topt.seed = opt_.tracer.seed * 1000003ull + 500 + round;
  ShadingVertices fresh = GatherShadingVertices(*scene_, views_, topt);
  CheckCancel();
  columns_.clear();
  if (opt_.combine_rounds && round > first) {
    vertices_ = Combine(vertices_, vertex_samples_, fresh, topt.spp);
    vertex_samples_ += topt.spp;
  } else {
    vertices_ = std::move(fresh);
    vertex_samples_ = topt.spp;
  }
  if (holdout_.empty()) {  // a fixed pseudo-random share of 8 x 8 pixel blocks (hash of view and block)
    holdout_.resize(vertices_.rows());
    const std::uint64_t share = static_cast<std::uint64_t>(opt_.point_lights.holdout * 1000);
    for (std::size_t r = 0; r < holdout_.size(); ++r) {
      const int width = views_[A_.row_view[r]].camera.width;
      const std::uint64_t block = (A_.row_pixel[r] / width / 8) * 100003ull + (A_.row_pixel[r] % width) / 8;
      std::uint64_t h = (static_cast<std::uint64_t>(A_.row_view[r]) << 40) ^ block;
      h = (h ^ (h >> 33)) * 0xff51afd7ed558ccdull;
      h ^= h >> 33;
      holdout_[r] = h % 1000 < share;
    }
  }
}

/// The round's problem with `lights` and the directional lights so far as columns after the
/// map's (the map's problem itself when there are none), warm-started from the estimate so far.
RoundProblem Estimator::WithLights(const std::vector<PointLight>& lights) {
  RoundProblem rp;
  rp.lights = AsLights(lights);
  for (const DirectionalLight& d : suns_) rp.lights.push_back(d);
  std::vector<std::vector<float>> columns;
  for (const Light& l : rp.lights) columns.push_back(Column(l));
  rp.problem = columns.empty() ? map_problem_
                               : std::make_shared<LinearProblem>(WithColumns(*map_problem_, cells_, columns));
  const LinearProblem& problem = *rp.problem;
  rp.init.resize(3 * problem.unknown_cells);
  for (int k = 0; k < problem.unknown_cells; ++k) {
    const int j = problem.cell_of[k];
    for (int c = 0; c < 3; ++c) rp.init[3 * k + c] = j < cells_ ? lambda_[3 * j + c] : Scale(rp.lights[j - cells_])[c];
  }
  return rp;
}

/// The intensity (per channel, >= 0) whose multiple of `col` best fits `target` in least
/// squares weighted by `weight`; false when a channel has no weighted column at all (that
/// channel is then 0).
bool WeightedIntensity(const std::vector<float>& col, const std::vector<double>& target,
                       const std::vector<double>& weight, Eigen::Vector3d* intensity) {
  Eigen::Vector3d num = Eigen::Vector3d::Zero(), den = Eigen::Vector3d::Zero();
  for (std::size_t e = 0; e < col.size(); ++e) {
    num[e % 3] += weight[e] * col[e] * target[e];
    den[e % 3] += weight[e] * double(col[e]) * col[e];
  }
  for (int c = 0; c < 3; ++c) (*intensity)[c] = den[c] > 0 ? std::max(0.0, num[c] / den[c]) : 0.0;
  return den.minCoeff() > 0;
}

/// Round 1's search for lamps, the map left dark so that a lamp gets its light before the
/// map can spread it over many cells: greedily, the candidate position around the scene
/// (columns from fewer paths) whose column best explains what the lights so far leave
/// (its intensity by least squares, scored by the Cauchy loss), then all the lights so far
/// refined together; until max_lights, or until the next light does not lower the loss.
/// The candidates' columns come from one path per pixel; the trials are refined on the
/// round's vertices (refining a second lamp's trials on the candidates' placed the
/// near-light scene's lamp 1.4 cm off instead of 1.1).
std::vector<PointLight> Estimator::Candidates(RoundInfo* info) {
  Stopwatch cs;
  TracerOptions topt = opt_.tracer;
  topt.cancelled = opt_.cancelled;
  topt.spp = opt_.point_lights.candidate_spp;
  topt.seed = opt_.tracer.seed * 1000003ull + 400;
  const ShadingVertices coarse = GatherShadingVertices(*scene_, views_, topt);
  const std::vector<Eigen::Vector3d> positions = CandidatePositions(centre_, radius_, bundle_.up);
  std::vector<std::vector<float>> columns(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    CheckCancel();
    PointLightColumn(*scene_, coarse, positions[i], &columns[i]);
  }
  Progress(Fmt("search: %.0f candidate positions' columns at %.0f path(s) per pixel in %.2f s",
               static_cast<double>(positions.size()), topt.spp, cs.Seconds()));
  const CauchyLoss cauchy{res_.objective_params.sigma};
  const auto loss = [&](const std::vector<double>& r) { return cauchy.Sum(r); };
  std::fill(lambda_.begin(), lambda_.end(), 1e-3);
  std::vector<PointLight> lights;
  std::vector<double> residual = y_;
  double best_loss = loss(residual);
  while (static_cast<int>(lights.size()) < opt_.point_lights.max_lights) {
    int best = -1;
    double best_score = best_loss;
    Eigen::Vector3d best_I = Eigen::Vector3d::Zero();
    // The intensity by least squares weighted as the Cauchy loss weighs what is left: a
    // hot spot or a highlight (an outlier of the residual) does not set it.
    std::vector<double> weight(residual.size());
    for (std::size_t e = 0; e < residual.size(); ++e) weight[e] = cauchy.Weight(residual[e]);
    for (std::size_t i = 0; i < positions.size(); ++i) {
      const std::vector<float>& col = columns[i];
      Eigen::Vector3d I;
      if (!WeightedIntensity(col, residual, weight, &I)) continue;
      double e = 0;
      for (std::size_t k = 0; k < col.size(); ++k) e += cauchy.Value(residual[k] - I[k % 3] * col[k]);
      if (e < best_score) best_score = e, best = static_cast<int>(i), best_I = I;
    }
    if (best < 0) break;
    std::vector<PointLight> trial = lights;
    trial.push_back({positions[best], best_I, 0});
    RefinePositions(&trial, info, "search", false);
    // What the lights leave, and whether the new one earned its place.
    std::vector<double> r = y_;
    std::vector<float> col;
    for (const PointLight& l : trial) {
      col = Column(l);
      for (std::size_t e = 0; e < r.size(); ++e) r[e] -= l.intensity[e % 3] * col[e];
    }
    const double trial_loss = loss(r);
    if (!(trial_loss < (1 - opt_.point_lights.min_gain) * best_loss)) break;
    // A light that renders too little of the light seen would be dropped right after the
    // search (FitPointLights): the search ends there instead of refining it with the rest
    // and trying more (the far-light scenes' and the lamps' spurious second lights).
    const double share = RenderedShare(trial.back());
    if (share < opt_.point_lights.min_share) {
      const Eigen::Vector3d q = trial.back().position;
      char line[240];
      std::snprintf(line, sizeof line,
                    "search: a light at (%.3f, %.3f, %.3f) renders %.3g of the light seen: not kept, the search ends",
                    q.x(), q.y(), q.z(), share);
      res_.point_light_choices.push_back(line);
      Progress(line);
      trial.pop_back();  // the others as refined beside it
      lights = std::move(trial);
      break;
    }
    lights = std::move(trial);
    residual = std::move(r);
    best_loss = trial_loss;
  }
  return lights;
}

/// Solves the round's problem warm-started, logging every iteration. Graduated Cauchy
/// scale: from the cold start (round 1, a dark map) every residual is about the mean
/// pixel; with a small sigma that is the loss's flat tail, where the activation penalty
/// outweighs the data and the all-zero map is a local minimum (sigma = 0.1 lit nothing
/// on the demo). Round 1 solves at kGraduatedSigmaStart first and halves the scale down
/// to sigma, each solve warm-started from the last.
/// The activation penalty's per-unknown weights: a cell's solid angle over the reference
/// one, a point light's PointLightOptions::weight.
ObjectiveParams Estimator::CellWeights(const LinearProblem& problem, ObjectiveParams params) const {
  params.cell_weight.resize(problem.unknown_cells);
  for (int k = 0; k < problem.unknown_cells; ++k) {
    const int j = problem.cell_of[k];
    params.cell_weight[k] =
        j < cells_ ? env_.solid_angle(j) / kAlphaReferenceSolidAngle : opt_.point_lights.weight;
  }
  return params;
}

/// A convergence row's scores against truth.json (and how many point lights it has).
void Estimator::Score(ConvergenceRow* row, const std::vector<double>& env_lambda,
                      const std::vector<PointLight>& points, const std::vector<DirectionalLight>& suns) const {
  row->point_lights = static_cast<int>(points.size());
  if (truth_.empty()) return;
  row->angular_error_deg = DominantAngularErrorDeg(env_, env_lambda, points, centre_, truth_, suns);
  row->position_error_m = WorstPositionError(points, truth_, centre_, opt_.point_lights.far * radius_);
}

SolveResult Estimator::Solve(const RoundProblem& rp, int round, RoundInfo* info, bool graduated) {
  const LinearProblem& problem = *rp.problem;
  ObjectiveParams params = CellWeights(problem, res_.objective_params);
  std::vector<double> sigmas;  // at most 7 steps: a tiny sigma jumps from 1/64 of the start
  if (graduated)
    for (double s = kGraduatedSigmaStart; s > std::max(params.sigma * 1.5, kGraduatedSigmaStart / 64); s *= 0.5)
      sigmas.push_back(s);
  sigmas.push_back(params.sigma);

  // Iterations count on within a round (its solves and its lights' refinement).
  int iteration_offset =
      !res_.convergence.empty() && res_.convergence.back().round == round ? res_.convergence.back().iteration + 1 : 0;
  double step_sigma = params.sigma;
  SolverOptions so = opt_.solver_options;
  so.on_iteration = [&](const IterationInfo& it) {
    ConvergenceRow row;
    row.wall_seconds = Now();
    row.round = round;
    row.iteration = iteration_offset + it.iteration;
    row.sigma = step_sigma;
    row.albedo_pass = res_.albedo_passes;  // the albedo the rounds run under
    row.objective = it.objective;
    row.relative_rmse = it.Rmse();
    row.photometric_rmse = row.relative_rmse * res_.image_mean;
    const std::vector<double> full = rp.Scatter(*it.lambda, cells_);
    Score(&row, full, rp.Lit<PointLight>(full, cells_), suns_);  // (the map's part is the first 3 * cells_)
    res_.convergence.push_back(row);
    if (opt_.on_convergence) opt_.on_convergence(row);
    if (opt_.solver_options.on_iteration) opt_.solver_options.on_iteration(it);
    CheckCancel();
  };
  Stopwatch ss;
  SolveResult sr;
  std::vector<double> start = rp.init;
  for (double sigma : sigmas) {
    ObjectiveParams step = params;
    step.sigma = step_sigma = sigma;
    Objective objective(problem, step);
    const bool increased = sr.objective_increased;
    sr = lp::Solve(opt_.solver, objective, start, so);
    sr.objective_increased = sr.objective_increased || increased;
    iteration_offset += sr.iterations + 1;
    info->solver_iterations += sr.iterations;
    start = sr.lambda;
  }
  info->solve_seconds = ss.Seconds();
  return sr;
}

/// Takes the round's solution as the estimate: how much it changed (in the map and in the
/// images), the round's record and its progress line.
void Estimator::Update(const RoundProblem& rp, const SolveResult& sr, RoundInfo* info) {
  info->objective = sr.objective;
  info->kkt_violation = sr.kkt_violation;
  res_.objective_increased = res_.objective_increased || sr.objective_increased;
  std::vector<double> next = rp.Scatter(sr.lambda, cells_);
  double diff = 0, norm = 0;
  for (int i = 0; i < 3 * cells_; ++i) {
    diff += (next[i] - lambda_[i]) * (next[i] - lambda_[i]);
    norm += next[i] * next[i];
  }
  info->change = norm > 0 ? std::sqrt(diff / norm) : 0.0;
  const std::vector<double> full = next;
  next.resize(3 * cells_);
  // The change that matters is in the images: neighbouring cells have nearly the same
  // columns, so noise moves energy between them without changing what is rendered.
  std::vector<double> delta(sr.lambda.size()), a_delta, a_new;
  for (std::size_t i = 0; i < delta.size(); ++i) delta[i] = sr.lambda[i] - rp.init[i];
  rp.problem->Multiply(delta, &a_delta);
  rp.problem->Multiply(sr.lambda, &a_new);
  double dn = 0, nn = 0;
  for (std::size_t i = 0; i < a_new.size(); ++i) {
    dn += a_delta[i] * a_delta[i];
    nn += a_new[i] * a_new[i];
  }
  info->image_change = nn > 0 ? std::sqrt(dn / nn) : 0.0;
  double rendered = 0;  // observations are normalized to mean 1
  for (double v : a_new) rendered += v;
  res_.rendered_fraction = a_new.empty() ? 0.0 : rendered / a_new.size();

  lambda_.swap(next);
  if (rp.Has<DirectionalLight>()) suns_ = rp.Lit<DirectionalLight>(full, cells_);
  if (NearLights() && (info->round == 1 || !points_.empty())) info->lights_moved = FitPointLights(rp, full, info);
  if (SunRound(info->round) && FitDirectionalLight(info)) info->lights_moved = true;
  map_share_ = MapShare();
  info->lambda = lambda_;
  for (double& v : info->lambda) v *= res_.image_mean;
  info->point_lights = InImageUnits(points_);
  info->directional_lights = InImageUnits(suns_);
  info->end_seconds = Now();
  res_.kkt_violation = sr.kkt_violation;
  res_.rounds.push_back(*info);
  if (opt_.on_round) opt_.on_round(*info, env_);
  Progress("round " + std::to_string(info->round) + ": " + ToString(opt_.solver) + " solver, " +
           Fmt("%.0f iterations in %.2f s, objective %.6g, change %.3g", sr.iterations, info->solve_seconds,
               sr.objective, info->change) +
           Fmt(" (in the image %.3g)", info->image_change) + Fmt(", KKT violation %.2g", sr.kkt_violation));
}

/// After a round's solve: the lights it lit (in round 1: those the search finds), their
/// positions refined, far ones, twins and weak ones folded away, and in round 1 each kept
/// only if the held-out pixels want it. True when the lights
/// moved or changed (the rounds then go on).
bool Estimator::FitPointLights(const RoundProblem& rp, const std::vector<double>& full, RoundInfo* info) {
  const bool candidates = info->round == 1;
  const std::vector<double> map = lambda_;
  std::vector<PointLight> kept = candidates ? Candidates(info) : rp.Lit<PointLight>(full, cells_);
  if (candidates && kept.empty()) lambda_ = map;  // no lamp: the round's map stands
  // Block coordinate descent: the positions (the map held), then the intensities and the
  // map together on the moved lights' columns, until the lights stay.
  // The search refined its lights with the map dark, which leaves them the map's light to
  // explain too: the map is solved beside them before their positions are refined again,
  // stepping the Cauchy scale down from the dark start as round 1's first solve does
  // (graduated; see Solve).
  if (candidates && !kept.empty()) SolveWithLights(&kept, info, true);
  for (int pass = 0; pass < (candidates ? 4 : 1) && !kept.empty(); ++pass) {
    const std::vector<PointLight> start = kept;
    RefinePositions(&kept, info, "lights", !candidates);
    FoldLights(&kept, info->round);
    SolveWithLights(&kept, info, false);
    // A light that renders too little of the light seen cannot be kept (SelectModel): drop
    // it now rather than refine it (the far-light scenes' lights end here).
    const std::size_t before = kept.size();
    for (std::size_t k = 0; k < kept.size();) {
      const double share = RenderedShare(kept[k]);
      if (share >= opt_.point_lights.min_share) {
        ++k;
        continue;
      }
      const Eigen::Vector3d q = kept[k].position;
      char line[240];
      std::snprintf(line, sizeof line, "point light at (%.3f, %.3f, %.3f): renders %.3g of the light seen: dropped",
                    q.x(), q.y(), q.z(), share);
      res_.point_light_choices.push_back(line);
      Progress(line);
      kept.erase(kept.begin() + k);
    }
    if (kept.size() < before && !kept.empty()) SolveWithLights(&kept, info, false);
    // After the first pass the lights are where their hard shadows put them: their radii
    // (soft shadows) are fitted once, and the passes after refine positions with them.
    bool radii_changed = false;
    if (candidates && pass == 0 && !kept.empty() && FitRadii(&kept)) {
      SolveWithLights(&kept, info, false);
      radii_changed = true;
    }
    bool settled = kept.size() == start.size() && !radii_changed;
    for (std::size_t k = 0; k < kept.size() && settled; ++k)
      settled = (kept[k].position - start[k].position).norm() < 0.01 * (start[k].position - centre_).norm();
    if (settled) break;
  }
  if (candidates && kept.empty()) lambda_ = map;  // every light dropped: round 1's map stands
  if (candidates && !kept.empty()) {
    const std::size_t found = kept.size();
    SelectModel(&kept);
    if (kept.empty()) lambda_ = map;  // no lamp after all: round 1's map stands, as without the search
    else if (kept.size() < found) SolveWithLights(&kept, info, false);  // the map takes the dropped lights' light
  }
  bool moved = kept.size() != points_.size();
  for (std::size_t k = 0; k < kept.size() && !moved; ++k)
    moved = (kept[k].position - points_[k].position).norm() > 0.02 * (kept[k].position - centre_).norm();
  points_ = std::move(kept);
  return moved;
}

/// Each light's radius (soft shadows), the map and the other lights held: the radius of a
/// small grid (0 and 0.8 % to 12.8 % of the scene's radius, doubling) whose column, with its
/// intensity fitted by reweighted least squares, gives the lowest Cauchy loss; a radius is
/// taken only if it lowers the loss by 0.5 % (else the light stays a point). True when a
/// radius changed.
bool Estimator::FitRadii(std::vector<PointLight>* lights) {
  CheckCancel();
  bool changed = false;
  const CauchyLoss cauchy{res_.objective_params.sigma};
  const std::vector<double> map = Plus(A_.Multiply(lambda_), LightsRender({}, suns_));
  for (std::size_t k = 0; k < lights->size(); ++k) {
    std::vector<double> base = map;
    std::vector<float> col;
    for (std::size_t j = 0; j < lights->size(); ++j) {
      if (j == k) continue;
      col = Column((*lights)[j]);
      for (std::size_t i = 0; i < base.size(); ++i) base[i] += (*lights)[j].intensity[i % 3] * col[i];
    }
    PointLight& light = (*lights)[k];
    double best_loss = 0, point_loss = 0, best_radius = 0;
    Eigen::Vector3d best_intensity = light.intensity;
    for (int g = 0; g < 6; ++g) {
      const double radius = g == 0 ? 0.0 : 0.004 * radius_ * std::pow(2.0, g);
      PointLight sized = light;
      sized.radius = radius;
      col = Column(sized);
      Eigen::Vector3d intensity = light.intensity;
      std::vector<double> r(base.size()), left(base.size()), w(base.size());
      for (std::size_t i = 0; i < r.size(); ++i) left[i] = y_[i] - base[i];
      for (int it = 0; it < 4; ++it) {  // reweighted least squares for the Cauchy loss
        for (std::size_t i = 0; i < r.size(); ++i) {
          r[i] = left[i] - intensity[i % 3] * col[i];
          w[i] = cauchy.Weight(r[i]);
        }
        WeightedIntensity(col, left, w, &intensity);
      }
      for (std::size_t i = 0; i < r.size(); ++i) r[i] = y_[i] - base[i] - intensity[i % 3] * col[i];
      const double loss = cauchy.Sum(r);
      if (g == 0) point_loss = best_loss = loss;
      if (loss < best_loss) best_loss = loss, best_radius = radius, best_intensity = intensity;
      CheckCancel();
    }
    if (best_radius > 0 && best_loss > (1 - 0.005) * point_loss) best_radius = 0;
    char line[240];
    std::snprintf(line, sizeof line,
                  "point light at (%.3f, %.3f, %.3f): radius %.3g m (Cauchy loss %.6g; as a point %.6g)",
                  light.position.x(), light.position.y(), light.position.z(), best_radius,
                  best_radius > 0 ? best_loss : point_loss, point_loss);
    res_.point_light_choices.push_back(line);
    Progress(line);
    if (best_radius != light.radius) {
      changed = true;
      light.radius = best_radius;
      if (best_radius > 0) light.intensity = best_intensity;
    }
  }
  return changed;
}

/// Far lights are the map's (dropped: the next solve gives their light to the map); two
/// lights closer than a tenth of their distance from the centre are one.
void Estimator::FoldLights(std::vector<PointLight>* lights, int round) {
  std::vector<PointLight> kept;
  for (const PointLight& l : *lights) {
    const double d = (l.position - centre_).norm();
    if (!(d < opt_.point_lights.far * radius_) || !(l.intensity.maxCoeff() > 0)) {
      if (l.intensity.maxCoeff() > 0)
        res_.point_light_choices.push_back(Fmt("round %.0f: a light refined to %.3g m from the centre is a far light; "
                                               "left to the map",
                                               round, d));
      continue;
    }
    bool merged = false;
    for (PointLight& k : kept) merged = merged || FoldInto(&k, l, d);
    if (!merged) kept.push_back(l);
  }
  lights->swap(kept);
}

/// The map's cells and the lights' intensities solved together at the lights' positions
/// (warm-started; rows logged), lambda_ and `lights` updated; lights left dark are dropped.
void Estimator::SolveWithLights(std::vector<PointLight>* lights, RoundInfo* info, bool graduated) {
  CheckCancel();
  const RoundProblem rp = WithLights(*lights);  // the directional lights held in the solve with the rest
  const SolveResult sr = Solve(rp, info->round, info, graduated);
  std::vector<double> full = rp.Scatter(sr.lambda, cells_);
  *lights = rp.Lit<PointLight>(full, cells_);
  suns_ = rp.Lit<DirectionalLight>(full, cells_);
  full.resize(3 * cells_);
  for (int j = 0; j < cells_; ++j)  // cells this problem did not reach keep their value
    if (reachable_[j]) std::copy(&full[3 * j], &full[3 * j] + 3, &lambda_[3 * j]);
}

/// Levenberg-Marquardt on the lights' positions and intensities, the map's render (and the
/// directional lights') held fixed, on this round's shading vertices, then (`shadows`) a
/// compass search of each position, which sees what the derivative does not: the shadows'
/// edges moving with the light. Every accepted step is a convergence row.
void Estimator::RefinePositions(std::vector<PointLight>* lights, RoundInfo* info, const char* step, bool shadows) {
  if (lights->empty()) return;
  // The logged objective is the whole one: the map's penalty (held fixed here) added.
  double map_penalty = 0;
  for (int j = 0; j < cells_; ++j)
    if (reachable_[j])
      map_penalty += res_.objective_params.alpha * env_.solid_angle(j) / kAlphaReferenceSolidAngle *
                     std::log1p(res_.objective_params.beta *
                                std::max(0.0, lambda_[3 * j] + lambda_[3 * j + 1] + lambda_[3 * j + 2]));
  std::vector<double> base = Plus(A_.Multiply(lambda_), LightsRender({}, suns_));
  const LightFitProblem fit = FitProblem(&base);
  // One convergence row; on a share of the rows (every stride-th) E and the squared
  // residuals times the stride estimate the whole problem's.
  const auto logger = [&](int stride) {
    return [&, stride](int, double E, double sse, const std::vector<Light>& now) {
      ConvergenceRow row = LightRow(*info, fit.loss.sigma, E * stride + map_penalty, sse * stride);
      row.step = step;
      Score(&row, lambda_, OfKind<PointLight>(now), suns_);
      Push(row);
    };
  };
  std::vector<Light> moving = AsLights(*lights);
  if (!shadows) {  // round 1: the lights found by the sparse solve, on all rows
    info->light_iterations = RefineLights(fit, &moving, 12, logger(1));
    *lights = OfKind<PointLight>(moving);
    return;
  }
  // Rounds 2 on, the lights near their places: Levenberg-Marquardt (4 iterations: past them
  // it only tried steps that failed, docs/benchmarks.md, session 20), then the compass search
  // (steps of 1 % of the light's distance, then 0.5 %, at most 12 columns a light: 24 cost
  // the Cycles cornerbox ~1.1 s for the same lamp, docs/benchmarks.md, session 21) that sees
  // the shadows' edges move. Both look at 4,800 of the rows (every n-th): each column on all
  // of a 160 x 120 view's 19,200 rows, with a lamp's 4 shadow rays a vertex, costs ~0.25 s
  // (lamp-0.5m's LM and search on all rows made it 1.6x the map alone's time; the search on
  // all of the demo's rows cost 11 s, docs/method.md, "Refinement"). What they find is kept
  // only if the whole objective, over all rows, falls too.
  const auto value = [&](const std::vector<PointLight>& now, double* sse = nullptr) {
    std::vector<std::vector<float>> columns;  // from the cache: the round's solve made the start's
    for (const PointLight& l : now) columns.push_back(Column(l));
    return fit.Value(AsLights(now), columns, sse);
  };
  const std::vector<PointLight> start = *lights;
  const double start_value = value(start);
  const LightFitSubset share(fit, kShadowRows);
  const auto log = logger(share.stride);
  const int iterations = RefineLights(share.problem, &moving, 4, log);
  const std::vector<PointLight> refined = OfKind<PointLight>(moving);
  const auto cancel = [&](int, double, double, const std::vector<Light>&) { CheckCancel(); };
  CompassOptions compass;
  compass.start = 0.01;
  compass.stop = 0.004;
  compass.max_evaluations = 12;
  const int moves = SearchLights(share.problem, &moving, centre_, compass, cancel);
  *lights = OfKind<PointLight>(moving);
  double sse = 0, ended = value(*lights, &sse);
  if (!(ended < start_value) && moves > 0) {  // the search's places fail on all rows: LM's?
    *lights = refined;
    ended = value(*lights, &sse);
  }
  if (!(ended < start_value)) {
    *lights = start;
    info->light_iterations = 0;
    return;
  }
  info->light_iterations = iterations + (moves > 0 ? 1 : 0);
  logger(1)(0, ended, sse, AsLights(*lights));  // one row: the whole objective where they ended
}

/// Model selection on the held-out pixels: each light (weakest first) stays only if the
/// map and the other lights, fitted without the held-out pixels, predict them worse
/// without it.
void Estimator::SelectModel(std::vector<PointLight>* lights) {
  Stopwatch ms;
  std::sort(lights->begin(), lights->end(), [&](const PointLight& a, const PointLight& b) {
    return a.intensity.sum() / (a.position - centre_).squaredNorm() <
           b.intensity.sum() / (b.position - centre_).squaredNorm();
  });
  for (std::size_t k = 0; k < lights->size();) {
    CheckCancel();
    std::vector<PointLight> without = *lights;
    without.erase(without.begin() + k);
    // The same light as a directional one from its direction (its irradiance the one that
    // renders the point light's image best, by least squares): does its distance matter,
    // or is it a far light (the map's, or a sun's)?
    const Eigen::Vector3d q = (*lights)[k].position, to = q - centre_;
    DirectionalLight far;
    far.direction = to.normalized();
    {
      const std::vector<float> point = Column(PointLight{q, {}, 0}), directional = Column(far);
      Eigen::Vector3d num = Eigen::Vector3d::Zero(), den = Eigen::Vector3d::Zero();
      for (std::size_t e = 0; e < point.size(); ++e) {
        num[e % 3] += double(directional[e]) * point[e] * (*lights)[k].intensity[e % 3];
        den[e % 3] += double(directional[e]) * directional[e];
      }
      for (int c = 0; c < 3; ++c) far.irradiance[c] = den[c] > 0 ? num[c] / den[c] : 0.0;
    }
    const double with_loss = HoldoutLoss(*lights), without_loss = HoldoutLoss(without),
                 far_loss = HoldoutLoss(without, &far);
    const double share = RenderedShare((*lights)[k]);
    const double bar = (1 - opt_.point_lights.min_gain) * std::min(without_loss, far_loss);
    const bool keep = with_loss < bar && share >= opt_.point_lights.min_share;
    char line[400];
    std::snprintf(line, sizeof line,
                  "point light at (%.3f, %.3f, %.3f): renders %.3g of the light seen; held-out loss %.6g with it, "
                  "%.6g without, %.6g with it far away: %s",
                  q.x(), q.y(), q.z(), share, with_loss, without_loss, far_loss, keep ? "kept" : "dropped");
    res_.point_light_choices.push_back(line);
    Progress(line);
    if (keep) ++k;
    else lights->erase(lights->begin() + k);
  }
  std::reverse(lights->begin(), lights->end());  // strongest first
  Progress(Fmt("model selection in %.2f s", ms.Seconds()));
}

/// The render of point and directional lights on vertices_ (3 per row).
std::vector<double> Estimator::LightsRender(const std::vector<PointLight>& points,
                                            const std::vector<DirectionalLight>& suns) {
  std::vector<double> out(y_.size(), 0.0);
  std::vector<float> col;
  for (const PointLight& l : points) {
    col = Column(l);
    for (std::size_t e = 0; e < out.size(); ++e) out[e] += l.intensity[e % 3] * col[e];
  }
  for (const DirectionalLight& d : suns) {
    col = Column(d);
    for (std::size_t e = 0; e < out.size(); ++e) out[e] += d.irradiance[e % 3] * col[e];
  }
  return out;
}

std::pair<std::vector<int>, double> Estimator::BrightestNeighbourhood() const {
  int peak = -1;
  double total = 0, best = 0;
  std::vector<double> power(cells_, 0.0);
  for (int j = 0; j < cells_; ++j) {
    power[j] = std::max(0.0, Luminance(lambda_[3 * j], lambda_[3 * j + 1], lambda_[3 * j + 2])) * env_.solid_angle(j);
    total += power[j];
    if (power[j] > best) best = power[j], peak = j;
  }
  if (peak < 0 || !(total > 0)) return {};
  const double reach = std::cos(2.5 * kPi / env_.rings());
  std::vector<int> cells;
  double near = 0;
  for (int j = 0; j < cells_; ++j)
    if (env_.direction(j).dot(env_.direction(peak)) > reach) cells.push_back(j), near += power[j];
  return {cells, near / total};
}

/// A directional light where the map concentrates its power (docs/method.md, "Directional
/// lights"): proposed from the brightest cell's neighbourhood, its shape fitted with the rest
/// held, settled against the map solved beside it, and kept only if the held-out pixels
/// want it, as a lamp is. True when one was added.
bool Estimator::FitDirectionalLight(RoundInfo* info) {
  CheckCancel();
  if (vertices_.size() == 0) return false;  // no near-light model: no vertices to light
  DirectionalProposal proposal;
  if (!ProposeDirectionalLight(&proposal)) return false;
  SunFit fit(*this, info);
  if (!ShapeDirectionalLight(&proposal, &fit)) return false;
  const std::vector<double> map = lambda_;
  const std::vector<PointLight> lamps = points_;
  const double without_loss = HoldoutLoss(points_);
  SettleDirectionalLight(&proposal, &fit, info);
  if (SelectDirectionalLight(proposal, without_loss)) return true;
  lambda_ = map;
  points_ = lamps;
  suns_.clear();
  return false;
}

/// The brightest cell's neighbourhood (cells within 2.5 ring spacings) holding at least
/// directional_min_share of the map's power and rendering at least min_share of the light
/// seen, as one light from its direction (the map's spread's centre) with its irradiance;
/// false when there is none.
bool Estimator::ProposeDirectionalLight(DirectionalProposal* out) {
  const auto [cells, map_share] = BrightestNeighbourhood();
  if (cells.empty() || map_share < opt_.directional_min_share) return false;
  DirectionalLight sun;
  Eigen::Vector3d dir = Eigen::Vector3d::Zero();
  for (int j : cells) {
    const double power =
        std::max(0.0, Luminance(lambda_[3 * j], lambda_[3 * j + 1], lambda_[3 * j + 2])) * env_.solid_angle(j);
    dir += power * env_.direction(j);
    for (int c = 0; c < 3; ++c) sun.irradiance[c] += std::max(0.0, lambda_[3 * j + c]) * env_.solid_angle(j);
  }
  if (!(dir.norm() > 0)) return false;
  // From the centre of the map's spread (the mean shift of DominantDirections), which a
  // far light's cells surround.
  const std::vector<Eigen::Vector3d> dominant = DominantDirections(env_, lambda_, 1);
  sun.direction = dominant.empty() ? dir.normalized() : dominant[0];
  // The map without those cells, and the lamps, held while the light is refined.
  std::vector<double> without = lambda_;
  for (int j : cells) std::fill(&without[3 * j], &without[3 * j] + 3, 0.0);
  {  // and the cells must light a good part of the scene, as a lamp must (min_share)
    std::vector<double> only(lambda_.size(), 0.0);
    for (int j : cells) std::copy(&lambda_[3 * j], &lambda_[3 * j] + 3, &only[3 * j]);
    double rendered = 0, seen = 0;
    const std::vector<double> render = A_.Multiply(only);
    for (std::size_t e = 0; e < render.size(); ++e) rendered += render[e], seen += y_[e];
    if (!(rendered >= opt_.point_lights.min_share * seen)) return false;
  }
  *out = {sun, cells, map_share, std::move(without)};
  return true;
}

/// The search across the sphere (steps of `start_deg` down to the light's finest step), the
/// light's irradiance refitted where it stands even if it does not move. Returns the moves.
int Estimator::SunFit::Search(DirectionalLight* sun, double start_deg) const {
  // The finest step (degrees): 0.05 for a sharp light; a quarter of a soft one's angular
  // radius, whose penumbrae are that much wider (and each of whose columns casts
  // kSphereShadowRays rays).
  const double finest = std::max(0.05, sun->angular_radius * 180 / kPi / 4);
  CompassOptions compass;
  compass.start = start_deg * (kPi / 180);
  compass.stop = finest * (kPi / 180);
  compass.refit_unmoved = true;
  std::vector<Light> moving{*sun};
  const int moves = SearchLights(share->problem, &moving, Eigen::Vector3d::Zero(), compass, log);
  *sun = std::get<DirectionalLight>(moving[0]);
  return moves;
}

/// The light's direction, irradiance and angular radius, the lamps and the map held without
/// the cells within kSunClear of it, on kShadowRows of the rows (the model selection looks at
/// every row): Levenberg-Marquardt, the angular radius (before the search too, or a wide
/// light's direction is sought by shadow edges it does not have), the compass search, the
/// angular radius again. False when the light is at least as wide as the widest radius
/// tried: the map's (the cells render a light that wide as well as a disc does, and its
/// direction is poorly held by its soft shadows).
bool Estimator::ShapeDirectionalLight(DirectionalProposal* proposal, SunFit* fit) {
  DirectionalLight& sun = proposal->light;
  // The cells next to the light's own still hold much of the light the map spread, and
  // held fixed that smear pulls the direction towards itself; a map left dark instead
  // makes the light explain every other light too (docs/method.md).
  constexpr double kSunClear = 35;  // degrees
  std::vector<double> cleared = lambda_;
  for (int j = 0; j < cells_; ++j)
    if (env_.direction(j).dot(sun.direction) > std::cos(kSunClear * kPi / 180))
      std::fill(&cleared[3 * j], &cleared[3 * j] + 3, 0.0);
  fit->Hold(Plus(A_.Multiply(cleared), LightsRender(points_, {})), proposal->without);
  {
    std::vector<Light> moving{sun};
    RefineLights(fit->share->problem, &moving, 12, fit->log);
    sun = std::get<DirectionalLight>(moving[0]);
  }
  const auto wide = [&] { return sun.angular_radius >= kMaxAngularRadiusDeg * kPi / 180 * 0.999; };
  if (FitAngularRadius(fit->share->problem, &sun), !wide()) {  // (a wide light is left at once)
    fit->Search(&sun, 2);
    FitAngularRadius(fit->share->problem, &sun);
  }
  if (!wide()) return true;
  char line[300];
  std::snprintf(line, sizeof line,
                "directional light from (%.4f, %.4f, %.4f): at least %.3g deg wide: a wide far light, left to "
                "the map",
                sun.direction.x(), sun.direction.y(), sun.direction.z(), kMaxAngularRadiusDeg);
  res_.point_light_choices.push_back(line);
  Progress(line);
  return false;
}

/// The light in place of its cells, the map and the lamps solved with it; then the
/// direction searched against that map and the map solved again, while the light moves:
/// each solve gives the light more of the light the map still held near its direction, and
/// held fixed that light pulls the direction towards itself (docs/method.md). Before the
/// model selection: from round 2 on the map fits the held-out pixels better than round 1's.
void Estimator::SettleDirectionalLight(DirectionalProposal* proposal, SunFit* fit, RoundInfo* info) {
  DirectionalLight& sun = proposal->light;
  lambda_ = proposal->without;
  suns_ = {sun};
  SolveWithLights(&points_, info, false);
  constexpr int kSunPasses = 6;
  for (int pass = 0; pass < kSunPasses && !suns_.empty(); ++pass) {
    sun = suns_[0];
    fit->Hold(Plus(A_.Multiply(lambda_), LightsRender(points_, {})), proposal->without);
    if (fit->Search(&sun, 1) == 0) break;
    suns_ = {sun};
    SolveWithLights(&points_, info, false);
  }
  if (!suns_.empty()) sun = suns_[0];
}

/// Model selection: the held-out loss of the map solved with the light against the map as
/// it was (`without_loss`), one line of why.
bool Estimator::SelectDirectionalLight(const DirectionalProposal& proposal, double without_loss) {
  const DirectionalLight& sun = proposal.light;
  const double with_loss = suns_.empty() ? without_loss : HoldoutLoss(points_, &sun, true);
  const bool keep = with_loss < (1 - opt_.point_lights.min_gain) * without_loss;
  char line[400];
  std::snprintf(line, sizeof line,
                "directional light from (%.4f, %.4f, %.4f), angular radius %.3g deg, in place of %zu cells holding "
                "%.3g of the map's power: held-out loss %.6g with it, %.6g with the cells: %s",
                sun.direction.x(), sun.direction.y(), sun.direction.z(), sun.angular_radius * 180 / kPi,
                proposal.cells.size(), proposal.map_share, with_loss, without_loss, keep ? "kept" : "dropped");
  res_.point_light_choices.push_back(line);
  Progress(line);
  return keep;
}

/// The cells of a uniform sky: those above the horizon some sampled path reached.
std::vector<int> Estimator::SkyCells() const {
  std::vector<int> out;
  for (int j = 0; j < cells_; ++j)
    if (reachable_[j] && env_.direction(j).dot(env_.up()) > 0) out.push_back(j);
  return out;
}

/// A light's unit column on vertices_ (UnitColumn), from the cache when the round's
/// vertices already gave it one for that shape (the last 8 shapes are kept).
std::vector<float> Estimator::Column(const Light& light) {
  for (const CachedColumn& c : columns_)
    if (SameShape(c.light, light)) return c.column;
  constexpr std::size_t kKept = 8;
  if (columns_.size() == kKept) columns_.erase(columns_.begin());
  columns_.push_back({light, {}});
  UnitColumn(*scene_, vertices_, light, &columns_.back().column);
  return columns_.back().column;
}

/// The share of the observed light a point light renders.
double Estimator::RenderedShare(const PointLight& light) {
  const std::vector<float> col = Column(light);
  double rendered = 0, seen = 0;
  for (std::size_t e = 0; e < col.size(); ++e) {
    rendered += light.intensity[e % 3] * col[e];
    seen += y_[e];
  }
  return seen > 0 ? rendered / seen : 0.0;
}

/// A directional light's unit column on the held-out rows, traced with as many paths as
/// the map's columns (tracer.spp), not taken from the shading vertices (point_lights.spp,
/// twice that in round 2): the held-out loss then compares the models, not their columns'
/// noise. A sun's light reaches a pixel mostly through paths that bounce (the walls it lights
/// light the rest), each vertex's shadow ray all or nothing: on Cycles' sun, in round 2
/// (the map's columns importance-sampled at 96 paths), its 16-path column lost to the map's
/// cells, held-out loss 47.5 against 30.7, with its direction 0.02 degrees off (8 paths:
/// 83.3; docs/benchmarks.md, session 22).
std::vector<float> Estimator::HeldOutSunColumn(const DirectionalLight& light) {
  return TracedSunColumn(light, &holdout_, opt_.tracer.spp, 900);
}

/// A directional light's unit column traced (`spp` paths a pixel, independent of the
/// shading vertices' and A's paths: `seed` offsets the tracer's), on the rows `rows` marks
/// (all when null), in their order.
std::vector<float> Estimator::TracedSunColumn(DirectionalLight light, const std::vector<std::uint8_t>* rows,
                                              int spp, std::uint64_t seed) {
  std::vector<View> traced = views_;
  if (rows)
    for (std::size_t r = 0; r < rows->size(); ++r)
      if (!(*rows)[r]) traced[A_.row_view[r]].valid[A_.row_pixel[r]] = 0;
  TracerOptions topt = opt_.tracer;
  topt.cancelled = opt_.cancelled;
  topt.spp = spp;
  topt.seed = opt_.tracer.seed * 1000003ull + seed;
  light.irradiance = Eigen::Vector3d::Ones();
  const std::vector<ImageRGB> images = RenderPointLights(*scene_, traced, {}, topt, false, nullptr, {light});
  CheckCancel();
  std::vector<float> out;
  for (std::size_t r = 0; r < A_.rows(); ++r) {
    if (rows && !(*rows)[r]) continue;
    const int width = views_[A_.row_view[r]].camera.width, p = static_cast<int>(A_.row_pixel[r]);
    const float* v = images[A_.row_view[r]].at(p % width, p / width);
    out.insert(out.end(), v, v + 3);
  }
  return out;
}

/// The sky beside a directional light (docs/method.md, "Directional lights", "The sky"):
/// after the rounds, a uniform sky above the horizon (one radiance, the sum of A's columns
/// of those cells) and the light's irradiance fitted together to what the map's cells and
/// the lamps leave, by instrumental variables: the light's column from the shading vertices
/// is noisy (16-40 paths), and least squares with it beside a smooth, clean column biases
/// the light low and moves that light into the sky (sun-and-sky's sky came back 100 times
/// too bright, its sun 10 % dim); an independently traced column of the light as the
/// instrument removes that bias. The sky's radiance is added to its cells.
void Estimator::FitSky() {
  if (suns_.size() != 1 || vertices_.size() == 0) return;
  const std::vector<int> cells = SkyCells();
  if (cells.empty()) return;
  DirectionalLight& sun = suns_[0];
  const std::vector<float> x = Column(sun);
  const std::vector<float> z = TracedSunColumn(sun, nullptr, 2 * opt_.point_lights.spp, 950);
  std::vector<double> unit(3 * cells_, 0.0);
  for (int j : cells) std::fill(&unit[3 * j], &unit[3 * j] + 3, 1.0);
  const std::vector<double> s = A_.Multiply(unit);
  // What the light and the sky render: the observations less the map's cells and the lamps.
  const std::vector<double> rest = Plus(A_.Multiply(lambda_), LightsRender(points_, {}));
  const CauchyLoss cauchy{res_.objective_params.sigma};
  Eigen::Vector3d irradiance = sun.irradiance, sky = Eigen::Vector3d::Zero();
  for (int c = 0; c < 3; ++c) {
    Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
    Eigen::Vector2d v = Eigen::Vector2d::Zero();
    for (std::size_t e = c; e < y_.size(); e += 3) {
      const double t = y_[e] - rest[e], r = t - sun.irradiance[c] * x[e];
      const double w = cauchy.Weight(r);  // at the fit
      m(0, 0) += w * z[e] * x[e], m(0, 1) += w * z[e] * s[e];
      m(1, 0) += w * s[e] * x[e], m(1, 1) += w * s[e] * s[e];
      v(0) += w * z[e] * t, v(1) += w * s[e] * t;
    }
    Eigen::Vector2d ab = m.fullPivLu().solve(v);
    if (!(ab(1) > 0) || !ab.allFinite()) ab = Eigen::Vector2d(m(0, 0) > 0 ? v(0) / m(0, 0) : irradiance[c], 0.0);
    irradiance[c] = std::max(0.0, ab(0));
    sky[c] = ab(1);
  }
  double up = 0;  // the sky's irradiance on a surface facing up
  for (int j : cells) up += env_.solid_angle(j) * env_.direction(j).dot(env_.up());
  Progress(Fmt("the sky beside the directional light: radiance %.4g %.4g %.4g", sky[0], sky[1], sky[2]) +
           Fmt(" (irradiance facing up %.4g of the light's %.4g -> %.4g)", up * Luminance(sky[0], sky[1], sky[2]),
               Luminance(sun.irradiance[0], sun.irradiance[1], sun.irradiance[2]),
               Luminance(irradiance[0], irradiance[1], irradiance[2])));
  sun.irradiance = irradiance;
  for (int j : cells)
    for (int c = 0; c < 3; ++c) lambda_[3 * j + c] += sky[c];
}

/// The Cauchy loss on the held-out rows of the map and `lights` (and a directional light)
/// fitted on the other rows.
double Estimator::HoldoutLoss(const std::vector<PointLight>& lights, const DirectionalLight* directional,
                              bool traced) {
  std::vector<Light> all = AsLights(lights);
  if (directional) all.push_back(*directional);
  std::vector<std::vector<float>> columns;
  for (const Light& l : all) columns.push_back(Column(l));
  std::vector<double> y_fit, y_held;
  for (std::size_t r = 0; r < holdout_.size(); ++r)
    for (int c = 0; c < 3; ++c) (holdout_[r] ? y_held : y_fit).push_back(y_[3 * r + c]);
  if (!holdout_fit_) {  // once per A_: the map's part of the fit, with its normal matrices
    holdout_fit_ = std::make_shared<LinearProblem>(MakeLinearProblem(SelectRows(A_, holdout_, false), y_fit));
    holdout_fit_->base_normal = MakeNormalMatrices(*holdout_fit_);
    holdout_held_ = SelectRows(A_, holdout_, true);
  }
  // The columns' fitted and held-out rows.
  std::vector<std::vector<float>> fit_columns(columns.size()), held_columns(columns.size());
  for (std::size_t k = 0; k < columns.size(); ++k)
    for (std::size_t r = 0; r < holdout_.size(); ++r)
      (holdout_[r] ? held_columns : fit_columns)[k].insert((holdout_[r] ? held_columns : fit_columns)[k].end(),
                                                           &columns[k][3 * r], &columns[k][3 * r] + 3);
  if (directional && traced) held_columns.back() = HeldOutSunColumn(*directional);
  const LinearProblem problem = WithColumns(*holdout_fit_, cells_, fit_columns);
  ObjectiveParams params = res_.objective_params;
  params.alpha *= static_cast<double>(holdout_fit_->rows()) / std::max<std::size_t>(1, holdout_.size());
  params = CellWeights(problem, params);
  std::vector<double> init(3 * problem.unknown_cells);
  for (int k = 0; k < problem.unknown_cells; ++k) {
    const int j = problem.cell_of[k];
    for (int c = 0; c < 3; ++c) init[3 * k + c] = j < cells_ ? lambda_[3 * j + c] : Scale(all[j - cells_])[c];
  }
  SolverOptions so;
  so.max_iterations = 50;
  const SolveResult sr = lp::Solve(opt_.solver, Objective(problem, params), init, so);
  std::vector<double> x(3 * (cells_ + columns.size()), 0.0);
  for (int k = 0; k < problem.unknown_cells; ++k)
    for (int c = 0; c < 3; ++c) x[3 * problem.cell_of[k] + c] = sr.lambda[3 * k + c];
  std::vector<double> residual = holdout_held_.Multiply(std::vector<double>(x.begin(), x.begin() + 3 * cells_));
  for (std::size_t i = 0; i < residual.size(); ++i) {
    for (std::size_t k = 0; k < columns.size(); ++k) residual[i] += held_columns[k][i] * x[3 * (cells_ + k) + i % 3];
    residual[i] = y_held[i] - residual[i];
  }
  return CauchyLoss{params.sigma}.Sum(residual);
}

// Albedo refinement: the reconstruction's albedo is the colour seen, flattened per
// segment of one chromaticity, so each segment's mean still holds its mean shading (and
// two surfaces of one chromaticity share one albedo). Divided by the estimate's
// irradiance, the colour seen is the albedo the estimate implies; segmented again (now
// a brightness step is a material's) it is the albedo the next rounds are solved under.
bool Estimator::AlbedoRefinable() {
  if (opt_.albedo_passes <= 0) res_.albedo_left_out = AlbedoLeftOut::kNoPasses;
  else if (bundle_.mesh.shaded.size() != bundle_.mesh.positions.size())
    res_.albedo_left_out = AlbedoLeftOut::kKnownAlbedo;
  if (res_.albedo_left_out != AlbedoLeftOut::kRefined) return false;
  mesh_ = bundle_.mesh;
  return true;
}

/// Per vertex of the bundle's mesh, the mean of `values` over the vertices of its cluster
/// whose normals are within 37 degrees of its own (a box's edge keeps its faces apart); a
/// vertex with none keeps its own value.
std::vector<float> Estimator::OverClusters(const std::vector<float>& values) const {
  if (cluster_.empty()) return values;
  const Mesh& full = bundle_.mesh;
  std::vector<int> start(scene_->mesh().positions.size() + 1, 0), members(cluster_.size());
  for (int c : cluster_)
    if (c >= 0) ++start[c + 1];
  for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (std::size_t v = 0; v < cluster_.size(); ++v)
    if (cluster_[v] >= 0) members[fill[cluster_[v]]++] = static_cast<int>(v);
  std::vector<float> out(values);
  ParallelForChunks(0, cluster_.size(), 1024, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      if (cluster_[v] < 0) continue;
      double sum = 0;
      int n = 0;
      // At most 64 members each (a mesh far finer than the pixels would make this quadratic).
      const int first = start[cluster_[v]], size = start[cluster_[v] + 1] - first, step = std::max(1, size / 64);
      for (int k = first; k < first + size; k += step)
        if (full.normals[members[k]].dot(full.normals[v]) > 0.8f) {
          sum += values[members[k]];
          ++n;
        }
      if (n > 0) out[v] = static_cast<float>(sum / n);
    }
  });
  return out;
}

/// The traced mesh under the albedo of `full` (the bundle's mesh): each cluster its
/// vertices' mean weighted by `irradiance` (what each adds to the light the cluster sends:
/// a vertex in the dark, whose de-lit albedo is least sure, adds least).
Mesh Estimator::WithAlbedoOf(const Mesh& full, const std::vector<float>& irradiance) const {
  if (cluster_.empty()) return full;
  Mesh traced = scene_->mesh();
  std::vector<Eigen::Vector3d> sum(traced.positions.size(), Eigen::Vector3d::Zero());
  std::vector<double> weight(traced.positions.size(), 0);
  for (std::size_t v = 0; v < cluster_.size(); ++v)
    if (cluster_[v] >= 0 && irradiance[v] > 0) {
      sum[cluster_[v]] += irradiance[v] * full.albedo[v].cast<double>();
      weight[cluster_[v]] += irradiance[v];
    }
  for (std::size_t i = 0; i < sum.size(); ++i)
    if (weight[i] > 0) traced.albedo[i] = (sum[i] / weight[i]).cast<float>();
  return traced;
}

/// Paths per vertex of the bundle's mesh for the albedo pass's irradiance: albedo_samples,
/// or on a clustered mesh about that many per cluster (at least 2 per vertex; OverClusters
/// averages them).
int Estimator::AlbedoPaths() const {
  if (cluster_.empty()) return opt_.albedo_samples;
  const double share = static_cast<double>(scene_->mesh().positions.size()) / bundle_.mesh.positions.size();
  return std::min(opt_.albedo_samples, std::max(2, static_cast<int>(std::lround(opt_.albedo_samples * share))));
}

bool Estimator::RefineAlbedo(int pass) {
  CheckCancel();
  Stopwatch as;
  int segments = -1;  // an estimate that lights nothing (warned in Conclude) has no irradiance
  std::vector<float> irradiance;
  if (res_.rendered_fraction >= 0.01) {
    const int paths = AlbedoPaths();
    Progress(Fmt("albedo pass %.0f: de-lighting %.0f vertices (%.0f paths each)", pass,
                 static_cast<double>(mesh_.positions.size()), paths));
    {
      // The bundle's mesh itself (a clustered mesh folds where a flat surface crosses a
      // cell's boundary, and a vertex there can sit behind its neighbours' triangles).
      std::unique_ptr<RayTracer> full;
      if (!cluster_.empty()) full = std::make_unique<RayTracer>(mesh_);
      VertexRadiance radiance(full ? *full : *scene_, env_, lambda_, opt_.tracer.bounces,
                              opt_.tracer.seed * 7919 + pass, points_, suns_);
      for (int done = 0; done < paths; done += 2) {  // Cancel is polled between steps
        radiance.Refine(std::min(2, paths - done));
        CheckCancel();
      }
      irradiance = OverClusters(radiance.Irradiance());
    }  // before the scene it refers to is replaced
    segments = DelightAlbedo(&mesh_, irradiance);
  }
  res_.albedo_seconds += as.Seconds();
  if (segments < 0) {
    if (res_.albedo_passes == 0) res_.albedo_left_out = AlbedoLeftOut::kNothingLit;
    Progress("albedo pass " + std::to_string(pass) + ": " + ToString(AlbedoLeftOut::kNothingLit) + "; albedo kept");
    return false;
  }
  res_.albedo_segments = segments;
  scene_ = std::make_unique<RayTracer>(WithAlbedoOf(mesh_, irradiance));
  columns_.clear();  // they saw the old albedo
  res_.albedo_passes = pass;
  Progress(Fmt("albedo pass %.0f: de-lit %.0f vertices into %.0f segments in %.2f s", pass,
               static_cast<double>(mesh_.positions.size()), segments, as.Seconds()));
  return true;
}

void Estimator::Conclude() {
  if (res_.albedo_passes > 0) res_.albedo = mesh_.albedo;
  res_.left_out.assign(cells_, 0);
  for (int j = 0; j < cells_; ++j) res_.left_out[j] = !reachable_[j];
  res_.lambda = lambda_;
  for (double& v : res_.lambda) v *= res_.image_mean;
  res_.final_relative_rmse = res_.convergence.empty() ? 0 : res_.convergence.back().relative_rmse;
  res_.final_rmse = res_.final_relative_rmse * res_.image_mean;
  res_.point_lights = InImageUnits(points_);
  res_.directional_lights = InImageUnits(suns_);
  if (!truth_.empty()) {
    res_.final_angular_error_deg =
        DominantAngularErrorDeg(env_, res_.lambda, res_.point_lights, centre_, truth_, res_.directional_lights);
    res_.final_position_error_m =
        WorstPositionError(res_.point_lights, truth_, centre_, opt_.point_lights.far * radius_,
                           &res_.final_position_error_share);
  }
  res_.dominant = DominantDirections(env_, res_.lambda, res_.directional_lights, 2);
  // A fit that renders (almost) nothing is the activation penalty winning over data it no
  // longer hears: a Cauchy scale far below the residuals makes every pixel an outlier.
  if (res_.rendered_fraction < 0.01) {
    char line[320];
    std::snprintf(line, sizeof line,
                  "the estimate lights nothing (it renders %.2g of the images' mean): with a Cauchy scale sigma of "
                  "%g every residual is in the loss's flat tail, or the activation penalty alpha %g outweighs the "
                  "data; use a larger sigma (default 0.5) or a smaller alpha (default 3)",
                  res_.rendered_fraction, opt_.objective.sigma, opt_.objective.alpha);
    res_.warnings.push_back(line);
  }
}

void Estimator::RenderFittedViews() {
  CheckCancel();
  Stopwatch rs;
  TracerOptions topt = opt_.tracer;
  topt.seed = opt_.tracer.seed * 1000003ull + 999;
  topt.spp = opt_.render_spp > 0 ? opt_.render_spp : kMaskedRenderSpp;
  topt.cancelled = opt_.cancelled;
  CellSampler sampler(env_, res_.lambda, reachable_, opt_.tracer.nee_floor);
  const bool traced = opt_.render_spp > 0;  // every pixel; else the fit and the pixels it did not use
  res_.renders = RenderLighting(*scene_, env_, res_.lambda, sampler, res_.point_lights, res_.directional_lights,
                                traced ? bundle_.views : UnusedPixels(views_), topt, traced);
  if (!traced) PutFit(&res_.renders);
  CheckCancel();
  res_.render_seconds = rs.Seconds();
  Progress(Fmt(traced ? "relit %.0f view(s) in %.2f s (%.0f samples per pixel)"
                                   : "relit %.0f view(s) in %.2f s (the fit, and the pixels it did not use at %.0f "
                                     "samples per pixel)",
               bundle_.views.size(), res_.render_seconds, topt.spp));
}

/// The views with only the pixels the fit did not use marked valid.
std::vector<View> Estimator::UnusedPixels(std::vector<View> views) {
  for (View& v : views) {
    const std::size_t n = static_cast<std::size_t>(v.camera.width) * v.camera.height;
    if (v.valid.size() != n) v.valid.assign(n, 0);  // none used: every pixel (as an empty mask renders none)
    for (auto& b : v.valid) b = !b;
  }
  return views;
}

/// The fitted pixels of `renders` set to the fit: the last round's A lambda plus the
/// point and directional lights' columns, in image units.
void Estimator::PutFit(std::vector<ImageRGB>* renders) {
  const std::vector<double> fit = Plus(A_.Multiply(lambda_), LightsRender(points_, suns_));
  for (std::size_t r = 0; r < A_.rows(); ++r) {
    ImageRGB& img = (*renders)[A_.row_view[r]];
    for (int c = 0; c < 3; ++c)
      img.data[3 * static_cast<std::size_t>(A_.row_pixel[r]) + c] = static_cast<float>(fit[3 * r + c] * res_.image_mean);
  }
}

}  // namespace

EstimateResult Estimate(const SceneBundle& bundle, const EstimateOptions& options) {
  Estimator estimator(bundle, options);
  estimator.RunRounds();
  if (estimator.AlbedoRefinable())
    for (int pass = 1; pass <= options.albedo_passes && estimator.RefineAlbedo(pass); ++pass) estimator.RunRounds();
  estimator.FitSky();
  estimator.Conclude();
  if (options.render) estimator.RenderFittedViews();
  return estimator.TakeResult();
}

}  // namespace lp
