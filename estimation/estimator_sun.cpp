#include "estimation/estimator_impl.h"

namespace lp::detail {

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
  if (vertices_.size() == 0) {  // no near-light model: no vertices to light
    Progress("no directional light tried: no shading vertices were gathered this round");
    return false;
  }
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
/// directional.min_map_share of the map's power and rendering at least directional.min_share of the light
/// seen, as one light from its direction (the map's spread's centre) with its irradiance;
/// false when there is none.
bool Estimator::ProposeDirectionalLight(DirectionalProposal* out) {
  const auto [cells, map_share] = BrightestNeighbourhood();
  if (cells.empty() || map_share < opt_.directional.min_map_share) {
    Progress(Fmt("no directional light tried: the map's brightest neighbourhood holds %.3g of its power (at least "
                 "%.3g wanted)",
                 map_share, opt_.directional.min_map_share));
    return false;
  }
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
    if (!(rendered >= opt_.directional.min_share * seen)) {
      Progress(Fmt("no directional light tried: the map's brightest neighbourhood renders %.3g of the light seen (at "
                   "least %.3g wanted)",
                   seen > 0 ? rendered / seen : 0.0, opt_.directional.min_share));
      return false;
    }
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
  const bool keep = with_loss < (1 - opt_.directional.min_gain) * without_loss;
  if (keep) sun_held_out_ratio_ = without_loss > 0 ? with_loss / without_loss : 1;
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

/// A directional light's unit column on the held-out rows, traced with as many paths as
/// the map's columns (tracer.spp), not taken from the shading vertices (point_lights.spp,
/// twice that in round 2): the held-out loss then compares the models, not their columns'
/// noise. A sun's light reaches a pixel mostly through paths that bounce (the walls it lights
/// light the rest), each vertex's shadow ray all or nothing: a column of few paths loses to
/// the map's importance-sampled cells even at the right direction (docs/benchmarks.md,
/// session 22).
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
  const std::vector<ImageRGB> images = RenderLights(*scene_, traced, {light}, topt, false);
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
/// the light low and moves that light into the sky (docs/method.md, "The sky"); an
/// independently traced column of the light as the instrument removes that bias. The sky's radiance is added to its cells.
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
  std::vector<double> t(y_.size());  // what the light and the sky render
  for (std::size_t e = 0; e < t.size(); ++e) t[e] = y_[e] - rest[e];
  const std::vector<std::uint8_t>* bounds = one_sided_.size() == y_.size() ? &one_sided_ : nullptr;
  for (int c = 0; c < 3; ++c) {
    const Eigen::Vector2d ab = FitLightBesideSky(x, z, s, t, sun.irradiance[c], cauchy, bounds, c, 3);
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

}  // namespace lp::detail
