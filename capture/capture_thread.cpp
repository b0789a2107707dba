#include "capture/capture_thread.h"

#include <chrono>

namespace lp {

CaptureThread::CaptureThread(std::unique_ptr<FrameSource> source, std::shared_ptr<FrameQueue> queue, bool hold_at_end)
    : source_(std::move(source)), queue_(std::move(queue)), hold_at_end_(hold_at_end) {
  stats_.running = true;
  thread_ = std::thread([this] { Run(); });
}

CaptureThread::~CaptureThread() { Stop(); }

void CaptureThread::Stop() {
  stop_ = true;
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void CaptureThread::Pause(bool paused) {
  paused_ = paused;
  wake_.notify_all();
}

void CaptureThread::Seek(std::int64_t frame) {
  seek_to_ = frame;
  wake_.notify_all();
}

CaptureStats CaptureThread::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  CaptureStats s = stats_;
  s.queue = queue_->counters();
  return s;
}

void CaptureThread::Run() {
  using Clock = std::chrono::steady_clock;
  auto window_start = Clock::now();
  std::int64_t window_frames = 0, window_depth = 0, window_color = 0;
  double last_depth_ts = -1, last_color_ts = -1;
  SourceStatus status = SourceStatus::kFrame;
  std::string error;
  bool source_paused = false, at_end = false;
  auto publish = [&](auto&& update) {
    std::lock_guard<std::mutex> lock(mutex_);
    update(stats_);
  };
  while (!stop_) {
    try {
      // Controls from other threads, applied here: the source belongs to this thread.
      if (const std::int64_t target = seek_to_.exchange(-1); target >= 0) {
        source_->Seek(target);
        source_paused = false;  // a seek may restart the source's clock: pause it again below
        at_end = false;
        publish([&](CaptureStats& s) { s.position = target; });
      }
      const bool pause = paused_ || at_end;
      if (pause != source_paused) {
        source_->SetPaused(pause);
        source_paused = pause;
        publish([&](CaptureStats& s) { s.paused = pause; });
      }
      if (pause) {
        std::unique_lock<std::mutex> lock(wake_mutex_);
        wake_.wait_for(lock, std::chrono::milliseconds(50));
        continue;
      }
      RgbdFrame frame;
      // Short timeouts so Stop() is honoured promptly even when a device goes quiet.
      status = source_->Next(&frame, 0.2);
      if (status == SourceStatus::kTimeout) continue;
      if (status == SourceStatus::kEnd && hold_at_end_) {
        at_end = true;
        continue;
      }
      if (status != SourceStatus::kFrame) break;
      window_depth += frame.depth_timestamp != last_depth_ts;
      window_color += frame.color_timestamp != last_color_ts;
      last_depth_ts = frame.depth_timestamp;
      last_color_ts = frame.color_timestamp;
      frame.queued_at = std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
      queue_->Push(std::move(frame));
    } catch (const std::exception& e) {
      error = e.what();
      status = SourceStatus::kEnd;
      break;
    }
    ++window_frames;
    const double dt = std::chrono::duration<double>(Clock::now() - window_start).count();
    publish([&](CaptureStats& s) {
      ++s.captured;
      ++s.position;
      if (dt >= 1.0) {
        s.fps = window_frames / dt;
        s.depth_fps = window_depth / dt;
        s.color_fps = window_color / dt;
        window_frames = window_depth = window_color = 0;
        window_start = Clock::now();
      }
    });
  }
  publish([&](CaptureStats& s) {
    s.running = false;
    s.last_status = status;
    s.error = error;
  });
  queue_->Close();
}

}  // namespace lp
