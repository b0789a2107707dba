#pragma once
/// The bounded queue between a capture thread and its consumer: Push never blocks and
/// drops the oldest frame when full (a live camera must not stall); Pop waits with a
/// timeout; Close wakes everyone for shutdown.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>

#include "capture/frame.h"

namespace lp {

struct QueueCounters {
  std::int64_t pushed = 0;   ///< frames offered by the producer
  std::int64_t dropped = 0;  ///< oldest frames discarded because the queue was full
  std::int64_t popped = 0;   ///< frames handed to the consumer
};

class FrameQueue {
 public:
  /// `capacity` >= 1 frames.
  explicit FrameQueue(std::size_t capacity);

  /// Adds a frame, discarding the oldest one if the queue is full. Never blocks on the
  /// consumer (only on the queue's own short lock). Returns false once closed.
  bool Push(RgbdFrame frame);
  /// The oldest frame, waiting at most `timeout_seconds`; nullopt on timeout or when the
  /// queue is closed and empty.
  std::optional<RgbdFrame> Pop(double timeout_seconds);
  /// No more pushes; waiting consumers wake up (frames still queued can be popped).
  void Close();
  bool closed() const;
  std::size_t size() const;
  QueueCounters counters() const;

 private:
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<RgbdFrame> frames_;
  QueueCounters counters_;
  bool closed_ = false;
};

}  // namespace lp
