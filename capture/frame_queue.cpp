#include "capture/frame_queue.h"

#include "common/error.h"

namespace lp {

FrameQueue::FrameQueue(std::size_t capacity) : capacity_(capacity) { LP_CHECK(capacity >= 1, "queue capacity"); }

bool FrameQueue::Push(RgbdFrame frame) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return false;
    ++counters_.pushed;
    if (frames_.size() >= capacity_) {
      frames_.pop_front();
      ++counters_.dropped;
    }
    frames_.push_back(std::move(frame));
  }
  ready_.notify_one();
  return true;
}

std::optional<RgbdFrame> FrameQueue::Pop(double timeout_seconds) {
  std::unique_lock<std::mutex> lock(mutex_);
  const auto wait = std::chrono::duration<double>(std::max(0.0, timeout_seconds));
  ready_.wait_for(lock, wait, [&] { return !frames_.empty() || closed_; });
  if (frames_.empty()) return std::nullopt;
  RgbdFrame f = std::move(frames_.front());
  frames_.pop_front();
  ++counters_.popped;
  return f;
}

void FrameQueue::Close() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
  }
  ready_.notify_all();
}

bool FrameQueue::closed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return closed_;
}

std::size_t FrameQueue::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return frames_.size();
}

QueueCounters FrameQueue::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

}  // namespace lp
