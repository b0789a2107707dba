#include "ui/estimate_job.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/parallel.h"
#include "estimation/lights/emitter_light.h"
#include "estimation/truth.h"
#include "estimation/truth_scorer.h"
#include "estimation/vertex_radiance.h"
#include "scene/surface_filter.h"
#include "scene/ray_tracer.h"

namespace lp::ui {

EstimateJob::EstimateJob(Settings settings) : settings_(std::move(settings)) {
  if (const EstimateStatus* last = settings_.shown.get()) {  // shown until this job has its own
    status_.lighting = last->lighting;
    status_.env = last->env;
    status_.dominant = last->dominant;
    status_.scene = last->scene;
    status_.result = last->result;
    status_.lit = last->lit;
    status_.error = last->error;
    status_.lit_samples = last->lit_samples;
    status_.lit_noise = last->lit_noise;
    status_.lit_done = last->lit_done;
    status_.renders = last->renders;
    status_.render_samples = last->render_samples;
    status_.render_noise = last->render_noise;
    status_.finished_at = last->finished_at;
  }
  settings_.shown.reset();
  status_.live = settings_.live;
  status_.live_index = settings_.live_index;
  status_.preview = settings_.preview;
  status_.warm = settings_.options.warm != nullptr;
  status_.started_at = settings_.pressed_at;
  status_.state = EstimateState::kPreparing;
  status_.message = "taking a snapshot of the scene";
  status_.version = settings_.version;
  status_.lit_version = settings_.lit_version;
}

EstimateJob::~EstimateJob() {
  Cancel();
  if (thread_.joinable()) thread_.join();
}

void EstimateJob::Start(SceneSource scene, std::vector<std::unique_ptr<EstimateJob>> retired) {
  bool cancelled = false;
  Update([&](EstimateStatus& s) {
    // Checked under the status lock, as Cancel sets it: a Cancel that came while the
    // snapshot was taken is not overwritten.
    if ((cancelled = cancel_.load())) return;
    s.message = "building the scene (mesh, keyframes)";  // still kPreparing: Cancel ends it at once
    s.options = settings_.options;
  });
  if (cancelled) {  // nothing to run: the replaced jobs still finish off the caller's thread
    thread_ = std::thread([retired = std::move(retired)]() mutable { retired.clear(); });
    return;
  }
  thread_ = std::thread([this, scene = std::move(scene), retired = std::move(retired)]() mutable {
    retired.clear();  // the jobs this one replaced finish on this thread, not the caller's
    // The window (and Mesa's rasterizer threads) comes first: the estimate takes the CPU
    // it leaves (its loops' workers too).
    RunThisThreadInBackground();
    Run(std::move(scene));
  });
}

void EstimateJob::Fail(const std::string& message) {
  Update([&](EstimateStatus& s) {
    if (s.state == EstimateState::kCancelled) return;
    s.state = EstimateState::kFailed;
    s.message = message;
  });
}

void EstimateJob::Cancel() {
  std::lock_guard<std::mutex> lock(mutex_);
  cancel_ = true;
  if (status_.state == EstimateState::kPreparing) {
    status_.state = EstimateState::kCancelled;
    status_.message = "cancelled";
  }
}

void EstimateJob::Retire() {
  Cancel();
  std::lock_guard<std::mutex> lock(mutex_);
  const std::uint64_t version = status_.version, lit_version = status_.lit_version;
  const EstimateState state = status_.state;
  status_ = EstimateStatus{};
  status_.state = state;
  status_.version = version;
  status_.lit_version = lit_version;
}

EstimateStatus EstimateJob::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return status_;
}

namespace {
/// `lighting` (on `env`'s cells, with its dominant directions) as the one shown; a new
/// version for the views to pick up.
void Show(EstimateStatus& s, const Lighting& lighting, const EnvMap& env, std::vector<Eigen::Vector3d> dominant) {
  if (!s.env || s.env->up() != env.up() || s.env->rings() != env.rings()) s.env = std::make_shared<const EnvMap>(env);
  s.lighting = lighting;
  s.dominant = std::move(dominant);
  ++s.version;
}
}  // namespace

/// The estimate's options with the job's cancel token and its live reports.
EstimateOptions EstimateJob::Callbacks() {
  EstimateOptions options = settings_.options;
  options.render_noise = 0;  // the relit keyframes are the fit until the job's clean render (CleanRender)
  EstimateJob* self = this;
  options.cancelled = [self] { return self->cancelled(); };
  options.progress = [self](const std::string& line) { self->Update([&](EstimateStatus& s) { s.message = line; }); };
  options.on_convergence = [self](const ConvergenceRow& row) {
    self->Update([&](EstimateStatus& s) { s.rows.push_back(row); });
  };
  const int max_rounds = options.max_rounds * (1 + std::max(0, options.albedo_passes));  // an upper bound
  options.on_first_solve = [self](const Lighting& lighting, const EnvMap& env) {
    auto dominant = DominantDirections(env, lighting.map, 2);
    const double t = self->SincePressed();
    self->Update([&](EstimateStatus& s) {
      Show(s, lighting, env, std::move(dominant));
      if (std::isnan(s.seconds_to_map)) s.seconds_to_map = t;
    });
  };
  options.on_round = [self, max_rounds](const RoundInfo& info, const EnvMap& env) {
    auto dominant = DominantDirections(env, info.lighting.map, 2);
    const double t = self->SincePressed();
    self->Update([&](EstimateStatus& s) {
      Show(s, info.lighting, env, std::move(dominant));
      s.progress = static_cast<double>(info.round) / (max_rounds + 1);
      if (std::isnan(s.seconds_to_first)) s.seconds_to_first = t;
    });
  };
  return options;
}

std::shared_ptr<const EstimateResult> EstimateJob::EstimateScene(SceneSource source,
                                                                 std::shared_ptr<const SceneBundle>* scene) {
  try {
    if (auto* loaded = std::get_if<std::shared_ptr<const SceneBundle>>(&source)) *scene = *loaded;
    else *scene = std::make_shared<const SceneBundle>(std::get<ReconstructionRunSnapshot>(source).Finish());
    if (cancelled()) throw Cancelled();
    Update([&](EstimateStatus& s) {
      if (s.state == EstimateState::kCancelled) return;
      s.state = EstimateState::kRunning;
      s.message = "tracing round 1";
      if (s.scene != *scene) {  // the last estimate's pictures belong to its own scene
        s.result.reset();
        s.lit.reset();
        s.error.reset();
        s.renders.reset();
        s.lit_samples = s.render_samples = 0;
        s.lit_noise = s.render_noise = std::nan("");
        s.lit_done = false;
        ++s.lit_version;
        ++s.render_version;
      }
      s.scene = *scene;
    });
    EstimateOptions options = Callbacks();
    options.time_offset = SincePressed();
    options.scorer = TruthScorer::FromBundle(**scene, options.point_lights.far);
    return std::make_shared<const EstimateResult>(lp::Estimate(**scene, options));
  } catch (const Cancelled&) {
    Update([&](EstimateStatus& s) {
      s.state = EstimateState::kCancelled;
      s.message = "cancelled";
    });
  } catch (const std::exception& e) {
    Fail(e.what());
  }
  return nullptr;
}

void EstimateJob::Run(SceneSource source) {
  std::shared_ptr<const SceneBundle> scene;
  const std::shared_ptr<const EstimateResult> result = EstimateScene(std::move(source), &scene);
  if (!result) return;
  const double t = SincePressed();
  Update([&](EstimateStatus& s) {
    s.state = EstimateState::kDone;
    s.progress = 1;
    s.result = result;
    Show(s, result->lighting, result->env, result->dominant);
    s.seconds_total = t;
    s.finished_at = settings_.clock->Seconds();
    s.message = "done in " + std::to_string(t).substr(0, 5) + " s";
    for (const std::string& w : result->warnings) s.message += "; warning: " + w;
  });
  try {  // the estimate's scene, its refined albedo, traced by both steps after it
    Mesh mesh = scene->mesh;
    if (result->albedo.size() == mesh.positions.size()) mesh.albedo = result->albedo;
    std::vector<std::uint8_t> open = TrianglesOnShapes(mesh, result->openings);  // (windows: no surface)
    const RayTracer tracer(std::move(mesh), std::move(open));
    RefineLit(tracer, *scene, *result);
    CleanRender(tracer, *scene, *result);
  } catch (const std::exception& e) {
    Update([&](EstimateStatus& s) { s.message = std::string("lit shading: ") + e.what(); });
  }
}

/// The keyframes' clean render under the estimate, pass by pass (ProgressiveRender, as
/// `estimate` writes render_view*: until EstimateOptions::render_noise, for as long as the
/// estimate took by default), each pass shown.
void EstimateJob::CleanRender(const RayTracer& tracer, const SceneBundle& scene, const EstimateResult& result) {
  const EstimateOptions& o = settings_.options;
  if (!o.render || o.render_spp > 0 || !(o.render_noise > 0) || cancelled()) return;
  try {
    std::vector<RenderPass> passes;
    lp::CleanRender(tracer, result.env, result.lighting, CellSampler(result.env, result.lighting.map, {}, o.tracer.nee_floor),
                    scene.views, o, result.total_seconds, &passes,
                    [&](const RenderPass& p, const std::vector<ImageRGB>& so_far) {
                      if (cancelled()) throw Cancelled();
                      auto renders = std::make_shared<const std::vector<ImageRGB>>(so_far);
                      Update([&](EstimateStatus& s) {
                        s.renders = renders;
                        s.render_samples = p.spp;
                        s.render_noise = p.noise;
                        ++s.render_version;
                      });
                    });
  } catch (const Cancelled&) {
  } catch (const std::exception& e) {
    Update([&](EstimateStatus& s) { s.message = std::string("clean render: ") + e.what(); });
  }
}

/// Progressive per-vertex radiance under the estimate, its noise smoothed out over the
/// surface (VertexRadiance::Clean), its first bounce stratified, until its noise is lit_noise
/// or it has lit_samples (more on a small mesh); then the error against the keyframes.
void EstimateJob::RefineLit(const RayTracer& tracer, const SceneBundle& scene, const EstimateResult& result) {
  try {
    VertexRadiance radiance(tracer, result.env, result.lighting, std::max(1, settings_.options.tracer.bounces), 1);
    radiance.SetStratified(true);
    const double more = std::max(1.0, kLitVertices / std::max<std::size_t>(1, tracer.mesh().positions.size()));
    const int most = static_cast<int>(std::min(1e6, settings_.lit_samples * more));
    const int target = most + most % 2;  // Clean needs an even count
    int step = 2;
    // The error shading follows the radiance's noise down: recomputed at 2 samples, then
    // each time they have grown 4-fold, and at the end.
    int error_at = 2;
    bool done = false;
    while (!done && !cancelled()) {
      radiance.Refine(std::min(step, target - radiance.samples()));
      LitShading clean = radiance.Clean(SurfaceFilter{});
      done = radiance.samples() >= target || clean.noise <= settings_.lit_noise;
      // The next step at most doubles the samples (32 at a time on a large mesh, where each
      // Clean shows progress), and is no longer than what reaches the noise asked with a
      // tenth to spare (the noise as one over the root of the samples): a small mesh's
      // doubling overshot (the cornerbox 4,094 samples where ~2,000 reach 0.7 %).
      const int s = radiance.samples();
      const double reach = clean.noise > 0 && settings_.lit_noise > 0
                               ? 1.1 * s * std::pow(clean.noise / settings_.lit_noise, 2) - s
                               : static_cast<double>(s);
      step = std::min({2 * step, std::max(32, target / 32 * 2), std::max(2, static_cast<int>(std::min(reach, 1e6)))});
      step += step % 2;  // Clean needs an even count
      auto lit = std::make_shared<const std::vector<Eigen::Vector3f>>(std::move(clean.radiance));
      std::shared_ptr<const std::vector<float>> error;
      if (done || radiance.samples() >= error_at) {
        error = std::make_shared<const std::vector<float>>(VertexPhotometricError(tracer, scene.views, *lit));
        error_at = 4 * radiance.samples();
      }
      const int samples = radiance.samples();
      Update([&](EstimateStatus& s) {
        s.lit = lit;
        if (error) s.error = error;
        s.lit_samples = samples;
        s.lit_noise = clean.noise;
        s.lit_done = done;
        ++s.lit_version;
      });
    }
  } catch (const std::exception& e) {
    Update([&](EstimateStatus& s) { s.message = std::string("lit shading: ") + e.what(); });
  }
}

}  // namespace lp::ui
