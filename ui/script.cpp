// The viewer's command file (docs/viewer.md): drives the window as a user would, one
// command per line, for tests and benchmarks. Commands that wait keep the window live.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include "common/error.h"
#include "ui/viewer_internal.h"

namespace lp::ui {

namespace {

/// Command name -> the number of words it takes (min, max), checked before anything runs.
const std::map<std::string, std::pair<int, int>>& Commands() {
  static const std::map<std::string, std::pair<int, int>> commands = {
      {"open", {1, 1}},          {"play", {0, 0}},        {"pause", {0, 0}},       {"seek", {1, 1}},
      {"speed", {1, 1}},         {"reconstruct", {1, 1}}, {"wait-end", {0, 1}},    {"wait-open", {0, 1}},
      {"estimate", {0, 20}},     {"cancel", {0, 0}},      {"wait-estimate", {0, 1}}, {"wait-lit", {1, 2}},
      {"wait-first", {0, 1}},    {"shading", {1, 1}},     {"keyframe", {1, 1}},    {"orbit", {2, 2}},
      {"frames", {1, 1}},        {"screenshot", {1, 1}},  {"bench-frames", {1, 2}}, {"export", {1, 1}},
      {"wait-export", {0, 1}},   {"state", {1, 1}},       {"expect-estimate", {1, 1}}, {"quit", {0, 0}},
      {"close", {0, 0}},         {"record", {2, 2}},      {"stop-recording", {0, 0}}, {"wait-record", {0, 1}},
  };
  return commands;
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

}  // namespace

ScriptRunner::ScriptRunner(const std::string& path, Viewer* viewer) : path_(path), viewer_(viewer) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot read the script");
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    const std::size_t hash = text.find('#');
    if (hash != std::string::npos) text.resize(hash);
    std::istringstream words(text);
    ScriptLine line;
    line.number = number;
    for (std::string w; words >> w;) line.words.push_back(w);
    if (line.words.empty()) continue;
    const auto it = Commands().find(line.words[0]);
    if (it == Commands().end()) throw InputError(path, "line " + std::to_string(number) + ": unknown command " + line.words[0]);
    const int args = static_cast<int>(line.words.size()) - 1;
    if (args < it->second.first || args > it->second.second)
      throw InputError(path, "line " + std::to_string(number) + ": wrong number of arguments for " + line.words[0]);
    lines_.push_back(line);
  }
}

void ScriptRunner::Fail(const ScriptLine& line, const std::string& why) const {
  throw InputError(path_, "line " + std::to_string(line.number) + " (" + line.words[0] + "): " + why);
}

bool ScriptRunner::Step() {
  while (next_ < lines_.size()) {
    const ScriptLine& line = lines_[next_];
    if (line_started_ < 0) {
      line_started_ = glfwGetTime();
      frames_waited_ = 0;
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
  Viewer& v = *viewer_;
  const std::string& cmd = line.words[0];
  const double waited = glfwGetTime() - line_started_;
  auto timeout = [&](double seconds, const char* what) {
    if (waited > seconds) Fail(line, std::string("timed out after ") + std::to_string(seconds) + " s waiting for " + what);
  };
  const bool first = frames_waited_ == 0;
  // A command posted to the session is done once the worker has taken and handled it.
  auto handled = [&] { return !v.session_.busy() && frames_waited_ > 0; };
  if (cmd == "open") {
    if (first) v.session_.Open(line.words[1]);
    return handled();
  }
  if (cmd == "wait-open") {
    timeout(Number(line, 1, 60), "the source to open");
    if (!v.live_.error.empty() && !v.live_.open) Fail(line, v.live_.error);
    return v.live_.open && !v.session_.busy();
  }
  if (cmd == "play" || cmd == "pause") {
    if (first) v.session_.SetPlaying(cmd == "play");
    return handled();
  }
  if (cmd == "seek") {
    if (first) v.session_.Seek(static_cast<std::int64_t>(Number(line, 1, 0)));
    return handled();
  }
  if (cmd == "speed") {
    if (first) v.session_.SetSpeed(Number(line, 1, 1));
    return handled();
  }
  if (cmd == "reconstruct") {
    const std::string& what = line.words[1];
    if (first) {
      if (what == "start") v.session_.StartReconstruction();
      else if (what == "stop") v.session_.StopReconstruction();
      else if (what == "reset") v.session_.ResetReconstruction();
      else Fail(line, "start, stop or reset, not " + what);
    }
    return handled();
  }
  if (cmd == "wait-end") {
    timeout(Number(line, 1, 300), "the end of the source");
    return frames_waited_ > 1 && !v.session_.busy() && !v.live_.playing;
  }
  if (cmd == "estimate") {
    if (first) {
      EstimateOptions o = v.settings_;
      for (std::size_t i = 1; i < line.words.size(); ++i) {
        const std::string& w = line.words[i];
        const std::size_t eq = w.find('=');
        if (eq == std::string::npos) Fail(line, "settings are key=value: " + w);
        const std::string key = w.substr(0, eq);
        ScriptLine value{line.number, {w.substr(eq + 1)}};
        const double x = key == "solver" ? 0 : Number(value, 0, 0);
        if (key == "rings") o.rings = static_cast<int>(x);
        else if (key == "spp") o.tracer.spp = static_cast<int>(x);
        else if (key == "bounces") o.tracer.bounces = static_cast<int>(x);
        else if (key == "rounds") o.max_rounds = static_cast<int>(x);
        else if (key == "render-spp") o.render_spp = static_cast<int>(x);
        else if (key == "albedo-passes") {
          if (x < 0 || x > 5 || x != std::floor(x)) Fail(line, "albedo-passes is 0 .. 5, not " + value.words[0]);
          o.albedo_passes = static_cast<int>(x);
        }
        else if (key == "alpha") o.objective.alpha = x;
        else if (key == "beta") o.objective.beta = x;
        else if (key == "sigma") o.objective.sigma = x;
        else if (key == "solver") o.solver = value.words[0] == "gradient" ? SolverKind::kGradient : SolverKind::kFast;
        else Fail(line, "unknown setting " + key);
      }
      v.settings_ = o;  // the panel shows what was pressed
      v.session_.Estimate(o);
    }
    return true;
  }
  if (cmd == "cancel") {
    v.session_.CancelEstimate();
    return true;
  }
  if (cmd == "wait-first") {
    timeout(Number(line, 1, 300), "the first estimate");
    if (v.est_.state == EstimateState::kFailed) Fail(line, v.est_.message);
    return !std::isnan(v.est_.seconds_to_first);
  }
  if (cmd == "wait-estimate") {
    timeout(Number(line, 1, 600), "the estimate");
    const EstimateState s = v.est_.state;
    return frames_waited_ > 1 && s != EstimateState::kRunning && s != EstimateState::kPreparing && !v.session_.busy();
  }
  if (cmd == "expect-estimate") {
    if (line.words[1] != ToString(v.est_.state))
      Fail(line, std::string("the estimate is ") + ToString(v.est_.state) + " (" + v.est_.message + ")");
    return true;
  }
  if (cmd == "wait-lit") {
    timeout(Number(line, 2, 300), "the lit shading");
    return v.est_.lit_samples >= Number(line, 1, 1);
  }
  if (cmd == "shading") {
    for (Shading s : {Shading::kAlbedo, Shading::kLit, Shading::kError, Shading::kNormals})
      if (line.words[1] == ToString(s)) {
        v.shading_ = s;
        return true;
      }
    Fail(line, "albedo, lit, error or normals, not " + line.words[1]);
  }
  if (cmd == "keyframe") {
    v.selected_keyframe_ = static_cast<int>(Number(line, 1, 0));
    return true;
  }
  if (cmd == "orbit") {
    v.camera_.yaw += static_cast<float>(Number(line, 1, 0));
    v.camera_.pitch += static_cast<float>(Number(line, 2, 0));
    return true;
  }
  if (cmd == "frames") return frames_waited_ >= Number(line, 1, 1);
  if (cmd == "screenshot") {
    if (first) v.Screenshot(line.words[1]);
    return frames_waited_ > 0 && v.pending_screenshot_.empty();
  }
  if (cmd == "bench-frames") {
    if (first) {
      if (line.words.size() > 2 && line.words[2] != "orbit") Fail(line, "the second word can only be orbit");
      v.bench_seconds_.clear();
      v.bench_orbit_ = line.words.size() > 2;
      v.bench_scene_renders_start_ = v.scene_renders_;
      v.bench_frames_left_ = static_cast<int>(Number(line, 1, 100));
    }
    return v.bench_frames_left_ == 0;
  }
  if (cmd == "record") {
    if (first) v.session_.Record(line.words[1], Number(line, 2, 0));
    return true;
  }
  if (cmd == "stop-recording") {
    v.session_.StopRecording();
    return true;
  }
  if (cmd == "wait-record") {  // the recording finished (its file in place)
    timeout(Number(line, 1, 120), "the recording");
    if (v.live_.record_message.rfind("recording failed", 0) == 0) Fail(line, v.live_.record_message);
    return !v.live_.recording && !v.session_.busy() && v.live_.record_message.rfind("recorded", 0) == 0;
  }
  if (cmd == "export") {
    if (first) v.session_.Export(line.words[1]);
    return true;
  }
  if (cmd == "wait-export") {
    timeout(Number(line, 1, 120), "the export");
    const std::string& m = v.est_.export_message;
    if (m.rfind("export failed", 0) == 0) Fail(line, m);
    return m.rfind("exported", 0) == 0;
  }
  if (cmd == "state") {
    v.WriteState(line.words[1]);
    return true;
  }
  if (cmd == "quit") {
    v.quit_ = true;
    return true;
  }
  if (cmd == "close") {  // as if the user closed the window (whatever runs is stopped)
    glfwSetWindowShouldClose(v.window_, GLFW_TRUE);
    return true;
  }
  Fail(line, "not handled");
}

}  // namespace lp::ui
