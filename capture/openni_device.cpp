// A live OpenNI2 device as a FrameSource (OpenOpenNiDevice), recording its running streams
// for its LiveRecorder, and the exposure bracket taken from it (CaptureBracket).
#include "capture/openni.h"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "capture/openni_runtime.h"
#include "common/error.h"

namespace lp {
namespace fs = std::filesystem;
using namespace openni_detail;

namespace {

/// A live device (OpenOpenNiDevice); its LiveRecorder records its running streams
/// (RecordableDevice, through the RecorderLink).
class DeviceSource : public FrameSource,
                     private OpenNiStreams,
                     private RecordableDevice,
                     private openni::OpenNI::DeviceDisconnectedListener {
 public:
  DeviceSource(const OpenNiDeviceOptions& o, CameraControls* applied) : options_(o) {
    InitOpenNi();
    OpenDevice(&device_, o.uri);
    uri_ = device_.getDeviceInfo().getUri();
    openni::OpenNI::addDeviceDisconnectedListener(this);
    try {
      if (depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK ||
          color_.create(device_, openni::SENSOR_COLOR) != openni::STATUS_OK)
        throw InputError(uri_, "the device needs a depth and a colour stream: " + OpenNiError());
      SelectMode(depth_, o.width, o.height, o.fps, openni::PIXEL_FORMAT_DEPTH_1_MM, "depth");
      SelectMode(color_, o.width, o.height, o.fps, openni::PIXEL_FORMAT_RGB888, "colour");
      if (o.register_depth && device_.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR))
        device_.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
      if (o.sync) device_.setDepthColorSyncEnabled(true);
      if (depth_.start() != openni::STATUS_OK || color_.start() != openni::STATUS_OK)
        throw InputError(uri_, "cannot start the streams: " + OpenNiError());
      controls_ = ApplyCameraControls(device_, color_, o.lock_exposure, o.exposure, o.gain, uri_);
    } catch (...) {
      openni::OpenNI::removeDeviceDisconnectedListener(this);
      CloseDevice();
      throw;
    }
    if (applied) *applied = controls_;
    link_->source = this;
  }
  ~DeviceSource() override {
    {
      std::lock_guard<std::mutex> lock(link_->read);
      if (rec_) EndRecording("the camera was closed");
      link_->source = nullptr;
    }
    openni::OpenNI::removeDeviceDisconnectedListener(this);
    CloseDevice();
  }

  std::string Describe() const override { return "OpenNI2 device " + uri_; }

  SourceStatus Next(RgbdFrame* out, double timeout_seconds) override {
    std::lock_guard<std::mutex> lock(link_->read);
    if (lost_) {
      if (rec_) EndRecording("the device was unplugged");
      return SourceStatus::kDeviceLost;
    }
    if (!broken_.empty()) throw InputError(uri_, broken_);
    openni::VideoFrameRef d, c;
    int dr = 0, cr = 0;
    if (!ReadPair(&d, &c, static_cast<int>(timeout_seconds * 1000), &dr, &cr, 1 << 30, 1 << 30)) {
      if (!lost_) return SourceStatus::kTimeout;
      if (rec_) EndRecording("the device was unplugged");
      return SourceStatus::kDeviceLost;
    }
    *out = ToFrame(d, c, produced_++);
    if (controls_.camera_settings) {
      out->exposure = controls_.exposure;
      out->gain = controls_.gain;
    }
    if (rec_) {
      RecordResult& r = rec_->result;
      if (r.depth_frames == 0) r.first_depth_frame_index = d.getFrameIndex();
      ++r.depth_frames;
      ++r.color_frames;
      std::lock_guard<std::mutex> state(link_->state);
      link_->depth_frames = r.depth_frames;
    }
    return SourceStatus::kFrame;
  }
  void Rewind() override { throw InputError(uri_, "a live device cannot rewind"); }

  std::shared_ptr<RecorderLink> link() const { return link_; }

  // The LiveRecorder's calls (RecordableDevice), with link()->read held, on an OpenNI2 thread.
  bool recording() const override { return rec_ != nullptr; }
  void StartRecording(const std::string& out_file, bool lossy_color) override {
    if (rec_) throw InputError(out_file, "already recording to " + rec_->out_file);
    if (lost_) throw InputError(uri_, "the device was unplugged");
    if (!broken_.empty()) throw InputError(uri_, broken_);
    auto r = std::make_unique<Recording>();
    r->out_file = out_file;
    r->lossy_color = lossy_color;
    r->tmp = RecordingTempFile(out_file);
    r->result.controls = controls_;
    try {
      if (r->recorder.create(r->tmp.c_str()) != openni::STATUS_OK)
        throw InputError(out_file, "cannot create: " + OpenNiError());
      if (r->recorder.attach(depth_, false) != openni::STATUS_OK ||
          r->recorder.attach(color_, lossy_color) != openni::STATUS_OK)
        throw InputError(out_file, "cannot attach the streams to the recorder: " + OpenNiError());
      WaitForPairedFrames(depth_, color_, uri_);
      if (r->recorder.start() != openni::STATUS_OK) throw InputError(out_file, "cannot start recording: " + OpenNiError());
    } catch (...) {
      // As when stopping: streams first (OpenNI2's Recorder deadlock), then the recorder;
      // a recorder never created had nothing attached: the streams ran on untouched.
      if (r->recorder.isValid()) {
        StopRecorder(r->recorder, depth_, color_);
        RestartStreams();
      }
      std::error_code ec;
      fs::remove(r->tmp, ec);
      throw;
    }
    r->start = std::chrono::steady_clock::now();
    std::lock_guard<std::mutex> state(link_->state);
    link_->recording = true;
    link_->depth_frames = 0;
    link_->start = r->start;
    link_->ended = RecordingEnd{};
    rec_ = std::move(r);
  }
  /// Finishes the file; the streams start again unless the source is closing or lost.
  RecordResult StopRecording(bool restart) override {
    std::unique_ptr<Recording> r = std::move(rec_);
    r->result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - r->start).count();
    StopRecorder(r->recorder, depth_, color_);
    {
      std::lock_guard<std::mutex> state(link_->state);
      link_->recording = false;
    }
    std::exception_ptr failure;  // the recording itself stays in its temporary file then
    try {
      PublishRecording(r->tmp, r->out_file, device_, r->result, r->lossy_color);
    } catch (...) {
      failure = std::current_exception();
    }
    if (restart && !lost_) RestartStreams();
    if (failure) std::rethrow_exception(failure);
    return r->result;
  }

 private:
  struct Recording {
    openni::Recorder recorder;
    std::string out_file;
    fs::path tmp;
    bool lossy_color = false;
    RecordResult result;
    std::chrono::steady_clock::time_point start;
  };

  /// A recording that ends without Stop (closing, unplugged): finished, and the outcome
  /// left for the recorder's owner.
  void EndRecording(const std::string& why) {
    const std::string file = rec_->out_file;
    RecordingEnd ended;
    try {
      ended.result = StopRecording(false);
      ended.how = RecordingEnd::How::kSaved;
      ended.message = DescribeRecording(ended.result, file) + " (" + why + ")";
    } catch (const std::exception& e) {
      ended.how = RecordingEnd::How::kFailed;
      ended.message = std::string("recording failed: ") + e.what();
    }
    std::lock_guard<std::mutex> state(link_->state);
    link_->ended = ended;
  }

  /// After a recording the streams run again with the exposure they had (read back at
  /// the start); a device that refuses is an error on the next read.
  void RestartStreams() {
    if (lost_) return;
    if (depth_.start() != openni::STATUS_OK || color_.start() != openni::STATUS_OK) {
      broken_ = "cannot restart the streams after recording: " + OpenNiError();
      return;
    }
    const bool keep = options_.lock_exposure && controls_.camera_settings;
    try {
      controls_ = ApplyCameraControls(device_, color_, options_.lock_exposure, keep ? controls_.exposure : options_.exposure,
                                      keep ? controls_.gain : options_.gain, uri_);
    } catch (const std::exception& e) {
      broken_ = e.what();
    }
  }

  void onDeviceDisconnected(const openni::DeviceInfo* info) override {
    if (info && uri_ == info->getUri()) lost_ = true;
  }

  OpenNiDeviceOptions options_;
  std::string uri_;
  CameraControls controls_;
  std::atomic<bool> lost_{false};
  std::int64_t produced_ = 0;
  std::shared_ptr<RecorderLink> link_ = std::make_shared<RecorderLink>();
  std::unique_ptr<Recording> rec_;
  std::string broken_;  ///< set when the streams could not restart after a recording
};

}  // namespace

std::unique_ptr<FrameSource> OpenOpenNiDevice(const OpenNiDeviceOptions& options, CameraControls* applied,
                                              std::shared_ptr<LiveRecorder>* recorder) {
  auto device = OnOpenNiThread([&] { return std::make_unique<DeviceSource>(options, applied); });
  if (recorder) *recorder = MakeLiveRecorder(device->link());
  return std::make_unique<OnOpenNiThreadSource>(std::move(device));
}

std::vector<RgbdFrame> CaptureBracket(const OpenNiDeviceOptions& device, const std::vector<int>& exposures,
                                      int settle) {
  std::vector<RgbdFrame> out;
  for (int e : exposures) {
    if (e <= 0) throw InputError("bracket: exposures must be positive");
    OpenNiDeviceOptions o = device;
    o.lock_exposure = true;
    o.exposure = e;
    auto source = OpenOpenNiDevice(o);
    RgbdFrame f;
    for (int k = 0; k <= settle; ++k) {
      const SourceStatus s = source->Next(&f, 3.0);
      if (s != SourceStatus::kFrame)
        throw InputError(source->Describe() + ": no frame at exposure " + std::to_string(e) + " (" + ToString(s) + ")");
    }
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace lp
