// The viewer's command file (docs/viewer.md): drives the window as a user would, one
// command per line, for tests and benchmarks. Commands that wait keep the window live.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>

#include "common/atomic_file.h"
#include "common/error.h"
#include "ui/viewer_internal.h"

namespace lp::ui {

namespace {

/// The error for one line of the script at `path`.
InputError LineError(const std::string& path, const ScriptLine& line, const std::string& why) {
  return InputError(path, "line " + std::to_string(line.number) + " (" + line.words[0] + "): " + why);
}

double Number(const ScriptLine& line, std::size_t i, double fallback) {
  if (i >= line.words.size()) return fallback;
  try {
    std::size_t used = 0;
    const double v = std::stod(line.words[i], &used);
    if (used == line.words[i].size()) return v;
  } catch (const std::exception&) {
  }
  throw InputError("line " + std::to_string(line.number) + ": not a number: " + line.words[i]);
}

/// The viewer as the script's commands see it: the session they post to, the statuses they
/// wait on and the window's own state they change. ScriptRunner, the viewer's friend, lends
/// these out line by line (ScriptRunner::Run).
struct ViewerParts {
  Session& session;
  const LiveStatus& live;
  const EstimateStatus& est;
  EstimateOptions& settings;  ///< what the Estimate panel shows
  Shading& shading;
  int& selected_keyframe;
  OrbitCamera& camera;
  const std::string& pending_screenshot;
  std::function<void(const std::string&)> screenshot, write_state;
  // The frame-time benchmark.
  std::vector<double>& bench_seconds;
  bool& bench_orbit;
  std::uint64_t& bench_scene_renders_start;
  const std::uint64_t& scene_renders;
  int& bench_frames_left;
  bool& quit;
  GLFWwindow* window;
};

/// One script line while it runs.
struct Call {
  const std::string& path;  ///< the script
  const ScriptLine& line;
  int frames_waited;  ///< frames drawn since the line started
  double waited;      ///< seconds since the line started
  std::int64_t frames_read_at_start;  ///< the live panel's frames read when the line started
  ViewerParts& v;

  bool first() const { return frames_waited == 0; }
  const std::string& word(std::size_t i) const { return line.words[i]; }
  double Arg(std::size_t i, double fallback) const { return Number(line, i, fallback); }
  [[noreturn]] void Fail(const std::string& why) const { throw LineError(path, line, why); }
  void Timeout(double seconds, const char* what) const {
    if (waited > seconds) Fail(std::string("timed out after ") + std::to_string(seconds) + " s waiting for " + what);
  }
  /// A command posted to the session is done once the worker has taken and handled it.
  bool Handled() const { return !v.session.busy() && frames_waited > 0; }
};

// ---- the source ----

bool Open(const Call& c) {
  if (c.first()) c.v.session.Open(c.word(1));
  return c.Handled();
}

bool WaitOpen(const Call& c) {
  c.Timeout(c.Arg(1, 60), "the source to open");
  if (!c.v.live.error.empty() && !c.v.live.open) c.Fail(c.v.live.error);
  return c.v.live.open && !c.v.session.busy();
}

bool PlayOrPause(const Call& c) {
  if (c.first()) c.v.session.SetPlaying(c.word(0) == "play");
  return c.Handled();
}

bool Seek(const Call& c) {
  if (c.first()) c.v.session.Seek(static_cast<std::int64_t>(c.Arg(1, 0)));
  return c.Handled();
}

bool Speed(const Call& c) {
  if (c.first()) c.v.session.SetSpeed(c.Arg(1, 1));
  return c.Handled();
}

bool Reconstruct(const Call& c) {
  const std::string& what = c.word(1);
  if (c.first()) {
    if (what == "start") c.v.session.StartReconstruction();
    else if (what == "stop") c.v.session.StopReconstruction();
    else if (what == "reset") c.v.session.ResetReconstruction();
    else c.Fail("start, stop or reset, not " + what);
  }
  return c.Handled();
}

bool WaitEnd(const Call& c) {
  c.Timeout(c.Arg(1, 300), "the end of the source");
  return c.frames_waited > 1 && !c.v.session.busy() && !c.v.live.playing;
}

/// Waits until the source has delivered N more frames than when the line started (the
/// previews go on: while recording, playing, reconstructing).
bool WaitFrames(const Call& c) {
  c.Timeout(c.Arg(2, 120), "frames from the source");
  if (!c.v.live.error.empty() && !c.v.live.open) c.Fail(c.v.live.error);
  return c.v.live.frames_read >= c.frames_read_at_start + static_cast<std::int64_t>(c.Arg(1, 1));
}

bool Record(const Call& c) {
  if (c.first()) c.v.session.Record(c.word(1), c.Arg(2, 0));
  return c.Handled();  // the recording has started (or failed) when the next line runs
}

bool StopRecording(const Call& c) {
  c.v.session.StopRecording();
  return true;
}

/// The recording finished (its file in place).
bool WaitRecord(const Call& c) {
  c.Timeout(c.Arg(1, 120), "the recording");
  const LiveStatus& live = c.v.live;
  if (live.record_state == RecordState::kFailed) c.Fail(live.record_message);
  return live.record_state == RecordState::kRecorded && !c.v.session.busy();
}

// ---- the estimate ----

/// One `key=value` of an estimate line into `o`: any option of the command line's
/// `estimate` by its key (estimation/estimate_options.h), its range checked there.
void ApplySetting(const Call& c, const std::string& w, EstimateOptions* o) {
  const std::size_t eq = w.find('=');
  if (eq == std::string::npos) c.Fail("settings are key=value: " + w);
  try {
    SetEstimateOption(o, w.substr(0, eq), w.substr(eq + 1));
  } catch (const InputError& e) {
    c.Fail(e.what());
  }
}

bool StartEstimate(const Call& c) {
  if (c.first()) {
    EstimateOptions o = c.v.settings;
    for (std::size_t i = 1; i < c.line.words.size(); ++i) ApplySetting(c, c.word(i), &o);
    c.v.settings = o;  // the panel shows what was pressed
    c.v.session.Estimate(o);
  }
  return true;
}

/// `live on|off [key=value ...]`: the live switch, the live estimates' settings as `estimate`'s.
bool SetLive(const Call& c) {
  if (c.word(1) != "on" && c.word(1) != "off") c.Fail("live takes on or off: " + c.word(1));
  EstimateOptions o = c.v.settings;
  for (std::size_t i = 2; i < c.line.words.size(); ++i) ApplySetting(c, c.word(i), &o);
  c.v.settings = o;
  c.v.session.SetLive(c.word(1) == "on", o);
  return true;
}

/// `wait-live N [timeout]`: until the N-th live estimate (or a later one) has its result.
bool WaitLive(const Call& c) {
  c.Timeout(c.Arg(2, 600), "the live estimates");
  if (c.v.est.state == EstimateState::kFailed) c.Fail(c.v.est.message);
  const EstimateStatus& e = c.v.est;
  return e.live && (e.live_index > c.Arg(1, 1) || (e.live_index == c.Arg(1, 1) && e.HasOwnResult()));
}

/// `sleep S`: S seconds pass, the window and the workers going on.
bool Sleep(const Call& c) { return c.waited >= c.Arg(1, 0); }

bool Cancel(const Call& c) {
  c.v.session.CancelEstimate();
  return true;
}

bool WaitMap(const Call& c) {
  c.Timeout(c.Arg(1, 300), "round 1's first solve");
  if (c.v.est.state == EstimateState::kFailed) c.Fail(c.v.est.message);
  return !std::isnan(c.v.est.seconds_to_map);
}

bool WaitFirst(const Call& c) {
  c.Timeout(c.Arg(1, 300), "the first estimate");
  if (c.v.est.state == EstimateState::kFailed) c.Fail(c.v.est.message);
  return !std::isnan(c.v.est.seconds_to_first);
}

bool WaitEstimate(const Call& c) {
  c.Timeout(c.Arg(1, 600), "the estimate");
  const EstimateState s = c.v.est.state;
  return c.frames_waited > 1 && s != EstimateState::kRunning && s != EstimateState::kPreparing && !c.v.session.busy();
}

bool ExpectEstimate(const Call& c) {
  if (c.word(1) != ToString(c.v.est.state))
    c.Fail(std::string("the estimate is ") + ToString(c.v.est.state) + " (" + c.v.est.message + ")");
  return true;
}

bool WaitLit(const Call& c) {
  c.Timeout(c.Arg(2, 300), "the lit shading");
  return c.v.est.lit_samples >= c.Arg(1, 1) || c.v.est.lit_done;
}

bool WaitRender(const Call& c) {
  c.Timeout(c.Arg(2, 300), "the clean render");
  return c.v.est.render_samples >= c.Arg(1, 1);
}

bool Export(const Call& c) {
  if (c.first()) {
    std::vector<ExportFormat> formats;  // `export DIR [blender,gltf,sh]`
    if (c.line.words.size() > 2) {
      std::stringstream list(c.word(2));
      std::string name;
      try {
        while (std::getline(list, name, ',')) formats.push_back(ParseExportFormat(name));
      } catch (const InputError& e) {
        c.Fail(e.what());
      }
    }
    c.v.session.Export(c.word(1), formats);
  }
  return true;
}

bool WaitExport(const Call& c) {
  c.Timeout(c.Arg(1, 120), "the export");
  if (c.v.est.export_state == ExportState::kFailed) c.Fail(c.v.est.export_message);
  return c.v.est.export_state == ExportState::kExported;
}

// ---- the window ----

bool SetShading(const Call& c) {
  for (Shading s : {Shading::kAlbedo, Shading::kLit, Shading::kError, Shading::kNormals})
    if (c.word(1) == ToString(s)) {
      c.v.shading = s;
      return true;
    }
  c.Fail("albedo, lit, error or normals, not " + c.word(1));
}

bool SelectKeyframe(const Call& c) {
  c.v.selected_keyframe = static_cast<int>(c.Arg(1, 0));
  return true;
}

bool Orbit(const Call& c) {
  c.v.camera.yaw += static_cast<float>(c.Arg(1, 0));
  c.v.camera.pitch += static_cast<float>(c.Arg(2, 0));
  return true;
}

bool Frames(const Call& c) { return c.frames_waited >= c.Arg(1, 1); }

bool Screenshot(const Call& c) {
  if (c.first()) c.v.screenshot(c.word(1));
  return c.frames_waited > 0 && c.v.pending_screenshot.empty();
}

bool BenchFrames(const Call& c) {
  if (c.first()) {
    if (c.line.words.size() > 2 && c.word(2) != "orbit") c.Fail("the second word can only be orbit");
    c.v.bench_seconds.clear();
    c.v.bench_orbit = c.line.words.size() > 2;
    c.v.bench_scene_renders_start = c.v.scene_renders;
    c.v.bench_frames_left = static_cast<int>(c.Arg(1, 100));
  }
  return c.v.bench_frames_left == 0;
}

bool State(const Call& c) {
  c.v.write_state(c.word(1));
  return true;
}

bool Quit(const Call& c) {
  c.v.quit = true;
  return true;
}

/// As if the user closed the window (whatever runs is stopped).
bool Close(const Call& c) {
  glfwSetWindowShouldClose(c.v.window, GLFW_TRUE);
  return true;
}

/// What runs each command of ScriptCommands() (true = done with the line, false = wait
/// another frame).
using Handler = bool (*)(const Call&);

const std::map<std::string, Handler>& Handlers() {
  static const std::map<std::string, Handler> handlers = {
      {"open", Open},
      {"wait-open", WaitOpen},
      {"play", PlayOrPause},
      {"pause", PlayOrPause},
      {"seek", Seek},
      {"speed", Speed},
      {"reconstruct", Reconstruct},
      {"wait-end", WaitEnd},
      {"wait-frames", WaitFrames},
      {"record", Record},
      {"stop-recording", StopRecording},
      {"wait-record", WaitRecord},
      {"estimate", StartEstimate},
      {"cancel", Cancel},
      {"live", SetLive},
      {"wait-live", WaitLive},
      {"sleep", Sleep},
      {"wait-map", WaitMap},
      {"wait-first", WaitFirst},
      {"wait-estimate", WaitEstimate},
      {"expect-estimate", ExpectEstimate},
      {"wait-lit", WaitLit},
      {"wait-render", WaitRender},
      {"export", Export},
      {"wait-export", WaitExport},
      {"shading", SetShading},
      {"keyframe", SelectKeyframe},
      {"orbit", Orbit},
      {"frames", Frames},
      {"screenshot", Screenshot},
      {"bench-frames", BenchFrames},
      {"state", State},
      {"quit", Quit},
      {"close", Close},
  };
  return handlers;
}

}  // namespace

std::vector<std::string> UnhandledScriptCommands() {
  std::vector<std::string> out;
  for (const auto& [name, syntax] : ScriptCommands())
    if (!Handlers().count(name)) out.push_back(name);
  return out;
}

ScriptRunner::ScriptRunner(const std::string& path, Viewer* viewer)
    : path_(path), viewer_(viewer), lines_(ParseScript(ReadTextFile(path), path)) {}

void ScriptRunner::Fail(const ScriptLine& line, const std::string& why) const { throw LineError(path_, line, why); }

bool ScriptRunner::Step() {
  while (next_ < lines_.size()) {
    const ScriptLine& line = lines_[next_];
    if (line_started_ < 0) {
      line_started_ = glfwGetTime();
      frames_waited_ = 0;
      line_frames_read_ = viewer_->live_.frames_read;
    }
    if (!Run(line)) {
      ++frames_waited_;
      return true;  // waiting: draw another frame
    }
    std::fprintf(stderr, "script %d: %s done (%.2f s)\n", line.number, line.words[0].c_str(),
                 glfwGetTime() - line_started_);
    ++next_;
    line_started_ = -1;
    // Commands that change what is drawn take effect over the next frames: one line a frame.
    return true;
  }
  return false;
}

bool ScriptRunner::Run(const ScriptLine& line) {
  const double waited = glfwGetTime() - line_started_;
  const auto it = Handlers().find(line.words[0]);
  if (it == Handlers().end()) Fail(line, "not handled");
  Viewer& v = *viewer_;
  ViewerParts parts{v.session_,
                    v.live_,
                    v.est_,
                    v.settings_,
                    v.shading_,
                    v.selected_keyframe_,
                    v.camera_,
                    v.pending_screenshot_,
                    [&v](const std::string& path) { v.Screenshot(path); },
                    [&v](const std::string& path) { v.WriteState(path); },
                    v.bench_seconds_,
                    v.bench_orbit_,
                    v.bench_scene_renders_start_,
                    v.scene_renders_,
                    v.bench_frames_left_,
                    v.quit_,
                    v.window_};
  return it->second({path_, line, frames_waited_, waited, line_frames_read_, parts});
}

}  // namespace lp::ui
