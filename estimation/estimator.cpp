#include "estimation/estimator.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>

#include "common/error.h"
#include "common/timer.h"
#include "estimation/albedo.h"
#include "estimation/ray_tracer.h"
#include "estimation/vertex_radiance.h"

namespace lp {

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

}  // namespace

EstimateResult Estimate(const SceneBundle& bundle, const EstimateOptions& opt) {
  Stopwatch sw;
  auto now = [&] { return opt.time_offset + sw.Seconds(); };
  auto progress = [&](const std::string& s) {
    if (opt.progress) opt.progress(s);
  };
  auto check_cancel = [&] {
    if (opt.cancelled && opt.cancelled()) throw Cancelled();
  };
  if (opt.rings < 2 || opt.rings > 181) throw InputError("--rings must be between 2 and 181");
  if (opt.max_rounds < 1) throw InputError("--max-rounds must be at least 1");
  if (!(opt.objective.sigma > 0) || !std::isfinite(opt.objective.sigma))
    throw InputError("--sigma must be positive and finite");
  EstimateResult res;
  res.env = EnvMap(opt.rings, bundle.up);
  const EnvMap& env = res.env;
  const int L = env.size();

  std::vector<double> y = CollectObservations(bundle.views);
  res.observations = static_cast<int>(y.size() / 3);
  if (y.empty())
    throw InputError((bundle.dir / "scene.json").string(), "every pixel of every view is masked or invalid");
  double mean = 0;
  for (double v : y) mean += v;
  mean /= y.size();
  if (!(mean > 0) || !std::isfinite(mean))
    throw InputError((bundle.dir / "scene.json").string(), "the observed pixels are all black");
  res.image_mean = mean;
  for (double& v : y) v /= mean;

  // alpha is given per 19,200 observed pixels (one 160x120 view): the data term grows with
  // the number of observations, and so must the penalty, or the balance between them
  // (how many cells light the scene) would change with resolution and view count.
  res.objective_params = opt.objective;
  res.objective_params.alpha = opt.objective.alpha * res.observations / kAlphaReferencePixels;

  Stopwatch bvh;
  auto scene = std::make_unique<RayTracer>(bundle.mesh);
  res.bvh_seconds = bvh.Seconds();

  std::vector<TruthLight> truth;
  if (bundle.truth_json) truth = ParseTruthLights(*bundle.truth_json, (bundle.dir / "truth.json").string());

  // Start dark and uniform (paper): every cell equally likely to be sampled.
  std::vector<double> lambda(3 * L, 1e-3);
  std::vector<std::uint8_t> reachable(L, 1);
  TransportMatrix A;
  // Rounds first..last under the current scene's albedo: round 1 is the cold start; a
  // later pass is warm-started from the estimate so far, with an A of its own.
  auto run_rounds = [&](int first, int last) {
  for (int round = first; round <= last; ++round) {
    check_cancel();
    RoundInfo info;
    info.round = round;
    Stopwatch ts;
    CellSampler sampler(env, round == 1 ? std::vector<double>() : lambda, reachable, opt.tracer.nee_floor);
    TracerOptions topt = opt.tracer;
    topt.seed = opt.tracer.seed * 1000003ull + round;
    topt.cancelled = opt.cancelled;  // a cancelled trace stops within 64 pixels
    TransportMatrix Ar = TraceTransport(*scene, env, bundle.views, sampler, topt, &res.trace);
    check_cancel();
    A = (opt.combine_rounds && round > first) ? Combine(A, Ar) : std::move(Ar);
    info.trace_seconds = ts.Seconds();
    info.nonzeros = static_cast<std::int64_t>(A.nonzeros());

    LinearProblem problem = MakeLinearProblem(A, y);
    info.unknown_cells = problem.unknown_cells;
    // Cells no sampled path reached are not unknowns, and are not sampled again.
    std::fill(reachable.begin(), reachable.end(), 0);
    for (int j : problem.cell_of) reachable[j] = 1;
    progress(Fmt("round %.0f: traced in %.2f s, %.0f unknown cells of ", round, info.trace_seconds,
                 problem.unknown_cells) +
             std::to_string(L) + ", " + std::to_string(A.nonzeros()) + " non-zeros");
    if (problem.unknown_cells == 0)
      throw InputError((bundle.dir / "scene.json").string(),
                       "no sampled path reaches the environment (camera inside closed geometry?)");

    ObjectiveParams params = res.objective_params;
    params.cell_weight.resize(problem.unknown_cells);
    for (int k = 0; k < problem.unknown_cells; ++k)
      params.cell_weight[k] = env.solid_angle(problem.cell_of[k]) / kAlphaReferenceSolidAngle;
    std::vector<double> init(3 * problem.unknown_cells);
    for (int k = 0; k < problem.unknown_cells; ++k)
      for (int c = 0; c < 3; ++c) init[3 * k + c] = lambda[3 * problem.cell_of[k] + c];
    auto scatter = [&](const std::vector<double>& compact) {
      std::vector<double> full(3 * L, 0.0);
      for (int k = 0; k < problem.unknown_cells; ++k)
        for (int c = 0; c < 3; ++c) full[3 * problem.cell_of[k] + c] = compact[3 * k + c];
      return full;
    };
    // Graduated Cauchy scale: from the cold start (round 1, a dark map) every residual is
    // about the mean pixel; with a small sigma that is the loss's flat tail, where the
    // activation penalty outweighs the data and the all-zero map is a local minimum
    // (sigma = 0.1 lit nothing on the demo). Round 1 solves at kGraduatedSigmaStart first and
    // halves the scale down to sigma, each solve warm-started from the last.
    std::vector<double> sigmas;  // at most 7 steps: a tiny sigma jumps from 1/64 of the start
    if (round == 1)
      for (double s = kGraduatedSigmaStart; s > std::max(params.sigma * 1.5, kGraduatedSigmaStart / 64); s *= 0.5)
        sigmas.push_back(s);
    sigmas.push_back(params.sigma);
    int iteration_offset = 0;
    double step_sigma = params.sigma;
    SolverOptions so = opt.solver_options;
    so.on_iteration = [&](const IterationInfo& it) {
      ConvergenceRow row;
      row.wall_seconds = now();
      row.round = round;
      row.iteration = iteration_offset + it.iteration;
      row.sigma = step_sigma;
      row.albedo_pass = res.albedo_passes;  // the albedo the rounds run under
      row.objective = it.objective;
      row.relative_rmse = it.Rmse();
      row.photometric_rmse = row.relative_rmse * mean;
      if (!truth.empty()) row.angular_error_deg = DominantAngularErrorDeg(env, scatter(*it.lambda), truth);
      res.convergence.push_back(row);
      if (opt.on_convergence) opt.on_convergence(row);
      if (opt.solver_options.on_iteration) opt.solver_options.on_iteration(it);
      check_cancel();
    };
    Stopwatch ss;
    SolveResult sr;
    std::vector<double> start = init;
    for (double sigma : sigmas) {
      ObjectiveParams step = params;
      step.sigma = step_sigma = sigma;
      Objective objective(problem, step);
      const bool increased = sr.objective_increased;
      sr = Solve(opt.solver, objective, start, so);
      sr.objective_increased = sr.objective_increased || increased;
      iteration_offset += sr.iterations + 1;
      info.solver_iterations += sr.iterations;
      start = sr.lambda;
    }
    info.solve_seconds = ss.Seconds();
    info.objective = sr.objective;
    info.kkt_violation = sr.kkt_violation;
    res.objective_increased = res.objective_increased || sr.objective_increased;
    std::vector<double> next = scatter(sr.lambda);
    double diff = 0, norm = 0;
    for (int i = 0; i < 3 * L; ++i) {
      diff += (next[i] - lambda[i]) * (next[i] - lambda[i]);
      norm += next[i] * next[i];
    }
    info.change = norm > 0 ? std::sqrt(diff / norm) : 0.0;
    // The change that matters is in the images: neighbouring cells have nearly the same
    // columns, so noise moves energy between them without changing what is rendered.
    {
      std::vector<double> delta(sr.lambda.size()), a_delta, a_new;
      for (std::size_t i = 0; i < delta.size(); ++i) delta[i] = sr.lambda[i] - init[i];
      problem.Multiply(delta, &a_delta);
      problem.Multiply(sr.lambda, &a_new);
      double dn = 0, nn = 0;
      for (std::size_t i = 0; i < a_new.size(); ++i) {
        dn += a_delta[i] * a_delta[i];
        nn += a_new[i] * a_new[i];
      }
      info.image_change = nn > 0 ? std::sqrt(dn / nn) : 0.0;
      double rendered = 0;  // observations are normalized to mean 1
      for (double v : a_new) rendered += v;
      res.rendered_fraction = a_new.empty() ? 0.0 : rendered / a_new.size();
    }
    lambda.swap(next);
    info.lambda = lambda;
    for (double& v : info.lambda) v *= mean;
    info.end_seconds = now();
    res.kkt_violation = sr.kkt_violation;
    res.rounds.push_back(info);
    if (opt.on_round) opt.on_round(info, env);
    progress("round " + std::to_string(round) + ": " + ToString(opt.solver) + " solver, " +
             Fmt("%.0f iterations in %.2f s, objective %.6g, change %.3g", sr.iterations, info.solve_seconds,
                 sr.objective, info.change) +
             Fmt(" (in the image %.3g)", info.image_change) +
             Fmt(", KKT violation %.2g", sr.kkt_violation));
    if (round > first && info.image_change < opt.change_threshold) break;
  }
  };
  run_rounds(1, opt.max_rounds);
  // Albedo refinement: the reconstruction's albedo is the colour seen, flattened per
  // segment of one chromaticity, so each segment's mean still holds its mean shading (and
  // two surfaces of one chromaticity share one albedo). Divided by the estimate's
  // irradiance, the colour seen is the albedo the estimate implies; segmented again (now
  // a brightness step is a material's) it is the albedo the next rounds are solved under.
  const char* kNothingToDivide = "the estimate lights nothing, or every colour seen is black";
  if (opt.albedo_passes <= 0) res.albedo_left_out = "--albedo-passes 0";
  else if (bundle.mesh.shaded.size() != bundle.mesh.positions.size())
    res.albedo_left_out = "the bundle's albedo is known (its mesh has no shaded colours)";
  Mesh mesh;
  if (res.albedo_left_out.empty()) mesh = scene->mesh();
  for (int pass = 1; res.albedo_left_out.empty() && pass <= opt.albedo_passes; ++pass) {
    check_cancel();
    Stopwatch as;
    int segments = -1;  // an estimate that lights nothing (warned below) has no irradiance
    if (res.rendered_fraction >= 0.01) {
      progress(Fmt("albedo pass %.0f: de-lighting %.0f vertices (%.0f paths each)", pass,
                   static_cast<double>(mesh.positions.size()), opt.albedo_samples));
      std::vector<float> irradiance;
      {
        VertexRadiance radiance(*scene, env, lambda, opt.tracer.bounces, opt.tracer.seed * 7919 + pass);
        for (int done = 0; done < opt.albedo_samples; done += 2) {  // Cancel is polled between steps
          radiance.Refine(std::min(2, opt.albedo_samples - done));     // (~0.4 s each on the demo)
          check_cancel();
        }
        irradiance = radiance.Irradiance();
      }  // before the scene it refers to is replaced
      segments = DelightAlbedo(&mesh, irradiance);
    }
    res.albedo_seconds += as.Seconds();
    if (segments < 0) {
      if (res.albedo_passes == 0) res.albedo_left_out = kNothingToDivide;
      progress("albedo pass " + std::to_string(pass) + ": " + kNothingToDivide + "; albedo kept");
      break;
    }
    res.albedo_segments = segments;
    scene = std::make_unique<RayTracer>(mesh);
    res.albedo_passes = pass;
    progress(Fmt("albedo pass %.0f: de-lit %.0f vertices into %.0f segments in %.2f s", pass,
                 static_cast<double>(mesh.positions.size()), segments, as.Seconds()));
    const int first = static_cast<int>(res.rounds.size()) + 1;
    run_rounds(first, first + opt.max_rounds - 1);
  }
  if (res.albedo_passes > 0) res.albedo = scene->mesh().albedo;

  res.left_out.assign(L, 0);
  for (int j = 0; j < L; ++j) res.left_out[j] = !reachable[j];
  res.lambda = lambda;
  for (double& v : res.lambda) v *= mean;
  res.final_relative_rmse = res.convergence.empty() ? 0 : res.convergence.back().relative_rmse;
  res.final_rmse = res.final_relative_rmse * mean;
  if (!truth.empty()) res.final_angular_error_deg = DominantAngularErrorDeg(env, res.lambda, truth);
  res.dominant = DominantDirections(env, res.lambda, 2);
  // A fit that renders (almost) nothing is the activation penalty winning over data it no
  // longer hears: a Cauchy scale far below the residuals makes every pixel an outlier.
  if (res.rendered_fraction < 0.01) {
    char line[320];
    std::snprintf(line, sizeof line,
                  "the estimate lights nothing (it renders %.2g of the images' mean): with --sigma %g every "
                  "residual is in the Cauchy loss's flat tail, or --alpha %g outweighs the data; use a larger "
                  "--sigma (default 0.5) or a smaller --alpha (default 3)",
                  res.rendered_fraction, opt.objective.sigma, opt.objective.alpha);
    res.warnings.push_back(line);
  }

  if (opt.render) {
    check_cancel();
    Stopwatch rs;
    TracerOptions topt = opt.tracer;
    topt.seed = opt.tracer.seed * 1000003ull + 999;
    if (opt.render_spp > 0) topt.spp = opt.render_spp;
    topt.cancelled = opt.cancelled;
    CellSampler sampler(env, res.lambda, reachable, opt.tracer.nee_floor);
    res.renders = RenderEnvironment(*scene, env, bundle.views, res.lambda, sampler, topt, true);
    check_cancel();
    res.render_seconds = rs.Seconds();
    progress(Fmt("relit %.0f view(s) in %.2f s", bundle.views.size(), res.render_seconds));
  }
  res.total_seconds = sw.Seconds();
  return res;
}

}  // namespace lp
