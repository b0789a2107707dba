#pragma once
/// Recording the open camera into an .oni file while the previews and the reconstruction
/// go on (Session::Record): OpenNI2's Recorder attached to the camera's running streams
/// through its LiveRecorder. Owned and driven by the session's worker; only RequestStop
/// is called from another thread.
#include <atomic>
#include <memory>
#include <optional>
#include <string>

#include "capture/openni.h"
#include "ui/status.h"

namespace lp::ui {

/// What the live panel shows of a recording, when it changed.
struct RecordingUpdate {
  RecordState state = RecordState::kIdle;
  int frames = 0;        ///< depth frames so far (kRecording)
  double seconds = 0;
  std::string message;   ///< the outcome or "recording to FILE"; "" = progress only
};

class Recording {
 public:
  /// The open camera's recorder (null: the source is not a camera).
  void Attach(std::shared_ptr<LiveRecorder> recorder);
  /// Starts recording into `path` for `seconds` (<= 0: until RequestStop). Throws
  /// InputError when there is no camera or a recording is running; a recorder that cannot
  /// start is an update with kFailed.
  RecordingUpdate Start(const std::string& path, double seconds);
  /// Any thread: ends the recording at the next Poll; the frames so far are kept.
  void RequestStop() { ++stop_requests_; }
  /// Between frames: the recording's progress, its end (its time is up or a stop was
  /// requested), or its end without us (the camera was unplugged).
  std::optional<RecordingUpdate> Poll();
  /// The source closes: a recording in progress finishes its file with the frames so far.
  std::optional<RecordingUpdate> Close();

 private:
  RecordingUpdate Finish();
  std::optional<RecordingUpdate> EndedWithoutStop();

  std::shared_ptr<LiveRecorder> recorder_;
  std::atomic<int> stop_requests_{0};
  int stop_seen_ = 0;     ///< stop_requests_ when the recording started
  double seconds_ = 0;    ///< its length (<= 0: no limit)
  std::string path_;
  bool started_ = false;  ///< a recording whose outcome is not reported yet
  RecordingUpdate last_;  ///< its last progress
};

}  // namespace lp::ui
