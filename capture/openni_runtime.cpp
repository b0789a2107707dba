// The OpenNI2 runtime the OpenNI2 sources and recordings share (openni_runtime.h): the
// thread pool every OpenNI2 call runs on, initialization, errors, device and stream
// helpers, and the streams both sources read.
#include "capture/openni_runtime.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include <PS1080.h>

#include "capture/usb_devices.h"
#include "common/error.h"

namespace lp {

std::string OpenNiDriverFolder() {
#ifdef LIGHTPROBE_OPENNI2_RUNTIME
  return std::string(LIGHTPROBE_OPENNI2_RUNTIME) + "/OpenNI2/Drivers";
#else
  return {};
#endif
}

namespace openni_detail {

OpenNiThreads& OpenNiThreads::Get() {
  static OpenNiThreads* pool = new OpenNiThreads;
  return *pool;
}

thread_local bool OpenNiThreads::on_pool_thread_ = false;

void OpenNiThreads::Loop() {
  on_pool_thread_ = true;
  std::unique_lock<std::mutex> lock(m_);
  for (;;) {
    ++idle_;
    cv_.wait(lock, [this] { return !jobs_.empty(); });
    --idle_;
    std::function<void()> job = std::move(jobs_.front());
    jobs_.pop_front();
    lock.unlock();
    job();
    lock.lock();
  }
}

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

void StopStreams(openni::VideoStream& depth, openni::VideoStream& color) {
  if (depth.isValid()) depth.stop();
  if (color.isValid()) color.stop();
  std::this_thread::sleep_for(std::chrono::milliseconds(150));  // frames in flight land first
}

void ReleaseStreams(openni::VideoStream& depth, openni::VideoStream& color) {
  StopStreams(depth, color);
  depth.destroy();
  color.destroy();
}

void StopRecorder(openni::Recorder& recorder, openni::VideoStream& depth, openni::VideoStream& color) {
  StopStreams(depth, color);
  if (recorder.isValid()) {
    recorder.stop();
    recorder.destroy();
  }
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

CameraControls ApplyCameraControls(openni::Device& device, openni::VideoStream& color, bool lock, int exposure,
                                   int gain, const std::string& uri) {
  CameraControls c;
  if (openni::CameraSettings* cs = color.getCameraSettings()) {
    if (lock) {
      cs->setAutoExposureEnabled(false);
      cs->setAutoWhiteBalanceEnabled(false);
    }
    if (exposure >= 0) cs->setExposure(exposure);
    if (gain >= 0) cs->setGain(gain);
    c.auto_exposure = cs->getAutoExposureEnabled();
    c.auto_white_balance = cs->getAutoWhiteBalanceEnabled();
    c.exposure = cs->getExposure();
    c.gain = cs->getGain();
    c.camera_settings = true;
  }
  c.registered = device.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
  if (lock && c.camera_settings && (c.auto_exposure || c.auto_white_balance))
    throw InputError(uri, "the camera did not lock its exposure / white balance (read back still automatic)");
  if (exposure >= 0 && c.camera_settings && c.exposure != exposure)
    throw InputError(uri, "the camera ignored exposure " + std::to_string(exposure) + " (reads back " +
                              std::to_string(c.exposure) + ")");
  if (gain >= 0 && c.camera_settings && c.gain != gain)
    throw InputError(uri, "the camera ignored gain " + std::to_string(gain) + " (reads back " +
                              std::to_string(c.gain) + ")");
  return c;
}

bool OpenNiStreams::Read(openni::VideoStream& s, openni::VideoFrameRef* f, int timeout_ms) {
  openni::VideoStream* p = &s;
  int ready = -1;
  if (openni::OpenNI::waitForAnyStream(&p, 1, &ready, timeout_ms) != openni::STATUS_OK) return false;
  return s.readFrame(f) == openni::STATUS_OK;
}

bool OpenNiStreams::ReadPair(openni::VideoFrameRef* d, openni::VideoFrameRef* c, int timeout_ms, int* depth_reads,
                             int* color_reads, int depth_budget, int color_budget) {
  // A read counts the frames up to the one read: in real-time playback OpenNI2 skips the
  // frames a slow reader missed, and its frame index (1-based in a recording) says where
  // it is, so the end of a file is still found.
  auto count = [](int* reads, const openni::VideoFrameRef& f) { *reads = std::max(*reads + 1, f.getFrameIndex()); };
  if (!Read(depth_, d, timeout_ms)) return false;
  count(depth_reads, *d);
  if (!Read(color_, c, timeout_ms)) return false;
  count(color_reads, *c);
  const int fps = std::max(1, depth_.getVideoMode().getFps());
  const long long half = 500000 / fps;  // microseconds
  for (int guard = 0; guard < 64; ++guard) {
    const long long dt = static_cast<long long>(c->getTimestamp()) - static_cast<long long>(d->getTimestamp());
    if (dt > half && *depth_reads < depth_budget) {
      if (!Read(depth_, d, timeout_ms)) return false;
      count(depth_reads, *d);
    } else if (-dt > half && *color_reads < color_budget) {
      if (!Read(color_, c, timeout_ms)) return false;
      count(color_reads, *c);
    } else {
      break;
    }
  }
  return true;
}

RgbdFrame OpenNiStreams::ToFrame(const openni::VideoFrameRef& d, const openni::VideoFrameRef& c, std::int64_t index) {
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
  f.depth_intrinsics = DepthIntrinsics(f.depth.width, f.depth.height);
  f.color_intrinsics = ColorIntrinsics(f.color.width, f.color.height);
  f.registered = device_.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
  if (!f.registered) f.device_extrinsics = DeviceExtrinsics();
  return f;
}

namespace {

/// A centred pinhole camera of w x h with horizontal / vertical fields of view (radians;
/// a vertical one of 0 means square pixels).
Camera FromFov(double hfov, double vfov, int w, int h) {
  Camera k;
  k.width = w;
  k.height = h;
  k.fx = 0.5 * w / std::tan(0.5 * hfov);
  k.fy = vfov > 0 ? 0.5 * h / std::tan(0.5 * vfov) : k.fx;
  k.cx = 0.5 * w - 0.5;
  k.cy = 0.5 * h - 0.5;
  return k;
}

/// The stream's own fields of view, when it reports them (0 otherwise: OpenNI2's getters
/// ignore a failed read).
std::pair<double, double> StreamFov(openni::VideoStream& s) {
  if (!s.isValid()) return {0, 0};
  const double h = s.getHorizontalFieldOfView(), v = s.getVerticalFieldOfView();
  return {std::isfinite(h) && h > 0 && h < 3.1 ? h : 0, std::isfinite(v) && v > 0 && v < 3.1 ? v : 0};
}

/// The horizontal field of view that a PS1080 depth stream's zero-plane distance (mm) and
/// pixel size (mm, at SXGA, 1280 px wide) give, as its driver computes it
/// (XnSensorDepthStream: 2 atan(ZPPS * 1280 / 2 / ZPD)); 0 when the stream lacks them.
double ZeroPlaneFov(openni::VideoStream& depth) {
  if (!depth.isValid()) return 0;
  std::uint64_t zpd = 0;
  double zpps = 0;
  if (depth.getProperty(XN_STREAM_PROPERTY_ZERO_PLANE_DISTANCE, &zpd) != openni::STATUS_OK ||
      depth.getProperty(XN_STREAM_PROPERTY_ZERO_PLANE_PIXEL_SIZE, &zpps) != openni::STATUS_OK)
    return 0;
  if (zpd == 0 || !(zpps > 0) || !std::isfinite(zpps)) return 0;
  return 2 * std::atan(zpps * 1280 / 2 / static_cast<double>(zpd));
}

/// The first field of view of the chain that exists, and the note that names it.
Camera Resolve(std::pair<double, double> own, std::pair<double, double> other, const char* other_name, double zero_plane,
               int w, int h, std::string* note) {
  if (own.first > 0) return FromFov(own.first, own.second, w, h);
  if (other.first > 0) {
    if (note) *note = std::string("from the ") + other_name + " stream's field of view (this stream reports none)";
    return FromFov(other.first, other.second, w, h);
  }
  if (zero_plane > 0) {
    if (note) *note = "from the depth stream's zero-plane distance and pixel size (no field of view recorded)";
    return FromFov(zero_plane, 0, w, h);
  }
  // TUM RGB-D, Open3D's PrimeSenseDefault and ROS openni_camera use 525 px at 640 px.
  if (note) *note = "the Kinect v1 / PrimeSense default, 525 px at 640 x 480 (nothing in the file gives them)";
  return FromFov(2 * std::atan(320.0 / 525.0), 0, w, h);
}

}  // namespace

Camera OpenNiStreams::ColorIntrinsics(int w, int h, std::string* note) {
  return Resolve(StreamFov(color_), StreamFov(depth_), "depth", ZeroPlaneFov(depth_), w, h, note);
}

RgbdFrame::Extrinsics OpenNiStreams::DeviceExtrinsics() {
  RgbdFrame::Extrinsics e;
  double cm = 0;
  const bool recorded = depth_.isValid() &&
                        depth_.getProperty(XN_STREAM_PROPERTY_DCMOS_RCMOS_DISTANCE, &cm) == openni::STATUS_OK &&
                        std::isfinite(cm) && cm > 0.5 && cm < 10;
  const double baseline = recorded ? cm / 100 : 0.025;
  const bool mirrored = depth_.isValid() && depth_.getMirroringEnabled();
  // Not mirrored, the colour camera sits to the right of the depth camera (+x): a point
  // at x in the depth camera is at x - baseline in the colour camera.
  e.color_from_depth(0, 3) = mirrored ? baseline : -baseline;
  char text[200];
  std::snprintf(text, sizeof text, "colour camera %.1f cm to the %s of the depth camera (%s%s)", 100 * baseline,
                mirrored ? "left" : "right",
                recorded ? "the depth stream's DCMOS-RCMOS distance" : "the Kinect v1 / PrimeSense factory baseline",
                mirrored ? ", images mirrored" : "");
  e.source = text;
  return e;
}

Camera OpenNiStreams::DepthIntrinsics(int w, int h, std::string* note) {
  return Resolve(StreamFov(depth_), {0, 0}, "", ZeroPlaneFov(depth_), w, h, note);
}

void OpenNiStreams::CloseDevice() {
  ReleaseStreams(depth_, color_);
  device_.close();
}

OnOpenNiThreadSource::~OnOpenNiThreadSource() {
  try {
    OnOpenNiThread([this] { inner_.reset(); });
  } catch (...) {
    // No pool thread could be started (the process is out of threads): leave the device
    // open rather than close it from this thread, which may exit (see OpenNiThreads);
    // a destructor that threw would end the process.
    (void)inner_.release();
  }
}

SourceStatus OnOpenNiThreadSource::Next(RgbdFrame* frame, double timeout_seconds) {
  return OnOpenNiThread([&] { return inner_->Next(frame, timeout_seconds); });
}

void OnOpenNiThreadSource::Rewind() {
  OnOpenNiThread([this] { inner_->Rewind(); });
}

void OnOpenNiThreadSource::Seek(std::int64_t frame) {
  OnOpenNiThread([&] { inner_->Seek(frame); });
}

void OnOpenNiThreadSource::SetPaused(bool paused) {
  OnOpenNiThread([&] { inner_->SetPaused(paused); });
}

}  // namespace openni_detail
}  // namespace lp
