#include "ui/recording.h"

#include "common/error.h"

namespace lp::ui {

void Recording::Attach(std::shared_ptr<LiveRecorder> recorder) { recorder_ = std::move(recorder); }

RecordingUpdate Recording::Start(const std::string& path, double seconds) {
  if (!recorder_) throw InputError("record: open a camera first (recording needs a live device)");
  if (recorder_->recording()) throw InputError("record: already recording");
  stop_seen_ = stop_requests_.load();  // a stop from now on ends this recording
  RecordingUpdate u;
  try {
    recorder_->Start(path);
  } catch (const std::exception& e) {
    u.state = RecordState::kFailed;
    u.message = std::string("recording failed: ") + e.what();
    return u;
  }
  seconds_ = seconds;
  path_ = path;
  started_ = true;
  last_ = RecordingUpdate{};
  u.state = RecordState::kRecording;
  u.message = "recording to " + path;
  return u;
}

std::optional<RecordingUpdate> Recording::Poll() {
  if (!recorder_) return std::nullopt;
  if (!recorder_->recording()) return started_ ? EndedWithoutStop() : std::nullopt;
  RecordingUpdate u;
  u.state = RecordState::kRecording;
  recorder_->Progress(&u.frames, &u.seconds);
  last_ = u;
  if (stop_requests_.load() != stop_seen_ || (seconds_ > 0 && u.seconds >= seconds_)) return Finish();
  return u;
}

std::optional<RecordingUpdate> Recording::Close() {
  std::optional<RecordingUpdate> u;
  if (recorder_ && recorder_->recording()) u = Finish();
  else if (started_) u = EndedWithoutStop();  // unplugged, not yet polled
  started_ = false;
  recorder_.reset();
  return u;
}

/// A recording the source finished by itself (the camera unplugged): its outcome. The
/// source stops recording before it has finished the file and said how it ended: until it
/// has, the recording stays started and the next poll asks again.
std::optional<RecordingUpdate> Recording::EndedWithoutStop() {
  const RecordingEnd ended = recorder_ ? recorder_->EndedWithoutStop() : RecordingEnd{};
  if (ended.how == RecordingEnd::How::kNotEnded) return std::nullopt;
  started_ = false;
  RecordingUpdate u = last_;
  u.state = ended.how == RecordingEnd::How::kSaved ? RecordState::kRecorded : RecordState::kFailed;
  u.message = ended.message;
  return u;
}

RecordingUpdate Recording::Finish() {
  RecordingUpdate u = last_;  // the frames and seconds it reached stay on the panel
  try {
    u.message = DescribeRecording(recorder_->Stop(), path_);
    u.state = RecordState::kRecorded;
  } catch (const std::exception& e) {
    // The source may have finished it first (unplugged while we asked): its outcome.
    const RecordingEnd ended = recorder_->EndedWithoutStop();
    u.state = ended.how == RecordingEnd::How::kSaved ? RecordState::kRecorded : RecordState::kFailed;
    u.message = ended.how == RecordingEnd::How::kNotEnded ? std::string("recording failed: ") + e.what()
                                                          : ended.message;
  }
  started_ = false;
  return u;
}

}  // namespace lp::ui
