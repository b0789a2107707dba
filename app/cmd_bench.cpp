// `lightprobe bench`: time to converge for each solver on the synthetic one-light
// scene, and the finite-difference Jacobian baseline. Prints a Markdown table.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>

#include "app/commands.h"
#include "capture/capture_thread.h"
#include "capture/openni.h"
#include "common/atomic_file.h"
#include "common/parallel.h"
#include "common/rng.h"
#include "common/timer.h"
#include "estimation/path_tracer.h"
#include "estimation/sampling.h"
#include "scene/ray_tracer.h"
#include "estimation/synth.h"
#include "estimation/truth_scorer.h"

namespace lp::app {
namespace fs = std::filesystem;

namespace {

double PeakMemoryMiB() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;
}

struct SolverTiming {
  double seconds_to_target = -1;  // -1: not reached
  double final_objective = 0;
  double total_seconds = 0;
  int iterations = 0;
  double kkt = 0;
  std::vector<std::pair<double, double>> trace;  // (seconds, objective) per iteration
};

/// Runs a solver on a fixed problem from lambda = 1e-3, logging (seconds, E) per iteration.
SolverTiming TimeSolver(SolverKind kind, const Objective& obj, double cap_seconds, bool adaptive = false) {
  SolverTiming t;
  Stopwatch sw;
  SolverOptions o;
  o.max_iterations = 100000;
  o.relative_tolerance = 1e-12;
  o.gradient_tolerance = 1e-12;
  o.max_seconds = cap_seconds;
  o.adaptive_step = adaptive;
  o.on_iteration = [&](const IterationInfo& it) { t.trace.emplace_back(sw.Seconds(), it.objective); };
  const SolveResult r = Solve(kind, obj, std::vector<double>(obj.unknowns(), 1e-3), o);
  t.total_seconds = sw.Seconds();
  t.final_objective = r.objective;
  t.iterations = r.iterations;
  t.kkt = r.kkt_violation;
  return t;
}

/// Records a VGA .oni through OpenNI2 from the Redwood frames (served by the project's
/// driver), then replays it as fast as possible, directly and through the capture thread.
template <typename Row>
void ReplayBench(const fs::path& out, const Row& row) {
  const fs::path frames = fs::path(DefaultDataDir()) / "rgbd" / "redwood_open3d" / "RGBD";
  if (!fs::exists(frames)) throw InputError(frames.string(), "replay benchmark: frames not found");
  std::error_code ec;
  fs::create_directories(out, ec);
  const fs::path oni = out / "replay_vga.oni";
  RecordOptions ro;
  ro.uri = "lpsynth://" + frames.string() + "?fps=30";
  ro.frames = 150;
  const RecordResult rec = RecordOni(oni.string(), ro);
  char note[256];
  std::snprintf(note, sizeof note, "%d depth + %d colour frames, 640x480, %.1f MiB", rec.depth_frames,
                rec.color_frames, fs::file_size(oni) / 1048576.0);
  row("640x480", "record .oni through OpenNI2 (30 fps source)", rec.seconds, 0, NAN, note);
  {
    // What the isolation costs: opening with the playback check in a separate process
    // (one decode pass there) against opening in this process only.
    OniPlaybackOptions direct;
    direct.isolate = false;
    Stopwatch sw;
    OpenOniFile(oni.string(), direct);
    const double plain = sw.Seconds();
    sw.Reset();
    OpenOniFile(oni.string());
    const double checked = sw.Seconds();
    std::snprintf(note, sizeof note, "%.2f s without the check, %.2f s with it", plain, checked);
    row("640x480", "open .oni, playback checked in a separate process", checked, 0, NAN, note);
  }
  {
    auto src = OpenOniFile(oni.string());
    RgbdFrame f;
    int n = 0;
    Stopwatch sw;
    while (src->Next(&f, 2.0) == SourceStatus::kFrame) ++n;
    const double s = sw.Seconds();
    std::snprintf(note, sizeof note, "%d frame pairs, %.0f frames/s", n, n / s);
    row("640x480", "replay .oni as fast as possible", s, 0, NAN, note);
  }
  {
    auto queue = std::make_shared<FrameQueue>(4);
    auto src = OpenOniFile(oni.string());  // the playback check is timed above
    Stopwatch sw;
    CaptureThread t(std::move(src), queue);
    std::vector<double> latency;
    while (auto f = queue->Pop(5.0)) {
      const double now = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
      latency.push_back(now - f->queued_at);
    }
    const double s = sw.Seconds();
    std::sort(latency.begin(), latency.end());
    const double median = latency.empty() ? NAN : latency[latency.size() / 2];
    const double p99 = latency.empty() ? NAN : latency[latency.size() * 99 / 100];
    std::snprintf(note, sizeof note, "%zu frames, %.0f frames/s; queue latency median %.3f ms, 99th %.3f ms, %lld dropped",
                  latency.size(), latency.size() / s, 1e3 * median, 1e3 * p99,
                  static_cast<long long>(t.stats().queue.dropped));
    row("640x480", "replay through the capture thread and queue", s, 0, NAN, note);
  }
}

struct BenchOptions {
  std::string out = "out/bench";
  std::vector<std::string> sizes = {"160x120", "320x240"};
  double cap = 120;  ///< seconds the gradient solver may run per problem
  EstimateOptions estimate;
  int threads = 0;
  std::vector<std::string> parts = {"estimate", "solvers", "fd"};

  bool Want(const char* part) const { return std::find(parts.begin(), parts.end(), part) != parts.end(); }
};

/// bench.md and bench.csv, one row per measurement (each row printed as it comes), and
/// solver_traces.csv.
class BenchTables {
 public:
  BenchTables() {
    traces_ << "size,solver,seconds,objective\n";
    csv_ << "size,method,seconds,relative_rmse,angular_error_deg,note\n";
    md_ << "| size | method | seconds | relative RMSE | light error (deg) | note |\n|---|---|---|---|---|---|\n";
  }

  void Row(const std::string& size, const std::string& method, double s, double rmse, double ang,
           const std::string& note) {
    char buf[512];
    std::snprintf(buf, sizeof buf, "| %s | %s | %.2f | %.4f | %.2f | %s |\n", size.c_str(), method.c_str(), s, rmse,
                  ang, note.c_str());
    md_ << buf;
    csv_ << size << ',' << method << ',' << s << ',' << rmse << ',' << ang << ',' << note << '\n';
    std::fputs(buf, stdout);
    std::fflush(stdout);
  }

  /// Row as the benchmarks in other files take it.
  BenchRow row() {
    return [this](const std::string& size, const std::string& method, double s, double rmse, double ang,
                  const std::string& note) { Row(size, method, s, rmse, ang, note); };
  }

  void Trace(const std::string& size, const char* solver, double seconds, double objective) {
    traces_ << size << ',' << solver << ',' << seconds << ',' << Num(objective) << '\n';
  }

  void Write(const fs::path& out) const {
    WriteTextAtomically(out / "bench.md", md_.str());
    WriteTextAtomically(out / "bench.csv", csv_.str());
    WriteTextAtomically(out / "solver_traces.csv", traces_.str());
  }

 private:
  std::ostringstream md_, csv_, traces_;
};

/// 1. Full estimates (trace + solve, all sMC rounds), each solver.
void BenchEstimates(const BenchOptions& o, const std::string& size, const SceneBundle& b, BenchTables* tables) {
  for (SolverKind kind : {SolverKind::kFast, SolverKind::kGradient}) {
    EstimateOptions eo = o.estimate;
    eo.solver = kind;
    eo.render = false;
    eo.solver_options.max_seconds = o.cap;
    eo.scorer = TruthScorer::FromBundle(b, eo.point_lights.far);
    Stopwatch sw;
    const EstimateResult r = Estimate(b, eo);
    tables->Row(size, std::string("estimate, ") + ToString(kind) + " solver", sw.Seconds(), r.final_relative_rmse,
                r.final_angular_error_deg, std::to_string(r.rounds.size()) + " sMC rounds");
  }
}

/// The objective as Estimate sets it up: alpha per 19,200 observed pixels, cells weighted by
/// solid angle.
ObjectiveParams EstimateObjectiveParams(const EstimateOptions& o, const EnvMap& env, const LinearProblem& problem) {
  ObjectiveParams params = o.objective;
  params.alpha *= problem.rows() / kAlphaReferencePixels;
  params.cell_weight.resize(problem.unknown_cells);
  for (int k = 0; k < problem.unknown_cells; ++k)
    params.cell_weight[k] = env.solid_angle(problem.cell_of[k]) / kAlphaReferenceSolidAngle;
  return params;
}

/// 2. Solvers on the same A (one round's trace). Each solver runs once to its own
/// convergence (or the cap); the target is the worst of their final objectives (+1e-6
/// relative), a value every one of them reaches: the objective is non-convex and they can
/// stop in different minima.
void BenchSolvers(const BenchOptions& o, const std::string& size, const EnvMap& env, const LinearProblem& problem,
                  BenchTables* tables) {
  const ObjectiveParams params = EstimateObjectiveParams(o.estimate, env, problem);
  const Objective obj(problem, params);
  struct Entry {
    const char* name;
    SolverTiming t;
  };
  std::vector<Entry> runs = {
      {"fast", TimeSolver(SolverKind::kFast, obj, o.cap)},
      {"gradient", TimeSolver(SolverKind::kGradient, obj, o.cap)},
      {"gradient, adaptive step", TimeSolver(SolverKind::kGradient, obj, o.cap, true)},
  };
  double worst = -1e300, best = 1e300;
  for (const Entry& e : runs) {
    worst = std::max(worst, e.t.final_objective);
    best = std::min(best, e.t.final_objective);
  }
  const double target = worst * (1 + 1e-6);
  double fast_seconds = 0;
  for (Entry& e : runs) {
    for (const auto& [sec, obj_value] : e.t.trace) {
      tables->Trace(size, e.name, sec, obj_value);
      if (e.t.seconds_to_target < 0 && obj_value <= target) e.t.seconds_to_target = sec;
    }
    if (e.t.seconds_to_target < 0) e.t.seconds_to_target = e.t.total_seconds;
    if (&e == &runs[0]) fast_seconds = e.t.seconds_to_target;
    char note[256];
    std::snprintf(note, sizeof note,
                  "%d iterations; %.1fx the fast solver; final E/E_best - 1 = %.1e after %.2f s, KKT %.1e",
                  e.t.iterations, e.t.seconds_to_target / std::max(1e-9, fast_seconds),
                  e.t.final_objective / best - 1, e.t.total_seconds, e.t.kkt);
    tables->Row(size, std::string(e.name) + " solver to E_common", e.t.seconds_to_target, 0, NAN, note);
  }
}

/// 3. Finite-difference Jacobian: one render per unknown cell plus the base render (common
/// random numbers and frozen importance make it exact for a linear render), extrapolated
/// from a few measured renders and compared with one trace of A (trace_s seconds).
void BenchFd(const BenchOptions& o, const std::string& size, const RayTracer& scene, const EnvMap& env,
             const SceneBundle& b, double trace_s, BenchTables* tables) {
  const int probes = 3;
  const double per_render = SecondsPerCellRender(scene, env, b.views, o.estimate.tracer, probes);
  char fd[160];
  std::snprintf(fd, sizeof fd, "%d renders x %.2f s (measured %d, extrapolated); %.0fx one trace of A",
                env.size() + 1, per_render, probes, per_render * (env.size() + 1) / trace_s);
  tables->Row(size, "finite-difference Jacobian", per_render * (env.size() + 1), 0, NAN, fd);
}

/// The observed pixels of the views, divided by their mean.
std::vector<double> NormalizedObservations(const std::vector<View>& views) {
  std::vector<double> y = CollectObservations(views);
  double mean = 0;
  for (double v : y) mean += v;
  mean /= y.size();
  for (double& v : y) v /= mean;
  return y;
}

/// The estimate, solver and FD parts at one image size of the synthetic one-light scene.
void BenchSize(const BenchOptions& o, const std::string& size, BenchTables* tables) {
  SynthOptions so;
  if (std::sscanf(size.c_str(), "%dx%d", &so.width, &so.height) != 2) throw InputError("--sizes: bad size " + size);
  so.spp = 256;
  const SceneBundle b = MakeSynthScene("one-light", so, DefaultDataDir());
  if (o.Want("estimate")) BenchEstimates(o, size, b, tables);
  if (!o.Want("solvers") && !o.Want("fd")) return;
  RayTracer scene(b.mesh);
  const EnvMap env(o.estimate.rings, b.up);
  Stopwatch ts;
  const TransportMatrix A =
      TraceTransport(scene, env, b.views, CellSampler(env, {}, {}, o.estimate.tracer.nee_floor), o.estimate.tracer);
  const double trace_s = ts.Seconds();
  const std::vector<double> y = NormalizedObservations(b.views);
  tables->Row(size, "trace A once", trace_s, 0, NAN, std::to_string(A.nonzeros()) + " non-zeros");
  const LinearProblem problem = MakeLinearProblem(A, y);
  if (o.Want("solvers")) BenchSolvers(o, size, env, problem, tables);
  if (o.Want("fd")) BenchFd(o, size, scene, env, b, trace_s, tables);
}

/// The tracer's ray throughput against Embree's own over the same BVH: a render of the
/// frag115 scene (the real reconstructed mesh) counts its rays (paths, next-event shadow
/// rays) and seconds; then as many rays of the same kinds (camera rays through jittered
/// pixels, and cosine-distributed rays leaving their hits) go through rtcIntersect1 alone.
void RaysBench(BenchTables* tables) {
  SynthOptions so;
  so.spp = 1;
  const SceneBundle b = MakeSynthScene("frag115", so, DefaultDataDir());
  const RayTracer scene(b.mesh);
  const EnvMap env(21, b.up);
  const std::vector<double> white(3 * env.size(), 1.0);
  TracerOptions t;
  t.spp = 32;
  TraceStats stats;
  double tracer_s = INFINITY, embree_s = INFINITY;  // the fastest of 3, alternating (a noisy machine)
  const CellSampler sampler(env, white, {}, t.nee_floor);
  RenderEnvironment(scene, env, b.views, white, sampler, t, true, &stats);
  // The same number of rays for Embree alone (made before the clock starts).
  std::vector<std::pair<Eigen::Vector3f, Eigen::Vector3f>> rays;
  const Camera& cam = b.views[0].camera;
  Rng rng(11);
  while (static_cast<std::int64_t>(rays.size()) < stats.rays) {
    const Eigen::Vector3d o = cam.center();
    const Eigen::Vector3d d = cam.RayDirection(rng.Uniform() * cam.width - 0.5, rng.Uniform() * cam.height - 0.5);
    rays.emplace_back(o.cast<float>(), d.cast<float>());
    SurfacePoint hit;
    if (!scene.Intersect(o, d, &hit)) continue;
    const Eigen::Vector3d w = SampleCosine(hit.shading, rng.Uniform(), rng.Uniform());
    rays.emplace_back((hit.position + hit.geometric * (4 * scene.epsilon())).cast<float>(), w.cast<float>());
  }
  std::int64_t hits = 0;
  for (int rep = 0; rep < 3; ++rep) {
    Stopwatch sw;
    RenderEnvironment(scene, env, b.views, white, sampler, t, true);
    tracer_s = std::min(tracer_s, sw.Seconds());
    sw = Stopwatch();
    hits = scene.CountHits(rays);
    embree_s = std::min(embree_s, sw.Seconds());
  }
  const double tracer_rate = stats.rays / tracer_s, embree_rate = rays.size() / embree_s;
  char note[256];
  std::snprintf(note, sizeof note, "%lld triangles, %.2f Mrays/s (%lld rays, 32 spp, hit records, NEE, sampling)",
                static_cast<long long>(b.mesh.triangles.size()), tracer_rate / 1e6, static_cast<long long>(stats.rays));
  tables->Row("160x120", "rays: the tracer (frag115), fastest of 3", tracer_s, 0, NAN, note);
  std::snprintf(note, sizeof note, "%.2f Mrays/s (%zu rays, %.0f %% hit); tracer / Embree = %.2f", embree_rate / 1e6,
                rays.size(), 100.0 * hits / rays.size(), tracer_rate / embree_rate);
  tables->Row("160x120", "rays: Embree rtcIntersect1 alone, same BVH, fastest of 3", embree_s, 0, NAN, note);
}

void RunBench(const BenchOptions& o) {
  ThreadLimit limit(o.threads);
  BenchTables tables;
  if (o.Want("replay")) ReplayBench(fs::path(o.out), tables.row());
  if (o.Want("reconstruct")) ReconstructionBench(tables.row());
  if (o.Want("rays")) RaysBench(&tables);
  if (o.Want("estimate") || o.Want("solvers") || o.Want("fd"))
    for (const std::string& size : o.sizes) BenchSize(o, size, &tables);
  char mem[64];
  std::snprintf(mem, sizeof mem, "%.0f MiB (whole run)", PeakMemoryMiB());
  tables.Row("all", "peak memory (RSS)", 0, 0, NAN, mem);
  tables.Write(fs::path(o.out));
  std::printf("results in %s (bench.md, bench.csv)\n", fs::absolute(o.out).lexically_normal().c_str());
}

}  // namespace

double SecondsPerCellRender(const RayTracer& scene, const EnvMap& env, const std::vector<View>& views,
                            const TracerOptions& tracer, int probes) {
  const CellSampler uniform(env, {}, {}, tracer.nee_floor);
  std::vector<double> lambda(3 * env.size());
  Stopwatch sw;
  for (int k = 0; k < probes; ++k) {
    lambda.assign(lambda.size(), 0.0);
    for (int c = 0; c < 3; ++c) lambda[3 * (k % env.size()) + c] = 1;
    RenderEnvironment(scene, env, views, lambda, uniform, tracer, false);
  }
  return sw.Seconds() / probes;
}

Run AddBench(CLI::App& app) {
  auto* cmd = app.add_subcommand("bench", "time the solvers and the finite-difference baseline (synthetic one-light)");
  auto o = std::make_shared<BenchOptions>();
  cmd->add_option("--parts", o->parts,
                  "which parts to run: estimate (full estimates), solvers (same A), fd, replay (.oni throughput), "
                  "reconstruct (frames/s by stage, OpenCV baseline, meshing a room), rays (the tracer's ray "
                  "throughput against Embree alone)")
      ->capture_default_str()
      ->check(CLI::IsMember({"estimate", "solvers", "fd", "replay", "reconstruct", "rays"}));
  cmd->add_option("--out", o->out, "directory for bench.csv and bench.md")->capture_default_str();
  cmd->add_option("--sizes", o->sizes,
                  "image sizes WxH of the estimate, solvers and fd parts (reconstruct runs 320x240 and 640x480)")
      ->capture_default_str();
  cmd->add_option("--gradient-cap", o->cap, "seconds the gradient solver may run per problem")->capture_default_str();
  AddEstimateOptions(*cmd, &o->estimate, &o->threads);
  return [o] { RunBench(*o); };
}

}  // namespace lp::app
