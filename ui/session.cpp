#include "ui/session.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <mutex>
#include <thread>
#include <variant>

#include "capture/capture_thread.h"
#include "capture/frame_source.h"
#include "capture/openni.h"
#include "common/error.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "estimation/ray_tracer.h"
#include "estimation/truth.h"
#include "estimation/vertex_radiance.h"

namespace lp::ui {
namespace fs = std::filesystem;

const char* ToString(EstimateState s) {
  switch (s) {
    case EstimateState::kIdle: return "idle";
    case EstimateState::kPreparing: return "preparing";
    case EstimateState::kRunning: return "running";
    case EstimateState::kDone: return "done";
    case EstimateState::kCancelled: return "cancelled";
    case EstimateState::kFailed: return "failed";
  }
  return "?";
}

struct Session::Impl {
  SessionOptions options;

  // Published state (read by the main thread).
  mutable std::mutex mutex;
  LiveStatus live;
  EstimateStatus est;

  // Commands for the worker.
  std::mutex command_mutex;
  std::condition_variable command_cv;
  std::deque<std::function<void()>> commands;
  std::atomic<int> pending{0};
  std::atomic<bool> stop{false};

  // Worker-owned (only the worker thread touches these).
  std::unique_ptr<FrameSource> source;        // files, directories: pulled directly
  std::shared_ptr<FrameQueue> queue;          // a camera: through a capture thread
  std::unique_ptr<CaptureThread> capture;
  std::shared_ptr<const SceneBundle> bundle;  // a loaded scene bundle
  std::unique_ptr<Reconstructor> reconstructor;
  ReconstructionOptions rec_options;
  bool playing = false, reconstructing = false, fused_any = false;
  double speed = 1;
  double pace_wall0 = 0, pace_stamp0 = -1;  // playback clock: wall time of the frame stamp0
  Stopwatch clock;
  Stopwatch since_mesh;
  std::deque<double> read_times, processed_times;

  // Estimation worker.
  // Each Estimate press is a generation; an estimate stops when a newer one is pressed,
  // when its own generation is cancelled, or at shutdown, and its reports are dropped
  // once it is not the latest.
  std::thread estimator;
  std::atomic<std::uint64_t> generation{0}, cancelled_generation{0};
  std::thread exporter;
  std::atomic<bool> exporting{false};
  std::atomic<int> record_stop_requests{0};  // StopRecording presses so far
  std::shared_ptr<LiveRecorder> recorder;  // worker-owned: the open camera's
  double record_seconds = 0;               // worker-owned: the recording's length (<= 0: no limit)
  std::string record_path;                 // worker-owned: the recording's file
  bool record_started = false;             // worker-owned: a recording this session has not reported
  int record_stop_seen = 0;                // worker-owned: record_stop_requests when it started

  std::thread worker;

  void Post(std::function<void()> f) {
    ++pending;
    {
      std::lock_guard<std::mutex> lock(command_mutex);
      commands.push_back(std::move(f));
    }
    command_cv.notify_one();
  }

  template <typename F>
  void UpdateLive(F f) {
    std::lock_guard<std::mutex> lock(mutex);
    f(live);
  }
  template <typename F>
  void UpdateEstimate(F f) {
    std::lock_guard<std::mutex> lock(mutex);
    f(est);
  }
  /// The same, only while `gen` is the latest estimate.
  template <typename F>
  void UpdateEstimate(std::uint64_t gen, F f) {
    std::lock_guard<std::mutex> lock(mutex);
    if (gen == generation.load()) f(est);
  }
  bool Stopped(std::uint64_t gen) const {
    return stop.load() || gen != generation.load() || cancelled_generation.load() >= gen;
  }
  /// Forgets the estimate (a new source or a reset model): the 3D view shows the live model.
  void ClearEstimate() {
    std::lock_guard<std::mutex> lock(mutex);
    const std::uint64_t gen = ++generation;
    cancelled_generation = gen;
    Restart(&est);
  }

  /// An empty status that still counts versions up (the window re-uploads what changed)
  /// and keeps the last export's outcome.
  static void Restart(EstimateStatus* s) {
    EstimateStatus fresh;
    fresh.version = s->version + 1;
    fresh.lit_version = s->lit_version + 1;
    fresh.export_message = s->export_message;
    *s = std::move(fresh);
  }

  void Fail(const std::string& what) {
    UpdateLive([&](LiveStatus& l) { l.error = what; });
  }

  /// Playback stops on an error (a source that failed or ended badly).
  void StopPlaying(const std::string& error) {
    playing = false;
    UpdateLive([&](LiveStatus& l) {
      l.playing = false;
      l.error = error;
    });
  }

  void CloseSource() {
    if (recorder && recorder->recording()) FinishRecording();
    else if (record_started) ReportEndedWithoutStop();  // unplugged, not yet polled
    record_started = false;
    recorder.reset();
    capture.reset();
    queue.reset();
    source.reset();
    bundle.reset();
    playing = false;
  }

  void ResetModel() {
    ClearEstimate();
    reconstructor.reset();
    fused_any = false;
    try {
      reconstructor = std::make_unique<Reconstructor>(rec_options);
    } catch (const std::exception& e) {
      Fail(e.what());
    }
    UpdateLive([&](LiveStatus& l) {
      l.model.reset();
      ++l.model_version;
      l.frames_tracked = l.frames_lost = 0;
      l.tracking = TrackingState::kWaiting;
      l.tracking_reason.clear();
      l.has_pose = false;
    });
  }

  void DoOpen(std::string input) {
    CloseSource();
    reconstructing = false;
    ResetModel();
    UpdateLive([&](LiveStatus& l) {
      const std::uint64_t model_version = l.model_version, frame_version = l.frame_version;
      std::string record_message = std::move(l.record_message);
      l = LiveStatus{};
      l.model_version = model_version + 1;
      l.frame_version = frame_version + 1;
      l.record_message = std::move(record_message);
    });
    std::string note;
    if (input == "auto") {  // an attached camera, else the bundled demo
      try {
        auto probe = OpenOpenNiDevice(OpenNiDeviceOptions{});
        probe.reset();
        input = "camera";
      } catch (const std::exception& e) {
        input = "demo";
        note = "no camera found: opened the bundled demo recording";
      }
    }
    if (input == "demo") input = options.demo_input;
    try {
      std::string description;
      bool camera = false, is_bundle = false;
      std::int64_t count = -1;
      if (input == "camera" || input.rfind("camera:", 0) == 0) {
        OpenNiDeviceOptions o;
        if (input.size() > 7) o.uri = input.substr(7);
        auto dev = OpenOpenNiDevice(o, nullptr, &recorder);
        description = dev->Describe();
        queue = std::make_shared<FrameQueue>(4);
        capture = std::make_unique<CaptureThread>(std::move(dev), queue);
        camera = true;
        playing = true;
      } else if (fs::is_directory(input) && fs::exists(fs::path(input) / "scene.json")) {
        bundle = std::make_shared<const SceneBundle>(LoadSceneBundle(input));
        description = "scene bundle " + input + " (" + std::to_string(bundle->mesh.triangles.size()) +
                      " triangles, " + std::to_string(bundle->views.size()) + " views)";
        is_bundle = true;
      } else {
        source = OpenFrameSource(input);
        description = source->Describe();
        if (auto n = source->FrameCount()) count = *n;
      }
      auto model = bundle ? std::make_shared<const Mesh>(bundle->mesh) : nullptr;
      UpdateLive([&](LiveStatus& l) {
        l.source = description;
        l.open = true;
        l.is_camera = camera;
        l.is_bundle = is_bundle;
        l.error = note;
        l.frame_count = count;
        l.playing = playing;
        l.speed = speed;
        if (model) {
          l.model = model;
          ++l.model_version;
        }
      });
    } catch (const std::exception& e) {
      CloseSource();
      Fail(e.what());
    }
  }

  static void CountRate(std::deque<double>* times, double now) {
    times->push_back(now);
    while (!times->empty() && times->front() < now - 1.0) times->pop_front();
  }
  static double Rate(const std::deque<double>& times) {
    if (times.size() < 2) return 0;
    return (times.size() - 1) / std::max(1e-6, times.back() - times.front());
  }

  void PublishModel() {
    if (!reconstructor || !fused_any) return;
    auto mesh = std::make_shared<Mesh>(reconstructor->volume().ExtractMesh(rec_options.mesh_min_weight));
    if (mesh->normals.size() != mesh->positions.size()) ComputeVertexNormals(mesh.get());
    UpdateLive([&](LiveStatus& l) {
      l.model = std::move(mesh);
      ++l.model_version;
    });
    since_mesh.Reset();
  }

  /// Reads and handles one frame when playing; returns false when there was nothing to do.
  bool Step() {
    if (!playing || (!source && !queue)) return false;
    RgbdFrame frame;
    if (queue) {
      auto f = queue->Pop(0.05);
      if (!f) {
        const CaptureStats st = capture->stats();
        if (!st.running)
          StopPlaying(st.error.empty() ? std::string("camera stopped: ") + ToString(st.last_status) : st.error);
        return true;
      }
      frame = std::move(*f);
    } else {
      SourceStatus s;
      try {
        s = source->Next(&frame, 0.05);
      } catch (const std::exception& e) {
        StopPlaying(e.what());
        return true;
      }
      if (s == SourceStatus::kTimeout) return true;
      if (s != SourceStatus::kFrame) {
        playing = false;
        PublishModel();
        UpdateLive([&](LiveStatus& l) {
          l.playing = false;
          l.at_end = true;
        });
        return true;
      }
      Pace(frame);
    }
    const double now = clock.Seconds();
    CountRate(&read_times, now);
    auto shared = std::make_shared<const RgbdFrame>(std::move(frame));
    FrameReport report;
    bool processed = false;
    if (reconstructing && reconstructor) {
      try {
        report = reconstructor->Process(*shared);
        processed = true;
        if (report.state == TrackingState::kTracking) fused_any = true;
      } catch (const std::exception& e) {
        reconstructing = false;
        Fail(e.what());
      }
    }
    if (processed) CountRate(&processed_times, clock.Seconds());
    const std::int64_t dropped = capture ? capture->stats().queue.dropped : 0;
    UpdateLive([&](LiveStatus& l) {
      l.frame = shared;
      ++l.frame_version;
      l.position = shared->index + 1;
      ++l.frames_read;
      l.dropped = dropped;
      l.source_fps = Rate(read_times);
      l.processed_fps = Rate(processed_times);
      l.reconstructing = reconstructing;
      if (processed) {
        l.tracking = report.state;
        l.tracking_reason = report.reason;
        if (report.state == TrackingState::kTracking) ++l.frames_tracked;
        if (report.state == TrackingState::kLost) ++l.frames_lost;
        l.has_pose = report.state != TrackingState::kWaiting;
        l.camera_pose = report.world_from_camera;
      } else if (shared->world_from_camera) {
        l.has_pose = true;
        l.camera_pose = *shared->world_from_camera;
      }
    });
    if (processed && since_mesh.Seconds() > 0.5) PublishModel();
    return true;
  }

  /// Holds a file's frame until its time at the chosen speed (0 = no waiting).
  void Pace(const RgbdFrame& frame) {
    const double stamp = frame.depth_timestamp;
    if (speed <= 0 || !(stamp > 0)) return;
    const double now = clock.Seconds();
    if (pace_stamp0 < 0 || stamp < pace_stamp0 || now - (pace_wall0 + (stamp - pace_stamp0) / speed) > 0.25) {
      pace_stamp0 = stamp;  // first frame, a seek, or we fell behind: restart the clock
      pace_wall0 = now;
      return;
    }
    const double due = pace_wall0 + (stamp - pace_stamp0) / speed;
    while (!stop && pending.load() == 0 && clock.Seconds() < due)
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }

  void Run() {
    while (!stop) {
      std::function<void()> command;
      {
        std::unique_lock<std::mutex> lock(command_mutex);
        if (commands.empty() && !playing) command_cv.wait_for(lock, std::chrono::milliseconds(50));
        if (!commands.empty()) {
          command = std::move(commands.front());
          commands.pop_front();
        }
      }
      if (command) {
        try {
          command();
          PollRecording();  // its Stop and time limit do not wait for the queue to drain
        } catch (const std::exception& e) {
          Fail(e.what());
        }
        --pending;
        continue;
      }
      try {
        PollRecording();
        Step();
      } catch (const std::exception& e) {  // nothing may escape the worker
        StopPlaying(e.what());
      }
    }
  }

  // ---- estimation ----

  /// A scene to estimate: a loaded bundle, or a reconstruction's snapshot still to finish.
  using SceneSource = std::variant<std::shared_ptr<const SceneBundle>, ReconstructionSnapshot>;

  /// On the worker, between frames: the scene to estimate. A loaded bundle is the scene; a
  /// reconstruction gives a snapshot (a copy of its volume and keyframes, milliseconds),
  /// finished into a bundle on the estimating thread so playback does not wait for meshing.
  SceneSource Snapshot() {
    if (bundle) return bundle;
    if (!reconstructor || !fused_any)
      throw InputError("nothing reconstructed yet: start the reconstruction and play some frames first");
    return reconstructor->Snapshot();
  }

  void DoEstimate(const EstimateOptions& options, double pressed_at, std::uint64_t gen) {
    if (Stopped(gen)) return;  // cancelled or replaced before it started
    SceneSource snapshot;
    try {
      snapshot = Snapshot();
    } catch (const std::exception& e) {
      UpdateEstimate(gen, [&](EstimateStatus& s) {
        s.state = EstimateState::kFailed;
        s.message = e.what();
      });
      return;
    }
    bool cancelled = false;
    UpdateEstimate(gen, [&](EstimateStatus& s) {
      // Checked under the status lock, as CancelEstimate sets it: a Cancel that came while
      // the snapshot was taken is not overwritten.
      if ((cancelled = Stopped(gen))) {
        s.state = EstimateState::kCancelled;
        s.message = "cancelled";
        return;
      }
      Restart(&s);
      s.state = EstimateState::kPreparing;  // until the scene is built: Cancel ends it at once
      s.message = "building the scene (mesh, keyframes)";
      s.options = options;
    });
    if (cancelled || Stopped(gen)) return;  // (replaced by a newer Estimate: not ours to update)
    // The previous estimate (already told to stop) is joined by the new thread, not here:
    // the worker keeps reading frames and commands meanwhile.
    std::thread previous = std::move(estimator);
    estimator = std::thread([this, options, snapshot = std::move(snapshot), pressed_at, gen,
                             previous = std::move(previous)]() mutable {
      if (previous.joinable()) previous.join();
      // The window (and Mesa's rasterizer threads) comes first: the estimate takes the CPU
      // it leaves (its loops' workers too).
      RunThisThreadInBackground();
      RunEstimate(options, std::move(snapshot), pressed_at, gen);
    });
  }

  /// On the estimator thread: builds the scene from a snapshot (a loaded bundle is one),
  /// estimates its lighting, then refines the lit shading.
  void RunEstimate(EstimateOptions options, SceneSource snapshot, double pressed_at, std::uint64_t gen) {
    options.cancelled = [this, gen] { return Stopped(gen); };
    options.progress = [this, gen](const std::string& line) {
      UpdateEstimate(gen, [&](EstimateStatus& s) { s.message = line; });
    };
    options.on_convergence = [this, gen](const ConvergenceRow& row) {
      UpdateEstimate(gen, [&](EstimateStatus& s) { s.rows.push_back(row); });
    };
    const int max_rounds = options.max_rounds * (1 + std::max(0, options.albedo_passes));  // an upper bound
    options.on_round = [this, pressed_at, max_rounds, gen](const RoundInfo& info, const EnvMap& env) {
      auto dominant = DominantDirections(env, info.lambda, 2);
      const double t = clock.Seconds() - pressed_at;
      UpdateEstimate(gen, [&](EstimateStatus& s) {
        if (!s.env) s.env = std::make_shared<const EnvMap>(env);
        s.lambda = info.lambda;
        s.dominant = dominant;
        ++s.version;
        s.progress = static_cast<double>(info.round) / (max_rounds + 1);
        if (std::isnan(s.seconds_to_first)) s.seconds_to_first = t;
      });
    };
    std::shared_ptr<const SceneBundle> scene;
    std::shared_ptr<const EstimateResult> result;
    try {
      if (auto* loaded = std::get_if<std::shared_ptr<const SceneBundle>>(&snapshot)) scene = *loaded;
      else scene = std::make_shared<const SceneBundle>(std::get<ReconstructionSnapshot>(snapshot).Finish());
      if (Stopped(gen)) throw Cancelled();
      UpdateEstimate(gen, [&](EstimateStatus& s) {
        if (s.state == EstimateState::kCancelled) return;
        s.state = EstimateState::kRunning;
        s.message = "tracing round 1";
        s.scene = scene;
      });
      options.time_offset = clock.Seconds() - pressed_at;
      result = std::make_shared<const EstimateResult>(lp::Estimate(*scene, options));
    } catch (const Cancelled&) {
      UpdateEstimate(gen, [&](EstimateStatus& s) {
        s.state = EstimateState::kCancelled;
        s.message = "cancelled";
      });
      return;
    } catch (const std::exception& e) {
      UpdateEstimate(gen, [&](EstimateStatus& s) {
        s.state = EstimateState::kFailed;
        s.message = e.what();
      });
      return;
    }
    const double t = clock.Seconds() - pressed_at;
    UpdateEstimate(gen, [&](EstimateStatus& s) {
      s.state = EstimateState::kDone;
      s.progress = 1;
      s.result = result;
      s.lambda = result->lambda;
      s.dominant = result->dominant;
      if (!s.env) s.env = std::make_shared<const EnvMap>(result->env);
      ++s.version;
      s.seconds_total = t;
      s.message = "done in " + std::to_string(t).substr(0, 5) + " s";
      for (const std::string& w : result->warnings) s.message += "; warning: " + w;
    });
    RefineLit(*scene, *result, options.tracer.bounces, gen);
  }

  /// Progressive per-vertex radiance under the estimate, then the error against the keyframes.
  void RefineLit(const SceneBundle& scene, const EstimateResult& result, int bounces, std::uint64_t gen) {
    try {
      Mesh mesh = scene.mesh;
      if (result.albedo.size() == mesh.positions.size()) mesh.albedo = result.albedo;  // refined
      const RayTracer tracer(std::move(mesh));
      VertexRadiance radiance(tracer, result.env, result.lambda, std::max(1, bounces));
      int step = 2;
      // The error shading follows the radiance's noise down: recomputed at 2 samples, then
      // each time they have grown 4-fold (~1 s each on the demo), and at the end.
      int error_at = 2;
      while (radiance.samples() < options.lit_samples && !Stopped(gen)) {
        radiance.Refine(std::min(step, options.lit_samples - radiance.samples()));
        step = std::min(step * 2, 32);
        auto lit = std::make_shared<const std::vector<Eigen::Vector3f>>(radiance.Radiance());
        std::shared_ptr<const std::vector<float>> error;
        if (radiance.samples() >= options.lit_samples || radiance.samples() >= error_at) {
          error = std::make_shared<const std::vector<float>>(
              VertexPhotometricError(tracer, scene.views, *lit));
          error_at = 4 * radiance.samples();
        }
        const int samples = radiance.samples();
        UpdateEstimate(gen, [&](EstimateStatus& s) {
          s.lit = lit;
          if (error) s.error = error;
          s.lit_samples = samples;
          ++s.lit_version;
        });
      }
    } catch (const std::exception& e) {
      UpdateEstimate(gen, [&](EstimateStatus& s) { s.message = std::string("lit shading: ") + e.what(); });
    }
  }

  void DoExport(const std::string& dir) {
    std::shared_ptr<const SceneBundle> scene;
    std::shared_ptr<const EstimateResult> result;
    EstimateOptions used;
    {
      std::lock_guard<std::mutex> lock(mutex);
      scene = est.scene;
      result = est.result;
      used = est.options;
    }
    std::string message;
    try {
      if (!scene || !result) throw InputError("nothing to export yet: run Estimate first");
      SceneBundle written = *scene;
      written.dir = fs::path(dir) / "scene";
      WriteSceneBundle(written.dir, written);
      if (options.write_estimate) options.write_estimate((fs::path(dir) / "estimate").string(), written, used, *result);
      message = "exported " + (fs::path(dir) / "scene").string() + " and " + (fs::path(dir) / "estimate").string();
    } catch (const std::exception& e) {
      message = std::string("export failed: ") + e.what();
    }
    UpdateEstimate([&](EstimateStatus& s) { s.export_message = message; });
  }

  void DoRecord(const std::string& path, double seconds) {
    if (!recorder) {  // only a camera has one
      Fail("record: open a camera first (recording needs a live device)");
      return;
    }
    if (recorder->recording()) {
      Fail("record: already recording");
      return;
    }
    record_stop_seen = record_stop_requests.load();  // a Stop from now on ends this recording
    try {
      recorder->Start(path);
    } catch (const std::exception& e) {
      const std::string message = std::string("recording failed: ") + e.what();
      UpdateLive([&](LiveStatus& l) {
        l.record_message = message;
        l.error = message;
      });
      return;
    }
    record_seconds = seconds;
    record_path = path;
    record_started = true;
    UpdateLive([&](LiveStatus& l) {
      l.recording = true;
      l.recorded_frames = 0;
      l.recorded_seconds = 0;
      l.record_message = "recording to " + path;
      l.error.clear();
    });
  }

  /// On the worker, between frames: the recording's progress, its end (its time is up or
  /// StopRecording was called), or its end without us (the camera was unplugged).
  void PollRecording() {
    if (!recorder) return;
    if (recorder->recording()) {
      int frames = 0;
      double seconds = 0;
      recorder->Progress(&frames, &seconds);
      UpdateLive([&](LiveStatus& l) {
        l.recorded_frames = frames;
        l.recorded_seconds = seconds;
      });
      if (record_stop_requests.load() != record_stop_seen || (record_seconds > 0 && seconds >= record_seconds))
        FinishRecording();
    } else if (record_started) {
      ReportEndedWithoutStop();
    }
  }

  /// A recording the source finished by itself (the camera unplugged): its outcome.
  void ReportEndedWithoutStop() {
    record_started = false;
    const std::string ended = recorder ? recorder->EndedWithoutStop() : std::string();
    if (ended.empty()) return;
    UpdateLive([&](LiveStatus& l) {
      l.recording = false;
      l.record_message = ended;
      if (ended.rfind("recorded", 0) != 0) l.error = ended;
    });
  }

  void FinishRecording() {
    std::string message;
    bool ok = false;
    try {
      message = DescribeRecording(recorder->Stop(), record_path);
      ok = true;
    } catch (const std::exception& e) {
      // The source may have finished it first (unplugged while we asked): its outcome.
      const std::string ended = recorder->EndedWithoutStop();
      ok = ended.rfind("recorded", 0) == 0;
      message = ended.empty() ? std::string("recording failed: ") + e.what() : ended;
    }
    record_started = false;
    UpdateLive([&](LiveStatus& l) {
      l.recording = false;
      l.record_message = message;
      if (!ok) l.error = message;
    });
  }
};

Session::Session(SessionOptions options) : impl_(std::make_unique<Impl>()) {
  impl_->options = std::move(options);
  impl_->rec_options = impl_->options.reconstruction;
  impl_->worker = std::thread([this] { impl_->Run(); });
}

Session::~Session() {
  impl_->stop = true;
  impl_->command_cv.notify_all();
  if (impl_->worker.joinable()) impl_->worker.join();
  if (impl_->estimator.joinable()) impl_->estimator.join();
  if (impl_->exporter.joinable()) impl_->exporter.join();  // an export finishes: nothing half-written
  impl_->CloseSource();  // a recording finishes its file with the frames so far
}

void Session::Record(const std::string& path, double seconds) {
  impl_->Post([this, path, seconds] { impl_->DoRecord(path, seconds); });
}

void Session::StopRecording() { ++impl_->record_stop_requests; }

void Session::Open(const std::string& input) {
  impl_->Post([this, input] { impl_->DoOpen(input); });
}

void Session::SetPlaying(bool playing) {
  impl_->Post([this, playing] {
    Impl& s = *impl_;
    if (!s.source && !s.queue) return;
    s.playing = playing;
    s.pace_stamp0 = -1;
    if (s.capture) s.capture->Pause(!playing);
    if (!playing) s.PublishModel();
    s.UpdateLive([&](LiveStatus& l) {
      l.playing = playing;
      if (playing) l.at_end = false;
    });
  });
}

void Session::Seek(std::int64_t frame) {
  impl_->Post([this, frame] {
    Impl& s = *impl_;
    if (!s.source) throw InputError("seek: only files and directories can seek");
    s.source->Seek(frame);
    s.pace_stamp0 = -1;
    s.UpdateLive([&](LiveStatus& l) {
      l.position = frame;
      l.at_end = false;
    });
  });
}

void Session::SetSpeed(double speed) {
  impl_->Post([this, speed] {
    impl_->speed = std::max(0.0, speed);
    impl_->pace_stamp0 = -1;
    impl_->UpdateLive([&](LiveStatus& l) { l.speed = impl_->speed; });
  });
}

void Session::StartReconstruction() {
  impl_->Post([this] {
    Impl& s = *impl_;
    if (s.bundle) throw InputError("a loaded scene bundle is already reconstructed");
    if (!s.reconstructor) s.ResetModel();
    s.reconstructing = true;
    s.UpdateLive([&](LiveStatus& l) { l.reconstructing = true; });
  });
}

void Session::StopReconstruction() {
  impl_->Post([this] {
    impl_->reconstructing = false;
    impl_->PublishModel();
    impl_->UpdateLive([&](LiveStatus& l) { l.reconstructing = false; });
  });
}

void Session::ResetReconstruction() {
  impl_->Post([this] { impl_->ResetModel(); });
}

void Session::SetReconstructionOptions(const ReconstructionOptions& options) {
  impl_->Post([this, options] { impl_->rec_options = options; });
}

void Session::Estimate(const EstimateOptions& options) {
  const double pressed = impl_->clock.Seconds();
  std::uint64_t gen;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    gen = ++impl_->generation;  // a running estimate stops at its next check
    EstimateStatus& s = impl_->est;
    s.state = EstimateState::kPreparing;
    s.message = "taking a snapshot of the scene";
    s.rows.clear();
    s.progress = 0;
    s.seconds_to_first = s.seconds_total = std::nan("");
    s.lit_samples = 0;
  }
  impl_->Post([this, options, pressed, gen] { impl_->DoEstimate(options, pressed, gen); });
}

void Session::CancelEstimate() {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mutex);
  m.cancelled_generation = m.generation.load();
  if (m.est.state == EstimateState::kPreparing) {
    m.est.state = EstimateState::kCancelled;
    m.est.message = "cancelled";
  }
}

void Session::Export(const std::string& dir) {
  if (impl_->exporting.exchange(true)) {
    impl_->UpdateEstimate([&](EstimateStatus& s) { s.export_message = "exporting: wait for the export in progress"; });
    return;
  }
  if (impl_->exporter.joinable()) impl_->exporter.join();  // finished: exporting was false
  impl_->UpdateEstimate([&](EstimateStatus& s) { s.export_message = "exporting to " + dir; });
  impl_->exporter = std::thread([this, dir] {
    impl_->DoExport(dir);
    impl_->exporting = false;
  });
}

LiveStatus Session::live() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->live;
}

EstimateStatus Session::estimate() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->est;
}

bool Session::busy() const { return impl_->pending.load() > 0; }

}  // namespace lp::ui
