// An OpenNI2 driver of the project's own: it serves the frames of an RGB-D frame directory
// (any layout capture/ reads) as a device with a depth and a colour stream, so recording,
// playback and the live code path run through the real OpenNI2 stack without a camera.
//
// URI: lpsynth://<directory>[?fps=N][&unplug_after=N]. unplug_after simulates pulling the
// cable: after N frames the device reports itself disconnected and delivers nothing more.
// Both streams expose the cropping property (OpenNI2's playback drops every frame of a
// stream recorded without it) and the colour stream the exposure controls a real Xtion has.
#define XN_NEW(type, ...) new type(__VA_ARGS__)
#define XN_DELETE(p) delete (p)
#include <Driver/OniDriverAPI.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "capture/frame_source.h"
#include "common/color.h"

namespace {

constexpr char kScheme[] = "lpsynth://";

struct UriOptions {
  std::string dir;
  int fps = 30;
  long unplug_after = -1;
};

bool ParseUri(const char* uri, UriOptions* o) {
  if (!uri || std::strncmp(uri, kScheme, sizeof kScheme - 1) != 0) return false;
  std::string rest(uri + sizeof kScheme - 1);
  const auto q = rest.find('?');
  o->dir = rest.substr(0, q);
  if (q != std::string::npos) {
    std::string query = rest.substr(q + 1);
    std::size_t start = 0;
    while (start <= query.size()) {
      const auto end = std::min(query.find('&', start), query.size());
      const std::string kv = query.substr(start, end - start);
      const auto eq = kv.find('=');
      if (eq != std::string::npos) {
        const std::string k = kv.substr(0, eq), v = kv.substr(eq + 1);
        if (k == "fps") o->fps = std::max(1, std::atoi(v.c_str()));
        if (k == "unplug_after") o->unplug_after = std::atol(v.c_str());
      }
      start = end + 1;
    }
  }
  return !o->dir.empty();
}

template <typename T>
OniStatus Put(const T& value, void* data, int* size) {
  if (*size < static_cast<int>(sizeof(T))) return ONI_STATUS_BAD_PARAMETER;
  std::memcpy(data, &value, sizeof(T));
  *size = sizeof(T);
  return ONI_STATUS_OK;
}

template <typename T>
bool Get(const void* data, int size, T* value) {
  if (size != static_cast<int>(sizeof(T))) return false;
  std::memcpy(value, data, sizeof(T));
  return true;
}

class SynthStream : public oni::driver::StreamBase {
 public:
  SynthStream(OniSensorType type, const OniVideoMode& mode, const lp::Camera& k)
      : type_(type), mode_(mode), k_(k) {
    cropping_.enabled = 0;
    cropping_.originX = cropping_.originY = 0;
    cropping_.width = mode.resolutionX;
    cropping_.height = mode.resolutionY;
  }

  OniStatus start() override {
    running_ = true;
    return ONI_STATUS_OK;
  }
  void stop() override { running_ = false; }
  OniSensorType type() const { return type_; }

  OniBool isPropertySupported(int id) override {
    switch (id) {
      case ONI_STREAM_PROPERTY_CROPPING:
      case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
      case ONI_STREAM_PROPERTY_VERTICAL_FOV:
      case ONI_STREAM_PROPERTY_VIDEO_MODE:
      case ONI_STREAM_PROPERTY_STRIDE:
      case ONI_STREAM_PROPERTY_MIRRORING:
        return TRUE;
      case ONI_STREAM_PROPERTY_MAX_VALUE:
      case ONI_STREAM_PROPERTY_MIN_VALUE:
        return type_ == ONI_SENSOR_DEPTH;
      case ONI_STREAM_PROPERTY_AUTO_WHITE_BALANCE:
      case ONI_STREAM_PROPERTY_AUTO_EXPOSURE:
      case ONI_STREAM_PROPERTY_EXPOSURE:
      case ONI_STREAM_PROPERTY_GAIN:
        return type_ == ONI_SENSOR_COLOR;
      default:
        return FALSE;
    }
  }

  OniStatus getProperty(int id, void* data, int* size) override {
    if (!isPropertySupported(id)) return ONI_STATUS_NOT_SUPPORTED;
    std::lock_guard<std::mutex> lock(mutex_);
    switch (id) {
      case ONI_STREAM_PROPERTY_CROPPING: return Put(cropping_, data, size);
      case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
        return Put(static_cast<float>(2 * std::atan(0.5 * mode_.resolutionX / k_.fx)), data, size);
      case ONI_STREAM_PROPERTY_VERTICAL_FOV:
        return Put(static_cast<float>(2 * std::atan(0.5 * mode_.resolutionY / k_.fy)), data, size);
      case ONI_STREAM_PROPERTY_VIDEO_MODE: return Put(mode_, data, size);
      case ONI_STREAM_PROPERTY_STRIDE: return Put(mode_.resolutionX * BytesPerPixel(), data, size);
      case ONI_STREAM_PROPERTY_MIRRORING: return Put(OniBool(FALSE), data, size);
      case ONI_STREAM_PROPERTY_MAX_VALUE: return Put(10000, data, size);
      case ONI_STREAM_PROPERTY_MIN_VALUE: return Put(0, data, size);
      case ONI_STREAM_PROPERTY_AUTO_WHITE_BALANCE: return Put(auto_wb_, data, size);
      case ONI_STREAM_PROPERTY_AUTO_EXPOSURE: return Put(auto_exposure_, data, size);
      case ONI_STREAM_PROPERTY_EXPOSURE: return Put(exposure_, data, size);
      case ONI_STREAM_PROPERTY_GAIN: return Put(gain_, data, size);
    }
    return ONI_STATUS_NOT_SUPPORTED;
  }

  OniStatus setProperty(int id, const void* data, int size) override {
    std::lock_guard<std::mutex> lock(mutex_);
    switch (id) {
      case ONI_STREAM_PROPERTY_VIDEO_MODE: {  // the frames have one size: only it is accepted
        OniVideoMode m;
        if (!Get(data, size, &m)) return ONI_STATUS_BAD_PARAMETER;
        return m.resolutionX == mode_.resolutionX && m.resolutionY == mode_.resolutionY &&
                       m.pixelFormat == mode_.pixelFormat
                   ? ONI_STATUS_OK
                   : ONI_STATUS_NOT_SUPPORTED;
      }
      case ONI_STREAM_PROPERTY_CROPPING: {  // only "no cropping" (the whole frame)
        OniCropping c;
        if (!Get(data, size, &c)) return ONI_STATUS_BAD_PARAMETER;
        if (c.enabled) return ONI_STATUS_NOT_SUPPORTED;
        cropping_.enabled = 0;
        return ONI_STATUS_OK;
      }
      case ONI_STREAM_PROPERTY_MIRRORING: {
        OniBool m;
        if (!Get(data, size, &m)) return ONI_STATUS_BAD_PARAMETER;
        return m ? ONI_STATUS_NOT_SUPPORTED : ONI_STATUS_OK;
      }
      case ONI_STREAM_PROPERTY_AUTO_WHITE_BALANCE:
        if (type_ != ONI_SENSOR_COLOR || !Get(data, size, &auto_wb_)) return ONI_STATUS_BAD_PARAMETER;
        return ONI_STATUS_OK;
      case ONI_STREAM_PROPERTY_AUTO_EXPOSURE:
        if (type_ != ONI_SENSOR_COLOR || !Get(data, size, &auto_exposure_)) return ONI_STATUS_BAD_PARAMETER;
        return ONI_STATUS_OK;
      case ONI_STREAM_PROPERTY_EXPOSURE:
        if (type_ != ONI_SENSOR_COLOR || !Get(data, size, &exposure_)) return ONI_STATUS_BAD_PARAMETER;
        return ONI_STATUS_OK;
      case ONI_STREAM_PROPERTY_GAIN:
        if (type_ != ONI_SENSOR_COLOR || !Get(data, size, &gain_)) return ONI_STATUS_BAD_PARAMETER;
        return ONI_STATUS_OK;
    }
    return ONI_STATUS_NOT_SUPPORTED;
  }

  /// Called by the device's producer thread; never blocks on the consumer.
  void Deliver(const lp::RgbdFrame& f, int index, std::uint64_t timestamp_us) {
    if (!running_) return;
    OniFrame* frame = getServices().acquireFrame();
    if (!frame) return;
    const int w = mode_.resolutionX, h = mode_.resolutionY;
    const std::size_t bytes = static_cast<std::size_t>(w) * h * BytesPerPixel();
    if (frame->dataSize < static_cast<int>(bytes)) {
      getServices().releaseFrame(frame);
      return;
    }
    if (type_ == ONI_SENSOR_DEPTH) {
      std::memcpy(frame->data, f.depth.data.data(), bytes);
    } else if (auto_exposure_ || (exposure_ == 100 && gain_ == 100)) {
      std::memcpy(frame->data, f.color.data.data(), bytes);
    } else {
      // A manual exposure acts like a camera's: the served images are taken at exposure x
      // gain = 100 x 100; others scale the light (linear, sRGB-encoded, clipped at 1).
      const float scale = exposure_ / 100.f * gain_ / 100.f;
      std::uint8_t table[256];
      for (int v = 0; v < 256; ++v)
        table[v] = static_cast<std::uint8_t>(
            std::lround(255 * lp::LinearToSrgb(std::min(1.f, lp::SrgbToLinear(v / 255.f) * scale))));
      auto* out = static_cast<std::uint8_t*>(frame->data);
      for (std::size_t i = 0; i < bytes; ++i) out[i] = table[f.color.data[i]];
    }
    frame->dataSize = static_cast<int>(bytes);
    frame->sensorType = type_;
    frame->timestamp = timestamp_us;
    frame->frameIndex = index;
    frame->width = w;
    frame->height = h;
    frame->videoMode = mode_;
    frame->croppingEnabled = FALSE;
    frame->cropOriginX = frame->cropOriginY = 0;
    frame->stride = w * BytesPerPixel();
    raiseNewFrame(frame);
    getServices().releaseFrame(frame);
  }

 private:
  int BytesPerPixel() const { return type_ == ONI_SENSOR_DEPTH ? 2 : 3; }

  const OniSensorType type_;
  const OniVideoMode mode_;
  const lp::Camera k_;
  std::atomic<bool> running_{false};
  std::mutex mutex_;
  OniCropping cropping_{};
  OniBool auto_wb_ = TRUE, auto_exposure_ = TRUE;
  int exposure_ = 100, gain_ = 100;
};

class SynthDriver;

class SynthDevice : public oni::driver::DeviceBase {
 public:
  SynthDevice(const UriOptions& o, const OniDeviceInfo& info, SynthDriver* driver);
  ~SynthDevice() override {
    stop_ = true;
    if (producer_.joinable()) producer_.join();
  }

  OniStatus getSensorInfoList(OniSensorInfo** infos, int* count) override {
    *infos = sensors_;
    *count = 2;
    return ONI_STATUS_OK;
  }

  oni::driver::StreamBase* createStream(OniSensorType type) override {
    if (type != ONI_SENSOR_DEPTH && type != ONI_SENSOR_COLOR) return nullptr;
    auto* s = new SynthStream(type, type == ONI_SENSOR_DEPTH ? depth_mode_ : color_mode_, k_);
    std::lock_guard<std::mutex> lock(mutex_);
    streams_.push_back(s);
    if (!producer_.joinable()) producer_ = std::thread([this] { Produce(); });
    return s;
  }

  void destroyStream(oni::driver::StreamBase* stream) override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (auto it = streams_.begin(); it != streams_.end(); ++it)
        if (*it == stream) {
          streams_.erase(it);
          break;
        }
    }
    delete stream;
  }

  OniBool isImageRegistrationModeSupported(OniImageRegistrationMode mode) override {
    return mode == ONI_IMAGE_REGISTRATION_OFF || mode == ONI_IMAGE_REGISTRATION_DEPTH_TO_COLOR;
  }
  OniBool isPropertySupported(int id) override { return id == ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION; }
  OniStatus getProperty(int id, void* data, int* size) override {
    if (id != ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION) return ONI_STATUS_NOT_SUPPORTED;
    return Put(registration_, data, size);
  }
  OniStatus setProperty(int id, const void* data, int size) override {
    if (id != ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION) return ONI_STATUS_NOT_SUPPORTED;
    OniImageRegistrationMode m;
    if (!Get(data, size, &m) || !isImageRegistrationModeSupported(m)) return ONI_STATUS_NOT_SUPPORTED;
    registration_ = m;  // the frames are registered already: nothing to do either way
    return ONI_STATUS_OK;
  }

 private:
  void Produce();

  UriOptions options_;
  OniDeviceInfo info_;
  SynthDriver* driver_;
  std::unique_ptr<lp::FrameSource> source_;
  lp::RgbdFrame first_;
  lp::Camera k_;
  OniVideoMode depth_mode_{}, color_mode_{};
  OniSensorInfo sensors_[2]{};
  OniImageRegistrationMode registration_ = ONI_IMAGE_REGISTRATION_OFF;
  std::mutex mutex_;
  std::vector<SynthStream*> streams_;
  std::thread producer_;
  std::atomic<bool> stop_{false};
};

class SynthDriver : public oni::driver::DriverBase {
 public:
  explicit SynthDriver(OniDriverServices* services) : DriverBase(services) {}

  OniStatus tryDevice(const char* uri) override {
    UriOptions o;
    if (!ParseUri(uri, &o)) return ONI_STATUS_ERROR;
    OniDeviceInfo info{};
    std::strncpy(info.uri, uri, ONI_MAX_STR - 1);
    std::strncpy(info.vendor, "lightprobe", ONI_MAX_STR - 1);
    std::strncpy(info.name, "synthetic RGB-D", ONI_MAX_STR - 1);
    deviceConnected(&info);
    return ONI_STATUS_OK;
  }

  oni::driver::DeviceBase* deviceOpen(const char* uri, const char*) override {
    UriOptions o;
    if (!ParseUri(uri, &o)) return nullptr;
    OniDeviceInfo info{};
    std::strncpy(info.uri, uri, ONI_MAX_STR - 1);
    try {
      return new SynthDevice(o, info, this);
    } catch (const std::exception& e) {
      getServices().errorLoggerAppend("lpsynth: %s", e.what());
      return nullptr;
    }
  }
  void deviceClose(oni::driver::DeviceBase* device) override { delete device; }
  void shutdown() override {}
  void Unplugged(const OniDeviceInfo& info) { deviceDisconnected(&info); }
};

SynthDevice::SynthDevice(const UriOptions& o, const OniDeviceInfo& info, SynthDriver* driver)
    : options_(o), info_(info), driver_(driver) {
  lp::DirectorySourceOptions so;
  so.loop = true;
  source_ = lp::OpenDirectorySource(o.dir, so);
  if (source_->Next(&first_) != lp::SourceStatus::kFrame) throw std::runtime_error("no frames in " + o.dir);
  source_->Rewind();
  k_ = first_.color_intrinsics;
  depth_mode_ = {ONI_PIXEL_FORMAT_DEPTH_1_MM, first_.depth.width, first_.depth.height, o.fps};
  color_mode_ = {ONI_PIXEL_FORMAT_RGB888, first_.color.width, first_.color.height, o.fps};
  sensors_[0] = {ONI_SENSOR_DEPTH, 1, &depth_mode_};
  sensors_[1] = {ONI_SENSOR_COLOR, 1, &color_mode_};
}

void SynthDevice::Produce() {
  const auto period = std::chrono::microseconds(1000000 / options_.fps);
  auto next = std::chrono::steady_clock::now();
  for (long i = 0; !stop_; ++i) {
    if (options_.unplug_after >= 0 && i >= options_.unplug_after) {
      driver_->Unplugged(info_);
      return;
    }
    lp::RgbdFrame f;
    try {
      if (source_->Next(&f) != lp::SourceStatus::kFrame) return;
    } catch (const std::exception&) {
      return;  // a frame file went missing: stop serving (the consumer times out)
    }
    const std::uint64_t ts = static_cast<std::uint64_t>(i) * 1000000ull / options_.fps;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (SynthStream* s : streams_) s->Deliver(f, static_cast<int>(i + 1), ts);
    }
    next += period;
    std::this_thread::sleep_until(next);
  }
}

}  // namespace

ONI_EXPORT_DRIVER(SynthDriver);
