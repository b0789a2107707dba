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
#include "ui/estimate_job.h"
#include "ui/recording.h"

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

const char* ToString(ExportState s) {
  switch (s) {
    case ExportState::kIdle: return "idle";
    case ExportState::kExporting: return "exporting";
    case ExportState::kExported: return "exported";
    case ExportState::kFailed: return "failed";
  }
  return "?";
}

struct Session::Impl {
  SessionOptions options;

  // Published state (read by the main thread).
  mutable std::mutex mutex;
  LiveStatus live;

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
  std::unique_ptr<ReconstructionRun> run;  // the reconstruction, as `reconstruct` runs it
  ReconstructionRunOptions rec_options;
  bool playing = false, reconstructing = false, fused_any = false;
  double speed = 1;
  double pace_wall0 = 0, pace_stamp0 = -1;  // playback clock: wall time of the frame stamp0
  Stopwatch clock;
  Stopwatch since_mesh;
  std::deque<double> read_times, processed_times;

  // Estimation: one job per press of Estimate (its thread, cancel token and status).
  // `job` is replaced under `mutex` by the main thread (Estimate) and the worker (a new
  // source); replaced jobs are cancelled and handed to the next job's thread to be joined
  // there (`retired` until one starts), so neither thread waits for an estimate to stop.
  std::unique_ptr<EstimateJob> job;
  std::vector<std::unique_ptr<EstimateJob>> retired;
  EstimateStatus idle;  // what estimate() shows without a job (its counters go on)
  // Live estimation (SetLive; worker-owned but for the flag, read by the main thread too).
  std::atomic<bool> live_on{false};
  EstimateOptions live_options;  // under `mutex`
  LiveTrigger trigger;
  Eigen::Matrix4d live_pose = Eigen::Matrix4d::Identity();  // the last tracked pose
  int live_started = 0;
  /// The run's frames when the last full estimate (not a preview; a pressed one too) took
  /// its snapshot.
  std::int64_t full_frames = -1;
  // Export: one at a time, on its own thread.
  std::thread exporter;
  std::atomic<bool> exporting{false};
  ExportState export_state = ExportState::kIdle;  // under `mutex`
  std::string export_message;                     // under `mutex`
  Recording recording;  // worker-owned (RequestStop from any thread)

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
  /// The status a new job (or none) starts from: the counters go on from the current one,
  /// so the window re-uploads what changed. Call under `mutex`.
  EstimateStatus Fresh() const {
    const EstimateStatus current = job ? job->status() : idle;
    EstimateStatus fresh;
    fresh.version = current.version + 1;
    fresh.lit_version = current.lit_version + 1;
    return fresh;
  }
  /// Replaces the job (under `mutex`): the old one is cancelled and retired.
  void ReplaceJob(std::unique_ptr<EstimateJob> next) {
    idle = Fresh();
    if (job) {
      job->Retire();
      retired.push_back(std::move(job));
    }
    job = std::move(next);
  }
  /// A new job's settings (under `mutex`): `estimate`, started now, its status's counters
  /// going on from the current job's.
  EstimateJob::Settings JobSettings(const EstimateOptions& estimate) const {
    EstimateJob::Settings settings;
    settings.options = estimate;
    settings.lit_samples = options.lit_samples;
    settings.clock = &clock;
    settings.pressed_at = clock.Seconds();
    const EstimateStatus fresh = Fresh();
    settings.version = fresh.version;
    settings.lit_version = fresh.lit_version;
    return settings;
  }
  /// A job of `settings` replaces the current one (under `mutex`); returns it.
  EstimateJob* ReplaceJob(EstimateJob::Settings settings) {
    auto next = std::make_unique<EstimateJob>(std::move(settings));
    EstimateJob* started = next.get();
    ReplaceJob(std::move(next));
    return started;
  }
  /// Forgets the estimate (a new source or a reset model): the 3D view shows the live model.
  void ClearEstimate() {
    std::lock_guard<std::mutex> lock(mutex);
    ReplaceJob(nullptr);
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
    if (auto u = recording.Close()) Publish(*u);  // a recording finishes with the frames so far
    capture.reset();
    queue.reset();
    source.reset();
    bundle.reset();
    playing = false;
  }

  void ResetModel() {
    ClearEstimate();
    run.reset();
    fused_any = false;
    trigger = LiveTrigger(options.live_trigger);
    live_started = 0;
    full_frames = -1;
    try {
      run = std::make_unique<ReconstructionRun>(rec_options);
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
      const RecordState record_state = l.record_state;
      l = LiveStatus{};
      l.model_version = model_version + 1;
      l.frame_version = frame_version + 1;
      l.record_message = std::move(record_message);
      l.record_state = record_state;
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
        std::shared_ptr<LiveRecorder> recorder;
        auto dev = OpenOpenNiDevice(o, nullptr, &recorder);
        recording.Attach(std::move(recorder));
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
    if (!run || !fused_any) return;
    auto mesh = std::make_shared<Mesh>(
        run->reconstructor().volume().ExtractMesh(rec_options.reconstruction.mesh_min_weight));
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
    if (reconstructing && run) {
      try {
        report = run->Process(*shared);
        processed = true;
        if (report.state == TrackingState::kTracking) fused_any = true;
      } catch (const std::exception& e) {
        reconstructing = false;
        Fail(e.what());
      }
    }
    if (processed) CountRate(&processed_times, clock.Seconds());
    if (processed && report.state == TrackingState::kTracking) {
      live_pose = report.world_from_camera;
      MaybeStartLive();
    }
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
          PollRecording();  // its stop and time limit do not wait for the queue to drain
        } catch (const std::exception& e) {
          Fail(e.what());
        }
        --pending;
        continue;
      }
      try {
        PollRecording();
        if (!Step()) MaybeStartLive(true);  // stopped: the scan's last frames, once
      } catch (const std::exception& e) {  // nothing may escape the worker
        StopPlaying(e.what());
      }
    }
  }

  // ---- estimation ----

  /// On the worker, between frames: the scene to estimate. A loaded bundle is the scene; a
  /// reconstruction gives a snapshot (a copy of its volume and keyframes, milliseconds),
  /// finished into a bundle on the job's thread so playback does not wait for meshing.
  SceneSource Snapshot() {
    if (bundle) return bundle;
    if (!run || !fused_any)
      throw InputError("nothing reconstructed yet: start the reconstruction and play some frames first");
    return run->Snapshot();
  }

  /// On the worker, after a tracked frame: a live preview (LivePreview), when live
  /// estimation is on, the model has changed enough since the last one's snapshot, and the
  /// last one has its result (or failed, or none runs); warm-started from that result. With
  /// `stopped` (the input paused or at its end), a full estimate once the one running has
  /// its result, when a frame came since the last full one's snapshot: the scan's last
  /// frames get one, as `--headless --live`'s last estimate.
  void MaybeStartLive(bool stopped = false) {
    if (!live_on || !run || !fused_any) return;
    if (stopped ? run->frames() == full_frames : !trigger.Due(*run, live_pose)) return;
    EstimateJob* started;
    {
      std::lock_guard<std::mutex> lock(mutex);
      EstimateStatus last = job ? job->status() : idle;
      const bool running = last.state == EstimateState::kPreparing || last.state == EstimateState::kRunning;
      // Its own result (a live job shows the last one's until it has its own).
      const bool has_result = last.HasOwnResult();
      if (running && !has_result) return;  // the last one still estimating
      EstimateJob::Settings settings = JobSettings(stopped ? live_options : LivePreview(live_options));
      if (last.result) settings.options.warm = WarmStartOf(*last.result);
      settings.shown = std::make_shared<const EstimateStatus>(std::move(last));
      settings.live = true;
      settings.live_index = live_started + 1;
      settings.preview = !stopped;
      started = ReplaceJob(std::move(settings));
    }
    trigger.Taken(*run, live_pose);
    ++live_started;
    UpdateLive([&](LiveStatus& l) { l.live_estimates = live_started; });
    StartJob(started, stopped);
  }

  /// On the worker: starts `target` (if it is still the current job) on a snapshot; `full`:
  /// not a preview.
  void StartJob(EstimateJob* target, bool full = true) {
    SceneSource snapshot;
    std::string error;
    try {
      snapshot = Snapshot();
      if (run && full) full_frames = run->frames();
    } catch (const std::exception& e) {
      error = e.what();
    }
    std::lock_guard<std::mutex> lock(mutex);
    if (job.get() != target) return;  // replaced (or cleared) before it started
    if (!error.empty()) return job->Fail(error);
    std::vector<std::unique_ptr<EstimateJob>> joined_there;
    joined_there.swap(retired);
    job->Start(std::move(snapshot), std::move(joined_there));
  }

  void DoExport(const std::string& dir, const std::vector<ExportFormat>& formats) {
    std::shared_ptr<const SceneBundle> scene;
    std::shared_ptr<const EstimateResult> result;
    EstimateOptions used;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (job) {
        const EstimateStatus st = job->status();
        scene = st.scene;
        result = st.result;
        used = st.options;
        if (result && st.renders) {  // render_view* from the clean render so far
          auto clean = std::make_shared<EstimateResult>(*result);
          clean->renders = *st.renders;
          result = clean;
        }
      }
    }
    std::string message;
    bool ok = false;
    try {
      if (!scene || !result) throw InputError("nothing to export yet: run Estimate first");
      SceneBundle written = *scene;
      written.dir = fs::path(dir) / "scene";
      WriteSceneBundle(written.dir, written);
      if (options.write_estimate) options.write_estimate((fs::path(dir) / "estimate").string(), written, used, *result);
      message = "exported " + (fs::path(dir) / "scene").string() + " and " + (fs::path(dir) / "estimate").string();
      if (!formats.empty()) {
        if (!options.write_estimate) throw InputError("no estimate writer: the formats need lights.json");
        const ExportScene exported = LoadExportScene(fs::path(dir) / "scene", fs::path(dir) / "estimate");
        for (ExportFormat f : formats) {
          WriteExport(exported, f, fs::path(dir) / ToString(f));
          message += std::string(", ") + ToString(f);
        }
      }
      ok = true;
    } catch (const std::exception& e) {
      message = std::string("export failed: ") + e.what();
    }
    std::lock_guard<std::mutex> lock(mutex);
    export_state = ok ? ExportState::kExported : ExportState::kFailed;
    export_message = message;
  }

  /// The recording's state as the live panel shows it.
  void Publish(const RecordingUpdate& u) {
    UpdateLive([&](LiveStatus& l) {
      l.record_state = u.state;
      l.recording = u.state == RecordState::kRecording;
      l.recorded_frames = u.frames;
      l.recorded_seconds = u.seconds;
      if (u.message.empty()) return;  // progress
      l.record_message = u.message;
      if (u.state == RecordState::kFailed) l.error = u.message;
      if (u.state == RecordState::kRecording) l.error.clear();
    });
  }

  void DoRecord(const std::string& path, double seconds) { Publish(recording.Start(path, seconds)); }

  /// On the worker, between frames: the recording's progress, its end (its time is up or
  /// StopRecording was called), or its end without us (the camera was unplugged).
  void PollRecording() {
    if (auto u = recording.Poll()) Publish(*u);
  }
};

Session::Session(SessionOptions options) : impl_(std::make_unique<Impl>()) {
  impl_->options = std::move(options);
  impl_->rec_options = impl_->options.reconstruction;
  impl_->trigger = LiveTrigger(impl_->options.live_trigger);
  impl_->live_on = impl_->options.live;
  impl_->live.live_estimation = impl_->options.live;
  impl_->worker = std::thread([this] { impl_->Run(); });
}

Session::~Session() {
  impl_->stop = true;
  impl_->command_cv.notify_all();
  if (impl_->worker.joinable()) impl_->worker.join();
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->ReplaceJob(nullptr);  // cancelled, joined below
  }
  impl_->retired.clear();
  if (impl_->exporter.joinable()) impl_->exporter.join();  // an export finishes: nothing half-written
  impl_->CloseSource();  // a recording finishes its file with the frames so far
}

void Session::Record(const std::string& path, double seconds) {
  impl_->Post([this, path, seconds] { impl_->DoRecord(path, seconds); });
}

void Session::StopRecording() { impl_->recording.RequestStop(); }

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
    if (!s.run) s.ResetModel();
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
  impl_->Post([this, options] {
    ReconstructionRunOptions& r = impl_->rec_options;
    const Calibration calibration = r.reconstruction.calibration;
    r.reconstruction = options;
    if (r.calibrated) r.reconstruction.calibration = calibration;  // `view --calibration` stays
  });
}

void Session::Estimate(const EstimateOptions& options) {
  Impl& m = *impl_;
  EstimateJob* started;
  {
    std::lock_guard<std::mutex> lock(m.mutex);
    started = m.ReplaceJob(m.JobSettings(options));  // a running estimate stops at its next check
  }
  m.Post([this, started] { impl_->StartJob(started); });
}

void Session::SetLive(bool on, const EstimateOptions& options) {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->live_options = options;
    impl_->live.live_estimation = on;
  }
  impl_->live_on = on;
}

void Session::CancelEstimate() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->job) impl_->job->Cancel();
}

void Session::Export(const std::string& dir, const std::vector<ExportFormat>& formats) {
  if (impl_->exporting.exchange(true)) {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->export_message = "exporting: wait for the export in progress";
    return;
  }
  if (impl_->exporter.joinable()) impl_->exporter.join();  // finished: exporting was false
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->export_state = ExportState::kExporting;
    impl_->export_message = "exporting to " + dir;
  }
  impl_->exporter = std::thread([this, dir, formats] {
    impl_->DoExport(dir, formats);
    impl_->exporting = false;
  });
}

LiveStatus Session::live() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->live;
}

EstimateStatus Session::estimate() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  EstimateStatus s = impl_->job ? impl_->job->status() : impl_->idle;
  s.export_state = impl_->export_state;
  s.export_message = impl_->export_message;
  return s;
}

double Session::seconds() const { return impl_->clock.Seconds(); }

bool Session::busy() const { return impl_->pending.load() > 0; }

}  // namespace lp::ui
