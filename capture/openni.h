#pragma once
/// OpenNI2 behind one wrapper (no OpenNI header here): live devices, `.oni` recordings
/// and the Recorder. Debian's OpenNI2 2.2 has playback traps (dependencies.md) that this
/// code works around: manual playback speed, frame counts instead of an end-of-file
/// signal, seek by reopening, and files checked before OpenNI2 sees them.
#include <memory>
#include <string>

#include "capture/frame_source.h"

namespace lp {

/// The folder the project's OpenNI2 runtime loads drivers from (with the project's
/// synthetic driver next to Debian's); empty when the build has none.
std::string OpenNiDriverFolder();

struct RecordOptions {
  std::string uri;          ///< OpenNI2 device URI ("" = the first device, lpsynth://DIR = synthetic)
  int frames = 30;          ///< depth frames to record (0 = use seconds)
  double seconds = 0;       ///< or record for this long
  bool lossy_color = false; ///< JPEG colour (smaller) instead of uncompressed
};

struct RecordResult {
  int depth_frames = 0, color_frames = 0;
  double seconds = 0;
};

/// Records depth (lossless) and colour from a device into `out_file` (.oni), written to a
/// temporary name and renamed when complete. Throws InputError with the reason when no
/// device opens (no camera on USB, no permission, no driver) or recording fails.
RecordResult RecordOni(const std::string& out_file, const RecordOptions& options);

struct OniPlaybackOptions {
  bool real_time = false;  ///< play at the recorded rate; default: as fast as frames are read
  bool loop = false;
};

/// Replays a `.oni` file through OpenNI2's OniFile driver. Depth and colour are paired by
/// frame index (a stream that dropped frames skips ahead to its partner). Throws
/// InputError for a missing, empty, truncated or malformed file before OpenNI2 reads it.
std::unique_ptr<FrameSource> OpenOniFile(const std::string& path, const OniPlaybackOptions& options = {});

/// Checks the structure of a `.oni` file (header and record chain) without OpenNI2;
/// throws InputError naming the file and the first problem.
void ValidateOniFile(const std::string& path);

}  // namespace lp
