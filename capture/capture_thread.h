#pragma once
/// One capture thread per source: it pulls frames from a FrameSource and pushes them into
/// a FrameQueue (which drops the oldest when the consumer is slow), until the source ends,
/// the device goes away, or Stop() is called. Counters and the last status are readable
/// from any thread (for the UI).
#include <atomic>
#include <condition_variable>
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
  double fps = 0;                  ///< paired frames per second over the last second or so
  /// Per stream: new depth / colour images per second over the same window (a frame
  /// whose image repeats the previous one's timestamp is not new: that stream dropped).
  double depth_fps = 0, color_fps = 0;
  bool running = false;
  bool paused = false;
  /// The source's frame the next read delivers: frames read since the start or the last
  /// seek, plus the seek target (a looping source keeps counting).
  std::int64_t position = 0;
  SourceStatus last_status = SourceStatus::kFrame;  ///< why it stopped, once stopped
  std::string error;               ///< an exception's message if the source threw
};

class CaptureThread {
 public:
  /// Starts reading `source` into `queue` at once. The queue is closed when the thread
  /// ends, so a consumer waiting in Pop() wakes up. With `hold_at_end` the thread does not
  /// end with the source: it pauses at the end and waits for a Seek() or Stop() (a
  /// viewer's play/pause/seek bar).
  CaptureThread(std::unique_ptr<FrameSource> source, std::shared_ptr<FrameQueue> queue, bool hold_at_end = false);
  /// Stops and joins.
  ~CaptureThread();
  CaptureThread(const CaptureThread&) = delete;
  CaptureThread& operator=(const CaptureThread&) = delete;

  /// Asks the thread to stop after the frame it is reading and waits for it.
  void Stop();
  /// Pause / resume reading (the source's clock is held: FrameSource::SetPaused).
  void Pause(bool paused);
  /// The next frame queued is the source's frame `frame`; applied on the capture thread
  /// (works while paused). A seek the source refuses ends the thread with the error.
  void Seek(std::int64_t frame);
  CaptureStats stats() const;

 private:
  void Run();

  std::unique_ptr<FrameSource> source_;
  std::shared_ptr<FrameQueue> queue_;
  std::atomic<bool> stop_{false}, paused_{false};
  std::atomic<std::int64_t> seek_to_{-1};
  bool hold_at_end_ = false;
  std::mutex wake_mutex_;
  std::condition_variable wake_;
  mutable std::mutex mutex_;
  CaptureStats stats_;
  std::thread thread_;
};

}  // namespace lp
