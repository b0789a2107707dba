// OpenNI2 wrapper: recording and .oni playback (the only file that includes OpenNI.h).
#include "capture/openni.h"

#include <OpenNI.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

extern char** environ;  // for posix_spawn

#include "capture/usb_devices.h"
#include "common/atomic_file.h"
#include "common/error.h"

namespace lp {
namespace fs = std::filesystem;

namespace {

/// OpenNI2 keeps an error log per calling thread, keyed by pthread_t, and when a thread
/// calls it for the first time it probes every thread it has seen with pthread_kill(id, 0).
/// Once a thread that called OpenNI2 has exited and glibc has unmapped its stack (glibc
/// keeps ~40 MiB of stacks cached), that probe reads unmapped memory and the process
/// crashes: e.g. a viewer Session that played a file, then a new Session opening a camera.
/// So no thread that calls OpenNI2 may exit: every call in this file runs on a thread of
/// this pool, which lives as long as the process. It grows to the number of calls in
/// flight at once (a capture thread's read, a recording, ...); idle threads wait.
class OpenNiThreads {
 public:
  /// Never destroyed: its threads wait on it until the process ends.
  static OpenNiThreads& Get() {
    static OpenNiThreads* pool = new OpenNiThreads;
    return *pool;
  }

  /// Runs f on a pool thread and returns its result (or rethrows its exception).
  template <class F>
  auto Run(F&& f) -> decltype(f()) {
    if (on_pool_thread_) return f();
    using R = decltype(f());
    auto task = std::make_shared<std::packaged_task<R()>>(std::forward<F>(f));
    std::future<R> result = task->get_future();
    {
      std::lock_guard<std::mutex> lock(m_);
      jobs_.emplace_back([task] { (*task)(); });
      if (jobs_.size() > idle_) {
        try {
          std::thread([this] { Loop(); }).detach();
        } catch (...) {  // no thread: the job (which refers to our caller's frame) must not stay queued
          jobs_.pop_back();
          throw;
        }
      }
    }
    cv_.notify_one();
    return result.get();
  }

 private:
  void Loop() {
    on_pool_thread_ = true;
    std::unique_lock<std::mutex> lock(m_);
    for (;;) {
      ++idle_;
      cv_.wait(lock, [this] { return !jobs_.empty(); });
      --idle_;
      std::function<void()> job = std::move(jobs_.front());
      jobs_.pop_front();
      lock.unlock();
      job();
      lock.lock();
    }
  }

  std::mutex m_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> jobs_;
  std::size_t idle_ = 0;
  static thread_local bool on_pool_thread_;
};
thread_local bool OpenNiThreads::on_pool_thread_ = false;

template <class F>
auto OnOpenNiThread(F&& f) -> decltype(f()) {
  return OpenNiThreads::Get().Run(std::forward<F>(f));
}

/// OpenNI2 is initialized once per process and never shut down (shutting down and
/// initializing again is not reliable in 2.2).
void InitOpenNi() {
  static std::once_flag once;
  static openni::Status status = openni::STATUS_OK;
  static std::string error;
  std::call_once(once, [] {
    status = openni::OpenNI::initialize();
    if (status != openni::STATUS_OK) error = openni::OpenNI::getExtendedError();
  });
  if (status != openni::STATUS_OK) throw InputError("OpenNI2 failed to initialize: " + error);
}

std::string OpenNiError() {
  std::string e = openni::OpenNI::getExtendedError();
  while (!e.empty() && (e.back() == '\n' || e.back() == ' ')) e.pop_back();
  for (char& c : e)
    if (c == '\n' || c == '\t') c = ' ';
  const auto first = e.find_first_not_of(' ');
  return first == std::string::npos ? std::string() : e.substr(first);
}

/// Stops the streams and gives the frames in flight time to land: drivers like
/// DummyDevice crash if their streams are destroyed right after stopping.
void StopStreams(openni::VideoStream& depth, openni::VideoStream& color) {
  if (depth.isValid()) depth.stop();
  if (color.isValid()) color.stop();
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
}

/// Stops (if not yet) and destroys the streams.
void ReleaseStreams(openni::VideoStream& depth, openni::VideoStream& color) {
  StopStreams(depth, color);
  depth.destroy();
  color.destroy();
}

/// OpenNI2's Recorder deadlocks when it is stopped while a frame arrives (the recorder's
/// lock and the stream's are taken in opposite orders): stop the streams first, then
/// stop and destroy the recorder. The streams stay (stopped).
void StopRecorder(openni::Recorder& recorder, openni::VideoStream& depth, openni::VideoStream& color) {
  StopStreams(depth, color);
  if (recorder.isValid()) {
    recorder.stop();
    recorder.destroy();
  }
}

/// StopRecorder, then the streams are destroyed.
void FinishRecording(openni::Recorder& recorder, openni::VideoStream& depth, openni::VideoStream& color) {
  StopRecorder(recorder, depth, color);
  depth.destroy();
  color.destroy();
}

void OpenDevice(openni::Device* device, const std::string& uri) {
  const bool any = uri.empty();
  if (device->open(any ? openni::ANY_DEVICE : uri.c_str()) == openni::STATUS_OK) return;
  const std::string why = OpenNiError();
  if (any || uri.rfind("lpsynth://", 0) != 0)
    throw InputError("no OpenNI2 device opened (" + why + "): " + ExplainNoDevice(ScanUsbCameras()));
  throw InputError(uri, "the synthetic OpenNI2 device did not open (" + why + "); driver folder: " +
                            (OpenNiDriverFolder().empty() ? "none" : OpenNiDriverFolder()));
}

/// Sets a stream to the mode with this size and pixel format, at `fps` or the nearest.
void SelectMode(openni::VideoStream& s, int w, int h, int fps, openni::PixelFormat format, const char* what) {
  const openni::Array<openni::VideoMode>& modes = s.getSensorInfo().getSupportedVideoModes();
  int best = -1;
  std::string available;
  for (int i = 0; i < modes.getSize(); ++i) {
    const openni::VideoMode& m = modes[i];
    available += (available.empty() ? "" : ", ") + std::to_string(m.getResolutionX()) + "x" +
                 std::to_string(m.getResolutionY()) + "@" + std::to_string(m.getFps());
    if (m.getResolutionX() != w || m.getResolutionY() != h || m.getPixelFormat() != format) continue;
    if (best < 0 || std::abs(m.getFps() - fps) < std::abs(modes[best].getFps() - fps)) best = i;
  }
  if (best < 0)
    throw InputError(std::string("the ") + what + " stream has no " + std::to_string(w) + "x" + std::to_string(h) +
                     " mode in the needed format (available: " + available + ")");
  if (s.setVideoMode(modes[best]) != openni::STATUS_OK)
    throw InputError(std::string("cannot set the ") + what + " mode: " + OpenNiError());
}

/// Locks auto exposure / white balance and sets exposure / gain (when >= 0) on the colour
/// stream, after the streams started (some devices ignore settings made before), then
/// reads back what the device uses; a device that did not take them is an error.
CameraControls ApplyCameraControls(openni::Device& device, openni::VideoStream& color, bool lock, int exposure,
                                   int gain, const std::string& uri) {
  CameraControls c;
  if (openni::CameraSettings* cs = color.getCameraSettings()) {
    if (lock) {
      cs->setAutoExposureEnabled(false);
      cs->setAutoWhiteBalanceEnabled(false);
    }
    if (exposure >= 0) cs->setExposure(exposure);
    if (gain >= 0) cs->setGain(gain);
    c.auto_exposure = cs->getAutoExposureEnabled();
    c.auto_white_balance = cs->getAutoWhiteBalanceEnabled();
    c.exposure = cs->getExposure();
    c.gain = cs->getGain();
    c.camera_settings = true;
  }
  c.registered = device.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
  if (lock && c.camera_settings && (c.auto_exposure || c.auto_white_balance))
    throw InputError(uri, "the camera did not lock its exposure / white balance (read back still automatic)");
  if (exposure >= 0 && c.camera_settings && c.exposure != exposure)
    throw InputError(uri, "the camera ignored exposure " + std::to_string(exposure) + " (reads back " +
                              std::to_string(c.exposure) + ")");
  if (gain >= 0 && c.camera_settings && c.gain != gain)
    throw InputError(uri, "the camera ignored gain " + std::to_string(gain) + " (reads back " +
                              std::to_string(c.gain) + ")");
  return c;
}

std::uint32_t U32(const unsigned char* p) { return p[0] | p[1] << 8 | p[2] << 16 | std::uint32_t(p[3]) << 24; }

}  // namespace

std::string OpenNiDriverFolder() {
#ifdef LIGHTPROBE_OPENNI2_RUNTIME
  return std::string(LIGHTPROBE_OPENNI2_RUNTIME) + "/OpenNI2/Drivers";
#else
  return {};
#endif
}

int ValidateOniFile(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path, "file not found");
  const std::uint64_t size = fs::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot read");
  constexpr std::size_t kFileHeader = 24, kRecordHeader = 28;
  constexpr std::uint32_t kRecordMagic = 0x0052494E;  // "NIR\0"
  unsigned char h[kRecordHeader];
  if (size < kFileHeader || !in.read(reinterpret_cast<char*>(h), kFileHeader))
    throw InputError(path, "empty or truncated .oni file (no header)");
  if (std::memcmp(h, "NI10", 4) != 0) throw InputError(path, "not an .oni recording (bad magic)");
  std::uint64_t pos = kFileHeader;
  int records = 0, frames = 0;
  bool end = false;
  while (!end) {
    if (pos + kRecordHeader > size)
      throw InputError(path, "truncated .oni file: record " + std::to_string(records) + " runs past the end");
    in.seekg(static_cast<std::streamoff>(pos));
    if (!in.read(reinterpret_cast<char*>(h), kRecordHeader)) throw InputError(path, "cannot read record header");
    const std::uint32_t magic = U32(h), type = U32(h + 4), fields = U32(h + 8 + 4), payload = U32(h + 16);
    if (magic != kRecordMagic)
      throw InputError(path, "corrupt .oni file: bad record magic at byte " + std::to_string(pos));
    if (type < 0x02 || type > 0x0E || fields < kRecordHeader)
      throw InputError(path, "corrupt .oni file: bad record header at byte " + std::to_string(pos));
    const std::uint64_t next = pos + fields + static_cast<std::uint64_t>(payload);
    if (next > size)
      throw InputError(path, "truncated .oni file: record at byte " + std::to_string(pos) + " runs past the end");
    frames += type == 0x0A;
    end = type == 0x0B;
    pos = next;
    ++records;
  }
  if (frames == 0) throw InputError(path, ".oni file has no frames");
  return frames;
}

namespace {

/// OpenNI2's recordings keep each stream's timestamps relative to its own first recorded
/// frame, so both streams must start recording with the same frame or replay pairs them
/// one frame apart: returns just after a depth and a colour frame with the same timestamp
/// arrived (the next pair is a frame period away), when the recorder is to start.
void WaitForPairedFrames(openni::VideoStream& depth, openni::VideoStream& color, const std::string& uri) {
  openni::VideoStream* streams[2] = {&depth, &color};
  openni::VideoFrameRef frame;
  std::uint64_t last[2] = {~0ull, ~1ull};
  for (int k = 0; k < 60 && last[0] != last[1]; ++k) {
    int ready = -1;
    if (openni::OpenNI::waitForAnyStream(streams, 2, &ready, 2000) != openni::STATUS_OK)
      throw InputError(uri, "the device delivers no frames: " + OpenNiError());
    if (streams[ready]->readFrame(&frame) == openni::STATUS_OK) last[ready] = frame.getTimestamp();
  }
}

/// Where a recording is written until it is finished: `.NAME.recording.oni` next to it.
fs::path RecordingTempFile(const std::string& out_file) {
  const fs::path out(out_file);
  std::error_code ec;
  if (!out.parent_path().empty()) fs::create_directories(out.parent_path(), ec);
  return out.parent_path() / ("." + out.filename().string() + ".recording.oni");
}

/// The frames a finished recording holds per stream, from OpenNI2's own index of the file:
/// the Recorder writes every frame the device sends while it is attached, which is not the
/// number this process read (a reader that falls behind drops frames, and the streams run
/// on for a moment after the last read). Keeps the counts read when the file cannot be opened.
void CountRecordedFrames(const fs::path& file, RecordResult* result) {
  try {
    ValidateOniFile(file.string());  // a file cut short (a full disk) is not handed to OpenNI2
  } catch (const InputError&) {
    return;
  }
  openni::Device playback;
  if (playback.open(file.c_str()) != openni::STATUS_OK) return;
  openni::VideoStream depth, color;
  if (openni::PlaybackControl* pc = playback.getPlaybackControl()) {
    if (depth.create(playback, openni::SENSOR_DEPTH) == openni::STATUS_OK) {
      const int n = pc->getNumberOfFrames(depth);
      if (n > 0) result->depth_frames = n;
      depth.destroy();
    }
    if (color.create(playback, openni::SENSOR_COLOR) == openni::STATUS_OK) {
      const int n = pc->getNumberOfFrames(color);
      if (n > 0) result->color_frames = n;
      color.destroy();
    }
  }
  playback.close();
}

/// Moves a finished recording into place and writes its side file (an old side file never
/// describes the new recording: removed before the .oni moves in); `result` takes the
/// frame counts the file holds.
void PublishRecording(const fs::path& tmp, const std::string& out_file, openni::Device& device,
                      RecordResult& result, bool lossy_color) {
  CountRecordedFrames(tmp, &result);
  nlohmann::json side;
  side["format"] = "lightprobe-oni-side";
  side["version"] = 1;
  side["device_uri"] = device.getDeviceInfo().getUri();
  side["device_name"] = device.getDeviceInfo().getName();
  const CameraControls& c = result.controls;
  side["registered"] = c.registered;
  side["camera_settings"] = c.camera_settings;
  side["auto_exposure"] = c.auto_exposure;
  side["auto_white_balance"] = c.auto_white_balance;
  side["exposure"] = c.exposure;
  side["gain"] = c.gain;
  side["lossy_color"] = lossy_color;
  side["depth_frames"] = result.depth_frames;
  side["color_frames"] = result.color_frames;
  side["first_depth_frame_index"] = result.first_depth_frame_index;
  std::error_code ec;
  fs::remove(OniSideFile(out_file), ec);
  fs::rename(tmp, out_file, ec);
  if (ec)
    throw InputError(out_file, "cannot move the recording into place (" + ec.message() + "); it is kept as " +
                                   tmp.string());
  WriteTextAtomically(OniSideFile(out_file), side.dump(2) + "\n");
}

RecordResult RecordOniHere(const std::string& out_file, const RecordOptions& o) {
  if (o.frames <= 0 && !(o.seconds > 0)) throw InputError("record: give a number of frames or seconds");
  InitOpenNi();
  openni::Device device;
  OpenDevice(&device, o.uri);
  openni::VideoStream depth, color;
  if (depth.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK)
    throw InputError(o.uri, "the device has no depth stream: " + OpenNiError());
  if (color.create(device, openni::SENSOR_COLOR) != openni::STATUS_OK) {
    depth.destroy();
    throw InputError(o.uri, "the device has no colour stream: " + OpenNiError());
  }
  try {
    if (o.width > 0 && o.height > 0) {
      SelectMode(depth, o.width, o.height, 30, openni::PIXEL_FORMAT_DEPTH_1_MM, "depth");
      SelectMode(color, o.width, o.height, 30, openni::PIXEL_FORMAT_RGB888, "colour");
    }
  } catch (...) {
    depth.destroy();
    color.destroy();
    throw;
  }
  if (device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR))
    device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
  device.setDepthColorSyncEnabled(true);
  const fs::path tmp = RecordingTempFile(out_file);
  openni::Recorder recorder;
  RecordResult result;
  try {
    if (recorder.create(tmp.c_str()) != openni::STATUS_OK) throw InputError(out_file, "cannot create: " + OpenNiError());
    if (recorder.attach(depth, false) != openni::STATUS_OK || recorder.attach(color, o.lossy_color) != openni::STATUS_OK)
      throw InputError(out_file, "cannot attach the streams to the recorder: " + OpenNiError());
    if (depth.start() != openni::STATUS_OK || color.start() != openni::STATUS_OK)
      throw InputError(o.uri, "cannot start the streams: " + OpenNiError());
    result.controls = ApplyCameraControls(device, color, o.lock_exposure, o.exposure, o.gain, o.uri);
    WaitForPairedFrames(depth, color, o.uri);
    openni::VideoStream* streams[2] = {&depth, &color};
    openni::VideoFrameRef frame;
    if (recorder.start() != openni::STATUS_OK) throw InputError(out_file, "cannot start recording: " + OpenNiError());
    const auto t0 = std::chrono::steady_clock::now();
    auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
    while ((o.frames > 0 ? result.depth_frames < o.frames : elapsed() < o.seconds) && !(o.stop && o.stop->load())) {
      int ready = -1;
      if (openni::OpenNI::waitForAnyStream(streams, 2, &ready, 2000) != openni::STATUS_OK)
        throw InputError(o.uri, "the device stopped delivering frames (unplugged?) after " +
                                    std::to_string(result.depth_frames) + " depth frames");
      if (streams[ready]->readFrame(&frame) != openni::STATUS_OK) continue;
      if (ready == 0 && result.depth_frames == 0) result.first_depth_frame_index = frame.getFrameIndex();
      (ready == 0 ? result.depth_frames : result.color_frames)++;
      if (ready == 0 && o.progress) o.progress(result.depth_frames, elapsed());
    }
    result.seconds = elapsed();
    FinishRecording(recorder, depth, color);
  } catch (...) {
    FinishRecording(recorder, depth, color);
    device.close();
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
  try {
    PublishRecording(tmp, out_file, device, result, o.lossy_color);
  } catch (...) {
    device.close();
    throw;
  }
  device.close();
  return result;
}

}  // namespace

RecordResult RecordOni(const std::string& out_file, const RecordOptions& o) {
  return OnOpenNiThread([&] { return RecordOniHere(out_file, o); });
}

std::string OniSideFile(const std::string& oni_file) { return oni_file + ".json"; }

std::string DescribeRecording(const RecordResult& r, const std::string& file) {
  char line[96];
  std::snprintf(line, sizeof line, "recorded %d depth frames in %.1f s to ", r.depth_frames, r.seconds);
  return line + file;
}

namespace {

/// The helper that plays a file in its own process: LIGHTPROBE_ONI_CHECK if set, else the
/// one the build put in the OpenNI2 runtime folder.
std::string OniCheckHelper() {
  if (const char* env = std::getenv("LIGHTPROBE_ONI_CHECK")) return env;
#ifdef LIGHTPROBE_OPENNI2_RUNTIME
  return std::string(LIGHTPROBE_OPENNI2_RUNTIME) + "/lightprobe-oni-check";
#else
  return {};
#endif
}

/// Plays `path` through once in a child process (the helper reads every frame with
/// isolate off). A crash, a hang past the time limit or an error there is an InputError
/// here; this process never hands OpenNI2 a file that broke it.
void PlayInChild(const std::string& path, int frame_records) {
  const std::string helper = OniCheckHelper();
  std::error_code ec;
  if (helper.empty() || !fs::exists(helper, ec)) {
    static std::once_flag warned;
    std::call_once(warned, [&] {
      std::fprintf(stderr, "warning: %s not found; .oni playback is not isolated in a separate process\n",
                   helper.empty() ? "lightprobe-oni-check" : helper.c_str());
    });
    return;
  }
  int pipe_fd[2];  // close-on-exec: no other child inherits the write end and holds it open
  if (pipe2(pipe_fd, O_CLOEXEC) != 0) throw InputError(path, "cannot create a pipe for the playback check");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, pipe_fd[1], 2);
  posix_spawn_file_actions_addclose(&actions, pipe_fd[0]);
  std::string arg0 = helper, arg1 = path;
  char* argv[] = {arg0.data(), arg1.data(), nullptr};
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, helper.c_str(), &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  close(pipe_fd[1]);
  if (rc != 0) {
    close(pipe_fd[0]);
    throw InputError(path, "cannot start the playback check " + helper + ": " + std::strerror(rc));
  }
  // Generous: the helper decodes ~1000 VGA frames/s; a hang is what this limit catches.
  const double limit = 30.0 + 0.05 * frame_records;
  const auto t0 = std::chrono::steady_clock::now();
  std::string err;
  int status = 0;
  bool done = false, killed = false;
  while (!done) {
    pollfd p{pipe_fd[0], POLLIN, 0};
    if (poll(&p, 1, 50) > 0) {
      char buf[512];
      const ssize_t n = read(pipe_fd[0], buf, sizeof buf);
      if (n > 0 && err.size() < 4096) err.append(buf, static_cast<std::size_t>(n));
      if (n <= 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));  // closed: do not spin
    }
    done = waitpid(pid, &status, WNOHANG) == pid;
    if (!done && std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      done = killed = true;
    }
  }
  fcntl(pipe_fd[0], F_SETFL, O_NONBLOCK);  // what is left, without waiting for anyone
  for (char buf[512];;) {  // what the child wrote just before it exited
    const ssize_t n = read(pipe_fd[0], buf, sizeof buf);
    if (n <= 0 || err.size() >= 4096) break;
    err.append(buf, static_cast<std::size_t>(n));
  }
  close(pipe_fd[0]);
  if (killed)
    throw InputError(path, "corrupt .oni file: OpenNI2 playback hung (checked in a separate process, stopped after " +
                               std::to_string(static_cast<int>(limit)) + " s)");
  if (WIFSIGNALED(status))
    throw InputError(path, "corrupt .oni file: OpenNI2 crashed playing it (signal " +
                               std::to_string(WTERMSIG(status)) + ", in a separate process)");
  if (WIFEXITED(status) && WEXITSTATUS(status) != 0) {
    // The helper's last line is the reason (it names the file).
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    const auto nl = err.rfind('\n');
    const std::string last = nl == std::string::npos ? err : err.substr(nl + 1);
    throw InputError(last.empty() ? path + ": the playback check failed" : last);
  }
}

}  // namespace

namespace {

/// What both OpenNI2 sources share: a device with a depth and a colour stream, frames
/// paired by timestamp (within half a frame period), copied into owned RgbdFrames.
class OpenNiStreams {
 protected:
  /// Reads one frame of `s`, waiting at most timeout_ms.
  bool Read(openni::VideoStream& s, openni::VideoFrameRef* f, int timeout_ms) {
    openni::VideoStream* p = &s;
    int ready = -1;
    if (openni::OpenNI::waitForAnyStream(&p, 1, &ready, timeout_ms) != openni::STATUS_OK) return false;
    return s.readFrame(f) == openni::STATUS_OK;
  }
  /// Reads a depth and a colour frame taken at the same time: the older one is read again
  /// until their timestamps are within half a frame period (a stream that dropped a frame
  /// skips ahead to its partner). `budget` limits the extra reads (end of a recording).
  bool ReadPair(openni::VideoFrameRef* d, openni::VideoFrameRef* c, int timeout_ms, int* depth_reads,
                int* color_reads, int depth_budget, int color_budget) {
    // A read counts the frames up to the one read: in real-time playback OpenNI2 skips the
    // frames a slow reader missed, and its frame index (1-based in a recording) says where
    // it is, so the end of a file is still found.
    auto count = [](int* reads, const openni::VideoFrameRef& f) { *reads = std::max(*reads + 1, f.getFrameIndex()); };
    if (!Read(depth_, d, timeout_ms)) return false;
    count(depth_reads, *d);
    if (!Read(color_, c, timeout_ms)) return false;
    count(color_reads, *c);
    const int fps = std::max(1, depth_.getVideoMode().getFps());
    const long long half = 500000 / fps;  // microseconds
    for (int guard = 0; guard < 64; ++guard) {
      const long long dt = static_cast<long long>(c->getTimestamp()) - static_cast<long long>(d->getTimestamp());
      if (dt > half && *depth_reads < depth_budget) {
        if (!Read(depth_, d, timeout_ms)) return false;
        count(depth_reads, *d);
      } else if (-dt > half && *color_reads < color_budget) {
        if (!Read(color_, c, timeout_ms)) return false;
        count(color_reads, *c);
      } else {
        break;
      }
    }
    return true;
  }
  RgbdFrame ToFrame(const openni::VideoFrameRef& d, const openni::VideoFrameRef& c, std::int64_t index) {
    RgbdFrame f;
    f.index = index;
    f.depth.width = d.getWidth();
    f.depth.height = d.getHeight();
    f.depth.data.resize(f.depth.pixels());
    const auto* dp = static_cast<const char*>(d.getData());
    for (int y = 0; y < f.depth.height; ++y)
      std::memcpy(&f.depth.data[static_cast<std::size_t>(y) * f.depth.width],
                  dp + static_cast<std::size_t>(y) * d.getStrideInBytes(), sizeof(std::uint16_t) * f.depth.width);
    f.color.width = c.getWidth();
    f.color.height = c.getHeight();
    f.color.data.resize(f.color.pixels() * 3);
    const auto* cp = static_cast<const std::uint8_t*>(c.getData());
    for (int y = 0; y < f.color.height; ++y)
      std::memcpy(&f.color.data[3 * static_cast<std::size_t>(y) * f.color.width],
                  cp + static_cast<std::size_t>(y) * c.getStrideInBytes(), 3 * static_cast<std::size_t>(f.color.width));
    f.depth_timestamp = d.getTimestamp() * 1e-6;
    f.color_timestamp = c.getTimestamp() * 1e-6;
    f.depth_intrinsics = FromFov(depth_, f.depth.width, f.depth.height);
    f.color_intrinsics = FromFov(color_, f.color.width, f.color.height);
    f.registered = device_.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
    return f;
  }
  /// OpenNI2 reports fields of view, not a principal point: centred, square-ish pixels.
  static Intrinsics FromFov(openni::VideoStream& s, int w, int h) {
    Intrinsics k;
    k.width = w;
    k.height = h;
    const double hfov = s.getHorizontalFieldOfView(), vfov = s.getVerticalFieldOfView();
    k.fx = hfov > 0 ? 0.5 * w / std::tan(0.5 * hfov) : 0;
    k.fy = vfov > 0 ? 0.5 * h / std::tan(0.5 * vfov) : k.fx;
    k.cx = 0.5 * w - 0.5;
    k.cy = 0.5 * h - 0.5;
    return k;
  }
  void CloseDevice() {
    ReleaseStreams(depth_, color_);
    device_.close();
  }

  openni::Device device_;
  openni::VideoStream depth_, color_;
};

class OniFileSource : public FrameSource, private OpenNiStreams {
 public:
  OniFileSource(const std::string& path, const OniPlaybackOptions& o) : path_(path), options_(o) {
    const int records = ValidateOniFile(path);
    ReadSideFile();
    if (o.isolate) PlayInChild(path, records);
    InitOpenNi();
    Open();
  }
  ~OniFileSource() override { CloseDevice(); }

  std::string Describe() const override { return ".oni file " + path_ + ", " + std::to_string(count_) + " frames"; }
  std::optional<std::int64_t> FrameCount() const override { return count_; }

  SourceStatus Next(RgbdFrame* out, double timeout_seconds) override {
    // No end-of-file signal in OpenNI2's playback: stop on the recorded frame counts.
    if (depth_read_ >= depth_count_ || color_read_ >= color_count_) {
      if (!options_.loop) return SourceStatus::kEnd;
      Rewind();
    }
    openni::VideoFrameRef d, c;
    if (!ReadPair(&d, &c, static_cast<int>(timeout_seconds * 1000), &depth_read_, &color_read_, depth_count_,
                  color_count_))
      return SourceStatus::kTimeout;
    *out = ToFrame(d, c, produced_++);
    if (side_registered_) out->registered = *side_registered_;
    out->exposure = side_exposure_;
    out->gain = side_gain_;
    return SourceStatus::kFrame;
  }

  /// OpenNI2's seek crashes: rewind by reopening the file.
  void Rewind() override {
    CloseDevice();
    Open();
  }

  /// Reopens and skips to `frame` at manual speed (OpenNI2's own seek crashes), then plays
  /// on at the chosen speed.
  void Seek(std::int64_t frame) override {
    seeking_ = true;  // Open() (through Rewind) plays at manual speed meanwhile
    try {
      FrameSource::Seek(frame);
    } catch (...) {
      seeking_ = false;
      throw;
    }
    seeking_ = false;
    // Paused stays paused: real time would run the file's clock on until the caller pauses
    // again, and a frame or two later is where the reader would land.
    device_.getPlaybackControl()->setSpeed(options_.real_time && !paused_ ? 1.0f : -1.0f);
  }

  /// Real-time playback runs on OpenNI2's clock: manual speed holds it while paused.
  void SetPaused(bool paused) override {
    paused_ = paused;
    if (!options_.real_time) return;
    if (openni::PlaybackControl* pc = device_.getPlaybackControl()) pc->setSpeed(paused ? -1.0f : 1.0f);
  }

 private:
  void Open() {
    if (device_.open(path_.c_str()) != openni::STATUS_OK)
      throw InputError(path_, "OpenNI2 cannot open it: " + OpenNiError());
    openni::PlaybackControl* pc = device_.getPlaybackControl();
    if (!pc) throw InputError(path_, "not a recording");
    pc->setSpeed(options_.real_time && !seeking_ && !paused_ ? 1.0f : -1.0f);  // -1: manual, one frame per read, none lost
    pc->setRepeatEnabled(false);
    if (depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK ||
        color_.create(device_, openni::SENSOR_COLOR) != openni::STATUS_OK)
      throw InputError(path_, "the recording needs a depth and a colour stream");
    depth_count_ = pc->getNumberOfFrames(depth_);
    color_count_ = pc->getNumberOfFrames(color_);
    count_ = std::min(depth_count_, color_count_);
    if (count_ <= 0) throw InputError(path_, "the recording has no frames in one of its streams");
    if (depth_.getVideoMode().getPixelFormat() != openni::PIXEL_FORMAT_DEPTH_1_MM ||
        color_.getVideoMode().getPixelFormat() != openni::PIXEL_FORMAT_RGB888)
      throw InputError(path_, "unsupported pixel format (expected 1 mm depth and RGB888 colour)");
    depth_.start();
    color_.start();
    depth_read_ = color_read_ = 0;
  }

  void ReadSideFile() {
    const std::string side = OniSideFile(path_);
    std::error_code ec;
    if (!fs::exists(side, ec)) return;
    try {
      const nlohmann::json j = nlohmann::json::parse(ReadTextFile(side));
      if (j.value("format", "") != "lightprobe-oni-side") throw InputError(side, "not a lightprobe side file");
      if (j.value("version", 0) != 1) throw InputError(side, "unsupported side file version");
      side_registered_ = j.at("registered").get<bool>();
      // Comparable across recordings only when the camera held them (not automatic).
      if (!j.value("auto_exposure", true) && j.value("exposure", -1) > 0 && j.value("gain", -1) > 0) {
        side_exposure_ = j.at("exposure").get<double>();
        side_gain_ = j.at("gain").get<double>();
      }
    } catch (const nlohmann::json::exception& e) {
      throw InputError(side, std::string("malformed side file: ") + e.what());
    }
  }

  std::string path_;
  OniPlaybackOptions options_;
  std::optional<bool> side_registered_;
  bool seeking_ = false;
  bool paused_ = false;  // SetPaused: a seek or a reopen keeps it
  double side_exposure_ = 0, side_gain_ = 0;
  int depth_count_ = 0, color_count_ = 0, depth_read_ = 0, color_read_ = 0;
  std::int64_t count_ = 0, produced_ = 0;
};


class DeviceSource;

/// What a DeviceSource and its LiveRecorder share. `read` is held by the source's reads
/// and by every recorder call (the Recorder must not start or stop during a read of the
/// same streams); `state` guards what the UI polls.
struct RecorderLink {
  std::mutex read;
  DeviceSource* source = nullptr;  ///< under `read`; null once the source is gone
  mutable std::mutex state;
  bool recording = false;
  int depth_frames = 0;
  std::chrono::steady_clock::time_point start;
  std::string ended;
};

class DeviceSource : public FrameSource, private OpenNiStreams, private openni::OpenNI::DeviceDisconnectedListener {
 public:
  DeviceSource(const OpenNiDeviceOptions& o, CameraControls* applied) : options_(o) {
    InitOpenNi();
    OpenDevice(&device_, o.uri);
    uri_ = device_.getDeviceInfo().getUri();
    openni::OpenNI::addDeviceDisconnectedListener(this);
    try {
      if (depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK ||
          color_.create(device_, openni::SENSOR_COLOR) != openni::STATUS_OK)
        throw InputError(uri_, "the device needs a depth and a colour stream: " + OpenNiError());
      SelectMode(depth_, o.width, o.height, o.fps, openni::PIXEL_FORMAT_DEPTH_1_MM, "depth");
      SelectMode(color_, o.width, o.height, o.fps, openni::PIXEL_FORMAT_RGB888, "colour");
      if (o.register_depth && device_.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR))
        device_.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
      if (o.sync) device_.setDepthColorSyncEnabled(true);
      if (depth_.start() != openni::STATUS_OK || color_.start() != openni::STATUS_OK)
        throw InputError(uri_, "cannot start the streams: " + OpenNiError());
      controls_ = ApplyCameraControls(device_, color_, o.lock_exposure, o.exposure, o.gain, uri_);
    } catch (...) {
      openni::OpenNI::removeDeviceDisconnectedListener(this);
      CloseDevice();
      throw;
    }
    if (applied) *applied = controls_;
    link_->source = this;
  }
  ~DeviceSource() override {
    {
      std::lock_guard<std::mutex> lock(link_->read);
      if (rec_) EndRecording("the camera was closed");
      link_->source = nullptr;
    }
    openni::OpenNI::removeDeviceDisconnectedListener(this);
    CloseDevice();
  }

  std::string Describe() const override { return "OpenNI2 device " + uri_; }

  SourceStatus Next(RgbdFrame* out, double timeout_seconds) override {
    std::lock_guard<std::mutex> lock(link_->read);
    if (lost_) {
      if (rec_) EndRecording("the device was unplugged");
      return SourceStatus::kDeviceLost;
    }
    if (!broken_.empty()) throw InputError(uri_, broken_);
    openni::VideoFrameRef d, c;
    int dr = 0, cr = 0;
    if (!ReadPair(&d, &c, static_cast<int>(timeout_seconds * 1000), &dr, &cr, 1 << 30, 1 << 30)) {
      if (!lost_) return SourceStatus::kTimeout;
      if (rec_) EndRecording("the device was unplugged");
      return SourceStatus::kDeviceLost;
    }
    *out = ToFrame(d, c, produced_++);
    if (controls_.camera_settings) {
      out->exposure = controls_.exposure;
      out->gain = controls_.gain;
    }
    if (rec_) {
      RecordResult& r = rec_->result;
      if (r.depth_frames == 0) r.first_depth_frame_index = d.getFrameIndex();
      ++r.depth_frames;
      ++r.color_frames;
      std::lock_guard<std::mutex> state(link_->state);
      link_->depth_frames = r.depth_frames;
    }
    return SourceStatus::kFrame;
  }
  void Rewind() override { throw InputError(uri_, "a live device cannot rewind"); }

  std::shared_ptr<RecorderLink> link() const { return link_; }

  // The LiveRecorder's calls, with link()->read held, on an OpenNI2 thread.
  bool recording() const { return rec_ != nullptr; }
  void StartRecording(const std::string& out_file, bool lossy_color) {
    if (rec_) throw InputError(out_file, "already recording to " + rec_->out_file);
    if (lost_) throw InputError(uri_, "the device was unplugged");
    if (!broken_.empty()) throw InputError(uri_, broken_);
    auto r = std::make_unique<Recording>();
    r->out_file = out_file;
    r->lossy_color = lossy_color;
    r->tmp = RecordingTempFile(out_file);
    r->result.controls = controls_;
    try {
      if (r->recorder.create(r->tmp.c_str()) != openni::STATUS_OK)
        throw InputError(out_file, "cannot create: " + OpenNiError());
      if (r->recorder.attach(depth_, false) != openni::STATUS_OK ||
          r->recorder.attach(color_, lossy_color) != openni::STATUS_OK)
        throw InputError(out_file, "cannot attach the streams to the recorder: " + OpenNiError());
      WaitForPairedFrames(depth_, color_, uri_);
      if (r->recorder.start() != openni::STATUS_OK) throw InputError(out_file, "cannot start recording: " + OpenNiError());
    } catch (...) {
      // As when stopping: streams first (OpenNI2's Recorder deadlock), then the recorder;
      // a recorder never created had nothing attached: the streams ran on untouched.
      if (r->recorder.isValid()) {
        StopRecorder(r->recorder, depth_, color_);
        RestartStreams();
      }
      std::error_code ec;
      fs::remove(r->tmp, ec);
      throw;
    }
    r->start = std::chrono::steady_clock::now();
    std::lock_guard<std::mutex> state(link_->state);
    link_->recording = true;
    link_->depth_frames = 0;
    link_->start = r->start;
    link_->ended.clear();
    rec_ = std::move(r);
  }
  /// Finishes the file; the streams start again unless the source is closing or lost.
  RecordResult StopRecording(bool restart = true) {
    std::unique_ptr<Recording> r = std::move(rec_);
    r->result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - r->start).count();
    StopRecorder(r->recorder, depth_, color_);
    {
      std::lock_guard<std::mutex> state(link_->state);
      link_->recording = false;
    }
    std::exception_ptr failure;  // the recording itself stays in its temporary file then
    try {
      PublishRecording(r->tmp, r->out_file, device_, r->result, r->lossy_color);
    } catch (...) {
      failure = std::current_exception();
    }
    if (restart && !lost_) RestartStreams();
    if (failure) std::rethrow_exception(failure);
    return r->result;
  }

 private:
  struct Recording {
    openni::Recorder recorder;
    std::string out_file;
    fs::path tmp;
    bool lossy_color = false;
    RecordResult result;
    std::chrono::steady_clock::time_point start;
  };

  /// A recording that ends without Stop (closing, unplugged): finished, and the outcome
  /// left for the recorder's owner.
  void EndRecording(const std::string& why) {
    const std::string file = rec_->out_file;
    std::string ended;
    try {
      ended = DescribeRecording(StopRecording(false), file) + " (" + why + ")";
    } catch (const std::exception& e) {
      ended = std::string("recording failed: ") + e.what();
    }
    std::lock_guard<std::mutex> state(link_->state);
    link_->ended = ended;
  }

  /// After a recording the streams run again with the exposure they had (read back at
  /// the start); a device that refuses is an error on the next read.
  void RestartStreams() {
    if (lost_) return;
    if (depth_.start() != openni::STATUS_OK || color_.start() != openni::STATUS_OK) {
      broken_ = "cannot restart the streams after recording: " + OpenNiError();
      return;
    }
    const bool keep = options_.lock_exposure && controls_.camera_settings;
    try {
      controls_ = ApplyCameraControls(device_, color_, options_.lock_exposure, keep ? controls_.exposure : options_.exposure,
                                      keep ? controls_.gain : options_.gain, uri_);
    } catch (const std::exception& e) {
      broken_ = e.what();
    }
  }

  void onDeviceDisconnected(const openni::DeviceInfo* info) override {
    if (info && uri_ == info->getUri()) lost_ = true;
  }

  OpenNiDeviceOptions options_;
  std::string uri_;
  CameraControls controls_;
  std::atomic<bool> lost_{false};
  std::int64_t produced_ = 0;
  std::shared_ptr<RecorderLink> link_ = std::make_shared<RecorderLink>();
  std::unique_ptr<Recording> rec_;
  std::string broken_;  ///< set when the streams could not restart after a recording
};

class DeviceRecorder : public LiveRecorder {
 public:
  explicit DeviceRecorder(std::shared_ptr<RecorderLink> link) : link_(std::move(link)) {}
  void Start(const std::string& out_file, bool lossy_color) override {
    OnOpenNiThread([&] {
      std::lock_guard<std::mutex> lock(link_->read);
      if (!link_->source) throw InputError(out_file, "cannot record: the camera is closed");
      link_->source->StartRecording(out_file, lossy_color);
    });
  }
  RecordResult Stop() override {
    return OnOpenNiThread([&] {
      std::lock_guard<std::mutex> lock(link_->read);
      if (!link_->source || !link_->source->recording()) throw InputError("record: not recording");
      return link_->source->StopRecording();
    });
  }
  bool recording() const override {
    std::lock_guard<std::mutex> state(link_->state);
    return link_->recording;
  }
  void Progress(int* depth_frames, double* seconds) const override {
    std::lock_guard<std::mutex> state(link_->state);
    *depth_frames = link_->recording ? link_->depth_frames : 0;
    *seconds = link_->recording
                   ? std::chrono::duration<double>(std::chrono::steady_clock::now() - link_->start).count()
                   : 0;
  }
  std::string EndedWithoutStop() const override {
    std::lock_guard<std::mutex> state(link_->state);
    return link_->ended;
  }

 private:
  std::shared_ptr<RecorderLink> link_;
};

/// A source whose every call (construction and destruction included) runs on the
/// OpenNI2 pool (OpenNiThreads).
class OnOpenNiThreadSource : public FrameSource {
 public:
  explicit OnOpenNiThreadSource(std::unique_ptr<FrameSource> inner) : inner_(std::move(inner)) {}
  ~OnOpenNiThreadSource() override {
    try {
      OnOpenNiThread([this] { inner_.reset(); });
    } catch (...) {
      // No pool thread could be started (the process is out of threads): leave the device
      // open rather than close it from this thread, which may exit (see OpenNiThreads);
      // a destructor that threw would end the process.
      (void)inner_.release();
    }
  }
  std::string Describe() const override { return inner_->Describe(); }
  std::optional<std::int64_t> FrameCount() const override { return inner_->FrameCount(); }
  SourceStatus Next(RgbdFrame* frame, double timeout_seconds) override {
    return OnOpenNiThread([&] { return inner_->Next(frame, timeout_seconds); });
  }
  void Rewind() override {
    OnOpenNiThread([this] { inner_->Rewind(); });
  }
  void Seek(std::int64_t frame) override {
    OnOpenNiThread([&] { inner_->Seek(frame); });
  }
  void SetPaused(bool paused) override {
    OnOpenNiThread([&] { inner_->SetPaused(paused); });
  }

 private:
  std::unique_ptr<FrameSource> inner_;
};

}  // namespace

std::unique_ptr<FrameSource> OpenOniFile(const std::string& path, const OniPlaybackOptions& options) {
  return std::make_unique<OnOpenNiThreadSource>(
      OnOpenNiThread([&]() -> std::unique_ptr<FrameSource> { return std::make_unique<OniFileSource>(path, options); }));
}

std::unique_ptr<FrameSource> OpenOpenNiDevice(const OpenNiDeviceOptions& options, CameraControls* applied,
                                              std::shared_ptr<LiveRecorder>* recorder) {
  auto device = OnOpenNiThread([&] { return std::make_unique<DeviceSource>(options, applied); });
  if (recorder) *recorder = std::make_shared<DeviceRecorder>(device->link());
  return std::make_unique<OnOpenNiThreadSource>(std::move(device));
}

std::vector<RgbdFrame> CaptureBracket(const OpenNiDeviceOptions& device, const std::vector<int>& exposures,
                                      int settle) {
  std::vector<RgbdFrame> out;
  for (int e : exposures) {
    if (e <= 0) throw InputError("bracket: exposures must be positive");
    OpenNiDeviceOptions o = device;
    o.lock_exposure = true;
    o.exposure = e;
    auto source = OpenOpenNiDevice(o);
    RgbdFrame f;
    for (int k = 0; k <= settle; ++k) {
      const SourceStatus s = source->Next(&f, 3.0);
      if (s != SourceStatus::kFrame)
        throw InputError(source->Describe() + ": no frame at exposure " + std::to_string(e) + " (" + ToString(s) + ")");
    }
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace lp
