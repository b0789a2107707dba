#pragma once
// Private to capture/: what the OpenNI2 files share (openni_runtime.cpp, oni_file.cpp,
// openni_device.cpp, oni_recording.cpp). It includes OpenNI.h, so no public header may
// include it (architecture.md: no OpenNI header in a public header).
#include <OpenNI.h>

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include "capture/frame_source.h"
#include "capture/openni.h"

namespace lp::openni_detail {

// ---- The runtime (openni_runtime.cpp) ----

/// OpenNI2 keeps an error log per calling thread, keyed by pthread_t, and when a thread
/// calls it for the first time it probes every thread it has seen with pthread_kill(id, 0).
/// Once a thread that called OpenNI2 has exited and glibc has unmapped its stack (glibc
/// keeps ~40 MiB of stacks cached), that probe reads unmapped memory and the process
/// crashes: e.g. a viewer Session that played a file, then a new Session opening a camera.
/// So no thread that calls OpenNI2 may exit: every OpenNI2 call in capture/ runs on a
/// thread of this pool, which lives as long as the process. It grows to the number of
/// calls in flight at once (a capture thread's read, a recording, ...); idle threads wait.
class OpenNiThreads {
 public:
  /// Never destroyed: its threads wait on it until the process ends.
  static OpenNiThreads& Get();

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
  void Loop();

  std::mutex m_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> jobs_;
  std::size_t idle_ = 0;
  static thread_local bool on_pool_thread_;
};

template <class F>
auto OnOpenNiThread(F&& f) -> decltype(f()) {
  return OpenNiThreads::Get().Run(std::forward<F>(f));
}

/// OpenNI2 is initialized once per process and never shut down (shutting down and
/// initializing again is not reliable in 2.2).
void InitOpenNi();

/// OpenNI2's extended error on one line (newlines and tabs as spaces, trimmed).
std::string OpenNiError();

/// Stops the streams and gives the frames in flight time to land: drivers like
/// DummyDevice crash if their streams are destroyed right after stopping.
void StopStreams(openni::VideoStream& depth, openni::VideoStream& color);

/// Stops (if not yet) and destroys the streams.
void ReleaseStreams(openni::VideoStream& depth, openni::VideoStream& color);

/// OpenNI2's Recorder deadlocks when it is stopped while a frame arrives (the recorder's
/// lock and the stream's are taken in opposite orders): stop the streams first, then
/// stop and destroy the recorder. The streams stay (stopped).
void StopRecorder(openni::Recorder& recorder, openni::VideoStream& depth, openni::VideoStream& color);

/// Opens `uri` ("" = the first device); throws InputError with the reason (the USB scan's
/// for a camera, the driver folder for the synthetic device).
void OpenDevice(openni::Device* device, const std::string& uri);

/// Sets a stream to the mode with this size and pixel format, at `fps` or the nearest.
void SelectMode(openni::VideoStream& s, int w, int h, int fps, openni::PixelFormat format, const char* what);

/// Locks auto exposure / white balance and sets exposure / gain (when >= 0) on the colour
/// stream, after the streams started (some devices ignore settings made before), then
/// reads back what the device uses; a device that did not take them is an error.
CameraControls ApplyCameraControls(openni::Device& device, openni::VideoStream& color, bool lock, int exposure,
                                   int gain, const std::string& uri);

/// What both OpenNI2 sources share: a device with a depth and a colour stream, frames
/// paired by timestamp (within half a frame period), copied into owned RgbdFrames.
class OpenNiStreams {
 protected:
  /// Reads one frame of `s`, waiting at most timeout_ms.
  bool Read(openni::VideoStream& s, openni::VideoFrameRef* f, int timeout_ms);
  /// Reads a depth and a colour frame taken at the same time: the older one is read again
  /// until their timestamps are within half a frame period (a stream that dropped a frame
  /// skips ahead to its partner). `budget` limits the extra reads (end of a recording).
  bool ReadPair(openni::VideoFrameRef* d, openni::VideoFrameRef* c, int timeout_ms, int* depth_reads,
                int* color_reads, int depth_budget, int color_budget);
  RgbdFrame ToFrame(const openni::VideoFrameRef& d, const openni::VideoFrameRef& c, std::int64_t index);
  /// The colour and depth cameras at w x h. OpenNI2 reports fields of view, not a
  /// principal point (centred); a stream without one (OpenNI 1 recordings) takes, in this
  /// order: for colour, the depth stream's (PS1080 reports one field of view for both);
  /// the depth stream's zero-plane distance and pixel size (PS1080 / OpenNI 1
  /// properties); the Kinect v1 / PrimeSense default, 525 px at 640 x 480. `note`, when
  /// given, says which was used ("" when each stream had its own).
  Camera ColorIntrinsics(int w, int h, std::string* note = nullptr);
  Camera DepthIntrinsics(int w, int h, std::string* note = nullptr);
  /// The PS1080 family's (Kinect v1, Xtion, Carmine) depth-to-colour transform for
  /// unregistered depth: the colour camera beside the depth camera, no rotation, at the
  /// depth stream's DCMOS-RCMOS distance when it reports one (OpenNI 1 recordings, PS1080
  /// devices), else 2.5 cm (ROS rgbd_launch's kinect_frames.launch); to the right of it
  /// as the device sees, to the left in mirrored images.
  RgbdFrame::Extrinsics DeviceExtrinsics();
  void CloseDevice();

  openni::Device device_;
  openni::VideoStream depth_, color_;
};

/// A source whose every call (construction and destruction included) runs on the
/// OpenNI2 pool (OpenNiThreads).
class OnOpenNiThreadSource : public FrameSource {
 public:
  explicit OnOpenNiThreadSource(std::unique_ptr<FrameSource> inner) : inner_(std::move(inner)) {}
  ~OnOpenNiThreadSource() override;
  std::string Describe() const override { return inner_->Describe(); }
  std::optional<std::int64_t> FrameCount() const override { return inner_->FrameCount(); }
  SourceStatus Next(RgbdFrame* frame, double timeout_seconds) override;
  void Rewind() override;
  void Seek(std::int64_t frame) override;
  void SetPaused(bool paused) override;

 private:
  std::unique_ptr<FrameSource> inner_;
};

// ---- Recording (oni_recording.cpp), shared by RecordOni and a live device's recording ----

/// OpenNI2's recordings keep each stream's timestamps relative to its own first recorded
/// frame, so both streams must start recording with the same frame or replay pairs them
/// one frame apart: returns just after a depth and a colour frame with the same timestamp
/// arrived (the next pair is a frame period away), when the recorder is to start.
void WaitForPairedFrames(openni::VideoStream& depth, openni::VideoStream& color, const std::string& uri);

/// Where a recording is written until it is finished: `.NAME.recording.oni` next to it.
std::filesystem::path RecordingTempFile(const std::string& out_file);

/// Moves a finished recording into place and writes its side file (an old side file never
/// describes the new recording: removed before the .oni moves in); `result` takes the
/// frame counts the file holds.
void PublishRecording(const std::filesystem::path& tmp, const std::string& out_file, openni::Device& device,
                      RecordResult& result, bool lossy_color);

/// A live source that records its own running streams (openni_device.cpp): what a
/// LiveRecorder drives. Its calls are made with RecorderLink::read held, on an OpenNI2
/// thread.
class RecordableDevice {
 public:
  virtual bool recording() const = 0;
  virtual void StartRecording(const std::string& out_file, bool lossy_color) = 0;
  /// Finishes the file; the streams start again when `restart` unless the device is lost.
  virtual RecordResult StopRecording(bool restart) = 0;

 protected:
  ~RecordableDevice() = default;
};

/// What a live source and its LiveRecorder share. `read` is held by the source's reads
/// and by every recorder call (the Recorder must not start or stop during a read of the
/// same streams); `state` guards what the UI polls.
struct RecorderLink {
  std::mutex read;
  RecordableDevice* source = nullptr;  ///< under `read`; null once the source is gone
  mutable std::mutex state;
  bool recording = false;
  int depth_frames = 0;
  std::chrono::steady_clock::time_point start;
  RecordingEnd ended;
};

/// The LiveRecorder of the source behind `link` (it outlives the source harmlessly).
std::shared_ptr<LiveRecorder> MakeLiveRecorder(std::shared_ptr<RecorderLink> link);

}  // namespace lp::openni_detail
