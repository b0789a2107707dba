// The map's prior chosen by the data (docs/method.md, "The map's prior"): in the first round
// on every pixel, the activation penalty's weight is tried from the given one down
// (kPriorFactors) with the lights found (and beside a directional light the map alone),
// each scored by the Cauchy loss on large blocks of pixels the fit did not use; the estimate
// is solved again at the strongest weight within one standard error of the best, and the
// rounds after it run at it.
#include "estimation/estimator_impl.h"

namespace lp {

std::size_t StrongestWithinOneStandardError(const std::vector<std::vector<double>>& block_loss,
                                            const std::vector<std::uint8_t>& used, std::vector<double>* loss,
                                            std::vector<double>* standard_error) {
  const std::size_t n = block_loss.size();
  const double blocks = static_cast<double>(std::count(used.begin(), used.end(), 1));
  loss->assign(n, 0.0);
  standard_error->assign(n, 0.0);
  if (n == 0) return 0;
  for (std::size_t k = 0; k < n; ++k)
    for (std::size_t b = 0; b < used.size(); ++b)
      if (used[b]) (*loss)[k] += block_loss[k][b];
  const std::size_t best = std::min_element(loss->begin(), loss->end()) - loss->begin();
  // The blocks' differences are independent; the blocks' own spread, common to every
  // weight, is not part of a difference's error.
  for (std::size_t k = 0; k < n && blocks > 1; ++k) {
    const double mean = ((*loss)[k] - (*loss)[best]) / blocks;
    double sq = 0;
    for (std::size_t b = 0; b < used.size(); ++b)
      if (used[b]) sq += std::pow(block_loss[k][b] - block_loss[best][b] - mean, 2);
    (*standard_error)[k] = std::sqrt(blocks * sq / (blocks - 1));
  }
  std::size_t k = 0;
  while ((*loss)[k] - (*loss)[best] > (*standard_error)[k]) ++k;
  return k;
}

std::size_t StrongestThatGains(const std::vector<std::vector<double>>& block_loss, const std::vector<std::uint8_t>& used,
                               double min_gain, std::vector<double>* loss, std::vector<double>* standard_error) {
  const std::size_t first = StrongestWithinOneStandardError(block_loss, used, loss, standard_error);
  if (first == 0) return 0;
  const double best = *std::min_element(loss->begin(), loss->end());
  for (std::size_t k = first; k < loss->size(); ++k)
    if ((*loss)[k] - best <= (*standard_error)[k] && (*loss)[0] - (*loss)[k] > min_gain * (*loss)[0]) return k;
  return 0;
}

}  // namespace lp

namespace lp::detail {

namespace {

/// The fold of block `b` of RowBlocks(kPriorBlocksAcross): (x + y + view) mod kPriorFolds,
/// so that every fold holds out blocks of every view, none beside another of its own.
int FoldOf(int b) {
  constexpr int n = kPriorBlocksAcross;
  return (b % n + (b / n) % n + b / (n * n)) % kPriorFolds;
}

/// The rows of `v` (3 per row) where keep[r] == want.
template <class T>
std::vector<T> Rows(const std::vector<T>& v, const std::vector<std::uint8_t>& keep, bool want) {
  std::vector<T> out;
  for (std::size_t r = 0; r < keep.size(); ++r)
    if (static_cast<bool>(keep[r]) == want) out.insert(out.end(), &v[3 * r], &v[3 * r] + 3);
  return out;
}

}  // namespace

/// Why the options leave the prior as given ("": they do not).
std::string Estimator::PriorGivenByOptions() const {
  if (!opt_.choose_prior) return "--choose-prior 0: the given --alpha";
  if (!(opt_.objective.alpha > 0 && opt_.objective.beta > 0))
    return "no activation penalty (--alpha 0 or --beta 0): nothing to choose";
  // (scored at a scale below the residuals, every held-out pixel is an outlier and the score
  // tells no weight from another; scored at the default one, it judges a fit it did not make:
  // at sigma 0.05 it took alpha 0.1 and a third of a lone cell's power spread over others)
  if (res_.objective_params.sigma < ObjectiveParams{}.sigma)
    return Fmt("a Cauchy scale below the default (--sigma %g < %g): the given --alpha", res_.objective_params.sigma,
               ObjectiveParams{}.sigma);
  return "";
}

/// Why the prior is not chosen here ("": it is).
std::string Estimator::PriorLeftOut(const std::vector<Light>& lights) const {
  if (std::string why = PriorGivenByOptions(); !why.empty()) return why;
  if (A_.rows() * 3 != y_.size() || (!lights.empty() && vertices_.rows() * 3 != y_.size()))
    return "the last round's rows are not every pixel's: the given --alpha";
  // (a reconstructed mesh's albedo is the colours seen: a weaker prior lets the map explain
  // its errors, and the held-out pixels, under the same albedo, agree: on our two-lamp scan
  // alpha 0.1 was chosen and the cool lamp came back 140 % of its distance off, 13 % at 3)
  if (!suns_.empty() && sun_held_out_ratio_ < kDecisiveSunRatio)
    return Fmt("a directional light that predicts the held-out pixels far better than the cells it replaced (its "
               "held-out loss %.3g of theirs, under %g): a sun, not a flat sky; the given --alpha",
               sun_held_out_ratio_, kDecisiveSunRatio);
  // (beside a window, an opening or a hole seen, its cells' prior is chosen alone, the others keeping the given
  // one: the light through a window is a sky's, and a sparse prior there leaves its light to
  // a spurious lamp; Cycles' glazed window scanned, docs/method.md)
  if (!bundle_.mesh.shaded.empty() && window_cells_.empty())
    return "a reconstructed mesh (its albedo is not known, and a weaker prior would let the map explain its "
           "errors): the given --alpha";
  return "";
}

/// A compact light in the map (a far lamp or a sun left to it) stays sparse: its
/// neighbourhood keeps the given prior (sparse_cells_), as a directional light's does.
void Estimator::MarkSparsePeak() {
  const auto [peak, share] = BrightestNeighbourhood();
  if (share < opt_.directional.min_map_share) return;
  sparse_cells_.assign(cells_, 0);
  for (int j : peak) sparse_cells_[j] = 1;
}

bool Estimator::ChoosePrior(RoundInfo* info) {
  PriorChoice& pc = res_.prior;
  pc.done = true;
  const std::vector<Light> lights = ColumnOrder(points_);  // the order of the problem solved again
  pc.why = PriorLeftOut(lights);
  if (!pc.why.empty()) return KeepTheGivenPrior();
  CheckCancel();
  Stopwatch ps;
  MarkSparsePeak();
  // With the lights: every weight, or only the given one beside a directional light (its
  // column is noisier than the map's, and a weaker prior lets the map take its power).
  // Beside a directional light also the map alone at every weaker weight: a flat sky under the
  // given prior is taken for a sun (Cycles' uniform sky: a sun and a lamp 7 m away,
  // docs/benchmarks.md).
  std::vector<MapPrior> with_alphas, alone_alphas;
  for (double f : kPriorFactors) alone_alphas.push_back({opt_.objective.alpha * f, 0});
  with_alphas = suns_.empty() ? alone_alphas : std::vector<MapPrior>{{opt_.objective.alpha, 0}};
  // (the map alone at the given weight is what the directional light's own selection beat)
  if (suns_.empty()) alone_alphas.clear();
  else alone_alphas.erase(alone_alphas.begin());
  const std::vector<int> block = RowBlocks(kPriorBlocksAcross);
  PriorFolds with = PriorLosses(lights, with_alphas, block);
  // (the glowing surfaces stay with the map alone: the pixels that see them are theirs)
  const std::vector<Light> glowing(emitters_.begin(), emitters_.end());
  PriorFolds alone = alone_alphas.empty() ? PriorFolds() : PriorLosses(glowing, alone_alphas, block);
  // The map alone (no lamp beside it) also smooth, where its weakest weight scored best.
  // (not beside a window: the smoothness would reach every cell, not its cells alone)
  if (points_.empty() && alone_alphas.empty() && window_cells_.empty())
    TrySmoothMaps(lights, block, &with_alphas, &with);
  if (!alone_alphas.empty()) TrySmoothMaps(glowing, block, &alone_alphas, &alone);
  if (with.loss.empty() || (!alone_alphas.empty() && alone.loss.empty())) {
    pc.why = "a fold of the views' blocks has no pixels (too few valid pixels): the given --alpha";
    return KeepTheGivenPrior();
  }
  std::vector<std::uint8_t> used(with.loss[0].size(), 0);
  for (int b : block) used[b] = 1;
  pc.folds = kPriorFolds;
  pc.blocks = static_cast<int>(std::count(used.begin(), used.end(), 1));
  // Of each kind, the strongest weight within one standard error of its best that gains
  // kPriorMinGain over the given one; where the map lights the room through a window (an
  // opening or a hole seen), the best: the light through a window is a sky's, extended, and the views'
  // blocks hardly see the cells that light the room only through it (Cycles' glazed window: docs/method.md, "The map's prior").
  std::vector<double> with_loss, with_se, alone_loss, alone_se;
  const auto choose = [&](const PriorFolds& folds, std::vector<double>* loss, std::vector<double>* se) {
    const std::size_t k = StrongestThatGains(folds.loss, used, kPriorMinGain, loss, se);
    return window_cells_.empty() ? k : static_cast<std::size_t>(std::min_element(loss->begin(), loss->end()) - loss->begin());
  };
  const std::size_t kw = choose(with, &with_loss, &with_se);
  const std::size_t ka = alone_alphas.empty() ? 0 : choose(alone, &alone_loss, &alone_se);
  // The lights stay unless the map alone, at its own prior, predicts the held-out blocks as
  // well (within the model selection's min_gain): a flat sky that was taken for a sun.
  const bool keep = alone_alphas.empty() || with_loss[kw] < (1 - opt_.point_lights.min_gain) * alone_loss[ka];
  for (std::size_t k = 0; k < with_alphas.size(); ++k)
    pc.tried.push_back({with_alphas[k].alpha, with_loss[k], with_se[k], static_cast<int>(lights.size()),
                        with_alphas[k].smooth});
  for (std::size_t k = 0; k < alone_alphas.size(); ++k)
    pc.tried.push_back({alone_alphas[k].alpha, alone_loss[k], alone_se[k], 0, alone_alphas[k].smooth});
  const MapPrior chosen = keep ? with_alphas[kw] : alone_alphas[ka];
  pc.chosen = chosen.alpha;
  pc.chosen_smooth = chosen.smooth;
  pc.lights_dropped = !keep;
  SayPrior(keep ? with_loss : alone_loss, keep ? with_se : alone_se, keep ? kw : ka, lights.size());
  // (against the weight in effect: beside a window seen before round 1 its cells' weakest)
  const bool changed = pc.chosen != alpha_ || pc.chosen_smooth != opt_.objective.smooth || !keep ||
                       (!sparse_cells_.empty() && pc.chosen < opt_.objective.alpha);
  if (!keep) {
    res_.point_light_choices.push_back("the map's prior: " + pc.why);
    points_.clear();
    suns_.clear();
  }
  if (changed) SolveAtPrior(chosen, (keep ? with : alone).mean[keep ? kw : ka], info);
  pc.seconds = ps.Seconds();
  Progress(Fmt("the map's prior chosen in %.2f s", pc.seconds));
  return changed;
}

/// Where the map's weakest weight in `priors` (the last; `folds` their losses) scored best,
/// the map also smooth at that weight (kSmoothFactors, strongest first), each fold's solves
/// warm-started from the folds' mean there; appended to both. Not beside lamps (the caller's):
/// there the data chose a smooth map that took the lamp's light (Cycles' lamp_sky: the sky
/// 29 % low and the lamp 1.9 cm off, against 14.5 % and 0.7 cm without; docs/benchmarks.md,
/// session 42). A compact light left to the map scores best at a stronger weight, and pays
/// nothing for it (synth one-light: 1 s of 7.7 when they were always tried).
void Estimator::TrySmoothMaps(const std::vector<Light>& lights, const std::vector<int>& block,
                              std::vector<MapPrior>* priors, PriorFolds* folds) {
  if (folds->loss.empty() || priors->empty()) return;
  std::vector<double> total(folds->loss.size(), 0.0);
  for (std::size_t k = 0; k < total.size(); ++k)
    for (double b : folds->loss[k]) total[k] += b;
  if (std::min_element(total.begin(), total.end()) - total.begin() != static_cast<std::ptrdiff_t>(total.size()) - 1)
    return;
  std::vector<MapPrior> smooth;
  for (double s : kSmoothFactors) smooth.push_back({priors->back().alpha, s});
  PriorFolds more = PriorLosses(lights, smooth, block, &folds->mean.back());
  if (more.loss.empty()) return;
  priors->insert(priors->end(), smooth.begin(), smooth.end());
  folds->loss.insert(folds->loss.end(), more.loss.begin(), more.loss.end());
  folds->mean.insert(folds->mean.end(), more.mean.begin(), more.mean.end());
}

/// res_.prior.why, and a progress line per weight tried: `loss` and `se` the kind chosen
/// (with `lights` lights, or the map alone), its `k`-th weight the one chosen.
void Estimator::SayPrior(const std::vector<double>& loss, const std::vector<double>& se, std::size_t k,
                         std::size_t lights) {
  PriorChoice& pc = res_.prior;
  const std::size_t best = std::min_element(loss.begin(), loss.end()) - loss.begin();
  const PriorChoice::Tried& least = pc.tried[(pc.lights_dropped ? pc.tried.size() - loss.size() : 0) + best];
  const std::string rule =
      window_cells_.empty()
          ? Fmt("the strongest prior whose loss is within one standard error of that and %g %% below the given one's",
                100 * kPriorMinGain)
          : std::string("beside a window (the light through it a sky's, extended), for its cells, that least one");
  pc.why = Fmt("with %zu light(s) the held-out loss is least at alpha %g, smoothness %g (%.6g over %d blocks in %d "
               "folds); %s: alpha %g, smoothness %g (%.6g, more by %.3g, standard error %.3g)",
               pc.lights_dropped ? 0 : lights, least.alpha, least.smooth, loss[best], pc.blocks, pc.folds,
               rule.c_str(), pc.chosen, pc.chosen_smooth, loss[k], loss[k] - loss[best], se[k]);
  if (pc.tried.size() > loss.size()) {  // the map alone was tried beside the lights
    const PriorChoice::Tried* alone = &pc.tried.back();
    for (const PriorChoice::Tried& t : pc.tried)
      if (t.lights == 0 && t.loss < alone->loss) alone = &t;
    pc.why = (pc.lights_dropped ? std::string("the lights are dropped (the map alone predicts as well): ")
                                : Fmt("the lights stay (with them %.6g at alpha %g; the map alone at best ",
                                      pc.tried[k].loss, pc.tried[k].alpha) +
                                      Fmt("%.6g, at alpha %g): ", alone->loss, alone->alpha)) +
             pc.why;
  }
  for (const PriorChoice::Tried& t : pc.tried)
    Progress(Fmt("the map's prior: alpha %g, smoothness %g with %d light(s), held-out loss %.6g (standard error of its "
                 "difference from the least %.3g)",
                 t.alpha, t.smooth, t.lights, t.loss, t.standard_error));
  Progress("the map's prior: " + pc.why);
}

/// For each fold (in parallel), the map and the lights' intensities (their shapes held)
/// fitted on the other folds' rows at each weight, strongest first, each solve warm-started
/// from the one before (the first from `start` where given, else the estimate), and scored
/// on the fold's rows. Empty when a fold has no rows to fit or none to score.
Estimator::PriorFolds Estimator::PriorLosses(const std::vector<Light>& lights, const std::vector<MapPrior>& weights,
                                             const std::vector<int>& block, const std::vector<double>* start) {
  const std::size_t blocks = bundle_.views.size() * kPriorBlocksAcross * kPriorBlocksAcross;
  const std::size_t alphas = weights.size(), unknowns = 3 * (cells_ + lights.size());
  PriorFolds out;
  out.loss.assign(alphas, std::vector<double>(blocks, 0.0));
  std::vector<std::vector<std::vector<double>>> solution(kPriorFolds);  // per fold, per weight
  std::vector<std::vector<float>> columns, scored;
  for (const Light& l : lights) columns.push_back(Column(l));
  // A directional light's held-out rows from a column traced at the map's paths (the
  // shading vertices' few paths would score it below a map of clean columns), as its own
  // selection scores it (HoldoutLoss).
  scored = columns;
  for (std::size_t l = 0; l < lights.size(); ++l)
    if (const auto* d = std::get_if<DirectionalLight>(&lights[l]))
      scored[l] = TracedSunColumn(*d, nullptr, opt_.tracer.spp, 960);
  const CauchyLoss cauchy{res_.objective_params.sigma};
  std::vector<std::uint8_t> empty(kPriorFolds, 0);
  std::vector<std::vector<ConvergenceRow>> rows(kPriorFolds);  // (their trial solves', logged after)
  // Each block is one fold's: the folds write disjoint entries of out.loss.
  ParallelFor(0, kPriorFolds, [&](std::size_t f) {
    CheckCancel();
    // The fold's rows are scored; the others on a grid of every kPriorStride-th pixel fitted.
    std::vector<std::uint8_t> held(A_.rows()), fitted(A_.rows());
    for (std::size_t r = 0; r < held.size(); ++r) {
      held[r] = FoldOf(block[r]) == static_cast<int>(f);
      fitted[r] = !held[r] && OnGrid(A_.row_pixel[r], bundle_.views[A_.row_view[r]].camera.width, kPriorStride);
    }
    if (std::count(held.begin(), held.end(), 1) == 0 || std::count(fitted.begin(), fitted.end(), 1) == 0) {
      empty[f] = 1;
      return;
    }
    const std::vector<double> y_held = Rows(y_, held, true);
    std::vector<std::vector<float>> fit_columns, held_columns;
    for (std::size_t l = 0; l < columns.size(); ++l) {
      fit_columns.push_back(Rows(columns[l], fitted, true));
      held_columns.push_back(Rows(scored[l], held, true));
    }
    LinearProblem problem = MakeLinearProblem(SelectRows(A_, fitted, true), Rows(y_, fitted, true));
    problem.one_sided = OneSidedRows(fitted, true);
    if (!columns.empty()) problem = WithColumns(problem, cells_, fit_columns);
    problem.base_normal = MakeNormalMatrices(problem);  // once for every weight's solve
    const TransportMatrix held_map = SelectRows(A_, held, true);
    std::vector<double> x = StartOf(problem, lights);
    if (start)  // (a full solution: the map's cells, then the lights)
      for (int k = 0; k < problem.unknown_cells; ++k)
        for (int c = 0; c < 3; ++c) x[3 * k + c] = (*start)[3 * problem.cell_of[k] + c];
    for (std::size_t a = 0; a < alphas; ++a) {
      ObjectiveParams params = res_.objective_params;
      params.alpha = weights[a].alpha * static_cast<double>(problem.rows()) / kAlphaReferencePixels;
      params.smooth = weights[a].smooth;
      const Objective objective(problem, CellWeights(problem, params, weights[a].alpha));
      x = lp::Solve(opt_.solver, objective, x, TrialOptions(kTrialIterations, &rows[f])).lambda;
      std::vector<double> full = Scattered(problem, x, cells_ + lights.size());
      const std::vector<double> residual = Residuals(y_held, HeldOutRender(held_map, held_columns, full), &held);
      std::size_t h = 0;  // the held-out rows in order
      for (std::size_t r = 0; r < held.size(); ++r) {
        if (!held[r]) continue;
        for (int c = 0; c < 3; ++c, ++h) out.loss[a][block[r]] += cauchy.Value(residual[h]);
      }
      solution[f].push_back(std::move(full));
    }
  });
  std::vector<ConvergenceRow> log;  // in the order of their times (the folds ran side by side)
  for (const std::vector<ConvergenceRow>& fold : rows) log.insert(log.end(), fold.begin(), fold.end());
  std::stable_sort(log.begin(), log.end(),
                   [](const ConvergenceRow& a, const ConvergenceRow& b) { return a.wall_seconds < b.wall_seconds; });
  for (const ConvergenceRow& row : log) Push(row);
  if (std::count(empty.begin(), empty.end(), 1) > 0) return {};
  out.mean.assign(alphas, std::vector<double>(unknowns, 0.0));
  for (std::size_t a = 0; a < alphas; ++a)
    for (int f = 0; f < kPriorFolds; ++f)
      for (std::size_t i = 0; i < unknowns; ++i) out.mean[a][i] += solution[f][a][i] / kPriorFolds;
  return out;
}

/// Beside lamps, where the data chose a weaker prior than the given one (extended light beside
/// them), the map and the lights' intensities (their places held) solved once more at the
/// weakest weight tried: the strongest prior the held-out pixels allow, chosen for the lamps'
/// sake, shrinks the dim sky it kept (docs/method.md, "The map's prior").
void Estimator::RelaxPrior() {
  PriorChoice& pc = res_.prior;
  const double weakest = opt_.objective.alpha * kPriorFactors[std::size(kPriorFactors) - 1];
  if (points_.empty() || res_.rounds.empty() || pc.lights_dropped || !(pc.chosen < opt_.objective.alpha) ||
      !(pc.chosen > weakest))
    return;
  CheckCancel();
  RoundInfo info = res_.rounds.back();
  SolveAtPrior({weakest, pc.chosen_smooth}, lambda_, &info);
  pc.why += Fmt("; beside the lamps the map solved once more at alpha %g, the weakest tried, so that the prior "
                "chosen does not shrink the extended light it kept",
                weakest);
}

/// The map's prior from now on at `alpha` (as EstimateOptions' alpha): the objective's weight
/// is given per kAlphaReferencePixels observed pixels.
void Estimator::UseAlpha(double alpha) {
  alpha_ = alpha;
  res_.objective_params.alpha = alpha * static_cast<double>(y_.size() / 3) / kAlphaReferencePixels;
}

/// Where the prior is not chosen, the rounds after go on at the given one (a window seen
/// before round 1 started its cells at the weakest: StartBesideSeenWindows); whether that
/// changed the weight in effect.
bool Estimator::KeepTheGivenPrior() {
  const bool changed = alpha_ != opt_.objective.alpha;
  UseAlpha(opt_.objective.alpha);
  prior_restored_ = prior_restored_ || changed;
  return changed;
}

/// The map and the lights' intensities solved again on every pixel at weight `alpha` (as
/// EstimateOptions' alpha), warm-started from `start` (the map's cells, then the lights of
/// WithLights(points_)); its iterations are convergence rows of step "prior". A lamp left
/// with no intensity is dropped.
void Estimator::SolveAtPrior(MapPrior prior, const std::vector<double>& start, RoundInfo* info) {
  UseAlpha(prior.alpha);
  res_.objective_params.smooth = prior.smooth;
  RoundProblem rp = WithLights(points_);
  for (int k = 0; k < rp.problem->unknown_cells; ++k)
    for (int c = 0; c < 3; ++c) rp.init[3 * k + c] = start[3 * rp.problem->cell_of[k] + c];
  solve_step_ = "prior";
  const double seconds = info->solve_seconds;
  const SolveResult sr = Solve(rp, info->round, info, false);
  info->solve_seconds += seconds;
  solve_step_ = "solve";
  // (the round's change is now from its start to this solution)
  const std::vector<double> full = TakeSolution(rp, sr, info);
  points_ = rp.Lit<PointLight>(full, cells_);
  map_share_ = MapShare();
  res_.kkt_violation = sr.kkt_violation;
  Progress(Fmt("the map and the lights solved again at alpha %g, smoothness %g: %d iterations, objective %.6g",
               prior.alpha, prior.smooth, sr.iterations, sr.objective));
}

}  // namespace lp::detail
