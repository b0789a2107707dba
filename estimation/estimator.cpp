#include "estimation/estimator.h"

#include "estimation/estimator_impl.h"

#include <utility>

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

}  // namespace lp

namespace lp::detail {
namespace {

bool Flagged(const std::vector<std::uint8_t>& flags, std::size_t p) { return p < flags.size() && flags[p]; }

/// Whether a pixel within kBloomMargin of (x, y) in a w x h view is `flagged`.
template <typename Flag>
bool Beside(int x, int y, int w, int h, const Flag& flagged) {
  for (int dy = -kBloomMargin; dy <= kBloomMargin; ++dy)
    for (int dx = -kBloomMargin; dx <= kBloomMargin; ++dx) {
      const int nx = x + dx, ny = y + dy;
      if ((dx || dy) && nx >= 0 && ny >= 0 && nx < w && ny < h && flagged(static_cast<std::size_t>(ny) * w + nx))
        return true;
    }
  return false;
}

/// Whether pixel p of view v is beside (kBloomMargin) a pixel clipped on or off the mesh.
bool BesideAClippedPixel(const View& v, std::size_t p) {
  const int w = v.camera.width, h = v.camera.height;
  const auto any = [&](std::size_t q) { return Flagged(v.clipped, q) || Flagged(v.clipped_off, q); };
  return Beside(static_cast<int>(p % w), static_cast<int>(p / w), w, h, any);
}

/// The pixels clipped on the mesh (on the grid of `stride`) become rows, except beside a
/// pixel clipped off it (a bulb's partly covered pixels on the wall behind it). The valid
/// pixels beside any clipped pixel stay rows, as upper bounds (ClippedEntries: bloom only
/// brightens). Returns {clipped rows, rows beside them}.
std::pair<int, int> ClippedAsRows(View* v, int stride) {
  const int w = v->camera.width, h = v->camera.height;
  if (v->clipped.empty() && v->clipped_off.empty()) return {0, 0};
  const auto off = [&](std::size_t q) { return Flagged(v->clipped_off, q); };
  std::vector<std::uint8_t> valid = v->valid;
  int rows = 0, beside = 0;
  for (std::size_t p = 0; p < valid.size(); ++p) {
    const int x = static_cast<int>(p % w), y = static_cast<int>(p / w);
    if (Flagged(v->clipped, p)) {
      valid[p] = OnGrid(p, w, stride) && !Flagged(v->clipped_off, p) && !Beside(x, y, w, h, off);
      rows += valid[p];
    } else if (valid[p] && BesideAClippedPixel(*v, p)) {
      ++beside;
    }
  }
  v->valid = std::move(valid);
  return {rows, beside};
}

/// Per entry of the observations of `views` (CollectObservations' order), how it bounds the
/// render (Bound): a clipped pixel's value is a lower bound; a pixel beside one an upper
/// bound (the bloom and flare of the light beside it may have brightened it; they never
/// darken); any other is exact.
std::vector<std::uint8_t> ClippedEntries(const std::vector<View>& views) {
  std::vector<std::uint8_t> out;
  for (const View& v : views)
    for (std::size_t p = 0; p < v.valid.size(); ++p)
      if (v.valid[p])
        out.insert(out.end(), 3,
                   Flagged(v.clipped, p) ? kAtLeast : BesideAClippedPixel(v, p) ? kAtMost : kExact);
  return out;
}

/// The rounds' uncertainty (`u`, of the lights `before`) carried to the polished lights
/// (`after`): the polish moves a lamp by millimetres, a small part of its region, so the
/// region is kept; an intensity's standard deviation keeps its share of the intensity. Computed
/// again where the polish dropped a light.
std::optional<std::vector<LightUncertainty>> CarriedTo(std::vector<LightUncertainty> u,
                                                       const std::vector<Light>& before,
                                                       const std::vector<Light>& after) {
  if (u.size() != before.size() || before.size() != after.size()) return std::nullopt;
  for (std::size_t k = 0; k < u.size(); ++k) {
    if (before[k].index() != after[k].index()) return std::nullopt;
    for (int c = 0; c < 3; ++c)
      if (Scale(before[k])[c] > 0) u[k].scale_sigma[c] *= Scale(after[k])[c] / Scale(before[k])[c];
  }
  return u;
}

}  // namespace

/// PolishSpp's uncertainty carried to the lights now (CarriedTo), or computed again.
std::vector<LightUncertainty> Estimator::Carried(const std::vector<LightUncertainty>& rounds,
                                                 const std::vector<Light>& before, const std::vector<Light>& now) {
  std::optional<std::vector<LightUncertainty>> u = CarriedTo(rounds, before, now);
  return u ? *u : Uncertainty();
}

Estimator::Estimator(const SceneBundle& bundle, const EstimateOptions& options, double albedo_scale)
    : bundle_(bundle), opt_(options), env_(res_.env), alpha_(options.objective.alpha) {
  Validate(opt_);
  res_.albedo_scale = albedo_scale;
  res_.env = EnvMap(opt_.rings, bundle_.up);
  cells_ = env_.size();
  adjacency_ = env_.Adjacency();
  Observe();
  Stopwatch bvh;
  scene_ = std::make_unique<RayTracer>(TracedMesh());
  res_.bvh_seconds = bvh.Seconds();
  // The scene's centre and size are the bundle's mesh's (TruthScorer's measures use them too).
  BoundingSphere(bundle_.mesh, &centre_, &radius_);
  res_.scene_centre = centre_;
  // Start dark and uniform (paper): every cell equally likely to be sampled.
  lambda_.assign(3 * cells_, 1e-3);
  reachable_.assign(cells_, 1);
  StartBesideSeenWindows();
  if (opt_.warm) StartWarm(*opt_.warm);
}

/// A live estimate's first map (WarmStart): the last one's, each cell from the cell of the
/// last map its direction falls in, each directional light's irradiance in its cell as
/// radiance (E = L x the cell's solid angle), over this estimate's image mean (the rounds'
/// units), at least the cold start's 1e-3.
void Estimator::StartWarm(const WarmStart& warm) {
  const EnvMap before(std::clamp(warm.rings, kMinRings, kMaxRings), warm.up.normalized());
  if (warm.lighting.map.size() != 3 * static_cast<std::size_t>(before.size())) return;
  std::vector<double> map = warm.lighting.map;
  for (const DirectionalLight& d : warm.lighting.Of<DirectionalLight>()) {
    const int j = before.Lookup(d.direction);
    for (int c = 0; c < 3; ++c) map[3 * j + c] += d.irradiance[c] / before.solid_angle(j);
  }
  for (int j = 0; j < cells_; ++j) {
    const int k = before.Lookup(env_.direction(j));
    for (int c = 0; c < 3; ++c) lambda_[3 * j + c] = std::max(1e-3, map[3 * k + c] / res_.image_mean);
  }
  warm_ = true;
  Progress(Fmt("warm start: the last estimate's map (%d cells) and %zu light(s)", before.size(),
               warm.lighting.lights.size()));
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
  res_.clipped_rows = res_.bloom_rows = 0;
  if (opt_.clipped_rows)
    for (View& v : views_) {
      const auto [rows, left] = ClippedAsRows(&v, stride);
      res_.clipped_rows += rows;
      res_.bloom_rows += left;
    }
  if (res_.clipped_rows + res_.bloom_rows > 0)
    Progress(Fmt("%d pixels clipped on the mesh fitted as lower bounds; %d beside clipped pixels as upper bounds (bloom)",
                 res_.clipped_rows, res_.bloom_rows));
  y_ = CollectObservations(views_);
  for (double& v : y_) v /= res_.image_mean;
  one_sided_ = res_.clipped_rows + res_.bloom_rows > 0 ? ClippedEntries(views_) : std::vector<std::uint8_t>();
  // alpha is given per 19,200 observed pixels (one 160x120 view): the data term grows with
  // the number of observations, and so must the penalty, or the balance between them
  // (how many cells light the scene) would change with resolution and view count.
  UseAlpha(alpha_);
  A_ = TransportMatrix();
  vertices_ = ShadingVertices();
  columns_.clear();
  row_segment_.clear();
  holdout_.clear();
  holdout_fit_.reset();
}

/// The rounds from `round` on fit the pixels on a grid of `stride` (UseViews); `round`, when
/// it is the first past round 1's grid, is marked so (after_grid_: its shading vertices
/// take twice the paths, and a sun is sought in it).
void Estimator::UseStride(int stride, int round) {
  if (round > 1 && stride_ > 1 && after_grid_ == 0) after_grid_ = round;
  UseViews(stride);
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

/// The grid of the rounds after round 1 and before the first albedo pass (where one is to
/// come): opt_.pre_albedo_stride, at most round 1's; 1 after it, or with no pass to come.
int Estimator::PreAlbedoStride() const {
  const bool pass_ahead = res_.albedo_passes == 0 && res_.albedo_left_out == AlbedoLeftOut::kRefined &&
                          AlbedoLeftOutByOptions() == AlbedoLeftOut::kRefined;
  return pass_ahead ? std::min(opt_.pre_albedo_stride, FirstRoundStride()) : 1;
}

void Estimator::RunRounds() {
  const int first = static_cast<int>(res_.rounds.size()) + 1, last = first + opt_.max_rounds - 1;
  int since = first;  // the first round on the current pixels and albedo
  for (int round = first; round <= last; ++round) {
    CheckCancel();
    const int stride = round == 1 ? FirstRoundStride() : PreAlbedoStride();
    // The first round past round 1's grid starts afresh, on another grid or none.
    if (stride != stride_ || (round > 1 && stride_ > 1 && after_grid_ == 0)) {
      UseStride(stride, round);
      since = round;
    }
    RoundInfo info;
    info.round = round_ = round;
    const RoundProblem rp = TraceRound(round, since, &info);
    const SolveResult sr = Solve(rp, round, &info, round == 1);
    const std::vector<double> full = TakeSolution(rp, sr, &info);
    if (round == 1 && !warm_ && opt_.on_first_solve) opt_.on_first_solve(InImageUnits(), env_);
    FitLights(rp, full, &info);
    // A changed prior is solved again in its round; one more round follows it (the transport
    // was sampled for the old prior's map). Beside lamps it refits them under the new prior:
    // ended by the change alone, lamp-and-sky's lamp came back 0.2 -> 0.7 cm off, seed 5's
    // 0.4 -> 1.3 cm (docs/benchmarks.md, session 43).
    // (a weight restored where the choice was left out also needs a round at it)
    const bool prior_changed = (PriorRound(round, last) && ChoosePrior(&info)) || std::exchange(prior_restored_, false);
    EndRound(sr, &info);
    const bool prior_ahead = PriorAhead();
    // Beside a window the map must settle too: the views hardly see the cells that light the
    // room only through it, which keep moving while the fitted image does not (Cycles' glazed
    // window: the map 21, 12, 9.5 % a round, the image 0.5, 0.3, 0.2 %; the held-out view
    // relit 1.33, 1.13, 1.05 times the true world's error after rounds 2-4). On the scenes
    // measured it did not settle below --change: the rounds ran to --max-rounds.
    const bool map_moving = !window_cells_.empty() && info.change >= opt_.change_threshold;
    if (round > first && info.image_change < opt_.change_threshold && !info.lights_moved && !prior_changed &&
        !prior_ahead && !map_moving)
      break;
  }
  if (!res_.prior.done) {
    res_.prior.done = true;
    KeepTheGivenPrior();  // (for the rounds after an albedo pass)
    res_.prior.why = Fmt("the rounds ended (--rounds %d) before the round that chooses the map's prior: the given --alpha",
                         opt_.max_rounds);
  }
}

std::vector<double> Estimator::Residuals(const std::vector<double>& y, const std::vector<double>& render,
                                         const std::vector<std::uint8_t>* keep) const {
  std::vector<double> r(y.size());
  for (std::size_t i = 0; i < r.size(); ++i) r[i] = y[i] - render[i];
  std::size_t i = 0;  // the entries of r, in order
  for (std::size_t row = 0; row < one_sided_.size() / 3 && i < r.size(); ++row) {
    if (keep && !(*keep)[row]) continue;
    for (int c = 0; c < 3; ++c, ++i)
      r[i] = BoundedResidual(one_sided_[3 * row + c], r[i]);
  }
  return r;
}

std::vector<std::uint8_t> Estimator::OneSidedRows(const std::vector<std::uint8_t>& keep, bool want) const {
  std::vector<std::uint8_t> out;
  for (std::size_t row = 0; row < keep.size() && !one_sided_.empty(); ++row)
    if (static_cast<bool>(keep[row]) == want) out.insert(out.end(), &one_sided_[3 * row], &one_sided_[3 * row] + 3);
  return out;
}

/// Whether this round (of `last`) chooses the map's prior (once): beside lamps the
/// kPriorRound-th on every pixel, after they were refined there (refined once, a far lamp was
/// still 7-8 cm off, a weak prior's sky that is not there took up its error, and the lamp
/// followed it: docs/method.md, "The map's prior"), or the last but one, so that a round can follow the
/// choice; without lamps the first on every pixel. Until then, where it will not be chosen
/// that is said at once (the rounds then need not wait for it).
bool Estimator::PriorRound(int round, int last) {
  if (!PriorAhead()) return false;
  if (points_.empty() || ++rounds_past_grid_ >= kPriorRound || round + 1 >= last) return true;
  res_.prior.why = PriorLeftOut(ColumnOrder(points_));
  res_.prior.done = !res_.prior.why.empty();
  if (res_.prior.done) KeepTheGivenPrior();
  return false;
}

/// Traces A with importance from the estimate so far (uniform in round 1), averages it
/// with the rounds before under the same albedo, and makes the round's problem.
RoundProblem Estimator::TraceRound(int round, int first, RoundInfo* info) {
  Stopwatch ts;
  const CellSampler sampler = Sampler(round == 1 && !warm_ ? std::vector<double>() : lambda_, reachable_);
  const TracerOptions topt = MapTracer(round, 0);
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
  // A round that looks for a directional light gathers them where the map so far holds half
  // the share the light's proposal will ask of this round's map: round 1's map, on a grid of
  // the pixels and sampled uniformly, is more spread (sun-and-sky's seed 8: 0.225 there,
  // 0.43 after round 2's solve; without the vertices no light was tried).
  const bool sun = SunRound(round) && BrightestNeighbourhood().second >= 0.5 * opt_.directional.min_map_share;
  if ((NearLights() && round == 1) || sun || !points_.empty() || !suns_.empty() || !emitters_.empty())
    GatherVertices(round, first);
  RoundProblem rp = WithLights(points_);
  Progress(Fmt("round %d: A traced at %d samples per pixel in %.2f s", round, topt.spp, trace_a) +
           Fmt(", combined and its normal matrices in %.2f s, the lights' vertices and columns in %.2f s",
               normal - trace_a, ts.Seconds() - normal));
  info->trace_seconds = ts.Seconds();
  info->nonzeros = static_cast<std::int64_t>(rp.problem->col.size());
  const LinearProblem& problem = *rp.problem;
  info->unknown_cells = static_cast<int>(  // the map's (the lights' columns are unknowns too)
      std::count_if(problem.cell_of.begin(), problem.cell_of.end(), [&](int j) { return j < cells_; }));
  MarkReachable(problem);
  Progress(Fmt("round %d: traced in %.2f s, %d unknown cells of ", round, info->trace_seconds,
               info->unknown_cells) +
           std::to_string(cells_) + ", " + std::to_string(A_.nonzeros()) + " non-zeros");
  if (info->unknown_cells == 0)
    throw InputError(SceneFile(), "no sampled path reaches the environment (camera inside closed geometry?)");
  return rp;
}

/// The map's tracer options in `round`: its samples, a seed of its own (`stream` apart from
/// the round's trace, 0), the cancel flag (a cancelled trace stops within 64 pixels).
TracerOptions Estimator::MapTracer(int round, std::uint64_t stream) const {
  TracerOptions topt = opt_.tracer;
  topt.seed = opt_.tracer.seed * 1000003ull + stream + round;
  topt.cancelled = opt_.cancelled;
  topt.spp = MapSamples(round);
  return topt;
}

/// Cells no sampled path of `problem` reached are not unknowns, and are not sampled again.
void Estimator::MarkReachable(const LinearProblem& problem) {
  std::fill(reachable_.begin(), reachable_.end(), 0);
  for (int j : problem.cell_of)
    if (j < cells_) reachable_[j] = 1;
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
/// that proportion: a map that renders half the light or more gets them all), at least
/// kMinMapSamples of them (a map left dark can still take light back; an eighth left
/// lamp-and-sky's and lamp-4m's map short of their skies on some seeds: docs/benchmarks.md).
int Estimator::MapSamples(int round) const {
  const int spp = opt_.tracer.spp;
  if (round == 1) return spp;
  const double share = std::clamp(2 * map_share_, kMinMapSamples, 1.0);
  return std::max(1, static_cast<int>(std::lround(share * spp)));
}

/// A_'s problem and its normal matrices, built once per round: the round's solves append
/// the lights' columns to it (WithColumns), so G is summed again only for those.
void Estimator::MakeMapProblem() {
  map_problem_ = std::make_shared<LinearProblem>(MakeLinearProblem(A_, y_));
  map_problem_->one_sided = one_sided_;
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
  // the paths (what rounds 1 and 2 hold on every pixel: noise in a column biases its
  // intensity low; docs/method.md).
  const int spp = opt_.point_lights.spp;
  topt.spp = round == 1 && stride_ > 1 ? std::max(1, spp / 2) : round == after_grid_ ? 2 * spp : spp;
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

/// Solves the round's problem warm-started, logging every iteration. Graduated Cauchy
/// scale: from the cold start (round 1, a dark map) every residual is about the mean
/// pixel; with a small sigma that is the loss's flat tail, where the activation penalty
/// outweighs the data and the all-zero map is a local minimum (sigma = 0.1 lit nothing
/// on the demo). Round 1 solves at kGraduatedSigmaStart first and halves the scale down
/// to sigma, each solve warm-started from the last.
/// The activation penalty's per-unknown weights: a cell's solid angle over the reference
/// one, a point light's PointLightOptions::weight. Under a map's prior weaker than the given
/// one (`prior`, as EstimateOptions' alpha; 0: alpha_), the lights and the map's cells
/// within 2.5 ring spacings of a light's direction (a lamp's from the scene's centre) or in
/// sparse_cells_, and beside a window (an opening or a hole seen) those not behind one (window_cells_), keep
/// the given weight: those cells' columns are nearly the light's (a far
/// lamp's too), and a weak prior there lets the map take its power or spread a compact light
/// (docs/method.md, "The map's prior").
ObjectiveParams Estimator::CellWeights(const LinearProblem& problem, ObjectiveParams params, double prior) const {
  const double keep = std::max(1.0, opt_.objective.alpha / (prior > 0 ? prior : alpha_));
  const double reach = std::cos(2.5 * kPi / env_.rings());
  params.cell_weight.resize(problem.unknown_cells);
  for (int k = 0; k < problem.unknown_cells; ++k) {
    const int j = problem.cell_of[k];
    if (j >= cells_) {
      params.cell_weight[k] = opt_.point_lights.weight * keep;
      continue;
    }
    params.cell_weight[k] = env_.solid_angle(j) / kAlphaReferenceSolidAngle;
    if (keep == 1) continue;
    bool near = !sparse_cells_.empty() && sparse_cells_[j];
    for (const DirectionalLight& d : suns_) near = near || env_.direction(j).dot(d.direction) > reach;
    for (const PointLight& p : points_) near = near || env_.direction(j).dot((p.position - centre_).normalized()) > reach;
    near = near || (!window_cells_.empty() && !window_cells_[j]);  // (beside a window: its cells alone)
    if (near) params.cell_weight[k] *= keep;
  }
  if (params.smooth > 0) params = WithSmoothness(problem, params);
  return params;
}

/// `params` with the map's smoothness between the problem's neighbouring cells, its weight
/// params.smooth times the median curvature of a cell's data term (sum_r A_rj^2): so a
/// weight means the same for any pixel count, exposure or albedo.
ObjectiveParams Estimator::WithSmoothness(const LinearProblem& problem, ObjectiveParams params) const {
  std::vector<int> compact(cells_, -1);
  std::vector<double> curvature;
  for (int k = 0; k < problem.unknown_cells; ++k) {
    if (problem.cell_of[k] >= cells_) continue;
    compact[problem.cell_of[k]] = k;
    double g = 0;
    for (std::int64_t q = problem.col_start[k]; q < problem.col_start[k + 1]; ++q)
      for (int c = 0; c < 3; ++c) g += double(problem.col_val[q][c]) * problem.col_val[q][c] / 3;
    curvature.push_back(g);
  }
  if (curvature.empty()) return params;
  std::nth_element(curvature.begin(), curvature.begin() + curvature.size() / 2, curvature.end());
  params.smooth *= curvature[curvature.size() / 2];
  params.neighbours.clear();
  for (const EnvMap::Neighbours& e : adjacency_)
    if (compact[e.a] >= 0 && compact[e.b] >= 0) params.neighbours.push_back({compact[e.a], compact[e.b], e.weight});
  return params;
}

/// A convergence row's scores against truth.json (and how many point lights it has).
void Estimator::Score(ConvergenceRow* row, const Lighting& lighting) const {
  row->point_lights = static_cast<int>(lighting.Count<PointLight>());
  if (opt_.scorer) opt_.scorer->Score(row, env_, lighting);
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
    row.step = solve_step_;
    row.objective = it.objective;
    row.relative_rmse = it.Rmse();
    row.photometric_rmse = row.relative_rmse * res_.image_mean;
    const std::vector<double> full = rp.Scatter(*it.lambda, cells_);
    Score(&row, {std::vector<double>(full.begin(), full.begin() + 3 * cells_),
                 Joined(suns_, rp.Lit<PointLight>(full, cells_))});
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

/// `lambda` (the round's problem's unknowns) with each emitter's radiance raised to its
/// floor (emitter_floor_).
std::vector<double> Estimator::Bounded(const RoundProblem& rp, std::vector<double> lambda) const {
  const LinearProblem& problem = *rp.problem;
  for (int k = 0; k < problem.unknown_cells; ++k) {
    const int j = problem.cell_of[k];
    if (j < cells_) continue;
    const auto* e = std::get_if<EmitterLight>(&rp.lights[j - cells_]);
    if (!e) continue;
    if (const auto it = emitter_floor_.find(e->shape); it != emitter_floor_.end())
      for (int c = 0; c < 3; ++c) lambda[3 * k + c] = std::max(lambda[3 * k + c], it->second[c]);
  }
  return lambda;
}

/// Takes the round's solution as the estimate (the map and the directional lights): how
/// much it changed, in the map and in the images. Returns the whole solution (the map's
/// cells, then each light's scale).
std::vector<double> Estimator::TakeSolution(const RoundProblem& rp, const SolveResult& sr, RoundInfo* info) {
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
  // What is taken: the emitters' radiance at least what their clipped pixels show (as
  // BoundEmitters sets it; the solve does not know the floor, and a change measured before
  // it was the drop below the floor every round: 70-84 % on the 3DJ recording, whose rounds
  // then never ended before --max-rounds).
  const std::vector<double> taken = Bounded(rp, sr.lambda);
  std::vector<double> delta(taken.size()), a_delta, a_new;
  for (std::size_t i = 0; i < delta.size(); ++i) delta[i] = taken[i] - rp.init[i];
  rp.problem->Multiply(delta, &a_delta);
  rp.problem->Multiply(taken, &a_new);
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
  if (rp.Has<EmitterLight>()) {
    emitters_ = rp.Lit<EmitterLight>(full, cells_);
    BoundEmitters();
  }
  return full;
}

/// The lights after a round's solve (docs/method.md): the lamps (round 1: sought; later:
/// refined from the solve's), then a directional light where the round seeks one.
void Estimator::FitLights(const RoundProblem& rp, const std::vector<double>& full, RoundInfo* info) {
  if (NearLights() && (info->round == 1 || !points_.empty())) info->lights_moved = FitPointLights(rp, full, info);
  if (SunRound(info->round) && FitDirectionalLight(info)) info->lights_moved = true;
  if (EmitterRound() && ProposeEmitters(info)) info->lights_moved = true;
}

/// The round's record (in image units), its callback and its progress line.
void Estimator::EndRound(const SolveResult& sr, RoundInfo* info) {
  map_share_ = MapShare();
  info->lighting = InImageUnits();
  info->end_seconds = Now();
  res_.kkt_violation = sr.kkt_violation;
  res_.rounds.push_back(*info);
  if (opt_.on_round) opt_.on_round(*info, env_);
  Progress("round " + std::to_string(info->round) + ": " + ToString(opt_.solver) + " solver, " +
           Fmt("%d iterations in %.2f s, objective %.6g, change %.3g", sr.iterations, info->solve_seconds,
               sr.objective, info->change) +
           Fmt(" (in the image %.3g)", info->image_change) + Fmt(", KKT violation %.2g", sr.kkt_violation));
}

void Estimator::Conclude() {
  RelaxPrior();
  if (res_.albedo_passes > 0) res_.albedo = mesh_.albedo;
  else if (res_.albedo_scale != 1) res_.albedo = bundle_.mesh.albedo;  // the scaled albedo the lights go with
  res_.left_out.assign(cells_, 0);
  for (int j = 0; j < cells_; ++j) res_.left_out[j] = !reachable_[j];
  // Left to the estimate, the lamps are polished where the uncertainty at the rounds' end says
  // their paths limit them (a scan's always, the uncertainty computed after it).
  std::optional<std::vector<LightUncertainty>> rounds;  // where PolishSpp judged by it
  const std::vector<Light> before = Lights();
  PolishLamps(PolishSpp(&rounds));
  const std::vector<LightUncertainty> uncertainty = rounds ? Carried(*rounds, before, Lights()) : Uncertainty();
  SayUncertainty(uncertainty);
  res_.lighting = InImageUnits();
  res_.uncertainty = uncertainty;
  OnBundleMesh(&res_.lighting.lights);
  SayTheLightThroughWindows();
  for (LightUncertainty& u : res_.uncertainty) u.scale_sigma *= res_.image_mean;
  // The rounds' last error (the polish's rows are on its own fresh vertices: another measure;
  // a trial's rows, such as the prior's folds after a last round's solve, are its own problem's).
  for (auto row = res_.convergence.rbegin(); row != res_.convergence.rend(); ++row)
    if (std::string(row->step) != "polish" && std::string(row->step) != "trial") {
      res_.final_relative_rmse = row->relative_rmse;
      break;
    }
  res_.final_rmse = res_.final_relative_rmse * res_.image_mean;
  if (opt_.scorer) opt_.scorer->Conclude(&res_);
  res_.dominant = DominantDirections(env_, res_.lighting.map, res_.lighting.Of<DirectionalLight>(), 2);
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

/// The polish's paths (0: none): PointLightOptions::polish_spp where given; left to the
/// estimate (-1), kPolishSpp on a scan and where a lamp's paths_ratio in the uncertainty at
/// the rounds' end (computed here, kept in `rounds`) is at least kPolishPathsRatio, said with why.
int Estimator::PolishSpp(std::optional<std::vector<LightUncertainty>>* rounds) {
  if (opt_.point_lights.polish_spp >= 0) return opt_.point_lights.polish_spp;
  if (res_.albedo_passes > 0) return kPolishSpp;
  if (points_.empty()) return 0;
  *rounds = Uncertainty();
  double most = 0;
  for (const LightUncertainty& u : **rounds) most = std::max(most, u.paths_ratio);
  const bool polish = most >= kPolishPathsRatio;
  const std::string line =
      Fmt("the lamps %s: where a lamp's place is least sure from its columns' paths, their noise is %.3g times the "
          "images' (%s %g)",
          polish ? "polished on fresh paths" : "not polished", most, polish ? "at least" : "under", kPolishPathsRatio);
  res_.point_light_choices.push_back(line);
  Progress(line);
  return polish ? kPolishSpp : 0;
}

/// The lamps refined once more after the last round on fresh shading vertices of `spp`
/// paths on every n-th row (kShadowRows of them), the rest of the image held and the fit
/// debiased: the rounds' vertices hold few paths, and their noise pulls a lamp along its
/// ray (docs/method.md, "The lamps polished"). False where it does not run.
bool Estimator::PolishLamps(int spp) {
  if (spp <= 0 || points_.empty() || vertices_.rows() != A_.rows()) return false;
  if (std::all_of(points_.begin(), points_.end(), [](const PointLight& l) { return l.held; })) return false;
  CheckCancel();
  Stopwatch watch;
  // The rows, observations, rest of the image and albedo segments of LightFitSubset's share;
  // the vertices fresh ones of those rows.
  const std::vector<double> all_base = Plus(A_.Multiply(lambda_), LightsRender({}, suns_));
  LightFitSubset share(FitProblem(&all_base), kShadowRows);
  const std::size_t stride = static_cast<std::size_t>(share.stride);
  std::vector<View> views = views_;
  for (std::size_t r = 0; r < A_.rows(); ++r)
    if (r % stride != 0) views[A_.row_view[r]].valid[A_.row_pixel[r]] = 0;
  TracerOptions topt = opt_.tracer;
  topt.cancelled = opt_.cancelled;
  topt.spp = spp;
  topt.seed = opt_.tracer.seed * 1000003ull + 977;
  const ShadingVertices fresh = GatherShadingVertices(*scene_, views, topt);
  const double traced = watch.Seconds();
  CheckCancel();
  LightFitProblem& fit = share.problem;
  LP_CHECK(fresh.rows() * 3 == fit.y->size(), "the polish's rows");
  fit.vertices = &fresh;
  fit.debiased = true;
  // Each accepted step a convergence row (step "polish"; its objective and error are the
  // polish's rows' times the stride, on its own vertices: not continuous with the rounds').
  const RoundInfo info = res_.rounds.empty() ? RoundInfo{} : res_.rounds.back();
  const auto log = [&](int, double E, double sse, const std::vector<Light>& now) {
    ConvergenceRow row = LightRow(info, fit.loss.sigma, E * stride, sse * stride);
    row.step = "polish";
    Score(&row, {lambda_, Joined(suns_, OfKind<PointLight>(now))});
    Push(row);
  };
  std::vector<Light> moving = AsLights(points_);
  const int iterations = RefineLights(fit, &moving, 12, log, kPolishMinDrop);
  CompassOptions compass;
  compass.start = 0.01;
  compass.stop = 0.002;
  compass.max_evaluations = 12;
  // (where the albedo is known, Levenberg-Marquardt alone: the compass's steps of 1 % of the
  // distance moved a far lamp on along its ray, where the images, not the paths, limit it)
  const int moves = res_.albedo_passes > 0 ? SearchLights(fit, &moving, centre_, compass, log) : 0;
  const std::vector<PointLight> polished = OfKind<PointLight>(moving);
  double moved = 0;
  for (std::size_t k = 0; k < polished.size(); ++k)
    moved = std::max(moved, (polished[k].position - points_[k].position).norm());
  points_.clear();  // (a lamp the polish left dark is dropped)
  for (const PointLight& l : polished)
    if (l.intensity.maxCoeff() > 0) points_.push_back(l);
  const std::string line = Fmt("lamps polished on %zu rows at %d fresh paths a pixel: %d iterations, %d compass moves, "
                               "moved at most %.3g m in %.2f s (traced in %.2f s)",
                               fresh.rows(), topt.spp, iterations, moves, moved, watch.Seconds(), traced);
  res_.point_light_choices.push_back(line);
  Progress(line);
  return true;
}

std::vector<int> Estimator::RowBlocks(int across) const {
  std::vector<int> block(A_.rows());
  for (std::size_t r = 0; r < A_.rows(); ++r) {
    const Camera& cam = bundle_.views[A_.row_view[r]].camera;
    const int x = A_.row_pixel[r] % cam.width, y = A_.row_pixel[r] / cam.width;
    const int bw = (cam.width + across - 1) / across, bh = (cam.height + across - 1) / across;
    block[r] = (A_.row_view[r] * across + y / bh) * across + x / bw;
  }
  return block;
}

std::vector<LightUncertainty> Estimator::Uncertainty() {
  const std::vector<Light> lights = Lights();
  if (lights.empty() || vertices_.rows() * 3 != y_.size() || A_.rows() * 3 != y_.size()) return {};
  CheckCancel();
  Stopwatch us;
  // (blocks no row falls in are empty: their score is 0)
  const std::vector<int> block = RowBlocks(kUncertaintyBlocksAcross);
  const std::vector<double> base = A_.Multiply(lambda_);
  LightFitProblem fit = FitProblem(&base);
  fit.segment = nullptr;  // under the albedo the map and the intensities were solved with
  std::vector<LightUncertainty> out = LightUncertainties(fit, lights, &A_, lambda_, block);
  // The columns' Monte Carlo noise, which the blocks left out do not see (docs/method.md,
  // "Uncertainty"): each lamp refitted on each part of the paths apart, and the pull that gives.
  const LightFitSubset share(fit, kShadowRows);
  const std::vector<Eigen::Matrix3d> noise = PartsCovariance(share.problem, lights, kPartsIterations);
  for (std::size_t k = 0; k < out.size() && k < noise.size(); ++k) {  // (noise is 0 but a lamp's)
    if (std::holds_alternative<PointLight>(lights[k]))
      out[k].paths_ratio = LargestVarianceRatio(noise[k], out[k].shape_covariance);
    out[k].shape_covariance += noise[k];
  }
  // A lamp held where the cameras saw it: its place is as sure as the triangulation.
  for (std::size_t k = 0; k < out.size(); ++k)
    if (const PointLight* l = std::get_if<PointLight>(&lights[k]); l && l->held)
      for (const SeenLamp& s : SeenLampsOnce())
        if ((s.position - l->position).norm() < 1e-9) out[k].shape_covariance = s.covariance;
  Progress(Fmt("the lights' uncertainty in %.2f s", us.Seconds()));
  return out;
}

/// A progress line per light: its 95 % region's size (`u`: Uncertainty()'s, in Lights()' order).
void Estimator::SayUncertainty(const std::vector<LightUncertainty>& u) {
  const std::vector<Light> lights = Lights();
  for (std::size_t k = 0; k < u.size() && k < lights.size(); ++k) {
    Eigen::Vector3d semi = Eigen::Vector3d::Constant(INFINITY);
    Eigen::Matrix3d axes;
    Region95(u[k].shape_covariance, ShapeDims(lights[k]), &semi, &axes);
    Progress(std::holds_alternative<PointLight>(lights[k])
                 ? Fmt("point light %zu: its place within %.3g m (the 95 %% region's longest semi-axis)", k, semi[2])
             : std::holds_alternative<EmitterLight>(lights[k])
                 ? Fmt("emitter %zu: its radiance within %.3g of %.3g (95 %%, the green channel, image units)", k,
                       1.96 * u[k].scale_sigma[1] * res_.image_mean, Scale(lights[k])[1] * res_.image_mean)
                 : Fmt("directional light %zu: its direction within %.3g degrees (95 %%)", k, semi[2] * 180 / kPi));
  }
}

void Estimator::RenderFittedViews() {
  CheckCancel();
  Stopwatch rs;
  TracerOptions topt = opt_.tracer;
  topt.seed = opt_.tracer.seed * 1000003ull + 999;
  topt.spp = kMaskedRenderSpp;
  topt.cancelled = opt_.cancelled;
  const CellSampler sampler = Sampler(res_.lighting.map, reachable_);
  // The fit where it used the pixels, the rest traced.
  res_.fits = RenderLighting(*scene_, env_, res_.lighting, sampler, UnusedPixels(views_), topt, false);
  PutFit(&res_.fits);
  CheckCancel();
  if (opt_.render_spp > 0) {  // every pixel traced again at render_spp
    topt.spp = opt_.render_spp;
    res_.renders = RenderLighting(*scene_, env_, res_.lighting, sampler, bundle_.views, topt, true);
  } else if (opt_.render_noise > 0) {
    res_.renders = CleanRender(sampler);
  } else {
    res_.renders = res_.fits;
  }
  CheckCancel();
  res_.render_seconds = rs.Seconds();
  Progress(Fmt("relit %zu view(s) in %.2f s (the fit; ", bundle_.views.size(), res_.render_seconds) +
           (opt_.render_spp > 0        ? Fmt("the render at %d samples per pixel)", opt_.render_spp)
            : !res_.render_passes.empty() ? Fmt("the clean render at %d samples per pixel, noise %.3g)",
                                                res_.render_passes.back().spp, res_.render_passes.back().noise)
                                          : std::string("the render is the fit)")));
}

/// The clean render (lp::CleanRender): its passes in res_.render_passes and the progress lines.
std::vector<ImageRGB> Estimator::CleanRender(const CellSampler& sampler) {
  const Stopwatch clock;
  std::vector<ImageRGB> clean =
      lp::CleanRender(*scene_, env_, res_.lighting, sampler, bundle_.views, opt_, clock_.Seconds(), &res_.render_passes,
                      [&](const RenderPass& p, const std::vector<ImageRGB>&) {
                        CheckCancel();
                        Progress(Fmt("clean render: %d samples per pixel in %.2f s, relative noise %.3g", p.spp,
                                     p.seconds, p.noise));
                      });
  res_.clean_render_seconds = clock.Seconds();
  return clean;
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

}  // namespace lp::detail

namespace lp {

std::vector<ImageRGB> CleanRender(const RayTracer& scene, const EnvMap& env, const Lighting& lighting,
                                  const CellSampler& sampler, const std::vector<View>& views,
                                  const EstimateOptions& options, double estimate_seconds,
                                  std::vector<RenderPass>* passes, const RenderPassCallback& on_pass) {
  TracerOptions t = options.tracer;
  t.seed = options.tracer.seed * 1000003ull + 998;
  t.spp = kMaskedRenderSpp / 2;  // a half's
  const double seconds =
      options.render_seconds > 0 ? options.render_seconds : std::max(kMinCleanRenderSeconds, estimate_seconds);
  return ProgressiveRender(scene, env, lighting, sampler, views, t, options.render_noise, seconds, kMaxCleanRenderSpp,
                           passes, on_pass, options.render_denoise);
}

std::shared_ptr<const WarmStart> WarmStartOf(const EstimateResult& result) {
  auto warm = std::make_shared<WarmStart>();
  warm->lighting = result.lighting;
  warm->rings = result.env.rings();
  warm->up = result.env.up();
  return warm;
}

EstimateResult Estimate(const SceneBundle& bundle, const EstimateOptions& options) {
  // A reconstructed mesh's albedo (the colours seen) at the scale of real albedos first.
  const bool reconstructed = bundle.mesh.shaded.size() == bundle.mesh.positions.size() && !bundle.mesh.shaded.empty();
  const double scale = reconstructed ? AlbedoScaleTo(bundle.mesh, options.room_albedo) : 1;
  std::optional<SceneBundle> scaled;
  if (scale != 1) {
    scaled = bundle;
    ScaleAlbedo(&scaled->mesh, scale);
  }
  detail::Estimator estimator(scaled ? *scaled : bundle, options, scale);
  estimator.RunRounds();
  if (estimator.AlbedoRefinable())
    for (int pass = 1; pass <= options.albedo_passes; ++pass) {
      const std::vector<Light> before = estimator.Lights();
      if (!estimator.RefineAlbedo(pass)) break;
      estimator.RunRounds();
      if (estimator.Settled(before)) break;
    }
  if (estimator.OnPreAlbedoGrid()) estimator.RunRounds();  // no albedo pass came after the grid's rounds
  estimator.FitSky();
  estimator.Conclude();
  estimator.LightsFinal();
  if (options.render) estimator.RenderFittedViews();
  return estimator.TakeResult();
}

}  // namespace lp

