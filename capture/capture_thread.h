#pragma once
/// One capture thread per source: it pulls frames from a FrameSource and pushes them into
/// a FrameQueue (which drops the oldest when the consumer is slow), until the source ends,
/// the device goes away, or Stop() is called. Counters and the last status are readable
/// from any thread (for the UI).
#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "capture/frame_queue.h"
#include "capture/frame_source.h"

namespace lp {

struct CaptureStats {
  std::int64_t captured = 0;       ///< frames read from the source
  QueueCounters queue;             ///< pushed / dropped / popped
  double fps = 0;                  ///< frames per second over the last second or so
  bool running = false;
  SourceStatus last_status = SourceStatus::kFrame;  ///< why it stopped, once stopped
  std::string error;               ///< an exception's message if the source threw
};

class CaptureThread {
 public:
  /// Starts reading `source` into `queue` at once. The queue is closed when the thread
  /// ends, so a consumer waiting in Pop() wakes up.
  CaptureThread(std::unique_ptr<FrameSource> source, std::shared_ptr<FrameQueue> queue);
  /// Stops and joins.
  ~CaptureThread();
  CaptureThread(const CaptureThread&) = delete;
  CaptureThread& operator=(const CaptureThread&) = delete;

  /// Asks the thread to stop after the frame it is reading and waits for it.
  void Stop();
  CaptureStats stats() const;

 private:
  void Run();

  std::unique_ptr<FrameSource> source_;
  std::shared_ptr<FrameQueue> queue_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mutex_;
  CaptureStats stats_;
  std::thread thread_;
};

}  // namespace lp
