// `lightprobe --headless INPUT --out DIR --live`: the input played at its recorded rate
// (frames a busy reconstruction could not take are dropped, as a camera's queue drops
// them), reconstructed, and its lighting estimated on a background thread while it plays:
// whenever the model has changed enough (reconstruction/live_trigger.h) and no estimate is
// running, one starts on a fresh snapshot, warm-started from the last (EstimateOptions::
// warm): a preview (LivePreview: seconds on one core) unless LiveSettings::preview is off.
// Each finished estimate is written to DIR/live/NNN/ and replaces DIR/estimate
// (atomically), twice: with its lights as soon as they are final, then with its pictures;
// DIR/live/live.csv logs when each started, had its lights and finished. At the input's end,
// when the model changed after the last snapshot, the running estimate (of an older
// snapshot) is cancelled and a preview is made of the whole scan; then its bundle is
// written to DIR/scene and the full estimate is made of it.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "capture/frame_source.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "estimation/truth_scorer.h"
#include "reconstruction/live_trigger.h"

namespace lp::app {
namespace fs = std::filesystem;

namespace {

constexpr double kFramePeriod = 1.0 / 30;  ///< frames without usable timestamps come at 30 per second

/// Holds each frame until its time at `speed` times the recorded rate (the frames'
/// timestamps, else 30 a second); a frame later than one frame period is to be dropped.
class FramePacer {
 public:
  FramePacer(double speed, const Stopwatch& clock) : speed_(speed), clock_(clock) {}
  /// Waits for `frame`'s time; false when it is already late (drop it).
  bool Wait(const RgbdFrame& frame) {
    if (speed_ <= 0) return true;
    double stamp = frame.depth_timestamp;
    if (!(stamp > last_stamp_)) stamp = last_stamp_ + kFramePeriod;  // none, or not increasing
    last_stamp_ = stamp;
    if (std::isnan(stamp0_)) stamp0_ = stamp, wall0_ = clock_.Seconds();
    const double due = wall0_ + (stamp - stamp0_) / speed_;
    const double late = clock_.Seconds() - due;
    if (late > kFramePeriod / speed_) return false;
    if (late < 0) std::this_thread::sleep_for(std::chrono::duration<double>(-late));
    return true;
  }

 private:
  double speed_;
  const Stopwatch& clock_;
  double stamp0_ = std::nan(""), wall0_ = 0, last_stamp_ = -1e300;
};

/// The live estimates of one run, one at a time on a background thread at a lower OS
/// priority; each warm-started from the one before.
class LiveEstimates {
 public:
  LiveEstimates(const fs::path& out, EstimateOptions options, const Stopwatch& clock)
      : out_(out), options_(std::move(options)), clock_(clock) {
    fs::create_directories(out_ / "live");
    std::ofstream csv(out_ / "live" / "live.csv");
    csv << "estimate,kind,frame,started_s,scene_s,lights_s,finished_s,estimate_s,vertices,keyframes,lights,rounds,"
           "relative_rmse,warm,position_error_share,error\n";
  }
  /// An estimate still running (the run ended with an error) stops at its next check.
  ~LiveEstimates() {
    stop_ = true;
    Wait();
  }
  bool busy() const { return busy_; }
  int finished() const { return finished_; }
  /// Waits for the running estimate (if any) to end, or to stop when cancelled.
  void Wait() {
    if (thread_.joinable()) thread_.join();
    cancel_ = false;
  }
  /// Asks the running estimate (if any) to stop at its next check (Wait waits for that): its
  /// snapshot is older than what comes next. It is logged as cancelled; the last finished
  /// one stays.
  void Cancel() { cancel_ = true; }
  /// What an estimate is: a preview (LivePreview), a full one while the input plays (its
  /// render_view* the fit), or the full one at the end (with its clean render).
  enum class Kind { kPreview, kWhilePlaying, kLast };
  /// Starts an estimate of `snapshot` (taken at input frame `frame`); the last must be done.
  void Start(ReconstructionRunSnapshot snapshot, std::int64_t frame, Kind kind) {
    Wait();
    busy_ = true;
    const int index = ++started_;
    thread_ = std::thread([this, snapshot = std::move(snapshot), frame, index, kind] {
      RunThisThreadInBackground();
      Run([&] { return snapshot.Finish([this] { return stop_.load() || cancel_.load(); }); }, frame, index, kind);
      busy_ = false;
    });
  }
  /// An estimate of the finished bundle, on the calling thread.
  void RunOn(const SceneBundle& bundle, std::int64_t frame, Kind kind) {
    Run([&] { return bundle; }, frame, ++started_, kind);
  }

 private:
  /// `scene` makes the bundle (a snapshot finished on this thread).
  void Run(const std::function<SceneBundle()>& scene, std::int64_t frame, int index, Kind kind);
  /// DIR/live/NAME made what `write` writes (into a fresh directory, with `snapshot`, over
  /// a hard-linked copy of what DIR/live/NAME holds when `over`), and DIR/estimate made a
  /// copy of it: each exchanged in one step (a reader sees the old or the new, never a mix).
  void Publish(const std::string& name, const nlohmann::json& snapshot, bool over,
               const std::function<void(const fs::path&)>& write);
  void Log(const std::string& row) {
    std::ofstream(out_ / "live" / "live.csv", std::ios::app) << row << "\n";
  }

  fs::path out_;
  EstimateOptions options_;
  const Stopwatch& clock_;
  std::shared_ptr<const WarmStart> warm_;  // the thread's alone (one estimate at a time)
  std::thread thread_;
  std::atomic<bool> busy_{false}, stop_{false}, cancel_{false};
  std::atomic<int> finished_{0};
  int started_ = 0;
};

void LiveEstimates::Publish(const std::string& name, const nlohmann::json& snapshot, bool over,
                            const std::function<void(const fs::path&)>& write) {
  const fs::path dir = out_ / "live" / name, tmp = out_ / "live" / (".tmp." + name);
  fs::remove_all(tmp);
  if (over) fs::copy(dir, tmp, fs::copy_options::recursive | fs::copy_options::create_hard_links);
  write(tmp);  // (each file written atomically: a new file, never into a linked one)
  WriteTextAtomically(tmp / "snapshot.json", snapshot.dump(2) + "\n");
  ReplaceDirectory(dir, tmp);
  const fs::path copy = out_ / ".tmp.estimate";
  fs::remove_all(copy);
  fs::copy(dir, copy, fs::copy_options::recursive | fs::copy_options::create_hard_links);
  ReplaceDirectory(out_ / "estimate", copy);
}

/// One live estimate: estimated, written to DIR/live/NNN/ and made DIR/estimate as soon as
/// its lights are final (lights.json, the map, the albedo), again with its pictures and
/// report when it ends, logged. A failure (nothing usable seen yet) or a cancel is logged
/// and the run goes on.
void LiveEstimates::Run(const std::function<SceneBundle()>& make_scene, std::int64_t frame, int index, Kind kind) {
  const double started = clock_.Seconds();
  char name[16];
  std::snprintf(name, sizeof name, "%03d", index);
  char row[512];
  double lit = NAN;
  const char* kind_name = kind == Kind::kPreview ? "preview" : "full";
  try {
    SceneBundle scene = make_scene();
    scene.dir = out_ / "scene";  // where the whole scan's bundle is written at the end
    const double scened = clock_.Seconds();
    EstimateOptions o = kind == Kind::kPreview ? LivePreview(options_) : options_;
    o.warm = warm_;
    o.cancelled = [this] { return stop_.load() || cancel_.load(); };
    if (kind == Kind::kWhilePlaying) o.render_noise = 0;
    o.scorer = TruthScorer::FromBundle(scene, o.point_lights.far);  // truth.json's errors, when it has one
    const bool warm = warm_ != nullptr;
    const nlohmann::json snap = {{"estimate", index},
                                 {"kind", kind_name},
                                 {"frame", frame},
                                 {"started_s", started},
                                 {"warm", warm},
                                 {"vertices", scene.mesh.positions.size()},
                                 {"keyframes", scene.views.size()}};
    o.on_lights = [&](const EstimateResult& r) {
      Publish(name, snap, false, [&](const fs::path& tmp) { WriteEstimateLights(tmp.string(), scene, r); });
      lit = clock_.Seconds();
      warm_ = WarmStartOf(r);  // (the next starts from these lights even if this one is cancelled)
    };
    const EstimateResult r = Estimate(scene, o);  // (on_lights came before it returned)
    Publish(name, snap, true, [&](const fs::path& tmp) {
      WriteEstimateOutputs(tmp.string(), scene, o, r, clock_.Seconds() - scened, true);
    });
    ++finished_;
    const double finished = clock_.Seconds();
    std::snprintf(row, sizeof row, "%d,%s,%lld,%.3f,%.3f,%s,%.3f,%.3f,%zu,%zu,%zu,%zu,%.6g,%d,%s,", index, kind_name,
                  static_cast<long long>(frame), started, scened, CsvNumber(lit).c_str(), finished, r.total_seconds,
                  scene.mesh.positions.size(), scene.views.size(), r.lighting.lights.size(), r.rounds.size(),
                  r.final_relative_rmse, warm ? 1 : 0, CsvNumber(r.final_position_error_share).c_str());
    std::printf("live estimate %d (%s, frame %lld, %s): %.1f s to %.1f s (its lights at %.1f s), %zu light(s), fit "
                "%.3f -> %s\n",
                index, kind_name, static_cast<long long>(frame), warm ? "warm" : "cold", started, finished, lit,
                r.lighting.lights.size(), r.final_relative_rmse, (out_ / "live" / name).c_str());
  } catch (const std::exception& e) {
    const bool cancelled = dynamic_cast<const Cancelled*>(&e) != nullptr;
    std::string what = cancelled ? "cancelled: a newer snapshot replaces it" : e.what();
    std::replace(what.begin(), what.end(), ',', ';');
    std::replace(what.begin(), what.end(), '\n', ' ');
    std::snprintf(row, sizeof row, "%d,%s,%lld,%.3f,,%s,%.3f,,,,,,,,,%s", index, kind_name,
                  static_cast<long long>(frame), started, CsvNumber(lit).c_str(), clock_.Seconds(), what.c_str());
    std::fprintf(stderr, "live estimate %d %s%s\n", index, cancelled ? "" : "failed: ", what.c_str());
  }
  std::fflush(stdout);
  Log(row);
}

}  // namespace

void RunLive(const std::string& input, const std::string& out, const ReconstructSettings& settings,
             const LiveSettings& live) {
  ThreadLimit limit(settings.threads);
  ReconstructionRun run(MakeRunOptions(settings, input));
  auto source = OpenFrameSource(input);
  std::printf("%s\nlive: played at %gx its recorded rate, estimated as it grows\n", source->Describe().c_str(),
              live.speed);
  Stopwatch clock;
  FramePacer pacer(live.speed, clock);
  LiveTrigger trigger(live.trigger);
  EstimateOptions options;  // the estimate subcommand's defaults
  LiveEstimates estimates(out, options, clock);
  RgbdFrame f;
  std::int64_t read = 0, dropped = 0, last_taken = -1;
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  while ((settings.max_frames == 0 || read < settings.max_frames) && source->Next(&f, 5.0) == SourceStatus::kFrame) {
    ++read;
    if (!pacer.Wait(f)) {
      ++dropped;
      continue;
    }
    const FrameReport report = run.Process(f);
    if (report.state == TrackingState::kTracking) pose = report.world_from_camera;
    if (!estimates.busy() && trigger.Due(run, pose)) {
      trigger.Taken(run, pose);
      last_taken = run.frames();
      estimates.Start(run.Snapshot(), f.index,
                      live.preview ? LiveEstimates::Kind::kPreview : LiveEstimates::Kind::kWhilePlaying);
    }
  }
  source.reset();  // a file player's threads stop with it
  if (run.frames() == 0) throw InputError(input, "has no frames");
  const double ended = clock.Seconds();
  std::printf("input ended after %.1f s: %lld frames read, %lld dropped (late), %lld tracked, %lld lost\n", ended,
              static_cast<long long>(read), static_cast<long long>(dropped), static_cast<long long>(run.tracked()),
              static_cast<long long>(run.lost()));
  // The whole scan supersedes a running estimate of an older snapshot: it stops, and the
  // last ones (warm from the last finished) start at once: a preview first (its lights in
  // seconds), then the full estimate (after a preview of the whole scan, whenever it came).
  const bool changed = last_taken != run.frames();
  if (changed) estimates.Cancel();
  const SceneBundle bundle = run.Finish();  // while the running estimate stops (or ends)
  estimates.Wait();
  if (changed && live.preview) estimates.RunOn(bundle, f.index, LiveEstimates::Kind::kPreview);
  WriteSceneBundle((fs::path(out) / "scene").string(), bundle);
  if (changed || live.preview) estimates.RunOn(bundle, f.index, LiveEstimates::Kind::kLast);
  std::printf("live done: %d estimate(s) finished, the last %.1f s after the input ended; %s (scene bundle), %s "
              "(the latest estimate), %s (each, and live.csv)\n",
              estimates.finished(), clock.Seconds() - ended, (fs::path(out) / "scene").c_str(),
              (fs::path(out) / "estimate").c_str(), (fs::path(out) / "live").c_str());
}

}  // namespace lp::app
