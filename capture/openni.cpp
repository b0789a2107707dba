// OpenNI2 wrapper: recording and .oni playback (the only file that includes OpenNI.h).
#include "capture/openni.h"

#include <OpenNI.h>

#include <chrono>
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

/// Stops and destroys streams with the pause DummyDevice-like drivers need before
/// destruction (they crash otherwise).
void StopStreams(openni::VideoStream& depth, openni::VideoStream& color) {
  if (depth.isValid()) depth.stop();
  if (color.isValid()) color.stop();
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
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
    if (recorder.start() != openni::STATUS_OK) throw InputError(out_file, "cannot start recording: " + OpenNiError());
    const auto t0 = std::chrono::steady_clock::now();
    openni::VideoStream* streams[2] = {&depth, &color};
    openni::VideoFrameRef frame;
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
    recorder.stop();
    recorder.destroy();
  } catch (...) {
    recorder.destroy();
    StopStreams(depth, color);
    device.close();
    fs::remove(tmp, ec);
    throw;
  }
  StopStreams(depth, color);
  device.close();
  fs::rename(tmp, out, ec);
  if (ec) throw InputError(out_file, "cannot move the recording into place: " + ec.message());
  return result;
}

namespace {

class OniFileSource : public FrameSource {
 public:
  OniFileSource(const std::string& path, const OniPlaybackOptions& o) : path_(path), options_(o) {
    ValidateOniFile(path);
    InitOpenNi();
    Open();
  }
  ~OniFileSource() override { Close(); }

  std::string Describe() const override {
    return ".oni file " + path_ + ", " + std::to_string(count_) + " frames";
  }
  std::optional<std::int64_t> FrameCount() const override { return count_; }

  SourceStatus Next(RgbdFrame* out, double timeout_seconds) override {
    // No end-of-file signal in OpenNI2's playback: stop on the recorded frame counts.
    if (depth_read_ >= depth_count_ || color_read_ >= color_count_) {
      if (!options_.loop) return SourceStatus::kEnd;
      Rewind();
    }
    const int timeout_ms = static_cast<int>(timeout_seconds * 1000);
    openni::VideoFrameRef d, c;
    if (!Read(depth_, &d, timeout_ms, &depth_read_) || !Read(color_, &c, timeout_ms, &color_read_))
      return SourceStatus::kTimeout;
    // Pair by frame index: a stream that dropped frames skips ahead to its partner.
    while (d.getFrameIndex() < c.getFrameIndex() && depth_read_ < depth_count_)
      if (!Read(depth_, &d, timeout_ms, &depth_read_)) return SourceStatus::kTimeout;
    while (c.getFrameIndex() < d.getFrameIndex() && color_read_ < color_count_)
      if (!Read(color_, &c, timeout_ms, &color_read_)) return SourceStatus::kTimeout;
    RgbdFrame f;
    f.index = produced_++;
    f.depth.width = d.getWidth();
    f.depth.height = d.getHeight();
    f.depth.data.resize(f.depth.pixels());
    const auto* dp = static_cast<const std::uint16_t*>(d.getData());
    for (int y = 0; y < f.depth.height; ++y)
      std::memcpy(&f.depth.data[static_cast<std::size_t>(y) * f.depth.width],
                  reinterpret_cast<const char*>(dp) + static_cast<std::size_t>(y) * d.getStrideInBytes(),
                  sizeof(std::uint16_t) * f.depth.width);
    f.color.width = c.getWidth();
    f.color.height = c.getHeight();
    f.color.data.resize(f.color.pixels() * 3);
    const auto* cp = static_cast<const std::uint8_t*>(c.getData());
    for (int y = 0; y < f.color.height; ++y)
      std::memcpy(&f.color.data[3 * static_cast<std::size_t>(y) * f.color.width],
                  cp + static_cast<std::size_t>(y) * c.getStrideInBytes(), 3 * static_cast<std::size_t>(f.color.width));
    f.depth_timestamp = d.getTimestamp() * 1e-6;
    f.color_timestamp = c.getTimestamp() * 1e-6;
    f.depth_intrinsics = Intrinsics_(depth_, f.depth.width, f.depth.height);
    f.color_intrinsics = Intrinsics_(color_, f.color.width, f.color.height);
    f.registered = device_.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
    *out = std::move(f);
    return SourceStatus::kFrame;
  }

  /// OpenNI2's seek crashes: rewind by reopening the file.
  void Rewind() override {
    Close();
    Open();
  }

 private:
  void Open() {
    if (device_.open(path_.c_str()) != openni::STATUS_OK) throw InputError(path_, "OpenNI2 cannot open it: " + OpenNiError());
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
  void Close() {
    StopStreams(depth_, color_);
    device_.close();
  }
  bool Read(openni::VideoStream& s, openni::VideoFrameRef* f, int timeout_ms, int* counter) {
    openni::VideoStream* p = &s;
    int ready = -1;
    if (openni::OpenNI::waitForAnyStream(&p, 1, &ready, timeout_ms) != openni::STATUS_OK) return false;
    if (s.readFrame(f) != openni::STATUS_OK) return false;
    ++*counter;
    return true;
  }
  static Intrinsics Intrinsics_(openni::VideoStream& s, int w, int h) {
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

  std::string path_;
  OniPlaybackOptions options_;
  openni::Device device_;
  openni::VideoStream depth_, color_;
  int depth_count_ = 0, color_count_ = 0, depth_read_ = 0, color_read_ = 0;
  std::int64_t count_ = 0, produced_ = 0;
};

}  // namespace

std::unique_ptr<FrameSource> OpenOniFile(const std::string& path, const OniPlaybackOptions& options) {
  return std::make_unique<OniFileSource>(path, options);
}

}  // namespace lp
