// Windows: a glowing surface the cameras saw may be glass that lets the sky through
// (docs/method.md, "Windows: a pane or an opening"). Each surface seen glowing that could be
// a window (flat, nothing behind it) is tried as an opening, after its own trial: its triangles left out of the
// traced scene, so that the pixels on it see the map through it and the map lights the
// room through it with its directions; the pane and the opening each traced afresh (the
// same paths' seed and samples), the opening kept where the held-out pixels say so.
#include <algorithm>

#include "common/rng.h"
#include "estimation/estimator_impl.h"
#include "estimation/sampling.h"

namespace lp::detail {
namespace {

/// A surface is flat when its area-weighted normals sum to this share of its area.
constexpr double kFlat = 0.95;
/// Rays cast out of its back (cosine-distributed about the side opposite its glow, from
/// points spread over it by area), and the share that must leave the scene for it to be a
/// window (a screen or a lamp's shade has a wall or the room behind it).
constexpr int kBehindRays = 32;
constexpr double kBehindEscape = 0.75;
/// The opening is kept where its held-out loss is lower than the pane's by this share
/// (the pane, what the depth camera saw, on a near tie), its whole objective no higher.
constexpr double kOpeningGain = 0.03;
/// Both hypotheses' solves run this long (a model's trial solves, kTrialIterations, stop
/// short here: the map seen through an opening starts from the map fitted without it, and
/// at 50 iterations Cycles' glazed window came out 33.0 against the pane's 30.7, at 300
/// 11.9 against 30.7).
constexpr int kOpeningIterations = 300;

/// The unit normal of the side `e` glows on, summed by area, and how flat it is (1: a plane).
std::pair<Eigen::Vector3d, double> Facing(const EmitterShape& e) {
  const Eigen::Vector3d sum = FacingSum(e);
  const double norm = sum.norm();
  return {norm > 0 ? Eigen::Vector3d(sum / norm) : Eigen::Vector3d::UnitZ(), e.area > 0 ? norm / e.area : 0.0};
}

/// A point on the shape, uniform by area (u1, u2, u3 uniform in [0, 1)).
Eigen::Vector3d PointOnShape(const EmitterShape& e, double u1, double u2, double u3) {
  const std::size_t t = std::min<std::size_t>(
      e.a.size() - 1, std::upper_bound(e.cumulative.begin(), e.cumulative.end(), u1 * e.area) - e.cumulative.begin());
  if (u2 + u3 > 1) u2 = 1 - u2, u3 = 1 - u3;
  return (e.a[t] + u2 * (e.b[t] - e.a[t]) + u3 * (e.c[t] - e.a[t])).cast<double>();
}

}  // namespace

std::vector<std::uint8_t> Estimator::TrianglesOn(const std::shared_ptr<const EmitterShape>& shape) const {
  std::vector<std::uint8_t> on = TrianglesOnShapes(scene_->mesh(), {shape});
  const std::vector<std::uint8_t>& open = scene_->open();
  for (std::size_t t = 0; t < open.size(); ++t) on[t] = on[t] || open[t];
  return on;
}

bool Estimator::CouldBeWindow(const EmitterLight& e, const RayTracer& opened) const {
  const auto [facing, flat] = Facing(*e.shape);
  if (flat < kFlat) return false;
  Rng rng(opt_.tracer.seed, 0x0be0);
  int out = 0;
  for (int i = 0; i < kBehindRays; ++i) {
    const Eigen::Vector3d from = PointOnShape(*e.shape, rng.Uniform(), rng.Uniform(), rng.Uniform()) - 0.01 * facing;
    out += !opened.Occluded(from, SampleCosine(-facing, rng.Uniform(), rng.Uniform()), 1e30);
  }
  return out >= kBehindEscape * kBehindRays;
}

void Estimator::TraceAfresh(int round) {
  // (every cell reachable: an opening lets the map in where the pane did not)
  const CellSampler sampler = Sampler(lambda_, std::vector<std::uint8_t>(cells_, 1));
  A_ = TraceTransport(*scene_, env_, views_, sampler, MapTracer(round, 7001), &res_.trace);
  CheckCancel();
  MakeMapProblem();
  GatherVertices(round, round);  // (their own, not combined with the rounds' before)
}

/// What an opening's trial changes, to put back where the pane stays.
struct Estimator::TracedState {
  TransportMatrix A;
  std::shared_ptr<LinearProblem> map_problem, holdout_fit;
  TransportMatrix holdout_held;
  ShadingVertices vertices;
  double vertex_samples = 0;
};

bool Estimator::TryOpening(const EmitterLight& candidate, const std::vector<EmitterLight>& as_is, double* objective,
                           double* held) {
  CheckCancel();
  // (a surface seen glowing again where a kept one lies is not tried: TryEmitter)
  auto opened = std::make_unique<RayTracer>(scene_->mesh(), TrianglesOn(candidate.shape));
  if (!CouldBeWindow(candidate, *opened)) return false;
  Stopwatch sw;
  const std::vector<EmitterLight> kept = emitters_;  // (without the candidate)
  TracedState before{std::move(A_), map_problem_, holdout_fit_, std::move(holdout_held_), vertices_, vertex_samples_};
  // The surface as the candidate's trial left it (`as_is`: glowing or not), on fresh paths.
  TraceAfresh(round_);
  const double closed_objective = ObjectiveWith(as_is, kOpeningIterations),
               closed_held = HoldoutLoss(points_, nullptr, false, kOpeningIterations);
  // The opening, on the same paths' seed and samples: the surface neither glows nor blocks.
  std::swap(scene_, opened);  // (`opened` the closed scene now)
  TraceAfresh(round_);
  const double open_objective = ObjectiveWith(kept, kOpeningIterations),
               open_held = HoldoutLoss(points_, nullptr, false, kOpeningIterations);
  const bool open = open_held < (1 - kOpeningGain) * closed_held && open_objective <= closed_objective;
  const std::string line = Fmt(
      "glowing surface of %.3g m^2 as a window's opening (the map seen through it) against %s: objective %.6g "
      "against %.6g, held-out loss %.6g against %.6g (%.2f s): %s",
      candidate.Area(),
      std::any_of(as_is.begin(), as_is.end(), [&](const EmitterLight& e) { return e.shape == candidate.shape; })
          ? "a glowing pane"
          : "a pane that does not glow",
      open_objective,
      closed_objective, open_held, closed_held, sw.Seconds(), open ? "an opening" : "not an opening");
  res_.point_light_choices.push_back(line);
  Progress(line);
  emitters_ = kept;
  if (!open) {
    scene_ = std::move(opened);
    A_ = std::move(before.A);
    map_problem_ = before.map_problem;
    holdout_fit_ = before.holdout_fit;
    holdout_held_ = std::move(before.holdout_held);
    vertices_ = std::move(before.vertices);
    vertex_samples_ = before.vertex_samples;
    columns_.clear();
    return false;
  }
  MarkReachable(*map_problem_);
  res_.openings.push_back(candidate.shape);
  MarkWindowCells(-FacingSum(*candidate.shape).normalized());
  portals_.push_back(PortalOf(*candidate.shape, bundle_.up));
  *objective = open_objective;
  *held = open_held;
  return true;
}

CellSampler Estimator::Sampler(const std::vector<double>& lambda, const std::vector<std::uint8_t>& reachable) const {
  CellSampler sampler(env_, lambda, reachable, opt_.tracer.nee_floor);
  if (!portals_.empty()) sampler.SetPortals(portals_, kPortalShare);
  return sampler;
}

/// window_cells_ gains the cells behind a window: those whose direction leaves the room
/// through its wall (`out`: an opening's, against the side its pixels were seen from, the side
/// it faced as a glowing candidate; a hole's, against its wall's normal into the room).
void Estimator::MarkWindowCells(const Eigen::Vector3d& out) {
  window_cells_.resize(cells_, 0);
  for (int j = 0; j < cells_; ++j)
    if (env_.direction(j).dot(out) > 0) window_cells_[j] = 1;
}

/// The windows the cameras saw as holes (seen_windows.h), found, said and their cells marked
/// once, each hole a portal.
void Estimator::MarkSeenWindows() {
  res_.windows = SeenWindows(bundle_.views, *scene_);
  for (const SeenWindow& w : res_.windows) {
    const std::string line =
        Fmt("a window the cameras saw as a hole (view %d, %d clipped pixels off the mesh, their rays leaving the scene): "
            "at (%.3f, %.3f, %.3f) in a wall facing (%.2f, %.2f, %.2f); the map's cells behind it are the window's",
            w.view, w.pixels, w.centre.x(), w.centre.y(), w.centre.z(), w.normal.x(), w.normal.y(), w.normal.z());
    res_.point_light_choices.push_back(line);
    Progress(line);
    // (its cells are the window's where the prior is chosen; given by the options, as before)
    if (PriorGivenByOptions().empty()) MarkWindowCells(-w.normal);
    if (Portal p; PortalOf(w, bundle_.up, &p)) portals_.push_back(p);
  }
}

namespace {

/// Whether `e` is the glowing pane over the hole whose rectangle is `p` (PanesOverHoles'
/// quad over that rectangle).
bool PaneOver(const EmitterLight& e, const Portal& p) {
  return e.in_a_hole && e.shape && (Centroid(*e.shape) - p.centre).norm() < 1e-3;
}

}  // namespace

void Estimator::SayTheLightThroughWindows() {
  for (const SeenWindow& w : res_.windows) {
    Portal p;
    if (!PortalOf(w, bundle_.up, &p)) continue;
    const Eigen::Vector3d map = PowerThrough(p, w.normal, env_, res_.lighting.map);
    Eigen::Vector3d pane = Eigen::Vector3d::Zero();
    for (const EmitterLight& e : res_.lighting.Of<EmitterLight>())
      if (PaneOver(e, p)) pane += e.Power();
    const std::string line = Fmt(
        "the window seen as a hole at (%.3f, %.3f, %.3f): %.2f x %.2f m; the light through it (image units x m^2 x sr) "
        "%.4g %.4g %.4g from the map, %.4g %.4g %.4g from a glowing pane over it",
        p.centre.x(), p.centre.y(), p.centre.z(), 2 * p.half_u, 2 * p.half_v, map.x(), map.y(), map.z(), pane.x(),
        pane.y(), pane.z());
    res_.point_light_choices.push_back(line);
    Progress(line);
  }
}

void Estimator::WindowCellsBesidePanes() {
  // (once the prior is chosen, by the windows' rule, its weights stay as they were chosen)
  if (window_cells_.empty() || !PriorGivenByOptions().empty() || res_.prior.done) return;
  std::vector<Eigen::Vector3d> outs;
  for (const auto& opening : res_.openings) outs.push_back(-FacingSum(*opening).normalized());
  bool any_paned = false;
  for (const SeenWindow& w : res_.windows) {
    Portal p;
    const bool pane = PortalOf(w, bundle_.up, &p) &&
                      std::any_of(emitters_.begin(), emitters_.end(), [&](const EmitterLight& e) { return PaneOver(e, p); });
    any_paned = any_paned || pane;
    if (!pane) outs.push_back(-w.normal);
  }
  if (!any_paned) return;
  window_cells_.clear();
  for (const Eigen::Vector3d& out : outs) MarkWindowCells(out);
  const std::string line =
      window_cells_.empty()
          ? "the glowing pane over the window seen as a hole holds its light: the map's cells behind it at the given "
            "prior"
          : "the glowing panes over windows seen as holes hold their light: the map's cells behind the other windows' "
            "walls only are the windows'";
  res_.point_light_choices.push_back(line);
  Progress(line);
  if (window_cells_.empty()) UseAlpha(opt_.objective.alpha);
}

/// Before round 1: the windows seen as holes; beside one, the map's cells behind it start at
/// the weakest prior the choice tries (until it chooses), so that a lamp is kept only where
/// it explains the images better than the light through the window, a sky's, extended (the
/// clear-window scan: held at the given prior, round 1 put a lamp in the room that rendered
/// 85 % of the light, and a glowing patch where the light falls).
void Estimator::StartBesideSeenWindows() {
  MarkSeenWindows();
  if (window_cells_.empty() || !PriorGivenByOptions().empty()) return;
  UseAlpha(opt_.objective.alpha * kPriorFactors[std::size(kPriorFactors) - 1]);
}

}  // namespace lp::detail
