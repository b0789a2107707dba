#include "estimation/estimator_impl.h"

namespace lp::detail {

/// The round's problem with `lights` and the directional lights so far as columns after the
/// map's (the map's problem itself when there are none), warm-started from the estimate so far.
RoundProblem Estimator::WithLights(const std::vector<PointLight>& lights) {
  RoundProblem rp;
  rp.lights = ColumnOrder(lights);
  std::vector<std::vector<float>> columns;
  for (const Light& l : rp.lights) columns.push_back(Column(l));
  rp.problem = columns.empty() ? map_problem_
                               : std::make_shared<LinearProblem>(WithColumns(*map_problem_, cells_, columns));
  rp.init = StartOf(*rp.problem, rp.lights);
  return rp;
}

std::vector<Light> Estimator::ColumnOrder(const std::vector<PointLight>& lights) const {
  std::vector<Light> out = AsLights(lights);
  for (const DirectionalLight& d : suns_) out.push_back(d);
  for (const EmitterLight& e : emitters_) out.push_back(e);
  return out;
}

std::vector<double> Estimator::HeldOutRender(const TransportMatrix& map_rows,
                                             const std::vector<std::vector<float>>& columns,
                                             const std::vector<double>& full) const {
  std::vector<double> render = map_rows.Multiply(std::vector<double>(full.begin(), full.begin() + 3 * cells_));
  for (std::size_t i = 0; i < render.size(); ++i)
    for (std::size_t k = 0; k < columns.size(); ++k) render[i] += columns[k][i] * full[3 * (cells_ + k) + i % 3];
  return render;
}

std::vector<double> Estimator::StartOf(const LinearProblem& problem, const std::vector<Light>& lights) const {
  std::vector<double> init(3 * problem.unknown_cells);
  for (int k = 0; k < problem.unknown_cells; ++k) {
    const int j = problem.cell_of[k];
    for (int c = 0; c < 3; ++c) init[3 * k + c] = j < cells_ ? lambda_[3 * j + c] : Scale(lights[j - cells_])[c];
  }
  return init;
}

namespace {

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

}  // namespace

/// The places where the cameras saw clipped blobs (seen_lamps.h), found and said once.
const std::vector<SeenLamp>& Estimator::SeenLampsOnce() {
  if (seen_lamps_) return *seen_lamps_;
  seen_lamps_ = opt_.point_lights.seen ? SeenLamps(bundle_.views, *scene_) : std::vector<SeenLamp>();
  // (a window's blobs, triangulated, meet behind its wall or at it: the sky's, or its pane's)
  seen_lamps_->erase(std::remove_if(seen_lamps_->begin(), seen_lamps_->end(),
                                    [&](const SeenLamp& l) {
                                      return BeyondAWindow(res_.windows, l.position, bundle_.up, -kBeyondWindow);
                                    }),
                     seen_lamps_->end());
  res_.seen_lamps = *seen_lamps_;
  for (const SeenLamp& l : *seen_lamps_) {
    const std::string line = Fmt("search: a lamp's place where the camera saw a clipped blob: (%.3f, %.3f, %.3f), %s",
                                 l.position.x(), l.position.y(), l.position.z(), l.how.c_str()) +
                             (l.how == "depth" ? "" : Fmt(" from %d views (rays within %.3f m)", l.views, l.gap)) +
                             Fmt(", %d pixels", l.pixels);
    res_.point_light_choices.push_back(line);
    Progress(line);
  }
  return *seen_lamps_;
}

/// The search's candidate places: a live estimate's lamps first (EstimateOptions::warm),
/// then where the cameras saw clipped blobs (from `first_seen`), then the grid around the
/// scene (from `first_grid`).
std::vector<Eigen::Vector3d> Estimator::SearchPlaces(std::size_t* first_seen, std::size_t* first_grid) {
  std::vector<Eigen::Vector3d> positions;
  if (opt_.warm)
    for (const PointLight& l : opt_.warm->lighting.Of<PointLight>()) positions.push_back(l.position);
  *first_seen = positions.size();
  for (const SeenLamp& l : SeenLampsOnce()) positions.push_back(l.position);
  *first_grid = positions.size();
  for (const Eigen::Vector3d& p : CandidatePositions(centre_, radius_, bundle_.up)) positions.push_back(p);
  return positions;
}

void Estimator::HoldAtSeen(std::vector<PointLight>* lights, RoundInfo* info) {
  if (!opt_.point_lights.hold_seen) return;
  bool held = false;
  for (const SeenLamp& seen : SeenLampsOnce()) {
    if (seen.how != "triangulated") continue;
    PointLight* nearest = nullptr;
    for (PointLight& l : *lights)
      if (!l.held && (!nearest || (l.position - seen.position).norm() < (nearest->position - seen.position).norm()))
        nearest = &l;
    if (!nearest) continue;
    const double off = (nearest->position - seen.position).norm();
    const double reach = std::max(kSeenHoldReachMin, kSeenHoldReach * (seen.position - centre_).norm());
    const bool hold = off <= reach;
    const std::string line =
        Fmt("point light at (%.3f, %.3f, %.3f): %.3g m from the place where the cameras saw a bulb, (%.3f, %.3f, "
            "%.3f) (%.3g m at most): ",
            nearest->position.x(), nearest->position.y(), nearest->position.z(), off, seen.position.x(),
            seen.position.y(), seen.position.z(), reach) +
        (hold ? "held there" : "not held");
    res_.point_light_choices.push_back(line);
    Progress(line);
    if (!hold) continue;
    nearest->position = seen.position;
    nearest->held = true;
    held = true;
  }
  if (held) SolveWithLights(lights, info, false);  // the map and the intensities with the lamps where they were seen
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
  std::size_t first_seen = 0, first_grid = 0;
  const std::vector<Eigen::Vector3d> positions = SearchPlaces(&first_seen, &first_grid);
  std::vector<std::vector<float>> columns(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    CheckCancel();
    PointLightColumn(*scene_, coarse, positions[i], &columns[i]);
  }
  Progress(Fmt("search: %zu candidate positions' columns at %d path(s) per pixel in %.2f s", positions.size(),
               topt.spp, cs.Seconds()));
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
    const std::size_t from = static_cast<std::size_t>(best);
    res_.point_light_choices.push_back(
        Fmt("search: light %zu starts from ", lights.size() + 1) +
        (from < first_seen   ? "the last estimate's lamp"
         : from < first_grid ? Fmt("the place where the camera saw clipped blob %zu", from - first_seen + 1)
                             : Fmt("the grid around the scene (candidate %zu)", from - first_grid + 1)));
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
    HoldAtSeen(&kept, info);
  }
  bool moved = kept.size() != points_.size();
  for (std::size_t k = 0; k < kept.size() && !moved; ++k)
    moved = (kept[k].position - points_[k].position).norm() > 0.02 * (kept[k].position - centre_).norm();
  points_ = std::move(kept);
  return moved;
}

/// Each light's radius (soft shadows), the map and the other lights held: the radius of a
/// small grid (0 and 0.8 % to 12.8 % of the scene's radius, doubling) whose column, with its
/// intensity fitted by reweighted least squares, gives the lowest Cauchy loss, then refined
/// between its neighbours on the grid (parabolas in the log of the radius: the grid's
/// doubling step alone left a 5 cm lamp at 3.8 cm, and its place millimetres across its
/// penumbrae off); a radius is taken only if it lowers the loss by 0.5 % (else the light
/// stays a point). True when a radius changed.
bool Estimator::FitRadii(std::vector<PointLight>* lights) {
  CheckCancel();
  bool changed = false;
  const std::vector<double> map = Plus(A_.Multiply(lambda_), LightsRender({}, suns_));
  std::vector<double> base;
  LightFitProblem fit = FitProblem(&base);
  fit.alpha = 0;  // the radius is chosen by the loss alone
  for (std::size_t k = 0; k < lights->size(); ++k) {
    base = map;
    SplitColumn col, others;  // the other lights' render in the base; their noise (debiased)
    if (fit.debiased) others.spread.assign(base.size(), 0.0f);
    for (std::size_t j = 0; j < lights->size(); ++j) {
      if (j == k) continue;
      col = Split((*lights)[j]);
      for (std::size_t i = 0; i < base.size(); ++i) base[i] += (*lights)[j].intensity[i % 3] * col.value[i];
      for (std::size_t i = 0; i < others.spread.size() && i < col.spread.size(); ++i)
        others.spread[i] += static_cast<float>((*lights)[j].intensity[i % 3] * col.spread[i]);
    }
    PointLight& light = (*lights)[k];
    // The loss with the lamp at `radius`, its intensity refitted there (kSphereShadowRays
    // each: the sizes' columns compared alike; the rounds' are the cache's).
    const SizeLoss loss_at = [&](double radius, Eigen::Vector3d* intensity) {
      if (radius == 0) col = Split(PointLight{light.position, light.intensity, 0});
      else
        PointLightColumn(*scene_, vertices_, light.position,
                         ColumnOut{&col.value, nullptr, fit.debiased ? &col.spread : nullptr}, radius,
                         kSphereShadowRays);
      *intensity = light.intensity;
      double sse = 0;
      const double loss = RefitScale(fit, col, others, intensity, &sse);
      CheckCancel();
      return loss;
    };
    const SizeChoice best = ChooseSize(loss_at, 0.008 * radius_, 5);
    const double radius = best.size;
    char line[240];
    std::snprintf(line, sizeof line,
                  "point light at (%.3f, %.3f, %.3f): radius %.3g m (Cauchy loss %.6g; as a point %.6g)",
                  light.position.x(), light.position.y(), light.position.z(), radius,
                  best.loss, best.zero_loss);
    res_.point_light_choices.push_back(line);
    Progress(line);
    if (radius != light.radius) {
      changed = true;
      light.radius = radius;
      if (radius > 0) light.intensity = best.scale;
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
        res_.point_light_choices.push_back(Fmt("round %d: a light refined to %.3g m from the centre is a far light; "
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
  emitters_ = rp.Lit<EmitterLight>(full, cells_);
  BoundEmitters();
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
  for (const EmitterLight& e : emitters_)  // (held fixed too, with the lights' weight)
    map_penalty += res_.objective_params.alpha * opt_.point_lights.weight *
                   std::max(1.0, opt_.objective.alpha / alpha_) *
                   std::log1p(res_.objective_params.beta * std::max(0.0, e.radiance.sum()));
  std::vector<double> base = Plus(A_.Multiply(lambda_), LightsRender({}, suns_));
  const LightFitProblem fit = FitProblem(&base);
  // One convergence row; on a share of the rows (every stride-th) E and the squared
  // residuals times the stride estimate the whole problem's.
  const auto logger = [&](int stride) {
    return [&, stride](int, double E, double sse, const std::vector<Light>& now) {
      ConvergenceRow row = LightRow(*info, fit.loss.sigma, E * stride + map_penalty, sse * stride);
      row.step = step;
      Score(&row, {lambda_, Joined(suns_, OfKind<PointLight>(now))});
      Push(row);
    };
  };
  std::vector<Light> moving = AsLights(*lights);
  if (!shadows) {  // round 1: the lights found by the sparse solve, on all rows
    info->light_iterations = RefineLights(fit, &moving, 12, logger(1));
    *lights = OfKind<PointLight>(moving);
    return;
  }
  // Rounds 2 on, the lights near their places: Levenberg-Marquardt (4 iterations), then the
  // compass search (steps of 1 % of the light's distance, then 0.5 %, at most 12 columns a
  // light) that sees the shadows' edges move. Both look at kShadowRows of the rows (every
  // n-th); what they find is kept only if the whole objective, over all rows, falls too.
  // (Why these numbers, measured: docs/method.md, "Refinement", and docs/benchmarks.md.)
  const auto value = [&](const std::vector<PointLight>& now, double* sse = nullptr) {
    std::vector<SplitColumn> columns;  // from the cache: the round's solve made the start's
    for (const PointLight& l : now) columns.push_back(Split(l));
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
      const std::vector<float> point = Column(PointLight{q, Eigen::Vector3d::Zero(), 0}), directional = Column(far);
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
  for (const EmitterLight& g : emitters_) {  // (always: the rest of the image for every other light)
    col = Column(g);
    for (std::size_t e = 0; e < out.size(); ++e) out[e] += g.radiance[e % 3] * col[e];
  }
  return out;
}

/// A light's unit column on vertices_ (UnitColumn) and, when the fit is debiased, its
/// halves' difference, from the cache when the round's vertices already gave them for that
/// shape (the last 8 shapes are kept).
SplitColumn Estimator::Split(const Light& light) {
  for (const CachedColumn& c : columns_)
    if (SameShape(c.light, light)) return c.column;
  constexpr std::size_t kKept = 8;
  if (columns_.size() == kKept) columns_.erase(columns_.begin());
  columns_.push_back({light, {}});
  SplitColumn& c = columns_.back().column;
  UnitColumn(*scene_, vertices_, light,
             ColumnOut{&c.value, nullptr, opt_.point_lights.debiased ? &c.spread : nullptr});
  return c;
}

/// A light's unit column on vertices_ (Split's value).
std::vector<float> Estimator::Column(const Light& light) { return Split(light).value; }

/// The share of the observed light a point light renders; a lamp inside a glowing surface
/// (a bulb in its shade) with the surface's: the two are one light, most of the bulb's
/// reaching the room through the shade.
double Estimator::RenderedShare(const PointLight& light) {
  const std::vector<float> col = Column(light);
  double rendered = 0, seen = 0;
  for (std::size_t e = 0; e < col.size(); ++e) {
    rendered += light.intensity[e % 3] * col[e];
    seen += y_[e];
  }
  if (const EmitterLight* shade = ShadeOf(light)) {
    const std::vector<float> glow = Column(Light(*shade));
    for (std::size_t e = 0; e < glow.size(); ++e) rendered += shade->radiance[e % 3] * glow[e];
  }
  return seen > 0 ? rendered / seen : 0.0;
}

/// The Cauchy loss on the held-out rows of the map and `lights` (and a directional light)
/// fitted on the other rows.
double Estimator::HoldoutLoss(const std::vector<PointLight>& lights, const DirectionalLight* directional,
                              bool traced, int iterations) {
  std::vector<Light> all = AsLights(lights);
  if (directional) all.push_back(*directional);
  for (const EmitterLight& e : emitters_) all.push_back(e);  // (the glowing surfaces so far beside them)
  std::vector<std::vector<float>> columns;
  for (const Light& l : all) columns.push_back(Column(l));
  std::vector<double> y_fit, y_held;
  for (std::size_t r = 0; r < holdout_.size(); ++r)
    for (int c = 0; c < 3; ++c) (holdout_[r] ? y_held : y_fit).push_back(y_[3 * r + c]);
  if (!holdout_fit_) {  // once per A_: the map's part of the fit, with its normal matrices
    holdout_fit_ = std::make_shared<LinearProblem>(MakeLinearProblem(SelectRows(A_, holdout_, false), y_fit));
    holdout_fit_->one_sided = OneSidedRows(holdout_, false);
    holdout_fit_->base_normal = MakeNormalMatrices(*holdout_fit_);
    holdout_held_ = SelectRows(A_, holdout_, true);
  }
  // The columns' fitted and held-out rows.
  std::vector<std::vector<float>> fit_columns(columns.size()), held_columns(columns.size());
  for (std::size_t k = 0; k < columns.size(); ++k)
    for (std::size_t r = 0; r < holdout_.size(); ++r)
      (holdout_[r] ? held_columns : fit_columns)[k].insert((holdout_[r] ? held_columns : fit_columns)[k].end(),
                                                           &columns[k][3 * r], &columns[k][3 * r] + 3);
  if (directional && traced) held_columns[lights.size()] = HeldOutSunColumn(*directional);  // (the emitters after it)
  const LinearProblem problem = WithColumns(*holdout_fit_, cells_, fit_columns);
  ObjectiveParams params = res_.objective_params;
  params.alpha *= static_cast<double>(holdout_fit_->rows()) / std::max<std::size_t>(1, holdout_.size());
  params = CellWeights(problem, params);
  const std::vector<double> init = StartOf(problem, all);
  const SolveResult sr = lp::Solve(opt_.solver, Objective(problem, params), init, TrialOptions(iterations));
  const std::vector<double> render =
      HeldOutRender(holdout_held_, held_columns, Scattered(problem, sr.lambda, cells_ + columns.size()));
  return CauchyLoss{params.sigma}.Sum(Residuals(y_held, render, &holdout_));
}

}  // namespace lp::detail
