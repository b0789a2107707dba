// The estimator's glowing surfaces (docs/method.md, "Glowing surfaces"): the segments of the
// traced mesh that the views see brighter than a white surface would be under the lights so
// far, each proposed as an emitter whose radiance is one more unknown of the linear problem,
// kept when the held-out pixels are fitted better with them.
#include <algorithm>
#include <map>
#include <numeric>
#include <unordered_map>

#include "estimation/estimator_impl.h"

namespace lp::detail {
namespace {

/// A pixel glows when its colour is this many times the render so far and, times its
/// surface's albedo (its de-lit albedo), too: twice as bright as a white surface could be
/// under the lights so far (a scan's albedo comes from the colours seen, and the lights so
/// far from an estimate: a margin against both).
constexpr double kGlowAlbedo = 2.0;
/// ... and it is brighter than this share of the images' mean (a dim surface the estimate
/// leaves dark is not a light).
constexpr double kGlowBrightness = 0.5;
/// Full-resolution pixels a segment must cover to be an emitter (one pixel is noise).
constexpr int kMinEmitterPixels = 16;
/// Glowing triangles whose centres lie in neighbouring cells of this size (metres) are one
/// segment.
constexpr float kJoinCell = 0.05f;
/// The emitters kept at most (and the candidates tried each time), and the share of the
/// whole objective each must take off, the held-out loss rising by no more (as the map's
/// prior asks of a weaker weight).
constexpr std::size_t kMaxEmitterCandidates = 6;
constexpr double kEmitterGain = 0.03;

int Root(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

}  // namespace

/// Per triangle of the traced mesh: the pixels seen glowing on it (and all the pixels that
/// see it), the side they saw it from, what they lack over the render (summed) and the least
/// radiance its clipped pixels show.
struct Estimator::Glow {
  explicit Glow(std::size_t triangles)
      : seen(triangles, 0), looked(triangles, 0), facing(triangles, Eigen::Vector3f::Zero()), glow(triangles, 0.0),
        floor(triangles, Eigen::Vector3d::Zero()) {}
  void Add(const SurfacePoint& hit, const Eigen::Vector3d& dir, double lack) {
    ++seen[hit.triangle];
    facing[hit.triangle] -= dir.cast<float>();
    glow[hit.triangle] += lack;
  }
  /// A triangle glows where most of the pixels that see it do: a few pixels of a large
  /// triangle (a true mesh's wall or floor) that the lights so far render too dark are not
  /// its whole surface glowing.
  void KeepWhereMostGlow() {
    for (std::size_t t = 0; t < seen.size(); ++t)
      if (2 * seen[t] < looked[t]) seen[t] = 0, facing[t].setZero(), glow[t] = 0, floor[t].setZero();
  }
  std::vector<int> seen, looked;
  std::vector<Eigen::Vector3f> facing;
  std::vector<double> glow;
  std::vector<Eigen::Vector3d> floor;
};

Estimator::Glow Estimator::GlowingTriangles() {
  const std::vector<double> render = Plus(A_.Multiply(lambda_), LightsRender(points_, suns_));
  Glow g(scene_->mesh().triangles.size());
  for (std::size_t r = 0; r < A_.rows(); ++r) {
    if (!one_sided_.empty() && one_sided_[3 * r]) continue;  // (a bound: a clipped row, below; bloom's, left out)
    const double y = (y_[3 * r] + y_[3 * r + 1] + y_[3 * r + 2]) / 3,
                 f = std::max(0.0, (render[3 * r] + render[3 * r + 1] + render[3 * r + 2]) / 3);
    const Camera& cam = views_[A_.row_view[r]].camera;
    const Eigen::Vector3d dir = cam.RayDirection(A_.row_pixel[r] % cam.width, A_.row_pixel[r] / cam.width);
    SurfacePoint hit;
    if (!scene_->Intersect(cam.center(), dir, &hit) || hit.triangle < 0) continue;
    ++g.looked[hit.triangle];
    if (!(y > kGlowBrightness) || !(y > kGlowAlbedo * f)) continue;
    // (>=: a surface that reflects nothing, albedo 0 and rendered black, seen bright glows)
    if (hit.albedo.mean() * y >= kGlowAlbedo * f) g.Add(hit, dir, y - f);
  }
  // Pixels the camera clipped glow whatever the render: at least their value (a lower bound
  // on the radiance of what they see).
  for (const View& v : views_) {
    if (v.clipped.size() != v.image.pixels()) continue;
    const Camera& cam = v.camera;
    for (std::size_t p = 0; p < v.clipped.size(); ++p) {
      if (!v.clipped[p]) continue;
      const int x = static_cast<int>(p % cam.width), y = static_cast<int>(p / cam.width);
      const Eigen::Vector3d dir = cam.RayDirection(x, y);
      SurfacePoint hit;
      if (!scene_->Intersect(cam.center(), dir, &hit) || hit.triangle < 0) continue;
      ++g.looked[hit.triangle];
      const float* c = v.image.at(x, y);
      const Eigen::Vector3d value = Eigen::Vector3d(c[0], c[1], c[2]) / res_.image_mean;
      g.Add(hit, dir, value.mean());
      g.floor[hit.triangle] = g.floor[hit.triangle].cwiseMax(value);
    }
  }
  g.KeepWhereMostGlow();
  return g;
}

namespace {

/// Per triangle of `mesh`: its segment (a root triangle), -1 for none. The `seen` triangles
/// joined where they share a vertex or lie within a cell of kJoinCell of each other (a scan's
/// glowing surface is often in pieces: glass and bright cloth return depth in patches), and
/// the triangles of one ring around them that no pixel saw (`looked`: the pixels' centres
/// miss some of a segment's small triangles; one a pixel saw not glowing is not glowing).
/// (Only the holes, the triangles with all three corners on them, took a pixel's width of
/// wall less around the Cycles frosted-window scan's pane, IoU 0.91 -> 0.98, but left the
/// 3DJ recording's curtained window, seen in pieces, a quarter of its area: not kept.)
std::vector<int> Segments(const Mesh& mesh, const std::vector<int>& seen, const std::vector<int>& looked) {
  const std::size_t triangles = mesh.triangles.size();
  std::vector<int> parent(triangles), by_vertex(mesh.positions.size(), -1);
  std::iota(parent.begin(), parent.end(), 0);
  const auto join = [&](int a, int b) { parent[Root(parent, a)] = Root(parent, b); };
  std::unordered_map<std::uint64_t, int> by_cell;  // a seen triangle in each cell of its centroid
  const auto cell = [](const Eigen::Vector3f& p, int dx, int dy, int dz) {
    const auto index = [](float x, int d) {
      return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(x / kJoinCell)) + d + (1 << 20)) & 0x1FFFFF;
    };
    return index(p.x(), dx) | index(p.y(), dy) << 21 | index(p.z(), dz) << 42;
  };
  for (std::size_t t = 0; t < triangles; ++t) {
    if (!seen[t]) continue;
    for (int c = 0; c < 3; ++c) {
      int& v = by_vertex[mesh.triangles[t][c]];
      if (v < 0) v = static_cast<int>(t);
      else join(static_cast<int>(t), v);
    }
    const Eigen::Vector3i& f = mesh.triangles[t];
    const Eigen::Vector3f centroid = (mesh.positions[f[0]] + mesh.positions[f[1]] + mesh.positions[f[2]]) / 3;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz)
          if (const auto it = by_cell.find(cell(centroid, dx, dy, dz)); it != by_cell.end()) join(static_cast<int>(t), it->second);
    by_cell.emplace(cell(centroid, 0, 0, 0), static_cast<int>(t));
  }
  std::vector<int> segment(triangles, -1);
  for (std::size_t t = 0; t < triangles; ++t) {
    if (seen[t]) {
      segment[t] = Root(parent, static_cast<int>(t));
      continue;
    }
    if (looked[t]) continue;
    for (int c = 0; c < 3 && segment[t] < 0; ++c)
      if (const int v = by_vertex[mesh.triangles[t][c]]; v >= 0) segment[t] = Root(parent, v);
  }
  return segment;
}

}  // namespace

std::vector<EmitterLight> Estimator::GlowingSegments() {
  const Mesh& mesh = scene_->mesh();
  const Glow glow = GlowingTriangles();
  triangle_floor_ = glow.floor;
  const std::vector<int> segment = Segments(mesh, glow.seen, glow.looked);
  struct Gathered {
    std::vector<int> triangles;
    std::vector<Eigen::Vector3f> facing;
    int pixels = 0;
    double glow = 0;
    Eigen::Vector3f mean_facing = Eigen::Vector3f::Zero();
    Eigen::Vector3d floor = Eigen::Vector3d::Zero();
  };
  std::map<int, Gathered> found;
  for (std::size_t t = 0; t < segment.size(); ++t)
    if (segment[t] >= 0) {
      Gathered& g = found[segment[t]];
      g.triangles.push_back(static_cast<int>(t));
      g.facing.push_back(glow.facing[t]);
      g.pixels += glow.seen[t];
      g.glow += glow.glow[t];
      g.mean_facing += glow.facing[t];
      g.floor = g.floor.cwiseMax(glow.floor[t]);
    }
  // Each segment with enough pixels (a grid's pixel stands for stride^2) an emitter.
  std::vector<EmitterLight> out;
  for (auto& [root, g] : found) {
    if (g.pixels * stride_ * stride_ < kMinEmitterPixels) continue;
    for (Eigen::Vector3f& f : g.facing)
      if (f.isZero()) f = g.mean_facing;  // (the ring around: the segment's side)
    EmitterLight e;
    e.id = static_cast<int>(out.size());
    e.shape = MakeEmitterShape(mesh, g.triangles, g.facing);
    e.radiance = Eigen::Vector3d::Constant(g.glow / g.pixels).cwiseMax(g.floor);  // a first guess
    if (!(e.Area() > 0)) continue;
    if (!g.floor.isZero()) emitter_floor_[e.shape] = g.floor;
    out.push_back(e);
  }
  return out;
}

std::vector<EmitterLight> Estimator::PanesOverHoles() {
  std::vector<EmitterLight> out;
  for (const SeenWindow& w : res_.windows) {
    Portal p;
    if (!PortalOf(w, bundle_.up, &p)) continue;
    Mesh quad;
    for (const auto& [u, v] : {std::pair{0.0, 0.0}, {1.0, 0.0}, {1.0, 1.0}, {0.0, 1.0}})
      quad.positions.push_back(p.Point(u, v).cast<float>());
    quad.triangles = {{0, 1, 2}, {0, 2, 3}};
    EmitterLight e;
    e.shape = MakeEmitterShape(quad, {0, 1}, std::vector<Eigen::Vector3f>(2, w.normal.cast<float>()));
    e.in_a_hole = true;
    if (!(e.Area() > 0)) continue;
    // What its clipped pixels show, at least (the pixels of the view that saw it whose rays
    // cross its rectangle before they meet anything: not a lamp seen against it).
    const View& v = bundle_.views[w.view];
    const Camera& cam = v.camera;
    Eigen::Vector3d floor = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < v.clipped_off.size(); ++i) {
      double cos = 0;
      const int x = static_cast<int>(i % cam.width), y = static_cast<int>(i / cam.width);
      const Eigen::Vector3d dir = cam.RayDirection(x, y);
      const double at = v.clipped_off[i] ? p.Crossing(cam.center(), dir, &cos) : 0.0;
      SurfacePoint hit;
      if (!(at > 0) || (scene_->Intersect(cam.center(), dir, &hit) && hit.distance < at - 0.05)) continue;
      const float* c = v.image.at(x, y);
      floor = floor.cwiseMax(Eigen::Vector3d(c[0], c[1], c[2]) / res_.image_mean);
    }
    e.radiance = floor;
    if (!floor.isZero()) emitter_floor_[e.shape] = floor;
    out.push_back(e);
  }
  return out;
}

void Estimator::OnBundleMesh(std::vector<Light>* lights) {
  if (cluster_.empty()) return;  // (the bundle's mesh is the traced one)
  const Mesh& full = mesh_.positions.empty() ? bundle_.mesh : mesh_;
  std::vector<std::uint8_t> taken(full.triangles.size(), 0);  // (no triangle glows twice)
  for (Light& l : *lights) {
    EmitterLight* e = std::get_if<EmitterLight>(&l);
    if (!e || !e->shape || e->in_a_hole) continue;  // (a pane over a hole: on no triangle)
    auto on = ShapeOnMesh(full, *e->shape, &taken);
    if (!on) continue;  // (keeps the traced mesh's)
    const double area = e->Area();
    e->shape = std::move(on);
    Progress(Fmt("emitter %d: %zu triangles of the bundle's mesh, %.4g m^2 (%.4g on the traced mesh)", e->id,
                 e->shape->a.size(), e->Area(), area));
  }
  for (auto& opening : res_.openings)
    if (auto on = ShapeOnMesh(full, *opening)) opening = std::move(on);
}

void Estimator::BoundEmitters() {
  for (EmitterLight& e : emitters_)
    if (const auto it = emitter_floor_.find(e.shape); it != emitter_floor_.end())
      e.radiance = e.radiance.cwiseMax(it->second);
}

double Estimator::ObjectiveWith(const std::vector<EmitterLight>& emitters, int iterations) {
  emitters_ = emitters;
  const RoundProblem rp = WithLights(points_);
  return lp::Solve(opt_.solver, Objective(*rp.problem, CellWeights(*rp.problem, res_.objective_params)), rp.init,
                   TrialOptions(iterations))
      .objective;
}

namespace {

/// Where a lamp inside a glowing surface would be (a lamp's shade: the bulb behind what
/// the cameras see glow): behind its centre, against the side it glows on, by half its
/// extent; a surface seen glowing all round (its sides' normals cancel) has it at its centre.
Eigen::Vector3d Inside(const EmitterLight& e) {
  const Eigen::Vector3d facing = FacingSum(*e.shape);
  if (!(e.shape->area > 0)) return Centroid(*e.shape);
  return Centroid(*e.shape) - facing / e.shape->area * 0.5 * std::sqrt(e.Area());
}

}  // namespace

const EmitterLight* Estimator::ShadeOf(const PointLight& lamp) const {
  for (const EmitterLight& e : emitters_)
    if (e.shape && !e.in_a_hole && (lamp.position - Inside(e)).norm() <= 0.5 * std::sqrt(e.Area())) return &e;
  return nullptr;
}

bool Estimator::LampInside(const EmitterLight& candidate, const std::vector<EmitterLight>& with, double* objective,
                           double* held) {
  const Eigen::Vector3d inside = Inside(candidate);
  std::size_t nearest = points_.size();  // (a lamp held where the cameras saw it stays)
  for (std::size_t k = 0; k < points_.size(); ++k)
    if (!points_[k].held && (nearest == points_.size() || (points_[k].position - inside).norm() <
                                                              (points_[nearest].position - inside).norm()))
      nearest = k;
  if (nearest == points_.size()) return false;
  const std::vector<PointLight> before = points_;
  points_[nearest].position = inside;
  const double objective_moved = ObjectiveWith(with), held_moved = HoldoutLoss(points_);
  const bool better = objective_moved < *objective && held_moved < *held;
  Progress(Fmt("point light %zu moved inside the glowing surface, to (%.3f, %.3f, %.3f): objective %.6g, held-out "
               "loss %.6g (%.6g, %.6g where it was): %s",
               nearest, inside.x(), inside.y(), inside.z(), objective_moved, held_moved, *objective, *held,
               better ? "moved" : "left where it was"));
  if (!better) {
    points_ = before;
    return false;
  }
  *objective = objective_moved;
  *held = held_moved;
  return true;
}

std::vector<EmitterLight> Estimator::ApartFrom(const std::vector<EmitterLight>& kept, const EmitterLight& candidate) {
  if (candidate.in_a_hole) return kept;  // (a pane over a hole is on no surface of the mesh)
  const Mesh& mesh = scene_->mesh();
  std::vector<EmitterLight> out;
  for (const EmitterLight& e : kept) {
    if (e.in_a_hole) {
      out.push_back(e);
      continue;
    }
    // The traced mesh's triangles on the kept surface and not on the candidate, and the
    // floor their clipped pixels show.
    std::vector<int> rest;
    std::vector<Eigen::Vector3f> facing;
    Eigen::Vector3d floor = Eigen::Vector3d::Zero();
    bool cut = false;
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      const Eigen::Vector3d centre = TriangleCentre(mesh, t);
      const int on = EmitterTriangleAt(*e.shape, centre);
      if (on < 0) continue;
      if (EmitterTriangleAt(*candidate.shape, centre) >= 0) {
        cut = true;
        continue;
      }
      rest.push_back(static_cast<int>(t));
      facing.push_back(e.shape->normal[on]);
      if (t < triangle_floor_.size()) floor = floor.cwiseMax(triangle_floor_[t]);
    }
    if (!cut) {
      out.push_back(e);
      continue;
    }
    if (rest.empty()) continue;  // (the candidate covers it all)
    EmitterLight apart = e;
    apart.shape = MakeEmitterShape(mesh, rest, facing);
    if (!(apart.Area() > 0)) continue;
    if (!floor.isZero()) emitter_floor_[apart.shape] = floor;
    out.push_back(apart);
  }
  return out;
}

namespace {

/// `emitters` with their ids their places in it.
std::vector<EmitterLight> Numbered(std::vector<EmitterLight> emitters) {
  for (std::size_t k = 0; k < emitters.size(); ++k) emitters[k].id = static_cast<int>(k);
  return emitters;
}

}  // namespace

bool Estimator::TryEmitter(const EmitterLight& candidate, std::vector<EmitterLight>* kept, double* objective,
                           double* held) {
  const bool over_a_hole = candidate.in_a_hole;
  CheckCancel();
  const std::vector<EmitterLight> apart = ApartFrom(*kept, candidate);
  std::vector<EmitterLight> with = apart;
  with.push_back(candidate);
  double objective_with = ObjectiveWith(with), held_with = HoldoutLoss(points_);
  const std::vector<PointLight> lamps = points_;
  if (!over_a_hole) LampInside(candidate, with, &objective_with, &held_with);  // (a bulb behind its shade, if the data says so)
  const bool keep = objective_with < (1 - kEmitterGain) * *objective && held_with < (1 + kEmitterGain) * *held;
  if (!keep) points_ = lamps;  // (a lamp moved inside a surface that is not kept goes back)
  const std::string line =
      Fmt("%s of %.3g m^2 (%s): objective %.6g with it, %.6g without; held-out loss %.6g with it, %.6g without: %s",
          over_a_hole ? "a window seen as a hole, as a glowing pane" : "glowing surface", candidate.Area(),
          over_a_hole ? "frosted glass or a curtain; else the map's light through it"
                      : "seen brighter than a white surface under the lights",
          objective_with, *objective, held_with, *held, keep ? "kept" : "left out");
  res_.point_light_choices.push_back(line);
  Progress(line);
  // A window's clear glass: the surface as an opening instead, where it could be one (not
  // a surface seen glowing again where a kept one lies: that one's own trial decided). The
  // opening's side has the kept emitters apart from it; the closed side is the trial's.
  const Eigen::Vector3d centre = Centroid(*candidate.shape);
  const bool on_kept = std::any_of(kept->begin(), kept->end(), [&](const EmitterLight& e) {
    return e.shape && EmitterTriangleAt(*e.shape, centre) >= 0;
  });
  emitters_ = apart;
  if (!over_a_hole && !on_kept && TryOpening(candidate, keep ? with : *kept, objective, held)) {
    points_ = lamps;  // (no lamp inside an opening)
    *kept = Numbered(apart);
    return true;
  }
  emitters_ = *kept;
  if (!keep) return false;
  *kept = Numbered(with);
  *objective = objective_with;
  *held = held_with;
  return true;
}

bool Estimator::ProposeEmitters(RoundInfo* info) {
  emitters_sought_ = true;
  // One at a time, brightest first (the most each pixel lacks: a lamp's shade before the
  // wall it lights), each kept when, beside those kept before, the whole objective (every
  // pixel, the activation penalty included) falls by kEmitterGain and the held-out pixels
  // are fitted no worse by that much; once one is kept the lights are solved with it and the
  // glowing pixels sought again (a wall the kept one lights glows no more).
  // The windows seen as holes are candidates too, as glowing panes over their openings.
  std::vector<EmitterLight> kept;
  const std::vector<EmitterLight> panes = PanesOverHoles();
  double objective = ObjectiveWith({}), held = HoldoutLoss(points_);
  for (std::size_t k = 0; k < kMaxEmitterCandidates; ++k) {
    std::vector<EmitterLight> found = GlowingSegments();
    for (const EmitterLight& p : panes)
      if (std::none_of(kept.begin(), kept.end(), [&](const EmitterLight& e) { return e.shape == p.shape; }))
        found.push_back(p);
    std::sort(found.begin(), found.end(),
              [](const EmitterLight& a, const EmitterLight& b) { return a.radiance.sum() > b.radiance.sum(); });
    bool more = false;
    for (std::size_t i = 0; i < found.size() && i < kMaxEmitterCandidates && !more; ++i)
      more = TryEmitter(found[i], &kept, &objective, &held);
    emitters_ = kept;
    if (!more) break;
    solve_step_ = "emitters";  // (a new model: a new descent)
    SolveWithLights(&points_, info, false);  // their radiance beside the map and the other lights
    solve_step_ = "solve";
    kept = emitters_;
  }
  for (auto it = emitter_floor_.begin(); it != emitter_floor_.end();)  // (the candidates left out)
    it = std::any_of(kept.begin(), kept.end(), [&](const EmitterLight& e) { return e.shape == it->first; })
             ? std::next(it)
             : emitter_floor_.erase(it);
  WindowCellsBesidePanes();
  if (!kept.empty()) ReselectLamps(info);
  return !kept.empty();
}

/// The lamps chosen before the glowing surfaces were found, chosen again beside them (the
/// held-out pixels, SelectModel's rule): a lamp round 1 placed to light what a window lights
/// stayed (the Cycles frosted-window scan: a lamp outside the room's open side rendering a
/// fifth of the light beside the pane).
void Estimator::ReselectLamps(RoundInfo* info) {
  if (points_.empty()) return;
  std::vector<PointLight> lamps = points_;
  const std::size_t before = lamps.size();
  SelectModel(&lamps);
  if (lamps.size() == before) return;
  points_ = lamps;
  SolveWithLights(&points_, info, false);  // (the map and the glowing surfaces take the dropped lamps' light)
}

}  // namespace lp::detail
