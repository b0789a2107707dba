// OpenNI2 wrapper: recording and .oni playback (the only file that includes OpenNI.h).
#include "capture/openni.h"

#include <OpenNI.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "capture/usb_devices.h"
#include "common/error.h"

namespace lp {
namespace fs = std::filesystem;

namespace {

/// OpenNI2 is initialized once per process and never shut down (shutting down and
/// initializing again is not reliable in 2.2).
void InitOpenNi() {
  static std::once_flag once;
  static openni::Status status = openni::STATUS_OK;
  static std::string error;
  std::call_once(once, [] {
    status = openni::OpenNI::initialize();
    if (status != openni::STATUS_OK) error = openni::OpenNI::getExtendedError();
  });
  if (status != openni::STATUS_OK) throw InputError("OpenNI2 failed to initialize: " + error);
}

std::string OpenNiError() {
  std::string e = openni::OpenNI::getExtendedError();
  while (!e.empty() && (e.back() == '\n' || e.back() == ' ')) e.pop_back();
  for (char& c : e)
    if (c == '\n' || c == '\t') c = ' ';
  const auto first = e.find_first_not_of(' ');
  return first == std::string::npos ? std::string() : e.substr(first);
}

/// Stops the streams and gives the frames in flight time to land: drivers like
/// DummyDevice crash if their streams are destroyed right after stopping.
void StopStreams(openni::VideoStream& depth, openni::VideoStream& color) {
  if (depth.isValid()) depth.stop();
  if (color.isValid()) color.stop();
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
}

/// Stops (if not yet) and destroys the streams.
void ReleaseStreams(openni::VideoStream& depth, openni::VideoStream& color) {
  StopStreams(depth, color);
  depth.destroy();
  color.destroy();
}

/// OpenNI2's Recorder deadlocks when it is stopped while a frame arrives (the recorder's
/// lock and the stream's are taken in opposite orders): stop the streams first, then
/// stop and destroy the recorder, then the streams.
void FinishRecording(openni::Recorder& recorder, openni::VideoStream& depth, openni::VideoStream& color) {
  StopStreams(depth, color);
  if (recorder.isValid()) {
    recorder.stop();
    recorder.destroy();
  }
  depth.destroy();
  color.destroy();
}

void OpenDevice(openni::Device* device, const std::string& uri) {
  const bool any = uri.empty();
  if (device->open(any ? openni::ANY_DEVICE : uri.c_str()) == openni::STATUS_OK) return;
  const std::string why = OpenNiError();
  if (any || uri.rfind("lpsynth://", 0) != 0)
    throw InputError("no OpenNI2 device opened (" + why + "): " + ExplainNoDevice(ScanUsbCameras()));
  throw InputError(uri, "the synthetic OpenNI2 device did not open (" + why + "); driver folder: " +
                            (OpenNiDriverFolder().empty() ? "none" : OpenNiDriverFolder()));
}

std::uint32_t U32(const unsigned char* p) { return p[0] | p[1] << 8 | p[2] << 16 | std::uint32_t(p[3]) << 24; }

}  // namespace

std::string OpenNiDriverFolder() {
#ifdef LIGHTPROBE_OPENNI2_RUNTIME
  return std::string(LIGHTPROBE_OPENNI2_RUNTIME) + "/OpenNI2/Drivers";
#else
  return {};
#endif
}

void ValidateOniFile(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path, "file not found");
  const std::uint64_t size = fs::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot read");
  constexpr std::size_t kFileHeader = 24, kRecordHeader = 28;
  constexpr std::uint32_t kRecordMagic = 0x0052494E;  // "NIR\0"
  unsigned char h[kRecordHeader];
  if (size < kFileHeader || !in.read(reinterpret_cast<char*>(h), kFileHeader))
    throw InputError(path, "empty or truncated .oni file (no header)");
  if (std::memcmp(h, "NI10", 4) != 0) throw InputError(path, "not an .oni recording (bad magic)");
  std::uint64_t pos = kFileHeader;
  int records = 0, frames = 0;
  bool end = false;
  while (!end) {
    if (pos + kRecordHeader > size)
      throw InputError(path, "truncated .oni file: record " + std::to_string(records) + " runs past the end");
    in.seekg(static_cast<std::streamoff>(pos));
    if (!in.read(reinterpret_cast<char*>(h), kRecordHeader)) throw InputError(path, "cannot read record header");
    const std::uint32_t magic = U32(h), type = U32(h + 4), fields = U32(h + 8 + 4), payload = U32(h + 16);
    if (magic != kRecordMagic)
      throw InputError(path, "corrupt .oni file: bad record magic at byte " + std::to_string(pos));
    if (type < 0x02 || type > 0x0E || fields < kRecordHeader)
      throw InputError(path, "corrupt .oni file: bad record header at byte " + std::to_string(pos));
    const std::uint64_t next = pos + fields + static_cast<std::uint64_t>(payload);
    if (next > size)
      throw InputError(path, "truncated .oni file: record at byte " + std::to_string(pos) + " runs past the end");
    frames += type == 0x0A;
    end = type == 0x0B;
    pos = next;
    ++records;
  }
  if (frames == 0) throw InputError(path, ".oni file has no frames");
}

RecordResult RecordOni(const std::string& out_file, const RecordOptions& o) {
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
  if (device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR))
    device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
  device.setDepthColorSyncEnabled(true);
  const fs::path out(out_file), tmp = out.parent_path() / ("." + out.filename().string() + ".recording.oni");
  std::error_code ec;
  if (!out.parent_path().empty()) fs::create_directories(out.parent_path(), ec);
  openni::Recorder recorder;
  RecordResult result;
  try {
    if (recorder.create(tmp.c_str()) != openni::STATUS_OK) throw InputError(out_file, "cannot create: " + OpenNiError());
    if (recorder.attach(depth, false) != openni::STATUS_OK || recorder.attach(color, o.lossy_color) != openni::STATUS_OK)
      throw InputError(out_file, "cannot attach the streams to the recorder: " + OpenNiError());
    if (depth.start() != openni::STATUS_OK || color.start() != openni::STATUS_OK)
      throw InputError(o.uri, "cannot start the streams: " + OpenNiError());
    // OpenNI2's recordings keep each stream's timestamps relative to its own first recorded
    // frame, so both streams must start recording with the same frame or replay pairs them
    // one frame apart: start the recorder just after a depth and a colour frame with the same
    // timestamp arrived (the next pair is a frame period away).
    openni::VideoStream* streams[2] = {&depth, &color};
    openni::VideoFrameRef frame;
    {
      std::uint64_t last[2] = {~0ull, ~1ull};
      for (int k = 0; k < 60 && last[0] != last[1]; ++k) {
        int ready = -1;
        if (openni::OpenNI::waitForAnyStream(streams, 2, &ready, 2000) != openni::STATUS_OK)
          throw InputError(o.uri, "the device delivers no frames: " + OpenNiError());
        if (streams[ready]->readFrame(&frame) == openni::STATUS_OK) last[ready] = frame.getTimestamp();
      }
    }
    if (recorder.start() != openni::STATUS_OK) throw InputError(out_file, "cannot start recording: " + OpenNiError());
    const auto t0 = std::chrono::steady_clock::now();
    auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
    while (o.frames > 0 ? result.depth_frames < o.frames : elapsed() < o.seconds) {
      int ready = -1;
      if (openni::OpenNI::waitForAnyStream(streams, 2, &ready, 2000) != openni::STATUS_OK)
        throw InputError(o.uri, "the device stopped delivering frames (unplugged?) after " +
                                    std::to_string(result.depth_frames) + " depth frames");
      if (streams[ready]->readFrame(&frame) != openni::STATUS_OK) continue;
      (ready == 0 ? result.depth_frames : result.color_frames)++;
    }
    result.seconds = elapsed();
    FinishRecording(recorder, depth, color);
  } catch (...) {
    FinishRecording(recorder, depth, color);
    device.close();
    fs::remove(tmp, ec);
    throw;
  }
  device.close();
  fs::rename(tmp, out, ec);
  if (ec) throw InputError(out_file, "cannot move the recording into place: " + ec.message());
  return result;
}

namespace {

/// What both OpenNI2 sources share: a device with a depth and a colour stream, frames
/// paired by timestamp (within half a frame period), copied into owned RgbdFrames.
class OpenNiStreams {
 protected:
  /// Reads one frame of `s`, waiting at most timeout_ms.
  bool Read(openni::VideoStream& s, openni::VideoFrameRef* f, int timeout_ms) {
    openni::VideoStream* p = &s;
    int ready = -1;
    if (openni::OpenNI::waitForAnyStream(&p, 1, &ready, timeout_ms) != openni::STATUS_OK) return false;
    return s.readFrame(f) == openni::STATUS_OK;
  }
  /// Reads a depth and a colour frame taken at the same time: the older one is read again
  /// until their timestamps are within half a frame period (a stream that dropped a frame
  /// skips ahead to its partner). `budget` limits the extra reads (end of a recording).
  bool ReadPair(openni::VideoFrameRef* d, openni::VideoFrameRef* c, int timeout_ms, int* depth_reads,
                int* color_reads, int depth_budget, int color_budget) {
    if (!Read(depth_, d, timeout_ms)) return false;
    ++*depth_reads;
    if (!Read(color_, c, timeout_ms)) return false;
    ++*color_reads;
    const int fps = std::max(1, depth_.getVideoMode().getFps());
    const long long half = 500000 / fps;  // microseconds
    for (int guard = 0; guard < 64; ++guard) {
      const long long dt = static_cast<long long>(c->getTimestamp()) - static_cast<long long>(d->getTimestamp());
      if (dt > half && *depth_reads < depth_budget) {
        if (!Read(depth_, d, timeout_ms)) return false;
        ++*depth_reads;
      } else if (-dt > half && *color_reads < color_budget) {
        if (!Read(color_, c, timeout_ms)) return false;
        ++*color_reads;
      } else {
        break;
      }
    }
    return true;
  }
  RgbdFrame ToFrame(const openni::VideoFrameRef& d, const openni::VideoFrameRef& c, std::int64_t index) {
    RgbdFrame f;
    f.index = index;
    f.depth.width = d.getWidth();
    f.depth.height = d.getHeight();
    f.depth.data.resize(f.depth.pixels());
    const auto* dp = static_cast<const char*>(d.getData());
    for (int y = 0; y < f.depth.height; ++y)
      std::memcpy(&f.depth.data[static_cast<std::size_t>(y) * f.depth.width],
                  dp + static_cast<std::size_t>(y) * d.getStrideInBytes(), sizeof(std::uint16_t) * f.depth.width);
    f.color.width = c.getWidth();
    f.color.height = c.getHeight();
    f.color.data.resize(f.color.pixels() * 3);
    const auto* cp = static_cast<const std::uint8_t*>(c.getData());
    for (int y = 0; y < f.color.height; ++y)
      std::memcpy(&f.color.data[3 * static_cast<std::size_t>(y) * f.color.width],
                  cp + static_cast<std::size_t>(y) * c.getStrideInBytes(), 3 * static_cast<std::size_t>(f.color.width));
    f.depth_timestamp = d.getTimestamp() * 1e-6;
    f.color_timestamp = c.getTimestamp() * 1e-6;
    f.depth_intrinsics = FromFov(depth_, f.depth.width, f.depth.height);
    f.color_intrinsics = FromFov(color_, f.color.width, f.color.height);
    f.registered = device_.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
    return f;
  }
  /// OpenNI2 reports fields of view, not a principal point: centred, square-ish pixels.
  static Intrinsics FromFov(openni::VideoStream& s, int w, int h) {
    Intrinsics k;
    k.width = w;
    k.height = h;
    const double hfov = s.getHorizontalFieldOfView(), vfov = s.getVerticalFieldOfView();
    k.fx = hfov > 0 ? 0.5 * w / std::tan(0.5 * hfov) : 0;
    k.fy = vfov > 0 ? 0.5 * h / std::tan(0.5 * vfov) : k.fx;
    k.cx = 0.5 * w - 0.5;
    k.cy = 0.5 * h - 0.5;
    return k;
  }
  void CloseDevice() {
    ReleaseStreams(depth_, color_);
    device_.close();
  }

  openni::Device device_;
  openni::VideoStream depth_, color_;
};

class OniFileSource : public FrameSource, private OpenNiStreams {
 public:
  OniFileSource(const std::string& path, const OniPlaybackOptions& o) : path_(path), options_(o) {
    ValidateOniFile(path);
    InitOpenNi();
    Open();
  }
  ~OniFileSource() override { CloseDevice(); }

  std::string Describe() const override { return ".oni file " + path_ + ", " + std::to_string(count_) + " frames"; }
  std::optional<std::int64_t> FrameCount() const override { return count_; }

  SourceStatus Next(RgbdFrame* out, double timeout_seconds) override {
    // No end-of-file signal in OpenNI2's playback: stop on the recorded frame counts.
    if (depth_read_ >= depth_count_ || color_read_ >= color_count_) {
      if (!options_.loop) return SourceStatus::kEnd;
      Rewind();
    }
    openni::VideoFrameRef d, c;
    if (!ReadPair(&d, &c, static_cast<int>(timeout_seconds * 1000), &depth_read_, &color_read_, depth_count_,
                  color_count_))
      return SourceStatus::kTimeout;
    *out = ToFrame(d, c, produced_++);
    return SourceStatus::kFrame;
  }

  /// OpenNI2's seek crashes: rewind by reopening the file.
  void Rewind() override {
    CloseDevice();
    Open();
  }

 private:
  void Open() {
    if (device_.open(path_.c_str()) != openni::STATUS_OK)
      throw InputError(path_, "OpenNI2 cannot open it: " + OpenNiError());
    openni::PlaybackControl* pc = device_.getPlaybackControl();
    if (!pc) throw InputError(path_, "not a recording");
    pc->setSpeed(options_.real_time ? 1.0f : -1.0f);  // -1: manual, one frame per read, none lost
    pc->setRepeatEnabled(false);
    if (depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK ||
        color_.create(device_, openni::SENSOR_COLOR) != openni::STATUS_OK)
      throw InputError(path_, "the recording needs a depth and a colour stream");
    depth_count_ = pc->getNumberOfFrames(depth_);
    color_count_ = pc->getNumberOfFrames(color_);
    count_ = std::min(depth_count_, color_count_);
    if (count_ <= 0) throw InputError(path_, "the recording has no frames in one of its streams");
    if (depth_.getVideoMode().getPixelFormat() != openni::PIXEL_FORMAT_DEPTH_1_MM ||
        color_.getVideoMode().getPixelFormat() != openni::PIXEL_FORMAT_RGB888)
      throw InputError(path_, "unsupported pixel format (expected 1 mm depth and RGB888 colour)");
    depth_.start();
    color_.start();
    depth_read_ = color_read_ = 0;
  }

  std::string path_;
  OniPlaybackOptions options_;
  int depth_count_ = 0, color_count_ = 0, depth_read_ = 0, color_read_ = 0;
  std::int64_t count_ = 0, produced_ = 0;
};

/// Sets a stream to the mode with this size and pixel format, at `fps` or the nearest.
void SelectMode(openni::VideoStream& s, int w, int h, int fps, openni::PixelFormat format, const char* what) {
  const openni::Array<openni::VideoMode>& modes = s.getSensorInfo().getSupportedVideoModes();
  int best = -1;
  std::string available;
  for (int i = 0; i < modes.getSize(); ++i) {
    const openni::VideoMode& m = modes[i];
    available += (available.empty() ? "" : ", ") + std::to_string(m.getResolutionX()) + "x" +
                 std::to_string(m.getResolutionY()) + "@" + std::to_string(m.getFps());
    if (m.getResolutionX() != w || m.getResolutionY() != h || m.getPixelFormat() != format) continue;
    if (best < 0 || std::abs(m.getFps() - fps) < std::abs(modes[best].getFps() - fps)) best = i;
  }
  if (best < 0)
    throw InputError(std::string("the ") + what + " stream has no " + std::to_string(w) + "x" + std::to_string(h) +
                     " mode in the needed format (available: " + available + ")");
  if (s.setVideoMode(modes[best]) != openni::STATUS_OK)
    throw InputError(std::string("cannot set the ") + what + " mode: " + OpenNiError());
}

class DeviceSource : public FrameSource, private OpenNiStreams, private openni::OpenNI::DeviceDisconnectedListener {
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
      // Exposure settings made before the streams start are ignored by some devices:
      // apply them now, then read back what the device actually uses.
      if (openni::CameraSettings* cs = color_.getCameraSettings()) {
        if (o.lock_exposure) {
          cs->setAutoExposureEnabled(false);
          cs->setAutoWhiteBalanceEnabled(false);
        }
        if (o.exposure >= 0) cs->setExposure(o.exposure);
        if (o.gain >= 0) cs->setGain(o.gain);
        controls_.auto_exposure = cs->getAutoExposureEnabled();
        controls_.auto_white_balance = cs->getAutoWhiteBalanceEnabled();
        controls_.exposure = cs->getExposure();
        controls_.gain = cs->getGain();
        controls_.camera_settings = true;
      }
      controls_.registered = device_.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
      if (o.lock_exposure && controls_.camera_settings && (controls_.auto_exposure || controls_.auto_white_balance))
        throw InputError(uri_, "the camera did not lock its exposure / white balance (read back still automatic)");
      if (o.exposure >= 0 && controls_.camera_settings && controls_.exposure != o.exposure)
        throw InputError(uri_, "the camera ignored exposure " + std::to_string(o.exposure) + " (reads back " +
                                   std::to_string(controls_.exposure) + ")");
    } catch (...) {
      openni::OpenNI::removeDeviceDisconnectedListener(this);
      CloseDevice();
      throw;
    }
    if (applied) *applied = controls_;
  }
  ~DeviceSource() override {
    openni::OpenNI::removeDeviceDisconnectedListener(this);
    CloseDevice();
  }

  std::string Describe() const override { return "OpenNI2 device " + uri_; }

  SourceStatus Next(RgbdFrame* out, double timeout_seconds) override {
    if (lost_) return SourceStatus::kDeviceLost;
    openni::VideoFrameRef d, c;
    int dr = 0, cr = 0;
    if (!ReadPair(&d, &c, static_cast<int>(timeout_seconds * 1000), &dr, &cr, 1 << 30, 1 << 30))
      return lost_ ? SourceStatus::kDeviceLost : SourceStatus::kTimeout;
    *out = ToFrame(d, c, produced_++);
    return SourceStatus::kFrame;
  }
  void Rewind() override { throw InputError(uri_, "a live device cannot rewind"); }

 private:
  void onDeviceDisconnected(const openni::DeviceInfo* info) override {
    if (info && uri_ == info->getUri()) lost_ = true;
  }

  OpenNiDeviceOptions options_;
  std::string uri_;
  CameraControls controls_;
  std::atomic<bool> lost_{false};
  std::int64_t produced_ = 0;
};

}  // namespace

std::unique_ptr<FrameSource> OpenOniFile(const std::string& path, const OniPlaybackOptions& options) {
  return std::make_unique<OniFileSource>(path, options);
}

std::unique_ptr<FrameSource> OpenOpenNiDevice(const OpenNiDeviceOptions& options, CameraControls* applied) {
  return std::make_unique<DeviceSource>(options, applied);
}

}  // namespace lp
