#pragma once
/// OpenNI2 behind one wrapper (no OpenNI header here): live devices, `.oni` recordings
/// and the Recorder. Debian's OpenNI2 2.2 has playback traps (dependencies.md) that this
/// code works around: manual playback speed, frame counts instead of an end-of-file
/// signal, seek by reopening, files checked before OpenNI2 sees them, and playback tried
/// in a separate process first (OpenNI2 crashes on some corrupted records).

#include <atomic>
#include <functional>
#include <memory>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "capture/frame_source.h"

namespace lp {

/// The folder the project's OpenNI2 runtime loads drivers from (with the project's
/// synthetic driver next to Debian's); empty when the build has none.
std::string OpenNiDriverFolder();

/// What a colour camera reports after its controls were applied.
struct CameraControls {
  bool camera_settings = false;  ///< the colour stream has exposure controls at all
  bool auto_exposure = true, auto_white_balance = true;
  int exposure = -1, gain = -1;
  bool registered = false;  ///< depth registered to colour (hardware registration on)
};

struct RecordOptions {
  std::string uri;            ///< OpenNI2 device URI ("" = the first device, lpsynth://DIR = synthetic)
  int frames = 30;            ///< depth frames to record (0 = use seconds)
  double seconds = 0;         ///< or record for this long
  bool lossy_color = false;   ///< JPEG colour (smaller) instead of uncompressed
  int width = 0, height = 0;  ///< size of both streams; 0 = the device's current mode
  /// As for a live source (OpenNiDeviceOptions): lock auto exposure / white balance and
  /// set exposure / gain when >= 0, after the streams start, then read them back.
  bool lock_exposure = true;
  int exposure = -1, gain = -1;
  /// When set and true, recording ends early (the frames so far are kept and the file is
  /// finished as for a complete recording): the window's Stop and its closing.
  const std::atomic<bool>* stop = nullptr;
  /// Called after each recorded depth frame: frames so far, seconds since the start.
  std::function<void(int depth_frames, double seconds)> progress;
};

struct RecordResult {
  /// Frames the file holds per stream (counted in it; the frames read while recording if
  /// it cannot be opened).
  int depth_frames = 0, color_frames = 0;
  double seconds = 0;
  CameraControls controls;  ///< as read back from the device (also in the side file)
  /// The device's frame index of the first recorded depth frame (a counter from 1 on the
  /// PS1080 and the synthetic device, which serves directory frame (index - 1) mod N).
  int first_depth_frame_index = -1;
};

/// Records depth (lossless) and colour from a device into `out_file` (.oni), written to a
/// temporary name and renamed when complete, after the side file OniSideFile(out_file):
/// what an .oni cannot hold (registration, exposure, gain, device URI; JSON). Throws
/// InputError with the reason when no device opens (no camera on USB, no permission, no
/// driver) or recording fails; an existing file is then left as it was.
RecordResult RecordOni(const std::string& out_file, const RecordOptions& options);

/// "recorded N depth frames in T s to FILE": the one line that reports a finished recording.
std::string DescribeRecording(const RecordResult& result, const std::string& file);

/// `FILE.oni` -> `FILE.oni.json`, the side file of a recording.
std::string OniSideFile(const std::string& oni_file);

/// What playback takes from a side file (docs/formats.md).
struct OniSideInfo {
  bool registered = false;
  /// The locked exposure and gain (device units); 0 when the recording ran on automatic
  /// exposure or did not say (frames are then not comparable across recordings).
  double exposure = 0, gain = 0;
};
/// Parses a side file's text (`name` for errors); throws InputError when it is not one.
OniSideInfo ParseOniSideFile(const std::string& text, const std::string& name);

struct OniPlaybackOptions {
  bool real_time = false;  ///< play at the recorded rate; default: as fast as frames are read
  bool loop = false;
  /// Play the whole file once in a separate process (lightprobe-oni-check) before this
  /// process opens it: OpenNI2 crashes on some corrupted records that pass the structure
  /// check, and a crash there becomes an InputError here. Costs one decode pass.
  bool isolate = true;
};

/// Replays a `.oni` file through OpenNI2's OniFile driver. Depth and colour are paired by
/// frame index (a stream that dropped frames skips ahead to its partner). Frames are
/// marked registered when the side file says the recording was (OpenNI2's recordings keep
/// stream properties, not the device's registration mode); without a side file, as
/// OpenNI2 reports. Throws InputError for a missing, empty, truncated or malformed file
/// (or side file) before this process's OpenNI2 reads it.
std::unique_ptr<FrameSource> OpenOniFile(const std::string& path, const OniPlaybackOptions& options = {});

struct OpenNiDeviceOptions {
  std::string uri;  ///< "" = the first device; lpsynth://DIR = the project's synthetic device
  int width = 640, height = 480, fps = 30;  ///< both streams (Xtion: 640x480 or 320x240 at 30 Hz)
  bool register_depth = true;  ///< hardware depth-to-colour registration when the device has it
  bool sync = true;            ///< depth/colour frame sync
  /// Photometric work needs a fixed exposure: auto exposure and auto white balance off,
  /// and exposure / gain set when >= 0 (device units). Applied after the streams start
  /// (set before, some devices ignore them) and read back; a device that does not take
  /// them is an error.
  bool lock_exposure = true;
  int exposure = -1, gain = -1;
};

/// Records an open device's running streams into an `.oni` file while the device keeps
/// serving frames (OpenNI2's Recorder attached to its streams): a window records without
/// closing its previews or its reconstruction. The file is written as
/// `.NAME.recording.oni` next to `out_file` and moved into place, with its side file, when
/// the recording stops; the source's destruction (closing the camera or the window) stops
/// it the same way, so a finished file is never lost. Any thread may call it; the calls
/// wait for the source's current read (at most its timeout). Pausing the source does not
/// pause a recording (the Recorder takes every frame the device sends).
/// How a recording ended without LiveRecorder::Stop (the source closed, the device lost).
struct RecordingEnd {
  enum class How {
    kNotEnded,  ///< still recording, never started, or ended by Stop
    kSaved,     ///< finished with the frames so far and moved into place
    kFailed,    ///< the file could not be finished
  };
  How how = How::kNotEnded;
  RecordResult result;  ///< kSaved: what the file holds
  std::string message;  ///< one line: "recorded N depth frames in S s to FILE (why)" or "recording failed: ..."
};

class LiveRecorder {
 public:
  virtual ~LiveRecorder() = default;
  /// Starts recording. Throws InputError when already recording, when the source is
  /// closed, or when OpenNI2 cannot create or start the recorder.
  virtual void Start(const std::string& out_file, bool lossy_color = false) = 0;
  /// Stops and finishes the file; returns what was recorded. Its frame counts (and the side
  /// file's, with first_depth_frame_index) are the frames the source read meanwhile; the
  /// Recorder itself takes every frame the device sends, read or not. Throws InputError
  /// when not recording, or when the file cannot be moved into place (it is then kept
  /// under its temporary name, which the message gives).
  virtual RecordResult Stop() = 0;
  virtual bool recording() const = 0;
  /// Depth frames the source read since Start and seconds since Start (0, 0 when idle).
  virtual void Progress(int* depth_frames, double* seconds) const = 0;
  /// Set when the source's destruction or a lost device finished the recording: what
  /// was recorded, or the reason it failed. Cleared by Start.
  virtual RecordingEnd EndedWithoutStop() const = 0;
};

/// A live OpenNI2 device as a FrameSource: depth + colour paired by timestamp, kTimeout
/// when nothing arrives in time, kDeviceLost once the device is unplugged. Throws
/// InputError (with the reason from the USB scan) when no device opens. `recorder`, when
/// given, receives the source's LiveRecorder (it outlives the source harmlessly).
std::unique_ptr<FrameSource> OpenOpenNiDevice(const OpenNiDeviceOptions& options, CameraControls* applied = nullptr,
                                              std::shared_ptr<LiveRecorder>* recorder = nullptr);

/// An exposure bracket from a live device for response calibration: for each exposure,
/// the device opened with auto exposure and white balance locked and that exposure set
/// (read back and checked), `settle` frames skipped, then one frame kept (it carries its
/// exposure and gain). Throws InputError as OpenOpenNiDevice does.
std::vector<RgbdFrame> CaptureBracket(const OpenNiDeviceOptions& device, const std::vector<int>& exposures,
                                      int settle = 5);

/// Checks the structure of a `.oni` file (header and record chain) without OpenNI2, in
/// both record layouts OpenNI2's file player reads (format versions 1.0.0.4 to 1.0.1.0:
/// 24-byte record headers before 1.0.1.0, 28 from it); throws InputError naming the file
/// and the first problem. Returns the number of frame records (both streams).
/// `facts`, when given, receives what the walk read on the way (below).
struct OniRecordFacts;
int ValidateOniFile(const std::string& path, OniRecordFacts* facts = nullptr);
/// The same on `size` bytes read from `in` (named `path` in errors).
int ValidateOniStream(std::istream& in, std::uint64_t size, const std::string& path, OniRecordFacts* facts = nullptr);

/// What a recording's own property records say that OpenNI2's player does not pass on.
struct OniRecordFacts {
  /// A node recorded with OpenNI 1's "AlternativeViewPoint" on: its depth was registered
  /// to the colour camera's view when recorded (OpenNI2's player drops the property and
  /// reports registration off).
  bool depth_registered = false;
};

}  // namespace lp
