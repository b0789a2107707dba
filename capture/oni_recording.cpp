// Recording `.oni` files: RecordOni (a device opened for the recording), the helpers it
// shares with a live device's recording, the LiveRecorder handle of a live device, and
// the side file that keeps what an `.oni` cannot hold.
#include "capture/openni.h"

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>

#include <nlohmann/json.hpp>

#include "capture/openni_runtime.h"
#include "common/atomic_file.h"
#include "common/error.h"

namespace lp {
namespace fs = std::filesystem;
using namespace openni_detail;

namespace {

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

/// StopRecorder, then the streams are destroyed.
void FinishRecording(openni::Recorder& recorder, openni::VideoStream& depth, openni::VideoStream& color) {
  StopRecorder(recorder, depth, color);
  depth.destroy();
  color.destroy();
}

/// RecordOni on the calling thread (one of OpenNiThreads).
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

/// A live device's LiveRecorder: every call goes to the device through the RecorderLink.
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
      return link_->source->StopRecording(/*restart=*/true);
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
  RecordingEnd EndedWithoutStop() const override {
    std::lock_guard<std::mutex> state(link_->state);
    return link_->ended;
  }

 private:
  std::shared_ptr<RecorderLink> link_;
};

}  // namespace

namespace openni_detail {

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

fs::path RecordingTempFile(const std::string& out_file) {
  const fs::path out(out_file);
  std::error_code ec;
  if (!out.parent_path().empty()) fs::create_directories(out.parent_path(), ec);
  return out.parent_path() / ("." + out.filename().string() + ".recording.oni");
}

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

std::shared_ptr<LiveRecorder> MakeLiveRecorder(std::shared_ptr<RecorderLink> link) {
  return std::make_shared<DeviceRecorder>(std::move(link));
}

}  // namespace openni_detail

RecordResult RecordOni(const std::string& out_file, const RecordOptions& o) {
  return OnOpenNiThread([&] { return RecordOniHere(out_file, o); });
}

std::string OniSideFile(const std::string& oni_file) { return oni_file + ".json"; }

std::string DescribeRecording(const RecordResult& r, const std::string& file) {
  char line[96];
  std::snprintf(line, sizeof line, "recorded %d depth frames in %.1f s to ", r.depth_frames, r.seconds);
  return line + file;
}

}  // namespace lp
