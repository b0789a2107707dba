#include "estimation/estimator.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>

#include "common/error.h"
#include "common/timer.h"
#include "scene/albedo.h"
#include "scene/ray_tracer.h"
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

std::string Fmt(const char* fmt, double a, double b = 0, double c = 0, double d = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, fmt, a, b, c, d);
  return buf;
}

/// A round's linear problem over the cells some sampled path reached, and the way back
/// from its compact unknowns to the whole map.
struct RoundProblem {
  LinearProblem problem;
  std::vector<double> init;  ///< the estimate so far, compact (3 per unknown cell)

  std::vector<double> Scatter(const std::vector<double>& compact, int cells) const {
    std::vector<double> full(3 * cells, 0.0);
    for (int k = 0; k < problem.unknown_cells; ++k)
      for (int c = 0; c < 3; ++c) full[3 * problem.cell_of[k] + c] = compact[3 * k + c];
    return full;
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
  /// The estimate in image units, its scores and what the user should know about it.
  void Conclude();
  /// Relit renders of the fitted views under the estimate.
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
  void Observe();
  RoundProblem TraceRound(int round, int first, RoundInfo* info);
  SolveResult Solve(const RoundProblem& rp, int round, RoundInfo* info);
  void Update(const RoundProblem& rp, const SolveResult& sr, RoundInfo* info);

  const SceneBundle& bundle_;
  const EstimateOptions& opt_;
  Stopwatch clock_;
  EstimateResult res_;
  const EnvMap& env_;  ///< res_.env
  int cells_ = 0;
  std::vector<double> y_;  ///< observations over their mean
  std::vector<TruthLight> truth_;
  std::unique_ptr<RayTracer> scene_;
  Mesh mesh_;  ///< the mesh whose albedo is refined (empty until then)
  std::vector<double> lambda_;  ///< the estimate, normalized units, 3 per cell
  std::vector<std::uint8_t> reachable_;  ///< per cell: some sampled path reached it
  TransportMatrix A_;
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
  scene_ = std::make_unique<RayTracer>(bundle_.mesh);
  res_.bvh_seconds = bvh.Seconds();
  if (bundle_.truth_json) truth_ = ParseTruthLights(*bundle_.truth_json, (bundle_.dir / "truth.json").string());
  // Start dark and uniform (paper): every cell equally likely to be sampled.
  lambda_.assign(3 * cells_, 1e-3);
  reachable_.assign(cells_, 1);
}

/// The valid pixels as observations normalized to mean 1, and the penalty at their scale.
void Estimator::Observe() {
  y_ = CollectObservations(bundle_.views);
  res_.observations = static_cast<int>(y_.size() / 3);
  if (y_.empty()) throw InputError(SceneFile(), "every pixel of every view is masked or invalid");
  double mean = 0;
  for (double v : y_) mean += v;
  mean /= y_.size();
  if (!(mean > 0) || !std::isfinite(mean)) throw InputError(SceneFile(), "the observed pixels are all black");
  res_.image_mean = mean;
  for (double& v : y_) v /= mean;
  // alpha is given per 19,200 observed pixels (one 160x120 view): the data term grows with
  // the number of observations, and so must the penalty, or the balance between them
  // (how many cells light the scene) would change with resolution and view count.
  res_.objective_params = opt_.objective;
  res_.objective_params.alpha = opt_.objective.alpha * res_.observations / kAlphaReferencePixels;
}

void Estimator::RunRounds() {
  const int first = static_cast<int>(res_.rounds.size()) + 1, last = first + opt_.max_rounds - 1;
  for (int round = first; round <= last; ++round) {
    CheckCancel();
    RoundInfo info;
    info.round = round;
    const RoundProblem rp = TraceRound(round, first, &info);
    const SolveResult sr = Solve(rp, round, &info);
    Update(rp, sr, &info);
    if (round > first && info.image_change < opt_.change_threshold) break;
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
  TransportMatrix Ar = TraceTransport(*scene_, env_, bundle_.views, sampler, topt, &res_.trace);
  CheckCancel();
  A_ = (opt_.combine_rounds && round > first) ? Combine(A_, Ar) : std::move(Ar);
  info->trace_seconds = ts.Seconds();
  info->nonzeros = static_cast<std::int64_t>(A_.nonzeros());

  RoundProblem rp{MakeLinearProblem(A_, y_), {}};
  const LinearProblem& problem = rp.problem;
  info->unknown_cells = problem.unknown_cells;
  // Cells no sampled path reached are not unknowns, and are not sampled again.
  std::fill(reachable_.begin(), reachable_.end(), 0);
  for (int j : problem.cell_of) reachable_[j] = 1;
  Progress(Fmt("round %.0f: traced in %.2f s, %.0f unknown cells of ", round, info->trace_seconds,
               problem.unknown_cells) +
           std::to_string(cells_) + ", " + std::to_string(A_.nonzeros()) + " non-zeros");
  if (problem.unknown_cells == 0)
    throw InputError(SceneFile(), "no sampled path reaches the environment (camera inside closed geometry?)");
  rp.init.resize(3 * problem.unknown_cells);
  for (int k = 0; k < problem.unknown_cells; ++k)
    for (int c = 0; c < 3; ++c) rp.init[3 * k + c] = lambda_[3 * problem.cell_of[k] + c];
  return rp;
}

/// Solves the round's problem warm-started, logging every iteration. Graduated Cauchy
/// scale: from the cold start (round 1, a dark map) every residual is about the mean
/// pixel; with a small sigma that is the loss's flat tail, where the activation penalty
/// outweighs the data and the all-zero map is a local minimum (sigma = 0.1 lit nothing
/// on the demo). Round 1 solves at kGraduatedSigmaStart first and halves the scale down
/// to sigma, each solve warm-started from the last.
SolveResult Estimator::Solve(const RoundProblem& rp, int round, RoundInfo* info) {
  const LinearProblem& problem = rp.problem;
  ObjectiveParams params = res_.objective_params;
  params.cell_weight.resize(problem.unknown_cells);
  for (int k = 0; k < problem.unknown_cells; ++k)
    params.cell_weight[k] = env_.solid_angle(problem.cell_of[k]) / kAlphaReferenceSolidAngle;
  std::vector<double> sigmas;  // at most 7 steps: a tiny sigma jumps from 1/64 of the start
  if (round == 1)
    for (double s = kGraduatedSigmaStart; s > std::max(params.sigma * 1.5, kGraduatedSigmaStart / 64); s *= 0.5)
      sigmas.push_back(s);
  sigmas.push_back(params.sigma);

  int iteration_offset = 0;
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
    if (!truth_.empty()) row.angular_error_deg = DominantAngularErrorDeg(env_, rp.Scatter(*it.lambda, cells_), truth_);
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
  // The change that matters is in the images: neighbouring cells have nearly the same
  // columns, so noise moves energy between them without changing what is rendered.
  std::vector<double> delta(sr.lambda.size()), a_delta, a_new;
  for (std::size_t i = 0; i < delta.size(); ++i) delta[i] = sr.lambda[i] - rp.init[i];
  rp.problem.Multiply(delta, &a_delta);
  rp.problem.Multiply(sr.lambda, &a_new);
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
  info->lambda = lambda_;
  for (double& v : info->lambda) v *= res_.image_mean;
  info->end_seconds = Now();
  res_.kkt_violation = sr.kkt_violation;
  res_.rounds.push_back(*info);
  if (opt_.on_round) opt_.on_round(*info, env_);
  Progress("round " + std::to_string(info->round) + ": " + ToString(opt_.solver) + " solver, " +
           Fmt("%.0f iterations in %.2f s, objective %.6g, change %.3g", sr.iterations, info->solve_seconds,
               sr.objective, info->change) +
           Fmt(" (in the image %.3g)", info->image_change) + Fmt(", KKT violation %.2g", sr.kkt_violation));
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
  mesh_ = scene_->mesh();
  return true;
}

bool Estimator::RefineAlbedo(int pass) {
  CheckCancel();
  Stopwatch as;
  int segments = -1;  // an estimate that lights nothing (warned in Conclude) has no irradiance
  if (res_.rendered_fraction >= 0.01) {
    Progress(Fmt("albedo pass %.0f: de-lighting %.0f vertices (%.0f paths each)", pass,
                 static_cast<double>(mesh_.positions.size()), opt_.albedo_samples));
    std::vector<float> irradiance;
    {
      VertexRadiance radiance(*scene_, env_, lambda_, opt_.tracer.bounces, opt_.tracer.seed * 7919 + pass);
      for (int done = 0; done < opt_.albedo_samples; done += 2) {  // Cancel is polled between steps
        radiance.Refine(std::min(2, opt_.albedo_samples - done));
        CheckCancel();
      }
      irradiance = radiance.Irradiance();
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
  scene_ = std::make_unique<RayTracer>(mesh_);
  res_.albedo_passes = pass;
  Progress(Fmt("albedo pass %.0f: de-lit %.0f vertices into %.0f segments in %.2f s", pass,
               static_cast<double>(mesh_.positions.size()), segments, as.Seconds()));
  return true;
}

void Estimator::Conclude() {
  if (res_.albedo_passes > 0) res_.albedo = scene_->mesh().albedo;
  res_.left_out.assign(cells_, 0);
  for (int j = 0; j < cells_; ++j) res_.left_out[j] = !reachable_[j];
  res_.lambda = lambda_;
  for (double& v : res_.lambda) v *= res_.image_mean;
  res_.final_relative_rmse = res_.convergence.empty() ? 0 : res_.convergence.back().relative_rmse;
  res_.final_rmse = res_.final_relative_rmse * res_.image_mean;
  if (!truth_.empty()) res_.final_angular_error_deg = DominantAngularErrorDeg(env_, res_.lambda, truth_);
  res_.dominant = DominantDirections(env_, res_.lambda, 2);
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
  if (opt_.render_spp > 0) topt.spp = opt_.render_spp;
  topt.cancelled = opt_.cancelled;
  CellSampler sampler(env_, res_.lambda, reachable_, opt_.tracer.nee_floor);
  res_.renders = RenderEnvironment(*scene_, env_, bundle_.views, res_.lambda, sampler, topt, true);
  CheckCancel();
  res_.render_seconds = rs.Seconds();
  Progress(Fmt("relit %.0f view(s) in %.2f s", bundle_.views.size(), res_.render_seconds));
}

}  // namespace

EstimateResult Estimate(const SceneBundle& bundle, const EstimateOptions& options) {
  Estimator estimator(bundle, options);
  estimator.RunRounds();
  if (estimator.AlbedoRefinable())
    for (int pass = 1; pass <= options.albedo_passes && estimator.RefineAlbedo(pass); ++pass) estimator.RunRounds();
  estimator.Conclude();
  if (options.render) estimator.RenderFittedViews();
  return estimator.TakeResult();
}

}  // namespace lp
