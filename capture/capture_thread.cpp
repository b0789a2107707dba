#include "capture/capture_thread.h"

#include <chrono>

namespace lp {

CaptureThread::CaptureThread(std::unique_ptr<FrameSource> source, std::shared_ptr<FrameQueue> queue)
    : source_(std::move(source)), queue_(std::move(queue)) {
  stats_.running = true;
  thread_ = std::thread([this] { Run(); });
}

CaptureThread::~CaptureThread() { Stop(); }

void CaptureThread::Stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
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
  std::int64_t window_frames = 0;
  SourceStatus status = SourceStatus::kFrame;
  std::string error;
  while (!stop_) {
    RgbdFrame frame;
    try {
      // Short timeouts so Stop() is honoured promptly even when a device goes quiet.
      status = source_->Next(&frame, 0.2);
    } catch (const std::exception& e) {
      error = e.what();
      status = SourceStatus::kEnd;
      break;
    }
    if (status == SourceStatus::kTimeout) continue;
    if (status != SourceStatus::kFrame) break;
    frame.queued_at = std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
    queue_->Push(std::move(frame));
    ++window_frames;
    const double dt = std::chrono::duration<double>(Clock::now() - window_start).count();
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.captured;
    if (dt >= 1.0) {
      stats_.fps = window_frames / dt;
      window_frames = 0;
      window_start = Clock::now();
    }
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.running = false;
    stats_.last_status = status;
    stats_.error = error;
  }
  queue_->Close();
}

}  // namespace lp
