#pragma once
/// Where RGB-D frames come from: a device, a recording, a directory, a renderer. Every
/// source yields owned RgbdFrames through the same interface, so everything after the
/// source is the same code for live and offline work.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame.h"

namespace lp {

/// What Next() produced. Per-frame events are statuses, not exceptions.
enum class SourceStatus {
  kFrame,       ///< a frame was written
  kEnd,         ///< no more frames (end of a file or directory, not looping)
  kTimeout,     ///< nothing arrived in time (a live device may still deliver later)
  kDeviceLost,  ///< the device went away (unplugged); frames already delivered are intact
};
const char* ToString(SourceStatus s);

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// One line for logs and the UI ("TUM directory /data/fr1_desk, 595 frames").
  virtual std::string Describe() const = 0;
  /// Number of frames when known (files, directories).
  virtual std::optional<std::int64_t> FrameCount() const { return std::nullopt; }
  /// Waits at most `timeout_seconds` for the next frame.
  virtual SourceStatus Next(RgbdFrame* frame, double timeout_seconds = 1.0) = 0;
  /// Back to the first frame (files and directories; a device throws InputError).
  virtual void Rewind() = 0;
  /// The next frame is the source's frame `frame` (0-based). Default: rewind and read
  /// past the frames before it (OpenNI2's own seek crashes). Throws InputError past the end.
  virtual void Seek(std::int64_t frame);
  /// Real-time sources hold their clock while paused, so playback resumes where it
  /// stopped instead of skipping the paused time (a no-op where frames are pulled).
  virtual void SetPaused(bool /*paused*/) {}
};

struct DirectorySourceOptions {
  bool loop = false;  ///< start again after the last frame instead of kEnd
};

/// A directory of RGB-D frames, recognized by its layout:
/// - TUM RGB-D: `rgb.txt` and `depth.txt` ("timestamp path" lines, '#' comments), paired by
///   `associations.txt` ("t_rgb rgb_path t_depth depth_path") when present, else by nearest
///   timestamp (within 20 ms); depth is 5000 per metre. Intrinsics: TUM's default
///   (525, 525, 319.5, 239.5) unless `intrinsics.json` is present.
/// - Redwood / Open3D: `color/` and `depth/` (millimetres) paired by sorted name, optional
///   `trajectory.log` (poses); intrinsics from `camera_primesense.json` or `camera.json` in
///   the directory or its parent ("intrinsic_matrix", column-major), else the PrimeSense
///   default.
/// - joinMap (slambook): `color/N.png`, `depth/N.pgm` (millimetres), `pose.txt`
///   ("tx ty tz qx qy qz qw" per frame); slambook's camera (518, 519, 325.5, 253.5) unless
///   `intrinsics.json` is present.
/// `intrinsics.json` (any layout): {"fx":..,"fy":..,"cx":..,"cy":..}. Throws InputError
/// naming the file for a missing directory, an unknown layout, or an index naming a
/// missing file (checked when the source opens, before any frame is delivered).
std::unique_ptr<FrameSource> OpenDirectorySource(const std::string& dir, const DirectorySourceOptions& options = {});
/// A frame directory's intrinsics file (`intrinsics.json`: {"fx", "fy", "cx", "cy"[, "width",
/// "height"]}, or Open3D's camera JSON with "intrinsic_matrix"); `name` for errors.
Camera ParseDirectoryIntrinsics(const std::string& text, const std::string& name);

/// Opens what a user names as input: a frame directory (any layout above) or an `.oni`
/// recording (played as fast as frames are read unless `real_time`). Throws InputError
/// naming the path when it is neither or cannot be opened.
std::unique_ptr<FrameSource> OpenFrameSource(const std::string& path, bool real_time = false);

/// Writes frames as a Redwood-layout directory that OpenDirectorySource reads back exactly:
/// color/NNNNN.png (8-bit), depth/NNNNN.png (16-bit mm), intrinsics.json (the first
/// frame's colour intrinsics; frames must be registered and of one size) and
/// trajectory.log when every frame has a pose. Built beside `dir` and renamed into place.
void WriteFrameDirectory(const std::string& dir, const std::vector<RgbdFrame>& frames);

}  // namespace lp
